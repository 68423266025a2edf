//! Table I of Hwangbo, Gehring, Sommer, Siegwart & Buchli, "ROCK*: Efficient black-box
//! optimization for policy learning" (Humanoids 2014) in its shape, on the 50-parameter
//! via-point arm of `host_tests::arm` (10 links, DMPs of 5 basis functions): ROCK*
//! (`Rockstar<50, 250>`, M = 5n), CMA-ES (`Cmaes<50, 15>`, the default population) and PI-BB
//! (`DiagonalCem<50, 10, 10>`, `Weighting::PiBb { h: 10 }`), 10 seeds (0..10) × 3,000
//! rollouts each. The paper's own rows (500 and 400 parameters) are
//! `examples/rockstar_arm_tables.rs`; the findings are in `findings/rockstar-arm.md`.
//!
//! The heavy test is compiled in release builds only (≈ 10 s on one core):
//!
//! ```text
//! cargo test --release -p experiments --test rockstar_arm -- --nocapture
//! ```
//!
//! The plant checks run in debug builds too.

use host_tests::arm::ViaPointArm;
use host_tests::reaching::ReachingArm;
use host_tests::rhythmic::{self, RhythmicArm};

/// Checks the generalised reaching plant used for the paper's 500-parameter row:
/// `ReachingArm::new(10, 5)` gives the 10-link arm's cost bit for bit (at the minimum-jerk
/// start and at a perturbed θ) and the same minimum-jerk weights (to 10⁻⁶ relative); the
/// paper's 50-link arm has 500 parameters and its minimum-jerk start misses the via point
/// (cost above 10⁶, as the 10-link start).
#[test]
fn reaching_arm_generalises_the_via_point_arm() {
    let small = ViaPointArm::new();
    let general = ReachingArm::new(10, 5);
    let theta = small.minimum_jerk_theta();
    let fitted = general.minimum_jerk_theta();
    for (a, b) in theta.iter().zip(&fitted) {
        assert!((a - b).abs() <= 1e-6 * a.abs().max(1.0), "{a} vs {b}");
    }
    let mut perturbed = theta;
    for (k, t) in perturbed.iter_mut().enumerate() {
        *t += 37.0 * ((k * 7 % 11) as f32 - 5.0);
    }
    for t in [theta, perturbed] {
        assert_eq!(small.evaluate(&t), general.evaluate(t.as_slice()));
    }
    let paper = ReachingArm::paper();
    assert_eq!(paper.params(), 500);
    let start = paper.minimum_jerk_theta();
    assert!(paper.cost(&start) > 1e6, "{}", paper.cost(&start));
}

/// Checks the rhythmic plant: θ = 0 (the stretched, still arm) costs exactly the weighted
/// via-point misses 10⁸·(0.32 + 0.20); a posture held still (every joint's weights equal)
/// has no acceleration cost; a moving one has.
#[test]
fn rhythmic_arm_costs() {
    let arm = RhythmicArm::new();
    let zero = vec![0.0f32; rhythmic::PARAMS];
    let terms = arm.evaluate(&zero);
    assert_eq!(terms.acceleration, 0.0);
    assert!((terms.total() - 5.2e7).abs() < 1.0, "{}", terms.total());
    let still: Vec<f32> = (0..rhythmic::PARAMS)
        .map(|k| 0.03 * (k / rhythmic::KERNELS) as f32)
        .collect();
    assert!(arm.evaluate(&still).acceleration < 1e-6);
    let moving: Vec<f32> = (0..rhythmic::PARAMS)
        .map(|k| 0.03 * (k % rhythmic::KERNELS) as f32)
        .collect();
    assert!(arm.evaluate(&moving).acceleration > 1.0);
}

#[cfg(not(debug_assertions))]
mod release {
    //! The comparison itself.

    use ctrl_adapt::optimizer::Vector;
    use experiments::rockstar_arm::{
        self, Method, Session, mean_curve, mean_median, out_dir, tuned,
    };
    use host_tests::arm::{self, ViaPointArm};
    use host_tests::plots::{Series, log_cost_curves};

    const SEEDS: u64 = 10;
    const ROLLOUTS: usize = 3000;

    fn std_of(method: Method) -> f32 {
        tuned::ARM_50
            .iter()
            .find(|(m, _)| *m == method)
            .map(|(_, s)| *s)
            .expect("a tuned value")
    }

