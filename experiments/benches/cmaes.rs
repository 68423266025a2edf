//! `Cmaes` overhead, printed as a Markdown table (asserts nothing; run with
//! `cargo bench -p experiments --bench cmaes`): host time per ask+tell pair (the objective
//! excluded; the eigendecomposition after every λ-th tell included, amortised) and
//! `size_of` the optimizer, for the AUV's N = 18 and the hopper's N = 31.
//!
//! Timing method as in `benches/cem.rs`: a recorded run's costs on the shifted sphere are
//! replayed into a fresh optimizer with the same seed (the search is deterministic given
//! seed and costs), so only `ask` and `tell` are inside the clock; median over repetitions.

use std::hint::black_box;
use std::time::Instant;

use ctrl_adapt::optimizer::{Bounds, Cmaes, CmaesConfig, Optimizer, Vector};
use host_tests::functions::sphere;
use host_tests::run;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const SEED: u64 = 1;
const REPETITIONS: usize = 9;
const MIN_PAIRS_PER_REPETITION: usize = 20_000;

fn bench<const N: usize, const L: usize>(eigen_interval: u32) {
    let make = || {
        Cmaes::<N, L>::try_new(
            Bounds::uniform(-1.0, 1.0).expect("valid box"),
            Vector::zeros(),
            CmaesConfig {
                initial_sigma: 0.3,
                eigen_interval,
                ..CmaesConfig::DEFAULT
            },
        )
        .expect("valid config")
    };
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(SEED);
    let costs = run(
        &mut make(),
        &mut rng,
        100 * N,
        |t, _| sphere(t, 0.2),
        |_, _, _| {},
    )
    .expect("a clean run")
    .costs;
    let replays = MIN_PAIRS_PER_REPETITION.div_ceil(costs.len());
    let mut per_pair_ns: Vec<f64> = (0..REPETITIONS)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..replays {
                let mut s = black_box(make());
                let mut rng = Xoshiro128PlusPlus::seed_from_u64(SEED);
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
        "| {N} | {L} | {eigen_interval} | {:.0} | {:.0} | {} |",
        per_pair_ns[REPETITIONS / 2],
        per_pair_ns[0],
        std::mem::size_of::<Cmaes<N, L>>(),
    );
}

fn main() {
    println!(
        "host: {} {}\n",
        std::env::consts::ARCH,
        std::env::consts::OS
    );
    println!("| N | λ | eigen interval | ns/ask+tell (median) | (min) | size_of (B) |");
    println!("|---:|---:|---:|---:|---:|---:|");
    bench::<18, 10>(1);
    bench::<18, 12>(1);
    bench::<31, 14>(1);
    bench::<31, 14>(7);
}
