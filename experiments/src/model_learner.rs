//! The library's model-based learner (`ctrl_adapt::model::ModelBased`) on the robots' tasks:
//! the episode loop ([`learn`]: the bare controller's episode, a few small exploration
//! episodes that make the model identifiable, then one proposal per real episode, screened
//! by the model), the tasks' plant models and their imagined episodes ([`AuvModels`],
//! [`HopperModel`], [`ArmModel`]), and the learner on an oracle trial ([`run_on_trial`], the
//! oracle's `model` method). The examples `model_safety_auv` and `model_learner_tasks` run
//! the same loop and models; their settings, chosen there, are the ones used here
//! (findings/model.md).
//!
//! Units: the learner searches u, with θ = u on the AUV (its box is [−1, 1]^18), θ = u ⊙ the
//! box's upper corner on the hopper (u ∈ [−1, 1]^31), and θ = θ₀ + 100·u on the arm (θ₀ the
//! minimum-jerk θ, 100 the via-point study's exploration).

use std::time::{Duration, Instant};

use ctrl_adapt::controller::Controller;
use ctrl_adapt::cost::{ApexHeightCost, HopSample, Shaper, SurveyCost};
use ctrl_adapt::model::{
    Affine, AffineWith, ModelBased, ModelBasedConfig, ModelConfig, Prediction, RlsModel, Source,
    imagine_episode_with_variance, rollout,
};
use ctrl_adapt::optimizer::{
    Bounds, Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch, Error, Optimizer, Vector,
};
use host_tests::arm::{self, LINKS, PARAMS, ViaPointArm};
use host_tests::auv_task::{self, RADIUS};
use host_tests::hopper::Hopper;
use host_tests::hopper_task::{self, P as HP};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

use crate::peers::{RunReport, Task, Tick, Trial, to_vec};

/// Where the θ of a real episode came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    /// The bare controller (u = 0), the first episode.
    Bare,
    /// A small exploration draw around the bare controller.
    Explore,
    /// The model's candidate, passed by the screen.
    Model,
    /// The model-free fallback's candidate.
    Fallback,
}

impl Origin {
    /// Its letter in the examples' traces: b, e, m, f.
    pub fn letter(self) -> char {
        match self {
            Self::Bare => 'b',
            Self::Explore => 'e',
            Self::Model => 'm',
            Self::Fallback => 'f',
        }
    }
}

/// One real episode, as a [`Plant`] reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Real {
    /// Its cost.
    pub cost: f32,
    /// The plant's own judgement of the episode (the oracle's unsafe episode; `false` where
    /// the plant does not judge).
    pub flagged: bool,
}

/// The robot and its model, in the learner's units u.
pub trait Plant<const P: usize> {
    /// Runs one real episode of u and fits the model on its ticks.
    fn episode(&mut self, u: &Vector<P>) -> Real;
    /// The model's predicted cost of u; an error where it cannot say (a diverging rollout).
    fn predict(&self, u: &Vector<P>) -> Result<f32, Error>;
    /// The predicted cost with the model's uncertainty about u (the learner's
    /// candidate-dependent screen, `ModelBasedConfig::uncertainty_weight`); by default the
    /// point prediction, uncertainty 0.
    fn prediction(&self, u: &Vector<P>) -> Result<Prediction, Error> {
        self.predict(u).map(Prediction::from)
    }
}

/// The prediction error the learner assumes before its first proposal
/// (`ModelBasedConfig::initial_error`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialError {
    /// This value.
    Fixed(f32),
    /// The root mean square of real − predicted over the exploration episodes, each
    /// predicted before it ran; an error of a failed prediction, and any larger one,
    /// counts as `cap`.
    Measured {
        /// The largest error one episode contributes.
        cap: f32,
    },
}

/// How [`learn`] runs the learner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings<const P: usize> {
    /// The learner's constants; `margin` and `initial_error` are replaced (below).
    pub config: ModelBasedConfig,
    /// The screen's margin as a fraction of the bare episode's |cost|.
    pub margin: f32,
    /// Exploration episodes after the bare one.
    pub explorations: usize,
    /// Their half-widths: u uniform in ±`explore` per coordinate (0: the bare θ, an episode
    /// that only feeds the plant's model, see [`learn`]).
    pub explore: Vector<P>,
    /// The initial prediction error.
    pub initial_error: InitialError,
}

impl<const P: usize> Settings<P> {
    /// The settings chosen on the AUV (`model_learner_auv`, kept by `model_safety_auv`):
    /// trust radius 0.15 in [0.05, 1], ×1.5 / ×0.6, the screen at 1.2 × the bare cost,
    /// 3 explorations of ±0.05, no pessimism; `inner_evaluations` predictions per proposal.
    pub fn chosen(inner_evaluations: u32) -> Self {
        Self {
            config: ModelBasedConfig {
                inner_evaluations,
                ..ModelBasedConfig::DEFAULT
            },
            margin: 0.2,
            explorations: 3,
            explore: Vector::repeat(0.05),
            initial_error: InitialError::Fixed(0.0),
        }
    }
}

