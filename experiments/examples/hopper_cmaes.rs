//! Diagnostic (host only, not library code): is the hopping plateau (training cost
//! ≈ 1.6–1.8e-4, apex spread ≈ 2 cm, see findings/hopping.md "Hopping leg") a limit of our
//! axis-aligned / diagonal optimizers on a rotated, ill-conditioned ridge, or a limit of the
//! policy and plant? A full-covariance CMA-ES answers it.
//!
//! ```text
//! cargo run --release -p experiments --example hopper_cmaes -- [RUN ...]
//! ```
//!
//! Each RUN is `start:variant:sigma0:budget:cost:seed`, e.g. `zero:full:0.15:6000:plain:1`:
//! * `start`: `zero` (θ = 0), `coord` (the best θ of the coordinate search of
//!   `tests/hopper_experiments.rs`, 400 episodes on the training course, replicated here) or
//!   `env` (the θ in the environment variable `CMAES_THETA`, comma-separated, as printed);
//! * `variant`: `full` (CMA-ES with a full covariance matrix) or `sep` (the same with the
//!   covariance restricted to its diagonal: sep-CMA-ES of Ros & Hansen 2008, c₁ and c_μ
//!   multiplied by (n + 2)/3);
//! * `sigma0`: initial step size in normalised units (θ_i / half-range_i, box [−1, 1]³¹);
//! * `budget`: episodes;
//! * `cost`: `plain` (`ApexHeightCost` on course 1001), `shaped` (course 1001, apex term
//!   without the first 3 apexes + 10 · spread², as in `hopper_attempts`), `shaped3` (the
//!   shaped cost averaged over courses 1001–1003: 3 episodes per evaluation);
//! * `seed`: the sampling seed.
//!
//! Without arguments it runs the default table (see `DEFAULT_RUNS`).
//!
//! # The algorithm
//! (μ/μ_w, λ)-CMA-ES after Hansen, "The CMA Evolution Strategy: A Tutorial" (2016), with its
//! default constants (those of pycma for positive weights): λ = 4 + ⌊3 ln n⌋ = 14,
//! μ = ⌊λ/2⌋ = 7, w_i ∝ ln((λ + 1)/2) − ln i, c_σ = (μ_eff + 2)/(n + μ_eff + 5),
//! d_σ = 1 + 2 max(0, √((μ_eff − 1)/(n + 1)) − 1) + c_σ,
//! c_c = (4 + μ_eff/n)/(n + 4 + 2μ_eff/n), c₁ = 2/((n + 1.3)² + μ_eff),
//! c_μ = min(1 − c₁, 2(μ_eff − 2 + 1/μ_eff)/((n + 2)² + μ_eff)), cumulative step-size
//! adaptation with the h_σ stall of the rank-one update, eigendecomposition
//! (`SymmetricEigen`) every generation. Deviations: no active (negative) weights (pycma
//! uses them by default); no restarts; stop when σ·√(largest eigenvalue of C) < 1e-6.
//!
//! # The box
//! A sample x outside [−1, 1]ⁿ is evaluated at its projection p onto the box (the θ that
//! actually runs) and told f(p) + 0.01 · ‖x − p‖² (normalised units); the optimizer learns from
//! x, as in pycma's `BoundPenalty` (with a fixed penalty weight). The best θ reported is the
//! best projected point by its unpenalised cost.

use std::time::Instant;

use ctrl_adapt::optimizer::{Optimizer, Vector};
use experiments::hopping::{
    self, HopEpisode, K, P, bounds, coordinate_search, evaluate, plant, run_episode,
    training_course,
};
use nalgebra::{SMatrix, SVector, SymmetricEigen};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

type V = SVector<f64, P>;
type M = SMatrix<f64, P, P>;

/// The default table: from zero and from the coordinate search, full and diagonal.
const DEFAULT_RUNS: &[&str] = &[
    "zero:full:0.15:6000:plain:1",
    "coord:full:0.02:3000:plain:1",
    "zero:sep:0.15:6000:plain:1",
    "coord:sep:0.02:3000:plain:1",
];

