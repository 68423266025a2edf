//! Stands for your board: a unit mass at `x` (m) moving at `v` (m/s), commanded in
//! acceleration, with a constant push (−1.5 m/s²) the PD was not designed for; the setpoint
//! is 1 m. On a robot, `read_state` is your sensor read, `write_command` your actuator write,
//! `go_to_start` your start-pose routine, and the tick loop waits for your control timer.
//!
//! On QEMU it also judges the run, from its own measurements: the firmware exits with
//! success when the last (deployed) episode's ∫ error² dt is below 35 % of the first one's
//! (the bare PD: the first episode runs θ = 0).

use ctrl_adapt::Vector;
use {cortex_m as _, defmt_semihosting as _}; // critical section; defmt over semihosting

/// Control period (s): a 50 Hz loop.
pub const DT: f32 = 0.02;
/// Ticks per episode: 10 s.
pub const TICKS: u32 = 500;

/// The simulated cart and the run's figures.
#[derive(Default)]
pub struct Robot {
    x: f32,
    v: f32,
    /// ∫ (1 − x)² dt of the running episode, as the robot measures it.
    cost: f32,
    /// That integral for the first and the last episode ended, and the episodes seen.
    first: Option<f32>,
    last: f32,
    episodes: u32,
}

impl Robot {
    /// Your start-pose routine: back at rest at 0. Closes the previous episode's figures.
    pub fn go_to_start(&mut self) {
        self.close_episode();
        (self.x, self.v, self.cost) = (0.0, 0.0, 0.0);
    }

    /// Your sensor read: the state [setpoint − position, velocity].
    pub fn read_state(&self) -> Vector<2> {
        Vector::from([1.0 - self.x, self.v])
    }

    /// Your actuator write: one control period of the commanded acceleration.
    pub fn write_command(&mut self, u: f32) {
        self.cost += (1.0 - self.x) * (1.0 - self.x) * DT;
        self.v += (u - 1.5) * DT; // −1.5 m/s²: the unmodelled push
        self.x += self.v * DT;
    }

    fn close_episode(&mut self) {
        if self.episodes > 0 {
            self.first.get_or_insert(self.cost);
            self.last = self.cost;
        }
        self.episodes += 1;
    }

    /// The end of the run: on QEMU, exit with success when the deployed correction beats
    /// the bare PD by the margin above.
    pub fn finish(mut self) -> ! {
        self.close_episode();
        let bare = self.first.unwrap_or(f32::NAN);
        defmt::info!(
            "measured by the robot: bare PD {}, deployed {}",
            bare,
            self.last
        );
        let learned = self.last < 0.35 * bare;
        semihosting::process::exit(if learned { 0 } else { 1 })
    }
}

/// Stops the firmware (on a board: keep running the bare PD, and report).
pub fn stop(why: &str) -> ! {
    defmt::error!("{}", why);
    semihosting::process::exit(1)
}

/// A panic ends the emulation with a failure code (on a board: reset, or fall back to the
/// bare controller). The library itself never panics on any input.
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    semihosting::process::exit(1)
}
