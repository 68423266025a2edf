//! `DiagonalCem` figures, printed as Markdown tables (asserts nothing; run with
//! `cargo bench -p experiments --bench cem`):
//!
//! 1. learning curves on the via-point arm task (Stulp & Sigaud 2012, section 3.1): the
//!    noise-free cost per update for each weighting and initial exploration λ_init, with and
//!    without covariance adaptation, K = 10, mean over 5 seeds;
//! 2. the shifted Sphere and Ackley functions on [−1, 1]^n (minimiser 0.2·1), budget 20n
//!    evaluations, n ∈ {10, 100}: best cost, mean ± standard deviation over 15 seeds, for each
//!    weighting with the default configuration, uniform random search as a baseline, and
//!    two ablations of the defaults;
//! 3. host time per ask+tell pair (the objective excluded) and `size_of` the optimizer.
//!
//! Timing method: `experiments::overhead::replay` (a recorded run's costs replayed with the
//! same seed, only `ask` and `tell` inside the clock; median over repetitions).

use ctrl_adapt::optimizer::{Bounds, CemConfig, DiagonalCem, Optimizer, Vector, Weighting};
use experiments::overhead::replay;
use host_tests::arm::{self, ViaPointArm};
use host_tests::functions::{ackley, sphere};
use host_tests::run;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const WEIGHTINGS: [(&str, Weighting); 3] = [
    ("CEM", Weighting::Cem),
    ("CMA-ES", Weighting::CmaEs),
    ("PI-BB", Weighting::PiBb { h: 10.0 }),
];

/// K = 10 with E = K/2 for the rank-based weightings (only the elite is weighted) and E = K
/// for PI-BB (every sample is).
fn learn_k10(
    arm: &ViaPointArm,
    weighting: Weighting,
    config: CemConfig,
    updates: u32,
    seed: u64,
) -> arm::Session {
    let config = CemConfig {
        weighting,
        ..config
    };
    match weighting {
        Weighting::PiBb { .. } => arm::learn::<10, 10>(arm, config, updates, seed),
        _ => arm::learn::<10, 5>(arm, config, updates, seed),
    }
    .expect("a valid configuration")
}

fn learning_curves() {
    const UPDATES: u32 = 200;
    const SEEDS: u64 = 5;
    const SHOWN: [usize; 7] = [0, 10, 20, 50, 100, 150, 200];
    let arm = ViaPointArm::new();
    println!("## Via-point arm: noise-free cost per update (K = 10, mean over {SEEDS} seeds)\n");
    print!("| weighting | Σ | λ_init |");
    for u in SHOWN {
        print!(" u = {u} |");
    }
    println!(" final λ |");
    println!("|---|---|---:|{}---:|", "---:|".repeat(SHOWN.len()));
    for (name, weighting) in WEIGHTINGS {
        for adapt in [false, true] {
            for lambda in [1e2f32, 1e4, 1e6] {
                let config = CemConfig {
                    initial_variance: lambda,
                    adapt_covariance: adapt,
                    exploration_floor: 1e2,
                    ..CemConfig::DEFAULT
                };
                let sessions: Vec<_> = (0..SEEDS)
                    .map(|seed| learn_k10(&arm, weighting, config, UPDATES, seed))
                    .collect();
                let mean_at = |u: usize| {
                    sessions.iter().map(|s| f64::from(s.curve[u])).sum::<f64>() / SEEDS as f64
                };
                let lambda_final = sessions
                    .iter()
                    .map(|s| f64::from(s.final_exploration()))
                    .sum::<f64>()
                    / SEEDS as f64;
                print!(
                    "| {name} | {} | {lambda:.0e} |",
                    if adapt { "adapted" } else { "fixed" }
                );
                for u in SHOWN {
                    print!(" {:.2e} |", mean_at(u));
                }
                println!(" {lambda_final:.0} |");
            }
        }
    }
    println!();
}

/// Best cost of each of 15 seeded runs of `optimizer(seed)` on `f` shifted to 0.2·1.
fn best_costs<const N: usize, O: Optimizer<N>>(
    make: impl Fn() -> O,
    f: fn(&Vector<N>, f64) -> f32,
) -> Vec<f64> {
    (0..15u64)
        .map(|seed| {
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            let result = run(
                &mut make(),
                &mut rng,
                20 * N,
                |t, _| f(t, 0.2),
                |_, _, _| {},
            )
            .expect("a clean run");
            f64::from(result.best_cost())
        })
        .collect()
}