/// What one learning run did, episode by episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// The real costs.
    pub costs: Vec<f32>,
    /// Where each θ came from.
    pub origin: Vec<Origin>,
    /// The plant's judgement of each ([`Real::flagged`]).
    pub flagged: Vec<bool>,
    /// The model's prediction of each (the bare episode's: none; a failed one: none).
    pub predicted: Vec<Option<f32>>,
    /// The model's uncertainty about each proposal ([`Plant::prediction`]; the bare and the
    /// exploration episodes': none).
    pub uncertainty: Vec<Option<f32>>,
    /// The learner's measured prediction error before each (after recording, for the bare
    /// and the exploration episodes).
    pub errors: Vec<f32>,
    /// The best real u.
    pub best: Option<Vec<f32>>,
    /// Time spent in the learner (the proposals with their imagined episodes, and tell).
    pub learner_time: Duration,
}

impl Run {
    /// The episodes whose θ came from `origin`.
    pub fn count(&self, origin: Origin) -> usize {
        self.origin.iter().filter(|o| **o == origin).count()
    }
}

fn uniform<const P: usize>(rng: &mut impl RngCore, half_width: &Vector<P>) -> Vector<P> {
    Vector::from_fn(|i, _| {
        let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
        half_width[i] * (2.0 * unit - 1.0)
    })
}

/// The learner on `plant` for at most `budget` real episodes (fewer if the fallback is
/// spent while the model's candidate does not pass): the bare controller (u = 0), the
/// exploration draws (each predicted before it runs), then `ModelBased` with `fallback`
/// and the inner optimizer `inner` builds, its threshold the bare cost plus the margin (its
/// trust region restarted by the learner itself when `config.restart_after` says so).
/// Errors: the learner's construction (a bad configuration or a non-finite bare cost).
pub fn learn<const P: usize, O: Optimizer<P>>(
    plant: &mut impl Plant<P>,
    bounds: Bounds<P>,
    fallback: impl Optimizer<P>,
    mut inner: impl FnMut(Bounds<P>, Vector<P>) -> Result<O, Error>,
    settings: &Settings<P>,
    budget: usize,
    rng: &mut impl RngCore,
) -> Result<Run, Error> {
    let bare = plant.episode(&Vector::zeros());
    let mut explored = Vec::with_capacity(settings.explorations);
    let mut squared = 0.0f32;
    for _ in 0..settings.explorations.min(budget.saturating_sub(1)) {
        let u = uniform(rng, &settings.explore);
        let predicted = plant.predict(&u);
        let e = plant.episode(&u);
        if let InitialError::Measured { cap } = settings.initial_error {
            let error = predicted.map_or(cap, |p| (e.cost - p).abs().min(cap));
            squared += error * error;
        }
        explored.push((u, e, predicted.ok()));
    }
    let initial_error = match settings.initial_error {
        InitialError::Fixed(e) => e,
        InitialError::Measured { .. } => (squared / explored.len().max(1) as f32).sqrt(),
    };
    let config = ModelBasedConfig {
        margin: settings.margin * bare.cost.abs(),
        initial_error,
        ..settings.config
    };
    let mut learner = ModelBased::try_new(bounds, fallback, config)?;
    learner.record(Vector::zeros(), bare.cost.min(f32::MAX))?;
    learner.set_reference(bare.cost)?;
    let mut run = Run {
        costs: vec![bare.cost],
        origin: vec![Origin::Bare],
        flagged: vec![bare.flagged],
        predicted: vec![None],
        uncertainty: vec![None],
        errors: vec![learner.prediction_error()],
        best: None,
        learner_time: Duration::ZERO,
    };
    for (u, e, predicted) in explored {
        // An exploration of u = 0 (half-widths 0) is the bare θ again, a plant's
        // identification episode (`auv_guard::GuardedAuv` dithers its commands): the bare
        // episode's cost stands for u = 0, so it only feeds the model.
        if u.iter().any(|v| *v != 0.0) {
            learner.record(u, e.cost.min(f32::MAX))?;
        }
        run.costs.push(e.cost);
        run.origin.push(Origin::Explore);
        run.flagged.push(e.flagged);
        run.predicted.push(predicted);
        run.uncertainty.push(None);
        run.errors.push(learner.prediction_error());
    }
    while run.costs.len() < budget {
        let error = learner.prediction_error();
        let t0 = Instant::now();
        let proposal =
            learner.propose_bounded(rng, &mut inner, |u: &Vector<P>| plant.prediction(u));
        run.learner_time += t0.elapsed();
        // The fallback is spent and the model's candidate did not pass: stop.
        let Ok(proposal) = proposal else { break };
        // The model's cost and uncertainty of the proposal, whichever proposed it.
        let prediction = plant.prediction(&proposal.theta).ok();
        let predicted = prediction.map(|p| p.cost);
        let e = plant.episode(&proposal.theta);
        let t1 = Instant::now();
        let told = learner.tell(e.cost.min(f32::MAX));
        run.learner_time += t1.elapsed();
        run.costs.push(e.cost);
        run.origin.push(match proposal.source {
            Source::Model(_) => Origin::Model,
            Source::Fallback => Origin::Fallback,
        });
        run.flagged.push(e.flagged);
        run.predicted.push(predicted);
        run.uncertainty.push(prediction.map(|p| p.uncertainty));
        run.errors.push(error);
        if told.is_err() {
            break;
        }
    }
    run.best = learner.best().map(|b| to_vec(&b.theta));
    Ok(run)
}

