//! The via-point experiments of Stulp & Sigaud 2012 (sections 3.1, 3.3, 3.4) with
//! `DiagonalCem` on the 10-link arm of `host_tests::arm`, fixed seeds. Each prints its
//! results table (`-- --nocapture`).
//!
//! The figure-6 experiment (30 sessions of 4,000 episodes) runs only in release:
//! `cargo test --release -p experiments --test via_point -- --nocapture`.

use ctrl_adapt::optimizer::{CemConfig, Weighting};
use host_tests::arm::{self, LINKS, Session, VIA_WEIGHT, ViaPointArm, end_effector};

/// ‖p(0.3 s) − (0.5, 0.5)‖ of the session's final mean, in metres.
fn via_distance(arm: &ViaPointArm, session: &Session) -> f64 {
    arm.evaluate(&session.mean).via_distance2.sqrt()
}

/// Checks the plant: the goal pose puts the tip on the y axis at (0, 0.1/sin(π/20)); the
/// 5-basis DMP fitted to the minimum-jerk movement ends within 2 cm of that tip at t = 0.5 s
/// and passes 25 ± 1 cm from the via point at t = 0.3 s, so the initialisation does not
/// solve the task; its cost is finite and the via-point term makes more than 99 % of it.
#[test]
fn the_arm_and_its_minimum_jerk_start() {
    let arm = ViaPointArm::new();
    let [gx, gy] = end_effector(arm.goal());
    assert!(gx.abs() < 1e-12, "tip x = {gx}");
    assert!((gy - 0.1 / (std::f64::consts::PI / 20.0).sin()).abs() < 1e-12);
    assert_eq!(arm.goal().len(), LINKS);

    let theta = arm.minimum_jerk_theta();
    let path = arm.end_effector_path(&theta, 1);
    assert_eq!(path.len(), 501);
    let [ex, ey] = path[500];
    assert!(
        ((ex - gx).powi(2) + (ey - gy).powi(2)).sqrt() < 0.02,
        "end {ex}, {ey}"
    );
    let terms = arm.evaluate(&theta);
    let d = terms.via_distance2.sqrt();
    assert!((d - 0.25).abs() < 0.01, "initial via distance {d}");
    assert!(terms.total().is_finite());
    assert!(VIA_WEIGHT * terms.via_distance2 > 0.99 * terms.total());
}

/// Section 3.3 / figure 5: each weighting — CEM (K_e = 5), CMA-ES (K_e = 5), PI-BB (h = 10,
/// all K samples) — with the paper's K = 10 trials per update (the first noise-free) and
/// constant exploration Σ = 10⁴·I, 3 sessions each (as in figure 5), 100 updates.
///
/// Checks, for every session: the noise-free cost after 100 updates is below 1 % of the
/// minimum-jerk start's, and the learned movement passes within 2 cm of the via point at
/// t = 0.3 s (the start misses it by 25 cm). Margins: these seeds give at most 0.16 % and
/// 8.1 mm; over 20 other seeds (10..30) the worst were 0.31 % and 12.2 mm (CEM).
#[test]
fn every_weighting_learns_the_via_point_task() {
    let arm = ViaPointArm::new();
    let fixed = |weighting| CemConfig {
        weighting,
        initial_variance: 1e4,
        adapt_covariance: false,
        ..CemConfig::DEFAULT
    };
    println!(
        "| weighting | seed | initial cost | after 25 | after 50 | after 100 | via miss (mm) |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|");
    for (name, weighting) in [
        ("CEM", Weighting::Cem),
        ("CMA-ES", Weighting::CmaEs),
        ("PI-BB", Weighting::PiBb { h: 10.0 }),
    ] {
        for seed in 0..3 {
            let session = match weighting {
                Weighting::PiBb { .. } => arm::learn::<10, 10>(&arm, fixed(weighting), 100, seed),
                _ => arm::learn::<10, 5>(&arm, fixed(weighting), 100, seed),
            }
            .unwrap();
            assert_eq!(session.episodes, 1000);
            let c = &session.curve;
            let d = via_distance(&arm, &session);
            println!(
                "| {name} | {seed} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.1} |",
                c[0],
                c[25],
                c[50],
                c[100],
                d * 1e3
            );
            assert!(
                c[100] < 0.01 * c[0],
                "{name} seed {seed}: {} vs {}",
                c[100],
                c[0]
            );
            assert!(d < 0.02, "{name} seed {seed}: via distance {d}");
        }
    }
}

