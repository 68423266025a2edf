//! The AUV survey task run through the library's own controller stack: [`Adapter`] over a
//! [`CorrectedPd`](ctrl_adapt::controller::CorrectedPd) (the vehicle's position PD plus the 18-parameter linear correction of
//! Leonetti et al. 2012, section 5) scored by [`SurveyCost`], driving the f64 [`Auv`] plant.
//!
//! The controller boundary is `f32`, as on the target: every tick the plant's measured state
//! becomes the policy's state `[target − p, v]` (6 × f32) and the adapter's velocity command
//! (3 × f32) goes back to the plant as f64. The reward is fed the *true* position error, so
//! measurement noise (when on) perturbs the controller, not the score.
//!
//! One tick observes the state the command is computed from (before the step): the survey
//! reward sees the positions at t = 0, 0.1, …, 23.9 s.

use ctrl_adapt::controller::{
    Adapter, AdapterConfig, AdapterError, EpisodeReport, EpisodeRunner, Mode,
};
use ctrl_adapt::cost::SurveyCost;
use ctrl_adapt::optimizer::{
    Bounds, ControlledRandomSearch, CoordinateConfig, CoordinateSearch, CrsConfig, Error,
    Optimizer, Vector,
};
use rand_core::RngCore;

use crate::Episodic;
use crate::auv::{Auv, AuvConfig};

// The AUV configuration lives in one no_std place, shared with the PIL firmware.
pub use auv_survey::{
    AuvAdapter, AuvController, C_MAX, CRS_POINTS, KD, KP, LOCAL_STEP, LOCAL_TOLERANCE, P, RADIUS,
    V_MAX, W_BOUND,
};

/// The global phase's optimizer: CRS with the paper's 100 initial samples.
pub type GlobalSearch = auv_survey::AuvCrs;

/// kp = 0.3, kd = 0.2, |v_cmd| ≤ 0.5 m/s per component, correction within ±0.5 m/s
/// ([`auv_survey::controller`]).
pub fn controller() -> AuvController {
    auv_survey::controller().expect("valid AUV controller constants")
}

/// The box [−1, 1]^18 of W.
pub fn bounds() -> Bounds<P> {
    Bounds::uniform(-W_BOUND, W_BOUND).expect("valid box")
}

/// The adapter's configuration for `learning_episodes` learning episodes. A failed episode
/// (never expected here: the plant's state is always finite) is told 10, more than the
/// start's 7.2 m distance to the target.
pub fn adapter_config(learning_episodes: u32) -> AdapterConfig {
    AdapterConfig {
        dt: 0.1,
        failure_cost: 10.0,
        max_faulty_ticks: 0,
        learning_episodes,
    }
}

/// An adapter over `optimizer` deploying `initial` before anything is told.
pub fn adapter<O: Optimizer<P>>(
    optimizer: O,
    learning_episodes: u32,
    initial: Vector<P>,
) -> Result<AuvAdapter<O>, Error> {
    Adapter::try_new(
        optimizer,
        controller(),
        SurveyCost::try_new(RADIUS)?,
        adapter_config(learning_episodes),
        initial,
    )
}

/// The local phase's optimizer: coordinate search from `start`, step 0.25, tolerance 1e-3.
pub fn coordinate_search(start: Vector<P>, budget: u32) -> Result<CoordinateSearch<P>, Error> {
    CoordinateSearch::try_new(bounds(), start, local_config(budget))
}

/// The coordinate-search configuration of the local phase with `budget` episodes.
pub fn local_config(budget: u32) -> CoordinateConfig {
    CoordinateConfig {
        initial_step: LOCAL_STEP,
        tolerance: LOCAL_TOLERANCE,
        max_evaluations: budget,
        ..CoordinateConfig::DEFAULT
    }
}

/// The global phase's CRS with `budget` episodes (tolerance 1e-6).
pub fn global_search(budget: u32) -> Result<GlobalSearch, Error> {
    ControlledRandomSearch::try_new(
        bounds(),
        CrsConfig {
            max_evaluations: budget,
            ..CrsConfig::DEFAULT
        },
    )
}

/// The "real" and "simulator" plants of the experiments: the paper's currents (0.6 and
/// 0.5 m/s) with seeded disturbances so that episodes are not exactly repeatable:
/// position noise 2 cm, velocity noise 1 cm/s, current turbulence 3 cm/s (5 s correlation).
/// The seed selects the disturbance sequence.
pub fn plant(config: AuvConfig, seed: u64) -> Auv {
    Auv::new(disturbed(config), seed)
}

/// `config` with the experiments' disturbances switched on (see [`plant`]).
pub fn disturbed(config: AuvConfig) -> AuvConfig {
    AuvConfig {
        position_noise_std: 0.02,
        velocity_noise_std: 0.01,
        turbulence_std: 0.03,
        ..config
    }
}

/// What one episode did.
#[derive(Debug, Clone, PartialEq)]
pub struct AuvEpisode {
    /// The adapter's report (θ, mode, cost, what was told).
    pub report: EpisodeReport<P>,
    /// The survey's minimum distance to the target d (m).
    pub min_distance: f32,
    /// Time spent within D (s).
    pub time_within: f32,
    /// The vehicle's true positions at every tick and at the end, when recorded.
    pub trajectory: Option<Vec<[f64; 3]>>,
}

