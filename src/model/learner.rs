//! A model-based learner: between real episodes, any of the library's optimizers searches
//! the model's predicted cost inside a trust region around the best real θ, and its best is
//! screened before the robot runs it (Black-DROPS, Chatzilygeroudis et al., IROS 2017, runs
//! CMA-ES on the learned model; the trust region and the screen are this library's
//! guards against a model that is exploited where it is wrong).
//!
//! One real episode at a time:
//!
//! 1. [`ModelBased::propose`] builds a fresh inner optimizer on the trust box (the
//!    half-width `radius` box around the best real θ, inside the outer bounds) and runs it
//!    for `inner_evaluations` predictions (`predict(θ)`, typically an
//!    [`imagine_episode`](super::imagine_episode) on the freshly refitted model);
//! 2. the inner best is proposed ([`Source::Model`]) if its predicted cost plus
//!    `error_weight` × the measured prediction error is at most the threshold (the
//!    reference cost, e.g. the bare controller's measured cost, plus `margin`) and its
//!    predicted cost is below the prediction for the best real θ; otherwise the fallback
//!    optimizer's own model-free candidate is ([`Source::Fallback`]). With
//!    [`ModelBased::propose_bounded`] and `uncertainty_weight` k_u > 0, "predicted cost"
//!    in steps 1 and 2 reads cost + k_u × the candidate's own uncertainty;
//! 3. [`ModelBased::tell`] reports the real cost: the best real θ is updated, the fallback
//!    is told only its own candidates, the error of the proposal's prediction is added to
//!    the measured prediction error ([`ModelBased::prediction_error`]), and the trust
//!    region grows after an improvement and shrinks otherwise. With `restart_after`
//!    R > 0, R consecutive told proposals made at the minimum radius without improving the
//!    best real θ restart the trust region: the radius is `initial_radius` again and the
//!    prediction error is measured afresh from `initial_error`; the best real θ, the
//!    reference and the fallback stay (after TuRBO's restart of a collapsed trust region,
//!    Eriksson et al., NeurIPS 2019, which starts anew from a fresh design instead).
//!
//! Episodes the caller runs itself (the bare controller, small exploration episodes that
//! make the model identifiable) are reported with [`ModelBased::record`].
//!
//! On the AUV it learns in a few real episodes, but some episodes exceed 1.2 × the bare cost
//! (the figures: `experiments/findings/model.md`): the screen trusts the same model the
//! inner search exploited. It is not a safety guarantee.
//!
//! The pessimistic screen (`error_weight` > 0) departs from PILCO's and Black-DROPS's
//! uncertainty-aware screens on purpose: an RLS model gives a point prediction, so the
//! margin is one measured number for every candidate (the RMS of real − predicted over
//! the episodes run so far), not a per-candidate variance. On the AUV it did not lower the
//! unsafe count (a constant margin does not tell a wrong candidate from a right one) and
//! sent episodes to the fallback; the default keeps it off (k = 0).
//!
//! The candidate-dependent bound ([`ModelBased::propose_bounded`],
//! `uncertainty_weight` k_u) adds the candidate's own uncertainty instead, e.g. the model's
//! predictive variance summed along its imagined episode
//! ([`imagine_episode_with_variance`](super::imagine_episode_with_variance)): the inner
//! search minimises, and the screen judges, cost + k_u × uncertainty. PILCO and
//! Black-DROPS minimise the *expected* cost under the model's uncertainty (a Gaussian
//! process's, propagated through the dynamics or sampled); this bound is pessimistic, on a
//! variance summed along the mean trajectory without propagation. On the AUV it lowered the
//! unsafe episodes only a little and did not remove them (the findings); it is off by
//! default (k_u = 0).
//!
//! # Footprint
//! For the AUV (N = 18, coordinate-search fallback) the learner is about 1 KB and its model
//! (`RlsModel<6, 3, 14>`) about 1.2 KB, kept between episodes (the bytes measured on the
//! Cortex-M4F are in `docs/firmware.md`). The inner
//! optimizer lives only inside `propose`, on the stack: 4,520 bytes for `Cmaes<18, 12>`.
//! A proposal costs `inner_evaluations` imagined episodes (240 × 240 ticks on the AUV), and
//! one more when the fallback proposes (its candidate is predicted too): its instructions on
//! a Cortex-M4F, counted whole on QEMU by the `bench_model` firmware, are in
//! `docs/model-based.md`.

use rand_core::RngCore;

use crate::bounds::Bounds;
use crate::error::{Error, require};
use crate::optimizer::{Best, Optimizer};
use crate::vector::Vector;

/// The constants of a [`ModelBased`] learner.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ModelBasedConfig {
    /// Initial half-width of the trust region, in θ units (> 0).
    pub initial_radius: f32,
    /// Smallest half-width (> 0, ≤ `initial_radius`).
    pub min_radius: f32,
    /// Largest half-width (≥ `initial_radius`).
    pub max_radius: f32,
    /// Factor on the half-width after a real episode that improves the best (≥ 1).
    pub grow: f32,
    /// Factor on the half-width after one that does not (in (0, 1]).
    pub shrink: f32,
    /// Margin added to the reference cost to make the screening threshold (≥ 0, finite).
    pub margin: f32,
    /// Predictions the inner optimizer may make per proposal (≥ 1).
    pub inner_evaluations: u32,
    /// k of the pessimistic screen (≥ 0, finite): a model candidate must pass the threshold
    /// with its prediction plus k times the model's measured prediction error
    /// ([`ModelBased::prediction_error`]). 0 screens on the point prediction alone.
    pub error_weight: f32,
    /// The prediction error assumed before any is measured (≥ 0, finite); it counts as one
    /// measurement in the running root mean square, so it fades as real episodes come in.
    pub initial_error: f32,
    /// k_u of the candidate-dependent screen (≥ 0, finite): with
    /// [`ModelBased::propose_bounded`], the inner search minimises and the screen judges
    /// J(θ) = predicted cost + k_u × the candidate's own [`Prediction::uncertainty`] (e.g. the
    /// [`Imagined::deviation`](super::Imagined::deviation) of its imagined episode), so that
    /// candidates that drive the model where it has no data are both avoided and screened
    /// out. 0 (the default) ignores the uncertainty: J is the predicted cost.
    pub uncertainty_weight: f32,
    /// R of the trust region's restart (0, the default: never). After R consecutive told
    /// proposals ([`ModelBased::tell`]) that were made while the radius was at
    /// `min_radius` and did not improve the best real θ, the radius goes back to
    /// `initial_radius` and the measured prediction error back to `initial_error`; the best
    /// real θ, the reference, the fallback and the episode count stay (TuRBO's restart of a
    /// collapsed trust region, Eriksson et al., NeurIPS 2019). A trust region that shrank to
    /// its minimum around a best θ picked by a lucky noisy episode otherwise stays there
    /// for the rest of the run. On the AUV under the runtime guard, R = 5 was chosen on
    /// seeds 101–110 (`experiments/findings/model.md`, "The learner under the runtime
    /// guard"). Any value is valid.
    pub restart_after: u32,
}

