//! The processor-in-the-loop firmware's main loop, shared by the `pil*` binaries (one per
//! optimizer): the controller and the learner run here, the plant runs on the host
//! (`cargo run -p host-tests --bin pil`), and the two exchange one state frame and one
//! action frame per control tick over UART0 ([`pil_link`] frames).
//!
//! A state frame that is corrupted, or that has not arrived [`TICK_DEADLINE_MS`] after the
//! previous answer, makes this tick's action the controller's fallback (the nominal PD on
//! the last valid state, flagged `FALLBACK` in the action frame).

use auv_survey::{self as auv, AuvLearner};
use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::{NVIC, SCB};
use ctrl_adapt::{Error, Optimizer};
use pil_link::{FrameReader, Kind, Learner, LinkError, Session, read_frame, write_frame};

use crate::clock::Millis;
use crate::uart::{CmsdkUart, Overrun, UART0_BASE, UART0_RX_IRQ};
use crate::{exit_failure, exit_success, stack};

/// How long a tick waits for its state frame before falling back. The host answers within
/// microseconds; the margin absorbs a loaded CI machine (QEMU's clock is the host's).
pub const TICK_DEADLINE_MS: u32 = 50;
/// Core clock of QEMU's mps2 boards (SYSCLK).
pub const CORE_HZ: u32 = 25_000_000;

/// UART0's receive interrupt, for the NVIC.
#[derive(Clone, Copy)]
struct Uart0Rx;

// SAFETY: 0 is UART0 RX's external interrupt number on mps2-an385/an386 (QEMU hw/arm/mps2.c),
// a valid interrupt of the board.
unsafe impl InterruptNumber for Uart0Rx {
    fn number(self) -> u16 {
        UART0_RX_IRQ
    }
}

/// UART0 whose empty [`ReadReady::read_ready`] poll sleeps in `wfi` until the next byte or
/// the next millisecond, instead of spinning.
///
/// Interrupts stay masked (PRIMASK): the UART's receive interrupt and SysTick only *wake*
/// the core (a pending interrupt that would be taken with PRIMASK clear ends `wfi`, ARMv7-M
/// B1.5.19), no handler runs, and the poll clears both before sleeping again. Under QEMU a
/// spinning core holds a host CPU and, at every register read, the emulator's global lock
/// that its I/O thread needs to deliver the host's bytes: sleeping takes the round trip per
/// tick from about 2.2 ms to (measured in docs/firmware.md). On a board it saves power, and
/// the same code runs over a HAL's UART with its receive interrupt.
struct SleepingPort {
    uart: CmsdkUart,
}

impl SleepingPort {
    fn new(mut uart: CmsdkUart, clock: &mut Millis) -> Self {
        cortex_m::interrupt::disable();
        uart.enable_rx_interrupt();
        clock.enable_wakeup();
        // SAFETY: interrupts are masked by PRIMASK for the rest of the program (nothing
        // re-enables them), so unmasking this line in the NVIC can never run a handler: it
        // only lets the line wake `wfi`.
        unsafe { NVIC::unmask(Uart0Rx) };
        Self { uart }
    }
}

impl embedded_io::ErrorType for SleepingPort {
    type Error = Overrun;
}

impl embedded_io::ReadReady for SleepingPort {
    fn read_ready(&mut self) -> Result<bool, Overrun> {
        if self.uart.read_ready()? {
            return Ok(true);
        }
        // Clear the wake-up sources, then look again: a byte or a tick after this point
        // pends its interrupt anew and `wfi` returns at once.
        self.uart.clear_rx_interrupt();
        NVIC::unpend(Uart0Rx);
        SCB::clear_pendst();
        if self.uart.read_ready()? {
            return Ok(true);
        }
        cortex_m::asm::wfi();
        Ok(false)
    }
}

impl embedded_io::Read for SleepingPort {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Overrun> {
        self.uart.read(buf)
    }
}

impl embedded_io::Write for SleepingPort {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Overrun> {
        self.uart.write(buf)
    }

