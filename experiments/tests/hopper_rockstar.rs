//! ROCK* on the hopping leg (Hwangbo et al., "ROCK*: Efficient black-box optimization for
//! policy learning", Humanoids 2014, section IV) on the Hunt–Crossley ground, and the
//! acceptance check of a deployed gait (findings/hopping.md, "ROCK*" and "Robust gaits").
//! Heavy: compiled in release builds only (debug `cargo test` skips it), runs on the
//! machine's cores:
//!
//! ```text
//! cargo test --release -p experiments --test hopper_rockstar -- --nocapture --test-threads 1
//! ```
//!
//! Learning: the library's `Rockstar<31, 155>` from the tuned nominal gait (θ = 0: the
//! constant-gain initial policy), σ₀ = 0.1, ξ ≈ ζ^{0.1} (`hopping::noisy_rockstar_config`),
//! a new block course every episode, the spread-weighted cost (`hopping::spread_apex_config`),
//! [`BUDGET`] episodes per run (a reduced budget: the full run is the example
//! `hopper_rockstar`, findings/hopping.md), [`SEEDS`] runs; θ* is scored every 250 episodes
//! on the validation courses 20 001–20 010 and the best-scored θ* deployed (early
//! stopping). Evaluation on the 20 unseen courses 10 001–10 020; the acceptance check
//! (`hopping::robustness`) of every deployed θ* whose unseen median is ≤ 1.5 cm.

#![cfg(not(debug_assertions))]

use std::sync::OnceLock;

use ctrl_adapt::optimizer::{Rockstar, Vector};
use experiments::hopping::{self, CHECK_DRAWS, HopRockstar, Perturbation, UNSEEN_COURSES};
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Learning episodes per run (the full run: 2000).
const BUDGET: u32 = 1000;

/// The optimizer seeds of the runs.
const SEEDS: [u64; 10] = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10];

/// One run: the deployed θ*, where it was kept and how it does.
struct Run {
    seed: u64,
    episode: u32,
    rollouts: u32,
    median: f64,
    max: f64,
    stable: bool,
    /// The absolute check's verdict, run only when the median is ≤ 1.5 cm and it is stable.
    absolute: Option<bool>,
    /// The extra apex after the 5.5 cm block (cm, 20 unseen courses).
    extra: f64,
}

/// ROCK* learning with optimizer seed `seed`, deployed θ* evaluated.
fn run(seed: u64) -> Run {
    let mut rockstar = HopRockstar::try_new(
        hopping::bounds(),
        Vector::zeros(),
        hopping::noisy_rockstar_config(0.1, BUDGET),
    )
    .unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut perturbation_rng = Xoshiro256PlusPlus::seed_from_u64(1_000_000 + seed);
    let scores = hopping::learn_sequentially(
        &mut rockstar,
        Rockstar::theta_star,
        |_, _| None,
        BUDGET,
        hopping::spread_apex_config(),
        Perturbation::NONE,
        &mut rng,
        &mut perturbation_rng,
        250,
    )
    .unwrap();
    let kept = scores.kept(BUDGET).unwrap();
    let (spreads, stable) = hopping::spreads_on(kept.theta, UNSEEN_COURSES).unwrap();
    let max = spreads.iter().copied().fold(0.0, f64::max);
    let median = median(spreads);
    let absolute = (median <= 1.5 && stable).then(|| {
        hopping::robustness(kept.theta, CHECK_DRAWS, 7)
            .unwrap()
            .passes_absolute()
    });
    Run {
        seed,
        episode: kept.episode,
        rollouts: kept.rollouts,
        median,
        max,
        stable,
        absolute,
        extra: hopping::block_extra_apex(kept.theta, UNSEEN_COURSES).unwrap(),
    }
}

/// The runs, computed once.
fn runs() -> &'static Vec<Run> {
    static RUNS: OnceLock<Vec<Run>> = OnceLock::new();
    RUNS.get_or_init(|| hopping::map_seeds(&SEEDS, run))
}

/// The initial gait's extra apex after the block (cm) and its acceptance check.
fn initial() -> &'static (f64, hopping::Robustness) {
    static INITIAL: OnceLock<(f64, hopping::Robustness)> = OnceLock::new();
    INITIAL.get_or_init(|| {
        (
            hopping::block_extra_apex(Vector::zeros(), UNSEEN_COURSES).unwrap(),
            hopping::robustness(Vector::zeros(), CHECK_DRAWS, 7).unwrap(),
        )
    })
}

