//! Research helpers for the hopping leg: deployed episodes on given courses, validation
//! courses, and the fresh-course CMA-ES learner that runs a generation's episodes on several
//! threads (bit for bit the adapter's sequential run). Re-exports the whole hopping task
//! (`host_tests::hopper_task`), so a study imports one module.

use ctrl_adapt::controller::AdapterError;
use ctrl_adapt::cost::ApexConfig;
use ctrl_adapt::optimizer::{
    Cmaes, CmaesConfig, Optimizer, Rockstar, RockstarConfig, Status, Vector,
};
use host_tests::hopper::{HopperConfig, NominalHopping};
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

/// The unseen courses every spread is reported on (20: five courses read a 1.88 cm gait as
/// 1.62 cm).
pub const UNSEEN_COURSES: std::ops::RangeInclusive<u64> = 10_001..=10_020;

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
        if every > 0 && k.is_multiple_of(every) {
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

// ROCK* on the hopping task, and robustness of a learned gait.

/// Remembered rollouts of [`HopRockstar`]: M = 5n, the size the module docs of
/// [`Rockstar`] recommend (the window of the authors' C++ code).
pub const ROCK_MEMORY: usize = 5 * P;

/// ROCK* (Hwangbo et al., Humanoids 2014) on the 31 hopping parameters.
pub type HopRockstar = Rockstar<P, ROCK_MEMORY>;

/// [`HopRockstar`] from `start` with σ₀ = `sigma0` (relative to each half-range of
/// [`bounds`]) and a budget of `evaluations`; every other setting is
/// [`RockstarConfig::DEFAULT`] (the paper's and the authors' code's defaults).
pub fn rockstar(
    start: Vector<P>,
    sigma0: f32,
    evaluations: u32,
) -> Result<HopRockstar, ctrl_adapt::Error> {
    Rockstar::try_new(bounds(), start, rockstar_config(sigma0, evaluations))
}

/// The configuration of [`rockstar`]: the defaults.
pub fn rockstar_config(sigma0: f32, evaluations: u32) -> RockstarConfig {
    RockstarConfig {
        initial_sigma: sigma0,
        max_evaluations: evaluations,
        ..RockstarConfig::DEFAULT
    }
}

/// ξ of [`noisy_rockstar_config`]: ≈ ζ^{0.1} for n = 31 (ζ = 1.3^{1/ln 33.5} ≈ 1.0776),
/// against the default ζ^{0.3}.
pub const NOISY_XI: f32 = 1.0075;

/// [`rockstar_config`] for costs that change from rollout to rollout (a new course every
/// episode): ξ = [`NOISY_XI`]. ROCK*'s step-size rule compares each rollout's cost with the
/// previous one's, growing σ by ζ after one no worse and shrinking it by ζξ after a worse
/// one. When the course-to-course noise decides the comparison (each way about half the
/// time), ξ = ζ^a shrinks σ by a factor ζ^{a/2} per rollout on average: ≈ 1.1 % a rollout
/// with the default a = 0.3, which took σ from 0.1 to 10⁻⁶ in ≈ 900 rollouts on the hopper
/// (findings/hopping.md); a = 0.1 shrinks it three times slower.
pub fn noisy_rockstar_config(sigma0: f32, evaluations: u32) -> RockstarConfig {
    RockstarConfig {
        xi: Some(NOISY_XI),
        ..rockstar_config(sigma0, evaluations)
    }
}

/// How the rollouts of one learning episode under a [`Perturbation`] are scored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrawScore {
    /// One rollout under one draw (plain domain randomisation).
    One,
    /// k rollouts on the same course under k draws, the highest cost told.
    WorstOf(u32),
    /// k rollouts on the same course under k draws, the mean cost told.
    MeanOf(u32),
}

impl DrawScore {
    /// Rollouts per learning episode.
    pub fn rollouts(self) -> u32 {
        match self {
            Self::One => 1,
            Self::WorstOf(k) | Self::MeanOf(k) => k.max(1),
        }
    }
}

