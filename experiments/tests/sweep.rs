//! The sweep: algorithm × plant, episodes to threshold and final cost, median over
//! 10 seeds, printed as a markdown table (the one in findings/sweep.md). Every run goes
//! through the library's `Adapter` with the task's controller and shaper; only the optimizer
//! changes. Release only (compiled out of debug test builds):
//!
//! ```text
//! cargo test --release -p experiments --test sweep -- --nocapture
//! ```
//!
//! * **AUV**: 300 episodes on the "real" plant (0.6 m/s current, disturbances seeded by the
//!   seed), from W = 0 where the algorithm has a start; threshold J > −1 (within D = 1 m);
//!   final = the best J told.
//! * **Hopper**: 200 episodes on the seed's training course (seed 1000 + s, replayed every
//!   episode), from the zero correction where the algorithm has a start; threshold cost
//!   ≤ 3·10⁻⁴ (r.m.s. apex deviation ≈ 1.7 cm; the initial policy's is ≈ 1.5·10⁻³); final =
//!   the best cost told, and the apex spread of the best θ on a course never learned on
//!   (seed 20 000 + s).
//!
//! To add an algorithm: one `entry(..)` line per plant in `sweep_table`, with a closure that
//! builds the optimizer for a seed.

#![cfg(not(debug_assertions))]

use ctrl_adapt::optimizer::{
    CemConfig, ControlledRandomSearch, CrsConfig, DiagonalCem, Optimizer, Rockstar, RockstarConfig,
    Sracos, SracosConfig, TwoPhase, Vector, Weighting,
};
use host_tests::auv::AuvConfig;
use host_tests::median;
use host_tests::{auv_task, hopper_task};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const SEEDS: std::ops::RangeInclusive<u64> = 1..=10;
const AUV_BUDGET: u32 = 300;
const HOPPER_BUDGET: u32 = 200;
const HOPPER_THRESHOLD: f32 = 3e-4;

/// One seed's outcome.
#[derive(Debug, Clone, Copy)]
struct Outcome {
    /// First episode (1-based) at the threshold, if reached.
    first: Option<usize>,
    /// Final figure (AUV: best J; hopper: best cost).
    last: f64,
    /// Hopper: apex spread (cm) of the best θ on an unseen course.
    spread: Option<f64>,
}

fn auv_run<O: Optimizer<18>>(optimizer: O, seed: u64) -> Outcome {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut real = auv_task::plant(AuvConfig::REAL, seed);
    let mut adapter = auv_task::adapter(optimizer, AUV_BUDGET, Vector::zeros()).unwrap();
    let episodes = auv_task::run_episodes(
        &mut adapter,
        &mut real,
        &mut rng,
        AUV_BUDGET as usize,
        |_| {},
    )
    .unwrap();
    Outcome {
        first: auv_task::episodes_to_success(&episodes),
        last: f64::from(*auv_task::best_so_far(&episodes).last().unwrap()),
        spread: None,
    }
}

fn hopper_run<O: Optimizer<31>>(optimizer: O, seed: u64) -> Outcome {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut adapter = hopper_task::adapter(optimizer, HOPPER_BUDGET, Vector::zeros()).unwrap();
    let mut first = None;
    for k in 0..HOPPER_BUDGET as usize {
        let mut course = hopper_task::plant(true, 1000 + seed);
        let e = hopper_task::run_episode(&mut adapter, &mut course, &mut rng, false).unwrap();
        if first.is_none() && e.report.told.is_some_and(|c| c <= HOPPER_THRESHOLD) {
            first = Some(k + 1);
        }
    }
    let best = adapter.optimizer().best().unwrap();
    let unseen = hopper_task::evaluate(
        best.theta,
        &mut hopper_task::plant(true, 20_000 + seed),
        &mut rng,
        false,
    )
    .unwrap();
    Outcome {
        first,
        last: f64::from(best.cost),
        spread: Some(if unseen.hops_stably() {
            unseen.apex_spread() * 100.0
        } else {
            f64::NAN
        }),
    }
}

/// Runs `run(seed)` for every seed on two threads (the machine's cores).
fn over_seeds(run: impl Fn(u64) -> Outcome + Sync) -> Vec<Outcome> {
    let seeds: Vec<u64> = SEEDS.collect();
    let (even, odd): (Vec<_>, Vec<_>) = seeds.iter().partition(|s| *s % 2 == 0);
    let run = &run;
    let (a, b) = std::thread::scope(|scope| {
        let h = scope.spawn(move || even.iter().map(|s| (*s, run(*s))).collect::<Vec<_>>());
        let b: Vec<_> = odd.iter().map(|s| (*s, run(*s))).collect();
        (h.join().unwrap(), b)
    });
    let mut all: Vec<(u64, Outcome)> = a.into_iter().chain(b).collect();
    all.sort_by_key(|(s, _)| *s);
    all.into_iter().map(|(_, o)| o).collect()
}

