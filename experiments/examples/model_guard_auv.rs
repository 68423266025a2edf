//! The model-based learner's real episodes under the runtime guard with the predictive trip
//! (`experiments::auv_guard`, the guard `tests/guard_auv.rs` chose), on the oracle's AUV
//! tasks `auv` and `auv-rotated` (the same plants, seeds and budget of 150 episodes as the
//! oracle's `model` method, `model_learner::run_on_trial`, whose learner settings are kept:
//! inner `Cmaes<18, 12>` with 240 predictions, coordinate-search fallback with step 0.25,
//! the screen at the bare cost + 20 %).
//!
//! ```text
//! cargo run --release -p experiments --example model_guard_auv -- choose          # seeds 101–110, every setting
//! cargo run --release -p experiments --example model_guard_auv -- report          # seeds 1–10, the unguarded learner and the chosen setting
//! cargo run --release -p experiments --example model_guard_auv -- report 1 10 dither-0.05 trace   # one setting, per-seed traces
//! ```
//!
//! Per task and setting: successes (an episode told a cost below 1, within 1 m), the median
//! episode of the first (1-based, the bare episode first), the unsafe episodes (executed
//! cost above the bare episode's by more than 20 % of it, the oracle's rule), of those the
//! ones the bare PD alone would not have run unsafe (replayed from tick 0 on the same
//! disturbances: not the bare controller's own spread), the unsafe explorations, and the
//! guard's trips. The settings:
//!
//! * `off`: no guard (the oracle's `model` method);
//! * `guard`: every learning episode guarded, the 3 explorations ±0.05 included;
//! * `guard-proposals`: the explorations unguarded, the proposals guarded;
//! * `dither-D`: the 3 explorations replaced by dithered bare episodes (the bare PD with a
//!   command noise uniform in ±D m/s per axis and tick: they feed the model, teach the
//!   guard's envelope, and are not recorded as candidates), the proposals guarded;
//! * `…-restart-R`: the trust region restarted after R stalled proposals at its minimum
//!   radius (`ModelBasedConfig::restart_after`); `…-min-radius-0.15`: a minimum radius of
//!   0.15 instead of 0.05.
//!
//! `PREDICTED=N` prints each run's first N episodes as origin, real cost / predicted cost.

use ctrl_adapt::model::ModelBasedConfig;
use ctrl_adapt::optimizer::Vector;
use experiments::auv_guard::{GuardedAuv, GuardedSettings, PREDICTIVE};
use experiments::model_learner::{Origin, Settings, auv_fallback, inner_cmaes, learn};
use experiments::peers::{Task, Trial};
use host_tests::auv_task::{self, P, RADIUS};
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const BUDGET: u32 = 150;

/// A setting of the study: its name, the plant's settings and the explorations' half-width.
struct Setting {
    name: &'static str,
    plant: GuardedSettings,
    explore: f32,
    /// `ModelBasedConfig::restart_after` (0: never).
    restart_after: u32,
    /// `ModelBasedConfig::min_radius`.
    min_radius: f32,
}

fn settings() -> Vec<Setting> {
    let plant = GuardedSettings {
        guard: Some(PREDICTIVE),
        guard_explorations: true,
        dither: 0.0,
        explorations: 3,
    };
    let dither = |name, dither| Setting {
        name,
        plant: GuardedSettings { dither, ..plant },
        explore: 0.0,
        restart_after: 0,
        min_radius: 0.05,
    };
    vec![
        Setting {
            name: "off",
            plant: GuardedSettings {
                guard: None,
                ..plant
            },
            explore: 0.05,
            restart_after: 0,
            min_radius: 0.05,
        },
        Setting {
            name: "guard",
            plant,
            explore: 0.05,
            restart_after: 0,
            min_radius: 0.05,
        },
        Setting {
            name: "guard-proposals",
            plant: GuardedSettings {
                guard_explorations: false,
                ..plant
            },
            explore: 0.05,
            restart_after: 0,
            min_radius: 0.05,
        },
        dither("dither-0.02", 0.02),
        dither("dither-0.05", 0.05),
        dither("dither-0.1", 0.1),
        Setting {
            restart_after: 5,
            ..dither("dither-0.05-restart-5", 0.05)
        },
        Setting {
            restart_after: 10,
            ..dither("dither-0.05-restart-10", 0.05)
        },
        Setting {
            name: "off-restart-5",
            plant: GuardedSettings {
                guard: None,
                ..plant
            },
            explore: 0.05,
            restart_after: 5,
            min_radius: 0.05,
        },
        Setting {
            name: "guard-restart-5",
            plant,
            explore: 0.05,
            restart_after: 5,
            min_radius: 0.05,
        },
        Setting {
            name: "guard-proposals-restart-5",
            plant: GuardedSettings {
                guard_explorations: false,
                ..plant
            },
            explore: 0.05,
            restart_after: 5,
            min_radius: 0.05,
        },
        Setting {
            min_radius: 0.15,
            ..dither("dither-0.05-min-radius-0.15", 0.05)
        },
    ]
}

