//! The runtime guard on the hopping leg: learning with and without it, for coordinate
//! search, diagonal CEM and CMA-ES, on each seed's training course (seed 1000 + s, replayed
//! every episode, as in the sweep). Release only:
//!
//! ```text
//! cargo test --release -p experiments --test guard_hopper -- --nocapture --test-threads 1
//! ```
//!
//! `tune` (seeds 101–110) and `report` (seeds 1–10), as in `guard_auv.rs`. Every run: 3 bare
//! episodes (`Mode::Nominal`: the envelope, and the bare controller's cost), then 200
//! learning episodes from the zero correction. The guard has no limit (the leg's state is
//! its joints; the collapse the plant detects already aborts the episode) and an envelope
//! over the whole 12 s episode at 1 kHz (`Guard<0, 12000>`).
//!
//! * **unsafe episode**: executed cost (the apex cost, whatever was told) above 1.2 × the
//!   bare controller's, or a collapse;
//! * **success**: the first learning episode with executed cost ≤ 3·10⁻⁴, untripped (the
//!   sweep's threshold).

#![cfg(not(debug_assertions))]

use ctrl_adapt::controller::Mode;
use ctrl_adapt::controller::guard::{Guard, GuardConfig, Supervisor};
use ctrl_adapt::optimizer::{
    CemConfig, Cmaes, CmaesConfig, DiagonalCem, Optimizer, Vector, Weighting,
};
use host_tests::hopper_task::{self, HopperAdapter, P};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const BUDGET: u32 = 200;
const BARE_EPISODES: usize = 3;
const TICKS: usize = 12_000;
const THRESHOLD: f32 = 3e-4;
const UNSAFE_RATIO: f32 = 1.2;

#[derive(Debug, Clone, Copy)]
struct Setting {
    relative_margin: f32,
    absolute_margin: f32,
}

#[derive(Debug, Clone, Copy, Default)]
struct Outcome {
    unsafe_episodes: u32,
    collapses: u32,
    tripped: u32,
    success: Option<u32>,
}

fn run<O: Optimizer<P>>(optimizer: O, seed: u64, guard: Option<Setting>) -> Outcome {
    let adapter = hopper_task::adapter(optimizer, BUDGET, Vector::zeros()).unwrap();
    match guard {
        None => learn(adapter, seed),
        Some(s) => {
            let guard = Guard::<0, TICKS>::try_new(GuardConfig {
                relative_margin: s.relative_margin,
                absolute_margin: s.absolute_margin,
                envelope_ticks: 2,
                tripped_cost_span: 1.0,
                ..GuardConfig::DEFAULT
            })
            .unwrap();
            learn(adapter.with_guard(guard).unwrap(), seed)
        }
    }
}

fn learn<O: Optimizer<P>, G: Supervisor<4>>(
    mut adapter: HopperAdapter<O, G>,
    seed: u64,
) -> Outcome {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut episode = |adapter: &mut HopperAdapter<O, G>| {
        let mut course = hopper_task::plant(true, 1000 + seed);
        hopper_task::run_episode(adapter, &mut course, &mut rng, false).unwrap()
    };
    adapter.set_mode(Mode::Nominal).unwrap();
    let bare = (0..BARE_EPISODES)
        .map(|_| episode(&mut adapter).report.cost)
        .sum::<f32>()
        / BARE_EPISODES as f32;
    adapter.set_mode(Mode::Learn).unwrap();
    let mut outcome = Outcome::default();
    for k in 1..=BUDGET {
        let e = episode(&mut adapter);
        if e.report.mode != Mode::Learn {
            break;
        }
        outcome.unsafe_episodes += u32::from(e.collapsed || e.report.cost > UNSAFE_RATIO * bare);
        outcome.collapses += u32::from(e.collapsed);
        outcome.tripped += u32::from(e.report.trip.is_some());
        let success = !e.report.failed && e.report.trip.is_none() && e.report.cost <= THRESHOLD;
        if success && outcome.success.is_none() {
            outcome.success = Some(k);
        }
    }
    outcome
}

type Learner = (&'static str, fn(u64, Option<Setting>) -> Outcome);

fn learners() -> [Learner; 3] {
    [
        ("coordinate search", |seed, guard| {
            run(
                hopper_task::coordinate_search(Vector::zeros(), BUDGET).unwrap(),
                seed,
                guard,
            )
        }),
        ("diagonal CEM", |seed, guard| {
            let sigma = hopper_task::local_steps();
            let config = CemConfig {
                weighting: Weighting::CmaEs,
                initial_variance: 1e-2,
                exploration_floor: 1e-6,
                max_variance: 28.0 * 28.0,
                max_evaluations: BUDGET,
                ..CemConfig::DEFAULT
            };
            let cem = DiagonalCem::<31, 10, 5>::try_with_variances(
                hopper_task::bounds(),
                Vector::zeros(),
                sigma.component_mul(&sigma),
                config,
            )
            .unwrap();
            run(cem, seed, guard)
        }),
        ("CMA-ES", |seed, guard| {
            let config = CmaesConfig {
                max_evaluations: BUDGET,
                ..CmaesConfig::DEFAULT
            };
            let cmaes =
                Cmaes::<31, 14>::try_new(hopper_task::bounds(), Vector::zeros(), config).unwrap();
            run(cmaes, seed, guard)
        }),
    ]
}

fn table(seeds: std::ops::RangeInclusive<u64>, setting: Setting) {
    println!(
        "| learner | unsafe episodes off / on | collapses off / on | tripped (on) | successes off / on | median episodes to success off / on |"
    );
    println!("| --- | --- | --- | --- | --- | --- |");
    for (name, learner) in learners() {
        let outcomes: Vec<(Outcome, Outcome)> = seeds
            .clone()
            .map(|seed| (learner(seed, None), learner(seed, Some(setting))))
            .collect();
        let sum = |f: &dyn Fn(&(Outcome, Outcome)) -> u32| outcomes.iter().map(f).sum::<u32>();
        let median = |f: &dyn Fn(&(Outcome, Outcome)) -> Option<u32>| {
            let v: Vec<f64> = outcomes.iter().filter_map(f).map(f64::from).collect();
            if v.is_empty() {
                "–".to_string()
            } else {
                format!("{}", host_tests::median(v))
            }
        };
        println!(
            "| {name} | {} / {} | {} / {} | {} | {} / {} | {} / {} |",
            sum(&|o| o.0.unsafe_episodes),
            sum(&|o| o.1.unsafe_episodes),
            sum(&|o| o.0.collapses),
            sum(&|o| o.1.collapses),
            sum(&|o| o.1.tripped),
            sum(&|o| u32::from(o.0.success.is_some())),
            sum(&|o| u32::from(o.1.success.is_some())),
            median(&|o| o.0.success),
            median(&|o| o.1.success),
        );
    }
}

/// The one setting tried on seeds 101–110 (a row takes about 2.5 minutes; see
/// findings/guard.md).
const CHOSEN: Setting = Setting {
    relative_margin: 0.2,
    absolute_margin: 0.01,
};

#[test]
fn tune() {
    println!("\n{CHOSEN:?}, seeds 101–110");
    table(101..=110, CHOSEN);
}

#[test]
fn report() {
    println!("\n{CHOSEN:?}, seeds 1–10");
    table(1..=10, CHOSEN);
}
