//! Optimizer overhead on the host: time per ask+tell pair (the objective excluded) and the
//! size of the optimizer state. Prints a table; asserts nothing about speed (these machines
//! are shared and noisy). Run with `cargo bench -p experiments`.
//!
//! Method: one run on a shifted sphere records the cost sequence; the timed loop replays it
//! into fresh optimizers (the search is deterministic given the costs), so only `ask` and
//! `tell` are inside the clock. The median over repetitions is reported.

use auv_survey::{AuvAdapter, AuvController};
use ctrl_adapt::controller::PeriodicPd;
use ctrl_adapt::cost::SurveyCost;
use ctrl_adapt::optimizer::{
    Bounds, CemConfig, ControlledRandomSearch, CoordinateConfig, CoordinateSearch, CrsConfig,
    DiagonalCem, Optimizer, Sracos, SracosConfig, Vector,
};
use experiments::overhead::replay;
use host_tests::functions::sphere;

const REPETITIONS: usize = 31;
const MIN_PAIRS_PER_REPETITION: usize = 200_000;

fn coordinate<const N: usize>() -> CoordinateSearch<N> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
    let config = CoordinateConfig {
        initial_step: 0.25,
        tolerance: 1e-6,
        ..CoordinateConfig::DEFAULT
    };
    CoordinateSearch::try_new(bounds, Vector::zeros(), config).expect("valid config")
}

fn crs<const N: usize, const M: usize>() -> ControlledRandomSearch<N, M> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
    let config = CrsConfig {
        max_evaluations: 20 * N as u32,
        ..CrsConfig::DEFAULT
    };
    ControlledRandomSearch::try_new(bounds, config).expect("valid config")
}

fn sracos<const N: usize>() -> Sracos<N> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
    let config = SracosConfig {
        max_evaluations: 20 * N as u32,
        ..SracosConfig::DEFAULT
    };
    Sracos::try_new(bounds, config).expect("valid config")
}

fn cem<const N: usize, const K: usize>() -> DiagonalCem<N, K> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
    let config = CemConfig {
        max_evaluations: 20 * N as u32,
        ..CemConfig::DEFAULT
    };
    DiagonalCem::try_new(bounds, Vector::zeros(), config).expect("valid config")
}

/// Times ask+tell of the optimizers `make` builds, replaying the costs of one recorded run
/// on the sphere centred at 0.3 (same seed each replay, so the same candidates).
fn bench<const N: usize, O: Optimizer<N>>(name: &str, make: impl Fn() -> O) {
    let o = replay(
        make,
        |t| sphere(t, 0.3),
        usize::MAX,
        REPETITIONS,
        MIN_PAIRS_PER_REPETITION,
    );
    println!(
        "| {name} | {N:>4} | {:>8} | {:>10.1} | {:>10.1} | {:>8} |",
        o.evaluations,
        o.median_ns,
        o.min_ns,
        std::mem::size_of::<O>(),
    );
}

fn main() {
    println!("host: {} {}", std::env::consts::ARCH, std::env::consts::OS);
    println!("| optimizer | N | evals/run | ns/ask+tell (median) | (min) | size_of (B) |");
    println!("|---|---:|---:|---:|---:|---:|");
    bench("CoordinateSearch", coordinate::<18>);
    bench("CoordinateSearch", coordinate::<100>);
    bench("ControlledRandomSearch (m = 10(n+1))", crs::<18, 190>);
    bench("ControlledRandomSearch (m = 2(n+1))", crs::<18, 38>);
    bench("Sracos (K = 2, M = 10)", sracos::<18>);
    bench("DiagonalCem (K = 10, PI-BB)", cem::<18, 10>);
    println!();
    println!("| state | size_of (B) |");
    println!("|---|---:|");
    for (name, size) in [
        (
            "Adapter<CoordinateSearch<18>, AUV policy, SurveyCost>",
            size_of::<AuvAdapter<CoordinateSearch<18>>>(),
        ),
        (
            "Adapter<ControlledRandomSearch<18, 38>, AUV policy, SurveyCost>",
            size_of::<AuvAdapter<ControlledRandomSearch<18, 38>>>(),
        ),
        (
            "AuvController (AUV policy: CorrectedPd over IdentityFeatures)",
            size_of::<AuvController>(),
        ),
        (
            "PeriodicPd<10, 31> (hopping-leg policy)",
            size_of::<PeriodicPd<10, 31>>(),
        ),
        ("SurveyCost", size_of::<SurveyCost>()),
    ] {
        println!("| {name} | {size} |");
    }
}