/// Random changes of one rollout (domain randomisation; the acceptance check
/// [`robustness`] uses [`Perturbation::CHECK`]'s ranges): every parameter moved by a uniform
/// draw in ± `theta` of its range (upper − lower bound of [`bounds`], the result clamped to
/// the box), the leg's mass (thigh and shank masses and inertias) scaled by 1 + a uniform
/// draw in ± `leg_mass`, the ground's stiffness and its dissipation ([`Contact::scaled`]) each
/// by a log-uniform factor in [1/f, f] for the factor f given.
///
/// [`Contact::scaled`]: host_tests::hopper::Contact::scaled
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Perturbation {
    /// Fraction of each parameter's range.
    pub theta: f32,
    /// Relative change of the leg's mass.
    pub leg_mass: f64,
    /// Largest factor (≥ 1) of the ground stiffness: ×[1/f, f].
    pub ground_stiffness: f64,
    /// Largest factor (≥ 1) of the ground's dissipation: ×[1/f, f].
    pub ground_damping: f64,
    /// How the rollouts of a learning episode are scored.
    pub score: DrawScore,
}

impl Perturbation {
    /// No change: the nominal rollout.
    pub const NONE: Self = Self {
        theta: 0.0,
        leg_mass: 0.0,
        ground_stiffness: 1.0,
        ground_damping: 1.0,
        score: DrawScore::One,
    };

    /// The ranges of the acceptance check: every parameter ± 2 % of its range, leg mass
    /// ± 10 %, ground stiffness and dissipation ×0.5 to ×2; one draw per episode.
    pub const CHECK: Self = Self {
        theta: 0.02,
        leg_mass: 0.1,
        ground_stiffness: 2.0,
        ground_damping: 2.0,
        score: DrawScore::One,
    };
}

/// A uniform draw in [−1, 1).
fn symmetric<G: RngCore>(rng: &mut G) -> f64 {
    (rng.next_u64() >> 11) as f64 * (2.0 / (1u64 << 53) as f64) - 1.0
}

/// `theta` with every parameter moved by a uniform draw in ± `fraction` of its range, clamped
/// to [`bounds`] (P draws from `rng`, whatever `fraction`).
pub fn perturb_theta<G: RngCore>(theta: Vector<P>, fraction: f32, rng: &mut G) -> Vector<P> {
    let b = bounds();
    let (lo, up) = (*b.lower(), *b.upper());
    Vector::<P>::from_fn(|i, _| {
        let moved = theta[i] + symmetric(rng) as f32 * fraction * (up[i] - lo[i]);
        moved.clamp(lo[i], up[i])
    })
}

/// A leg variant: scales of the leg mass, the ground stiffness and its dissipation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leg {
    /// Leg mass scale (thigh and shank masses and inertias).
    pub mass: f64,
    /// Ground stiffness scale.
    pub stiffness: f64,
    /// Ground dissipation scale.
    pub damping: f64,
}

impl Leg {
    /// The nominal leg and ground.
    pub const NOMINAL: Self = Self {
        mass: 1.0,
        stiffness: 1.0,
        damping: 1.0,
    };

    /// [`HopperConfig::SCARLETH`] with these scales.
    pub fn config(&self) -> HopperConfig {
        let c = HopperConfig::SCARLETH;
        HopperConfig {
            thigh_mass: c.thigh_mass * self.mass,
            shank_mass: c.shank_mass * self.mass,
            thigh_inertia: c.thigh_inertia * self.mass,
            shank_inertia: c.shank_inertia * self.mass,
            contact: c.contact.scaled(self.stiffness, self.damping),
            ..c
        }
    }
}

/// One deployed episode (cost `apex`) of `theta` on the course of `seed`, on the leg `leg`.
pub fn episode_on_leg(
    theta: Vector<P>,
    seed: u64,
    apex: ApexConfig,
    leg: Leg,
) -> Result<HopEpisode, AdapterError> {
    let mut unused = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(0);
    evaluate_with(
        theta,
        &mut plant_for(leg.config(), true, seed),
        &mut unused,
        false,
        &NominalHopping::TUNED,
        apex,
    )
}

