//! The hopping leg learned with the library's ROCK* ([`Rockstar`], `Rockstar<31, 155>`) on
//! a new block course every episode, as the paper's blocks were slid in by hand (Hwangbo et
//! al., "ROCK*: Efficient black-box optimization for policy learning", Humanoids 2014,
//! section IV), from the tuned nominal gait (θ = 0: constant gains, the initial policy the
//! paper describes), with the paper's cost terms (apex deviation, hops, energy, limits)
//! aimed at the apex variation ([`hopping::spread_apex_config`]); or with `Cmaes`,
//! `CoordinateSearch` or `DiagonalCem` in the same harness.
//!
//! ```text
//! cargo run --release -p experiments --example hopper_rockstar -- [SEED ...]
//! ```
//!
//! For every seed (default 1): the optimizer from θ = 0 for `BUDGET` learning episodes
//! (default 3000). Every `EVERY` episodes (default 250) its deployable policy (ROCK*'s θ*,
//! the CMA-ES and CEM mean, the coordinate search's best point) is scored on the validation
//! courses 20 001–20 010 (10 rollouts each time, counted in the rollouts reported) and the
//! best-scored one is kept (early stopping). Printed for each budget in `REPORT` (default
//! 500, 1000, 2000, 3000): the kept policy's apex spread median / max (cm) on the 20 unseen
//! courses 10 001–10 020, whether it hops stably on all, the rollouts spent, and — when the
//! median is ≤ 1.5 cm and it hops stably — the acceptance check ([`hopping::robustness`]:
//! 100 draws of ± 2 % of every parameter's range; leg mass ± 10 %, ground stiffness and
//! dissipation ×0.5–×2) with its absolute verdict. A run **succeeds** at the first budget
//! whose kept policy has a median ≤ 1.5 cm, hops stably and passes the absolute check; its
//! rollouts are those spent up to the kept policy. Then, per run, the extra apex after the
//! 5.5 cm block ([`hopping::block_extra_apex`], 20 unseen courses) of the final kept policy
//! against the initial gait's. At the end: successes and rollouts per optimizer, and
//! learning curves (the median over seeds of the lowest validation cost so far, against
//! rollouts) as an SVG at `SVG` (default `target/figures/hopper-learning.svg`).
//!
//! `OPT` = `rockstar` (default), `cmaes`, `coordinate`, `cem`, or a comma-separated list
//! (`all` = the four). Seeds run on the machine's cores (`hopping::map_seeds`); each run is
//! the same whatever the number of threads.
//!
//! ROCK*'s settings are [`RockstarConfig::DEFAULT`] (the paper's and the authors' code's;
//! σ₀ `SIGMA0`, default 0.1) unless `XI` (ξ; `XI=1.0075`, ≈ ζ^{0.1}, is
//! `hopping::noisy_rockstar_config`), `LAMBDA` or `TOLERANCE` are set; `RESTART=σ` starts a new search
//! from θ* with that σ₀ whenever one stops with episodes left. `Cmaes<31, 14>`: σ₀
//! `CMAES_SIGMA0` (default 0.3), no active weights. `CoordinateSearch`: steps a sixth of each
//! half-range ([`hopping::coordinate_search`]). `DiagonalCem<31, 20, 20>` (PI-BB, h = 10,
//! covariance adaptation): standard deviations σ₀ `SIGMA0` of each half-range.
//!
//! `ROBUST=t,m,k,c[,worst:K|mean:K]` (or `ROBUST=check`, the check's ranges) learns and
//! validates under random perturbations (domain randomisation, [`hopping::Perturbation`]):
//! every rollout's parameters moved by ± t of their range, leg mass by ± m, ground stiffness
//! and dissipation by log-uniform factors in [1/k, k] and [1/c, c]; each learning episode
//! scored as one draw, the worst of K or the mean of K, drawn from RNG seed 1 000 000 + seed.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use ctrl_adapt::optimizer::{
    CemConfig, DiagonalCem, Optimizer, Rockstar, RockstarConfig, Vector, Weighting,
};
use experiments::hopping::{self, DrawScore, P, Perturbation, Scores, UNSEEN_COURSES};
use host_tests::median;
use host_tests::plots::{Series, log_cost_curves};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

fn env<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).map_or(default, |v| {
        v.parse()
            .unwrap_or_else(|_| panic!("{name}: cannot parse {v:?}"))
    })
}

/// The perturbation of `ROBUST`.
fn perturbation() -> Perturbation {
    let Ok(v) = std::env::var("ROBUST") else {
        return Perturbation::NONE;
    };
    if v == "check" {
        return Perturbation::CHECK;
    }
    let parts: Vec<&str> = v.split(',').collect();
    assert!(
        parts.len() == 4 || parts.len() == 5,
        "ROBUST=t,m,k,c[,worst:K|mean:K]"
    );
    let f: Vec<f64> = parts[..4]
        .iter()
        .map(|x| x.parse().expect("ROBUST"))
        .collect();
    let score = match parts.get(4).map(|s| s.split_once(':')) {
        None => DrawScore::One,
        Some(Some(("worst", k))) => DrawScore::WorstOf(k.parse().expect("ROBUST worst:K")),
        Some(Some(("mean", k))) => DrawScore::MeanOf(k.parse().expect("ROBUST mean:K")),
        Some(_) => panic!("ROBUST: the fifth field is worst:K or mean:K"),
    };
    Perturbation {
        theta: f[0] as f32,
        leg_mass: f[1],
        ground_stiffness: f[2],
        ground_damping: f[3],
        score,
    }
}

