//! Footprint benchmark of ROCK* (`Rockstar`), apart from the `bench` firmware because its
//! state is large and its calls long: `Rockstar<18, 90>` (the AUV's 18 parameters with the
//! recommended memory of 5n rollouts) and `Rockstar<31, 155>` (the hopping leg's 31
//! parameters, 5n again), each for [`MEASURED`] evaluations of the ill-conditioned
//! ellipsoid of its dimension over the box [−1, 1]ⁿ from 0: past the memory's filling and
//! into its eviction.
//!
//! A `tell` runs about a million instructions, too many to trace one by one, so the counts
//! come from SysTick under QEMU's `-icount shift=0`
//! ([`ctrl_adapt_firmware::bench::icount`], exact to ±40 instructions): each `ask` and
//! `tell` logs `footprint: sample rockstar_ask = N` (…`_tell`, and `rockstar_hopper_…` for
//! N = 31), which `scripts/footprint` turns into the table's statistics. It also prints the
//! `size_of` of both, of the AUV adapter around the 18-parameter one, and the peak stack.
#![no_std]
#![no_main]

use auv_survey::{self as auv, AuvAdapter};
use ctrl_adapt::{Bounds, Error, Rockstar, RockstarConfig, Vector};
use ctrl_adapt_firmware::bench::icount::Counter;
use ctrl_adapt_firmware::bench::long::{Plan, build_and_measure};
use ctrl_adapt_firmware::{exit_failure, exit_success, log_size, stack};

/// The AUV's parameters.
const N: usize = auv::P;
/// The hopping leg's parameters (10 periodic kernels for each of three gains, and the period).
const N_HOPPER: usize = 31;
/// Measured evaluations per size: more than the larger memory (155), so the counts include
/// the memory full and evicting, and several refactorings of the covariance (every n).
pub const MEASURED: u32 = 200;

/// `Rockstar<18, 90>` with the defaults over the AUV box, from 0. Out of line: its
/// temporaries (the box, the configuration) are not in the frame that holds the optimizer
/// while it runs; the optimizer itself is written into the caller's `Result`.
#[inline(never)]
fn auv_rockstar() -> Result<Rockstar<N, 90>, Error> {
    Rockstar::try_new(auv::bounds()?, Vector::zeros(), RockstarConfig::DEFAULT)
}

/// `Rockstar<31, 155>` with the defaults over the hopping leg's box [−1, 1]ⁿ, from 0.
#[inline(never)]
fn hopper_rockstar() -> Result<Rockstar<N_HOPPER, 155>, Error> {
    let bounds = Bounds::uniform(-1.0, 1.0)?;
    Rockstar::try_new(bounds, Vector::zeros(), RockstarConfig::DEFAULT)
}

/// The stack ROCK* may take beyond its own state (the rule every optimizer follows).
const STACK_BEYOND_STATE: usize = 2048;

#[cortex_m_rt::entry]
fn main() -> ! {
    log_size!("Rockstar<18, 90>", Rockstar<N, 90>);
    log_size!("Rockstar<31, 155>", Rockstar<N_HOPPER, 155>);
    log_size!("Adapter with Rockstar<18, 90>", AuvAdapter<Rockstar<N, 90>>);
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        exit_failure()
    };
    let mut counter = Counter::new(peripherals.SYST);
    // Calibration: an empty call, whose count is the reads' own cost (0 or 40).
    for _ in 0..4 {
        let ((), empty) = counter.measure(|| ());
        defmt::info!("footprint: sample empty = {=u32}", empty);
    }
    let plan = |name| Plan {
        name,
        evaluations: MEASURED,
        split: u32::MAX,
        later: name,
    };
    let measured = build_and_measure(&mut counter, plan("rockstar"), auv_rockstar)
        .and_then(|()| build_and_measure(&mut counter, plan("rockstar_hopper"), hopper_rockstar));
    if let Err(e) = measured {
        defmt::error!("benchmark failed: {}", e);
        exit_failure()
    }
    let peak = stack::peak_bytes();
    defmt::info!("footprint: peak stack bench_rockstar = {=u32}", peak);
    // ROCK* needs O(n) stack beyond its own state, like every other optimizer: the largest
    // one measured here may take at most its state + 2 KB.
    let budget = core::mem::size_of::<Rockstar<N_HOPPER, 155>>() + STACK_BEYOND_STATE;
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
