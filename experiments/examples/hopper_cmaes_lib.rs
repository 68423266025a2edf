//! The hopping leg learned with the **library's** [`Cmaes`] (f32, `Cmaes<31, 14>`), to check
//! that it reproduces the host-only f64 diagnostic `hopper_cmaes.rs` (findings/hopping.md).
//!
//! ```text
//! cargo run --release -p experiments --example hopper_cmaes_lib -- [RUN ...]
//! ```
//!
//! Each RUN is `start:sigma0:budget:cost:seed`, e.g. `zero:0.15:6000:plain:1` (the default):
//! * `start`: `zero` (θ = 0) or `env` (the θ in `CMAES_THETA`, comma-separated, as printed);
//! * `sigma0`: initial step size relative to the box's half-widths;
//! * `budget`: episodes;
//! * `cost`: `plain` — the episodes run through the library's [`Adapter`]
//!   (`hopping::adapter`, `run_episode` on the training course 1001; the adapter asks
//!   the optimizer and tells it the `ApexHeightCost`, or the failure cost on a collapse);
//!   `shaped` / `shaped3` — the optimizer driven directly (ask, `evaluate`, tell) with the
//!   shaped cost of the diagnostic (apex term without the first 3 apexes + 10 · spread², on
//!   course 1001, or averaged over 1001–1003); `generation` / `fresh` — plain cost through
//!   the adapter, but on a new course every generation (the λ candidates of a generation
//!   share it: common random numbers within the ranking) or every episode (seeds
//!   100 000 + generation or + episode); the rows then report the search's mean, not its
//!   best told θ (a lucky draw on an easy course); `freshspread` — a new course every
//!   episode with the spread-weighted cost `hopping::spread_apex_config`, through
//!   `hopping::learn_on_fresh_courses`, its episodes on all cores, or `THREADS`);
//!   `refine` — the optimizer driven directly with the spread-weighted cost averaged over
//!   a fixed set of `REFINE_N` courses (default 5, seeds 30 001 …), usually from `env`;
//! * `seed`: the RNG seed of the optimizer's draws.
//!
//! Box penalty 0.01 (as the diagnostic), tolerance 1e-6, a decomposition every generation;
//! `ACTIVE=1` turns on the active (negative) weights (`CmaesConfig::active`).
//! During a `fresh` / `freshspread` run the search's mean is scored every 1000 episodes on the
//! validation courses 20 001–20 010 (mean told cost; `MISSING_HOP` overrides the cost per
//! missing hop) and the best is printed as the run's "kept by validation" row (early
//! stopping); after several runs, the run with the lowest validation cost.
//! The rows printed are those of findings/hopping.md's table: best objective, the plain cost on
//! course 1001 split into apex term + rest, training spread, unseen median / max (courses
//! 10 001–10 005), stability; plus σ and the axis ratio.
//!
//! [`Adapter`]: ctrl_adapt::controller::Adapter

use std::time::Instant;

use ctrl_adapt::optimizer::{Cmaes, Optimizer, Status, Vector};
use experiments::hopping::{self, HopEpisode, P, evaluate, plant, run_episode, training_course};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

/// λ = 4 + ⌊3 ln 31⌋.
const LAMBDA: usize = hopping::FRESH_LAMBDA;

/// Episodes at which the best-so-far θ is reported.
const CHECKPOINTS: &[u32] = &[1000, 2000, 4000, 6000, 8000, 10_000, 12_000, 14_000, 16_000];

/// Unseen courses of `tests/hopper_experiments.rs`.

#[derive(Clone, Copy, PartialEq)]
enum Cost {
    Plain,
    Shaped,
    Shaped3,
    /// Plain cost, a new course every generation (all λ candidates of a generation on the
    /// same one): seed 100 000 + generation.
    Generation,
    /// Plain cost, a new course every episode: seed 100 000 + episode.
    Fresh,
    /// The spread-weighted cost of `hopping::spread_apex_config`, a new course every
    /// episode (`hopping::learn_on_fresh_courses`, as `tests/hopper_experiments.rs`).
    FreshSpread,
    /// The spread-weighted cost averaged over a fixed set of `REFINE_N` (default 5) courses,
    /// seeds 30 001 …: a refinement with common random numbers, from `env`.
    Refine,
}

