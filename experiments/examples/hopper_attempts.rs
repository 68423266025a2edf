//! One of the attempts at the hopping target (apex spread ≤ 1.5 cm on unseen courses) that
//! did NOT reach it, kept to reproduce the figures of findings/hopping.md ("What was tried"):
//!
//! ```text
//! cargo run --release -p experiments --example hopper_attempts   # ≈ 4–6 min
//! ```
//!
//! A chain of the library's optimizers, each started from the previous best θ, driven through
//! the ask/tell API (every episode runs through a deployed `Adapter`; an evaluation may be the
//! mean over several training courses and use a shaped cost, computed here on the host):
//! 1. `CoordinateSearch`, 400 episodes on course 1001, the plain `ApexHeightCost` (the
//!    experiment of `tests/hopper_experiments.rs`);
//! 2. `CoordinateSearch`, 1500 evaluations, each the mean over courses 1001–1003 of a shaped
//!    cost: the apex term without the first 3 apexes (the drop from rest) plus
//!    10 · (max − min apex after 3 hops)²;
//! 3. `DiagonalCem` (PI-BB, h = 10, K = 20, covariance adaptation, floor 1e-7), 800
//!    evaluations of the same shaped 3-course cost, σ per row: 0.01 rad, 2 N·m/rad,
//!    0.1 N·m·s/rad, 0.5 ms.
//!
//! After each stage: the apex spread on the training course and on the 5 unseen courses of
//! the test (seeds 10 001–10 005) and 10 more (30 001–30 010).

use ctrl_adapt::optimizer::{CemConfig, DiagonalCem, Optimizer, Status, Vector, Weighting};
use experiments::hopping::spreads_on;
use experiments::hopping::{self, HopEpisode, P, evaluate, plant};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// How an evaluation is scored.
#[derive(Clone, Copy)]
struct Scoring {
    /// Apexes left out of the squared-deviation term.
    skip: usize,
    /// Weight of the squared apex spread (m²).
    spread_weight: f64,
}

const PLAIN: Scoring = Scoring {
    skip: 0,
    spread_weight: 0.0,
};
const SHAPED: Scoring = Scoring {
    skip: 3,
    spread_weight: 10.0,
};

/// The episode's cost: `ApexHeightCost`'s as told, or with its apex term replaced.
fn cost(e: &HopEpisode, s: Scoring) -> f64 {
    let told = f64::from(e.report.cost);
    if e.collapsed || (s.skip == 0 && s.spread_weight == 0.0) {
        return told;
    }
    let mean_sq =
        |a: &[f64]| a.iter().map(|h| (h - 0.6).powi(2)).sum::<f64>() / a.len().max(1) as f64;
    let rest = told - mean_sq(&e.apexes); // energy, limits, missing hops
    mean_sq(e.apexes.get(s.skip..).unwrap_or(&[]))
        + rest
        + s.spread_weight * e.apex_spread().powi(2)
}

/// Runs `optimizer` for `budget` evaluations, each the mean cost over `courses`.
fn learn<O: Optimizer<P>>(
    mut optimizer: O,
    budget: usize,
    courses: &[u64],
    s: Scoring,
) -> Vector<P> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    for _ in 0..budget {
        if optimizer.status() != Status::Running {
            break;
        }
        let theta = optimizer.ask(&mut rng).expect("ask");
        let c: f64 = courses
            .iter()
            .map(|&seed| {
                cost(
                    &evaluate(theta, &mut plant(true, seed), &mut rng, false).expect("episode"),
                    s,
                )
            })
            .sum::<f64>()
            / courses.len() as f64;
        optimizer.tell(c as f32).expect("tell");
    }
    let best = optimizer.best().expect("told");
    println!("  best cost {:.3e}", best.cost);
    best.theta
}

fn report(stage: &str, theta: Vector<P>) {
    let (train, _) = spreads_on(theta, 1001..=1003).expect("episode");
    let (unseen, stable) = spreads_on(theta, 10_001..=10_005).expect("episode");
    let (more, stable_more) = spreads_on(theta, 30_001..=30_010).expect("episode");
    println!(
        "{stage}: spread (cm) on courses 1001–1003 {train:.2?}; unseen 10001–10005 {unseen:.2?}, \
         median {:.2}; 30001–30010 median {:.2}, max {:.2}; stable hopping {}",
        host_tests::median(unseen.clone()),
        host_tests::median(more.clone()),
        more.iter().copied().fold(0.0, f64::max),
        stable && stable_more
    );
}

fn main() {
    let t = std::time::Instant::now();
    let theta = learn(
        hopping::coordinate_search(Vector::zeros(), 400).expect("search"),
        400,
        &[1001],
        PLAIN,
    );
    report("1. coordinate search, 400, plain cost, course 1001", theta);
    let theta = learn(
        hopping::coordinate_search(theta, 1500).expect("search"),
        1500,
        &[1001, 1002, 1003],
        SHAPED,
    );
    report(
        "2. + coordinate search, 1500 × 3 courses, shaped cost",
        theta,
    );
    let sigma = Vector::<P>::from_fn(|i, _| [0.01, 2.0, 0.1, 5e-4][(i / hopping::K).min(3)]);
    let config = CemConfig {
        weighting: Weighting::PiBb { h: 10.0 },
        initial_variance: 0.0,
        exploration_floor: 1e-7,
        max_variance: 28.0,
        max_evaluations: 800,
        ..CemConfig::DEFAULT
    };
    let cem = DiagonalCem::<P, 20, 20>::try_with_variances(
        hopping::bounds(),
        theta,
        sigma.component_mul(&sigma),
        config,
    )
    .expect("cem");
    let theta = learn(cem, 800, &[1001, 1002, 1003], SHAPED);
    report(
        "3. + DiagonalCem PI-BB, 800 × 3 courses, shaped cost",
        theta,
    );
    println!(
        "θ = {:?}\n{:.0} s",
        theta.as_slice(),
        t.elapsed().as_secs_f64()
    );
}