/// One seed's run: the first success, unsafe episodes, unsafe not the bare's spread,
/// unsafe explorations, trips, and the trace.
struct Outcome {
    success: Option<usize>,
    unsafe_episodes: usize,
    not_spread: usize,
    unsafe_explorations: usize,
    trips: usize,
    trace: String,
}

fn run(task: Task, seed: u64, setting: &Setting) -> Outcome {
    let trial = Trial::new(task, seed);
    let auv = trial.auv().expect("an AUV task").clone();
    let mut plant = GuardedAuv::new(auv, setting.plant, seed).expect("valid guard");
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let chosen = Settings::chosen(240);
    let learner = Settings {
        config: ModelBasedConfig {
            min_radius: setting.min_radius,
            restart_after: setting.restart_after,
            ..chosen.config
        },
        explorations: setting.plant.explorations,
        explore: Vector::repeat(setting.explore),
        ..chosen
    };
    let run = learn(
        &mut plant,
        auv_task::bounds(),
        auv_fallback(Vector::repeat(0.25), BUDGET),
        inner_cmaes::<P, 12>(240),
        &learner,
        BUDGET as usize,
        &mut rng,
    )
    .expect("a finite bare cost");
    if std::env::var("PREDICTED").is_ok() {
        let pairs: Vec<String> = (0..run.costs.len().min(
            std::env::var("PREDICTED")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(40),
        ))
            .map(|k| {
                format!(
                    "{k}{}:{:.2}/{}",
                    run.origin[k].letter(),
                    run.costs[k],
                    run.predicted[k].map_or("-".into(), |p| format!("{p:.2}"))
                )
            })
            .collect();
        println!("    {} seed {seed}: {}", task.name(), pairs.join(" "));
    }
    let episodes = &plant.episodes;
    let mut trace = String::new();
    for (k, (e, o)) in episodes.iter().zip(&run.origin).enumerate() {
        // t: tripped; !: unsafe; s: the bare PD alone unsafe too.
        let mark = format!(
            "{}{}{}",
            if e.trip.is_some() { "t" } else { "" },
            if e.unsafe_episode { "!" } else { "" },
            if e.bare_unsafe == Some(true) { "s" } else { "" },
        );
        if k < 12 || !mark.is_empty() {
            trace += &format!(" {k}{}{:.2}{mark}", o.letter(), e.executed);
        }
    }
    Outcome {
        success: run.costs.iter().position(|c| *c < RADIUS).map(|k| k + 1),
        unsafe_episodes: episodes.iter().filter(|e| e.unsafe_episode).count(),
        not_spread: episodes
            .iter()
            .filter(|e| e.bare_unsafe == Some(false))
            .count(),
        unsafe_explorations: episodes
            .iter()
            .zip(&run.origin)
            .filter(|(e, o)| e.unsafe_episode && **o == Origin::Explore)
            .count(),
        trips: episodes.iter().filter(|e| e.trip.is_some()).count(),
        trace,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let report = args.first().is_some_and(|a| a == "report");
    let (from, to) = match (args.get(1), args.get(2)) {
        (Some(a), Some(b)) => (a.parse().unwrap(), b.parse().unwrap()),
        _ if report => (1, 10),
        _ => (101, 110),
    };
    let only = args.get(3).filter(|a| *a != "trace");
    let trace = args.iter().any(|a| a == "trace");
    println!("seeds {from}–{to}, {BUDGET} episodes");
    println!(
        "| setting | task | successes | median episodes to success | unsafe | unsafe, not the bare PD's spread | unsafe explorations | trips |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for setting in settings() {
        if only.is_some_and(|o| o != setting.name) {
            continue;
        }
        for task in [Task::Auv, Task::AuvRotated] {
            let outcomes: Vec<Outcome> = (from..=to).map(|s| run(task, s, &setting)).collect();
            let to_success: Vec<f64> = outcomes
                .iter()
                .filter_map(|o| o.success.map(|k| k as f64))
                .collect();
            let sum = |f: fn(&Outcome) -> usize| outcomes.iter().map(f).sum::<usize>();
            println!(
                "| {} | {} | {}/{} | {} | {} | {} | {} | {} |",
                setting.name,
                task.name(),
                to_success.len(),
                outcomes.len(),
                if to_success.is_empty() {
                    "–".to_string()
                } else {
                    format!("{}", median(to_success.clone()))
                },
                sum(|o| o.unsafe_episodes),
                sum(|o| o.not_spread),
                sum(|o| o.unsafe_explorations),
                sum(|o| o.trips),
            );
            if trace {
                for (s, o) in (from..=to).zip(&outcomes) {
                    println!(
                        "    seed {s}: success {:?}, unsafe {} ({} not spread), trips {}:{}",
                        o.success, o.unsafe_episodes, o.not_spread, o.trips, o.trace
                    );
                }
            }
        }
    }
}
