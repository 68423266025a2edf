//! Research helpers for the hopping leg: deployed episodes on given courses, validation
//! courses, and the fresh-course CMA-ES learner that runs a generation's episodes on several
//! threads (bit for bit the adapter's sequential run). Re-exports the whole hopping task
//! (`host_tests::hopper_task`), so a study imports one module.

use ctrl_adapt::controller::AdapterError;
use ctrl_adapt::cost::ApexConfig;
use ctrl_adapt::optimizer::{Cmaes, CmaesConfig, Optimizer, Status, Vector};
use host_tests::hopper::NominalHopping;
pub use host_tests::hopper_task::*;
use rand_core::{RngCore, SeedableRng};

/// One deployed episode of `theta` (nominal gait [`NominalHopping::TUNED`], cost `apex`) on
/// the block course of `seed`, not recorded.
pub fn episode_on(
    theta: Vector<P>,
    seed: u64,
    apex: ApexConfig,
) -> Result<HopEpisode, AdapterError> {
    let mut unused = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(0);
    evaluate_with(
        theta,
        &mut plant(true, seed),
        &mut unused,
        false,
        &NominalHopping::TUNED,
        apex,
    )
}

/// The cost a learning [`Adapter`](ctrl_adapt::controller::Adapter) (cost `apex`) tells for one episode of `theta` on the
/// course of `seed` ([`episode_on`]): the episode's cost, or the failure cost if it failed
/// (collapse, non-finite cost, faulty ticks).
pub fn told_cost(theta: Vector<P>, seed: u64, apex: ApexConfig) -> Result<f32, AdapterError> {
    let e = episode_on(theta, seed, apex)?;
    Ok(if e.report.failed {
        adapter_config(1).failure_cost
    } else {
        e.report.cost
    })
}

/// The apex spreads (cm) of the fixed policy `theta` on the courses `seeds` (one episode
/// each, in order), and whether it hops stably on all of them ([`HopEpisode::hops_stably`]).
pub fn spreads_on(
    theta: Vector<P>,
    seeds: impl Iterator<Item = u64>,
) -> Result<(Vec<f64>, bool), AdapterError> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2);
    let episodes = seeds
        .map(|s| evaluate(theta, &mut plant(true, s), &mut rng, false))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((
        episodes.iter().map(|e| e.apex_spread() * 100.0).collect(),
        episodes.iter().all(HopEpisode::hops_stably),
    ))
}

/// The unseen courses of `tests/hopper_experiments.rs`.
pub const UNSEEN_COURSES: std::ops::RangeInclusive<u64> = 10_001..=10_005;

/// A Markdown table row for the fixed policy `theta` (the tables of findings/hopping.md): `label`,
/// `episodes`, `cost`, the plain cost on the training course split into its apex term and
/// the rest (energy, limits, missing hops), the apex spread (cm) on the training course, the
/// median and max over [`UNSEEN_COURSES`], whether it hops stably on all of them, `extra`.
pub fn figures_row(
    label: &str,
    episodes: u64,
    cost: f64,
    theta: Vector<P>,
    extra: &str,
) -> Result<String, AdapterError> {
    let (train, stable_t) = spreads_on(theta, TRAINING_SEED..=TRAINING_SEED)?;
    let (unseen, stable_u) = spreads_on(theta, UNSEEN_COURSES)?;
    let max = unseen.iter().copied().fold(0.0, f64::max);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2);
    let e = evaluate(theta, &mut training_course(), &mut rng, false)?;
    let apex =
        e.apexes.iter().map(|h| (h - 0.6).powi(2)).sum::<f64>() / e.apexes.len().max(1) as f64;
    let rest = f64::from(e.report.cost) - apex;
    Ok(format!(
        "| {label} | {episodes} | {cost:.3e} | {apex:.2e} + {rest:.2e} | {:.2} | {:.2} | \
         {max:.2} | {} | {extra} |",
        train.first().copied().unwrap_or(f64::NAN),
        host_tests::median(unseen),
        if stable_t && stable_u { "yes" } else { "NO" }
    ))
}

/// Threads for [`learn_on_fresh_courses`]: the machine's parallelism.
pub fn threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Population of [`FreshCmaes`]: the tutorial's 4 + ⌊3 ln 31⌋.
pub const FRESH_LAMBDA: usize = 14;

/// The full-covariance CMA-ES that learns on a new course every episode.
pub type FreshCmaes = Cmaes<P, FRESH_LAMBDA>;

