//! The library's `model::ModelBased` on the hopping leg and on the via-point arm, beside its
//! inner optimizer (CMA-ES) and its fallback (coordinate search) alone: successes, episodes
//! to success, best cost, unsafe episodes and the episodes that fell back to the model-free
//! step. Nothing here was tuned: the learner keeps the AUV's settings
//! (`model_learner_auv`: trust radius 0.15 in [0.05, 1], ×1.5 / ×0.6, screen at 1.2 × the
//! bare cost), in normalised units (θ = u ⊙ scale, u ∈ [−1, 1]^P: the hopper's box, the
//! arm's unit below), with 3 exploration episodes of ±0.05 after the bare one. The loop,
//! the models and their imagined episodes are `experiments::model_learner`'s, the episodes
//! those of the oracle's trials (`experiments::peers::Trial`): this is the oracle's `model`
//! method with 60 episodes.
//!
//! ```text
//! cargo run --release -p experiments --example model_learner_tasks -- hopper 1 10
//! cargo run --release -p experiments --example model_learner_tasks -- arm 1 10
//! cargo run --release -p experiments --example model_learner_tasks -- hopper 1 10 CMA-ES  # one row
//! ```
//!
//! **Hopper** (`host_tests::hopper_task`: the 31-parameter periodic PD, the apex cost, each
//! seed's training course 1000 + s replayed every episode, as in `guard_hopper`), 60 real
//! episodes per seed. Model (`model_learner::HopperModel`): `RlsModel<6, 2, 9>` (affine)
//! of [knee, hip, knee rate, hip rate, body height, body velocity] and the two torques, fitted on every 1 kHz tick; the
//! imagined episode runs the same `PeriodicPd` on the first four and feeds `ApexHeightCost`
//! the predicted body height and velocity (power from the command and the joint rates; no
//! limit flag), 12,000 ticks. Inner `Cmaes<31, 14>`, 60 imagined episodes per proposal.
//! Fallback: the coordinate search of `hopper_task` (steps a sixth of the box). Unsafe:
//! cost above 1.2 × the bare episode's or a collapse; success: cost ≤ 3·10⁻⁴ (the sweep's).
//!
//! **Arm** (`host_tests::arm`, the 10-link via-point arm of Stulp & Sigaud 2012, 50 DMP
//! weights, deterministic), 60 real episodes per seed from the minimum-jerk θ₀. Model
//! (`model_learner::ArmModel`):
//! `RlsModel<20, 10, 31>` (affine) of the joint angles and the DMP's scaled velocities
//! [y, z] with the 10 forcing terms as the command, fitted on every 1 ms tick; the imagined
//! episode integrates it with the forcing of θ and scores the via-point distance at 0.3 s
//! and the weighted accelerations as `host_tests::arm` does. Unit: θ = θ₀ + 100·u (100 is
//! the standard deviation of the CEM exploration of the via-point study), box
//! u ∈ [−100, 100]^50. Inner `Cmaes<50, 14>`, 240 imagined episodes. Fallback: coordinate
//! search, step 0.25 units. Unsafe: cost above 1.2 × θ₀'s; success: cost below 1 % of
//! θ₀'s. The seed drives the optimizers' RNG (the arm has no noise).

use ctrl_adapt::optimizer::{
    Bounds, Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch, Optimizer, Vector,
};
use experiments::model_learner::{ARM_UNIT, arm_bounds, run_on_trial};
use experiments::peers::{Task, Trial};
use host_tests::arm::{PARAMS, ViaPointArm};
use host_tests::hopper_task::{self, P as HP};
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const EPISODES: usize = 60;

/// What a learning run did: per real episode its cost, its source ('b' bare, 'e'
/// exploration, 'm' model, 'f' fallback or the optimizer alone) and whether it was unsafe.
struct Run {
    /// The bare controller's (θ₀'s) cost: the reference of "unsafe" and of the ratio.
    bare: f32,
    costs: Vec<f32>,
    source: Vec<char>,
    unsafe_: Vec<bool>,
}

/// The learner on the task's trial of seed `seed` (`experiments::model_learner`, the
/// oracle's `model` method), RNG seeded by `seed`. Unsafe: a cost above 1.2 × the bare
/// episode's (a collapse of the leg costs 1, far above it).
fn model_based(task: Task, seed: u64) -> Run {
    let (run, _) = run_on_trial(&mut Trial::new(task, seed), EPISODES as u32, seed)
        .expect("a robot task and a finite bare cost");
    let bare = run.costs[0];
    Run {
        bare,
        source: run.origin.iter().map(|o| o.letter()).collect(),
        unsafe_: run.costs.iter().map(|c| *c > 1.2 * bare).collect(),
        costs: run.costs,
    }
}