/// The inner optimizer of every task: CMA-ES (λ = `L`) from the best real u, σ₀ half the
/// trust box, `evaluations` predictions.
pub fn inner_cmaes<const P: usize, const L: usize>(
    evaluations: u32,
) -> impl FnMut(Bounds<P>, Vector<P>) -> Result<Cmaes<P, L>, Error> {
    move |trust, centre| {
        let config = CmaesConfig {
            initial_sigma: 0.5,
            max_evaluations: evaluations,
            ..CmaesConfig::DEFAULT
        };
        Cmaes::try_new(trust, centre, config)
    }
}

// ---------------------------------------------------------------------------------------
// The AUV.

/// The AUV's control period (s).
pub const AUV_DT: f32 = 0.1;
/// Ticks of an AUV episode (24 s).
pub const AUV_TICKS: u32 = 240;
/// Regressors of the AUV model: [x, u, 1] and the four bounded-drag features.
pub const AUV_R: usize = 14;
/// The AUV's plant model.
pub type AuvRls = RlsModel<6, 3, AUV_R>;
/// The AUV model's regressor map.
pub type AuvMap = AffineWith<4, fn(&Vector<6>, &Vector<3>) -> Vector<4>>;

/// The bounded-drag features of `model_auv` ([depth above the current layer], |v|·v per
/// axis with v clamped to the vehicle's reach ±0.6 m/s).
pub fn bounded_drag(x: &Vector<6>, _: &Vector<3>) -> Vector<4> {
    const LAYER: f32 = 2.0;
    const TARGET_DEPTH: f32 = 4.8;
    let q = |v: f32| {
        let v = v.clamp(-0.6, 0.6);
        v.abs() * v
    };
    let layer = if TARGET_DEPTH - x[2] > LAYER {
        1.0
    } else {
        0.0
    };
    Vector::<4>::new(layer, q(x[3]), q(x[4]), q(x[5]))
}

/// The AUV's model: `RlsModel<6, 3, 14>` of the policy's state [target − p, v] and the
/// velocity command with the bounded-drag features, fitted on every tick; optionally an
/// ensemble (model j + 1 leaves out the episodes whose index is j modulo `ensemble`), the
/// prediction then the worst of theirs and the full model's.
#[derive(Debug, Clone)]
pub struct AuvModels {
    map: AuvMap,
    models: Vec<AuvRls>,
    ensemble: usize,
    episodes: usize,
    start: Option<Vector<6>>,
}

impl AuvModels {
    /// Fresh models (`ModelConfig::DEFAULT`); `ensemble` 0 for the full model alone.
    pub fn new(ensemble: usize) -> Self {
        let model = AuvRls::try_new(ModelConfig::DEFAULT).expect("the default model config");
        Self {
            map: AffineWith::new(bounded_drag as fn(&Vector<6>, &Vector<3>) -> Vector<4>),
            models: vec![model; 1 + ensemble],
            ensemble,
            episodes: 0,
            start: None,
        }
    }

    /// Fits one episode's ticks: states x₀ … x_T and the commands u₀ … u_{T−1}. The first
    /// episode's first state is the start of every imagined episode.
    pub fn fit(&mut self, states: &[Vector<6>], commands: &[Vector<3>]) {
        self.start = self.start.or(states.first().copied());
        for (m, model) in self.models.iter_mut().enumerate() {
            if m > 0 && self.episodes % self.ensemble == m - 1 {
                continue;
            }
            for (k, u) in commands.iter().enumerate() {
                // A transition the model refuses changes nothing (RlsModel::update).
                let _ = model.update(&self.map, &states[k], u, &states[k + 1]);
            }
        }
        self.episodes += 1;
    }

    /// The worst of the models' predicted survey costs of θ (the task's own controller and
    /// `SurveyCost`, 240 ticks from the start).
    pub fn predict(&self, theta: &Vector<{ auv_task::P }>) -> Result<f32, Error> {
        self.prediction(theta).map(|p| p.cost)
    }