impl ModelBasedConfig {
    /// The AUV prototype's settings: radius 0.15 in [0.05, 1], ×1.5 / ×0.6, margin 0 (set
    /// it for the task), 240 predictions per proposal.
    pub const DEFAULT: Self = Self {
        initial_radius: 0.15,
        min_radius: 0.05,
        max_radius: 1.0,
        grow: 1.5,
        shrink: 0.6,
        margin: 0.0,
        inner_evaluations: 240,
        error_weight: 0.0,
        initial_error: 0.0,
        uncertainty_weight: 0.0,
        restart_after: 0,
    };

    /// Checks every field (named in the error; `restart_after` takes any value).
    pub fn validate(&self) -> Result<(), Error> {
        require(
            self.min_radius > 0.0 && self.min_radius.is_finite(),
            "min_radius",
        )?;
        require(
            self.initial_radius >= self.min_radius && self.initial_radius.is_finite(),
            "initial_radius",
        )?;
        require(
            self.max_radius >= self.initial_radius && self.max_radius.is_finite(),
            "max_radius",
        )?;
        require(self.grow >= 1.0 && self.grow.is_finite(), "grow")?;
        require(self.shrink > 0.0 && self.shrink <= 1.0, "shrink")?;
        require(self.margin >= 0.0 && self.margin.is_finite(), "margin")?;
        require(self.inner_evaluations >= 1, "inner_evaluations")?;
        require(
            self.error_weight >= 0.0 && self.error_weight.is_finite(),
            "error_weight",
        )?;
        require(
            self.initial_error >= 0.0 && self.initial_error.is_finite(),
            "initial_error",
        )?;
        require(
            self.uncertainty_weight >= 0.0 && self.uncertainty_weight.is_finite(),
            "uncertainty_weight",
        )
    }
}

impl Default for ModelBasedConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The model's prediction of a candidate for [`ModelBased::propose_bounded`]: its cost and
/// how uncertain the model is about it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Prediction {
    /// The predicted cost (finite, or the prediction counts as failed).
    pub cost: f32,
    /// The model's uncertainty about this candidate, in cost units once weighted by
    /// [`ModelBasedConfig::uncertainty_weight`] (≥ 0 and finite, or the prediction counts as
    /// failed when the weight is not 0), e.g. [`Imagined::deviation`](super::Imagined).
    pub uncertainty: f32,
}

impl From<f32> for Prediction {
    /// A point prediction: no uncertainty.
    fn from(cost: f32) -> Self {
        Self {
            cost,
            uncertainty: 0.0,
        }
    }
}

/// Where a proposed θ comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Source {
    /// The inner search on the model; its predicted cost.
    Model(f32),
    /// The fallback optimizer's model-free step (the model's best did not pass the screen,
    /// or every prediction failed).
    Fallback,
}

/// A θ for the next real episode, and where it comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Proposal<const N: usize> {
    /// The parameters to run.
    pub theta: Vector<N>,
    /// Model or fallback.
    pub source: Source,
}

/// The model-based learner of the [module docs](self): `F` is the model-free fallback
/// optimizer, told only the candidates it proposed; the inner optimizer is built afresh for
/// each proposal by a closure, so any of the library's optimizers can serve.
///
/// ```
/// use ctrl_adapt::model::{ModelBased, ModelBasedConfig, Source};
/// use ctrl_adapt::optimizer::{Bounds, Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch};
/// use ctrl_adapt::Vector;
/// use rand_core::SeedableRng;
/// let bounds = Bounds::<2>::uniform(-1.0, 1.0)?;
/// // The real cost, and a model of it that is right up to an offset.
/// let real = |t: &Vector<2>| (t[0] - 0.5).powi(2) + (t[1] + 0.2).powi(2);
/// let predict = |t: &Vector<2>| Ok(real(t) + 0.01);
/// let fallback = CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT)?;
/// let config = ModelBasedConfig { margin: 0.1, initial_radius: 0.3, ..ModelBasedConfig::DEFAULT };
/// let mut learner = ModelBased::try_new(bounds, fallback, config)?;
/// learner.record(Vector::zeros(), real(&Vector::zeros()))?; // the bare controller
/// learner.set_reference(real(&Vector::zeros()))?;
/// let inner = |b: Bounds<2>, start: Vector<2>| {
///     Cmaes::<2, 6>::try_new(b, start, CmaesConfig { max_evaluations: 120, ..CmaesConfig::DEFAULT })
/// };
/// let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
/// let mut from_model = 0;
/// for _ in 0..6 {
///     let proposal = learner.propose(&mut rng, inner, predict)?;
///     // Near the optimum the model cannot promise better than the best real θ: the
///     // fallback takes those episodes.
///     from_model += matches!(proposal.source, Source::Model(_)) as u32;
///     learner.tell(real(&proposal.theta))?;
/// }
/// assert!(from_model >= 3);
/// assert!(learner.best().unwrap().cost < 1e-2);
/// # Ok::<(), ctrl_adapt::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ModelBased<F, const N: usize> {
    config: ModelBasedConfig,
    bounds: Bounds<N>,
    fallback: F,
    best: Option<Best<N>>,
    radius: f32,
    reference: Option<f32>,
    pending: Option<Proposal<N>>,
    evaluations: u32,
    /// The model's prediction of the pending proposal, when it could make one.
    pending_prediction: Option<f32>,
    /// Σ (real − predicted)² over the told proposals with a prediction, and their number.
    squared_errors: f32,
    errors: u32,
    /// Consecutive told proposals made at the minimum radius that did not improve the best
    /// (saturating), and the trust region's restarts so far (saturating).
    stalled: u32,
    restarts: u32,
}