/// Uniform random search over the box, `budget` evaluations: the baseline.
fn random_search<const N: usize>(f: fn(&Vector<N>, f64) -> f32) -> Vec<f64> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
    (0..15u64)
        .map(|seed| {
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            (0..20 * N)
                .map(|_| f64::from(f(&bounds.sample_uniform(&mut rng), 0.2)))
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

fn mean_std(values: &[f64]) -> String {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let std = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    format!("{mean:.3e} ± {std:.1e}")
}

fn cem<const N: usize>(weighting: Weighting, config: CemConfig) -> impl Fn() -> CemRun<N> {
    move || {
        let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
        let config = CemConfig {
            weighting,
            ..config
        };
        match weighting {
            Weighting::PiBb { .. } => CemRun::All(
                DiagonalCem::try_new(bounds, Vector::zeros(), config).expect("valid config"),
            ),
            _ => CemRun::Half(
                DiagonalCem::try_new(bounds, Vector::zeros(), config).expect("valid config"),
            ),
        }
    }
}

/// `DiagonalCem<N, 10, 10>` or `<N, 10, 5>` behind one type, for the table.
enum CemRun<const N: usize> {
    All(DiagonalCem<N, 10, 10>),
    Half(DiagonalCem<N, 10, 5>),
}

impl<const N: usize> Optimizer<N> for CemRun<N> {
    ctrl_adapt::forward_optimizer!(All, Half);
}

fn functions_row(label: &str, weighting: Weighting, config: CemConfig) {
    println!(
        "| {label} | {} | {} | {} | {} |",
        mean_std(&best_costs(cem::<10>(weighting, config), sphere)),
        mean_std(&best_costs(cem::<10>(weighting, config), ackley)),
        mean_std(&best_costs(cem::<100>(weighting, config), sphere)),
        mean_std(&best_costs(cem::<100>(weighting, config), ackley)),
    );
}

fn shifted_functions() {
    println!(
        "## Shifted Sphere / Ackley on [−1, 1]^n, budget 20n, best cost (mean ± std, 15 seeds)\n"
    );
    println!("| optimizer | Sphere n = 10 | Ackley n = 10 | Sphere n = 100 | Ackley n = 100 |");
    println!("|---|---:|---:|---:|---:|");
    let defaults = CemConfig::DEFAULT;
    for (name, weighting) in WEIGHTINGS {
        functions_row(
            &format!("DiagonalCem {name}, defaults"),
            weighting,
            defaults,
        );
    }
    let pibb = Weighting::PiBb { h: 10.0 };
    functions_row(
        "DiagonalCem PI-BB, no floor (ε = 0)",
        pibb,
        CemConfig {
            exploration_floor: 0.0,
            ..defaults
        },
    );
    functions_row(
        "DiagonalCem PI-BB, no noise-free sample",
        pibb,
        CemConfig {
            first_is_mean: false,
            ..defaults
        },
    );
    println!(
        "| uniform random search | {} | {} | {} | {} |",
        mean_std(&random_search::<10>(sphere)),
        mean_std(&random_search::<10>(ackley)),
        mean_std(&random_search::<100>(sphere)),
        mean_std(&random_search::<100>(ackley)),
    );
    println!();
}

const REPETITIONS: usize = 31;
const MIN_PAIRS_PER_REPETITION: usize = 200_000;

fn bench_overhead<const N: usize, const E: usize>(name: &str) {
    let make = || {
        let bounds = Bounds::<N>::uniform(-1.0, 1.0).expect("valid box");
        let config = CemConfig {
            weighting: if E == 10 {
                Weighting::PiBb { h: 10.0 }
            } else {
                Weighting::CmaEs
            },
            ..CemConfig::DEFAULT
        };
        DiagonalCem::<N, 10, E>::try_new(bounds, Vector::zeros(), config).expect("valid config")
    };
    let o = replay(
        make,
        |t| sphere(t, 0.2),
        20 * N,
        REPETITIONS,
        MIN_PAIRS_PER_REPETITION,
    );
    println!(
        "| {name} | {N} | 10 | {E} | {:.1} | {:.1} | {} |",
        o.median_ns,
        o.min_ns,
        std::mem::size_of::<DiagonalCem<N, 10, E>>(),
    );
}

fn overhead() {
    println!("## Overhead: host time per ask+tell (objective excluded) and state size\n");
    println!(
        "host: {} {}\n",
        std::env::consts::ARCH,
        std::env::consts::OS
    );
    println!("| weighting | N | K | E | ns/ask+tell (median) | (min) | size_of (B) |");
    println!("|---|---:|---:|---:|---:|---:|---:|");
    bench_overhead::<18, 10>("PI-BB");
    bench_overhead::<18, 5>("CMA-ES");
    bench_overhead::<50, 10>("PI-BB");
    bench_overhead::<50, 5>("CMA-ES");
    println!();
}

fn main() {
    overhead();
    shifted_functions();
    learning_curves();
}
