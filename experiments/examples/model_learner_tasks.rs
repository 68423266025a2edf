//! The library's `model::ModelBased` on the hopping leg and on the via-point arm, beside its
//! inner optimizer (CMA-ES) and its fallback (coordinate search) alone: successes, episodes
//! to success, best cost, unsafe episodes and the episodes that fell back to the model-free
//! step. Nothing here was tuned: the learner keeps the AUV's settings
//! (`model_learner_auv`: trust radius 0.15 in [0.05, 1], ×1.5 / ×0.6, screen at 1.2 × the
//! bare cost), in normalised units (θ = u ⊙ scale, u ∈ [−1, 1]^P: the hopper's box, the
//! arm's unit below), with 3 exploration episodes of ±0.05 after the bare one.
//!
//! ```text
//! cargo run --release -p experiments --example model_learner_tasks -- hopper 1 10
//! cargo run --release -p experiments --example model_learner_tasks -- arm 1 10
//! cargo run --release -p experiments --example model_learner_tasks -- hopper 1 10 CMA-ES  # one row
//! ```
//!
//! **Hopper** (`host_tests::hopper_task`: the 31-parameter periodic PD, the apex cost, each
//! seed's training course 1000 + s replayed every episode, as in `guard_hopper`), 60 real
//! episodes per seed. Model: `RlsModel<6, 2, 9>` (affine) of [knee, hip, knee rate, hip
//! rate, body height, body velocity] and the two torques, fitted on every 1 kHz tick; the
//! imagined episode runs the same `PeriodicPd` on the first four and feeds `ApexHeightCost`
//! the predicted body height and velocity (power from the command and the joint rates; no
//! limit flag), 12,000 ticks. Inner `Cmaes<31, 14>`, 60 imagined episodes per proposal.
//! Fallback: the coordinate search of `hopper_task` (steps a sixth of the box). Unsafe:
//! cost above 1.2 × the bare episode's or a collapse; success: cost ≤ 3·10⁻⁴ (the sweep's).
//!
//! **Arm** (`host_tests::arm`, the 10-link via-point arm of Stulp & Sigaud 2012, 50 DMP
//! weights, deterministic), 60 real episodes per seed from the minimum-jerk θ₀. Model:
//! `RlsModel<20, 10, 31>` (affine) of the joint angles and the DMP's scaled velocities
//! [y, z] with the 10 forcing terms as the command, fitted on every 1 ms tick; the imagined
//! episode integrates it with the forcing of θ and scores the via-point distance at 0.3 s
//! and the weighted accelerations as `host_tests::arm` does. Unit: θ = θ₀ + 100·u (100 is
//! the standard deviation of the CEM exploration of the via-point study), box
//! u ∈ [−100, 100]^50. Inner `Cmaes<50, 14>`, 240 imagined episodes. Fallback: coordinate
//! search, step 0.25 units. Unsafe: cost above 1.2 × θ₀'s; success: cost below 1 % of
//! θ₀'s. The seed drives the optimizers' RNG (the arm has no noise).

use ctrl_adapt::controller::Controller;
use ctrl_adapt::cost::{ApexHeightCost, HopSample, Shaper};
use ctrl_adapt::model::{
    Affine, ModelBased, ModelBasedConfig, ModelConfig, RlsModel, Source, rollout,
};
use ctrl_adapt::optimizer::{
    Bounds, Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch, Error, Optimizer, Vector,
};
use host_tests::arm::{self, LINKS, PARAMS, ViaPointArm};
use host_tests::hopper::Hopper;
use host_tests::hopper_task::{self, P as HP};
use host_tests::median;
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

const EPISODES: usize = 60;
const EXPLORATIONS: usize = 3;
const EXPLORE: f32 = 0.05;
/// Imagined episodes per proposal on the arm.
const INNER: u32 = 240;

/// What a learning run did: per real episode its cost, its source ('b' bare, 'e'
/// exploration, 'm' model, 'f' fallback or the optimizer alone) and whether it was unsafe.
struct Run {
    /// The bare controller's (θ₀'s) cost: the reference of "unsafe" and of the ratio.
    bare: f32,
    costs: Vec<f32>,
    source: Vec<char>,
    unsafe_: Vec<bool>,
}

fn uniform<const N: usize>(rng: &mut impl RngCore, half_width: f32) -> Vector<N> {
    Vector::from_fn(|_, _| {
        let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
        half_width * (2.0 * unit - 1.0)
    })
}

