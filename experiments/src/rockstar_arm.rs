//! The arm tasks of Hwangbo, Gehring, Sommer, Siegwart & Buchli, "ROCK*: Efficient
//! black-box optimization for policy learning" (Humanoids 2014), table I: ROCK*
//! ([`Rockstar`]), CMA-ES ([`Cmaes`]) and PI-BB ([`DiagonalCem`] with
//! [`Weighting::PiBb`]) on a cost, each for a fixed number of rollouts.
//!
//! **What is reported.** The paper's table lists "the lowest costs after 3,000 rollouts
//! averaged over 10 trials", and its learning curves plot cost against rollouts: the
//! lowest cost among the rollouts *sampled* so far. That is what [`lowest_so_far`] records
//! for every optimizer (the best told cost, [`Optimizer::best`]); it needs no extra
//! rollout. The cost of the deployable point (ROCK*'s θ*, the CMA-ES or PI-BB mean) after
//! the last rollout is reported next to it as one extra evaluation that is *not* counted
//! in the budget.
//!
//! Every session spends its whole budget: ROCK*'s and CMA-ES's stopping tolerances are set
//! to 0 (with ROCK*'s default, σ ≤ 10⁻⁶ of the half-width, at least 8 of 10 rhythmic-task
//! sessions declared convergence early, the shortest after 1,248 of its 3,000 rollouts).
//! DiagonalCem has none by default.
//!
//! The exploration of each method is a standard deviation in the task's parameter units
//! (`std`): σ₀ = `std` / half-width for [`Rockstar`] and [`Cmaes`] (both search in
//! box-normalised coordinates), an initial variance `std`² for [`DiagonalCem`].

use ctrl_adapt::optimizer::{
    Bounds, CemConfig, Cmaes, CmaesConfig, DiagonalCem, Error, Optimizer, Rockstar, RockstarConfig,
    Status, Vector, Weighting,
};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// PI-BB's samples per update (K = 10, as in Stulp & Sigaud 2012).
pub const PIBB_K: usize = 10;

/// One session: the lowest sampled cost after each rollout, and the cost of the
/// deployable point at the end.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// `lowest[k]`: the lowest cost among rollouts 1..=k+1 (non-increasing). If the
    /// optimizer stops before the budget, the last value is repeated (no further rollout).
    pub lowest: Vec<f32>,
    /// The cost of θ* (ROCK*) or the mean (CMA-ES, PI-BB) after the last rollout: one
    /// evaluation outside the budget.
    pub deployed: f32,
    /// Rollouts actually run.
    pub rollouts: u32,
}

impl Session {
    /// The lowest sampled cost after the budget.
    pub fn final_lowest(&self) -> f32 {
        self.lowest.last().copied().unwrap_or(f32::INFINITY)
    }

    /// The number of rollouts (1-based) after which the lowest cost is ≤ `target`, if any.
    pub fn rollouts_to_reach(&self, target: f32) -> Option<usize> {
        self.lowest.iter().position(|&c| c <= target).map(|k| k + 1)
    }
}

/// Runs `opt` for `rollouts` rollouts of `cost` with xoshiro128++ seeded by `seed` and
/// returns the lowest told cost after each rollout (padded with the last value if the
/// optimizer stops early).
pub fn lowest_so_far<const N: usize, O: Optimizer<N>>(
    opt: &mut O,
    cost: &mut impl FnMut(&Vector<N>) -> f32,
    rollouts: usize,
    seed: u64,
) -> Result<Vec<f32>, Error> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut lowest = Vec::with_capacity(rollouts);
    let mut best = f32::INFINITY;
    while lowest.len() < rollouts && opt.status() == Status::Running {
        let theta = opt.ask(&mut rng)?;
        let c = cost(&theta);
        opt.tell(c)?;
        best = best.min(c);
        lowest.push(best);
    }
    while lowest.len() < rollouts {
        lowest.push(best);
    }
    Ok(lowest)
}

/// ROCK* with memory `M`, σ₀ = `std`/half-width, no stopping tolerance (every session
/// spends its budget, as in the paper) and the library's defaults otherwise.
/// Built in a `Box` (`Rockstar<500, 2500>` holds 7 MB: call it on a thread with a large
/// stack).
pub fn rockstar<const N: usize, const M: usize>(
    bounds: Bounds<N>,
    start: Vector<N>,
    half_width: f32,
    std: f32,
    rollouts: usize,
    seed: u64,
    cost: &mut impl FnMut(&Vector<N>) -> f32,
) -> Result<Session, Error> {
    let config = rockstar_config(RockstarConfig::DEFAULT, std / half_width, rollouts);
    rockstar_with::<N, M>(config, bounds, start, seed, cost)
}

/// `base` with σ₀ = `initial_sigma`, no stopping tolerance and a budget of `rollouts`: the
/// configuration of [`rockstar`] when `base` is the default.
pub fn rockstar_config(
    base: RockstarConfig,
    initial_sigma: f32,
    rollouts: usize,
) -> RockstarConfig {
    RockstarConfig {
        initial_sigma,
        tolerance: 0.0,
        max_evaluations: rollouts as u32,
        ..base
    }
}

/// One ROCK* session with `config` (its budget is `config.max_evaluations` rollouts), boxed
/// as in [`rockstar`].
pub fn rockstar_with<const N: usize, const M: usize>(
    config: RockstarConfig,
    bounds: Bounds<N>,
    start: Vector<N>,
    seed: u64,
    cost: &mut impl FnMut(&Vector<N>) -> f32,
) -> Result<Session, Error> {
    let rollouts = config.max_evaluations as usize;
    let mut opt = Box::new(Rockstar::<N, M>::try_new(bounds, start, config)?);
    let lowest = lowest_so_far(opt.as_mut(), cost, rollouts, seed)?;
    Ok(Session {
        lowest,
        deployed: cost(&opt.theta_star()),
        rollouts: opt.evaluations(),
    })
}