/// Section 3.4 / figure 6 and conclusion 1: PI-BB (h = 10) with K = 20 trials per update,
/// 200 updates, 5 sessions per initial exploration λ_init ∈ {10², 10⁴, 10⁶}, with covariance
/// adaptation (PI²-CMA: floor 10²·I after each update, as in the paper) and without (PI²,
/// Σ = λ_init·I throughout).
///
/// Checks (the values these seeds give are in findings/via-point-arm.md, with two other seed sets):
/// * sensitivity: the ratio between the largest and the smallest per-λ_init mean final
///   cost is below 10 with adaptation and above 100 without (these seeds: 3.6 and 423;
///   seeds 100..105 and 200..205: 3.6 / 364 and 5.8 / 287);
/// * level: the mean final cost over all 15 sessions with adaptation is below a quarter of
///   the one without (the paper's 10⁵·8 against 10⁵·35; these seeds: 0.04). The standard
///   deviations are printed but not asserted: one slow adaptive session dominates them
///   (their ratio is 0.025 here but 0.10 with seeds 200..205);
/// * exploration: with adaptation the final λ (mean variance) of all 15 sessions lie within
///   a factor 3 of each other, λ grew from 10² and shrank from 10⁶ (the paper's (F)–(I):
///   every λ_init converges to the same magnitude; these seeds: 605 to 848).
///
/// Heavy (about a minute in debug): compiled in release only; CI runs
/// `cargo test --release -p experiments --test via_point`.
#[test]
#[cfg(not(debug_assertions))]
fn covariance_adaptation_makes_learning_insensitive_to_initial_exploration() {
    const LAMBDAS: [f32; 3] = [1e2, 1e4, 1e6];
    let arm = ViaPointArm::new();
    let mut summary = Vec::new();
    println!("| covariance | λ_init | final cost per session | mean | final λ per session |");
    println!("|---|---:|---|---:|---|");
    for adapt in [false, true] {
        let mut per_lambda = Vec::new();
        let mut all = Vec::new();
        let mut exploration = Vec::new();
        for lambda in LAMBDAS {
            let config = CemConfig {
                weighting: Weighting::PiBb { h: 10.0 },
                initial_variance: lambda,
                adapt_covariance: adapt,
                exploration_floor: 1e2,
                ..CemConfig::DEFAULT
            };
            let sessions: Vec<Session> = (0..5)
                .map(|seed| arm::learn::<20, 20>(&arm, config, 200, seed).unwrap())
                .collect();
            let finals: Vec<f64> = sessions.iter().map(|s| f64::from(s.final_cost())).collect();
            let lambdas: Vec<f32> = sessions.iter().map(Session::final_exploration).collect();
            let mean = finals.iter().sum::<f64>() / finals.len() as f64;
            println!(
                "| {} | {lambda:.0e} | {} | {mean:.2e} | {} |",
                if adapt { "adapted" } else { "fixed" },
                finals
                    .iter()
                    .map(|c| format!("{c:.2e}"))
                    .collect::<Vec<_>>()
                    .join(" "),
                lambdas
                    .iter()
                    .map(|l| format!("{l:.0}"))
                    .collect::<Vec<_>>()
                    .join(" "),
            );
            if adapt {
                exploration.push(lambdas);
            }
            per_lambda.push(mean);
            all.extend(finals);
        }
        let ratio = per_lambda.iter().copied().fold(f64::MIN, f64::max)
            / per_lambda.iter().copied().fold(f64::MAX, f64::min);
        let mean = all.iter().sum::<f64>() / all.len() as f64;
        let std = (all.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / all.len() as f64).sqrt();
        println!(
            "{}: all sessions {mean:.2e} ± {std:.2e}; max/min over λ_init of the mean final cost {ratio:.1}",
            if adapt { "adapted" } else { "fixed" }
        );
        summary.push((ratio, mean, exploration));
    }
    let (fixed_ratio, fixed_mean, _) = &summary[0];
    let (adapted_ratio, adapted_mean, exploration) = &summary[1];
    assert!(
        *fixed_ratio > 100.0,
        "fixed exploration ratio {fixed_ratio}"
    );
    assert!(*adapted_ratio < 10.0, "adapted ratio {adapted_ratio}");
    assert!(
        *adapted_mean < 0.25 * fixed_mean,
        "mean {adapted_mean} vs {fixed_mean}"
    );
    let flat: Vec<f32> = exploration.iter().flatten().copied().collect();
    let (lo, hi) = flat
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), &l| (lo.min(l), hi.max(l)));
    assert!(hi < 3.0 * lo, "final λ from {lo} to {hi}");
    assert!(
        exploration[0].iter().all(|&l| l > 2e2),
        "λ from 10² did not grow"
    );
    assert!(
        exploration[2].iter().all(|&l| l < 1e4),
        "λ from 10⁶ did not shrink"
    );
}
