//! The controller layer: the firmware's PD loop, the linear correction policy that makes it
//! adaptive, and the episodic [`Adapter`] that tunes the correction with an optimizer inside
//! a safety envelope.
//!
//! ```text
//!  state ──► nominal PD ──┐
//!  state ──► φ(state, t) ─┴─► u = u_pd + clamp(W·φ)   (W = θ from the optimizer)
//!  end of episode: cost = shaper.cost()  ──► optimizer.tell(cost), optimizer.ask() ──► next θ
//! ```
//!
//! The optimizer never sees the plant and the plant never sees the optimizer: the adapter is
//! the only piece that knows both.

pub mod adapter;
pub mod builder;
pub mod change;
pub mod guard;
pub mod nominal;
pub mod pd;
pub mod policy;

pub use adapter::{Adapter, AdapterConfig, AdapterError, EpisodeReport, EpisodeRunner, Mode};
pub use builder::{AdapterBuilder, CorrectedAdapter};
pub use change::{ChangeConfig, ChangeDetector, Verdict};
pub use guard::{Guard, GuardConfig, Limit, Source, Trip, TripReason, Unguarded};
pub use nominal::{Corrected, Nominal};
pub use pd::{Derivative, Pd};
pub use policy::{
    CorrectedPd, FeatureMap, IdentityFeatures, LinearPolicy, PeriodicPd, PeriodicRbf, StateFeatures,
};

use crate::vector::Vector;

/// `value` limited to the interval from `lower` to `upper`: `f32::clamp` without its
/// `lower <= upper` assertion, the same for every input (NaN stays NaN) when
/// `lower <= upper`.
///
/// The assertion is a panic path the compiler cannot remove (it cannot know that the limits
/// were validated) and its message links float formatting (~10 KB of flash); `max`/`min`
/// instead would call `fmaxf`/`fminf` on a Cortex-M4F (about 35 instructions each, no
/// single-instruction min/max before Armv8), where these two compares are 4–6 instructions.
#[inline]
pub(crate) fn clamp(value: f32, lower: f32, upper: f32) -> f32 {
    if value < lower {
        lower
    } else if value > upper {
        upper
    } else {
        value
    }
}

/// A controller with a nominal behaviour and a correction parameterised by θ ∈ R^P, over a
/// state in R^S (time since the episode began given separately) and an action in R^A.
///
/// Both control methods take `&mut self`: a controller may keep state between ticks (a PD
/// that differentiates its own error keeps the previous one, a filter keeps its memory).
/// The [`Adapter`] and the [`EpisodeRunner`] call, on every tick, **either** [`nominal`]
/// **or** [`corrected`], once. There is one exception, a tick whose corrected action is not
/// finite: the runner then also calls [`nominal`] with the same state, for the fallback
/// action (a stateful controller sees that tick twice; it is a faulty tick already). At the
/// start of every episode the runner calls [`reset`].
///
/// To make your own nominal law adaptive without implementing this trait, wrap it in
/// [`Corrected`] (any `FnMut(&state, time) -> action` is a [`Nominal`]), or let
/// [`AdapterBuilder`] build the whole adapter.
///
/// [`nominal`]: Controller::nominal
/// [`corrected`]: Controller::corrected
/// [`reset`]: Controller::reset
pub trait Controller<const P: usize, const S: usize, const A: usize> {
    /// The firmware's own controller, unchanged (θ plays no part).
    fn nominal(&mut self, state: &Vector<S>, time: f32) -> Vector<A>;

    /// The controller with the correction of θ applied, inside the correction envelope.
    fn corrected(&mut self, theta: &Vector<P>, state: &Vector<S>, time: f32) -> Vector<A>;

    /// Called when an episode begins (the robot is back at its start): forget what the
    /// previous episode left, e.g. a PD's previous error. Nothing by default.
    fn reset(&mut self) {}

    /// What to command when even the nominal action is not finite (a NaN state): zeros by
    /// default (stop the thrusters, relax the joints). Override if zero is not safe.
    fn safe_action(&self) -> Vector<A> {
        Vector::zeros()
    }
}
