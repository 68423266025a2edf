//! The NUCLEO-F401RE driving a cart on a rail: minimal-adapter's `robot.rs` made real.
//!
//! | signal | pin (Arduino header) | peripheral |
//! | --- | --- | --- |
//! | encoder A, B | PA0 (A0), PA1 (A1) | TIM2 in encoder mode: a 32-bit count, ×4 decoding |
//! | motor PWM | PC7 (D9) | TIM3 channel 2 at 20 kHz, to a PWM + direction motor driver |
//! | motor direction | PA9 (D8) | output, high for a negative command |
//! | user button B1 | PC13 | input, pulled up on the board, low when pressed |
//! | user LED LD2 | PA5 (D13) | output, high = on |
//!
//! The clock is the internal 16 MHz RC oscillator (HSI) through the PLL to 84 MHz, the
//! F401's maximum: it works on every revision of the board. For a crystal-accurate clock,
//! `Config::hse(8.MHz()).bypass_hse_oscillator()` takes the ST-LINK's 8 MHz output on
//! OSC_IN, where the board revision wires it (UM1724, "OSC clock").
//!
//! The control tick is SysTick, counting down at 50 Hz: [`Board::read_state`] waits for it,
//! so the loop runs at a fixed rate whatever the computation takes, and a tick whose
//! computation overran its period is counted. The independent watchdog (IWDG, on its own
//! 32 kHz oscillator) resets the chip when the loop stops for 100 ms; a reset leaves the PWM
//! pin floating, so the motor driver's PWM input needs a pull-down to stop the motor.
//!
//! The encoder is incremental: position 0 is where the cart was at power-on. On a rig with a
//! home switch, drive to it and call `set_count(0)` on the encoder before the first episode.

use ctrl_adapt::Vector;
use stm32f4xx_hal::{
    gpio::{Input, Output, PA5, PA9, PC13},
    pac,
    prelude::*,
    qei::Qei,
    rcc::Config,
    timer::{PwmChannel, SysCounterHz},
    watchdog::IndependentWatchdog,
};
use {defmt_rtt as _, panic_probe as _}; // defmt over RTT (read by probe-rs); panics logged

/// Control period (s): a 50 Hz loop.
pub const DT: f32 = 0.02;
/// Ticks per episode: 10 s.
pub const TICKS: u32 = 500;
/// Where each episode starts (m).
pub const START: f32 = 0.0;
/// The position the PD holds during an episode (m).
pub const SETPOINT: f32 = 1.0;
/// The positions the cart may reach (m): the rail's ends less a braking distance. Outside,
/// an episode is aborted and the motor stopped.
const SAFE_RANGE: (f32, f32) = (-0.05, 1.15);
/// Metres per encoder count: a 1000-line encoder counted on both edges of both channels
/// (4000 counts per turn) on a 20-tooth GT2 pulley (40 mm of belt per turn).
const METRES_PER_COUNT: f32 = 0.04 / 4000.0;
/// "At the start pose": within 5 mm of it, moving slower than 1 cm/s.
const AT_REST: (f32, f32) = (0.005, 0.01);
/// A press counts after the button was seen up on this many ticks in a row (60 ms): its
/// contacts bounce for a few milliseconds, which a 20 ms sample may catch once.
const RELEASED_TICKS: u8 = 3;
/// Watchdog timeout (ms): five control periods.
const WATCHDOG_MS: u32 = 100;

/// What the user LED shows.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Led {
    /// Between episodes, the motor under the bare PD.
    Off,
    /// A learning episode.
    On,
    /// The deployed correction (after the learning episodes): 1 Hz.
    SlowBlink,
    /// Motor off after an abort: the operator's press re-arms it. 5 Hz.
    FastBlink,
}

/// Why an episode stopped early.
#[derive(Clone, Copy, defmt::Format)]
pub enum Fault {
    /// The cart left [`SAFE_RANGE`].
    OutOfRange,
    /// The operator pressed the button.
    OperatorStop,
}

/// The board's peripherals and the cart's last reading.
pub struct Board {
    encoder: Qei<pac::TIM2>,
    pwm: PwmChannel<pac::TIM3, 1>,
    direction: PA9<Output>,
    button: PC13<Input>,
    led: PA5<Output>,
    tick: SysCounterHz,
    watchdog: IndependentWatchdog,
    /// Position (m) and velocity (m/s) at the last tick.
    x: f32,
    v: f32,
    /// Ticks the button has been up in a row, and whether it was pressed since `pressed`
    /// was last called.
    up_ticks: u8,
    press: bool,
    pattern: Led,
    ticks: u32,
    overruns: u32,
}