impl<F: Optimizer<N>, const N: usize> ModelBased<F, N> {
    /// A learner over `bounds` with the model-free `fallback`, if `config` validates and
    /// the fallback searches the same box ([`Error::InvalidParameter`]`("fallback")`
    /// otherwise: its candidates become the learner's best θ).
    pub fn try_new(
        bounds: Bounds<N>,
        fallback: F,
        config: ModelBasedConfig,
    ) -> Result<Self, Error> {
        config.validate()?;
        require(fallback.bounds() == &bounds, "fallback")?;
        Ok(Self {
            config,
            bounds,
            fallback,
            best: None,
            radius: config.initial_radius,
            reference: None,
            pending: None,
            evaluations: 0,
            pending_prediction: None,
            squared_errors: 0.0,
            errors: 0,
            stalled: 0,
            restarts: 0,
        })
    }

    /// Sets the reference cost of the screen (the bare controller's measured cost): a model
    /// candidate must be predicted at most `reference + margin`. Without a reference only
    /// the comparison with the best real θ's prediction screens.
    pub fn set_reference(&mut self, cost: f32) -> Result<(), Error> {
        require(cost.is_finite(), "reference").map_err(|_| Error::NonFinite("reference"))?;
        self.reference = Some(cost);
        Ok(())
    }

    /// Reports a real episode the caller chose itself (the bare controller, an exploration
    /// episode): it counts for the best real θ, not for the fallback or the trust region.
    pub fn record(&mut self, theta: Vector<N>, cost: f32) -> Result<(), Error> {
        if self.pending.is_some() {
            return Err(Error::CandidatePending);
        }
        self.bounds.check(&theta, "theta")?;
        require(cost.is_finite(), "cost").map_err(|_| Error::NonFinite("cost"))?;
        self.improve(theta, cost);
        self.evaluations = self.evaluations.saturating_add(1);
        Ok(())
    }

    fn improve(&mut self, theta: Vector<N>, cost: f32) -> bool {
        let better = self.best.is_none_or(|b| cost < b.cost);
        if better {
            self.best = Some(Best { theta, cost });
        }
        better
    }

    /// The θ of the next real episode (see the [module docs](self)). `inner(trust, start)`
    /// builds the inner optimizer on the trust box, started at the best real θ (the outer
    /// bounds' centre before any episode); `predict(θ)` is the model's cost of θ, an error
    /// when the model cannot say (a diverging rollout): such θ are told a cost worse than
    /// any prediction seen. Repeats the pending proposal until it is told.
    ///
    /// Errors: the fallback's ([`Error::Stopped`] when it is spent and the model's
    /// candidate did not pass), or the inner optimizer's construction.
    pub fn propose<R, O>(
        &mut self,
        rng: &mut R,
        inner: impl FnMut(Bounds<N>, Vector<N>) -> Result<O, Error>,
        mut predict: impl FnMut(&Vector<N>) -> Result<f32, Error>,
    ) -> Result<Proposal<N>, Error>
    where
        R: RngCore + ?Sized,
        O: Optimizer<N>,
    {
        self.propose_bounded(rng, inner, |theta| predict(theta).map(Prediction::from))
    }