    fn flush(&mut self) -> Result<(), Overrun> {
        self.uart.flush()
    }
}

/// The AUV PIL firmware's `main` with the optimizer `optimizer` (an [`auv_survey`] builder,
/// called with no episode budget: the host decides how many episodes learn, each Start
/// frame says): builds the learner, logs the session's `size_of` as `name`, and serves it.
///
/// The learner is built by a function that is never inlined, so the builders' by-value moves
/// (optimizer into adapter into learner) leave their temporaries in a frame that is gone
/// before the session runs; it stays where it landed, inside the `Result`, and is lent to
/// the session (moving it out would put a second copy of its state on the stack).
pub fn run_auv<O: Optimizer<{ auv::P }>>(name: &str, optimizer: fn(u32) -> Result<O, Error>) -> ! {
    let mut learner =
        apart(|| optimizer(u32::MAX).and_then(|o| AuvLearner::try_new(o, u32::MAX, auv::SEED)));
    let Ok(learner) = &mut learner else {
        defmt::error!("invalid AUV configuration");
        exit_failure()
    };
    defmt::info!(
        "footprint: size_of Session<AuvLearner<{=str}>> = {=usize}",
        name,
        core::mem::size_of::<Session<AuvLearner<O>>>()
    );
    serve(learner)
}

/// `build()`, in a stack frame of its own.
#[inline(never)]
fn apart<T>(build: impl FnOnce() -> T) -> T {
    build()
}

/// Serves the PIL protocol with `controller` until the host says Shutdown, then logs the link
/// counters and the peak stack and exits 0.
pub fn serve<C: Learner>(controller: C) -> ! {
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut clock = Millis::new(peripherals.SYST, CORE_HZ);
    // SAFETY: UART0 of mps2-an386 is a CMSDK APB UART at this address (QEMU hw/arm/mps2.c),
    // and this is its only user.
    let uart = unsafe { CmsdkUart::new(UART0_BASE, 16) };
    let mut uart = SleepingPort::new(uart, &mut clock);
    let mut session = Session::new(controller);
    defmt::info!("pil: waiting for the host on UART0");

    let mut reader = FrameReader::new();
    let mut deadline = clock.now().wrapping_add(TICK_DEADLINE_MS);
    loop {
        let awaiting = session.awaiting_tick();
        let received = read_frame(&mut uart, &mut reader, || {
            awaiting && clock.now().wrapping_sub(deadline) as i32 >= 0
        });
        let reply = match received {
            Ok(frame) => session.on_frame(&frame),
            Err(LinkError::Timeout) => session.on_timeout(),
            Err(LinkError::Corrupt(why)) => {
                defmt::debug!("corrupt frame: {}", why);
                session.on_corrupt();
                None
            }
            Err(LinkError::Io(_)) => {
                // A lost byte: whatever frame it belonged to is damaged.
                session.on_corrupt();
                reader = FrameReader::new();
                None
            }
        };
        let Some(reply) = reply else { continue };
        match reply.kind {
            Kind::Started => defmt::info!(
                "episode {=u16}: theta = {=[?]}",
                reply.episode,
                reply.values.as_slice()
            ),
            Kind::Report => defmt::info!(
                "episode {=u16}: report [cost, told, best, mode, faulty ticks] = {=[?]}, fallback ticks {=u16}",
                reply.episode,
                reply.values.as_slice(),
                reply.tick
            ),
            _ => {}
        }
        if write_frame(&mut uart, &reply).is_err() {
            defmt::error!("UART write failed");
            exit_failure()
        }
        deadline = clock.now().wrapping_add(TICK_DEADLINE_MS);
        if session.finished() {
            let stats = session.stats();
            defmt::info!(
                "pil: done; corrupt frames {=u32}, fallback ticks {=u32}, ignored frames {=u32}",
                stats.corrupt,
                stats.fallbacks,
                stats.ignored
            );
            defmt::info!("footprint: peak stack pil = {=u32}", stack::peak_bytes());
            exit_success()
        }
    }
}
