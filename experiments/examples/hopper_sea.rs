//! The hopping experiment of `tests/hopper_experiments.rs` on the leg with series-elastic
//! joints (`HopperConfig::SCARLETH_SEA`, see `host_tests::hopper`): does the compliance
//! ScarlETH is built around let the clock-driven policy reject the unperceived blocks better?
//!
//! ```text
//! cargo run --release -p experiments --example hopper_sea              # the SEA leg (≈ 1 min)
//! cargo run --release -p experiments --example hopper_sea -- --tune    # + retune its nominal
//! cargo run --release -p experiments --example hopper_sea -- --variations   # + k, f_τ sweep
//! ```
//!
//! For each leg:
//! 1. the nominal gait (`NominalHopping`): for `SCARLETH_SEA`, `NominalHopping::SEA_TUNED`;
//!    with `--tune` and for every variation, found again by the procedure of
//!    `tests/hopper_tuning.rs` on flat ground (grid, then `CoordinateSearch` over the 6
//!    parameters, 600 episodes of 8 s), with the motor-limit steps counted as violations too;
//! 2. the protocol of `tests/hopper_experiments.rs` around that nominal
//!    (`hopping::controller_for`): 400 coordinate-search episodes of 12 s on the training
//!    course (block sequence of seed 1001, replayed), optimizer seed 1; the initial (θ = 0)
//!    and learned policies evaluated on the 5 unseen courses 10 001–10 005 (rng seed 2).
//!
//! Printed per leg: hops, mean apex and spread (max − min after 3 hops) on every unseen course,
//! their median, and the apex after a stance on each block height (learned policy, all
//! unseen courses).

use ctrl_adapt::optimizer::{Optimizer, Vector};
use experiments::hopping::{
    self, HopEpisode, LEARNING_EPISODES, P, TRAINING_SEED, coordinate_search, evaluate_for,
    plant_for, run_episode,
};
use host_tests::hopper::{HopperConfig, NominalHopping, SeaConfig};
use host_tests::hopper_tuning;
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const EVAL_SEEDS: std::ops::RangeInclusive<u64> = 10_001..=10_005;

// ---------------------------------------------------------------- nominal tuning

/// The procedure of `host_tests::hopper_tuning` (that of `tests/hopper_tuning.rs`; its cost
/// counts the series-elastic motor's limit steps as violations too) on `leg`.
fn tune(leg: HopperConfig) -> NominalHopping {
    let t = hopper_tuning::tune(leg).expect("tuning runs");
    println!(
        "  tuned on flat ground: {} episodes, cost {:.4}: {:?}",
        t.episodes, t.cost, t.nominal
    );
    t.nominal
}

/// Apexes after 3 hops and limit counts of `nominal` on flat ground (8 s).
fn describe_flat(leg: HopperConfig, nominal: NominalHopping) {
    let config = HopperConfig {
        episode_duration: 8.0,
        ground_heights: &[0.0],
        ..leg
    };
    let hopper = hopper_tuning::episode(config, nominal);
    let a = hopper.apex_heights().get(3..).unwrap_or(&[]);
    let max = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = a.iter().copied().fold(f64::INFINITY, f64::min);
    let s = hopper.stats();
    println!(
        "  flat ground, nominal: apex {min:.4}..{max:.4} m over {} hops; steps at a limit: \
         command {}, motor {}, joint {}",
        a.len(),
        s.torque_limit_steps,
        s.motor_limit_steps,
        s.joint_limit_steps
    );
}

// ---------------------------------------------------------------- learning protocol

fn evaluations(leg: HopperConfig, nominal: &NominalHopping, theta: Vector<P>) -> Vec<HopEpisode> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2);
    EVAL_SEEDS
        .map(|s| {
            evaluate_for(
                theta,
                &mut plant_for(leg, true, s),
                &mut rng,
                false,
                nominal,
            )
            .expect("evaluation runs")
        })
        .collect()
}

fn summary(episodes: &[HopEpisode]) -> String {
    let spreads: Vec<f64> = episodes.iter().map(HopEpisode::apex_spread).collect();
    let min = spreads.iter().copied().fold(f64::INFINITY, f64::min);
    let max = spreads.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let hops: Vec<String> = episodes.iter().map(|e| e.hops().to_string()).collect();
    let means: Vec<String> = episodes
        .iter()
        .map(|e| format!("{:.3}", e.apex_mean()))
        .collect();
    let stable = episodes.iter().all(HopEpisode::hops_stably);
    format!(
        "spread median {:.2} cm ({:.2}–{:.2}); hops {}; mean apex {} m; stable {stable}",
        100.0 * median(spreads),
        100.0 * min,
        100.0 * max,
        hops.join("/"),
        means.join("/")
    )
}

