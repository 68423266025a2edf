//! The hopping leg learned with the library's ROCK* ([`Rockstar`], `Rockstar<31, 155>`) on
//! a new block course every episode, as the paper's blocks were slid in by hand (Hwangbo et
//! al., "ROCK*: Efficient black-box optimization for policy learning", Humanoids 2014,
//! section IV), from the tuned nominal gait (θ = 0: constant gains, the initial policy the
//! paper describes), with the paper's cost terms (apex deviation, hops, energy, limits)
//! aimed at the apex variation ([`hopping::spread_apex_config`]). One thread.
//!
//! ```text
//! cargo run --release -p experiments --example hopper_rockstar -- [SEED ...]
//! ```
//!
//! For every seed (default 1): ROCK* from θ = 0 with σ₀ = `SIGMA0` (default 0.1, relative
//! to the box's half-widths) for `BUDGET` learning episodes (default 3000). Every `EVERY`
//! episodes (default 250) θ* is scored on the validation courses 20 001–20 010 (10 rollouts
//! each time, counted in the rollouts reported) and the best-scored θ* is kept (early
//! stopping). Printed for each budget in `REPORT` (default 500, 1000, 2000, 3000): the kept
//! θ*'s apex spread median / max (cm) on the unseen courses 10 001–10 005, whether it hops
//! stably on all, the rollouts spent; then the last θ*, the best told θ, and the
//! robustness check ([`hopping::robustness`]: 100 draws of ± 2 % of every parameter's
//! range, legs with mass and ground stiffness ± 10 %) of the kept θ*. After all seeds, the
//! fraction of runs whose kept θ* has an unseen median ≤ 1.5 cm at each budget.
//!
//! The ROCK* settings are [`RockstarConfig::DEFAULT`] (the paper's and the authors' code's)
//! unless `XI` (ξ; `XI=1.0075`, ≈ ζ^{0.1}, is `hopping::noisy_rockstar_config`), `LAMBDA`
//! (λ) or `TOLERANCE` (σ at which a search stops) are set; `RESTART=σ` starts a new search
//! from θ* with that σ₀ whenever one stops with episodes left (a restart).
//!
//! `OPT=cmaes` runs the library's `Cmaes<31, 14>` instead (σ₀ `SIGMA0`, deploys its mean,
//! as findings/hopping.md §7), one thread. `ROBUST=t,m,k` learns (and validates) under
//! random perturbations: every rollout's parameters moved uniformly by ± t of their range,
//! its leg mass and ground stiffness scaled by 1 ± m and 1 ± k ([`hopping::Perturbation`]),
//! drawn from RNG seed 1 000 000 + seed.

use std::time::Instant;

use ctrl_adapt::optimizer::{Optimizer, Rockstar, RockstarConfig, Vector};
use experiments::hopping::{self, P, Perturbation, Scores};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

fn env<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name).map_or(default, |v| {
        v.parse()
            .unwrap_or_else(|_| panic!("{name}: cannot parse {v:?}"))
    })
}