/// The diagnostic's shaped cost: the apex term without the first 3 apexes + 10 · spread².
fn shaped(e: &HopEpisode) -> f64 {
    let told = f64::from(e.report.cost);
    if e.collapsed {
        return told;
    }
    let mean_sq =
        |a: &[f64]| a.iter().map(|h| (h - 0.6).powi(2)).sum::<f64>() / a.len().max(1) as f64;
    let rest = told - mean_sq(&e.apexes);
    mean_sq(e.apexes.get(3..).unwrap_or(&[])) + rest + 10.0 * e.apex_spread().powi(2)
}

/// One row of the table ([`hopping::figures_row`]).
fn row(label: &str, episodes: u32, cost: f32, theta: Vector<P>, extra: &str) {
    let row = hopping::figures_row(label, episodes as u64, f64::from(cost), theta, extra);
    println!("{}", row.expect("episode"));
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs = if args.is_empty() {
        vec!["zero:0.15:6000:plain:1".to_string()]
    } else {
        args
    };
    println!(
        "| run | episodes | best objective | plain cost on 1001: apex + rest | training spread \
         (cm) | unseen median | unseen max | stable | notes |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |");
    let mut chosen: Vec<(f64, String)> = Vec::new();
    for run in &runs {
        let f: Vec<&str> = run.split(':').collect();
        assert_eq!(
            f.len(),
            5,
            "RUN is start:sigma0:budget:cost:seed, got {run}"
        );
        let sigma0: f32 = f[1].parse().expect("sigma0");
        let budget: u32 = f[2].parse().expect("budget");
        let cost = match f[3] {
            "plain" => Cost::Plain,
            "shaped" => Cost::Shaped,
            "shaped3" => Cost::Shaped3,
            "generation" => Cost::Generation,
            "fresh" => Cost::Fresh,
            "freshspread" => Cost::FreshSpread,
            "refine" => Cost::Refine,
            c => panic!("cost {c}"),
        };
        let seed: u64 = f[4].parse().expect("seed");
        let start = match f[0] {
            "zero" => Vector::<P>::zeros(),
            "env" => {
                let theta: Vec<f32> = hopping::theta_from_env().expect("CMAES_THETA is not set");
                let theta = Vector::<P>::from_column_slice(&theta);
                row("given θ (start)", 0, f32::NAN, theta, "");
                theta
            }
            s => panic!("start {s}"),
        };
        let active = std::env::var("ACTIVE").is_ok_and(|v| v == "1");
        let label = format!(
            "library {} σ₀ {sigma0} {}{} seed {seed}",
            f[0],
            f[3],
            if active { " active" } else { "" }
        );
        let refine_n: u64 = std::env::var("REFINE_N").map_or(5, |v| v.parse().unwrap());
        let refine: Vec<u64> = (30_001..30_001 + refine_n).collect();
        let courses: &[u64] = if cost == Cost::Shaped3 {
            &[1001, 1002, 1003]
        } else if cost == Cost::Refine {
            &refine
        } else {
            &[1001]
        };
        let evaluations = budget.div_ceil(courses.len() as u32);
        let cma = hopping::fresh_cmaes(start, sigma0, evaluations, active).expect("valid config");
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let t = Instant::now();
        let report = |cma: &Cmaes<P, LAMBDA>, episodes: u32| {
            let best = cma.best().expect("told");
            // On changing courses the best told cost is a lucky draw: report the mean.
            let (cost, theta) =
                if matches!(cost, Cost::Generation | Cost::Fresh | Cost::FreshSpread) {
                    (f32::NAN, cma.mean())
                } else {
                    (best.cost, best.theta)
                };
            row(
                &label,
                episodes,
                cost,
                theta,
                &format!(
                    "σ {:.2e}, axis ratio {:.0}, {:.0} s",
                    cma.sigma(),
                    cma.axis_ratio(),
                    t.elapsed().as_secs_f64()
                ),
            );
        };
        let checkpoint = |cma: &Cmaes<P, LAMBDA>| {
            let episodes = cma.evaluations() * courses.len() as u32;
            if CHECKPOINTS.contains(&episodes) && episodes < budget {
                report(cma, episodes);
            }
        };
        let cma = if matches!(cost, Cost::Fresh | Cost::FreshSpread) {
            let mut apex = if cost == Cost::Fresh {
                hopping::apex_config()
            } else {
                hopping::spread_apex_config()
            };
            if let Ok(m) = std::env::var("MISSING_HOP") {
                apex.missing_hop_cost = m.parse().expect("MISSING_HOP");
            }
            let threads = std::env::var("THREADS")
                .map_or_else(|_| hopping::threads(), |t| t.parse().expect("THREADS"));
            // Early stopping: every 1000 episodes the mean is scored on the validation
            // courses (10 episodes more); the best is what a robot would keep.
            let kept = hopping::learn_with_validation(
                cma,
                budget,
                apex,
                &mut rng,
                threads,
                1000,
                |_, cma| checkpoint(cma),
            )
            .expect("episode");
            row(
                &format!("{label}, kept by validation"),
                kept.episode,
                kept.validation_cost as f32,
                kept.theta,
                "the mean with the lowest validation cost (every 1000 episodes)",
            );
            chosen.push((kept.validation_cost, format!("{label} at {}", kept.episode)));
            kept.cma
        } else if matches!(cost, Cost::Plain | Cost::Generation) {
            let mut adapter = hopping::adapter(cma, budget, start).expect("adapter");
            for k in 0..u64::from(budget) {
                let mut course = match cost {
                    Cost::Generation => plant(true, 100_000 + k / LAMBDA as u64),
                    _ => training_course(),
                };
                run_episode(&mut adapter, &mut course, &mut rng, false).expect("episode");
                checkpoint(adapter.optimizer());
                if adapter.optimizer().status() != Status::Running {
                    break;
                }
            }
            adapter.optimizer().clone()
        } else {
            let mut cma = cma;
            let mut eval_rng = Xoshiro256PlusPlus::seed_from_u64(3);
            while let Ok(theta) = cma.ask(&mut rng) {
                let c = courses
                    .iter()
                    .map(|&s| {
                        if cost == Cost::Refine {
                            return f64::from(
                                hopping::told_cost(theta, s, hopping::spread_apex_config())
                                    .unwrap(),
                            );
                        }
                        shaped(
                            &evaluate(theta, &mut plant(true, s), &mut eval_rng, false)
                                .expect("episode"),
                        )
                    })
                    .sum::<f64>()
                    / courses.len() as f64;
                cma.tell(c as f32).expect("finite cost");
                checkpoint(&cma);
            }
            cma
        };
        report(&cma, cma.evaluations() * courses.len() as u32);
        println!(
            "  {label}: {:?} after {} generations, {} recoveries",
            cma.status(),
            cma.generations(),
            cma.recoveries()
        );
        println!("  θ = {:?}", cma.best().expect("told").theta.as_slice());
        println!("  mean = {:?}", cma.mean().as_slice());
    }
    // Independent runs with a selection: the one a robot would keep is the run whose mean
    // costs least on the validation courses (not on the unseen courses reported above).
    if chosen.len() > 1 {
        chosen.sort_by(|a, b| a.0.total_cmp(&b.0));
        println!(
            "lowest validation cost: {} ({:.3e})",
            chosen[0].1, chosen[0].0
        );
    }
}