/// CMA-ES with population `L`, σ₀ = `std`/half-width, no stopping tolerance and the
/// library's defaults otherwise.
pub fn cmaes<const N: usize, const L: usize>(
    bounds: Bounds<N>,
    start: Vector<N>,
    half_width: f32,
    std: f32,
    rollouts: usize,
    seed: u64,
    cost: &mut impl FnMut(&Vector<N>) -> f32,
) -> Result<Session, Error> {
    let config = CmaesConfig {
        initial_sigma: std / half_width,
        tolerance: 0.0,
        max_evaluations: rollouts as u32,
        ..CmaesConfig::DEFAULT
    };
    let mut opt = Box::new(Cmaes::<N, L>::try_new(bounds, start, config)?);
    let lowest = lowest_so_far(opt.as_mut(), cost, rollouts, seed)?;
    Ok(Session {
        lowest,
        deployed: cost(&opt.mean()),
        rollouts: opt.evaluations(),
    })
}

/// How PI-BB's exploration evolves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PiBbExploration {
    /// Σ = `std`²·I throughout (PI-BB as Stulp & Sigaud define it).
    Fixed,
    /// Σ adapted from the weighted samples (PI²-CMA, diagonal), with the exploration floor
    /// ε·I added after each update, ε = (`std`/10)² (the 10²·I of Stulp & Sigaud for their
    /// 10⁴·I start).
    Adapted,
}

/// PI-BB: `DiagonalCem<N, 10, 10>`, h = 10, all K samples weighted, the first of each batch
/// noise-free, initial variance `std`².
pub fn pibb<const N: usize>(
    bounds: Bounds<N>,
    start: Vector<N>,
    std: f32,
    exploration: PiBbExploration,
    rollouts: usize,
    seed: u64,
    cost: &mut impl FnMut(&Vector<N>) -> f32,
) -> Result<Session, Error> {
    let variance = std * std;
    let config = CemConfig {
        weighting: Weighting::PiBb { h: 10.0 },
        elite: None,
        initial_variance: variance,
        adapt_covariance: exploration == PiBbExploration::Adapted,
        exploration_floor: match exploration {
            PiBbExploration::Fixed => 0.0,
            PiBbExploration::Adapted => variance / 100.0,
        },
        first_is_mean: true,
        max_evaluations: rollouts as u32,
        ..CemConfig::DEFAULT
    };
    let mut opt = Box::new(DiagonalCem::<N, PIBB_K, PIBB_K>::try_new(
        bounds, start, config,
    )?);
    let lowest = lowest_so_far(opt.as_mut(), cost, rollouts, seed)?;
    Ok(Session {
        lowest,
        deployed: cost(opt.mean()),
        rollouts: opt.evaluations(),
    })
}

/// Mean and median of `values`.
pub fn mean_median(values: &[f32]) -> (f64, f64) {
    let mean = values.iter().map(|&v| f64::from(v)).sum::<f64>() / values.len().max(1) as f64;
    let mut sorted: Vec<f64> = values.iter().map(|&v| f64::from(v)).collect();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let median = if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        sorted[n / 2]
    } else {
        0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
    };
    (mean, median)
}

/// The mean over sessions of the lowest cost after each rollout.
pub fn mean_curve(sessions: &[Session]) -> Vec<f64> {
    let len = sessions.iter().map(|s| s.lowest.len()).min().unwrap_or(0);
    (0..len)
        .map(|k| {
            sessions.iter().map(|s| f64::from(s.lowest[k])).sum::<f64>() / sessions.len() as f64
        })
        .collect()
}

/// The methods compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// [`Rockstar`] with M = 5n.
    Rockstar,
    /// [`Cmaes`].
    Cmaes,
    /// [`pibb`] with [`PiBbExploration::Fixed`].
    PiBbFixed,
    /// [`pibb`] with [`PiBbExploration::Adapted`].
    PiBbAdapted,
}

impl Method {
    /// The name in tables and plots.
    pub fn name(self) -> &'static str {
        match self {
            Method::Rockstar => "ROCK*",
            Method::Cmaes => "CMA-ES",
            Method::PiBbFixed => "PI-BB fixed",
            Method::PiBbAdapted => "PI-BB adapted",
        }
    }
}

/// The initial exploration (standard deviation in parameter units) of each method, chosen
/// by the sweeps of `examples/rockstar_arm_tables.rs` on tuning seeds 100.. (disjoint from
/// the test seeds 0..10): the value with the lowest mean lowest cost after 3,000 rollouts.
pub mod tuned {
    use super::Method;

    /// The 50-parameter via-point arm (`sweep50`, seeds 100..105).
    pub const ARM_50: [(Method, f32); 4] = [
        (Method::Rockstar, 2.0),
        (Method::Cmaes, 10.0),
        (Method::PiBbFixed, 20.0),
        (Method::PiBbAdapted, 20.0),
    ];
    /// The 500-parameter reaching task (`sweep500`, seeds 100 and 101).
    pub const REACHING_500: [(Method, f32); 3] = [
        (Method::Rockstar, 0.5),
        (Method::PiBbFixed, 50.0),
        (Method::PiBbAdapted, 20.0),
    ];
    /// The 400-parameter rhythmic task (`sweep400`, seeds 100 and 101), in rad.
    pub const RHYTHMIC_400: [(Method, f32); 3] = [
        (Method::Rockstar, 0.0003),
        (Method::PiBbFixed, 0.003),
        (Method::PiBbAdapted, 0.01),
    ];
}

/// Where the experiments' figures go: `target/experiments/` of the workspace.
pub fn out_dir() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/experiments")
}