    /// [`AuvModels::predict`] with the full model's uncertainty along its imagined episode
    /// (`Imagined::deviation`).
    pub fn prediction(&self, theta: &Vector<{ auv_task::P }>) -> Result<Prediction, Error> {
        let start = self.start.ok_or(Error::InvalidParameter("start"))?;
        let mut worst = f32::MIN;
        let mut uncertainty = 0.0;
        for (m, model) in self.models.iter().enumerate() {
            let mut controller = auv_task::controller();
            let mut shaper = SurveyCost::try_new(RADIUS)?;
            let imagined = imagine_episode_with_variance(
                model,
                &self.map,
                &start,
                AUV_TICKS,
                AUV_DT,
                &mut controller,
                theta,
                &mut shaper,
                |x| Vector::<3>::new(x[0], x[1], x[2]),
            )?;
            worst = worst.max(imagined.cost);
            if m == 0 {
                uncertainty = imagined.deviation();
            }
        }
        Ok(Prediction {
            cost: worst,
            uncertainty,
        })
    }
}

/// The AUV's fallback: coordinate search from θ = 0 with the task's local settings
/// (`auv_task::local_config`), the steps `steps`, at most `budget` evaluations.
pub fn auv_fallback(
    steps: Vector<{ auv_task::P }>,
    budget: u32,
) -> CoordinateSearch<{ auv_task::P }> {
    let config = CoordinateConfig {
        max_evaluations: budget,
        ..auv_task::local_config(budget)
    };
    CoordinateSearch::try_with_steps(auv_task::bounds(), Vector::zeros(), steps, config)
        .expect("valid coordinate steps")
}

// ---------------------------------------------------------------------------------------
// The hopper.

/// Ticks of a hopper episode (12 s at 1 kHz).
pub const HOPPER_TICKS: u32 = 12_000;

/// The hopper's model state: [knee, hip, knee rate, hip rate, body height, body velocity].
pub fn hopper_state(hopper: &Hopper) -> Vector<6> {
    let s = hopper.state();
    let x = hopper_task::policy_state(hopper);
    Vector::<6>::new(
        x[0],
        x[1],
        x[2],
        x[3],
        s.body_height as f32,
        s.body_velocity as f32,
    )
}

/// θ of the hopper's u: u ⊙ the box's upper corner.
pub fn hopper_theta(u: &Vector<HP>) -> Vector<HP> {
    u.component_mul(hopper_task::bounds().upper())
}

/// The hopper's model: `RlsModel<6, 2, 9>` (affine) of [`hopper_state`] and the two torques,
/// fitted on every 1 kHz tick.
#[derive(Debug, Clone)]
pub struct HopperModel {
    model: RlsModel<6, 2, 9>,
    start: Option<Vector<6>>,
}

impl Default for HopperModel {
    fn default() -> Self {
        Self {
            model: RlsModel::try_new(ModelConfig::DEFAULT).expect("the default model config"),
            start: None,
        }
    }
}

impl HopperModel {
    /// Fits one episode's ticks (see [`AuvModels::fit`]).
    pub fn fit(&mut self, states: &[Vector<6>], commands: &[Vector<2>]) {
        self.start = self.start.or(states.first().copied());
        for (k, u) in commands.iter().enumerate() {
            let _ = self.model.update(&Affine, &states[k], u, &states[k + 1]);
        }
    }

    /// The predicted cost of θ: the task's `PeriodicPd` on the first four model states,
    /// `ApexHeightCost` fed the predicted body height and velocity (power from the command
    /// and the joint rates; no limit flag), 12,000 ticks.
    pub fn predict(&self, theta: &Vector<HP>) -> Result<f32, Error> {
        let start = self.start.ok_or(Error::InvalidParameter("start"))?;
        let mut controller = hopper_task::controller();
        let mut shaper = ApexHeightCost::try_new(hopper_task::apex_config())?;
        controller.reset();
        shaper.reset();
        let dt = 1e-3;
        rollout(&self.model, &Affine, &start, HOPPER_TICKS, |k, x| {
            let q = Vector::<4>::new(x[0], x[1], x[2], x[3]);
            let tau = controller.corrected(theta, &q, k as f32 * dt);
            shaper.observe(
                &HopSample {
                    height: x[4],
                    vertical_velocity: x[5],
                    power: (tau[0] * x[2]).abs() + (tau[1] * x[3]).abs(),
                    limit_violation: false,
                },
                dt,
            );
            tau
        })?;
        let c = shaper.cost();
        if c.is_finite() {
            Ok(c)
        } else {
            Err(Error::NonFinite("cost"))
        }
    }
}

/// The hopper's fallback: coordinate search on u ∈ [−1, 1]^31 from 0, step a sixth of the
/// box (`hopper_task`'s), tolerance 10⁻³, at most `budget` evaluations.
pub fn hopper_fallback(budget: u32) -> CoordinateSearch<HP> {
    let config = CoordinateConfig {
        initial_step: 1.0 / 6.0,
        tolerance: 1e-3,
        max_evaluations: budget,
        ..CoordinateConfig::DEFAULT
    };
    CoordinateSearch::try_new(unit_box(), Vector::zeros(), config).expect("valid steps")
}

