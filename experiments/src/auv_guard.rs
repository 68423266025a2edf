//! The runtime guard of the AUV survey as `tests/guard_auv.rs` chose it (the tapered
//! envelope, the 8 m limit and the predictive trip, findings/guard.md), shared by that study
//! and by the model-based learner run under it ([`GuardedAuv`], the example
//! `model_guard_auv`, findings/model.md "The learner under the runtime guard").
//!
//! A guarded episode runs the candidate in an [`EpisodeRunner`] with a [`Guard`] of two
//! limits: the distance to the target within [`FAR`] (signal 0) and the [`forecast`] of the
//! episode's end (signal 1) at most `ratio` × the model's forecast of the bare episode. On a
//! trip the bare PD runs the rest of the episode and the learner is told what the adapter
//! tells ([`tripped_cost`]).

use std::cell::Cell;

use ctrl_adapt::controller::guard::{Guard, GuardConfig, Limit, Source, Supervisor, tripped_cost};
use ctrl_adapt::controller::{EpisodeRunner, Mode};
use ctrl_adapt::cost::SurveyCost;
use ctrl_adapt::model::{
    AffineWith, ModelConfig, OnlineModel, RlsModel, TickModel, imagine_handover,
};
use ctrl_adapt::optimizer::{Error, Vector};
use host_tests::auv::Auv;
use host_tests::auv_task::{self, AuvController, P, RADIUS};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

use ctrl_adapt::model::Prediction;

use crate::model_learner::{AUV_DT, AUV_R, AuvMap, AuvModels, Plant, Real, bounded_drag};

/// Ticks of an episode (24 s at 10 Hz), the envelope's length.
pub const TICKS: usize = 240;
/// The distance limit (m): the vehicle starts 7.2 m from the target.
pub const FAR: f32 = 8.0;

/// The guard's constants (the fields of `GuardConfig` the study varies, and the forecast).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardSetting {
    /// `GuardConfig::relative_margin`.
    pub relative_margin: f32,
    /// `GuardConfig::absolute_margin`.
    pub absolute_margin: f32,
    /// `GuardConfig::envelope_ticks`.
    pub envelope_ticks: u32,
    /// `GuardConfig::margin_taper` (1: constant margins).
    pub margin_taper: f32,
    /// The predictive trip: a second limit on the forecast of the episode's cost, as a
    /// multiple of the model's forecast of the bare episode, and the ticks the candidate
    /// keeps running in a forecast before the hand-over (see [`forecast`]); `None`: no
    /// forecast.
    pub forecast: Option<(f32, usize)>,
}

/// The tapered envelope chosen by `guard_auv`'s `tune_taper` on seeds 101–110.
pub const CHOSEN: GuardSetting = GuardSetting {
    relative_margin: 1.0,
    absolute_margin: 1.0,
    envelope_ticks: 2,
    margin_taper: 0.1,
    forecast: None,
};

/// The predictive trip on top of [`CHOSEN`], chosen by `guard_auv`'s `tune_forecast` on
/// seeds 101–110 (κ = 1.05, L = 6).
pub const PREDICTIVE: GuardSetting = GuardSetting {
    forecast: Some((1.05, 6)),
    ..CHOSEN
};

/// The distance limit: signal 0 within [0, [`FAR`]].
pub const FAR_LIMIT: Limit = Limit {
    source: Source::Signal(0),
    low: 0.0,
    high: FAR,
};

/// The guard's configuration of `setting` with `limits`: trips after 2 ticks beyond a limit;
/// a tripped learning episode is told the failure cost plus up to 5.
pub fn guard_config<const L: usize>(setting: &GuardSetting, limits: [Limit; L]) -> GuardConfig<L> {
    GuardConfig {
        limits,
        limit_ticks: 2,
        envelope_ticks: setting.envelope_ticks,
        relative_margin: setting.relative_margin,
        absolute_margin: setting.absolute_margin,
        margin_taper: setting.margin_taper,
        tripped_cost_span: 5.0,
    }
}