/// Mean apex after a stance on each ground height (after the transient), over `episodes`.
fn apex_by_block(episodes: &[HopEpisode], heights: &[f64]) -> String {
    let parts: Vec<String> = heights
        .iter()
        .map(|&h| {
            let a: Vec<f64> = episodes
                .iter()
                .flat_map(|e| {
                    e.apexes
                        .iter()
                        .zip(&e.grounds)
                        .skip(hopping::TRANSIENT_HOPS)
                        .filter(|(_, g)| (**g - h).abs() < 1e-9)
                        .map(|(a, _)| *a)
                })
                .collect();
            let mean = a.iter().sum::<f64>() / a.len().max(1) as f64;
            format!("{:.1} cm: {mean:.4} m (n = {})", 100.0 * h, a.len())
        })
        .collect();
    parts.join(", ")
}

/// The learning protocol of `tests/hopper_experiments.rs` on `leg` around `nominal`.
fn experiment(leg: HopperConfig, nominal: &NominalHopping) {
    describe_flat(leg, *nominal);
    let training = || plant_for(leg, true, TRAINING_SEED);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let search = coordinate_search(Vector::zeros(), LEARNING_EPISODES).expect("valid search");
    let mut adapter = hopping::adapter_for(search, LEARNING_EPISODES, Vector::zeros(), nominal)
        .expect("valid adapter");
    let mut first = f32::NAN;
    for episode in 0..LEARNING_EPISODES {
        let e = run_episode(&mut adapter, &mut training(), &mut rng, false).expect("episode");
        if episode == 0 {
            first = e.report.cost;
        }
    }
    let best = adapter.optimizer().best().expect("something was told");
    let status = adapter.optimizer().status();
    println!(
        "  learning: {LEARNING_EPISODES} episodes ({status:?}), training cost {first:.3e} -> {:.3e}",
        best.cost
    );
    let before = evaluations(leg, nominal, Vector::zeros());
    let after = evaluations(leg, nominal, best.theta);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2);
    let train_after = evaluate_for(best.theta, &mut training(), &mut rng, false, nominal)
        .expect("evaluation runs");
    println!("  initial: {}", summary(&before));
    println!("  learned: {}", summary(&after));
    println!(
        "  learned on the training course: spread {:.2} cm",
        100.0 * train_after.apex_spread()
    );
    let course = &after[0];
    let hops: Vec<String> = course
        .apexes
        .iter()
        .zip(&course.grounds)
        .map(|(a, g)| format!("{:.3}@{:.1}", a, 100.0 * g))
        .collect();
    println!(
        "  learned, course {}: apex (m) @ stance block (cm): {}",
        EVAL_SEEDS.start(),
        hops.join(" ")
    );
    println!(
        "  apex by the stance's block, initial: {}",
        apex_by_block(&before, leg.ground_heights)
    );
    println!(
        "  apex by the stance's block, learned: {}",
        apex_by_block(&after, leg.ground_heights)
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |f: &str| args.iter().any(|a| a == f);

    println!("== rigid leg (HopperConfig::SCARLETH, NominalHopping::TUNED): the reference");
    experiment(HopperConfig::SCARLETH, &NominalHopping::TUNED);

    let leg = HopperConfig::SCARLETH_SEA;
    println!(
        "== series-elastic leg (HopperConfig::SCARLETH_SEA, {:?})",
        SeaConfig::SCARLETH
    );
    let nominal = if flag("--tune") {
        tune(leg)
    } else {
        NominalHopping::SEA_TUNED
    };
    println!("  nominal {nominal:?}");
    experiment(leg, &nominal);

    if flag("--variations") {
        let variations: [(&str, SeaConfig); 5] = [
            (
                "motor limit 60 N·m",
                SeaConfig {
                    motor_torque_limit: 60.0,
                    ..SeaConfig::SCARLETH
                },
            ),
            (
                "k = 50 N·m/rad",
                SeaConfig {
                    stiffness: 50.0,
                    ..SeaConfig::SCARLETH
                },
            ),
            (
                "k = 300 N·m/rad",
                SeaConfig {
                    stiffness: 300.0,
                    ..SeaConfig::SCARLETH
                },
            ),
            (
                "f_τ = 10 Hz",
                SeaConfig {
                    torque_bandwidth: 10.0,
                    ..SeaConfig::SCARLETH
                },
            ),
            (
                "f_τ = 30 Hz",
                SeaConfig {
                    torque_bandwidth: 30.0,
                    ..SeaConfig::SCARLETH
                },
            ),
        ];
        for (name, sea) in variations {
            println!("== variation: {name} ({sea:?})");
            let leg = HopperConfig {
                series_elasticity: Some(sea),
                ..HopperConfig::SCARLETH_SEA
            };
            let nominal = tune(leg);
            experiment(leg, &nominal);
        }
    }
}