/// The cost a learning adapter tells (the episode's cost, or the failure cost) for one
/// learning episode of `theta` on the course of `seed` under `perturbation`: one rollout per
/// draw ([`DrawScore`]), each draw P + 3 numbers from `rng` (whatever the perturbation), the
/// rollouts scored as one, worst-of-k or mean-of-k. What the robot meets when its gait
/// parameters, its leg and its ground are not exactly the ones the policy was learned for.
pub fn perturbed_told_cost<G: RngCore>(
    theta: Vector<P>,
    seed: u64,
    apex: ApexConfig,
    perturbation: Perturbation,
    rng: &mut G,
) -> Result<f32, AdapterError> {
    let log_factor = |f: f64, rng: &mut G| (f.max(1.0).ln() * symmetric(rng)).exp();
    let k = perturbation.score.rollouts();
    let (mut worst, mut total) = (f32::NEG_INFINITY, 0.0f32);
    for _ in 0..k {
        let moved = perturb_theta(theta, perturbation.theta, rng);
        let leg = Leg {
            mass: 1.0 + perturbation.leg_mass * symmetric(rng),
            stiffness: log_factor(perturbation.ground_stiffness, rng),
            damping: log_factor(perturbation.ground_damping, rng),
        };
        let e = episode_on_leg(moved, seed, apex, leg)?;
        let cost = if e.report.failed {
            adapter_config(1).failure_cost
        } else {
            e.report.cost
        };
        worst = worst.max(cost);
        total += cost;
    }
    Ok(match perturbation.score {
        DrawScore::WorstOf(_) => worst,
        _ => total / k as f32,
    })
}

/// The mean [`perturbed_told_cost`] of `theta` over the [`VALIDATION_COURSES`], the
/// perturbations drawn from a fixed seed (the same draws for every θ scored, so scores
/// compare policies, not draws); with [`Perturbation::NONE`] it is [`validation_cost`].
pub fn perturbed_validation_cost(
    theta: Vector<P>,
    apex: ApexConfig,
    perturbation: Perturbation,
) -> Result<f64, AdapterError> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(0x5eed);
    let mut total = 0.0;
    for seed in VALIDATION_COURSES {
        total += f64::from(perturbed_told_cost(
            theta,
            seed,
            apex,
            perturbation,
            &mut rng,
        )?);
    }
    Ok(total / VALIDATION_COURSES.count() as f64)
}

/// One scoring of a learner's deployable policy on the validation courses.
#[derive(Debug, Clone)]
pub struct Scored {
    /// Learning episodes told so far.
    pub episode: u32,
    /// Rollouts so far: learning episodes plus the validation episodes of every scoring up to
    /// and including this one (the robot runs those too).
    pub rollouts: u32,
    /// The deployable policy scored.
    pub theta: Vector<P>,
    /// Its [`perturbed_validation_cost`].
    pub validation_cost: f64,
}

/// What [`learn_sequentially`] returns: every scoring, in order.
#[derive(Debug, Clone)]
pub struct Scores(pub Vec<Scored>);

impl Scores {
    /// The policy early stopping keeps within a budget of `episodes` learning episodes: the
    /// scoring with the lowest validation cost among those after at most `episodes`.
    pub fn kept(&self, episodes: u32) -> Option<&Scored> {
        self.0
            .iter()
            .filter(|s| s.episode <= episodes)
            .min_by(|a, b| a.validation_cost.total_cmp(&b.validation_cost))
    }
}

/// Learns with `optimizer` for up to `episodes` episodes, one thread, episode k (from 0) on
/// a new course (seed [`FRESH_COURSES`] + k, as [`learn_on_fresh_courses`]), each rollout
/// under a random draw of `perturbation` from `perturbation_rng` ([`perturbed_told_cost`];
/// [`Perturbation::NONE`] for the nominal task) and told its cost with `apex`. At the start,
/// after every `every` episodes and at the end, `deploy(optimizer)` (e.g. ROCK*'s θ*, or
/// CMA-ES's mean) is scored by [`perturbed_validation_cost`] with the same perturbation
/// (early stopping: [`Scores::kept`]). When the optimizer stops (converged, or its own
/// budget spent) with episodes left, `restart(optimizer, episodes left)` may hand a new one
/// to continue with (e.g. a new search from the last θ*: a restart); with `None` learning
/// ends there.
#[allow(clippy::too_many_arguments)]
pub fn learn_sequentially<O: Optimizer<P>, G: RngCore, H: RngCore>(
    optimizer: &mut O,
    deploy: impl Fn(&O) -> Vector<P>,
    mut restart: impl FnMut(&O, u32) -> Option<O>,
    episodes: u32,
    apex: ApexConfig,
    perturbation: Perturbation,
    rng: &mut G,
    perturbation_rng: &mut H,
    every: u32,
) -> Result<Scores, AdapterError> {
    let per_scoring = VALIDATION_COURSES.count() as u32 * perturbation.score.rollouts();
    let mut scores = Vec::new();
    let mut rollouts = 0;
    let mut score = |k: u32, o: &O, rollouts: &mut u32| -> Result<(), AdapterError> {
        let theta = deploy(o);
        *rollouts += per_scoring;
        scores.push(Scored {
            episode: k,
            rollouts: *rollouts,
            theta,
            validation_cost: perturbed_validation_cost(theta, apex, perturbation)?,
        });
        Ok(())
    };
    score(0, optimizer, &mut rollouts)?;
    let mut k = 0u32;
    while k < episodes {
        if optimizer.status() != Status::Running {
            match restart(optimizer, episodes - k) {
                Some(o) => *optimizer = o,
                None => break,
            }
        }
        let theta = optimizer.ask(rng)?;
        let cost = perturbed_told_cost(
            theta,
            FRESH_COURSES + u64::from(k),
            apex,
            perturbation,
            perturbation_rng,
        )?;
        optimizer.tell(cost)?;
        k += 1;
        rollouts += perturbation.score.rollouts();
        if every > 0 && k.is_multiple_of(every) {
            score(k, optimizer, &mut rollouts)?;
        }
    }
    if every == 0 || !k.is_multiple_of(every) {
        score(k, optimizer, &mut rollouts)?;
    }
    Ok(Scores(scores))
}

