//! Footprint benchmark: runs `CoordinateSearch<18>` on the 18-D ellipsoid with every `ask`
//! and `tell` between exec-trace markers ([`ctrl_adapt_firmware::bench`]), and prints the
//! `size_of` figures. `scripts/footprint` runs it under QEMU with an instruction trace.
#![no_std]
#![no_main]

use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Status, Vector};
use ctrl_adapt_firmware::bench::sections;
use ctrl_adapt_firmware::{exit_failure, exit_success, functions, stack};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = 18;
/// Measured evaluations: enough to pass through every phase of the state machine (start,
/// probes, expansions, contractions, several complete sweeps over the 36 directions).
const MEASURED: u32 = 400;

#[cortex_m_rt::entry]
fn main() -> ! {
    defmt::info!(
        "footprint: size_of CoordinateSearch<18> = {=usize}",
        core::mem::size_of::<CoordinateSearch<N>>()
    );
    for _ in 0..8 {
        sections::empty::measure(|| ());
    }
    match measure_coordinate_search() {
        Ok(()) => {}
        Err(e) => {
            defmt::error!("benchmark failed: {}", e);
            exit_failure()
        }
    }
    measure_controller();
    defmt::info!("footprint: peak stack bench = {=u32}", stack::peak_bytes());
    exit_success()
}

/// `MEASURED` ask+tell pairs of the coordinate search at N = 18.
fn measure_coordinate_search() -> Result<(), ctrl_adapt::Error> {
    let bounds = Bounds::<N>::uniform(-2.0, 2.0)?;
    let config = CoordinateConfig {
        initial_step: 0.5,
        tolerance: 1e-5,
        ..CoordinateConfig::DEFAULT
    };
    let mut search = CoordinateSearch::try_new(bounds, Vector::<N>::repeat(-1.0), config)?;
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let ellipsoid = functions::Ellipsoid::<N>::new();
    for _ in 0..MEASURED {
        if search.status() != Status::Running {
            break;
        }
        let theta = sections::ask::measure(|| search.ask(&mut rng))?;
        let cost = ellipsoid.eval(&theta);
        sections::tell::measure(|| search.tell(cost))?;
    }
    defmt::info!(
        "footprint: measured ask+tell pairs = {=u32}",
        search.evaluations()
    );
    Ok(())
}

/// Slot for the controller layer (issue 5). When `LinearPolicy` and `Adapter` exist:
/// 1. build the 18-parameter AUV policy and an `Adapter` around `CoordinateSearch<18>`;
/// 2. log `footprint: size_of Adapter<..> = {}` like the line in `main`;
/// 3. call the per-tick correction a few hundred times on varied states, each inside
///    `sections::correction::measure(|| policy.correction(&state, &theta))`.
///
/// `scripts/footprint` then reports the `correction` section and the adapter's size with no
/// change to the script.
fn measure_controller() {
    // Nothing to measure until the controller layer lands; the `correction` markers are never
    // called, and the script prints "not measured yet" for that row.
}