fn learner_config(reference: f32, inner_evaluations: u32) -> ModelBasedConfig {
    ModelBasedConfig {
        margin: 0.2 * reference.abs(),
        inner_evaluations,
        ..ModelBasedConfig::DEFAULT
    }
}

// ---------------------------------------------------------------------------------------
// The hopper.

struct HopperEpisode {
    states: Vec<Vector<6>>,
    commands: Vec<Vector<2>>,
    cost: f32,
    collapsed: bool,
}

fn hopper_scale() -> Vector<HP> {
    *hopper_task::bounds().upper()
}

fn model_state(hopper: &Hopper) -> Vector<6> {
    let s = hopper.state();
    let x = hopper_task::policy_state(hopper);
    Vector::<6>::new(
        x[0],
        x[1],
        x[2],
        x[3],
        s.body_height as f32,
        s.body_velocity as f32,
    )
}

fn hop(theta: &Vector<HP>, seed: u64) -> HopperEpisode {
    let mut hopper = hopper_task::plant(true, 1000 + seed);
    hopper.reset();
    let mut controller = hopper_task::controller();
    let mut shaper = ApexHeightCost::try_new(hopper_task::apex_config()).unwrap();
    controller.reset();
    shaper.reset();
    let limit = hopper.config().torque_limit;
    let mut violation = false;
    let mut joint_stops = hopper.stats().joint_limit_steps;
    let mut states = vec![model_state(&hopper)];
    let mut commands = Vec::new();
    let dt = 1e-3;
    for tick in 0..hopper.steps_per_episode() {
        let s = hopper.state();
        let applied = hopper.applied_torques();
        let power = applied[0] * s.joint_velocities[0] + applied[1] * s.joint_velocities[1];
        shaper.observe(
            &HopSample {
                height: s.body_height as f32,
                vertical_velocity: s.body_velocity as f32,
                power: power.abs() as f32,
                limit_violation: violation,
            },
            dt,
        );
        let x = hopper_task::policy_state(&hopper);
        let tau = controller.corrected(theta, &x, tick as f32 * dt);
        hopper.step([f64::from(tau[1]), f64::from(tau[0])]);
        let stops = hopper.stats().joint_limit_steps;
        violation = stops > joint_stops
            || (f64::from(tau[0].abs()) >= limit[1] - 1e-3)
            || (f64::from(tau[1].abs()) >= limit[0] - 1e-3);
        joint_stops = stops;
        commands.push(tau);
        states.push(model_state(&hopper));
        if hopper.collapsed() {
            break;
        }
    }
    let collapsed = hopper.collapsed();
    let cost = if collapsed {
        hopper_task::adapter_config(1).failure_cost
    } else {
        shaper.cost()
    };
    HopperEpisode {
        states,
        commands,
        cost,
        collapsed,
    }
}

fn hopper_predict(
    model: &RlsModel<6, 2, 9>,
    start: &Vector<6>,
    theta: &Vector<HP>,
) -> Result<f32, Error> {
    let mut controller = hopper_task::controller();
    let mut shaper = ApexHeightCost::try_new(hopper_task::apex_config())?;
    controller.reset();
    shaper.reset();
    let dt = 1e-3;
    rollout(model, &Affine, start, 12_000, |k, x| {
        let q = Vector::<4>::new(x[0], x[1], x[2], x[3]);
        let tau = controller.corrected(theta, &q, k as f32 * dt);
        shaper.observe(
            &HopSample {
                height: x[4],
                vertical_velocity: x[5],
                power: (tau[0] * x[2]).abs() + (tau[1] * x[3]).abs(),
                limit_violation: false,
            },
            dt,
        );
        tau
    })?;
    let c = shaper.cost();
    if c.is_finite() {
        Ok(c)
    } else {
        Err(Error::NonFinite("cost"))
    }
}

