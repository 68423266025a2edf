//! The hopping experiment of Hwangbo et al., section IV, through the library's own
//! controller stack (`Adapter` over `PeriodicPd`, 31 parameters, `ApexHeightCost`), learning
//! with the library's `CoordinateSearch` (ROCK* is not available). Heavy: compiled in release
//! builds only (debug `cargo test` skips it),
//!
//! ```text
//! cargo test --release -p experiments --test hopper_experiments -- --nocapture
//! ```
//!
//! Learning: 400 episodes of 12 s, every one on the same training course (the block
//! sequence of seed 1001, replayed: common random numbers). Evaluation: the initial and the
//! learned policy on the 20 courses never used in learning (`hopping::UNSEEN_COURSES`, seeds
//! 10 001–10 020).
//!
//! Also checks that the fresh-course CMA-ES learner of `findings/hopping.md`
//! (`hopping::learn_on_fresh_courses`, 12 000 episodes per run: not run here), which runs
//! a generation's episodes on several threads, is the sequential run through a learning
//! `Adapter`, bit for bit. That learner reaches the paper's ≈ 1 cm on about one run in four
//! (12 000 episodes) to one in two (20 000), with active weights on four runs in sixteen at
//! 12 000; no test asserts it (a seed that happens to pass would break
//! with any change to the random streams).

#![cfg(not(debug_assertions))]

use std::sync::OnceLock;

use ctrl_adapt::optimizer::{Optimizer, Vector};
use experiments::hopping::{
    self, HopEpisode, LEARNING_EPISODES, P, coordinate_search, evaluate, fresh_cmaes,
    learn_on_fresh_courses, plant, run_episode, spread_apex_config, training_course,
};

/// σ₀ of the fresh-course CMA-ES runs of findings/hopping.md (relative to the half-ranges).
const FRESH_SIGMA0: f32 = 0.3;
use host_tests::median;
use rand_core::SeedableRng;
use rand_xoshiro::{Xoshiro128PlusPlus, Xoshiro256PlusPlus};

const EVAL_SEEDS: std::ops::RangeInclusive<u64> = experiments::hopping::UNSEEN_COURSES;

struct Learned {
    theta: Vector<P>,
    costs: Vec<f32>,
}

/// The learning run, shared by the tests of this file (computed once).
fn learned() -> &'static Learned {
    static LEARNED: OnceLock<Learned> = OnceLock::new();
    LEARNED.get_or_init(|| {
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
        let search = coordinate_search(Vector::zeros(), LEARNING_EPISODES).unwrap();
        let mut adapter = hopping::adapter(search, LEARNING_EPISODES, Vector::zeros()).unwrap();
        let costs: Vec<f32> = (0..LEARNING_EPISODES)
            .map(|_| {
                let e = run_episode(&mut adapter, &mut training_course(), &mut rng, false);
                e.unwrap().report.cost
            })
            .collect();
        let best = adapter.optimizer().best().unwrap();
        println!(
            "learning: {} episodes, best training cost {:.3e} (first {:.3e}), θ = {:.3?}",
            LEARNING_EPISODES,
            best.cost,
            costs_first(&costs),
            best.theta.as_slice()
        );
        Learned {
            theta: best.theta,
            costs,
        }
    })
}

fn costs_first(costs: &[f32]) -> f32 {
    costs.first().copied().unwrap_or(f32::NAN)
}

fn evaluations(theta: Vector<P>) -> Vec<HopEpisode> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2);
    EVAL_SEEDS
        .map(|s| evaluate(theta, &mut plant(true, s), &mut rng, false).unwrap())
        .collect()
}

fn spreads(episodes: &[HopEpisode]) -> Vec<f64> {
    episodes.iter().map(HopEpisode::apex_spread).collect()
}