impl AuvEpisode {
    /// The paper's reward J = −cost.
    pub fn reward(&self) -> f32 {
        -self.report.cost
    }
}

/// The policy's state `[target − p, v]` from the plant's measurement, in f32.
pub fn policy_state(auv: &Auv) -> Vector<6> {
    let m = auv.measurement();
    let t = auv.target();
    Vector::from_fn(|i, _| {
        if i < 3 {
            (t[i] - m.position[i]) as f32
        } else {
            m.velocity[i - 3] as f32
        }
    })
}

/// The true position error (target − p), for the reward.
pub fn true_error(auv: &Auv) -> Vector<3> {
    let (t, p) = (auv.target(), auv.state().position);
    Vector::from_fn(|i, _| (t[i] - p[i]) as f32)
}

/// Runs one episode of `adapter` on `auv` (reset first): begin, one control tick per plant
/// step, end. Records the true trajectory if `record`.
pub fn run_episode<O: Optimizer<P>, G: RngCore>(
    adapter: &mut AuvAdapter<O>,
    auv: &mut Auv,
    rng: &mut G,
    record: bool,
) -> Result<AuvEpisode, AdapterError> {
    auv.reset();
    adapter.begin_episode(rng)?;
    drive(adapter, auv, record, &mut |_, _| {})
}

/// The ticks and the end of an episode that has begun; `observe` sees the plant before
/// every step with the command sent, and once more after the last step without one.
fn drive(
    episode: &mut impl Episodic<SurveyCost, P, 6, 3>,
    auv: &mut Auv,
    record: bool,
    observe: &mut dyn FnMut(&Auv, Option<&Vector<3>>),
) -> Result<AuvEpisode, AdapterError> {
    let mut trajectory = record.then(|| Vec::with_capacity(auv.steps_per_episode() + 1));
    for _ in 0..auv.steps_per_episode() {
        if let Some(t) = trajectory.as_mut() {
            t.push(auv.state().position);
        }
        let u = episode.control(&policy_state(auv), &true_error(auv));
        observe(auv, Some(&u));
        auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
    }
    observe(auv, None);
    if let Some(t) = trajectory.as_mut() {
        t.push(auv.state().position);
    }
    let (min_distance, time_within) = (
        episode.shaper().min_distance(),
        episode.shaper().time_within(),
    );
    let report = episode.end_episode()?;
    Ok(AuvEpisode {
        report,
        min_distance,
        time_within,
        trajectory,
    })
}

/// Runs `episodes` episodes of `adapter` on `auv`, calling `on_episode` after each.
pub fn run_episodes<O: Optimizer<P>, G: RngCore>(
    adapter: &mut AuvAdapter<O>,
    auv: &mut Auv,
    rng: &mut G,
    episodes: usize,
    mut on_episode: impl FnMut(&AuvEpisode),
) -> Result<Vec<AuvEpisode>, AdapterError> {
    (0..episodes)
        .map(|_| {
            let e = run_episode(adapter, auv, rng, false)?;
            on_episode(&e);
            Ok(e)
        })
        .collect()
}

/// The first episode (1-based) whose reward is above −`RADIUS`·1 = −1 (cost below 1), if any.
pub fn episodes_to_success(episodes: &[AuvEpisode]) -> Option<usize> {
    episodes
        .iter()
        .position(|e| e.report.cost < RADIUS)
        .map(|k| k + 1)
}

/// The best reward after each episode (non-decreasing).
pub fn best_so_far(episodes: &[AuvEpisode]) -> Vec<f32> {
    let mut best = f32::NEG_INFINITY;
    episodes
        .iter()
        .map(|e| {
            best = best.max(e.reward());
            best
        })
        .collect()
}

/// Runs one episode of the fixed policy `theta` on `auv` (no optimizer: an
/// [`EpisodeRunner`] inside the same envelope, reported as
/// [`Mode::Deploy`]), recording the trajectory if `record`.
pub fn evaluate<G: RngCore>(
    theta: Vector<P>,
    auv: &mut Auv,
    rng: &mut G,
    record: bool,
) -> Result<AuvEpisode, AdapterError> {
    evaluate_observed(theta, auv, rng, record, |_, _| {})
}

/// [`evaluate`], handing `observe` every tick's transition for a plant model: the plant
/// before each step with the command sent to it, and the plant once more after the last
/// step (no command).
pub fn evaluate_observed<G: RngCore>(
    theta: Vector<P>,
    auv: &mut Auv,
    _rng: &mut G,
    record: bool,
    mut observe: impl FnMut(&Auv, Option<&Vector<3>>),
) -> Result<AuvEpisode, AdapterError> {
    bounds().check(&theta, "theta")?;
    let shaper = SurveyCost::try_new(RADIUS)?;
    let mut runner = EpisodeRunner::try_new(controller(), shaper, adapter_config(1))?;
    auv.reset();
    runner.begin_episode(theta, Mode::Deploy)?;
    drive(&mut runner, auv, record, &mut observe)
}
