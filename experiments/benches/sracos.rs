//! SRACOS against batch RACOS and uniform random search on the SRACOS paper's synthetic
//! set-up, in the paper's table format, plus the optimizers' own cost on the host. Prints;
//! asserts nothing (shared, noisy machines). Run with
//! `cargo bench -p experiments --bench sracos`; compare with `scripts/zoopt_compare.py`.
//!
//! * Quality: Sphere and Ackley shifted to 0.2 on [−1, 1]^n, budget 20n, mean ± (population)
//!   std of the best value over 15 seeded runs (seeds 1..=15), n ∈ {10, 100, 1000}; set sizes
//!   are ZOOpt's for the budget, (k, m) = (2, 10) at 200 evaluations and (2, 20) above 1000.
//! * Overhead: time per ask+tell pair with the objective excluded. One run records its cost
//!   sequence; the timed loop replays it into fresh optimizers with the same seed, which
//!   retraces the same candidates, so only `ask` and `tell` are inside the clock. Median
//!   over repetitions.
//! * `size_of` the optimizer state.

use ctrl_adapt::optimizer::sracos::zoopt_set_sizes;
use ctrl_adapt::optimizer::{Bounds, Optimizer, Racos, Sracos, SracosConfig, Status, Vector};
use experiments::overhead::replay;
use host_tests::functions::{ackley, sphere};
use host_tests::{random_search, run};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const SEEDS: u64 = 15;
const REPETITIONS: usize = 11;
const MIN_PAIRS_PER_REPETITION: usize = 100_000;

fn sracos<const N: usize, const K: usize, const M: usize>() -> Sracos<N, K, M> {
    let config = SracosConfig {
        max_evaluations: 20 * N as u32,
        ..SracosConfig::DEFAULT
    };
    Sracos::try_new(Bounds::uniform(-1.0, 1.0).expect("valid box"), config).expect("valid")
}

fn racos<const N: usize, const K: usize, const M: usize>() -> Racos<N, K, M> {
    let config = SracosConfig {
        max_evaluations: 20 * N as u32,
        ..SracosConfig::DEFAULT
    };
    Racos::try_new(Bounds::uniform(-1.0, 1.0).expect("valid box"), config).expect("valid")
}

/// `mean ± std` of `values`.
fn summary(values: &[f64]) -> String {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    format!("{mean:.4} ± {:.4}", var.sqrt())
}

/// Best values over the seeds of the optimizer `make` builds.
fn bests<const N: usize, O: Optimizer<N>>(make: fn() -> O, f: fn(&Vector<N>) -> f32) -> Vec<f64> {
    (1..=SEEDS)
        .map(|seed| {
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            let r = run(&mut make(), &mut rng, usize::MAX, |t, _| f(t), |_, _, _| {})
                .expect("a clean run");
            assert_eq!(r.status, Status::BudgetSpent);
            f64::from(r.best_cost())
        })
        .collect()
}

/// Median and minimum ns per ask+tell of the optimizer `make` builds, replaying the costs
/// of one seeded run on `f`.
fn overhead<const N: usize, O: Optimizer<N>>(
    make: fn() -> O,
    f: fn(&Vector<N>) -> f32,
) -> (f64, f64) {
    let o = replay(make, f, usize::MAX, REPETITIONS, MIN_PAIRS_PER_REPETITION);
    (o.median_ns, o.min_ns)
}

fn sphere02<const N: usize>(t: &Vector<N>) -> f32 {
    sphere(t, 0.2)
}

fn ackley02<const N: usize>(t: &Vector<N>) -> f32 {
    ackley(t, 0.2)
}

fn quality<const N: usize, const K: usize, const M: usize>() {
    assert_eq!(zoopt_set_sizes(20 * N as u32), (K, M));
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
    for (name, f) in [
        ("Sphere", sphere02::<N> as fn(&Vector<N>) -> f32),
        ("Ackley", ackley02::<N>),
    ] {
        let random: Vec<f64> = (1..=SEEDS)
            .map(|seed| {
                let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
                f64::from(random_search(&bounds, 20 * N, &mut rng, f))
            })
            .collect();
        println!(
            "| {name} | {N} | {} | ({K}, {M}) | {} | {} | {} |",
            20 * N,
            summary(&bests(sracos::<N, K, M>, f)),
            summary(&bests(racos::<N, K, M>, f)),
            summary(&random),
        );
    }
}

fn cost<const N: usize, const K: usize, const M: usize>() {
    let (s, s_min) = overhead(sracos::<N, K, M>, sphere02::<N>);
    let (r, r_min) = overhead(racos::<N, K, M>, sphere02::<N>);
    println!(
        "| {N} | ({K}, {M}) | {s:.0} ({s_min:.0}) | {r:.0} ({r_min:.0}) | {} | {} |",
        size_of::<Sracos<N, K, M>>(),
        size_of::<Racos<N, K, M>>(),
    );
}

fn main() {
    println!("host: {} {}", std::env::consts::ARCH, std::env::consts::OS);
    println!();
    println!("Best value after 20n evaluations, mean ± std over {SEEDS} seeds:");
    println!("| function | n | budget | (k, m) | SRACOS | RACOS | random search |");
    println!("|---|---:|---:|---|---:|---:|---:|");
    quality::<10, 2, 10>();
    quality::<100, 2, 20>();
    quality::<1000, 2, 20>();
    println!();
    println!("Optimizer cost on the host (objective excluded), ns per ask+tell, median (min):");
    println!("| n | (k, m) | SRACOS ns | RACOS ns | size_of SRACOS (B) | size_of RACOS (B) |");
    println!("|---:|---|---:|---:|---:|---:|");
    cost::<18, 2, 10>();
    cost::<10, 2, 10>();
    cost::<100, 2, 20>();
    cost::<1000, 2, 20>();
}
