//! Footprint benchmark of LineBO (`LineBo`), apart from the `bench` firmware because its
//! state is large and its calls long: `LineBo<18, 64>` (the AUV's 18 parameters with the
//! recommended capacity of 64 remembered episodes) without a threshold and with one, each
//! for [`MEASURED`] evaluations of the ill-conditioned 18-D ellipsoid over the AUV box from
//! 0: past the GP's filling and into its eviction.
//!
//! The settings follow LineBO's rule as the AUV experiments applied it before their settings
//! were re-chosen on seeds 101–110 (experiments/findings/line-bo.md): σ_f = the start's cost
//! J(0), σ_n = 5 % of it, ℓ = 0.15 of the box, β = 2; without a threshold one episode per
//! coordinate line, with the threshold h = 1.2 J(0) (SafeOpt on the line) three.
//!
//! Each call runs about a million instructions or more, too many to trace one by one, so
//! the counts come from SysTick under QEMU's `-icount shift=0`
//! ([`ctrl_adapt_firmware::bench::icount`], exact to ±40 instructions): each `ask` and
//! `tell` logs `footprint: sample line_bo_ask = N` (…`_tell`, and `line_bo_safe_…` with the
//! threshold); from the 65th evaluation on, with the GP full, under `line_bo_full_…` and
//! `line_bo_safe_full_…`. `scripts/footprint` turns them into the table's statistics. It
//! also prints the `size_of` of the optimizer and of the AUV adapter around it, and the peak
//! stack.
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvAdapter};
use ctrl_adapt::{Error, LineBo, LineBoConfig, Vector};
use ctrl_adapt_firmware::bench::icount::Counter;
use ctrl_adapt_firmware::bench::long::{Plan, build_and_measure};
use ctrl_adapt_firmware::functions::Ellipsoid;
use ctrl_adapt_firmware::{exit_failure, exit_success, log_size, stack};

/// The AUV's parameters.
const N: usize = auv::P;
/// Episodes the GP remembers: the recommended capacity at n = 18.
const M: usize = 64;
/// Measured evaluations per variant: past the GP's capacity, so the counts include the
/// eviction (a rank-one update of the factor per `tell`).
pub const MEASURED: u32 = 100;

/// LineBO's settings for the ellipsoid from 0 (module docs), with or without the threshold.
fn config(safe: bool) -> LineBoConfig {
    let start = Ellipsoid::<N>::new().eval(&Vector::zeros());
    let noise = 0.05 * start;
    LineBoConfig {
        signal_variance: start * start,
        noise_variance: noise * noise,
        length_scale: 0.15,
        evaluations_per_line: if safe { 3 } else { 1 },
        threshold: safe.then_some(1.2 * start),
        ..LineBoConfig::DEFAULT
    }
}

/// `LineBo<18, 64>` without a threshold. Out of line: its temporaries are not in the frame
/// that holds the optimizer while it runs; the optimizer itself is written into the
/// caller's `Result`.
#[inline(never)]
fn unthresholded() -> Result<LineBo<N, M>, Error> {
    LineBo::try_new(auv::bounds()?, Vector::zeros(), config(false))
}

/// `LineBo<18, 64>` with the threshold.
#[inline(never)]
fn safe() -> Result<LineBo<N, M>, Error> {
    LineBo::try_new(auv::bounds()?, Vector::zeros(), config(true))
}

/// The stack LineBO may take beyond its own state (the rule every optimizer follows).
const STACK_BEYOND_STATE: usize = 2048;

#[cortex_m_rt::entry]
fn main() -> ! {
    log_size!("LineBo<18, 64>", LineBo<N, M>);
    log_size!("Adapter with LineBo<18, 64>", AuvAdapter<LineBo<N, M>>);
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut counter = Counter::new(peripherals.SYST);
    // Calibration: an empty call, whose count is the reads' own cost (0 or 40).
    for _ in 0..4 {
        let ((), empty) = counter.measure(|| ());
        defmt::info!("footprint: sample empty = {=u32}", empty);
    }
    // From the (M + 1)-th evaluation on the GP is full: every `tell` evicts a point.
    let plan = |name, later| Plan {
        name,
        evaluations: MEASURED,
        split: M as u32,
        later,
    };
    let measured = build_and_measure(&mut counter, plan("line_bo", "line_bo_full"), unthresholded)
        .and_then(|()| {
            build_and_measure(
                &mut counter,
                plan("line_bo_safe", "line_bo_safe_full"),
                safe,
            )
        });
    if let Err(e) = measured {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    let peak = stack::peak_bytes();
    defmt::info!("footprint: peak stack bench_line_bo = {=u32}", peak);
    // The target every other optimizer meets: at most its state + 2 KB of stack (the
    // working columns of the posterior pass and of the expander test are in the state).
    let budget = core::mem::size_of::<LineBo<N, M>>() + STACK_BEYOND_STATE;
    if peak as usize > budget {
        defmt::error!(
            "peak stack {=u32} B exceeds state + 2 KB = {=usize} B",
            peak,
            budget
        );
        exit_failure()
    }
    exit_success()
}