/// The absolute pass criterion of [`robustness`]: a run passes if it hops stably with an apex
/// spread of at most this (cm).
pub const ABSOLUTE_SPREAD_CM: f64 = 3.0;

/// The parameter draws of [`robustness`].
pub const CHECK_DRAWS: usize = 100;

/// How a set of runs of [`robustness`] fared.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Runs {
    /// Runs.
    pub runs: usize,
    /// Hopped stably with a spread ≤ 2× the policy's own on that course (relative).
    pub relative: usize,
    /// Hopped stably with a spread ≤ [`ABSOLUTE_SPREAD_CM`] (absolute).
    pub absolute: usize,
    /// Collapsed.
    pub collapsed: usize,
    /// Kept hopping but not stably (fewer than 15 hops, or the mean apex more than 5 cm from
    /// the set height: another gait).
    pub off_gait: usize,
    /// The largest spread (cm) among the runs that did not collapse.
    pub worst_spread: f64,
}

impl Runs {
    fn add(&mut self, e: &HopEpisode, own: f64) {
        let spread = e.apex_spread() * 100.0;
        self.runs += 1;
        self.relative += usize::from(e.hops_stably() && spread <= 2.0 * own);
        self.absolute += usize::from(e.hops_stably() && spread <= ABSOLUTE_SPREAD_CM);
        if e.collapsed {
            self.collapsed += 1;
        } else {
            self.off_gait += usize::from(!e.hops_stably());
            self.worst_spread = self.worst_spread.max(spread);
        }
    }

    fn line(&self) -> String {
        format!(
            "{}/{} absolute, {}/{} relative, {} collapse, {} off the gait, worst spread {:.2} cm",
            self.absolute,
            self.runs,
            self.relative,
            self.runs,
            self.collapsed,
            self.off_gait,
            self.worst_spread
        )
    }
}

/// One leg variant of [`Robustness`], run on every unseen course.
#[derive(Debug, Clone)]
pub struct LegResult {
    /// The variant.
    pub leg: Leg,
    /// Spreads (cm) on the [`UNSEEN_COURSES`].
    pub spreads: Vec<f64>,
    /// How its runs fared.
    pub runs: Runs,
}

/// How a fixed policy stands up to small changes ([`robustness`]).
#[derive(Debug, Clone)]
pub struct Robustness {
    /// The policy's own apex spreads (cm) on the [`UNSEEN_COURSES`], nominal leg.
    pub nominal: Vec<f64>,
    /// Whether the policy itself hops stably on every unseen course.
    pub nominal_stable: bool,
    /// The parameter draws.
    pub theta: Runs,
    /// The leg and ground variants.
    pub legs: Vec<LegResult>,
}

impl Robustness {
    /// All leg runs together.
    pub fn leg_runs(&self) -> Runs {
        let mut all = Runs::default();
        for l in &self.legs {
            let r = &l.runs;
            all.runs += r.runs;
            all.relative += r.relative;
            all.absolute += r.absolute;
            all.collapsed += r.collapsed;
            all.off_gait += r.off_gait;
            all.worst_spread = all.worst_spread.max(r.worst_spread);
        }
        all
    }

