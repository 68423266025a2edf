//! Optimizer overhead on the host: time per ask+tell pair (the objective excluded) and the
//! size of the optimizer state. Prints a table; asserts nothing about speed (these machines
//! are shared and noisy). Run with `cargo bench -p host-tests`.
//!
//! Method: one run on a shifted sphere records the cost sequence; the timed loop replays it
//! into fresh optimizers (the search is deterministic given the costs), so only `ask` and
//! `tell` are inside the clock. The median over repetitions is reported.

use std::hint::black_box;
use std::time::Instant;

use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Vector};
use host_tests::{functions::sphere, run};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

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

fn bench_coordinate<const N: usize>() {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let costs = run(
        &mut coordinate::<N>(),
        &mut rng,
        usize::MAX,
        |t, _| sphere(t, 0.3),
        |_, _, _| {},
    )
    .expect("a clean run")
    .costs;

    let replays = MIN_PAIRS_PER_REPETITION.div_ceil(costs.len());
    let mut per_pair_ns: Vec<f64> = (0..REPETITIONS)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..replays {
                let mut s = black_box(coordinate::<N>());
                for &cost in &costs {
                    black_box(s.ask(&mut rng).expect("replay stays in step"));
                    s.tell(black_box(cost)).expect("finite cost");
                }
                black_box(&s);
            }
            start.elapsed().as_nanos() as f64 / (replays * costs.len()) as f64
        })
        .collect();
    per_pair_ns.sort_by(f64::total_cmp);
    println!(
        "| CoordinateSearch | {N:>4} | {:>8} | {:>10.1} | {:>10.1} | {:>8} |",
        costs.len(),
        per_pair_ns[REPETITIONS / 2],
        per_pair_ns[0],
        std::mem::size_of::<CoordinateSearch<N>>(),
    );
}

fn main() {
    println!("host: {} {}", std::env::consts::ARCH, std::env::consts::OS);
    println!("| optimizer | N | evals/run | ns/ask+tell (median) | (min) | size_of (B) |");
    println!("|---|---:|---:|---:|---:|---:|");
    bench_coordinate::<18>();
    bench_coordinate::<100>();
}