    /// [`ModelBased::propose`] with a candidate-dependent bound: `predict(θ)` returns the
    /// predicted cost and the model's uncertainty about θ ([`Prediction`]), typically from
    /// [`imagine_episode_with_variance`](super::imagine_episode_with_variance). The inner
    /// search minimises, and the screen judges, J(θ) = cost + k_u·uncertainty with
    /// k_u = [`ModelBasedConfig::uncertainty_weight`]: a model candidate is proposed if
    /// J + `error_weight` × [`ModelBased::prediction_error`] is at most the threshold and J
    /// is below the best real θ's J. With k_u = 0 this is [`ModelBased::propose`].
    ///
    /// The bound is a pessimistic (upper-confidence) objective, as in safe exploration;
    /// PILCO and Black-DROPS instead minimise the expected cost under the model's
    /// uncertainty, which rewards exploring it. Here every candidate runs on the robot, so
    /// the model's ignorance counts against it.
    pub fn propose_bounded<R, O>(
        &mut self,
        rng: &mut R,
        mut inner: impl FnMut(Bounds<N>, Vector<N>) -> Result<O, Error>,
        mut predict: impl FnMut(&Vector<N>) -> Result<Prediction, Error>,
    ) -> Result<Proposal<N>, Error>
    where
        R: RngCore + ?Sized,
        O: Optimizer<N>,
    {
        if let Some(p) = self.pending {
            return Ok(p);
        }
        let centre = match self.best {
            Some(b) => b.theta,
            None => (self.bounds.lower() + self.bounds.upper()) * 0.5,
        };
        let r = self.radius;
        let (lower, upper) = (self.bounds.lower(), self.bounds.upper());
        // A radius below the spacing of f32 around the centre (a tiny `min_radius`) leaves
        // no box to search: the fallback proposes.
        let trust = Bounds::try_new(
            Vector::<N>::from_fn(|i, _| max(centre[i] - r, lower[i])),
            Vector::<N>::from_fn(|i, _| min(centre[i] + r, upper[i])),
        )
        .ok();
        let mut search = match trust {
            Some(trust) => Some(inner(trust, centre)?),
            None => None,
        };
        let mut worst = f32::MIN;
        let weight = self.config.uncertainty_weight;
        // J(θ) = cost + k_u·uncertainty and the point cost, or None when either is unusable.
        let mut objective = |theta: &Vector<N>| -> Option<(f32, f32)> {
            let p = predict(theta).ok()?;
            if !p.cost.is_finite() {
                return None;
            }
            if weight == 0.0 {
                return Some((p.cost, p.cost));
            }
            let j = p.cost + weight * p.uncertainty;
            (p.uncertainty >= 0.0 && j.is_finite()).then_some((j, p.cost))
        };
        // The candidate's θ, J and point cost.
        let mut best_model: Option<(Vector<N>, f32, f32)> = None;
        for _ in 0..self.config.inner_evaluations {
            let Some(search) = search.as_mut() else { break };
            let Ok(theta) = search.ask(rng) else { break };
            let cost = match objective(&theta) {
                Some((c, point)) => {
                    worst = max(worst, c);
                    if best_model.is_none_or(|(_, b, _)| c < b) {
                        best_model = Some((theta, c, point));
                    }
                    c
                }
                // Worse than anything predicted so far, and finite.
                _ => {
                    if worst > f32::MIN {
                        worst + libm::fabsf(worst) + 1.0
                    } else {
                        f32::MAX / 2.0
                    }
                }
            };
            if search.tell(cost).is_err() {
                break;
            }
        }
        let incumbent = self.best.map(|b| objective(&b.theta).map(|(j, _)| j));
        let threshold = self.reference.map(|c| c + self.config.margin);
        let pessimism = if self.config.error_weight > 0.0 {
            min(self.config.error_weight * self.prediction_error(), f32::MAX)
        } else {
            0.0
        };
        let passes = |predicted: f32| {
            threshold.is_none_or(|t| predicted + pessimism <= t)
                && match incumbent {
                    // No real episode yet: nothing to beat.
                    None => true,
                    Some(Some(i)) => predicted < i,
                    // The model cannot predict the best real θ: it cannot rank against it.
                    Some(None) => false,
                }
        };
        let (proposal, prediction) = match best_model {
            Some((theta, j, predicted)) if passes(j) && self.bounds.contains(&theta) => (
                Proposal {
                    theta,
                    source: Source::Model(predicted),
                },
                Some(predicted),
            ),
            _ => {
                let theta = self.fallback.ask(rng)?;
                // Predicted too, so that the model's error is measured on every episode,
                // not only on those it chose.
                let predicted = predict(&theta)
                    .ok()
                    .map(|p| p.cost)
                    .filter(|c| c.is_finite());
                (
                    Proposal {
                        theta,
                        source: Source::Fallback,
                    },
                    predicted,
                )
            }
        };
        self.pending = Some(proposal);
        self.pending_prediction = prediction;
        Ok(proposal)
    }

    /// Reports the real cost of the pending proposal, and restarts the trust region when it
    /// has stalled ([`ModelBasedConfig::restart_after`]). A missing proposal
    /// ([`Error::NoPendingAsk`]) or a non-finite cost ([`Error::NonFinite`]) changes nothing.
    pub fn tell(&mut self, cost: f32) -> Result<(), Error> {
        let proposal = self.pending.ok_or(Error::NoPendingAsk)?;
        require(cost.is_finite(), "cost").map_err(|_| Error::NonFinite("cost"))?;
        if proposal.source == Source::Fallback {
            self.fallback.tell(cost)?;
        }
        self.pending = None;
        if let Some(predicted) = self.pending_prediction.take() {
            let e = cost - predicted;
            // Saturated, so that a huge error keeps the statistic large and finite.
            self.squared_errors = min(self.squared_errors + e * e, f32::MAX);
            self.errors = self.errors.saturating_add(1);
        }
        self.evaluations = self.evaluations.saturating_add(1);
        // The proposal was searched at the minimum radius (the radius it was made with).
        let at_min = self.radius <= self.config.min_radius;
        let improved = self.improve(proposal.theta, cost);
        self.radius = if improved {
            min(self.radius * self.config.grow, self.config.max_radius)
        } else {
            max(self.radius * self.config.shrink, self.config.min_radius)
        };
        self.stalled = if at_min && !improved {
            self.stalled.saturating_add(1)
        } else {
            0
        };
        let restart = self.config.restart_after;
        if restart > 0 && self.stalled >= restart {
            // The model's error measured around the old incumbent at the smallest radius
            // says little about the wider box: it is measured afresh.
            self.radius = self.config.initial_radius;
            self.squared_errors = 0.0;
            self.errors = 0;
            self.stalled = 0;
            self.restarts = self.restarts.saturating_add(1);
        }
        Ok(())
    }

    /// The best real (θ, cost) so far.
    pub fn best(&self) -> Option<Best<N>> {
        self.best
    }

    /// The proposal handed out and not yet told.
    pub fn pending(&self) -> Option<&Proposal<N>> {
        self.pending.as_ref()
    }

    /// The model's measured prediction error of a real episode's cost: the root mean square
    /// of real − predicted over the proposals told so far (since the trust region's last
    /// restart, if any) that the model could predict (the model's own and the fallback's),
    /// with `initial_error` counted as one more. The screen adds `error_weight` times this
    /// to a candidate's prediction.
    pub fn prediction_error(&self) -> f32 {
        let i = self.config.initial_error;
        let sum = min(min(i * i, f32::MAX) + self.squared_errors, f32::MAX);
        libm::sqrtf(sum / (1.0 + self.errors as f32))
    }