    /// The absolute check: the policy hops stably with a spread ≤ [`ABSOLUTE_SPREAD_CM`] on
    /// every unseen course, and so does every parameter draw and every leg run.
    pub fn passes_absolute(&self) -> bool {
        let legs = self.leg_runs();
        self.nominal_stable
            && self.nominal.iter().all(|&s| s <= ABSOLUTE_SPREAD_CM)
            && self.theta.absolute == self.theta.runs
            && legs.absolute == legs.runs
    }

    /// The relative check: the policy hops stably on every unseen course, and every draw and
    /// leg run hops stably within 2× the policy's own spread on its course. Strictest on the
    /// gaits with the smallest spreads; reported beside the absolute check.
    pub fn passes_relative(&self) -> bool {
        let legs = self.leg_runs();
        self.nominal_stable && self.theta.relative == self.theta.runs && legs.relative == legs.runs
    }

    /// One line: nominal spreads, the parameter draws, the legs, and both verdicts.
    pub fn summary(&self) -> String {
        format!(
            "own median {:.2} cm, max {:.2} (stable {}); every parameter ± 2 % of its range: {}; \
             leg mass ± 10 %, ground stiffness and dissipation ×0.5–×2: {}; passes absolute \
             {}, relative {}",
            host_tests::median(self.nominal.clone()),
            self.nominal.iter().copied().fold(0.0, f64::max),
            self.nominal_stable,
            self.theta.line(),
            self.leg_runs().line(),
            self.passes_absolute(),
            self.passes_relative(),
        )
    }
}

/// The leg variants of [`robustness`]: mass ×0.9 and ×1.1, ground stiffness ×0.5 and ×2,
/// ground dissipation ×0.5 and ×2, one at a time, then the eight corners.
pub fn check_legs() -> Vec<Leg> {
    let mut legs = Vec::new();
    for (mass, stiffness, damping) in [
        (0.9, 1.0, 1.0),
        (1.1, 1.0, 1.0),
        (1.0, 0.5, 1.0),
        (1.0, 2.0, 1.0),
        (1.0, 1.0, 0.5),
        (1.0, 1.0, 2.0),
    ] {
        legs.push(Leg {
            mass,
            stiffness,
            damping,
        });
    }
    for mass in [0.9, 1.1] {
        for stiffness in [0.5, 2.0] {
            for damping in [0.5, 2.0] {
                legs.push(Leg {
                    mass,
                    stiffness,
                    damping,
                });
            }
        }
    }
    legs
}

/// The acceptance check of a deployed gait: `theta` on the [`UNSEEN_COURSES`] (nominal leg),
/// then `draws` draws of every parameter moved uniformly by ± 2 % of its range
/// ([`perturb_theta`], RNG seed `seed`; draw j on unseen course j mod 20), then the leg and
/// ground variants of [`check_legs`] (14 × 20 courses). Each run is judged absolutely (hops
/// stably — no collapse, ≥ 15 hops, mean apex within 5 cm of 0.6 m — with a spread ≤
/// [`ABSOLUTE_SPREAD_CM`]) and relatively (hops stably with a spread ≤ 2× `theta`'s own on
/// that course); [`Robustness::passes_absolute`] and [`Robustness::passes_relative`].
pub fn robustness(theta: Vector<P>, draws: usize, seed: u64) -> Result<Robustness, AdapterError> {
    let apex = apex_config();
    let courses: Vec<u64> = UNSEEN_COURSES.collect();
    let own = courses
        .iter()
        .map(|&s| episode_on_leg(theta, s, apex, Leg::NOMINAL))
        .collect::<Result<Vec<_>, AdapterError>>()?;
    let nominal: Vec<f64> = own.iter().map(|e| e.apex_spread() * 100.0).collect();
    let nominal_stable = own.iter().all(HopEpisode::hops_stably);
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut draws_run = Runs::default();
    for j in 0..draws {
        let moved = perturb_theta(theta, 0.02, &mut rng);
        let c = j % courses.len();
        draws_run.add(
            &episode_on_leg(moved, courses[c], apex, Leg::NOMINAL)?,
            nominal[c],
        );
    }
    let mut legs = Vec::new();
    for leg in check_legs() {
        let mut runs = Runs::default();
        let mut spreads = Vec::new();
        for (c, &s) in courses.iter().enumerate() {
            let e = episode_on_leg(theta, s, apex, leg)?;
            runs.add(&e, nominal[c]);
            spreads.push(e.apex_spread() * 100.0);
        }
        legs.push(LegResult { leg, spreads, runs });
    }
    Ok(Robustness {
        nominal,
        nominal_stable,
        theta: draws_run,
        legs,
    })
}