// ---------------------------------------------------------------------------------------
// The hopper.

/// An optimizer alone started at the bare θ (the episode is deterministic: the bare cost,
/// the reference, is measured once more outside the budget).
fn hopper_alone<O: Optimizer<HP>>(seed: u64, mut optimizer: O) -> Run {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut trial = Trial::new(Task::Hopper, seed);
    let bare = trial.start_cost().expect("the bare episode");
    let mut run = Run {
        bare,
        costs: Vec::new(),
        source: Vec::new(),
        unsafe_: Vec::new(),
    };
    while run.costs.len() < EPISODES {
        let Ok(theta) = optimizer.ask(&mut rng) else {
            break;
        };
        // A collapse costs 1, far above 1.2 × the bare cost.
        let c = trial.score(theta.as_slice()).expect("31 finite numbers");
        optimizer.tell(c).unwrap();
        run.unsafe_.push(c > 1.2 * bare);
        run.source.push(if theta == Vector::<HP>::zeros() {
            'b'
        } else {
            'f'
        });
        run.costs.push(c);
    }
    run
}

// ---------------------------------------------------------------------------------------
// The arm.

/// An optimizer alone on u, started at 0 (θ₀; the arm is deterministic: θ₀'s cost, the
/// reference, is measured once more outside the budget).
fn arm_alone<O: Optimizer<PARAMS>>(seed: u64, mut optimizer: O) -> Run {
    let arm_ = ViaPointArm::new();
    let theta0 = arm_.minimum_jerk_theta();
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let bare = arm_.cost(&theta0);
    let mut run = Run {
        bare,
        costs: Vec::new(),
        source: Vec::new(),
        unsafe_: Vec::new(),
    };
    while run.costs.len() < EPISODES {
        let Ok(u) = optimizer.ask(&mut rng) else {
            break;
        };
        let c = arm_.cost(&(theta0 + u * ARM_UNIT));
        optimizer.tell(c).unwrap();
        run.unsafe_.push(c > 1.2 * bare);
        run.source.push(if u == Vector::<PARAMS>::zeros() {
            'b'
        } else {
            'f'
        });
        run.costs.push(c);
    }
    run
}

fn arm_study(seeds: &[u64]) {
    println!(
        "arm, seeds {seeds:?}, {EPISODES} real episodes per seed; success: cost below 1 % of θ₀'s"
    );
    header();
    let success = |r: &Run, c: f32| c < 0.01 * r.bare;
    report(
        "`ModelBased` (inner CMA-ES, fallback coordinate search)",
        seeds,
        |s| model_based(Task::Arm, s),
        success,
    );
    let theta0 = ViaPointArm::new().minimum_jerk_theta();
    report(
        "coordinate search alone (step 0.25 units)",
        seeds,
        |s| {
            let config = CoordinateConfig {
                initial_step: 0.25,
                tolerance: 1e-3,
                max_evaluations: EPISODES as u32,
                ..CoordinateConfig::DEFAULT
            };
            let unit = arm_bounds(&theta0);
            arm_alone(
                s,
                CoordinateSearch::try_new(unit, Vector::zeros(), config).unwrap(),
            )
        },
        success,
    );
    report(
        "CMA-ES alone (λ = 14, σ₀ one unit)",
        seeds,
        |s| {
            // σ₀ one unit (100): the via-point study's exploration.
            let config = CmaesConfig {
                initial_sigma: 0.01,
                max_evaluations: EPISODES as u32,
                ..CmaesConfig::DEFAULT
            };
            let b = Bounds::<PARAMS>::uniform(-100.0, 100.0).unwrap();
            arm_alone(
                s,
                Cmaes::<PARAMS, 14>::try_new(b, Vector::zeros(), config).unwrap(),
            )
        },
        success,
    );
}

// ---------------------------------------------------------------------------------------
// Reporting.