fn hopper_model_based(seed: u64) -> Run {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let scale = hopper_scale();
    let mut model = RlsModel::<6, 2, 9>::try_new(ModelConfig::DEFAULT).unwrap();
    let fit = |model: &mut RlsModel<6, 2, 9>, e: &HopperEpisode| {
        for (k, u) in e.commands.iter().enumerate() {
            let _ = model.update(&Affine, &e.states[k], u, &e.states[k + 1]);
        }
    };
    let bare = hop(&Vector::zeros(), seed);
    fit(&mut model, &bare);
    let start = bare.states[0];
    let unit = Bounds::<HP>::uniform(-1.0, 1.0).unwrap();
    let fallback = CoordinateSearch::try_new(
        unit,
        Vector::zeros(),
        CoordinateConfig {
            initial_step: 1.0 / 6.0,
            tolerance: 1e-3,
            max_evaluations: EPISODES as u32,
            ..CoordinateConfig::DEFAULT
        },
    )
    .unwrap();
    let mut learner = ModelBased::try_new(unit, fallback, learner_config(bare.cost, 60)).unwrap();
    learner.record(Vector::zeros(), bare.cost).unwrap();
    learner.set_reference(bare.cost).unwrap();
    let limit = 1.2 * bare.cost;
    let mut run = Run {
        bare: bare.cost,
        costs: vec![bare.cost],
        source: vec!['b'],
        unsafe_: vec![bare.collapsed],
    };
    for _ in 0..EXPLORATIONS {
        let u: Vector<HP> = uniform(&mut rng, EXPLORE);
        let e = hop(&u.component_mul(&scale), seed);
        fit(&mut model, &e);
        learner.record(u, e.cost).unwrap();
        run.costs.push(e.cost);
        run.source.push('e');
        run.unsafe_.push(e.collapsed || e.cost > limit);
    }
    let inner = |trust: Bounds<HP>, centre: Vector<HP>| {
        Cmaes::<HP, 14>::try_new(
            trust,
            centre,
            CmaesConfig {
                initial_sigma: 0.5,
                max_evaluations: 60,
                ..CmaesConfig::DEFAULT
            },
        )
    };
    while run.costs.len() < EPISODES {
        let predict = |u: &Vector<HP>| hopper_predict(&model, &start, &u.component_mul(&scale));
        let Ok(proposal) = learner.propose(&mut rng, inner, predict) else {
            break;
        };
        let e = hop(&proposal.theta.component_mul(&scale), seed);
        fit(&mut model, &e);
        learner.tell(e.cost).unwrap();
        run.costs.push(e.cost);
        run.source.push(match proposal.source {
            Source::Model(_) => 'm',
            Source::Fallback => 'f',
        });
        run.unsafe_.push(e.collapsed || e.cost > limit);
    }
    run
}

/// An optimizer alone started at the bare θ (the episode is deterministic: the bare cost,
/// the reference, is measured once more outside the budget).
fn hopper_alone<O: Optimizer<HP>>(seed: u64, mut optimizer: O) -> Run {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let bare = hop(&Vector::zeros(), seed).cost;
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
        let e = hop(&theta, seed);
        optimizer.tell(e.cost).unwrap();
        run.unsafe_.push(e.collapsed || e.cost > 1.2 * bare);
        run.source.push(if theta == Vector::<HP>::zeros() {
            'b'
        } else {
            'f'
        });
        run.costs.push(e.cost);
    }
    run
}

// ---------------------------------------------------------------------------------------
// The arm.

const UNIT: f32 = 100.0;
type ArmModel = RlsModel<20, 10, 31>;

/// The unit box around θ₀ inside the arm's box: θ = θ₀ + 100·u.
fn arm_bounds(theta0: &Vector<PARAMS>) -> Bounds<PARAMS> {
    let limit = arm::WEIGHT_LIMIT;
    Bounds::try_new(
        Vector::from_fn(|i, _| (-limit - theta0[i]) / UNIT),
        Vector::from_fn(|i, _| (limit - theta0[i]) / UNIT),
    )
    .unwrap()
}

fn to_f32<const N: usize>(v: &[f64; N]) -> Vector<N> {
    Vector::from_fn(|i, _| v[i] as f32)
}

/// One real episode of θ: its cost, and the model fitted on its ticks.
fn reach(arm_: &ViaPointArm, model: &mut ArmModel, theta: &Vector<PARAMS>) -> f32 {
    let (states, forcings, terms) = arm_.ticks(theta);
    for (k, f) in forcings.iter().enumerate() {
        let _ = model.update(
            &Affine,
            &to_f32(&states[k]),
            &to_f32(f),
            &to_f32(&states[k + 1]),
        );
    }
    terms.total() as f32
}