/// Weight of the squared distance (normalised units) to the box.
const PENALTY: f64 = 0.01;

/// Episodes at which the best-so-far θ is reported.
const CHECKPOINTS: &[usize] = &[400, 1000, 2000, 4000, 6000, 8000, 10_000, 12_000];

/// Unseen courses of `tests/hopper_experiments.rs`.

#[derive(Clone, Copy, PartialEq)]
enum Variant {
    Full,
    Sep,
}

#[derive(Clone, Copy)]
enum Cost {
    Plain,
    Shaped,
    Shaped3,
}

impl Cost {
    fn courses(self) -> &'static [u64] {
        match self {
            Cost::Plain | Cost::Shaped => &[1001],
            Cost::Shaped3 => &[1001, 1002, 1003],
        }
    }
}

/// The episode's cost: as told, or (shaped) with the apex term over the apexes after the
/// first 3 plus 10 · spread² (m²), as in `hopper_attempts`.
fn episode_cost(e: &HopEpisode, c: Cost) -> f64 {
    let told = f64::from(e.report.cost);
    if e.collapsed || matches!(c, Cost::Plain) {
        return told;
    }
    let mean_sq =
        |a: &[f64]| a.iter().map(|h| (h - 0.6).powi(2)).sum::<f64>() / a.len().max(1) as f64;
    let rest = told - mean_sq(&e.apexes);
    mean_sq(e.apexes.get(3..).unwrap_or(&[])) + rest + 10.0 * e.apex_spread().powi(2)
}

/// Half-ranges of the box.
fn half() -> V {
    bounds().upper().map(f64::from)
}

/// θ of a normalised point inside the box.
fn theta_of(x: &V) -> Vector<P> {
    let up = *bounds().upper();
    Vector::<P>::from_fn(|i, _| ((x[i] * half()[i]) as f32).clamp(-up[i], up[i]))
}

fn normal<R: RngCore>(rng: &mut R) -> f64 {
    // Box–Muller; u1 ∈ (0, 1].
    let u = |rng: &mut R| ((rng.next_u64() >> 11) as f64 + 1.0) / (1u64 << 53) as f64;
    let (u1, u2) = (u(rng), u(rng));
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// One row of the table ([`hopping::figures_row`]).
fn row(label: &str, episodes: usize, cost: f64, theta: Vector<P>, extra: &str) {
    let row = hopping::figures_row(label, episodes as u64, cost, theta, extra);
    println!("{}", row.expect("episode"));
}

/// The coordinate search of `tests/hopper_experiments.rs` (400 episodes from zero on the
/// training course, through the adapter), returning its best θ and cost.
fn coordinate_start() -> (Vector<P>, f64) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
    let n = hopping::LEARNING_EPISODES;
    let search = coordinate_search(Vector::zeros(), n).expect("search");
    let mut adapter = hopping::adapter(search, n, Vector::zeros()).expect("adapter");
    for _ in 0..n {
        run_episode(&mut adapter, &mut training_course(), &mut rng, false).expect("episode");
    }
    let best = adapter.optimizer().best().expect("told");
    (best.theta, f64::from(best.cost))
}

struct Run {
    start: String,
    variant: Variant,
    sigma0: f64,
    budget: usize,
    cost: Cost,
    seed: u64,
}

fn parse(s: &str) -> Run {
    let f: Vec<&str> = s.split(':').collect();
    assert_eq!(
        f.len(),
        6,
        "RUN is start:variant:sigma0:budget:cost:seed, got {s}"
    );
    Run {
        start: f[0].to_string(),
        variant: match f[1] {
            "full" => Variant::Full,
            "sep" => Variant::Sep,
            v => panic!("variant {v}"),
        },
        sigma0: f[2].parse().expect("sigma0"),
        budget: f[3].parse().expect("budget"),
        cost: match f[4] {
            "plain" => Cost::Plain,
            "shaped" => Cost::Shaped,
            "shaped3" => Cost::Shaped3,
            c => panic!("cost {c}"),
        },
        seed: f[5].parse().expect("seed"),
    }
}