    /// The trust region's current half-width.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Real episodes reported (told and recorded).
    pub fn evaluations(&self) -> u32 {
        self.evaluations
    }

    /// Consecutive told proposals, up to the last, that were made at the minimum radius and
    /// did not improve the best real θ (reset by an improvement, a proposal made at a larger
    /// radius, and a restart); with `restart_after` R > 0 it stays below R.
    pub fn stalled(&self) -> u32 {
        self.stalled
    }

    /// The trust region's restarts so far ([`ModelBasedConfig::restart_after`]).
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// The fallback optimizer.
    pub fn fallback(&self) -> &F {
        &self.fallback
    }

    /// The constants.
    pub fn config(&self) -> &ModelBasedConfig {
        &self.config
    }
}

#[cfg(feature = "serde")]
impl<F, const N: usize> ModelBased<F, N>
where
    F: Optimizer<N> + crate::record::Persistent,
{
    /// The checks of a decoded learner ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (the configuration, the box, the fallback's own checks and its box
    /// the learner's) and the state's: the radius within its bounds, a finite reference, a
    /// best real θ inside the box with a finite cost, and a pending proposal inside the box
    /// (a model candidate with a finite prediction; a fallback candidate the one the
    /// fallback will be told), the prediction-error statistic: a finite, non-negative
    /// sum, and a pending prediction only beside a pending proposal, finite; and the
    /// restart's counts as `tell` leaves them: the stall count and the restarts at most the
    /// episodes reported (each takes a told episode), the stall count below `restart_after`
    /// when it is set (it restarts on reaching it), and no restart when it is not.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::require_finite;
        self.config.validate()?;
        self.bounds.check_decoded()?;
        self.fallback.validate()?;
        require(self.fallback.bounds() == &self.bounds, "fallback")?;
        require(
            self.radius >= self.config.min_radius && self.radius <= self.config.max_radius,
            "radius",
        )?;
        require_finite(&self.reference, "reference")?;
        if let Some(b) = &self.best {
            self.bounds.check(&b.theta, "best")?;
            require_finite([&b.cost], "best")?;
        }
        require(
            self.squared_errors.is_finite() && self.squared_errors >= 0.0,
            "squared_errors",
        )?;
        let restart = self.config.restart_after;
        require(
            self.stalled <= self.evaluations && (restart == 0 || self.stalled < restart),
            "stalled",
        )?;
        require(
            self.restarts <= self.evaluations && (restart > 0 || self.restarts == 0),
            "restarts",
        )?;
        require(
            self.pending_prediction
                .is_none_or(|c| c.is_finite() && self.pending.is_some()),
            "pending_prediction",
        )?;
        if let Some(p) = &self.pending {
            self.bounds.check(&p.theta, "pending")?;
            match p.source {
                Source::Model(predicted) => require_finite([&predicted], "pending")?,
                Source::Fallback => {
                    require(self.fallback.pending() == Some(&p.theta), "pending")?;
                }
            }
        }
        Ok(())
    }
}