/// The guard of `setting` with the predictive trip of ratio `ratio`: limits [`FAR_LIMIT`]
/// and the forecast (signal 1) at most `ratio`.
pub fn predictive_guard(setting: &GuardSetting, ratio: f32) -> Result<Guard<2, TICKS>, Error> {
    let forecast = Limit {
        source: Source::Signal(1),
        low: f32::NEG_INFINITY,
        high: ratio,
    };
    Guard::try_new(guard_config(setting, [FAR_LIMIT, forecast]))
}

/// The plant model the forecast runs on: the bounded-drag regressors of `findings/model.md`,
/// fitted on every tick.
pub type ForecastModel = OnlineModel<AuvMap, 6, 3, AUV_R>;

/// A fresh [`ForecastModel`] (`ModelConfig::DEFAULT`).
pub fn forecast_model() -> ForecastModel {
    OnlineModel::new(
        RlsModel::try_new(ModelConfig::DEFAULT).expect("the default model config"),
        AffineWith::new(bounded_drag as fn(&Vector<6>, &Vector<3>) -> Vector<4>),
    )
}

/// The predictive trip's signal at `tick` (before this tick's control), as a multiple of the
/// bare cost: the survey cost the episode would end with if the candidate `theta` ran
/// `lookahead` more ticks and the bare PD the rest, forecast on `model` (fitted to every
/// tick so far) from `state` with copies of the episode's `controller` and `shaper` (as
/// they are before this tick). A safety filter with the nominal controller as its backup
/// (Brunke et al. 2022, "predictive safety filters"): trip as soon as the backup, started
/// `lookahead` ticks from now, is forecast to end above the limit (`ratio` × the bare
/// cost) — unless the candidate itself, run to the end, is forecast to end lower than that
/// backup (then a hand-over could only make the episode worse, e.g. where the bare PD's
/// own spread reaches the limit): the signal then reads 0. A forecast that leaves the
/// finite numbers reads +∞. `reference` holds the model's forecast of the bare episode,
/// set at tick 0.
#[allow(clippy::too_many_arguments)]
pub fn forecast(
    model: &ForecastModel,
    controller: &AuvController,
    shaper: &SurveyCost,
    theta: &Vector<P>,
    state: &Vector<6>,
    tick: usize,
    (ratio, lookahead): (f32, usize),
    reference: &Cell<f32>,
) -> f32 {
    // The episode's end if the candidate runs `candidate_ticks` more ticks, then the PD.
    let end = |candidate_ticks: usize| {
        imagine_handover(
            model.model(),
            model.map(),
            state,
            tick as u32,
            TICKS as u32,
            AUV_DT,
            *controller,
            theta,
            candidate_ticks as u32,
            *shaper,
            |x| Vector::<3>::new(x[0], x[1], x[2]),
        )
        .unwrap_or(f32::INFINITY)
    };
    if tick == 0 {
        reference.set(end(0));
    }
    let backup = end(lookahead) / reference.get();
    if backup > ratio && end(TICKS) / reference.get() < backup {
        0.0
    } else {
        backup
    }
}

/// How [`GuardedAuv`] runs the learner's episodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardedSettings {
    /// The guard of the proposals (the model's and the fallback's candidates); `None`:
    /// unguarded, the oracle's episodes.
    pub guard: Option<GuardSetting>,
    /// Whether the exploration episodes are guarded too.
    pub guard_explorations: bool,
    /// Exploration episodes whose u is 0 are *dithered bare episodes*: the bare PD with a
    /// command noise uniform in ±`dither` m/s per axis and tick (0: none).
    pub dither: f32,
    /// Real episodes that are explorations (after the first, bare, one).
    pub explorations: usize,
}

/// What one real episode of a [`GuardedAuv`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardedEpisode {
    /// The survey cost it ran to (the bare PD's after a trip).
    pub executed: f32,
    /// The tick of the guard's trip, if it tripped.
    pub trip: Option<u32>,
    /// Unsafe: executed above the bare episode's cost plus 20 % of its magnitude (the
    /// oracle's rule, `peers::Trial::safe_threshold`).
    pub unsafe_episode: bool,
    /// For an unsafe episode, whether the bare PD alone (handed back at tick 0, the same
    /// disturbances) is unsafe too: the bare controller's own spread.
    pub bare_unsafe: Option<bool>,
}