/// Seed of the first learning course of [`learn_on_fresh_courses`]: episode k (from 0) runs on
/// the block sequence of seed `FRESH_COURSES + k`, far from [`TRAINING_SEED`] and
/// [`UNSEEN_COURSES`].
pub const FRESH_COURSES: u64 = 100_000;

/// [`FreshCmaes`] from `start` with σ₀ = `sigma0` (relative to each half-range of
/// [`bounds`]), box penalty 0.01 (≈ the cost scale: a sample 0.1 half-range outside the box
/// costs 10⁻⁴), tolerance 10⁻⁶, a budget of `evaluations` (the CMA-ES examples' settings),
/// and active weights if `active` ([`CmaesConfig::active`]: off by default; see
/// `findings/hopping.md`).
pub fn fresh_cmaes(
    start: Vector<P>,
    sigma0: f32,
    evaluations: u32,
    active: bool,
) -> Result<FreshCmaes, ctrl_adapt::Error> {
    Cmaes::try_new(
        bounds(),
        start,
        CmaesConfig {
            initial_sigma: sigma0,
            penalty: 0.01,
            tolerance: 1e-6,
            max_evaluations: evaluations,
            active,
            ..CmaesConfig::DEFAULT
        },
    )
}

/// Learns with `cma` for up to `episodes` episodes, episode k (from 0) on a new course (seed
/// [`FRESH_COURSES`] + k: the blocks the robot meets are never the same twice, as when the
/// paper's blocks were slid in by hand), each told the cost a learning [`Adapter`](ctrl_adapt::controller::Adapter) with the
/// [`ApexHeightCost`](ctrl_adapt::cost::ApexHeightCost) `apex` tells ([`told_cost`]; e.g. [`spread_apex_config`]). Calls
/// `on_episode(k + 1, &cma)` after each tell; stops early if the search stops. Returns the
/// search: deploy its [`Cmaes::mean`], not its best told θ (a lucky draw on an easy course).
///
/// The episodes of a generation run on `threads` threads: the candidates a generation will
/// hand out are drawn first on a copy of the search and of `rng` (telling the copy
/// placeholder costs: within a generation the draws do not depend on the costs), the
/// episodes run, and the search is then asked and told in order, checking each candidate
/// against its copy. The run is therefore the sequential one, bit for bit, whatever
/// `threads` is (`tests/hopper_experiments.rs` checks this).
pub fn learn_on_fresh_courses<G: RngCore + Clone>(
    mut cma: FreshCmaes,
    episodes: u32,
    apex: ApexConfig,
    rng: &mut G,
    threads: usize,
    mut on_episode: impl FnMut(u32, &FreshCmaes),
) -> Result<FreshCmaes, AdapterError> {
    let mut k = 0u32;
    while k < episodes && cma.status() == Status::Running {
        let left = FRESH_LAMBDA - cma.told_in_generation();
        let n = left.min((episodes - k) as usize);
        let (mut probe, mut probe_rng) = (cma.clone(), rng.clone());
        let candidates = (0..n)
            .map(|_| {
                let theta = probe.ask(&mut probe_rng)?;
                probe.tell(0.0)?;
                Ok(theta)
            })
            .collect::<Result<Vec<_>, AdapterError>>()?;
        let costs = parallel_costs(&candidates, FRESH_COURSES + u64::from(k), apex, threads)?;
        for (theta, cost) in candidates.iter().zip(costs) {
            assert_eq!(
                cma.ask(rng)?,
                *theta,
                "a generation's draws depend on its costs"
            );
            cma.tell(cost)?;
            k += 1;
            on_episode(k, &cma);
        }
    }
    Ok(cma)
}

/// [`told_cost`] of `candidates[i]` on course `first_seed + i`, on up to `threads` threads.
fn parallel_costs(
    candidates: &[Vector<P>],
    first_seed: u64,
    apex: ApexConfig,
    threads: usize,
) -> Result<Vec<f32>, AdapterError> {
    let chunk = candidates.len().div_ceil(threads.max(1)).max(1);
    std::thread::scope(|scope| {
        let handles: Vec<_> = candidates
            .chunks(chunk)
            .enumerate()
            .map(|(c, part)| {
                scope.spawn(move || {
                    part.iter()
                        .enumerate()
                        .map(|(i, theta)| {
                            told_cost(*theta, first_seed + (c * chunk + i) as u64, apex)
                        })
                        .collect::<Result<Vec<_>, AdapterError>>()
                })
            })
            .collect();
        let mut costs = Vec::with_capacity(candidates.len());
        for h in handles {
            costs.extend(h.join().expect("an episode thread panicked")?);
        }
        Ok(costs)
    })
}