impl Board {
    /// Clocks, pins, timers and the watchdog, started; the motor off. Called once, at reset.
    pub fn take() -> Self {
        let dp = defmt::unwrap!(pac::Peripherals::take());
        let cp = defmt::unwrap!(cortex_m::Peripherals::take());
        let mut rcc = dp.RCC.freeze(Config::hsi().sysclk(84.MHz()));
        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpioc = dp.GPIOC.split(&mut rcc);

        let encoder = Qei::new(dp.TIM2, (gpioa.pa0, gpioa.pa1), &mut rcc);
        let (_, (_, pwm, ..)) = dp.TIM3.pwm_hz(20.kHz(), &mut rcc);
        let mut pwm = pwm.with(gpioc.pc7);
        pwm.set_duty(0);
        pwm.enable();

        let mut tick = cp.SYST.counter_hz(&rcc.clocks);
        defmt::unwrap!(tick.start(50.Hz()).ok()); // 84 MHz / 50 Hz fits SysTick's 24 bits
        let mut watchdog = IndependentWatchdog::new(dp.IWDG);
        watchdog.stop_on_debug(&dp.DBGMCU, true); // a halted debugger does not reset the chip
        watchdog.start(WATCHDOG_MS.millis());

        let mut board = Self {
            encoder,
            pwm,
            direction: gpioa.pa9.into_push_pull_output(),
            button: gpioc.pc13.into_input(),
            led: gpioa.pa5.into_push_pull_output(),
            tick,
            watchdog,
            x: 0.0,
            v: 0.0,
            up_ticks: 0,
            press: false,
            pattern: Led::Off,
            ticks: 0,
            overruns: 0,
        };
        board.x = board.position();
        board
    }

    /// Waits for the next control tick, then reads the cart: the state
    /// [`setpoint` − position, velocity], in m and m/s.
    pub fn read_state(&mut self, setpoint: f32) -> Vector<2> {
        // A tick already due means the last period's work overran it.
        if self.tick.wait().is_ok() {
            self.overruns = self.overruns.wrapping_add(1);
        } else {
            while self.tick.wait().is_err() {}
        }
        self.watchdog.feed();
        self.ticks = self.ticks.wrapping_add(1);

        let x = self.position();
        self.v = (x - self.x) / DT;
        self.x = x;
        if self.button.is_low() {
            self.press |= self.up_ticks >= RELEASED_TICKS;
            self.up_ticks = 0;
        } else {
            self.up_ticks = self.up_ticks.saturating_add(1);
        }
        self.update_led();
        Vector::from([setpoint - x, self.v])
    }

    /// The motor command: a duty in [−1, 1], its sign the direction. Anything else (a
    /// non-finite value) stops the motor.
    pub fn write_command(&mut self, u: f32) {
        let duty = if u.is_finite() { u.abs().min(1.0) } else { 0.0 };
        self.direction.set_state((u < 0.0).into());
        self.pwm
            .set_duty((duty * f32::from(self.pwm.get_max_duty())) as u16);
    }

    /// Motor off (duty 0).
    pub fn stop_motor(&mut self) {
        self.pwm.set_duty(0);
    }

    /// Whether the episode must stop, from this tick's reading (checked before the
    /// command is computed).
    pub fn fault(&mut self) -> Option<Fault> {
        if self.outside_safe_range() {
            Some(Fault::OutOfRange)
        } else if self.pressed() {
            Some(Fault::OperatorStop)
        } else {
            None
        }
    }

    /// Whether the cart is outside the positions it may reach.
    pub fn outside_safe_range(&self) -> bool {
        !(SAFE_RANGE.0..=SAFE_RANGE.1).contains(&self.x)
    }

    /// Whether the button went down since the last call.
    pub fn pressed(&mut self) -> bool {
        core::mem::take(&mut self.press)
    }

    /// Whether the cart rests at `position`.
    pub fn at_rest(&self, position: f32) -> bool {
        (self.x - position).abs() < AT_REST.0 && self.v.abs() < AT_REST.1
    }

    /// Sets what the user LED shows from the next tick on.
    pub fn show(&mut self, pattern: Led) {
        self.pattern = pattern;
    }

    /// Ticks since the last call whose computation overran the control period.
    pub fn take_overruns(&mut self) -> u32 {
        core::mem::take(&mut self.overruns)
    }

    /// Stops for good on an error the firmware cannot run past: motor off, LED blinking,
    /// the watchdog still fed (a reset would only meet the same error).
    pub fn halt(mut self, why: &str) -> ! {
        defmt::error!("{}", why);
        self.stop_motor();
        self.show(Led::FastBlink);
        loop {
            self.read_state(0.0);
        }
    }

    fn position(&self) -> f32 {
        // The 32-bit count read as signed: positions on both sides of the power-on one.
        self.encoder.count() as i32 as f32 * METRES_PER_COUNT
    }

    fn update_led(&mut self) {
        // Half-periods in ticks: 25 ticks = 0.5 s (1 Hz), 5 ticks = 0.1 s (5 Hz).
        let on = match self.pattern {
            Led::Off => false,
            Led::On => true,
            Led::SlowBlink => (self.ticks / 25).is_multiple_of(2),
            Led::FastBlink => (self.ticks / 5).is_multiple_of(2),
        };
        self.led.set_state(on.into());
    }
}