fn unit_box<const P: usize>() -> Bounds<P> {
    Bounds::uniform(-1.0, 1.0).expect("valid box")
}

// ---------------------------------------------------------------------------------------
// The arm.

/// θ = θ₀ + `ARM_UNIT`·u on the arm.
pub const ARM_UNIT: f32 = 100.0;

/// The arm's u box around θ₀ inside the arm's box.
pub fn arm_bounds(theta0: &Vector<PARAMS>) -> Bounds<PARAMS> {
    let limit = arm::WEIGHT_LIMIT;
    Bounds::try_new(
        Vector::from_fn(|i, _| (-limit - theta0[i]) / ARM_UNIT),
        Vector::from_fn(|i, _| (limit - theta0[i]) / ARM_UNIT),
    )
    .expect("θ₀ inside the arm's box")
}

fn to_f32<const N: usize>(v: &[f64; N]) -> Vector<N> {
    Vector::from_fn(|i, _| v[i] as f32)
}

/// The arm's model: `RlsModel<20, 10, 31>` (affine) of the joint angles and the DMP's
/// scaled velocities [y, z] with the 10 forcing terms as the command, fitted on every 1 ms
/// tick. The DMPs are linear in [y, z, forcing, 1]: one episode identifies them.
#[derive(Debug, Clone)]
pub struct ArmModel {
    arm: ViaPointArm,
    theta0: Vector<PARAMS>,
    model: RlsModel<20, 10, 31>,
}

impl Default for ArmModel {
    fn default() -> Self {
        let arm = ViaPointArm::new();
        Self {
            theta0: arm.minimum_jerk_theta(),
            arm,
            model: RlsModel::try_new(ModelConfig::DEFAULT).expect("the default model config"),
        }
    }
}

impl ArmModel {
    /// The minimum-jerk θ₀, u = 0.
    pub fn theta0(&self) -> &Vector<PARAMS> {
        &self.theta0
    }

    /// θ of u: θ₀ + [`ARM_UNIT`]·u.
    pub fn theta(&self, u: &Vector<PARAMS>) -> Vector<PARAMS> {
        self.theta0 + u * ARM_UNIT
    }

    /// Fits one episode's ticks: states (T + 1) and forcings (T).
    pub fn fit(&mut self, states: &[[f64; 2 * LINKS]], forcings: &[[f64; LINKS]]) {
        for (k, f) in forcings.iter().enumerate() {
            let _ = self.model.update(
                &Affine,
                &to_f32(&states[k]),
                &to_f32(f),
                &to_f32(&states[k + 1]),
            );
        }
    }

    /// The arm's cost of θ on the model: the forcing of θ drives the model from the start;
    /// the via-point distance at 0.3 s and the weighted accelerations as `host_tests::arm`.
    pub fn predict(&self, theta: &Vector<PARAMS>) -> Result<f32, Error> {
        let forcings = self.arm.forcings(theta);
        let weight_sum: f64 = (1..=LINKS).map(|d| (LINKS + 1 - d) as f64).sum();
        let mut start = [0.0; 2 * LINKS];
        start[..LINKS].copy_from_slice(self.arm.start());
        let mut acceleration = 0.0f64;
        let mut via = f64::NAN;
        let mut previous = to_f32(&start);
        // The weighted squared accelerations of the step from `previous` to x: ÿ = ż/τ with
        // ż from the model's increment of z.
        let weighted = |x: &Vector<20>, previous: &Vector<20>| {
            let mut w = 0.0;
            for d in 0..LINKS {
                let zd = f64::from(x[LINKS + d] - previous[LINKS + d]) / arm::DT;
                let ydd = zd / arm::DURATION;
                w += (LINKS - d) as f64 * ydd * ydd;
            }
            w / weight_sum * arm::DT
        };
        let end = rollout(
            &self.model,
            &Affine,
            &to_f32(&start),
            forcings.len() as u32,
            |k, x| {
                if k > 0 {
                    acceleration += weighted(x, &previous);
                    if k as usize == arm::VIA_STEP {
                        let y: [f64; LINKS] = std::array::from_fn(|d| f64::from(x[d]));
                        let [px, py] = arm::end_effector(&y);
                        via = (px - arm::VIA_POINT[0]).powi(2) + (py - arm::VIA_POINT[1]).powi(2);
                    }
                }
                previous = *x;
                to_f32(&forcings[k as usize])
            },
        )?;
        // The last step's acceleration (the closure sees the states before each step).
        let acceleration = acceleration + weighted(&end, &previous);
        let c = (arm::VIA_WEIGHT * via + acceleration) as f32;
        if c.is_finite() {
            Ok(c)
        } else {
            Err(Error::NonFinite("cost"))
        }
    }
}

