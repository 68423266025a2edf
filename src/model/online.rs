//! The plant model fed from the adapter's ticks: every tick of every episode (the bare ones
//! included), the runner hands the state it measured and the command it sent to a
//! [`TickModel`]; the next tick's state completes the transition (x, u, x′) that
//! [`OnlineModel`] fits into its [`RlsModel`].
//!
//! The model lives on the adapter's side, beside the guard, not inside an optimizer: the
//! adapter is the only piece that sees the ticks. Like the guard it is a type parameter of
//! [`EpisodeRunner`](crate::controller::EpisodeRunner) and
//! [`Adapter`](crate::controller::Adapter), [`Unmodelled`] by default: no bytes and no
//! instructions when unused. `with_model` attaches one between episodes.
//!
//! What is fitted: within one episode, tick k's (state, command actually sent — after the
//! guard, the clamp and the non-finite fallbacks) and tick k + 1's state. The last tick of
//! an episode has no successor and is not fitted, nor is a transition into or out of a
//! non-finite state (a sensor glitch leaves a gap of one transition). Ticks outside an
//! episode are not fitted. A transition the model refuses (one so large that the fit would
//! overflow f32) is counted ([`OnlineModel::refused`]) and changes nothing.
//!
//! ```
//! use ctrl_adapt::controller::{
//!     Adapter, AdapterConfig, Controller, CorrectedPd, LinearPolicy, Mode, Pd, StateFeatures,
//! };
//! use ctrl_adapt::cost::{QuadraticCost, Shaper};
//! use ctrl_adapt::model::{Affine, ModelConfig, OnlineModel, RlsModel, imagine_episode};
//! use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Vector};
//! # use rand_core::SeedableRng;
//! # let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
//!
//! // A position error e and its velocity v, the command an acceleration (dt = 0.1):
//! // e' = e − 0.1 v, v' = v + 0.1 u.
//! let plant = |x: &Vector<2>, u: &Vector<1>| Vector::<2>::new(x[0] - 0.1 * x[1], x[1] + 0.1 * u[0]);
//! let pd = Pd::<1>::try_new(Vector::repeat(1.0), Vector::repeat(1.5))?;
//! let policy = LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(1.0))?;
//! let controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
//! let bounds = Bounds::uniform(-1.0, 1.0)?;
//! let search = CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT)?;
//! let config = AdapterConfig { dt: 0.1, failure_cost: 100.0, max_faulty_ticks: 0, learning_episodes: 20 };
//! let shaper = QuadraticCost::try_new(Vector::<1>::repeat(1.0))?;
//! // The model: x' = x + Wᵀ [x, u, 1] (R = 2 + 1 + 1), fed by the adapter every tick.
//! let model = OnlineModel::new(RlsModel::<2, 1, 4>::try_new(ModelConfig::DEFAULT)?, Affine);
//! let mut adapter = Adapter::try_new(search, controller, shaper, config, Vector::zeros())?
//!     .with_model(model)?;
//! for _ in 0..4 {
//!     adapter.begin_episode(&mut rng)?;
//!     let mut x = Vector::<2>::new(1.0, 0.0);
//!     for _ in 0..50 {
//!         let u = adapter.control(&x, &Vector::repeat(x[0]));
//!         x = plant(&x, &u);
//!     }
//!     adapter.end_episode()?;
//! }
//! // 4 episodes of 50 ticks: 49 transitions each.
//! let fed = adapter.model();
//! assert_eq!(fed.model().ticks(), 4 * 49);
//! assert_eq!(fed.start(), Some(Vector::<2>::new(1.0, 0.0)));
//! let (x, u) = (Vector::<2>::new(0.3, -0.2), Vector::<1>::new(0.5));
//! assert!((fed.model().predict(&Affine, &x, &u) - plant(&x, &u)).amax() < 1e-3);
//! // Between episodes, any θ can be scored on the model with the adapter's own controller
//! // and shaper (copies: the adapter's are not touched).
//! let (mut controller, mut shaper) = (*adapter.controller(), *adapter.shaper());
//! let theta = Vector::<2>::new(0.5, 0.2);
//! let predicted = imagine_episode(fed.model(), fed.map(), &fed.start().unwrap(), 50, 0.1,
//!     &mut controller, &theta, &mut shaper, |x| Vector::<1>::new(x[0]))?;
//! assert!(predicted.is_finite());
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```

use super::{Regressors, RlsModel};
use crate::error::{Error, require_finite};
use crate::vector::Vector;

/// What the [`EpisodeRunner`](crate::controller::EpisodeRunner) hands every tick of an
/// episode to: a plant model learning from the robot's own ticks (see the
/// [module docs](self)). Implement it to feed a model of your own; every method has a
/// default that does nothing.
pub trait TickModel<const S: usize, const A: usize> {
    /// An episode begins: its first state starts a new trajectory (it is not the successor
    /// of the previous episode's last tick).
    fn begin(&mut self) {}
    /// A tick of the episode: `state` was measured and `command` was sent to the plant.
    fn tick(&mut self, state: &Vector<S>, command: &Vector<A>) {
        let _ = (state, command);
    }
    /// Extra checks of a decoded model (the runner's record calls it).
    fn validate_decoded(&self) -> Result<(), Error> {
        Ok(())
    }
}

/// No model: the runner's default, zero bytes and no instructions per tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Unmodelled;

impl<const S: usize, const A: usize> TickModel<S, A> for Unmodelled {}

/// An [`RlsModel`] with its regressor map, fitted on every transition of every episode
/// the runner holding it runs (see the [module docs](self)).
///
/// The map is stored with the model (the runner has no other place to pass it from). To
/// save the runner or adapter holding it as a record (feature `serde`), the map must be
/// persistent too: [`Affine`](super::Affine) is; for features of your own, write them as a
/// named type implementing [`Regressors`] rather than a closure (as for a nominal law).
///
/// State: the model, the map, the previous tick's state and command and the episode's
/// first state: (R·S + R² + 3·S + A + 10)·4 bytes plus the map's, e.g. 1,268 bytes for the
/// AUV's `RlsModel<6, 3, 14>` with a zero-sized map.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct OnlineModel<M, const S: usize, const A: usize, const R: usize> {
    model: RlsModel<S, A, R>,
    map: M,
    /// The previous tick of the running episode: its state and command.
    previous: Option<(Vector<S>, Vector<A>)>,
    /// The first finite state of the running (or last) episode.
    start: Option<Vector<S>>,
    /// Transitions the model refused.
    refused: u32,
}

impl<M: Regressors<S, A, R>, const S: usize, const A: usize, const R: usize>
    OnlineModel<M, S, A, R>
{
    /// `model` fitted with the regressors of `map` from now on.
    pub const fn new(model: RlsModel<S, A, R>, map: M) -> Self {
        Self {
            model,
            map,
            previous: None,
            start: None,
            refused: 0,
        }
    }

    /// The model.
    pub fn model(&self) -> &RlsModel<S, A, R> {
        &self.model
    }

    /// The model, mutable (to reset it, or to fit ticks recorded elsewhere).
    pub fn model_mut(&mut self) -> &mut RlsModel<S, A, R> {
        &mut self.model
    }

    /// The regressor map.
    pub fn map(&self) -> &M {
        &self.map
    }

    /// The first finite state of the running episode, or of the last one between episodes:
    /// the start of its imagined episodes.
    pub fn start(&self) -> Option<Vector<S>> {
        self.start
    }

    /// Transitions the model refused (a fit that would overflow f32).
    pub fn refused(&self) -> u32 {
        self.refused
    }
}

impl<M: Regressors<S, A, R>, const S: usize, const A: usize, const R: usize> TickModel<S, A>
    for OnlineModel<M, S, A, R>
{
    fn begin(&mut self) {
        self.previous = None;
        self.start = None;
    }

    fn tick(&mut self, state: &Vector<S>, command: &Vector<A>) {
        let state_finite = state.iter().all(|v| v.is_finite());
        if let Some((x, u)) = self.previous.take()
            && state_finite
            && self.model.update(&self.map, &x, &u, state).is_err()
        {
            self.refused = self.refused.saturating_add(1);
        }
        if state_finite && command.iter().all(|v| v.is_finite()) {
            self.previous = Some((*state, *command));
            if self.start.is_none() {
                self.start = Some(*state);
            }
        }
    }

    fn validate_decoded(&self) -> Result<(), Error> {
        self.model.validate()?;
        if let Some((x, u)) = &self.previous {
            require_finite(x.iter().chain(u.iter()), "previous")?;
        }
        require_finite(self.start.iter().flat_map(|s| s.iter()), "start")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Affine, ModelConfig};

    fn fed() -> OnlineModel<Affine, 1, 1, 3> {
        OnlineModel::new(RlsModel::try_new(ModelConfig::DEFAULT).unwrap(), Affine)
    }

    /// Checks: transitions are fitted within an episode only, a non-finite state breaks the
    /// chain for one transition on each side, and an overflowing one is counted, not fitted.
    #[test]
    fn fits_transitions_within_episodes_and_skips_gaps() {
        let mut m = fed();
        let u = Vector::<1>::new(0.5);
        m.begin();
        for k in 0..5 {
            m.tick(&Vector::<1>::new(k as f32), &u);
        }
        assert_eq!(m.model().ticks(), 4);
        assert_eq!(m.start(), Some(Vector::<1>::new(0.0)));
        m.begin();
        m.tick(&Vector::<1>::new(10.0), &u);
        assert_eq!(m.model().ticks(), 4, "no transition across episodes");
        m.tick(&Vector::<1>::new(f32::NAN), &u);
        m.tick(&Vector::<1>::new(11.0), &u);
        assert_eq!(m.model().ticks(), 4, "no transition into or out of a NaN");
        m.tick(&Vector::<1>::new(12.0), &u);
        assert_eq!(m.model().ticks(), 5);
        assert_eq!(m.start(), Some(Vector::<1>::new(10.0)));
        // From f32::MAX to −f32::MAX: the increment overflows.
        m.begin();
        m.tick(&Vector::<1>::new(f32::MAX), &u);
        m.tick(&Vector::<1>::new(-f32::MAX), &u);
        assert_eq!((m.refused(), m.model().ticks()), (1, 5));
        m.validate_decoded().unwrap();
    }
}