/// The AUV under the runtime guard, as the model-based learner's [`Plant`]: its first
/// episode is the bare controller's (it teaches the guard's envelope and sets the unsafe
/// threshold), the next `explorations` ones the learner's explorations (dithered bare
/// episodes where u = 0 and `dither` > 0), then the proposals, guarded. Every tick, the
/// guard's hand-over included, feeds the learner's model ([`AuvModels`]) and the forecast's.
pub struct GuardedAuv {
    auv: Auv,
    settings: GuardedSettings,
    guarded: EpisodeRunner<AuvController, SurveyCost, P, 6, 3, Guard<2, TICKS>>,
    plain: EpisodeRunner<AuvController, SurveyCost, P, 6, 3>,
    forecast_model: ForecastModel,
    models: AuvModels,
    dither_rng: Xoshiro128PlusPlus,
    threshold: f32,
    /// Every real episode so far.
    pub episodes: Vec<GuardedEpisode>,
}

impl GuardedAuv {
    /// The learner's plant on `auv` (as it is before the first episode), the dither's RNG
    /// seeded by `seed`.
    pub fn new(auv: Auv, settings: GuardedSettings, seed: u64) -> Result<Self, Error> {
        let setting = settings.guard.unwrap_or(PREDICTIVE);
        let ratio = setting.forecast.map_or(f32::INFINITY, |f| f.0);
        let shaper = || SurveyCost::try_new(RADIUS);
        let config = auv_task::adapter_config(1);
        let runner_error = |_| Error::InvalidParameter("guard");
        Ok(Self {
            auv,
            settings,
            guarded: EpisodeRunner::try_new(auv_task::controller(), shaper()?, config)?
                .with_guard(predictive_guard(&setting, ratio)?)
                .map_err(runner_error)?,
            plain: EpisodeRunner::try_new(auv_task::controller(), shaper()?, config)?,
            forecast_model: forecast_model(),
            models: AuvModels::new(0),
            dither_rng: Xoshiro128PlusPlus::seed_from_u64(seed ^ 0xd17e),
            threshold: f32::INFINITY,
            episodes: Vec::new(),
        })
    }

    /// The plant.
    pub fn auv(&self) -> &Auv {
        &self.auv
    }
}