fn main() {
    let seeds: Vec<u64> = std::env::args()
        .skip(1)
        .map(|s| s.parse().expect("SEED"))
        .collect();
    let seeds = if seeds.is_empty() { vec![1] } else { seeds };
    let budget: u32 = env("BUDGET", 3000);
    let sigma0: f32 = env("SIGMA0", 0.1);
    let every: u32 = env("EVERY", 250);
    let cmaes = std::env::var("OPT").is_ok_and(|o| o == "cmaes");
    let report: Vec<u32> = std::env::var("REPORT").map_or_else(
        |_| vec![500, 1000, 2000, 3000],
        |v| v.split(',').map(|b| b.parse().expect("REPORT")).collect(),
    );
    let perturbation = std::env::var("ROBUST").map_or(Perturbation::NONE, |v| {
        let f: Vec<f64> = v.split(',').map(|x| x.parse().expect("ROBUST")).collect();
        assert_eq!(f.len(), 3, "ROBUST=t,m,k");
        Perturbation {
            theta: f[0] as f32,
            leg_mass: f[1],
            ground_stiffness: f[2],
        }
    });
    let apex = hopping::spread_apex_config();
    let name = if cmaes { "Cmaes" } else { "Rockstar" };
    println!(
        "{name} σ₀ {sigma0}, budget {budget}, validation every {every}, perturbation {perturbation:?}"
    );
    println!(
        "| seed | budget | kept at episode | rollouts | validation cost | unseen median | unseen max | stable |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |");
    let mut success = vec![0usize; report.len()];
    for &seed in &seeds {
        let t = Instant::now();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut prng = Xoshiro256PlusPlus::seed_from_u64(1_000_000 + seed);
        let (scores, last, best): (Scores, Vector<P>, Vector<P>) = if cmaes {
            let mut o =
                hopping::fresh_cmaes(Vector::zeros(), sigma0, budget, false).expect("valid config");
            let s = hopping::learn_sequentially(
                &mut o,
                |o| o.mean(),
                |_, _| None,
                budget,
                apex,
                perturbation,
                &mut rng,
                &mut prng,
                every,
            )
            .expect("episode");
            (s, o.mean(), o.best().expect("told").theta)
        } else {
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
            let mut restarts = 0;
            let s = hopping::learn_sequentially(
                &mut o,
                Rockstar::theta_star,
                |o: &hopping::HopRockstar, left| {
                    let sigma = restart_sigma?;
                    restarts += 1;
                    let config = RockstarConfig {
                        initial_sigma: sigma,
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
                &mut rng,
                &mut prng,
                every,
            )
            .expect("episode");
            println!(
                "  {restarts} restarts; last search: σ {:.3e}, {} updates, {} covariance updates, {} recoveries",
                o.sigma(),
                o.updates(),
                o.covariance_updates(),
                o.recoveries()
            );
            (s, o.theta_star(), o.best().expect("told").theta)
        };
        let learning = t.elapsed().as_secs_f64();
        for (i, &b) in report.iter().enumerate() {
            let kept = scores.kept(b).expect("scored at the start");
            let (spreads, stable) =
                hopping::spreads_on(kept.theta, hopping::UNSEEN_COURSES).expect("episode");
            let max = spreads.iter().copied().fold(0.0, f64::max);
            let median = host_tests::median(spreads);
            if median <= 1.5 && stable {
                success[i] += 1;
            }
            println!(
                "| {seed} | {b} | {} | {} | {:.3e} | {median:.2} | {max:.2} | {} |",
                kept.episode,
                kept.rollouts,
                kept.validation_cost,
                if stable { "yes" } else { "NO" }
            );
        }
        for (label, theta) in [("last θ*/mean", last), ("best told θ", best)] {
            let (spreads, stable) =
                hopping::spreads_on(theta, hopping::UNSEEN_COURSES).expect("episode");
            println!(
                "  {label}: unseen median {:.2}, stable {stable}",
                host_tests::median(spreads)
            );
        }
        let kept = scores.kept(budget).expect("scored");
        let r = hopping::robustness(kept.theta, 100, 7).expect("episode");
        println!(
            "  robustness of the kept θ (episode {}): {}; passes: {}",
            kept.episode,
            r.summary(),
            r.passes()
        );
        for l in &r.legs {
            println!(
                "    mass ×{}, stiffness ×{}: spreads {:.2?}, {} pass",
                l.mass, l.stiffness, l.spreads, l.passed
            );
        }
        println!("  kept θ = {:?}", kept.theta.as_slice());
        println!(
            "  seed {seed}: {learning:.0} s learning, {:.0} s in all",
            t.elapsed().as_secs_f64()
        );
    }
    for (b, s) in report.iter().zip(&success) {
        println!(
            "budget {b}: {s} of {} runs keep a θ with unseen median ≤ 1.5 cm (stable)",
            seeds.len()
        );
    }
}