/// One table row.
struct Row {
    plant: &'static str,
    algorithm: &'static str,
    outcomes: Vec<Outcome>,
    budget: u32,
}

impl Row {
    fn print(&self) {
        let reached = self.outcomes.iter().filter(|o| o.first.is_some()).count();
        // A run that never reached the threshold counts as +∞ in the median.
        let firsts: Vec<f64> = self
            .outcomes
            .iter()
            .map(|o| o.first.map_or(f64::INFINITY, |k| k as f64))
            .collect();
        let m = median(firsts.clone());
        let finite: Vec<f64> = firsts.iter().copied().filter(|v| v.is_finite()).collect();
        let range = if finite.is_empty() {
            "–".to_string()
        } else {
            let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            format!("{lo}–{hi}")
        };
        let median_first = if m.is_finite() {
            format!("{m}")
        } else {
            format!("> {}", self.budget)
        };
        let last = median(self.outcomes.iter().map(|o| o.last).collect());
        let spread = self
            .outcomes
            .iter()
            .map(|o| o.spread)
            .collect::<Option<Vec<f64>>>()
            .map_or("".to_string(), |v| {
                let unstable = v.iter().filter(|s| s.is_nan()).count();
                let stable: Vec<f64> = v.into_iter().filter(|s| !s.is_nan()).collect();
                let m = if stable.is_empty() {
                    "–".to_string()
                } else {
                    format!("{:.1}", median(stable))
                };
                if unstable > 0 {
                    format!("{m} ({unstable} off the gait)")
                } else {
                    m
                }
            });
        let last = if self.plant == "AUV" {
            format!("J {last:.2}")
        } else {
            format!("{last:.2e}")
        };
        println!(
            "| {} | {} | {reached}/{} | {median_first} | {range} | {last} | {spread} |",
            self.plant,
            self.algorithm,
            self.outcomes.len()
        );
    }
}

fn auv_entry<O: Optimizer<18>>(algorithm: &'static str, make: impl Fn(u64) -> O + Sync) -> Row {
    Row {
        plant: "AUV",
        algorithm,
        outcomes: over_seeds(|s| auv_run(make(s), s)),
        budget: AUV_BUDGET,
    }
}

fn hopper_entry<O: Optimizer<31>>(algorithm: &'static str, make: impl Fn(u64) -> O + Sync) -> Row {
    Row {
        plant: "hopper",
        algorithm,
        outcomes: over_seeds(|s| hopper_run(make(s), s)),
        budget: HOPPER_BUDGET,
    }
}

/// CMA-ES-weighted diagonal CEM: 10 samples per update (the first the mean), the best 5
/// weighted, initial σ per coordinate `sigma`, σ at most `max_sigma`, floor 1e-4 σ².
fn cem_config(max_sigma: f32, budget: u32) -> CemConfig {
    CemConfig {
        weighting: Weighting::CmaEs,
        initial_variance: 1e-2,
        exploration_floor: 1e-6,
        max_variance: max_sigma * max_sigma,
        max_evaluations: budget,
        ..CemConfig::DEFAULT
    }
}

