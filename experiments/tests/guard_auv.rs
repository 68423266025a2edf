//! The runtime guard on the AUV survey: learning with and without it, for coordinate search,
//! diagonal CEM and CMA-ES, in the "real" current (0.6 m/s along +x) and in the same current
//! rotated by 45° about the vertical (along (1, 1, 0)/√2). Release only:
//!
//! ```text
//! cargo test --release -p experiments --test guard_auv -- --nocapture --test-threads 1
//! ```
//!
//! `tune` chooses the guard's envelope margin and hysteresis on seeds 101–110; `report`
//! measures the chosen guard on seeds 1–10 (the table in findings/guard.md).
//!
//! Every run: 3 bare episodes ([`Mode::Nominal`]; they teach the guard its envelope, and
//! their mean cost is "the bare controller's cost" of the seed), then 150 learning episodes
//! from W = 0. Both arms run the same bare episodes and the same plant seed.
//!
//! * **unsafe episode**: a learning episode whose *executed* survey cost (the shaper's,
//!   whatever was told) exceeds 1.2 × the bare controller's cost;
//! * **ticks beyond limits**: ticks at which the vehicle is more than 8 m from the target
//!   (it starts 7.2 m away; the guard's one limit, a safety signal computed by the loop);
//! * **success**: the first learning episode with cost < D = 1 m (J > −1).

#![cfg(not(debug_assertions))]

use std::cell::Cell;

use ctrl_adapt::controller::guard::{Guard, GuardConfig, Limit, Source, Supervisor};
use ctrl_adapt::controller::{Adapter, Mode};
use ctrl_adapt::cost::SurveyCost;
use ctrl_adapt::model::TickModel;
use ctrl_adapt::optimizer::{
    CemConfig, Cmaes, CmaesConfig, DiagonalCem, Optimizer, Vector, Weighting,
};
use experiments::auv_guard::{
    CHOSEN, FAR, FAR_LIMIT, GuardSetting as Setting, PREDICTIVE, TICKS, forecast_model,
    guard_config, predictive_guard,
};
use host_tests::auv::{Auv, AuvConfig};
use host_tests::auv_task::{self, AuvController, P, RADIUS};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const BUDGET: u32 = 150;
const BARE_EPISODES: usize = 3;
const UNSAFE_RATIO: f32 = 1.2;

#[derive(Debug, Clone, Copy, Default)]
struct Outcome {
    unsafe_episodes: u32,
    /// Of the unsafe episodes, those the guard had tripped.
    unsafe_tripped: u32,
    ticks_beyond: u32,
    tripped: u32,
    success: Option<u32>,
    best: f32,
}

fn rotated() -> AuvConfig {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    AuvConfig {
        current_direction: [s, s, 0.0],
        ..AuvConfig::REAL
    }
}

/// Runs the episodes of one arm; `guard` None runs unguarded.
fn run<O: Optimizer<P>>(
    optimizer: O,
    plant: AuvConfig,
    seed: u64,
    guard: Option<Setting>,
) -> Outcome {
    let adapter = auv_task::adapter(optimizer, BUDGET, Vector::zeros()).unwrap();
    let mut auv = auv_task::plant(plant, seed);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    fn no_signal<T>(_: &T, _: &Vector<6>, _: usize, _: f32) -> f32 {
        0.0
    }
    let Some(s) = guard else {
        return learn(adapter, &mut auv, &mut rng, no_signal);
    };
    match s.forecast {
        None => {
            let guard = Guard::<1, TICKS>::try_new(guard_config(&s, [FAR_LIMIT])).unwrap();
            learn(
                adapter.with_guard(guard).unwrap(),
                &mut auv,
                &mut rng,
                no_signal,
            )
        }
        Some((ratio, lookahead)) => {
            let adapter = adapter
                .with_guard(predictive_guard(&s, ratio).unwrap())
                .unwrap()
                .with_model(forecast_model())
                .unwrap();
            let reference = Cell::new(f32::NAN);
            learn(adapter, &mut auv, &mut rng, |a, x, k, _| {
                // The forecast of the pending candidate (`auv_guard::forecast`).
                let Some(theta) = a.optimizer().pending().copied() else {
                    return 0.0;
                };
                experiments::auv_guard::forecast(
                    a.model(),
                    a.controller(),
                    a.shaper(),
                    &theta,
                    x,
                    k,
                    (ratio, lookahead),
                    &reference,
                )
            })
        }
    }
}