/// One learning run: the scorings of its deployable policy.
fn learn(opt: &str, seed: u64, budget: u32, perturbation: Perturbation) -> Scores {
    let apex = hopping::spread_apex_config();
    let every: u32 = env("EVERY", 250);
    let sigma0: f32 = env("SIGMA0", 0.1);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut prng = Xoshiro256PlusPlus::seed_from_u64(1_000_000 + seed);
    let mut run =
        |o: &mut dyn FnMut(&mut Xoshiro256PlusPlus, &mut Xoshiro256PlusPlus) -> Scores| {
            o(&mut rng, &mut prng)
        };
    match opt {
        "cmaes" => run(&mut |rng, prng| {
            let mut o =
                hopping::fresh_cmaes(Vector::zeros(), env("CMAES_SIGMA0", 0.3), budget, false)
                    .expect("valid config");
            hopping::learn_sequentially(
                &mut o,
                |o| o.mean(),
                |_, _| None,
                budget,
                apex,
                perturbation,
                rng,
                prng,
                every,
            )
            .expect("episode")
        }),
        "coordinate" => run(&mut |rng, prng| {
            let mut o = hopping::coordinate_search(Vector::zeros(), budget).expect("valid config");
            hopping::learn_sequentially(
                &mut o,
                |o| o.best().map_or(Vector::zeros(), |b| b.theta),
                |_, _| None,
                budget,
                apex,
                perturbation,
                rng,
                prng,
                every,
            )
            .expect("episode")
        }),
        "cem" => run(&mut |rng, prng| {
            let sigma = *hopping::bounds().upper() * sigma0;
            let config = CemConfig {
                weighting: Weighting::PiBb { h: 10.0 },
                exploration_floor: 1e-7,
                max_variance: 28.0,
                max_evaluations: budget,
                ..CemConfig::DEFAULT
            };
            let mut o = DiagonalCem::<P, 20, 20>::try_with_variances(
                hopping::bounds(),
                Vector::zeros(),
                sigma.component_mul(&sigma),
                config,
            )
            .expect("valid config");
            hopping::learn_sequentially(
                &mut o,
                |o| *o.mean(),
                |_, _| None,
                budget,
                apex,
                perturbation,
                rng,
                prng,
                every,
            )
            .expect("episode")
        }),
        "rockstar" => run(&mut |rng, prng| {
            let config = RockstarConfig {
                xi: std::env::var("XI").ok().map(|v| v.parse().expect("XI")),
                lambda: env("LAMBDA", RockstarConfig::DEFAULT.lambda),
                tolerance: env("TOLERANCE", RockstarConfig::DEFAULT.tolerance),
                ..hopping::rockstar_config(sigma0, budget)
            };
            let mut o = hopping::HopRockstar::try_new(hopping::bounds(), Vector::zeros(), config)
                .expect("valid config");
            let restart_sigma: Option<f32> = std::env::var("RESTART")
                .ok()
                .map(|v| v.parse().expect("RESTART"));
            hopping::learn_sequentially(
                &mut o,
                Rockstar::theta_star,
                |o: &hopping::HopRockstar, left| {
                    let config = RockstarConfig {
                        initial_sigma: restart_sigma?,
                        max_evaluations: left,
                        ..*o.config()
                    };
                    Some(
                        hopping::HopRockstar::try_new(hopping::bounds(), o.theta_star(), config)
                            .expect("valid config"),
                    )
                },
                budget,
                apex,
                perturbation,
                rng,
                prng,
                every,
            )
            .expect("episode")
        }),
        other => panic!("OPT: unknown optimizer {other:?}"),
    }
}

/// What one run printed and what the summary needs.
struct Run {
    lines: Vec<String>,
    /// Rollouts to the first success, if any.
    success: Option<u32>,
    /// (rollouts, lowest validation cost so far) after every scoring.
    curve: Vec<(u32, f64)>,
}