fn summary(name: &str, runs: &[Run], success: impl Fn(&Run, f32) -> bool) {
    let first: Vec<Option<usize>> = runs
        .iter()
        .map(|r| r.costs.iter().position(|c| success(r, *c)).map(|k| k + 1))
        .collect();
    let reached = first.iter().flatten().count();
    let med = median(
        first
            .iter()
            .map(|f| f.unwrap_or(EPISODES + 1) as f64)
            .collect(),
    );
    let best: Vec<f64> = runs
        .iter()
        .map(|r| f64::from(r.costs.iter().copied().fold(f32::INFINITY, f32::min)))
        .collect();
    let bare: Vec<f64> = runs.iter().map(|r| f64::from(r.bare)).collect();
    let ratio = median(best.iter().zip(&bare).map(|(b, c)| b / c).collect());
    let count = |kind: char| -> usize {
        runs.iter()
            .map(|r| {
                r.source
                    .iter()
                    .zip(&r.unsafe_)
                    .filter(|(s, u)| **s == kind && **u)
                    .count()
            })
            .sum()
    };
    let unsafe_total: usize = runs
        .iter()
        .map(|r| r.unsafe_.iter().filter(|u| **u).count())
        .sum();
    let fell_back: usize = runs
        .iter()
        .map(|r| r.source.iter().filter(|s| **s == 'f').count())
        .sum();
    let from_model: usize = runs
        .iter()
        .map(|r| r.source.iter().filter(|s| **s == 'm').count())
        .sum();
    let per_seed: Vec<String> = first
        .iter()
        .map(|f| f.map_or("–".to_string(), |k| k.to_string()))
        .collect();
    println!(
        "| {name} | {reached}/{} | {med} | {:.3e} | {ratio:.2e} | {unsafe_total} (bare {}, explore {}, model {}, fallback/alone {}) | {from_model} | {fell_back} | {} |",
        runs.len(),
        median(best.clone()),
        count('b'),
        count('e'),
        count('m'),
        count('f'),
        per_seed.join(" ")
    );
}

fn header() {
    println!(
        "| learner | successes | median episodes to success | median best cost | median best / bare | unsafe episodes | episodes chosen by the model | fallback episodes (model-based) / optimizer episodes | first success per seed |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | --- | ---: | ---: | --- |");
}

fn hopper_study(seeds: &[u64]) {
    println!("hopper, seeds {seeds:?}, {EPISODES} real episodes per seed; success: cost ≤ 3e-4");
    header();
    let success = |_: &Run, c: f32| c <= 3e-4;
    report(
        "`ModelBased` (inner CMA-ES, fallback coordinate search)",
        seeds,
        |s| model_based(Task::Hopper, s),
        success,
    );
    report(
        "coordinate search alone",
        seeds,
        |s| {
            let search = hopper_task::coordinate_search(Vector::zeros(), EPISODES as u32);
            hopper_alone(s, search.unwrap())
        },
        success,
    );
    report(
        "CMA-ES alone (λ = 14, default σ₀ 0.3 of the box)",
        seeds,
        |s| {
            let config = CmaesConfig {
                max_evaluations: EPISODES as u32,
                ..CmaesConfig::DEFAULT
            };
            let b = hopper_task::bounds();
            hopper_alone(
                s,
                Cmaes::<HP, 14>::try_new(b, Vector::zeros(), config).unwrap(),
            )
        },
        success,
    );
}

/// One row: `run` on every seed, if the row is selected.
fn report(
    name: &str,
    seeds: &[u64],
    run: impl Fn(u64) -> Run,
    success: impl Fn(&Run, f32) -> bool,
) {
    if !row(name) {
        return;
    }
    let runs: Vec<Run> = seeds.iter().map(|&s| run(s)).collect();
    summary(name, &runs, success);
}

/// Only the rows whose name contains this (the 4th argument; all by default).
static ROWS: std::sync::OnceLock<String> = std::sync::OnceLock::new();

fn row(name: &str) -> bool {
    ROWS.get().is_none_or(|r| name.contains(r.as_str()))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let task = args.first().map_or("hopper", String::as_str).to_string();
    let from: u64 = args.get(1).map_or(1, |a| a.parse().expect("seed"));
    let to: u64 = args.get(2).map_or(10, |a| a.parse().expect("seed"));
    let seeds: Vec<u64> = (from..=to).collect();
    ROWS.set(args.get(3).cloned().unwrap_or_default()).unwrap();
    match task.as_str() {
        "hopper" => hopper_study(&seeds),
        "arm" => arm_study(&seeds),
        other => panic!("unknown task {other}"),
    }
}