/// One episode of `runner` on `auv` (reset first): `signal(runner, state, tick)` the guard's
/// signals, `dither` the command noise's half-width; every tick's state and sent command go
/// to `forecast_model` and into `states`/`commands`.
#[allow(clippy::too_many_arguments)]
fn drive<G: Supervisor<6>>(
    runner: &mut EpisodeRunner<AuvController, SurveyCost, P, 6, 3, G>,
    auv: &mut Auv,
    theta: Vector<P>,
    mode: Mode,
    forecast_model: &mut ForecastModel,
    dither: (f32, &mut Xoshiro128PlusPlus),
    signal: impl Fn(
        &EpisodeRunner<AuvController, SurveyCost, P, 6, 3, G>,
        &ForecastModel,
        &Vector<6>,
        usize,
    ) -> f32,
    states: &mut Vec<Vector<6>>,
    commands: &mut Vec<Vector<3>>,
) -> Result<(f32, Option<u32>), Error> {
    let (dither, rng) = dither;
    auv.reset();
    forecast_model.begin();
    runner
        .begin_episode(theta, mode)
        .map_err(|_| Error::InvalidParameter("episode"))?;
    for tick in 0..auv.steps_per_episode() {
        let state = auv_task::policy_state(auv);
        let error = auv_task::true_error(auv);
        let predicted = signal(runner, forecast_model, &state, tick);
        let u = runner.control_with_signal(&state, &error, &[error.norm(), predicted]);
        let u = if dither > 0.0 {
            u + Vector::<3>::from_fn(|_, _| {
                let unit = (rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
                dither * (2.0 * unit - 1.0)
            })
        } else {
            u
        };
        forecast_model.tick(&state, &u);
        states.push(state);
        commands.push(u);
        auv.step([f64::from(u[0]), f64::from(u[1]), f64::from(u[2])]);
    }
    states.push(auv_task::policy_state(auv));
    let report = runner
        .end_episode()
        .map_err(|_| Error::InvalidParameter("episode"))?;
    Ok((report.cost, report.trip.map(|t| t.tick)))
}

impl Plant<P> for GuardedAuv {
    fn episode(&mut self, u: &Vector<P>) -> Real {
        let k = self.episodes.len();
        let before = self.auv.clone();
        let exploration = (1..=self.settings.explorations).contains(&k);
        let dithered = exploration && self.settings.dither > 0.0 && u.iter().all(|v| *v == 0.0);
        let guarded = self.settings.guard.is_some()
            && k > 0
            && !dithered
            && (!exploration || self.settings.guard_explorations);
        let (mut states, mut commands) = (Vec::with_capacity(TICKS + 1), Vec::with_capacity(TICKS));
        let ratio_lookahead = self
            .settings
            .guard
            .and_then(|g| g.forecast)
            .unwrap_or((f32::INFINITY, 0));
        let reference = Cell::new(f32::NAN);
        let dither = if dithered { self.settings.dither } else { 0.0 };
        let ran = if k == 0 || dithered {
            // The bare PD: teaches the guard's envelope.
            drive(
                &mut self.guarded,
                &mut self.auv,
                Vector::zeros(),
                Mode::Nominal,
                &mut self.forecast_model,
                (dither, &mut self.dither_rng),
                |_, _, _, _| 0.0,
                &mut states,
                &mut commands,
            )
        } else if guarded {
            let theta = *u;
            drive(
                &mut self.guarded,
                &mut self.auv,
                theta,
                Mode::Learn,
                &mut self.forecast_model,
                (0.0, &mut self.dither_rng),
                |runner, model, state, tick| {
                    if ratio_lookahead.0.is_finite() {
                        forecast(
                            model,
                            runner.controller(),
                            runner.shaper(),
                            &theta,
                            state,
                            tick,
                            ratio_lookahead,
                            &reference,
                        )
                    } else {
                        0.0
                    }
                },
                &mut states,
                &mut commands,
            )
        } else {
            drive(
                &mut self.plain,
                &mut self.auv,
                *u,
                Mode::Deploy,
                &mut self.forecast_model,
                (0.0, &mut self.dither_rng),
                |_, _, _, _| 0.0,
                &mut states,
                &mut commands,
            )
        };
        self.models.fit(&states, &commands);
        let Ok((executed, trip)) = ran else {
            self.episodes.push(GuardedEpisode {
                executed: f32::INFINITY,
                trip: None,
                unsafe_episode: true,
                bare_unsafe: None,
            });
            return Real {
                cost: f32::INFINITY,
                flagged: true,
            };
        };
        if k == 0 {
            self.threshold = executed + 0.2 * executed.abs();
        }
        let unsafe_episode = executed.is_nan() || executed > self.threshold;
        let bare_unsafe = unsafe_episode.then(|| {
            let mut replay = before;
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(0);
            auv_task::evaluate(Vector::zeros(), &mut replay, &mut rng, false).map_or(true, |e| {
                e.report.cost.is_nan() || e.report.cost > self.threshold
            })
        });
        self.episodes.push(GuardedEpisode {
            executed,
            trip,
            unsafe_episode,
            bare_unsafe,
        });
        let told = match trip {
            Some(tick) => tripped_cost(
                self.guarded.config().failure_cost,
                self.guarded.guard().config().tripped_cost_span,
                tick,
                TICKS as u32,
            ),
            None => executed,
        };
        Real {
            cost: told,
            flagged: unsafe_episode,
        }
    }

    fn predict(&self, u: &Vector<P>) -> Result<f32, Error> {
        self.models.predict(u)
    }

    fn prediction(&self, u: &Vector<P>) -> Result<Prediction, Error> {
        self.models.prediction(u)
    }
}