fn evaluate(opt: &str, seed: u64, budget: u32, report: &[u32], initial_extra: f64) -> Run {
    let t = Instant::now();
    let scores = learn(opt, seed, budget, perturbation());
    let mut lines = Vec::new();
    let mut success = None;
    let mut checked: HashMap<Vec<u32>, bool> = HashMap::new();
    for &b in report {
        let kept = scores.kept(b).expect("scored at the start");
        let (spreads, stable) = hopping::spreads_on(kept.theta, UNSEEN_COURSES).expect("episode");
        let max = spreads.iter().copied().fold(0.0, f64::max);
        let med = median(spreads);
        let mut verdict = String::from("—");
        if med <= 1.5 && stable {
            let key: Vec<u32> = kept.theta.iter().map(|v| v.to_bits()).collect();
            let pass = *checked.entry(key).or_insert_with(|| {
                let r = hopping::robustness(kept.theta, hopping::CHECK_DRAWS, 7).expect("episode");
                lines.push(format!(
                    "  check of the policy kept at {b}: {}",
                    r.summary()
                ));
                r.passes_absolute()
            });
            verdict = if pass { "pass" } else { "fail" }.into();
            if pass && success.is_none() {
                success = Some(kept.rollouts);
            }
        }
        lines.push(format!(
            "| {opt} | {seed} | {b} | {} | {} | {:.3e} | {med:.2} | {max:.2} | {} | {verdict} |",
            kept.episode,
            kept.rollouts,
            kept.validation_cost,
            if stable { "yes" } else { "NO" }
        ));
    }
    let kept = scores.kept(budget).expect("scored");
    let extra = hopping::block_extra_apex(kept.theta, UNSEEN_COURSES).expect("episode");
    lines.push(format!(
        "  {opt} seed {seed}: extra apex after the 5.5 cm block {extra:.2} cm (initial gait \
         {initial_extra:.2} cm, reduced {:.1}×); success {}; {:.0} s",
        initial_extra / extra,
        success.map_or("no".into(), |r| format!("at {r} rollouts")),
        t.elapsed().as_secs_f64()
    ));
    lines.push(format!("  kept θ = {:?}", kept.theta.as_slice()));
    let mut lowest = f64::INFINITY;
    let curve = scores
        .0
        .iter()
        .map(|s| {
            lowest = lowest.min(s.validation_cost);
            (s.rollouts, lowest)
        })
        .collect();
    Run {
        lines,
        success,
        curve,
    }
}

fn main() {
    let seeds: Vec<u64> = std::env::args()
        .skip(1)
        .map(|s| s.parse().expect("SEED"))
        .collect();
    let seeds = if seeds.is_empty() { vec![1] } else { seeds };
    let budget: u32 = env("BUDGET", 3000);
    let report: Vec<u32> = std::env::var("REPORT").map_or_else(
        |_| vec![500, 1000, 2000, 3000],
        |v| v.split(',').map(|b| b.parse().expect("REPORT")).collect(),
    );
    let opts: Vec<String> = match std::env::var("OPT").as_deref() {
        Err(_) => vec!["rockstar".into()],
        Ok("all") => ["rockstar", "cmaes", "coordinate", "cem"]
            .map(String::from)
            .to_vec(),
        Ok(v) => v.split(',').map(String::from).collect(),
    };
    println!(
        "budget {budget}, perturbation {:?}, optimizers {opts:?}, seeds {seeds:?}",
        perturbation()
    );
    let initial_extra =
        hopping::block_extra_apex(Vector::zeros(), UNSEEN_COURSES).expect("episode");
    let initial = hopping::robustness(Vector::zeros(), hopping::CHECK_DRAWS, 7).expect("episode");
    println!(
        "initial gait: extra apex after the 5.5 cm block {initial_extra:.2} cm; {}",
        initial.summary()
    );
    println!(
        "| optimizer | seed | budget | kept at episode | rollouts | validation cost | unseen median | unseen max | stable | absolute check |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |");
    let mut curves: Vec<(String, Vec<f64>)> = Vec::new();
    let mut summary = Vec::new();
    for opt in &opts {
        let runs = hopping::map_seeds(&seeds, |s| {
            let run = evaluate(opt, s, budget, &report, initial_extra);
            for l in &run.lines {
                println!("{l}");
            }
            run
        });
        let mut rollouts: Vec<u32> = runs.iter().filter_map(|r| r.success).collect();
        rollouts.sort_unstable();
        summary.push(format!(
            "{opt}: {} of {} runs succeed (median ≤ 1.5 cm on 20 unseen courses, stable, absolute check) within {budget} episodes; rollouts to success {rollouts:?}",
            rollouts.len(),
            runs.len()
        ));
        // Median over seeds of the lowest validation cost so far, at every rollout.
        let last = runs
            .iter()
            .filter_map(|r| r.curve.last())
            .map(|c| c.0)
            .max()
            .unwrap_or(1);
        let first = runs
            .iter()
            .filter_map(|r| r.curve.first())
            .map(|c| c.0)
            .max()
            .unwrap_or(1);
        let series: Vec<f64> = (first..=last)
            .map(|k| {
                median(
                    runs.iter()
                        .filter_map(|r| r.curve.iter().rev().find(|c| c.0 <= k).map(|c| c.1))
                        .collect(),
                )
            })
            .collect();
        curves.push((opt.clone(), series));
    }
    for s in &summary {
        println!("{s}");
    }
    let path = PathBuf::from(
        std::env::var("SVG").unwrap_or_else(|_| "target/figures/hopper-learning.svg".into()),
    );
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).expect("figure directory");
    }
    let series: Vec<Series> = curves
        .iter()
        .map(|(name, values)| Series { name, values })
        .collect();
    log_cost_curves(
        &path,
        "hopping leg: median over seeds of the best validation cost so far",
        &series,
        "validation cost (10 courses)",
    )
    .expect("plot");
    println!("learning curves: {}", path.display());
}