/// Prints the table of the runs.
fn table(runs: &[Run], initial_extra: f64) {
    println!("\nROCK*, {BUDGET} episodes per run, 20 unseen courses");
    println!(
        "| seed | kept at episode | rollouts | unseen median (cm) | unseen max | stable | absolute check | extra apex after the block (cm) |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | --- | --- | ---: |");
    for r in runs {
        println!(
            "| {} | {} | {} | {:.2} | {:.2} | {} | {} | {:.2} |",
            r.seed,
            r.episode,
            r.rollouts,
            r.median,
            r.max,
            if r.stable { "yes" } else { "NO" },
            r.absolute.map_or("—", |p| if p { "pass" } else { "fail" }),
            r.extra
        );
    }
    println!("initial gait: extra apex after the block {initial_extra:.2} cm");
}

/// The acceptance check measures what it should on the initial gait (constant gains): it
/// keeps hopping under every draw and every leg and ground variant (no collapse, none off
/// the gait), so it passes the relative check; its own spread (≈ 8 cm) fails the absolute
/// one.
#[test]
fn the_check_passes_the_initial_gait_relatively_and_fails_it_absolutely() {
    let (_, r) = initial();
    println!("initial policy (θ = 0): {}", r.summary());
    assert_eq!(r.theta.runs, CHECK_DRAWS);
    assert_eq!(r.legs.len(), 14);
    assert_eq!(r.nominal.len(), 20);
    let legs = r.leg_runs();
    assert_eq!((r.theta.collapsed, legs.collapsed), (0, 0));
    assert_eq!((r.theta.off_gait, legs.off_gait), (0, 0));
    assert!(r.passes_relative());
    assert!(!r.passes_absolute());
}

/// ROCK* over ten seeds at the reduced budget: rates, not one lucky seed (the runs are the
/// 1000 column of findings/hopping.md §15, bit for bit). Asserted: at least 9 of 10 runs hop
/// stably on all 20 unseen courses (observed 10), at least 8 of 10 have an unseen median at
/// most 75 % of the initial gait's 8.24 cm (observed 10, at 1.95–5.89 cm), at least 8 of 10
/// cut the extra apex after the 5.5 cm block by at least 1.4× (observed 10, 1.44–3.63×;
/// 6.06 cm for the initial gait), and the median of that cut over the runs is at least 2×
/// (observed 2.2×). The issue's targets are printed, not asserted, because they are missed:
/// no run reaches 1.5 cm (so none is checked for acceptance), and the paper's five-fold cut
/// is not reached by any run.
#[test]
fn rockstar_rates_over_seeds() {
    let (initial_extra, r) = initial();
    let initial_median = median(r.nominal.clone());
    let runs = runs();
    table(runs, *initial_extra);
    let stable = runs.iter().filter(|r| r.stable).count();
    let reduced = runs
        .iter()
        .filter(|r| r.stable && r.median <= 0.75 * initial_median)
        .count();
    let cuts: Vec<f64> = runs.iter().map(|r| initial_extra / r.extra).collect();
    let cut = cuts.iter().filter(|&&c| c >= 1.4).count();
    let median_cut = median(cuts.clone());
    let target = runs.iter().filter(|r| r.absolute == Some(true)).count();
    let five_fold = cuts.iter().filter(|&&c| c >= 5.0).count();
    println!(
        "{stable} of 10 stable; {reduced} of 10 at ≤ 75 % of the initial {initial_median:.2} cm; \
         {cut} of 10 cut the block's extra apex ≥ 1.4× (median cut {median_cut:.2}×); targets: \
         {target} of 10 at ≤ 1.5 cm passing the absolute check, {five_fold} of 10 at a five-fold cut"
    );
    assert!(stable >= 9, "{stable} of 10 runs hop stably");
    assert!(
        reduced >= 8,
        "{reduced} of 10 runs at ≤ 75 % of the initial spread"
    );
    assert!(cut >= 8, "{cut} of 10 runs cut the extra apex ≥ 1.4×");
    assert!(median_cut >= 2.0, "median cut {median_cut}");
}