/// The loop, generic over the guard and the model: bare episodes, then learning. `signal(adapter,
/// state, tick, bare cost)` is the guard's second safety signal (the forecast), computed in
/// learning episodes only.
fn learn<O, G, M>(
    mut adapter: Adapter<O, AuvController, SurveyCost, P, 6, 3, G, M>,
    auv: &mut Auv,
    rng: &mut Xoshiro128PlusPlus,
    signal: impl Fn(
        &Adapter<O, AuvController, SurveyCost, P, 6, 3, G, M>,
        &Vector<6>,
        usize,
        f32,
    ) -> f32,
) -> Outcome
where
    O: Optimizer<P>,
    G: Supervisor<6>,
    M: TickModel<6, 3>,
{
    let mut episode = |adapter: &mut Adapter<O, AuvController, SurveyCost, P, 6, 3, G, M>,
                       bare: Option<f32>| {
        auv.reset();
        adapter.begin_episode(rng).unwrap();
        let mut beyond = 0;
        for tick in 0..auv.steps_per_episode() {
            let state = auv_task::policy_state(auv);
            let error = auv_task::true_error(auv);
            let d = error.norm();
            if d > FAR {
                beyond += 1;
            }
            let predicted = bare.map_or(0.0, |b| signal(adapter, &state, tick, b));
            let u = adapter.control_with_signal(&state, &error, &[d, predicted]);
            auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
        }
        let report = adapter.end_episode().unwrap();
        (report, beyond)
    };
    adapter.set_mode(Mode::Nominal).unwrap();
    let bare: f32 = (0..BARE_EPISODES)
        .map(|_| episode(&mut adapter, None).0.cost)
        .sum::<f32>()
        / BARE_EPISODES as f32;
    adapter.set_mode(Mode::Learn).unwrap();
    let mut outcome = Outcome {
        best: f32::INFINITY,
        ..Outcome::default()
    };
    for k in 1..=BUDGET {
        let (report, beyond) = episode(&mut adapter, Some(bare));
        if report.mode != Mode::Learn {
            break;
        }
        let unsafe_episode = report.cost > UNSAFE_RATIO * bare;
        outcome.unsafe_episodes += u32::from(unsafe_episode);
        outcome.unsafe_tripped += u32::from(unsafe_episode && report.trip.is_some());
        outcome.ticks_beyond += beyond;
        outcome.tripped += u32::from(report.trip.is_some());
        if report.cost < RADIUS && outcome.success.is_none() {
            outcome.success = Some(k);
        }
        outcome.best = outcome.best.min(report.cost);
    }
    outcome
}