/// The arm's cost of θ on the model: the forcing of θ drives the model from the start;
/// the via-point distance at 0.3 s and the weighted accelerations as `host_tests::arm`.
fn arm_predict(arm_: &ViaPointArm, model: &ArmModel, theta: &Vector<PARAMS>) -> Result<f32, Error> {
    let forcings = arm_.forcings(theta);
    let weight_sum: f64 = (1..=LINKS).map(|d| (LINKS + 1 - d) as f64).sum();
    let mut start = [0.0; 2 * LINKS];
    start[..LINKS].copy_from_slice(arm_.start());
    let mut acceleration = 0.0f64;
    let mut via = f64::NAN;
    let mut previous = to_f32(&start);
    rollout(
        model,
        &Affine,
        &to_f32(&start),
        forcings.len() as u32,
        |k, x| {
            if k > 0 {
                // The step that led to x: ÿ = ż/τ with ż from the model's increment of z.
                let mut weighted = 0.0;
                for d in 0..LINKS {
                    let zd = f64::from(x[LINKS + d] - previous[LINKS + d]) / arm::DT;
                    let ydd = zd / arm::DURATION;
                    weighted += (LINKS - d) as f64 * ydd * ydd;
                }
                acceleration += weighted / weight_sum * arm::DT;
                if k as usize == arm::VIA_STEP {
                    let y: [f64; LINKS] = std::array::from_fn(|d| f64::from(x[d]));
                    let [px, py] = arm::end_effector(&y);
                    via = (px - arm::VIA_POINT[0]).powi(2) + (py - arm::VIA_POINT[1]).powi(2);
                }
            }
            previous = *x;
            to_f32(&forcings[k as usize])
        },
    )
    .map(|end| {
        // The last step's acceleration (the closure sees states before each step).
        let mut weighted = 0.0;
        for d in 0..LINKS {
            let zd = f64::from(end[LINKS + d] - previous[LINKS + d]) / arm::DT;
            let ydd = zd / arm::DURATION;
            weighted += (LINKS - d) as f64 * ydd * ydd;
        }
        acceleration + weighted / weight_sum * arm::DT
    })
    .and_then(|acceleration| {
        let c = (arm::VIA_WEIGHT * via + acceleration) as f32;
        if c.is_finite() {
            Ok(c)
        } else {
            Err(Error::NonFinite("cost"))
        }
    })
}

fn arm_model_based(seed: u64) -> Run {
    let arm_ = ViaPointArm::new();
    let theta0 = arm_.minimum_jerk_theta();
    let theta = |u: &Vector<PARAMS>| theta0 + u * UNIT;
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut model = ArmModel::try_new(ModelConfig::DEFAULT).unwrap();
    let bare = reach(&arm_, &mut model, &theta0);
    let unit = arm_bounds(&theta0);
    let fallback = CoordinateSearch::try_new(
        unit,
        Vector::zeros(),
        CoordinateConfig {
            initial_step: 0.25,
            tolerance: 1e-3,
            max_evaluations: EPISODES as u32,
            ..CoordinateConfig::DEFAULT
        },
    )
    .unwrap();
    let mut learner = ModelBased::try_new(unit, fallback, learner_config(bare, INNER)).unwrap();
    learner.record(Vector::zeros(), bare).unwrap();
    learner.set_reference(bare).unwrap();
    let limit = 1.2 * bare;
    let mut run = Run {
        bare,
        costs: vec![bare],
        source: vec!['b'],
        unsafe_: vec![false],
    };
    for _ in 0..EXPLORATIONS {
        let u: Vector<PARAMS> = uniform(&mut rng, EXPLORE);
        let c = reach(&arm_, &mut model, &theta(&u));
        learner.record(u, c).unwrap();
        run.costs.push(c);
        run.source.push('e');
        run.unsafe_.push(c > limit);
    }
    let inner = |trust: Bounds<PARAMS>, centre: Vector<PARAMS>| {
        Cmaes::<PARAMS, 14>::try_new(
            trust,
            centre,
            CmaesConfig {
                initial_sigma: 0.5,
                max_evaluations: INNER,
                ..CmaesConfig::DEFAULT
            },
        )
    };
    while run.costs.len() < EPISODES {
        let predict = |u: &Vector<PARAMS>| arm_predict(&arm_, &model, &theta(u));
        let Ok(proposal) = learner.propose(&mut rng, inner, predict) else {
            break;
        };
        let c = reach(&arm_, &mut model, &theta(&proposal.theta));
        learner.tell(c).unwrap();
        run.costs.push(c);
        run.source.push(match proposal.source {
            Source::Model(_) => 'm',
            Source::Fallback => 'f',
        });
        run.unsafe_.push(c > limit);
    }
    run
}

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
        let c = arm_.cost(&(theta0 + u * UNIT));
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
        arm_model_based,
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
        hopper_model_based,
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
