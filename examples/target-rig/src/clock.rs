//! A millisecond clock from SysTick, polled (no interrupt): the PIL firmware's only timer,
//! for the per-tick deadline.

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;

/// Counts SysTick wraps of one millisecond each.
pub struct Millis {
    syst: SYST,
    ms: u32,
}

impl Millis {
    /// Starts SysTick on the core clock with a 1 ms period (`core_hz / 1000` cycles; the
    /// QEMU mps2 boards clock the core at 25 MHz).
    pub fn new(mut syst: SYST, core_hz: u32) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload((core_hz / 1000).saturating_sub(1).clamp(1, 0x00FF_FFFF));
        syst.clear_current();
        syst.enable_counter();
        Self { syst, ms: 0 }
    }

    /// Also pends the SysTick exception at every millisecond, so that a core waiting in
    /// `wfi` wakes up to advance the clock (with interrupts masked by PRIMASK the exception
    /// is never taken: the waiter clears it, see [`crate::pil`]).
    pub fn enable_wakeup(&mut self) {
        self.syst.enable_interrupt();
    }

    /// Milliseconds since `new`. Must be polled at least once per millisecond to be exact;
    /// polled less often, it runs slow, which only stretches a deadline.
    pub fn now(&mut self) -> u32 {
        if self.syst.has_wrapped() {
            self.ms = self.ms.wrapping_add(1);
        }
        self.ms
    }
}
