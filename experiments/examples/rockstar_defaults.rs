//! ROCK*'s extrapolation rate λ and the gate on its extra descent start points, measured
//! (findings in `experiments/findings/rockstar-arm.md`, "λ and the start-point gate"):
//!
//! ```text
//! cargo run --release -p experiments --example rockstar_defaults -- ellipsoid [SEEDS]
//! cargo run --release -p experiments --example rockstar_defaults -- arm [SEEDS]
//! ```
//!
//! Each runs four configurations, λ ∈ {0.5, 0.3} × gate ∈ {2n, none}, on seeds 0..SEEDS
//! (default 10), every other parameter the library's default and no stopping tolerance
//! (every session spends its budget):
//!
//! * the gate 2n ([`RockstarConfig::extra_starts_from`] = `None`, the default): the extra
//!   start points (the cheapest near rollout, the new rollout, the best ever) are used only
//!   when the near set holds at least 2n rollouts, as in the authors' `ROCKstar.m` from
//!   2015; "none" (`Some(0)`) uses them at every update, as its 2014 revision did.
//! * `ellipsoid`: the rotated 10-D ellipsoid of condition 10³
//!   ([`host_tests::functions::rotated_ellipsoid`]) over [−1, 1]¹⁰ from 0,
//!   `Rockstar<10, 50>` (M = 5n), σ₀ = 0.1, 1,000 rollouts. Prints, per configuration, the
//!   median over seeds of θ*'s cost after the last rollout and of the lowest sampled cost.
//! * `arm`: the 50-parameter via-point arm of `--test rockstar_arm` (`Rockstar<50, 250>`,
//!   the tuned exploration std 2, 3,000 rollouts). Prints the mean and median lowest sampled
//!   cost after 3,000 rollouts (the paper's statistic) and θ*'s mean cost.

use ctrl_adapt::optimizer::{Bounds, RockstarConfig, Vector};
use experiments::rockstar_arm::{self, Method, Session, mean_median, tuned};
use host_tests::arm::{self, ViaPointArm};
use host_tests::functions::rotated_ellipsoid;

/// The configurations compared: (label, λ, extra_starts_from).
const CONFIGS: [(&str, f32, Option<u32>); 4] = [
    ("λ = 0.5, gate 2n", 0.5, None),
    ("λ = 0.5, no gate", 0.5, Some(0)),
    ("λ = 0.3, gate 2n", 0.3, None),
    ("λ = 0.3, no gate", 0.3, Some(0)),
];

fn base(lambda: f32, extra_starts_from: Option<u32>) -> RockstarConfig {
    RockstarConfig {
        lambda,
        extra_starts_from,
        ..RockstarConfig::DEFAULT
    }
}

fn median(values: &[f32]) -> f64 {
    mean_median(values).1
}

fn ellipsoid(seeds: u64) {
    const ROLLOUTS: usize = 1000;
    let bounds = Bounds::<10>::uniform(-1.0, 1.0).expect("a valid box");
    let mut cost = |t: &Vector<10>| rotated_ellipsoid(t, 3.0);
    println!(
        "rotated 10-D ellipsoid, condition 1e3, Rockstar<10, 50>, σ₀ 0.1, {ROLLOUTS} rollouts, seeds 0..{seeds}"
    );
    println!("| configuration | median θ* cost | median lowest | θ* cost per seed |");
    println!("|---|---:|---:|---|");
    for (label, lambda, gate) in CONFIGS {
        let config = rockstar_arm::rockstar_config(base(lambda, gate), 0.1, ROLLOUTS);
        let sessions: Vec<Session> = (0..seeds)
            .map(|seed| {
                rockstar_arm::rockstar_with::<10, 50>(
                    config,
                    bounds,
                    Vector::zeros(),
                    seed,
                    &mut cost,
                )
                .expect("a valid configuration")
            })
            .collect();
        let deployed: Vec<f32> = sessions.iter().map(|s| s.deployed).collect();
        let lowest: Vec<f32> = sessions.iter().map(Session::final_lowest).collect();
        let per_seed: Vec<String> = deployed.iter().map(|c| format!("{c:.2e}")).collect();
        println!(
            "| {label} | {:.3e} | {:.3e} | {} |",
            median(&deployed),
            median(&lowest),
            per_seed.join(" ")
        );
    }
}

fn arm(seeds: u64) {
    const ROLLOUTS: usize = 3000;
    let plant = ViaPointArm::new();
    let start = plant.minimum_jerk_theta();
    let bounds = arm::bounds();
    let std = tuned::ARM_50
        .iter()
        .find(|(m, _)| *m == Method::Rockstar)
        .map(|(_, s)| *s)
        .expect("a tuned value");
    let mut cost = |t: &Vector<50>| plant.cost(t);
    println!(
        "50-parameter via-point arm, Rockstar<50, 250>, std {std}, {ROLLOUTS} rollouts, seeds 0..{seeds}"
    );
    println!("| configuration | mean lowest | median lowest | mean θ* cost | lowest per seed |");
    println!("|---|---:|---:|---:|---|");
    for (label, lambda, gate) in CONFIGS {
        let config =
            rockstar_arm::rockstar_config(base(lambda, gate), std / arm::WEIGHT_LIMIT, ROLLOUTS);
        let sessions: Vec<Session> = (0..seeds)
            .map(|seed| {
                rockstar_arm::rockstar_with::<50, 250>(config, bounds, start, seed, &mut cost)
                    .expect("a valid configuration")
            })
            .collect();
        let lowest: Vec<f32> = sessions.iter().map(Session::final_lowest).collect();
        let deployed: Vec<f32> = sessions.iter().map(|s| s.deployed).collect();
        let (mean, med) = mean_median(&lowest);
        let per_seed: Vec<String> = lowest.iter().map(|c| format!("{c:.0}")).collect();
        println!(
            "| {label} | {mean:.0} | {med:.0} | {:.0} | {} |",
            mean_median(&deployed).0,
            per_seed.join(" ")
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let seeds = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let clock = std::time::Instant::now();
    match args.first().map(String::as_str) {
        Some("ellipsoid") => ellipsoid(seeds),
        Some("arm") => arm(seeds),
        _ => {
            eprintln!("usage: rockstar_defaults (ellipsoid | arm) [SEEDS]");
            std::process::exit(2);
        }
    }
    eprintln!("{:.0} s", clock.elapsed().as_secs_f64());
}