fn max(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

fn min(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optimizer::{Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch};
    use crate::testing::rng;
    use proptest::prelude::*;
    use rand_xoshiro::Xoshiro128PlusPlus;

    type Learner = ModelBased<CoordinateSearch<2>, 2>;

    fn learner(config: ModelBasedConfig) -> Learner {
        let bounds = Bounds::uniform(-1.0, 1.0).unwrap();
        let fallback =
            CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT).unwrap();
        ModelBased::try_new(bounds, fallback, config).unwrap()
    }

    fn inner(b: Bounds<2>, start: Vector<2>) -> Result<Cmaes<2, 6>, Error> {
        let config = CmaesConfig {
            max_evaluations: 60,
            ..CmaesConfig::DEFAULT
        };
        Cmaes::try_new(b, start, config)
    }

    fn real(t: &Vector<2>) -> f32 {
        (t[0] - 0.5).powi(2) + (t[1] + 0.2).powi(2)
    }

    #[test]
    fn model_candidates_stay_in_the_trust_region() {
        let mut l = learner(ModelBasedConfig {
            initial_radius: 0.1,
            ..ModelBasedConfig::DEFAULT
        });
        l.record(Vector::zeros(), real(&Vector::zeros())).unwrap();
        let p = l.propose(&mut rng(1), inner, |t| Ok(real(t))).unwrap();
        assert!(matches!(p.source, Source::Model(_)));
        assert!(p.theta.amax() <= 0.1 + 1e-6);
        // Repeated until told.
        assert_eq!(l.propose(&mut rng(2), inner, |t| Ok(real(t))).unwrap(), p);
        assert_eq!(l.record(Vector::zeros(), 1.0), Err(Error::CandidatePending));
        l.tell(real(&p.theta)).unwrap();
        assert!((l.radius() - 0.15).abs() < 1e-6);
    }

    #[test]
    fn falls_back_when_the_screen_rejects_or_the_model_fails() {
        let config = ModelBasedConfig {
            margin: 0.0,
            ..ModelBasedConfig::DEFAULT
        };
        // A model that predicts everything worse than the reference.
        let mut l = learner(config);
        l.record(Vector::zeros(), 0.29).unwrap();
        l.set_reference(0.29).unwrap();
        let p = l
            .propose(&mut rng(1), inner, |t| Ok(real(t) + 1.0))
            .unwrap();
        assert_eq!(p.source, Source::Fallback);
        let before = *l.fallback();
        l.tell(0.5).unwrap();
        assert_ne!(
            *l.fallback(),
            before,
            "the fallback is told its own candidate"
        );
        // A model that cannot predict.
        let p = l
            .propose(&mut rng(2), inner, |_| Err(Error::NonFinite("prediction")))
            .unwrap();
        assert_eq!(p.source, Source::Fallback);
    }

    #[test]
    fn a_radius_below_the_f32_spacing_falls_back_instead_of_failing() {
        // A valid but tiny radius: 0.3 ± 1e-12 is 0.3 in f32, so the trust region has no
        // width (found by the forged-record sweep, where a forged `min_radius` got there).
        let mut l = learner(ModelBasedConfig {
            min_radius: 1e-12,
            initial_radius: 1e-12,
            ..ModelBasedConfig::DEFAULT
        });
        l.record(Vector::repeat(0.3), real(&Vector::repeat(0.3)))
            .unwrap();
        let p = l.propose(&mut rng(1), inner, |t| Ok(real(t))).unwrap();
        assert_eq!(p.source, Source::Fallback);
        l.tell(real(&p.theta)).unwrap();
    }

    #[test]
    fn the_pessimistic_screen_adds_the_measured_error() {
        // The model predicts every cost 0.1 too low.
        let config = ModelBasedConfig {
            error_weight: 2.0,
            initial_error: 1.0,
            ..ModelBasedConfig::DEFAULT
        };
        let mut l = learner(config);
        let bare = real(&Vector::zeros());
        l.record(Vector::zeros(), bare).unwrap();
        l.set_reference(bare).unwrap();
        assert!((l.prediction_error() - 1.0).abs() < 1e-6);
        // The model's best passes on its point prediction (below the bare cost 0.29, the
        // threshold with margin 0) but not with 2 × the assumed error 1 added: fallback.
        let predict = |t: &Vector<2>| Ok(real(t) - 0.1);
        let p = l.propose(&mut rng(1), inner, predict).unwrap();
        assert_eq!(p.source, Source::Fallback);
        let predicted = real(&p.theta) - 0.1;
        l.tell(real(&p.theta)).unwrap();
        // The fallback's episode was predicted too: its error (0.1) is measured.
        let e = ((1.0 + 0.1f32 * 0.1) / 2.0).sqrt();
        assert!(
            (l.prediction_error() - e).abs() < 1e-4,
            "{}",
            l.prediction_error()
        );
        assert!((real(&p.theta) - predicted - 0.1).abs() < 1e-6);
        // The same model with k = 0 passes its candidate.
        let mut l = learner(ModelBasedConfig {
            error_weight: 0.0,
            ..config
        });
        l.record(Vector::zeros(), bare).unwrap();
        l.set_reference(bare).unwrap();
        let p = l.propose(&mut rng(1), inner, predict).unwrap();
        assert!(matches!(p.source, Source::Model(_)));
    }

    #[test]
    fn propose_is_propose_bounded_without_uncertainty() {
        for weight in [0.0, 5.0] {
            let config = ModelBasedConfig {
                uncertainty_weight: weight,
                ..ModelBasedConfig::DEFAULT
            };
            let (mut a, mut b) = (learner(config), learner(config));
            for l in [&mut a, &mut b] {
                l.record(Vector::zeros(), 0.29).unwrap();
                l.set_reference(0.29).unwrap();
            }
            let (mut ra, mut rb) = (rng(3), rng(3));
            for _ in 0..4 {
                let p = a.propose(&mut ra, inner, |t| Ok(real(t))).unwrap();
                let q = b
                    .propose_bounded(&mut rb, inner, |t| Ok(Prediction::from(real(t))))
                    .unwrap();
                assert_eq!(p, q);
                a.tell(real(&p.theta)).unwrap();
                b.tell(real(&q.theta)).unwrap();
                assert_eq!(a, b);
            }
        }
    }

    /// A model that is right near θ = 0, where the ticks were recorded, and wrongly
    /// optimistic away from it; its uncertainty grows with the distance.
    fn optimistic(t: &Vector<2>) -> Result<Prediction, Error> {
        Ok(Prediction {
            cost: real(t) - 2.0 * t.norm_squared(),
            uncertainty: 3.0 * t.norm_squared(),
        })
    }

    #[test]
    fn the_uncertainty_weight_keeps_the_search_near_the_data_and_screens() {
        let propose = |weight: f32, reference: f32| {
            let mut l = learner(ModelBasedConfig {
                initial_radius: 1.0,
                uncertainty_weight: weight,
                ..ModelBasedConfig::DEFAULT
            });
            l.record(Vector::zeros(), real(&Vector::zeros())).unwrap();
            l.set_reference(reference).unwrap();
            l.propose_bounded(&mut rng(4), inner, optimistic).unwrap()
        };
        let bare = real(&Vector::zeros());
        // k_u = 0 exploits the optimism to the box's corner, whose real cost is worse
        // than the bare θ's.
        let blind = propose(0.0, bare);
        assert!(matches!(blind.source, Source::Model(_)));
        assert!(blind.theta.amax() > 0.9, "{}", blind.theta);
        assert!(real(&blind.theta) > bare);
        // k_u = 1: J = real + |θ|², minimised at (0.25, −0.1), better than bare for real.
        let bounded = propose(1.0, bare);
        let Source::Model(predicted) = bounded.source else {
            panic!("{bounded:?}")
        };
        assert!((bounded.theta - Vector::<2>::new(0.25, -0.1)).amax() < 0.05);
        assert!(real(&bounded.theta) < bare);
        // The source carries the point prediction, not J.
        assert_eq!(predicted, optimistic(&bounded.theta).unwrap().cost);
        // The screen judges J: with the threshold just below the bound's J, fallback.
        let j = |t: &Vector<2>| {
            let p = optimistic(t).unwrap();
            p.cost + p.uncertainty
        };
        assert_eq!(
            propose(1.0, j(&bounded.theta) - 0.01).source,
            Source::Fallback
        );
        // An unusable uncertainty (negative, NaN) with k_u > 0 is a failed prediction.
        let mut l = learner(ModelBasedConfig {
            uncertainty_weight: 1.0,
            ..ModelBasedConfig::DEFAULT
        });
        l.record(Vector::zeros(), bare).unwrap();
        let p = l
            .propose_bounded(&mut rng(5), inner, |t| {
                Ok(Prediction {
                    cost: real(t),
                    uncertainty: f32::NAN,
                })
            })
            .unwrap();
        assert_eq!(p.source, Source::Fallback);
    }

    /// One proposal told `cost`: the model predicts the real cost 0.1 too low, or (`fails`)
    /// cannot predict at all, so that the fallback proposes.
    fn step(l: &mut Learner, r: &mut Xoshiro128PlusPlus, fails: bool, cost: f32) {
        let p = l
            .propose(r, inner, |t| {
                if fails {
                    Err(Error::NonFinite("prediction"))
                } else {
                    Ok(real(t) - 0.1)
                }
            })
            .unwrap();
        assert_eq!(p.source == Source::Fallback, fails);
        l.tell(cost).unwrap();
    }

    /// With `restart_after` 3: the radius shrinks 0.15 → 0.09 → 0.054 → 0.05 without a
    /// stalled proposal (none was made at the minimum); the third that is made there and
    /// does not improve restarts the trust region. Beside a twin that never restarts, told
    /// the same, the restart changes only the radius (back to 0.15), the measured error
    /// (back to `initial_error`) and the counts: the best, the fallback, the reference and
    /// the episode count are the twin's.
    #[test]
    fn a_stalled_trust_region_restarts_and_keeps_the_rest() {
        let config = ModelBasedConfig {
            initial_error: 0.5,
            restart_after: 3,
            ..ModelBasedConfig::DEFAULT
        };
        let mut l = learner(config);
        let mut twin = learner(ModelBasedConfig {
            restart_after: 0,
            ..config
        });
        let (mut r, mut rt) = (rng(7), rng(7));
        for m in [&mut l, &mut twin] {
            // Nothing told below beats the bare cost 0; the screen's threshold 10 passes
            // every model candidate better than the bare θ.
            m.record(Vector::zeros(), 0.0).unwrap();
            m.set_reference(10.0).unwrap();
        }
        let radii = [0.09, 0.054, 0.05, 0.05, 0.05];
        for (k, radius) in radii.into_iter().enumerate() {
            // Every other proposal the fallback's, so that it is told too.
            step(&mut l, &mut r, k % 2 == 0, 1.0);
            step(&mut twin, &mut rt, k % 2 == 0, 1.0);
            assert!((l.radius() - radius).abs() < 1e-6, "{k}: {}", l.radius());
            assert_eq!(l.stalled(), k.saturating_sub(2) as u32);
            assert_eq!(l, ModelBased { config, ..twin });
        }
        assert!(l.prediction_error() != 0.5);
        step(&mut l, &mut r, false, 1.0);
        step(&mut twin, &mut rt, false, 1.0);
        assert_eq!(
            (twin.radius(), twin.stalled(), twin.restarts()),
            (0.05, 3, 0)
        );
        assert_eq!((l.radius(), l.stalled(), l.restarts()), (0.15, 0, 1));
        assert_eq!(l.prediction_error(), 0.5);
        assert_eq!(l.evaluations(), 7);
        assert_eq!(
            l,
            ModelBased {
                config,
                radius: 0.15,
                squared_errors: 0.0,
                errors: 0,
                stalled: 0,
                restarts: 1,
                ..twin
            }
        );
        assert_ne!(
            *l.fallback(),
            learner(config).fallback,
            "the fallback was told"
        );
        // The restarted region searches the initial radius again.
        let p = l.propose(&mut r, inner, |t| Ok(real(t) - 0.1)).unwrap();
        assert!(
            p.theta.amax() > 0.05 && p.theta.amax() <= 0.15 + 1e-6,
            "{}",
            p.theta
        );
    }

    /// `restart_after` 0: the stall count grows without bound and the radius stays at its
    /// minimum.
    #[test]
    fn restart_after_zero_never_restarts() {
        let mut l = learner(ModelBasedConfig::DEFAULT);
        l.record(Vector::zeros(), 0.0).unwrap();
        let mut r = rng(8);
        for _ in 0..40 {
            step(&mut l, &mut r, false, 1.0);
        }
        assert_eq!((l.radius(), l.stalled(), l.restarts()), (0.05, 37, 0));
    }

    /// An improvement resets the stall count (and grows the radius, so that the next
    /// proposal is not made at the minimum): a restart then takes `restart_after` stalled
    /// proposals from there.
    #[test]
    fn an_improvement_resets_the_stall_count() {
        let mut l = learner(ModelBasedConfig {
            restart_after: 3,
            ..ModelBasedConfig::DEFAULT
        });
        l.record(Vector::zeros(), 0.0).unwrap();
        let mut r = rng(9);
        for _ in 0..5 {
            step(&mut l, &mut r, false, 1.0);
        }
        assert_eq!((l.radius(), l.stalled()), (0.05, 2));
        // An improvement at the minimum radius: 0.05 × 1.5.
        step(&mut l, &mut r, false, -1.0);
        assert_eq!(l.stalled(), 0);
        assert!((l.radius() - 0.075).abs() < 1e-6);
        // Made at 0.075: not stalled; back to the minimum.
        step(&mut l, &mut r, false, 1.0);
        assert_eq!((l.radius(), l.stalled()), (0.05, 0));
        for k in 1..3 {
            step(&mut l, &mut r, false, 1.0);
            assert_eq!((l.radius(), l.stalled(), l.restarts()), (0.05, k, 0));
        }
        step(&mut l, &mut r, false, 1.0);
        assert_eq!((l.radius(), l.stalled(), l.restarts()), (0.15, 0, 1));
        assert_eq!(l.best().unwrap().cost, -1.0);
    }

    #[test]
    fn refuses_bad_tells_and_records_without_change() {
        let mut l = learner(ModelBasedConfig::DEFAULT);
        assert_eq!(l.tell(1.0), Err(Error::NoPendingAsk));
        assert_eq!(
            l.record(Vector::zeros(), f32::NAN),
            Err(Error::NonFinite("cost"))
        );
        assert_eq!(
            l.record(Vector::repeat(2.0), 1.0),
            Err(Error::OutOfBounds("theta"))
        );
        assert_eq!(
            l.set_reference(f32::INFINITY),
            Err(Error::NonFinite("reference"))
        );
        l.propose(&mut rng(1), inner, |t| Ok(real(t))).unwrap();
        let before = l;
        assert_eq!(l.tell(f32::NAN), Err(Error::NonFinite("cost")));
        assert_eq!(l, before);
    }

    #[test]
    fn config_is_checked() {
        for (config, field) in [
            (
                ModelBasedConfig {
                    min_radius: 0.0,
                    ..ModelBasedConfig::DEFAULT
                },
                "min_radius",
            ),
            (
                ModelBasedConfig {
                    initial_radius: 0.01,
                    ..ModelBasedConfig::DEFAULT
                },
                "initial_radius",
            ),
            (
                ModelBasedConfig {
                    max_radius: 0.1,
                    ..ModelBasedConfig::DEFAULT
                },
                "max_radius",
            ),
            (
                ModelBasedConfig {
                    grow: 0.5,
                    ..ModelBasedConfig::DEFAULT
                },
                "grow",
            ),
            (
                ModelBasedConfig {
                    shrink: 0.0,
                    ..ModelBasedConfig::DEFAULT
                },
                "shrink",
            ),
            (
                ModelBasedConfig {
                    margin: f32::NAN,
                    ..ModelBasedConfig::DEFAULT
                },
                "margin",
            ),
            (
                ModelBasedConfig {
                    inner_evaluations: 0,
                    ..ModelBasedConfig::DEFAULT
                },
                "inner_evaluations",
            ),
            (
                ModelBasedConfig {
                    error_weight: -1.0,
                    ..ModelBasedConfig::DEFAULT
                },
                "error_weight",
            ),
            (
                ModelBasedConfig {
                    initial_error: f32::INFINITY,
                    ..ModelBasedConfig::DEFAULT
                },
                "initial_error",
            ),
            (
                ModelBasedConfig {
                    uncertainty_weight: -0.1,
                    ..ModelBasedConfig::DEFAULT
                },
                "uncertainty_weight",
            ),
            (
                ModelBasedConfig {
                    uncertainty_weight: f32::NAN,
                    ..ModelBasedConfig::DEFAULT
                },
                "uncertainty_weight",
            ),
        ] {
            assert_eq!(config.validate(), Err(Error::InvalidParameter(field)));
        }
    }

    proptest! {
        /// Any predictions, real costs, screen weights and restarts: no panic, proposals
        /// inside the bounds, the radius inside its range, the best real cost never worse,
        /// the measured prediction error finite, the stall count below `restart_after`.
        #[test]
        fn never_panics(
            predictions in proptest::collection::vec(any::<f32>(), 1..40),
            costs in proptest::collection::vec(any::<f32>(), 1..20),
            seed in any::<u64>(),
            error_weight in prop_oneof![Just(0.0f32), 0.0f32..1e3, Just(f32::MAX)],
            initial_error in prop_oneof![Just(0.0f32), 0.0f32..1e3, Just(f32::MAX)],
            uncertainty_weight in prop_oneof![Just(0.0f32), 0.0f32..1e3, Just(f32::MAX)],
            uncertainties in proptest::collection::vec(any::<f32>(), 1..40),
            restart_after in prop_oneof![Just(0u32), 1u32..6, Just(u32::MAX)],
        ) {
            let mut l = learner(ModelBasedConfig {
                inner_evaluations: 30,
                error_weight,
                initial_error,
                uncertainty_weight,
                restart_after,
                ..ModelBasedConfig::DEFAULT
            });
            let _ = l.set_reference(costs[0]);
            let mut r = rng(seed);
            let mut best = f32::INFINITY;
            for (k, cost) in costs.iter().enumerate() {
                let mut i = k;
                let p = l.propose_bounded(&mut r, inner, |_| {
                    i += 1;
                    Ok(Prediction {
                        cost: predictions[i % predictions.len()],
                        uncertainty: uncertainties[i % uncertainties.len()],
                    })
                });
                let Ok(p) = p else { break };
                prop_assert!(l.bounds.contains(&p.theta));
                let _ = l.tell(*cost);
                let c = config_range(&l);
                prop_assert!(c);
                if let Some(b) = l.best() {
                    prop_assert!(b.cost <= best);
                    best = b.cost;
                }
                prop_assert!(l.prediction_error().is_finite() && l.prediction_error() >= 0.0);
                prop_assert!(restart_after == 0 || l.stalled() < restart_after);
                prop_assert!(l.restarts() <= l.evaluations());
            }
        }
    }

    fn config_range(l: &Learner) -> bool {
        l.radius() >= l.config().min_radius && l.radius() <= l.config().max_radius
    }
}

#[cfg(test)]
mod footprint {
    use super::*;
    use crate::optimizer::{Cmaes, CoordinateSearch};

    /// The AUV's learner state beside its model: the learner with its coordinate-search
    /// fallback is kept between episodes; the inner CMA-ES lives only during `propose`.
    #[test]
    fn sizes_for_the_auv() {
        extern crate std;
        let learner = core::mem::size_of::<ModelBased<CoordinateSearch<18>, 18>>();
        let inner = core::mem::size_of::<Cmaes<18, 12>>();
        let model = core::mem::size_of::<crate::model::RlsModel<6, 3, 14>>();
        std::println!(
            "ModelBased<CoordinateSearch<18>, 18>: {learner} B; Cmaes<18, 12>: {inner} B; RlsModel<6, 3, 14>: {model} B"
        );
        assert!(model + learner <= 4096);
    }
}