/// The arm's fallback: coordinate search on u from 0 (θ₀), step 0.25 units, tolerance
/// 10⁻³, at most `budget` evaluations.
pub fn arm_fallback(theta0: &Vector<PARAMS>, budget: u32) -> CoordinateSearch<PARAMS> {
    let config = CoordinateConfig {
        initial_step: 0.25,
        tolerance: 1e-3,
        max_evaluations: budget,
        ..CoordinateConfig::DEFAULT
    };
    CoordinateSearch::try_new(arm_bounds(theta0), Vector::zeros(), config).expect("valid steps")
}

// ---------------------------------------------------------------------------------------
// The learner on an oracle trial.

/// One episode's ticks as a trial hands them out: each state with the command sent from it
/// (none after the last step).
type Ticks<S, C> = Vec<(S, Option<C>)>;

/// The states (T + 1) and the commands (T) of an episode's ticks.
fn split<S: Copy, C: Copy>(ticks: &[(S, Option<C>)]) -> (Vec<S>, Vec<C>) {
    (
        ticks.iter().map(|t| t.0).collect(),
        ticks.iter().filter_map(|t| t.1).collect(),
    )
}

/// An episode's ticks, of whichever task.
#[derive(Default)]
struct Recorded {
    auv: Ticks<Vector<6>, Vector<3>>,
    hopper: Ticks<Vector<6>, Vector<2>>,
    arm: Ticks<[f64; 2 * LINKS], [f64; LINKS]>,
}

/// A trial's episodes with the task's model fitted on their ticks.
struct TrialPlant<'a, M, const P: usize> {
    trial: &'a mut Trial,
    model: M,
    theta: fn(&M, &Vector<P>) -> Vector<P>,
    fit: fn(&mut M, &Recorded),
    predict: fn(&M, &Vector<P>) -> Result<f32, Error>,
}

impl<M, const P: usize> Plant<P> for TrialPlant<'_, M, P> {
    fn episode(&mut self, u: &Vector<P>) -> Real {
        let theta = (self.theta)(&self.model, u);
        let mut ticks = Recorded::default();
        let scored = self
            .trial
            .episode_observed(theta.as_slice(), &mut |tick| match tick {
                Tick::Auv(a, c) => ticks.auv.push((auv_task::policy_state(a), c.copied())),
                Tick::Hopper(h, c) => ticks.hopper.push((hopper_state(h), c.copied())),
                Tick::Arm(x, f) => ticks.arm.push((*x, f.copied())),
            });
        (self.fit)(&mut self.model, &ticks);
        scored.map_or(
            Real {
                cost: f32::INFINITY,
                flagged: true,
            },
            |s| Real {
                cost: s.cost,
                flagged: s.unsafe_episode,
            },
        )
    }

    fn predict(&self, u: &Vector<P>) -> Result<f32, Error> {
        (self.predict)(&self.model, u)
    }
}

/// The model-based learner on `trial` (the oracle's `model` method) for `budget` episodes,
/// RNG seeded by `seed`, with the settings chosen in the examples ([`Settings::chosen`];
/// inner `Cmaes` with λ = 12 / 14 / 14 and 240 / 60 / 240 predictions on the AUV / the
/// hopper / the arm; fallback [`auv_fallback`] with step 0.25, [`hopper_fallback`],
/// [`arm_fallback`]; the model [`AuvModels`] without an ensemble, [`HopperModel`],
/// [`ArmModel`]), and the θ it returns, the best real one. `None` on a synthetic task (no
/// plant to model) or if the learner cannot be built (a non-finite bare cost).
pub fn run_on_trial(trial: &mut Trial, budget: u32, seed: u64) -> Option<(Run, Vec<f32>)> {
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let episodes = budget as usize;
    match trial.task() {
        Task::Auv | Task::AuvCalm | Task::AuvRotated => {
            let mut plant = TrialPlant {
                trial,
                model: AuvModels::new(0),
                theta: |_, u| *u,
                fit: |m, t| {
                    let (states, commands) = split(&t.auv);
                    m.fit(&states, &commands);
                },
                predict: AuvModels::predict,
            };
            let fallback = auv_fallback(Vector::repeat(0.25), budget);
            let inner = inner_cmaes::<{ auv_task::P }, 12>(240);
            let settings = Settings::chosen(240);
            let bounds = auv_task::bounds();
            let run = learn(
                &mut plant, bounds, fallback, inner, &settings, episodes, &mut rng,
            );
            let run = run.ok()?;
            let returned = run.best.clone().unwrap_or_else(|| vec![0.0; auv_task::P]);
            Some((run, returned))
        }
        Task::Hopper => {
            let mut plant = TrialPlant {
                trial,
                model: HopperModel::default(),
                theta: |_, u| hopper_theta(u),
                fit: |m, t| {
                    let (states, commands) = split(&t.hopper);
                    m.fit(&states, &commands);
                },
                predict: |m, u| m.predict(&hopper_theta(u)),
            };
            let fallback = hopper_fallback(budget);
            let inner = inner_cmaes::<HP, 14>(60);
            let settings = Settings::chosen(60);
            let run = learn(
                &mut plant,
                unit_box(),
                fallback,
                inner,
                &settings,
                episodes,
                &mut rng,
            );
            let run = run.ok()?;
            let best = best_u::<HP>(&run);
            Some((run, to_vec(&hopper_theta(&best))))
        }
        Task::Arm => {
            let model = ArmModel::default();
            let (bounds, fallback) = (
                arm_bounds(model.theta0()),
                arm_fallback(model.theta0(), budget),
            );
            let mut plant = TrialPlant {
                trial,
                model,
                theta: ArmModel::theta,
                fit: |m, t| {
                    let (states, forcings) = split(&t.arm);
                    m.fit(&states, &forcings);
                },
                predict: |m, u| m.predict(&m.theta(u)),
            };
            let inner = inner_cmaes::<PARAMS, 14>(240);
            let settings = Settings::chosen(240);
            let run = learn(
                &mut plant, bounds, fallback, inner, &settings, episodes, &mut rng,
            );
            let run = run.ok()?;
            let best = best_u::<PARAMS>(&run);
            Some((run, to_vec(&plant.model.theta(&best))))
        }
        Task::Sphere | Task::Ackley => None,
    }
}