type Learner = (&'static str, fn(AuvConfig, u64, Option<Setting>) -> Outcome);

fn learners() -> [Learner; 3] {
    [
        ("coordinate search", |plant, seed, guard| {
            run(
                auv_task::coordinate_search(Vector::zeros(), BUDGET).unwrap(),
                plant,
                seed,
                guard,
            )
        }),
        ("diagonal CEM", |plant, seed, guard| {
            let config = CemConfig {
                weighting: Weighting::CmaEs,
                initial_variance: 1e-2,
                exploration_floor: 1e-6,
                max_variance: 0.25,
                max_evaluations: BUDGET,
                ..CemConfig::DEFAULT
            };
            let cem = DiagonalCem::<18, 10, 5>::try_with_variances(
                auv_task::bounds(),
                Vector::zeros(),
                Vector::repeat(0.25 * 0.25),
                config,
            )
            .unwrap();
            run(cem, plant, seed, guard)
        }),
        ("CMA-ES", |plant, seed, guard| {
            let config = CmaesConfig {
                initial_sigma: 0.25,
                max_evaluations: BUDGET,
                ..CmaesConfig::DEFAULT
            };
            let cmaes =
                Cmaes::<18, 12>::try_new(auv_task::bounds(), Vector::zeros(), config).unwrap();
            run(cmaes, plant, seed, guard)
        }),
    ]
}

#[derive(Debug, Default)]
struct Totals {
    unsafe_episodes: u32,
    unsafe_tripped: u32,
    ticks_beyond: u32,
    tripped: u32,
    successes: u32,
    to_success: Vec<f64>,
}

impl Totals {
    fn add(&mut self, o: Outcome) {
        self.unsafe_episodes += o.unsafe_episodes;
        self.unsafe_tripped += o.unsafe_tripped;
        self.ticks_beyond += o.ticks_beyond;
        self.tripped += o.tripped;
        if let Some(k) = o.success {
            self.successes += 1;
            self.to_success.push(f64::from(k));
        }
    }

    fn median(&self) -> String {
        if self.to_success.is_empty() {
            "–".into()
        } else {
            format!("{}", host_tests::median(self.to_success.clone()))
        }
    }
}

fn table(seeds: std::ops::RangeInclusive<u64>, setting: Setting) -> Vec<(String, Totals, Totals)> {
    let mut rows = Vec::new();
    for (current, plant) in [
        ("0.6 m/s +x", AuvConfig::REAL),
        ("0.6 m/s rotated 45°", rotated()),
    ] {
        for (name, learner) in learners() {
            let (mut off, mut on) = (Totals::default(), Totals::default());
            for seed in seeds.clone() {
                off.add(learner(plant, seed, None));
                on.add(learner(plant, seed, Some(setting)));
            }
            rows.push((format!("{name}, {current}"), off, on));
        }
    }
    rows
}

fn print(rows: &[(String, Totals, Totals)]) {
    println!(
        "| learner, current | unsafe episodes off / on (on and tripped) | ticks beyond 8 m off / on | tripped (on) | successes off / on | median episodes to success off / on |"
    );
    println!("| --- | --- | --- | --- | --- | --- |");
    for (name, off, on) in rows {
        println!(
            "| {name} | {} / {} ({}) | {} / {} | {} | {} / {} | {} / {} |",
            off.unsafe_episodes,
            on.unsafe_episodes,
            on.unsafe_tripped,
            off.ticks_beyond,
            on.ticks_beyond,
            on.tripped,
            off.successes,
            on.successes,
            off.median(),
            on.median()
        );
    }
}

/// The constant-margin setting `tune` chose, reported beside it.
const CONSTANT: Setting = Setting {
    relative_margin: 0.5,
    absolute_margin: 0.5,
    envelope_ticks: 2,
    margin_taper: 1.0,
    forecast: None,
};

#[test]
fn tune() {
    // The first grid (two hysteresis counts were not compared there: with the survey cost
    // a violation, once begun, lasts) then around its best.
    let grid = [
        (0.05, 0.0),
        (0.05, 0.5),
        (0.2, 0.0),
        (0.2, 0.5),
        (0.5, 0.0),
        (0.5, 0.5),
    ]
    .map(|(r, a)| (r, a, 2))
    .into_iter()
    .chain([(0.5, 0.5, 1), (0.5, 0.5, 3), (0.3, 0.5, 2), (0.5, 1.0, 2)]);
    for (relative_margin, absolute_margin, envelope_ticks) in grid {
        let setting = Setting {
            relative_margin,
            absolute_margin,
            envelope_ticks,
            margin_taper: 1.0,
            forecast: None,
        };
        if std::env::var("GUARD_TUNE_ALL").is_err()
            && envelope_ticks == 2
            && relative_margin != 0.3
            && absolute_margin != 1.0
        {
            continue;
        }
        println!("\n{setting:?}, seeds 101–110");
        print(&table(101..=110, setting));
    }
}

/// Tapered margins (wide early, narrow late), chosen on seeds 101–110 by the rule of `tune`:
/// among the settings whose successes for coordinate search and CMA-ES are within one seed
/// of the unguarded ones in both currents, the fewest unsafe episodes of those two learners
/// (hysteresis kept at 2 ticks).
#[test]
fn tune_taper() {
    for (relative_margin, absolute_margin) in [(0.5, 0.5), (1.0, 0.5), (1.0, 1.0)] {
        for margin_taper in [0.5, 0.25, 0.1, 0.0] {
            let setting = Setting {
                relative_margin,
                absolute_margin,
                envelope_ticks: 2,
                margin_taper,
                forecast: None,
            };
            println!("\n{setting:?}, seeds 101–110");
            print(&table(101..=110, setting));
        }
    }
}

/// The predictive trip (a forecast of the episode's end on a plant model fitted to every
/// tick, [`forecast`]) on top of the chosen tapered envelope, chosen on seeds 101–110 by the
/// rule of `tune`: among the limits whose successes for coordinate search and CMA-ES are
/// within one seed of the unguarded ones in both currents, the fewest unsafe episodes of
/// those two learners.
#[test]
fn tune_forecast() {
    let grid = [
        (1.1, 2),
        (1.05, 2),
        (1.0, 2),
        (1.05, 6),
        (1.05, 12),
        (1.0, 6),
        (0.95, 6),
    ];
    let from = std::env::var("GRID_FROM").map_or(0, |v| v.parse().unwrap());
    for &(ratio, lookahead) in &grid[from..] {
        let setting = Setting {
            forecast: Some((ratio, lookahead)),
            ..CHOSEN
        };
        println!("\n{setting:?}, seeds 101–110");
        print(&table(101..=110, setting));
    }
}

#[test]
fn report() {
    let only_predictive = std::env::var("GUARD_REPORT").is_ok_and(|v| v == "predictive");
    for setting in [PREDICTIVE, CHOSEN, CONSTANT] {
        if only_predictive && setting.forecast.is_none() {
            continue;
        }
        println!("\n{setting:?}, seeds 1–10");
        print(&table(1..=10, setting));
    }
}

/// How early must a guard hand an unsafe episode back to stay safe? For every unsafe
/// learning episode of the unguarded coordinate search and CMA-ES (seeds 1–10, both
/// currents), the episode is replayed on a copy of the plant as it was before it (the same
/// disturbances), with θ handed back to the bare PD at tick h = 0, 5, …, 235 (a guard whose
/// signal limit trips at exactly h), and the latest h whose episode still ends safe (cost
/// ≤ 1.2 × the bare cost) is kept: the lead time any guard needs on that episode. Nothing
/// is chosen here; it measures the plant.
#[test]
fn lead_time() {
    const STEP: usize = 5;
    for (current, plant) in [
        ("0.6 m/s +x", AuvConfig::REAL),
        ("0.6 m/s rotated 45°", rotated()),
    ] {
        for (name, cmaes) in [("coordinate search", false), ("CMA-ES", true)] {
            // Latest safe hand-over tick per unsafe episode; None: unsafe even when handed
            // back at tick 0 (the bare PD's own noise).
            let mut latest: Vec<Option<usize>> = Vec::new();
            for seed in 1..=10u64 {
                let optimizer: Box<dyn FnOnce() -> Vec<Unsafe>> = if cmaes {
                    let config = CmaesConfig {
                        initial_sigma: 0.25,
                        max_evaluations: BUDGET,
                        ..CmaesConfig::DEFAULT
                    };
                    let o = Cmaes::<18, 12>::try_new(auv_task::bounds(), Vector::zeros(), config)
                        .unwrap();
                    Box::new(move || unsafe_episodes(o, plant, seed))
                } else {
                    let o = auv_task::coordinate_search(Vector::zeros(), BUDGET).unwrap();
                    Box::new(move || unsafe_episodes(o, plant, seed))
                };
                for (before, theta, bare, cost) in optimizer() {
                    // The replay never handed back is the episode itself.
                    assert_eq!(replay(&before, theta, TICKS), cost, "{name}, seed {seed}");
                    let safe_at = |h: usize| replay(&before, theta, h) <= UNSAFE_RATIO * bare;
                    latest.push((0..TICKS).step_by(STEP).rev().find(|&h| safe_at(h)));
                }
            }
            let n = latest.len();
            let never = latest.iter().filter(|h| h.is_none()).count();
            let within = |s: usize| {
                latest
                    .iter()
                    .filter(|h| h.is_some_and(|h| h < s * 10))
                    .count()
            };
            let mut known: Vec<f64> = latest.iter().flatten().map(|&h| h as f64 / 10.0).collect();
            known.sort_by(f64::total_cmp);
            let median = if known.is_empty() {
                f64::NAN
            } else {
                host_tests::median(known.clone())
            };
            println!(
                "| {name}, {current} | {n} | {never} | {} | {} | {} | {median:.1} |",
                within(2),
                within(5),
                within(10),
            );
        }
    }
}

/// An unsafe learning episode: the plant before it, its θ, the bare cost of the run and the
/// episode's cost.
type Unsafe = (Auv, Vector<P>, f32, f32);

/// The unsafe learning episodes of an unguarded run.
fn unsafe_episodes<O: Optimizer<P>>(optimizer: O, plant: AuvConfig, seed: u64) -> Vec<Unsafe> {
    let mut adapter = auv_task::adapter(optimizer, BUDGET, Vector::zeros()).unwrap();
    let mut auv = auv_task::plant(plant, seed);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut episode = |adapter: &mut auv_task::AuvAdapter<O>, auv: &mut Auv| {
        auv.reset();
        adapter.begin_episode(&mut rng).unwrap();
        for _ in 0..auv.steps_per_episode() {
            let state = auv_task::policy_state(auv);
            let error = auv_task::true_error(auv);
            let u = adapter.control(&state, &error);
            auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
        }
        adapter.end_episode().unwrap()
    };
    adapter.set_mode(Mode::Nominal).unwrap();
    let bare: f32 = (0..BARE_EPISODES)
        .map(|_| episode(&mut adapter, &mut auv).cost)
        .sum::<f32>()
        / BARE_EPISODES as f32;
    adapter.set_mode(Mode::Learn).unwrap();
    let mut out = Vec::new();
    for _ in 0..BUDGET {
        let before = auv.clone();
        let report = episode(&mut adapter, &mut auv);
        if report.mode != Mode::Learn {
            break;
        }
        if report.cost > UNSAFE_RATIO * bare {
            out.push((before, report.theta, bare, report.cost));
        }
    }
    out
}

/// The executed cost of θ on a copy of `before`, handed back to the bare PD at tick `h`.
fn replay(before: &Auv, theta: Vector<P>, h: usize) -> f32 {
    let mut auv = before.clone();
    let guard = Guard::<1, 0>::try_new(GuardConfig {
        limits: [Limit {
            source: Source::Signal(0),
            low: 0.0,
            high: 0.5,
        }],
        limit_ticks: 1,
        ..GuardConfig::DEFAULT
    })
    .unwrap();
    let mut adapter = auv_task::adapter(
        auv_task::coordinate_search(Vector::zeros(), 1).unwrap(),
        1,
        Vector::zeros(),
    )
    .unwrap()
    .with_guard(guard)
    .unwrap();
    auv.reset();
    adapter.begin_fixed_episode(theta).unwrap();
    for k in 0..auv.steps_per_episode() {
        let state = auv_task::policy_state(&auv);
        let error = auv_task::true_error(&auv);
        let signal = if k >= h { 1.0 } else { 0.0 };
        let u = adapter.control_with_signal(&state, &error, &[signal]);
        auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
    }
    adapter.end_episode().unwrap().cost
}