    /// ROCK* against CMA-ES and PI-BB on the 50-parameter via-point arm, 10 seeds (0..10) ×
    /// 3,000 rollouts per method, printed as a table, with the mean learning curves written
    /// to `target/experiments/rockstar_arm50.svg`.
    ///
    /// **What is compared.** As in the paper's table I, the lowest cost among the rollouts
    /// sampled in a session (the best told cost), after 3,000 rollouts, averaged over the
    /// seeds. The cost of the deployable point at the end (ROCK*'s θ*, the CMA-ES and
    /// PI-BB means) is printed next to it; it is one evaluation outside the 3,000.
    ///
    /// **Exploration, tuned as the paper did** (it hand-tuned the exploration of every
    /// method per task and found the other parameters of small impact): the initial
    /// standard deviation (in DMP-weight units; σ₀ = std/10⁴ for ROCK* and CMA-ES, whose
    /// search is box-normalised, variance std² for PI-BB) was swept over
    /// {0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500} on tuning seeds 100..105, disjoint from
    /// the test seeds (`cargo run --release -p experiments --example rockstar_arm_tables
    /// -- sweep50`), and the value of lowest mean lowest cost kept: ROCK* 2 (mean 804;
    /// 868 at 10, 1.89·10³ at 100), CMA-ES 10 (2.66·10³; 2.87·10³ to 4.19·10³ from 0.5 to
    /// 100), PI-BB with fixed exploration 20 (880); PI-BB with adapted covariance (floor
    /// (std/10)²) did worse (its best mean, 5.92·10³ at 20, is far behind) and is not run
    /// here (the ROCK* sweep was run with its earlier defaults, λ = 0.5 and no gate on the
    /// extra descent start points, and not repeated). Every other parameter is the
    /// library's default (ROCK*: λ = 0.3, the 2n gate, M = 5n = 250; CMA-ES: λ = 15; PI-BB: K = 10, h = 10, noise-free first trial), except that ROCK*
    /// and CMA-ES get no stopping tolerance: every session spends its 3,000 rollouts, as in
    /// the paper (also asserted).
    ///
    /// **Asserted (the paper's shape, as rates over the 10 seeds)**, both met (figures in
    /// `findings/rockstar-arm.md`):
    /// * ROCK*'s mean lowest cost is ≤ 0.65 × CMA-ES's (the paper: 21,765 against 34,892,
    ///   0.62, on its 500-parameter reaching task; observed 0.25);
    /// * ROCK*'s lowest cost is below CMA-ES's on ≥ 8 of the 10 seeds, seed by seed
    ///   (observed 10 of 10).
    ///
    /// **Printed, not asserted, because they do not hold here** (the paper's shape missed):
    /// * the speed: ROCK* reaches its seed's CMA-ES 3,000-rollout cost within 1,000
    ///   rollouts on only 4 of 10 seeds (it needs 153–2,559, median ≈ 1,140); the statement
    ///   "within 1,000 on ≥ 8 of 10" was chosen before the run and is not met;
    /// * PI-BB: the paper has ROCK* at 0.51 × PI-BB's cost; here ROCK*'s mean lowest cost is
    ///   0.77 × PI-BB's (fixed exploration), and ROCK* ends below PI-BB on 8 of 10 seeds.
    #[test]
    fn rockstar_against_cmaes_and_pibb_on_the_via_point_arm() {
        let clock = std::time::Instant::now();
        let arm = ViaPointArm::new();
        let start = arm.minimum_jerk_theta();
        let bounds = arm::bounds();
        let half = arm::WEIGHT_LIMIT;
        let mut cost = |t: &Vector<50>| arm.cost(t);
        let methods = [Method::Rockstar, Method::Cmaes, Method::PiBbFixed];
        let runs: Vec<Vec<Session>> = methods
            .iter()
            .map(|&method| {
                let std = std_of(method);
                (0..SEEDS)
                    .map(|seed| {
                        match method {
                            Method::Rockstar => rockstar_arm::rockstar::<50, 250>(
                                bounds, start, half, std, ROLLOUTS, seed, &mut cost,
                            ),
                            Method::Cmaes => rockstar_arm::cmaes::<50, 15>(
                                bounds, start, half, std, ROLLOUTS, seed, &mut cost,
                            ),
                            _ => rockstar_arm::pibb::<50>(
                                bounds,
                                start,
                                std,
                                rockstar_arm::PiBbExploration::Fixed,
                                ROLLOUTS,
                                seed,
                                &mut cost,
                            ),
                        }
                        .expect("a valid configuration")
                    })
                    .collect()
            })
            .collect();

        println!("50-parameter via-point arm, seeds 0..{SEEDS}, {ROLLOUTS} rollouts");
        println!(
            "| method | std | mean lowest | median lowest | mean deployed (+1 rollout) | per-seed lowest |"
        );
        println!("|---|---:|---:|---:|---:|---|");
        let mut means = Vec::new();
        for (method, sessions) in methods.iter().zip(&runs) {
            let finals: Vec<f32> = sessions.iter().map(Session::final_lowest).collect();
            let deployed: Vec<f32> = sessions.iter().map(|s| s.deployed).collect();
            let (mean, median) = mean_median(&finals);
            let (deployed_mean, _) = mean_median(&deployed);
            let per_seed: Vec<String> = finals.iter().map(|c| format!("{c:.3e}")).collect();
            println!(
                "| {} | {} | {mean:.4e} | {median:.4e} | {deployed_mean:.4e} | {} |",
                method.name(),
                std_of(*method),
                per_seed.join(" ")
            );
            means.push(mean);
            assert!(sessions.iter().all(|s| s.rollouts as usize == ROLLOUTS));
        }
        let (rock, cmaes, pibb) = (&runs[0], &runs[1], &runs[2]);
        let reach = |baseline: &[Session]| -> Vec<Option<usize>> {
            rock.iter()
                .zip(baseline)
                .map(|(r, b)| r.rollouts_to_reach(b.final_lowest()))
                .collect()
        };
        let show = |v: &[Option<usize>]| -> String {
            v.iter()
                .map(|k| k.map_or("—".to_string(), |k| k.to_string()))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let to_cmaes = reach(cmaes);
        let to_pibb = reach(pibb);
        println!(
            "ROCK* rollouts to reach CMA-ES's 3,000-rollout cost, per seed: {}",
            show(&to_cmaes)
        );
        println!(
            "ROCK* rollouts to reach PI-BB's 3,000-rollout cost, per seed: {}",
            show(&to_pibb)
        );
        let ratio_cmaes = means[0] / means[1];
        let ratio_pibb = means[0] / means[2];
        let within = to_cmaes
            .iter()
            .filter(|k| k.is_some_and(|k| k <= 1000))
            .count();
        let below = |baseline: &[Session]| {
            rock.iter()
                .zip(baseline)
                .filter(|(r, b)| r.final_lowest() < b.final_lowest())
                .count()
        };
        let (below_cmaes, below_pibb) = (below(cmaes), below(pibb));
        let mut needed: Vec<f32> = to_cmaes
            .iter()
            .map(|k| k.map_or(f32::INFINITY, |k| k as f32))
            .collect();
        needed.sort_by(f32::total_cmp);
        let (_, median_needed) = mean_median(&needed);
        println!(
            "ROCK*/CMA-ES mean lowest {ratio_cmaes:.3}, ROCK*/PI-BB {ratio_pibb:.3}; \
             ROCK* below CMA-ES on {below_cmaes}/{SEEDS} seeds, below PI-BB on \
             {below_pibb}/{SEEDS}; ROCK* reaches CMA-ES's cost within 1,000 rollouts on \
             {within}/{SEEDS} seeds (median {median_needed} rollouts)"
        );

        let curves: Vec<(String, Vec<f64>)> = methods
            .iter()
            .zip(&runs)
            .map(|(m, s)| (format!("{} (std {})", m.name(), std_of(*m)), mean_curve(s)))
            .collect();
        let series: Vec<Series> = curves
            .iter()
            .map(|(name, values)| Series { name, values })
            .collect();
        let dir = out_dir();
        std::fs::create_dir_all(&dir).expect("target/experiments is writable");
        log_cost_curves(
            &dir.join("rockstar_arm50.svg"),
            "via-point arm, 50 parameters: mean lowest cost over 10 seeds",
            &series,
            "lowest cost so far",
        )
        .expect("the plot is written");
        println!("({:.1} s)", clock.elapsed().as_secs_f64());

        assert!(
            ratio_cmaes <= 0.65,
            "ROCK*'s mean lowest cost is {ratio_cmaes:.3} × CMA-ES's"
        );
        assert!(
            below_cmaes >= 8,
            "ROCK* ended below CMA-ES on {below_cmaes}/{SEEDS} seeds"
        );
    }
}