/// Checks, on the 20 courses unseen in learning:
/// * the initial policy (tuned on flat ground) keeps hopping and its apex varies by several
///   cm: spread (max − min after 3 hops) above 3 cm on every course (measured 6.6–9.6 cm);
/// * after 400 learning episodes the learned policy keeps hopping stably (no collapse, ≥ 15
///   hops in 12 s, mean apex within 5 cm of 0.6 m: measured 0.589–0.603 m) and its spread
///   is at most 4.5 cm on every course and at most 45 % of the initial policy's median
///   (measured on the Hunt–Crossley ground 2.6–4.0 cm, median 3.19 cm against 8.24 cm, 39 %;
///   on the earlier linear ground, over the first 5 of these courses, it was 2.1–2.4 cm,
///   median 2.2 against 7.6, and the bounds were 3 cm and 40 %).
///
/// The paper's "about 1 cm" (the issue's ≤ 1.5 cm) is NOT reached with the coordinate
/// search: see findings/hopping.md for what was tried.
#[test]
fn learning_reduces_the_apex_spread_and_keeps_hopping() {
    let before = evaluations(Vector::zeros());
    let learned = learned();
    let after = evaluations(learned.theta);
    println!("course | initial: hops, mean (m), spread (cm) | learned: hops, mean, spread");
    for ((s, b), a) in EVAL_SEEDS.zip(&before).zip(&after) {
        println!(
            "{s} | {}, {:.3}, {:.1} | {}, {:.3}, {:.1}",
            b.hops(),
            b.apex_mean(),
            b.apex_spread() * 100.0,
            a.hops(),
            a.apex_mean(),
            a.apex_spread() * 100.0
        );
    }
    let (mb, ma) = (median(spreads(&before)), median(spreads(&after)));
    println!(
        "median apex spread: initial {:.2} cm, learned {:.2} cm; training cost {:.3e} -> {:.3e}",
        mb * 100.0,
        ma * 100.0,
        costs_first(&learned.costs),
        learned.costs.iter().copied().fold(f32::INFINITY, f32::min)
    );
    for b in &before {
        assert!(b.hops_stably(), "initial policy stopped hopping");
        assert!(b.apex_spread() > 0.03, "initial spread {}", b.apex_spread());
    }
    for a in &after {
        assert!(a.hops_stably(), "learned policy stopped hopping");
        assert!(
            a.apex_spread() <= 0.045,
            "learned spread {}",
            a.apex_spread()
        );
    }
    assert!(ma <= 0.45 * mb, "median spread {ma} vs initial {mb}");
}

/// `learn_on_fresh_courses` runs a generation's episodes in parallel but is the sequential
/// run through a learning `Adapter` bit for bit: two and a half generations (35 episodes)
/// driven by the adapter one episode at a time, and by `learn_on_fresh_courses` on 1 and on
/// 3 threads, end in the same search state (mean, σ, covariance, best).
#[test]
fn fresh_course_learning_is_the_adapters_run_on_any_number_of_threads() {
    const EPISODES: u32 = 35;
    let sequential = {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        let cma = fresh_cmaes(Vector::zeros(), FRESH_SIGMA0, EPISODES, true).unwrap();
        let mut adapter = hopping::adapter_with(
            cma,
            EPISODES,
            Vector::zeros(),
            &host_tests::hopper::NominalHopping::TUNED,
            spread_apex_config(),
        )
        .unwrap();
        for k in 0..EPISODES {
            let mut course = plant(true, hopping::FRESH_COURSES + u64::from(k));
            run_episode(&mut adapter, &mut course, &mut rng, false).unwrap();
        }
        adapter.optimizer().clone()
    };
    let parallel = |threads| {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        let cma = fresh_cmaes(Vector::zeros(), FRESH_SIGMA0, EPISODES, true).unwrap();
        let mut told = 0;
        let cma = learn_on_fresh_courses(
            cma,
            EPISODES,
            spread_apex_config(),
            &mut rng,
            threads,
            |k, _| told = k,
        )
        .unwrap();
        assert_eq!(told, EPISODES);
        cma
    };
    assert_eq!(sequential.generations(), 2);
    for cma in [parallel(1), parallel(3)] {
        assert_eq!(cma.evaluations(), EPISODES);
        assert_eq!(cma.mean(), sequential.mean());
        assert_eq!(cma.sigma().to_bits(), sequential.sigma().to_bits());
        assert_eq!(cma.covariance(), sequential.covariance());
        assert_eq!(cma.best(), sequential.best());
    }
}

/// Early stopping (`learn_with_validation`) scores the search's mean on the validation
/// courses without changing the search: over 35 episodes scored every 14 (and at the end),
/// the search ends as `learn_on_fresh_courses` ends it, and the kept mean is one of the
/// scored ones with the lowest validation cost, which re-scoring reproduces.
#[test]
fn early_stopping_keeps_the_best_scored_mean_and_leaves_the_search_alone() {
    const EPISODES: u32 = 35;
    let apex = spread_apex_config();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    let mut scored = Vec::new();
    let kept = hopping::learn_with_validation(
        fresh_cmaes(Vector::zeros(), FRESH_SIGMA0, EPISODES, true).unwrap(),
        EPISODES,
        apex,
        &mut rng,
        2,
        14,
        |k, cma| {
            if k % 14 == 0 {
                scored.push(cma.mean());
            }
        },
    )
    .unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
    let plain = learn_on_fresh_courses(
        fresh_cmaes(Vector::zeros(), FRESH_SIGMA0, EPISODES, true).unwrap(),
        EPISODES,
        apex,
        &mut rng,
        2,
        |_, _| {},
    )
    .unwrap();
    assert_eq!(kept.cma.mean(), plain.mean());
    assert_eq!(kept.cma.covariance(), plain.covariance());
    scored.push(plain.mean());
    let costs: Vec<f64> = scored
        .iter()
        .map(|&theta| hopping::validation_cost(theta, apex, 2).unwrap())
        .collect();
    let best = costs.iter().copied().fold(f64::INFINITY, f64::min);
    assert!([14, 28, 35].contains(&kept.episode));
    assert_eq!(kept.validation_cost, best);
    assert_eq!(hopping::validation_cost(kept.theta, apex, 1).unwrap(), best);
}