/// Courses for choosing among learned policies (e.g. the results of independent searches):
/// never learned on, and not the [`UNSEEN_COURSES`] the results are reported on.
pub const VALIDATION_COURSES: std::ops::RangeInclusive<u64> = 20_001..=20_010;

/// The mean told cost ([`told_cost`] with `apex`) of `theta` over [`VALIDATION_COURSES`],
/// the episodes on up to `threads` threads.
pub fn validation_cost(
    theta: Vector<P>,
    apex: ApexConfig,
    threads: usize,
) -> Result<f64, AdapterError> {
    let thetas: Vec<_> = VALIDATION_COURSES.map(|_| theta).collect();
    let costs = parallel_costs(&thetas, *VALIDATION_COURSES.start(), apex, threads)?;
    Ok(costs.iter().map(|&c| f64::from(c)).sum::<f64>() / costs.len() as f64)
}

/// What [`learn_with_validation`] keeps.
#[derive(Debug, Clone)]
pub struct Kept {
    /// The search at the end of the budget.
    pub cma: FreshCmaes,
    /// The search's mean with the lowest validation cost: the policy to deploy.
    pub theta: Vector<P>,
    /// The episode after which that mean was scored.
    pub episode: u32,
    /// Its validation cost ([`validation_cost`]).
    pub validation_cost: f64,
}

/// [`learn_on_fresh_courses`] with early stopping: after every `every` episodes (and at the
/// end) the search's mean is scored on the [`VALIDATION_COURSES`] ([`validation_cost`], 10
/// episodes more each time; the search itself is not affected), and the best-scoring mean
/// is kept — as a robot would deploy the mean for a few episodes now and then and keep the
/// best, instead of trusting wherever the search ends (the search can drift off the gait
/// late in a run). `on_episode` as in [`learn_on_fresh_courses`].
pub fn learn_with_validation<G: RngCore + Clone>(
    cma: FreshCmaes,
    episodes: u32,
    apex: ApexConfig,
    rng: &mut G,
    threads: usize,
    every: u32,
    mut on_episode: impl FnMut(u32, &FreshCmaes),
) -> Result<Kept, AdapterError> {
    let mut kept: Option<(f64, u32, Vector<P>)> = None;
    let mut failed = None;
    let mut score = |k: u32, cma: &FreshCmaes| match validation_cost(cma.mean(), apex, threads) {
        Ok(v) if kept.as_ref().is_none_or(|(best, _, _)| v < *best) => {
            kept = Some((v, k, cma.mean()))
        }
        Ok(_) => {}
        Err(e) => failed = Some(e),
    };
    let cma = learn_on_fresh_courses(cma, episodes, apex, rng, threads, |k, cma| {
        on_episode(k, cma);
        if every > 0 && k % every == 0 {
            score(k, cma);
        }
    })?;
    let told = cma.evaluations();
    if every == 0 || told % every != 0 {
        score(told, &cma);
    }
    if let Some(e) = failed {
        return Err(e);
    }
    let (validation_cost, episode, theta) = kept.unwrap_or((f64::NAN, told, cma.mean()));
    Ok(Kept {
        cma,
        theta,
        episode,
        validation_cost,
    })
}

/// The θ in the environment variable `CMAES_THETA`, as the examples print it ([`P`]
/// comma-separated numbers, optionally in brackets), parsed as `T`; `None` when unset.
///
/// # Panics
/// On a malformed value or a count other than [`P`] (a tool for the examples).
pub fn theta_from_env<T: std::str::FromStr>() -> Option<Vec<T>> {
    let text = std::env::var("CMAES_THETA").ok()?;
    let theta: Vec<T> = text
        .trim_matches(|c| c == '[' || c == ']' || char::is_whitespace(c))
        .split(',')
        .map(|v| match v.trim().parse() {
            Ok(x) => x,
            Err(_) => panic!("CMAES_THETA: {v:?} is not a number"),
        })
        .collect();
    assert_eq!(theta.len(), P, "CMAES_THETA needs {P} values");
    Some(theta)
}