fn cma(run: &Run, label: &str, start: V) {
    let n = P as f64;
    let lambda = 4 + (3.0 * n.ln()).floor() as usize;
    let mu = lambda / 2;
    let raw: Vec<f64> = (1..=mu)
        .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
        .collect();
    let sum: f64 = raw.iter().sum();
    let w: Vec<f64> = raw.iter().map(|r| r / sum).collect();
    let mu_eff = 1.0 / w.iter().map(|w| w * w).sum::<f64>();
    let c_sigma = (mu_eff + 2.0) / (n + mu_eff + 5.0);
    let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (n + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
    let c_c = (4.0 + mu_eff / n) / (n + 4.0 + 2.0 * mu_eff / n);
    let mut c_1 = 2.0 / ((n + 1.3).powi(2) + mu_eff);
    let mut c_mu =
        (2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((n + 2.0).powi(2) + mu_eff)).min(1.0 - c_1);
    if run.variant == Variant::Sep {
        let f = (n + 2.0) / 3.0;
        c_1 *= f;
        c_mu = (c_mu * f).min(1.0 - c_1);
    }
    let chi_n = n.sqrt() * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n * n));

    let mut rng = Xoshiro256PlusPlus::seed_from_u64(run.seed);
    let mut eval_rng = Xoshiro256PlusPlus::seed_from_u64(3);
    let mut mean = start;
    let mut sigma = run.sigma0;
    let mut c = M::identity();
    let mut b = M::identity();
    let mut d = V::repeat(1.0);
    let mut p_sigma = V::zeros();
    let mut p_c = V::zeros();
    let mut episodes = 0usize;
    let mut generation = 0usize;
    let mut best: (f64, Vector<P>) = (f64::INFINITY, theta_of(&start));
    let mut next_checkpoint = 0usize;
    let t = Instant::now();
    let courses = run.cost.courses();
    let report = |episodes: usize, best: &(f64, Vector<P>), sigma: f64, d: &V| {
        let dmax = d.max();
        let dmin = d.min();
        row(
            label,
            episodes,
            best.0,
            best.1,
            &format!(
                "σ {sigma:.2e}, axis ratio {:.0}, {:.0} s",
                dmax / dmin,
                t.elapsed().as_secs_f64()
            ),
        );
    };
    'outer: loop {
        // Sample λ points, evaluate each at its projection.
        let mut pop: Vec<(f64, V)> = Vec::with_capacity(lambda);
        for _ in 0..lambda {
            let z = V::from_fn(|_, _| normal(&mut rng));
            let y = b * d.component_mul(&z);
            let x = mean + sigma * y;
            let proj = x.map(|v| v.clamp(-1.0, 1.0));
            let theta = theta_of(&proj);
            let f = courses
                .iter()
                .map(|&s| {
                    let e = evaluate(theta, &mut plant(true, s), &mut eval_rng, false)
                        .expect("episode");
                    episode_cost(&e, run.cost)
                })
                .sum::<f64>()
                / courses.len() as f64;
            episodes += courses.len();
            if f < best.0 {
                best = (f, theta);
            }
            pop.push((f + PENALTY * (x - proj).norm_squared(), x));
            while next_checkpoint < CHECKPOINTS.len() && episodes >= CHECKPOINTS[next_checkpoint] {
                if CHECKPOINTS[next_checkpoint] < run.budget {
                    report(episodes, &best, sigma, &d);
                }
                next_checkpoint += 1;
            }
            if episodes >= run.budget {
                break 'outer;
            }
        }
        pop.sort_by(|a, b| a.0.total_cmp(&b.0));
        let old = mean;
        mean = V::zeros();
        for (wi, (_, x)) in w.iter().zip(&pop) {
            mean += *wi * x;
        }
        let step = (mean - old) / sigma;
        // C^{-1/2} step = B D^{-1} Bᵀ step.
        let inv_sqrt = b * (b.transpose() * step).component_div(&d);
        p_sigma =
            (1.0 - c_sigma) * p_sigma + (c_sigma * (2.0 - c_sigma) * mu_eff).sqrt() * inv_sqrt;
        generation += 1;
        let ps_norm = p_sigma.norm();
        let h_sigma = ps_norm / (1.0 - (1.0 - c_sigma).powi(2 * generation as i32)).sqrt()
            < (1.4 + 2.0 / (n + 1.0)) * chi_n;
        let h = if h_sigma { 1.0 } else { 0.0 };
        p_c = (1.0 - c_c) * p_c + h * (c_c * (2.0 - c_c) * mu_eff).sqrt() * step;
        let mut rank_mu = M::zeros();
        for (wi, (_, x)) in w.iter().zip(&pop) {
            let y = (x - old) / sigma;
            rank_mu += *wi * y * y.transpose();
        }
        let delta = (1.0 - h) * c_c * (2.0 - c_c);
        c = (1.0 - c_1 - c_mu) * c + c_1 * (p_c * p_c.transpose() + delta * c) + c_mu * rank_mu;
        sigma *= ((c_sigma / d_sigma) * (ps_norm / chi_n - 1.0)).exp();
        if run.variant == Variant::Sep {
            c = M::from_diagonal(&c.diagonal());
            b = M::identity();
            d = c.diagonal().map(f64::sqrt);
        } else {
            c = 0.5 * (c + c.transpose());
            let eig = SymmetricEigen::new(c);
            b = eig.eigenvectors;
            d = eig.eigenvalues.map(|e| e.max(1e-300).sqrt());
        }
        if sigma * d.max() < 1e-6 {
            println!("  ({label}: stopped, σ·√λ_max < 1e-6 after {episodes} episodes)");
            break;
        }
    }
    report(episodes, &best, sigma, &d);
    let theta = best.1;
    let normalised: Vec<f64> = (0..P).map(|i| f64::from(theta[i]) / half()[i]).collect();
    let on_bound = normalised.iter().filter(|v| v.abs() > 0.999).count();
    println!(
        "  {label}: {on_bound} coordinates at the box; knee weights (normalised) {:.2?}; \
         period offset {:.1} ms",
        &normalised[..K],
        theta[P - 1] * 1e3
    );
    println!("  θ = {:?}", theta.as_slice());
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let runs: Vec<Run> = if args.is_empty() {
        DEFAULT_RUNS.iter().map(|s| parse(s)).collect()
    } else {
        args.iter().map(|s| parse(s)).collect()
    };
    println!(
        "| run | episodes | best objective | plain cost on 1001: apex + rest | training spread \
         (cm) | unseen median | unseen max | stable | notes |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |");
    let mut coord: Option<(Vector<P>, f64)> = None;
    for run in &runs {
        let label = format!(
            "{} {} σ₀ {} {} seed {}",
            run.start,
            if run.variant == Variant::Full {
                "full"
            } else {
                "sep"
            },
            run.sigma0,
            match run.cost {
                Cost::Plain => "plain",
                Cost::Shaped => "shaped",
                Cost::Shaped3 => "shaped×3",
            },
            run.seed
        );
        let start = match run.start.as_str() {
            "zero" => V::zeros(),
            "coord" => {
                let (theta, cost) = *coord.get_or_insert_with(|| {
                    let c = coordinate_start();
                    row("coordinate search (start)", 400, c.1, c.0, "");
                    c
                });
                let _ = cost;
                V::from_fn(|i, _| f64::from(theta[i]) / half()[i])
            }
            "env" => {
                let theta: Vec<f64> = hopping::theta_from_env().expect("CMAES_THETA is not set");
                let start = V::from_fn(|i, _| theta[i] / half()[i]);
                row("given θ (start)", 0, f64::NAN, theta_of(&start), "");
                start
            }
            s => panic!("start {s}"),
        };
        cma(run, &label, start);
    }
}
