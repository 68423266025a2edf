//! The optimizer contract: sequential ask/tell minimisation over a box in R^N.
//!
//! On a robot one evaluation of the objective is one *episode* (seconds to minutes of
//! running the plant), so every optimizer here is a resumable state machine rather than a
//! function that takes a closure over the objective:
//!
//! 1. [`Optimizer::ask`] proposes the next parameter vector θ (always inside the
//!    [`Bounds`]);
//! 2. the caller runs an episode with θ and measures its cost (lower is better);
//! 3. [`Optimizer::tell`] reports that cost.
//!
//! Batch algorithms (CEM, RACOS) still hand out one candidate per `ask` and update their
//! model when a batch is complete, so a firmware never holds more than one candidate.
//! Host callers that evaluate a generation in parallel wrap the optimizer in
//! [`InFlight`], which hands out several candidates with tickets and gives the same
//! results as this sequential contract ([`in_flight`]).
//!
//! # Why `ask` returns the candidate by value
//! `ask` returns an owned [`Vector`] (4·N bytes, 72 bytes for the 18-parameter AUV policy)
//! rather than a reference into the optimizer. A borrow would pin the optimizer for the whole
//! episode, while the episode loop needs the candidate (in the policy) *and* the optimizer
//! (to `tell` at the end) at the same time; the copy costs a few dozen instructions once per
//! episode, which is nothing next to an episode.
//!
//! # Call order and errors
//! * `ask` while a candidate is pending returns the *same* candidate again (idempotent), so a
//!   firmware that lost it (a reset of the episode loop, a retry) can ask again without
//!   perturbing the search.
//! * `tell` without a pending candidate is [`Error::NoPendingAsk`]; a NaN or infinite cost is
//!   [`Error::NonFinite`]. A rejected call leaves the optimizer exactly as it was: the
//!   candidate stays pending, so the caller may re-run the episode and tell again.
//! * `ask` after the optimizer has stopped (see [`Status`]) is [`Error::Stopped`]; the best
//!   parameters are still available from [`Optimizer::best`].
//!
//! Randomness and time belong to the caller: the RNG is passed to `ask` as a
//! [`rand_core::RngCore`], so runs are reproducible from a seed and the optimizer holds no
//! RNG state of its own.

use rand_core::RngCore;

pub mod any;
pub mod cem;
pub mod cmaes;
pub mod coordinate;
pub mod crs;
pub mod in_flight;
pub mod line_bo;
pub mod rockstar;
pub mod sracos;
pub mod two_phase;

mod cholesky;
mod ledger;

pub use any::AnyOptimizer;
pub use cem::{CemConfig, DiagonalCem, Weighting};
pub use cmaes::{Cmaes, CmaesConfig};
pub use coordinate::{CoordinateConfig, CoordinateSearch};
pub use crs::{ControlledRandomSearch, CrsConfig};
pub use in_flight::{Draw, Generation, InFlight, Ticket};
pub use line_bo::{LineBo, LineBoConfig, LineDirections};
pub use rockstar::{Rockstar, RockstarConfig};
#[allow(deprecated)]
pub use sracos::RacosConfig;
pub use sracos::{Racos, Replacement, Sracos, SracosConfig, Suppression};
pub use two_phase::{Phase, TwoPhase};

// The shared vocabulary, also reachable from here (where it lived before 0.2.0).
pub use crate::bounds::Bounds;
pub use crate::error::Error;
use crate::error::require;
pub(crate) use crate::random::random_index;
pub use crate::random::{normal_pair_f32, unit_f32};
pub use crate::vector::Vector;
pub(crate) use ledger::{Ledger, ledger_accessors};

/// Where an optimizer is in its run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Status {
    /// It will propose more candidates.
    Running,
    /// Its own stopping test holds (for example all step sizes below the tolerance).
    Converged,
    /// It has used its evaluation budget.
    BudgetSpent,
}

/// The best parameters seen so far and their cost.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Best<const N: usize> {
    /// The parameter vector.
    pub theta: Vector<N>,
    /// Its measured cost.
    pub cost: f32,
}

/// The sequential ask/tell interface every algorithm implements (minimisation).
///
/// `N` is the number of parameters, fixed at compile time so the optimizer's memory is
/// known to the linker. There is no `dyn` here (`ask` is generic over the RNG); pick an
/// algorithm with generics or an enum over them.
pub trait Optimizer<const N: usize> {
    /// The next candidate θ to evaluate, inside [`Optimizer::bounds`]. Repeats the pending
    /// candidate if there is one; [`Error::Stopped`] once [`Optimizer::status`] is not
    /// [`Status::Running`].
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error>;

    /// Reports the cost of the pending candidate. Rejects a non-finite cost or a missing
    /// `ask` without changing any state.
    fn tell(&mut self, cost: f32) -> Result<(), Error>;

    /// The best (θ, cost) told so far, `None` before the first `tell`.
    fn best(&self) -> Option<Best<N>>;

    /// The candidate handed out by `ask` and not yet told, if any.
    fn pending(&self) -> Option<&Vector<N>>;

    /// How many costs have been accepted by `tell`.
    fn evaluations(&self) -> u32;

    /// Whether the optimizer will propose more candidates.
    fn status(&self) -> Status;

    /// The box every candidate lies in.
    fn bounds(&self) -> &Bounds<N>;
}

/// The checks every optimizer's configuration ends with: a finite stopping tolerance ≥ 0
/// (`None` for an optimizer that has none) and a budget of at least one evaluation.
pub(crate) fn check_stopping(tolerance: Option<f32>, max_evaluations: u32) -> Result<(), Error> {
    require(
        tolerance.is_none_or(|t| t.is_finite() && t >= 0.0),
        "tolerance",
    )?;
    require(max_evaluations != 0, "max_evaluations")?;
    Ok(())
}

/// The step-size checks of the strategies that adapt one (CMA-ES, ROCK*): the largest σ
/// finite and > 0, the initial σ finite, > 0 and at most the largest.
pub(crate) fn check_sigmas(initial_sigma: f32, max_sigma: f32) -> Result<(), Error> {
    let positive = |v: f32| v.is_finite() && v > 0.0;
    require(positive(max_sigma), "max_sigma")?;
    require(
        positive(initial_sigma) && initial_sigma <= max_sigma,
        "initial_sigma",
    )?;
    Ok(())
}

/// `impl Default` as the configuration's `DEFAULT` constant, for each type named.
macro_rules! default_is_const {
    ($($config:ty),+) => {
        $(impl Default for $config {
            fn default() -> Self {
                Self::DEFAULT
            }
        })+
    };
}
pub(crate) use default_is_const;

/// Inserts `sample` into `kept`, sorted by `cost` (ties after the samples told before), if
/// it is among the best `room` so far; the worst drops out when `kept` holds `room` already.
/// Shared by the batch algorithms that keep only their elites of a batch.
pub(crate) fn keep_ranked<T, const C: usize>(
    kept: &mut heapless::Vec<T, C>,
    room: usize,
    sample: T,
    cost: impl Fn(&T) -> f32,
) {
    let value = cost(&sample);
    let rank = kept.partition_point(|s| cost(s) <= value);
    if kept.len() >= room {
        if rank >= kept.len() {
            return;
        }
        kept.pop();
    }
    // len < room ≤ C here (callers keep room ≤ C), so the insertion cannot fail; and
    // rank ≤ len always (a partition point), tested only so that `insert`'s assertion has
    // no panic path.
    if rank <= kept.len() {
        let _ = kept.insert(rank, sample);
    }
}
