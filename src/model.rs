//! A model of the plant learned from the robot's own ticks, and imagined episodes on it.
//!
//! Model-based policy search (PILCO, Deisenroth & Rasmussen, ICML 2011; Black-DROPS,
//! Chatzilygeroudis et al., IROS 2017; model-based PID tuning, Doerr et al., ICRA 2017) learns
//! a model of the plant from every tick the robot runs and searches the policy on the model
//! between episodes, so that few real episodes are needed and every candidate can be screened
//! before the robot runs it. This module holds the pieces a microcontroller can afford:
//!
//! * [`RlsModel`]: the next state as the current state plus an increment linear in features
//!   of the state and the command, x' = x + Wᵀ·z(x, u), fitted every tick by regularised
//!   recursive least squares with a forgetting factor ([`rls`]);
//! * [`imagine_episode`] and [`rollout`]: the controller, its correction θ and the cost
//!   shaper run against the model instead of the plant ([`imagine`]); [`imagine_handover`]:
//!   the rest of a running episode if the guard handed it back to the nominal controller
//!   some ticks from now (a predictive trip); [`imagine_episode_with_variance`]: an
//!   imagined episode with the model's predictive variance summed along it;
//! * [`OnlineModel`]: the model fed by the adapter from every tick of every episode, a type
//!   parameter of the runner like the guard ([`Unmodelled`] by default, [`online`]);
//! * [`ModelBased`]: any optimizer searching the model in a trust region around the best
//!   real θ, its candidate screened by predicted cost, with a model-free fallback
//!   ([`learner`]).
//!
//! # The model class and its limits
//! PILCO and Black-DROPS use Gaussian processes: their cost grows with the data (PILCO's
//! inference is cubic in the number of points), which no allocation-free firmware can hold.
//! A model linear in fixed features keeps a constant footprint (R·S weights and an R×R
//! covariance for R features) and a constant O(R²) cost per tick, and it still captures a
//! lot with the right features: the regressors are the state, the command and a constant
//! ([`Affine`]) plus any the user knows matter ([`AffineWith`]: |v|·v for quadratic drag,
//! an indicator of a depth band for a current layer, sin θ for gravity on a joint). What it
//! cannot capture is what no fixed feature set of the state and command expresses:
//!
//! * hybrid dynamics with contacts and impacts (the hopping leg: flight and stance phases
//!   switch on a state-dependent event and the impact is a jump); a linear-in-features model
//!   averages the phases and its rollouts are wrong after the first touchdown;
//! * hidden state (a thruster's lag, a filter inside the low-level loop): the one-step
//!   prediction error stays above the noise floor, and grows over a rollout;
//! * the uncertainty of its own predictions: unlike a Gaussian process, the model gives a
//!   point prediction. Its running one-step error ([`RlsModel::one_step_error`]), its
//!   open-loop episode error ([`RlsModel::episode_error`]) and the leverage of a state and
//!   command ([`RlsModel::predictive_variance`]: how far they lie from the recorded ticks)
//!   say how far to trust it; a learner should keep its search near θ the robot has run
//!   (a trust region).

pub mod imagine;
pub mod learner;
pub mod online;
pub mod rls;

pub use imagine::{
    Imagined, imagine_episode, imagine_episode_with_variance, imagine_handover, rollout,
};
pub use learner::{ModelBased, ModelBasedConfig, Prediction, Proposal, Source};
pub use online::{OnlineModel, TickModel, Unmodelled};
pub use rls::{ModelConfig, RlsModel};

use crate::vector::{Vector, unrolled};

/// The regressors z(x, u) ∈ R^R the model's increment is linear in.
///
/// Implement it for a feature set of your own, or use [`Affine`] (z = [x, u, 1]) and
/// [`AffineWith`] (z = [x, u, 1, g(x, u)] with g a closure). The model holds only the
/// weights: the same map must be given to every call on one model.
pub trait Regressors<const S: usize, const A: usize, const R: usize> {
    /// z(state, command).
    fn regressors(&self, state: &Vector<S>, command: &Vector<A>) -> Vector<R>;
}

/// z = [x, u, 1]: a linear (affine) plant, R = S + A + 1 (checked at compile time).
///
/// ```
/// use ctrl_adapt::model::{Affine, Regressors};
/// use ctrl_adapt::Vector;
/// let z: Vector<4> = Affine.regressors(&Vector::<2>::new(1.0, 2.0), &Vector::<1>::new(3.0));
/// assert_eq!(z, Vector::<4>::new(1.0, 2.0, 3.0, 1.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Affine;

impl<const S: usize, const A: usize, const R: usize> Regressors<S, A, R> for Affine {
    fn regressors(&self, state: &Vector<S>, command: &Vector<A>) -> Vector<R> {
        const { assert!(R == S + A + 1, "Affine: R must be S + A + 1") };
        affine(state, command)
    }
}

/// z = [x, u, 1, g(x, u)]: the affine regressors plus E features of the user's own, computed
/// by `g`; R = S + A + 1 + E (checked at compile time).
///
/// ```
/// use ctrl_adapt::model::{AffineWith, Regressors};
/// use ctrl_adapt::Vector;
/// // A velocity with quadratic drag: the extra feature is |v|·v.
/// let drag = AffineWith::new(|x: &Vector<1>, _u: &Vector<1>| Vector::<1>::new(x[0].abs() * x[0]));
/// let z: Vector<4> = drag.regressors(&Vector::<1>::new(-2.0), &Vector::<1>::new(0.5));
/// assert_eq!(z, Vector::<4>::new(-2.0, 0.5, 1.0, -4.0));
/// ```
#[derive(Debug, Clone, Copy)]
pub struct AffineWith<const E: usize, G> {
    extra: G,
}

impl<const E: usize, G> AffineWith<E, G> {
    /// The affine regressors extended by `extra(state, command)`.
    pub fn new<const S: usize, const A: usize>(extra: G) -> Self
    where
        G: Fn(&Vector<S>, &Vector<A>) -> Vector<E>,
    {
        Self { extra }
    }
}

impl<const S: usize, const A: usize, const R: usize, const E: usize, G> Regressors<S, A, R>
    for AffineWith<E, G>
where
    G: Fn(&Vector<S>, &Vector<A>) -> Vector<E>,
{
    fn regressors(&self, state: &Vector<S>, command: &Vector<A>) -> Vector<R> {
        const { assert!(R == S + A + 1 + E, "AffineWith: R must be S + A + 1 + E") };
        let mut z: Vector<R> = affine(state, command);
        let extra = (self.extra)(state, command);
        unrolled::<E>(|i| z[S + A + 1 + i] = extra[i]);
        z
    }
}

/// [x, u, 1, 0, …] in R^R (R ≥ S + A + 1).
#[inline]
fn affine<const S: usize, const A: usize, const R: usize>(
    state: &Vector<S>,
    command: &Vector<A>,
) -> Vector<R> {
    // Straight-line copies (see `unrolled`): the model builds z on every imagined tick.
    let mut z = Vector::<R>::zeros();
    unrolled::<S>(|i| z[i] = state[i]);
    unrolled::<A>(|i| z[S + i] = command[i]);
    z[S + A] = 1.0;
    z
}
