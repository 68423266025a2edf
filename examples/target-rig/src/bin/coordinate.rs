//! `CoordinateSearch<18>` entirely on the emulated Cortex-M4F: minimises the 18-D
//! ill-conditioned ellipsoid (condition number 1e3) in `f32`, logs its progress over defmt,
//! reports the optimizer's size and the peak stack, and exits 0 only if the search converged
//! to the known minimiser.
//!
//! `cargo run --release --bin coordinate` (from `examples/target-rig/`).
#![no_std]
#![no_main]

use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Status, Vector};
use ctrl_adapt_firmware::{exit_failure, exit_success, functions, stack};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// The number of parameters of the AUV survey policy (and of the paper's experiment).
const N: usize = 18;
/// Episode budget: far above what the search needs (about 5,000 evaluations).
const BUDGET: u32 = 100_000;

#[cortex_m_rt::entry]
fn main() -> ! {
    match run() {
        Ok(()) => exit_success(),
        Err(e) => {
            defmt::error!("coordinate search failed: {}", e);
            exit_failure()
        }
    }
}

fn run() -> Result<(), ctrl_adapt::Error> {
    let bounds = Bounds::<N>::uniform(-2.0, 2.0)?;
    let config = CoordinateConfig {
        initial_step: 0.5,
        tolerance: 1e-5,
        max_evaluations: BUDGET,
        ..CoordinateConfig::DEFAULT
    };
    let mut search = CoordinateSearch::try_new(bounds, Vector::<N>::repeat(-1.0), config)?;
    // The coordinate search draws no random numbers; the RNG belongs to the common interface.
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let ellipsoid = functions::Ellipsoid::<N>::new();
    defmt::info!(
        "footprint: size_of CoordinateSearch<18> = {=usize}",
        core::mem::size_of::<CoordinateSearch<N>>()
    );
    defmt::info!("coordinate search, 18-D ellipsoid (cond 1e3) from theta = -1");

    let mut next_report = 1;
    while search.status() == Status::Running {
        let theta = search.ask(&mut rng)?;
        search.tell(ellipsoid.eval(&theta))?;
        let k = search.evaluations();
        if k == next_report {
            let best = search.best().map_or(f32::INFINITY, |b| b.cost);
            defmt::info!("evaluation {=u32}: best cost {=f32}", k, best);
            next_report *= 2;
        }
    }

    let best = search.best().ok_or(ctrl_adapt::Error::NoPendingAsk)?;
    let worst_error = (0..N)
        .map(|i| libm::fabsf(best.theta[i] - functions::ellipsoid_minimiser::<N>(i)))
        .fold(0.0f32, f32::max);
    defmt::info!(
        "stopped: {} after {=u32} evaluations, {=u32} iterations; best cost {=f32}, largest coordinate error {=f32}",
        search.status(),
        search.evaluations(),
        search.iterations(),
        best.cost,
        worst_error
    );
    defmt::info!(
        "footprint: peak stack = {=u32} (of {=u32} bytes of stack region)",
        stack::peak_bytes(),
        stack::region_bytes()
    );
    if search.status() == Status::Converged && best.cost < 1e-6 && worst_error < 2e-3 {
        defmt::info!("ok: converged to the minimiser");
        Ok(())
    } else {
        defmt::error!("did not converge to the minimiser");
        exit_failure()
    }
}