/// The run's best u (0 before any).
fn best_u<const P: usize>(run: &Run) -> Vector<P> {
    run.best
        .as_ref()
        .filter(|b| b.len() == P)
        .map_or_else(Vector::zeros, |b| Vector::from_fn(|i, _| b[i]))
}

/// The oracle's report of the learner on `trial` ([`run_on_trial`]).
pub fn report_on_trial(trial: &mut Trial, budget: u32, seed: u64) -> Option<RunReport> {
    let (run, returned) = run_on_trial(trial, budget, seed)?;
    Some(RunReport {
        optimizer_ns: run.learner_time.as_nanos() as f64 / run.costs.len().max(1) as f64,
        unsafe_episodes: run.flagged.iter().filter(|f| **f).count(),
        fallback_episodes: Some(run.count(Origin::Fallback)),
        costs: run.costs,
        returned,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::peers::{Conditions, run_library};

    /// A plant with the cost |θ − 0.3|² per coordinate and a model that is either exact or
    /// always fails.
    struct Quadratic {
        exact: bool,
        episodes: usize,
    }

    impl Plant<2> for Quadratic {
        fn episode(&mut self, u: &Vector<2>) -> Real {
            self.episodes += 1;
            Real {
                cost: self.predict_exactly(u),
                flagged: false,
            }
        }

        fn predict(&self, u: &Vector<2>) -> Result<f32, Error> {
            if self.exact {
                Ok(self.predict_exactly(u))
            } else {
                Err(Error::NonFinite("cost"))
            }
        }
    }

    impl Quadratic {
        fn predict_exactly(&self, u: &Vector<2>) -> f32 {
            (u - Vector::repeat(0.3)).norm_squared() + 1.0
        }
    }

    fn learn_on(exact: bool, budget: usize) -> (Run, usize) {
        let mut plant = Quadratic { exact, episodes: 0 };
        let fallback = CoordinateSearch::try_new(
            unit_box(),
            Vector::zeros(),
            CoordinateConfig {
                initial_step: 0.1,
                max_evaluations: budget as u32,
                ..CoordinateConfig::DEFAULT
            },
        )
        .unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(7);
        let settings = Settings::chosen(50);
        let inner = inner_cmaes::<2, 6>(50);
        let run = learn(
            &mut plant,
            unit_box(),
            fallback,
            inner,
            &settings,
            budget,
            &mut rng,
        );
        (run.unwrap(), plant.episodes)
    }

    /// The loop's order and bookkeeping (seed 7): the bare episode, 3 explorations inside
    /// ±0.05, then proposals up to the budget, one entry per real episode in every column.
    /// With an exact model of a quadratic every proposal passes the screen and the best
    /// cost falls below the bare one; with a model that always fails every proposal is
    /// the fallback's.
    #[test]
    fn the_loop_runs_bare_explorations_then_proposals() {
        for exact in [true, false] {
            let (run, episodes) = learn_on(exact, 12);
            assert_eq!(episodes, 12);
            assert_eq!(run.costs.len(), 12);
            assert_eq!(run.origin.len(), 12);
            assert_eq!(run.predicted.len(), 12);
            assert_eq!(run.errors.len(), 12);
            assert_eq!(run.origin[0], Origin::Bare);
            assert_eq!(run.costs[0], 1.0 + 2.0 * 0.09);
            assert!(run.origin[1..4].iter().all(|o| *o == Origin::Explore));
            assert_eq!(run.count(Origin::Explore), 3);
            let proposals = run.count(Origin::Model) + run.count(Origin::Fallback);
            assert_eq!(proposals, 8);
            if exact {
                // The model's candidates run until it can no longer predict an improvement
                // on the best real θ (then the fallback proposes).
                assert_eq!(run.origin[4], Origin::Model);
                let best = run.costs.iter().copied().fold(f32::INFINITY, f32::min);
                assert!(best < 1.01, "{best} {:?} {:?}", run.costs, run.origin);
            } else {
                assert_eq!(run.count(Origin::Fallback), 8);
                assert!(run.predicted.iter().all(Option::is_none));
            }
        }
    }

    /// A plant whose model is wrong about the optimum's side: real cost |u − 0.3|² + 1 per
    /// coordinate, predicted |u + 0.5|², so that every model step from u = 0 goes the wrong
    /// way; it records every u it runs.
    struct Misled {
        runs: Vec<Vector<2>>,
    }

    impl Plant<2> for Misled {
        fn episode(&mut self, u: &Vector<2>) -> Real {
            self.runs.push(*u);
            Real {
                cost: (u - Vector::repeat(0.3)).norm_squared() + 1.0,
                flagged: false,
            }
        }

        fn predict(&self, u: &Vector<2>) -> Result<f32, Error> {
            Ok((u + Vector::repeat(0.5)).norm_squared())
        }
    }

    /// The restart of a collapsed trust region (seed 7, 30 episodes, no explorations): the
    /// misled model's steps never improve on u = 0, so the radius shrinks to its minimum
    /// 0.05 and, without a restart, every later step stays within it; with the learner's
    /// restart after 3 stalled steps (`ModelBasedConfig::restart_after`) the radius is back
    /// at 0.15 and later steps go beyond 0.1 again.
    #[test]
    fn a_collapsed_trust_region_restarts() {
        let widest_late_step = |restart_after: u32| {
            let mut plant = Misled { runs: Vec::new() };
            let fallback = CoordinateSearch::try_new(
                unit_box(),
                Vector::zeros(),
                CoordinateConfig {
                    initial_step: 0.1,
                    max_evaluations: 30,
                    ..CoordinateConfig::DEFAULT
                },
            )
            .unwrap();
            let chosen = Settings::chosen(50);
            let settings = Settings {
                config: ModelBasedConfig {
                    restart_after,
                    ..chosen.config
                },
                explorations: 0,
                ..chosen
            };
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(7);
            let run = learn(
                &mut plant,
                unit_box(),
                fallback,
                inner_cmaes::<2, 6>(50),
                &settings,
                30,
                &mut rng,
            )
            .unwrap();
            assert_eq!(run.costs.len(), 30);
            // The best stays the bare u = 0: no step improves on it.
            assert_eq!(run.best, Some(vec![0.0, 0.0]));
            assert!(run.origin[1..].iter().all(|o| *o == Origin::Model));
            plant.runs[10..]
                .iter()
                .map(|u| u.amax())
                .fold(0.0f32, f32::max)
        };
        assert!(widest_late_step(0) <= 0.05);
        assert!(widest_late_step(3) > 0.1);
    }

    /// The oracle's `model` method on the AUV (seed 1, 6 episodes): its first episode is
    /// the bare controller's, of the trial's own start cost, every episode is counted by
    /// the trial, the fallback episodes are reported, and the returned θ is the best
    /// episode's. The synthetic tasks have no model.
    #[test]
    fn the_oracle_runs_the_learner_on_a_trial() {
        let mut trial = Trial::new(Task::Auv, 1);
        let bare = trial.start_cost().unwrap();
        let report = run_library("model", &mut trial, 6, 1).unwrap();
        assert_eq!(report.costs.len(), 6);
        assert_eq!(trial.evaluations(), 6);
        assert_eq!(report.costs[0], bare);
        assert!(report.fallback_episodes.is_some_and(|f| f <= 2));
        // The returned θ, re-run on a fresh copy of the trial's episodes, is a real θ.
        assert_eq!(report.returned.len(), auv_task::P);
        assert!(report.returned.iter().all(|v| v.abs() <= 1.0));
        assert!(run_library("model", &mut Trial::new(Task::Sphere, 1), 6, 1).is_none());
    }

    /// `auv-rotated` is the AUV with the current turned by 45°: its bare cost is that of
    /// the `auv` task in conditions turned by 45°, and not the nominal one.
    #[test]
    fn the_rotated_task_turns_the_current_by_45_degrees() {
        let rotated = Trial::new(Task::AuvRotated, 2).start_cost();
        let turned = Conditions::parse("rotated:45").unwrap();
        assert_eq!(
            rotated,
            Trial::with_conditions(Task::Auv, 2, turned).start_cost()
        );
        assert_ne!(rotated, Trial::new(Task::Auv, 2).start_cost());
        assert_eq!(Task::parse("auv-rotated"), Some(Task::AuvRotated));
    }
}