/// The extra apex after the 5.5 cm block (cm) of `theta` over the courses `seeds`, nominal
/// leg: the mean apex of the hops launched from the block right after a lower ground minus
/// the mean apex of the hops launched from the floor after the floor, both pooled over the
/// courses ([`HopEpisode::block_apexes`]); NaN if the courses have no such hops.
pub fn block_extra_apex(
    theta: Vector<P>,
    seeds: impl Iterator<Item = u64>,
) -> Result<f64, AdapterError> {
    let (mut up, mut flat) = (Vec::new(), Vec::new());
    for s in seeds {
        let (u, f) = episode_on_leg(theta, s, apex_config(), Leg::NOMINAL)?.block_apexes();
        up.extend(u);
        flat.extend(f);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    Ok((mean(&up) - mean(&flat)) * 100.0)
}

/// `run(seed)` for every seed of `seeds`, on [`threads`] threads (each run on one thread, so
/// a run's result does not depend on the number of threads), results in the order of `seeds`.
pub fn map_seeds<T: Send>(seeds: &[u64], run: impl Fn(u64) -> T + Sync) -> Vec<T> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<(usize, T)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads().min(seeds.len()).max(1))
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(&seed) = seeds.get(i) else { break };
                        done.push((i, run(seed)));
                    }
                    done
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a run panicked"))
            .collect()
    });
    results.sort_by_key(|(i, _)| *i);
    results.into_iter().map(|(_, r)| r).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use host_tests::hopper::Contact;

    /// Checks: a leg variant scales the leg's masses and inertias and the ground's stiffness
    /// and dissipation (Hunt–Crossley: k by the stiffness scale, λ = 3/2 α k by both), and
    /// the check's variants are the 6 one-at-a-time and the 8 corners, all distinct.
    #[test]
    fn leg_variants_scale_what_they_name() {
        let leg = Leg {
            mass: 1.1,
            stiffness: 2.0,
            damping: 0.5,
        };
        let (c, n) = (leg.config(), HopperConfig::SCARLETH);
        assert_eq!(c.thigh_mass, n.thigh_mass * 1.1);
        assert_eq!(c.shank_inertia, n.shank_inertia * 1.1);
        assert_eq!(c.body_mass, n.body_mass);
        let (
            Contact::HuntCrossley {
                stiffness: k,
                damping: l,
                ..
            },
            Contact::HuntCrossley {
                stiffness: k0,
                damping: l0,
                ..
            },
        ) = (c.contact, n.contact)
        else {
            panic!("the default ground is Hunt–Crossley");
        };
        assert_eq!((k, l), (k0 * 2.0, l0 * 2.0 * 0.5));
        assert_eq!(Leg::NOMINAL.config(), n);
        let legs = check_legs();
        assert_eq!(legs.len(), 14);
        for (i, a) in legs.iter().enumerate() {
            assert!(legs[i + 1..].iter().all(|b| b != a), "{a:?} twice");
        }
    }

    /// Checks: worst-of-k tells the highest of its k costs and mean-of-k their mean, from the
    /// same draws (same RNG seed): worst ≥ mean, and k rollouts are counted per episode.
    #[test]
    fn worst_of_k_is_at_least_mean_of_k() {
        let apex = spread_apex_config();
        let told = |score| {
            let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(3);
            let p = Perturbation {
                score,
                ..Perturbation::CHECK
            };
            perturbed_told_cost(Vector::zeros(), 10_001, apex, p, &mut rng).unwrap()
        };
        let (worst, mean) = (told(DrawScore::WorstOf(2)), told(DrawScore::MeanOf(2)));
        assert!(worst >= mean && mean > 0.0, "worst {worst}, mean {mean}");
        assert_eq!(DrawScore::WorstOf(3).rollouts(), 3);
        assert_eq!(DrawScore::One.rollouts(), 1);
    }
}