fn sweep_table() -> Vec<Row> {
    let auv_bounds = auv_task::bounds();
    let hop_bounds = hopper_task::bounds();
    let crs = |budget| CrsConfig {
        max_evaluations: budget,
        ..CrsConfig::DEFAULT
    };
    let sracos = |budget| SracosConfig {
        max_evaluations: budget,
        ..SracosConfig::DEFAULT
    };
    vec![
        auv_entry("coordinate search (step 0.25)", |_| {
            auv_task::coordinate_search(Vector::zeros(), AUV_BUDGET).unwrap()
        }),
        auv_entry("CRS (m = 100)", |_| {
            auv_task::global_search(AUV_BUDGET).unwrap()
        }),
        auv_entry("two-phase: CRS 150, then coordinate search", |_| {
            TwoPhase::try_new(
                auv_task::global_search(150).unwrap(),
                150,
                auv_task::local_config(AUV_BUDGET - 150),
            )
            .unwrap()
        }),
        auv_entry("SRACOS (K = 2, M = 10, ZOOpt defaults)", |_| {
            Sracos::<18>::try_new(auv_bounds, sracos(AUV_BUDGET)).unwrap()
        }),
        auv_entry("two-phase: SRACOS 150, then coordinate search", |_| {
            TwoPhase::try_new(
                Sracos::<18>::try_new(auv_bounds, sracos(150)).unwrap(),
                150,
                auv_task::local_config(AUV_BUDGET - 150),
            )
            .unwrap()
        }),
        auv_entry("DiagonalCem (CMA-ES weights, K = 10, σ₀ = 0.25)", |_| {
            DiagonalCem::<18, 10, 5>::try_with_variances(
                auv_bounds,
                Vector::zeros(),
                Vector::repeat(0.25 * 0.25),
                cem_config(0.5, AUV_BUDGET),
            )
            .unwrap()
        }),
        auv_entry("ROCK* (M = 5n, σ₀ = 0.25)", |_| {
            Rockstar::<18, 90>::try_new(
                auv_bounds,
                Vector::zeros(),
                rockstar(0.25 / auv_task::W_BOUND, AUV_BUDGET),
            )
            .unwrap()
        }),
        hopper_entry("coordinate search (steps = half-range / 6)", |_| {
            hopper_task::coordinate_search(Vector::zeros(), HOPPER_BUDGET).unwrap()
        }),
        hopper_entry("CRS (m = 64)", |_| {
            ControlledRandomSearch::<31, 64>::try_new(hop_bounds, crs(HOPPER_BUDGET)).unwrap()
        }),
        hopper_entry("two-phase: CRS 100, then coordinate search", |_| {
            TwoPhase::try_with_steps(
                ControlledRandomSearch::<31, 64>::try_new(hop_bounds, crs(100)).unwrap(),
                100,
                hopper_task::local_steps(),
                ctrl_adapt::optimizer::CoordinateConfig {
                    tolerance: 1e-3,
                    max_evaluations: HOPPER_BUDGET - 100,
                    ..Default::default()
                },
            )
            .unwrap()
        }),
        hopper_entry("SRACOS (K = 2, M = 10, ZOOpt defaults)", |_| {
            Sracos::<31>::try_new(hop_bounds, sracos(HOPPER_BUDGET)).unwrap()
        }),
        hopper_entry(
            "DiagonalCem (CMA-ES weights, K = 10, σ₀ = half-range / 6)",
            |_| {
                let sigma = hopper_task::local_steps();
                DiagonalCem::<31, 10, 5>::try_with_variances(
                    hop_bounds,
                    Vector::zeros(),
                    sigma.component_mul(&sigma),
                    cem_config(28.0, HOPPER_BUDGET),
                )
                .unwrap()
            },
        ),
        hopper_entry("ROCK* (M = 5n, σ₀ = half-range / 6)", |_| {
            Rockstar::<31, 155>::try_new(
                hop_bounds,
                Vector::zeros(),
                rockstar(1.0 / 6.0, HOPPER_BUDGET),
            )
            .unwrap()
        }),
    ]
}

/// ROCK* with the authors' defaults, σ₀ in half-widths of the box (the exploration of the
/// diagonal CEM's rows) and the budget.
fn rockstar(initial_sigma: f32, budget: u32) -> RockstarConfig {
    RockstarConfig {
        initial_sigma,
        max_evaluations: budget,
        ..RockstarConfig::DEFAULT
    }
}

/// Prints the sweep table and checks that every algorithm ran its budget to a finite final
/// figure no worse than the start's (AUV: the bare PD's J ≈ −3.2; hopper: the initial
/// policy's cost ≈ 1.5·10⁻³), and that the coordinate search, the paper's local method,
/// reaches the AUV threshold on every seed.
#[test]
fn sweep() {
    let rows = sweep_table();
    println!(
        "| plant | algorithm | reached | episodes to threshold (median) | (min–max) | final (median) | apex spread on an unseen course, cm (median) |"
    );
    println!("| --- | --- | ---: | ---: | ---: | ---: | ---: |");
    for row in &rows {
        row.print();
    }
    for row in &rows {
        for o in &row.outcomes {
            assert!(o.last.is_finite(), "{}: {o:?}", row.algorithm);
            if row.plant == "AUV" {
                assert!(o.last > -3.5, "{}: {o:?}", row.algorithm);
            } else {
                assert!(o.last < 3e-3, "{}: {o:?}", row.algorithm);
            }
        }
    }
    let cs = &rows[0];
    assert!(cs.outcomes.iter().all(|o| o.first.is_some()));
}
