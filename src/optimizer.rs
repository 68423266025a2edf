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

use core::fmt;

use nalgebra::SVector;
use rand_core::RngCore;

pub mod cem;
pub mod cmaes;
pub mod coordinate;
pub mod crs;
pub mod rockstar;
pub mod sracos;
pub mod two_phase;

pub use cem::{CemConfig, DiagonalCem, Weighting};
pub use cmaes::{Cmaes, CmaesConfig};
pub use coordinate::{CoordinateConfig, CoordinateSearch};
pub use crs::{ControlledRandomSearch, CrsConfig};
pub use rockstar::{Rockstar, RockstarConfig};
pub use sracos::{Racos, RacosConfig, Replacement, Sracos, SracosConfig, Suppression};
pub use two_phase::TwoPhase;

/// A parameter vector θ ∈ R^N in the on-target number type (`f32`: the Cortex-M4F FPU is
/// single precision, `f64` would be emulated in software).
pub type Vector<const N: usize> = SVector<f32, N>;

/// What went wrong in a call. Small and `Copy`, so it can be returned from an interrupt
/// handler or logged without allocation; the `&'static str` names the offending parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// A value that must be finite was NaN or infinite (`"cost"`, `"start"`, ...).
    NonFinite(&'static str),
    /// `tell` was called without a pending candidate from `ask`.
    NoPendingAsk,
    /// A configuration parameter is outside its valid range (named as in the config).
    InvalidParameter(&'static str),
    /// The box is invalid in coordinate `index`: a bound is not finite or `lower >= upper`.
    InvalidBounds {
        /// The first offending coordinate.
        index: usize,
    },
    /// A parameter vector (named) lies outside the box.
    OutOfBounds(&'static str),
    /// The optimizer has stopped (converged or budget spent) and proposes nothing more.
    Stopped,
    /// A candidate is pending: tell its cost first.
    CandidatePending,
    /// Nothing has been evaluated yet.
    NoEvaluation,
    /// An episode is running: end it before beginning another or changing mode.
    EpisodeInProgress,
    /// No episode is running: begin one first.
    NoEpisode,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite(what) => write!(f, "{what} is not finite"),
            Self::NoPendingAsk => f.write_str("tell without a pending ask"),
            Self::InvalidParameter(what) => write!(f, "invalid parameter: {what}"),
            Self::InvalidBounds { index } => write!(
                f,
                "invalid bounds in coordinate {index}: bounds must be finite with lower < upper"
            ),
            Self::OutOfBounds(what) => write!(f, "{what} lies outside the bounds"),
            Self::Stopped => f.write_str("the optimizer has stopped"),
            Self::CandidatePending => f.write_str("a candidate is pending: tell its cost first"),
            Self::NoEvaluation => f.write_str("nothing has been evaluated yet"),
            Self::EpisodeInProgress => f.write_str("an episode is in progress"),
            Self::NoEpisode => f.write_str("no episode is in progress"),
        }
    }
}

impl core::error::Error for Error {}

/// Where an optimizer is in its run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
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
pub struct Best<const N: usize> {
    /// The parameter vector.
    pub theta: Vector<N>,
    /// Its measured cost.
    pub cost: f32,
}

/// A box `lower <= θ <= upper` in R^N: the parameter region an optimizer may propose from.
///
/// On a robot this is the first layer of the safety envelope: no candidate ever leaves it.
///
/// ```
/// use ctrl_adapt::optimizer::{Bounds, Error, Vector};
/// let b = Bounds::try_new([-1.0, 0.0].into(), [1.0, 2.0].into())?;
/// assert!(b.contains(&[0.5, 2.0].into()));
/// assert_eq!(b.clamp(&[3.0, -1.0].into()), Vector::from([1.0, 0.0]));
/// assert_eq!(
///     Bounds::<1>::try_new([1.0].into(), [1.0].into()),
///     Err(Error::InvalidBounds { index: 0 })
/// );
/// # Ok::<(), Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Bounds<const N: usize> {
    lower: Vector<N>,
    upper: Vector<N>,
}

impl<const N: usize> Bounds<N> {
    /// The box `[lower, upper]`; every bound must be finite and `lower[i] < upper[i]`
    /// (a coordinate with no room to move should not be a parameter).
    pub fn try_new(lower: Vector<N>, upper: Vector<N>) -> Result<Self, Error> {
        const { assert!(N > 0, "an optimizer needs at least one parameter") };
        for i in 0..N {
            let (lo, hi) = (lower[i], upper[i]);
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return Err(Error::InvalidBounds { index: i });
            }
        }
        Ok(Self { lower, upper })
    }

    /// The same interval `[lower, upper]` in every coordinate.
    pub fn uniform(lower: f32, upper: f32) -> Result<Self, Error> {
        Self::try_new(Vector::repeat(lower), Vector::repeat(upper))
    }

    /// Lower corner.
    pub fn lower(&self) -> &Vector<N> {
        &self.lower
    }

    /// Upper corner.
    pub fn upper(&self) -> &Vector<N> {
        &self.upper
    }

    /// Whether `theta` is finite and inside the box (bounds included).
    pub fn contains(&self, theta: &Vector<N>) -> bool {
        (0..N).all(|i| theta[i] >= self.lower[i] && theta[i] <= self.upper[i])
    }

    /// `theta` projected onto the box coordinate-wise. A NaN coordinate maps to the lower
    /// bound, so the result is always inside the box.
    pub fn clamp(&self, theta: &Vector<N>) -> Vector<N> {
        Vector::from_fn(|i, _| {
            let v = theta[i];
            if v.is_nan() {
                self.lower[i]
            } else {
                // Not `f32::clamp`: its `min <= max` assertion is a panic path the
                // compiler cannot remove (`lower < upper` is an invariant of `try_new`).
                v.max(self.lower[i]).min(self.upper[i])
            }
        })
    }

    /// `Ok` if `theta` is finite and inside the box; otherwise an error naming it `what`.
    pub fn check(&self, theta: &Vector<N>, what: &'static str) -> Result<(), Error> {
        if theta.iter().any(|v| !v.is_finite()) {
            Err(Error::NonFinite(what))
        } else if self.contains(theta) {
            Ok(())
        } else {
            Err(Error::OutOfBounds(what))
        }
    }

    /// A point drawn uniformly from the box.
    pub fn sample_uniform<R: RngCore + ?Sized>(&self, rng: &mut R) -> Vector<N> {
        Vector::from_fn(|i, _| {
            let v = self.lower[i] + unit_f32(rng) * (self.upper[i] - self.lower[i]);
            // `lower + u·width` can round up to just past `upper`.
            v.min(self.upper[i])
        })
    }
}

/// A uniform `f32` in `[0, 1)` from the top 24 bits of one `u32` (the mantissa width, so
/// every value is exactly representable and 1.0 is never produced).
pub fn unit_f32<R: RngCore + ?Sized>(rng: &mut R) -> f32 {
    (rng.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// A uniform index in `0..len` (`len` ≥ 1) by Lemire's multiply-shift: no division, and a
/// bias below len/2³² (negligible for the set sizes here). Returns 0 for `len` = 0.
pub(crate) fn random_index<R: RngCore + ?Sized>(rng: &mut R, len: usize) -> usize {
    // (x·len) >> 32 < len already; the `min` only tells the compiler, so that indexing with
    // the result needs no bounds check (and has no panic path).
    (((u64::from(rng.next_u32()) * len as u64) >> 32) as usize).min(len.saturating_sub(1))
}

/// Attempts of [`normal_pair_f32`]'s rejection step before it gives up.
const POLAR_ATTEMPTS: usize = 16;

/// Two independent standard normal `f32` draws by Marsaglia and Bray's polar method:
/// (u, v) uniform in the square (−1, 1)², kept when s = u² + v² ∈ (0, 1), then
/// z = (u, v)·√(−2 ln s / s).
///
/// Only `f32` arithmetic, `logf` and `sqrtf`: no sine or cosine. (The Box–Muller transform
/// this replaces spent most of a `DiagonalCem` ask on `sincosf`, which libm computes in
/// software `f64` on a Cortex-M4F: 27k instructions per ask+tell at N = 18.)
///
/// u and v have 24-bit resolution, so s ≥ 2⁻⁴⁶ and the radius √(−2 ln s) is at most
/// √(92 ln 2) ≈ 7.99: a normal truncated at 7.99 σ (probability ≈ 10⁻¹⁴ beyond). A pair is
/// accepted with probability π/4, so it takes 2.55 `u32` on average; the RNG advances by a
/// value-dependent amount (deterministic for a seed). After 16 rejections in a row
/// (probability (1 − π/4)¹⁶ ≈ 2·10⁻¹¹, or an RNG stuck on one word) the pair is (0, 0):
/// bounded time, no panic, always finite.
pub fn normal_pair_f32<R: RngCore + ?Sized>(rng: &mut R) -> [f32; 2] {
    for _ in 0..POLAR_ATTEMPTS {
        let u = 2.0 * unit_f32(rng) - 1.0;
        let v = 2.0 * unit_f32(rng) - 1.0;
        let s = u * u + v * v;
        if s > 0.0 && s < 1.0 {
            let scale = libm::sqrtf(-2.0 * libm::logf(s) / s);
            return [u * scale, v * scale];
        }
    }
    [0.0, 0.0]
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

/// The five [`Optimizer`] accessors every algorithm answers the same way, from its `ledger`,
/// `status` and `bounds` fields; used inside each `impl Optimizer<N> for …` block.
macro_rules! ledger_accessors {
    () => {
        fn best(&self) -> Option<$crate::optimizer::Best<N>> {
            self.ledger.best()
        }

        fn pending(&self) -> Option<&$crate::optimizer::Vector<N>> {
            self.ledger.pending()
        }

        fn evaluations(&self) -> u32 {
            self.ledger.evaluations()
        }

        fn status(&self) -> $crate::optimizer::Status {
            self.status
        }

        fn bounds(&self) -> &$crate::optimizer::Bounds<N> {
            &self.bounds
        }
    };
}
pub(crate) use ledger_accessors;

/// The book-keeping every algorithm shares: the pending candidate, the evaluation count
/// against the budget, and the best (θ, cost) so far. Keeping it in one place makes the
/// "rejected call changes nothing" rule hold the same way in every optimizer.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub(crate) struct Ledger<const N: usize> {
    pending: Option<Vector<N>>,
    evaluations: u32,
    budget: u32,
    best: Option<Best<N>>,
}

impl<const N: usize> Ledger<N> {
    /// A fresh ledger allowing `budget` evaluations.
    pub(crate) const fn new(budget: u32) -> Self {
        Self {
            pending: None,
            evaluations: 0,
            budget,
            best: None,
        }
    }

    /// Marks `theta` as handed out.
    pub(crate) fn hand_out(&mut self, theta: Vector<N>) -> Vector<N> {
        self.pending = Some(theta);
        theta
    }

    /// Checks a `tell` before anything is changed; on success takes the pending candidate,
    /// counts the evaluation and updates the best, returning the candidate.
    pub(crate) fn accept(&mut self, cost: f32) -> Result<Vector<N>, Error> {
        let theta = self.pending.ok_or(Error::NoPendingAsk)?;
        if !cost.is_finite() {
            return Err(Error::NonFinite("cost"));
        }
        self.pending = None;
        self.evaluations = self.evaluations.saturating_add(1);
        if self.best.is_none_or(|b| cost < b.cost) {
            self.best = Some(Best { theta, cost });
        }
        Ok(theta)
    }

    pub(crate) fn pending(&self) -> Option<&Vector<N>> {
        self.pending.as_ref()
    }

    pub(crate) fn evaluations(&self) -> u32 {
        self.evaluations
    }

    pub(crate) fn budget_spent(&self) -> bool {
        self.evaluations >= self.budget
    }

    pub(crate) fn best(&self) -> Option<Best<N>> {
        self.best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    #[test]
    fn bounds_reject_non_finite_and_empty_intervals() {
        let ok = Vector::<3>::repeat(1.0);
        let mut lo = Vector::<3>::zeros();
        assert!(Bounds::try_new(lo, ok).is_ok());
        lo[2] = f32::NAN;
        assert_eq!(
            Bounds::try_new(lo, ok),
            Err(Error::InvalidBounds { index: 2 })
        );
        lo[2] = 0.0;
        lo[1] = 1.0;
        assert_eq!(
            Bounds::try_new(lo, ok),
            Err(Error::InvalidBounds { index: 1 })
        );
        assert_eq!(
            Bounds::<2>::uniform(0.0, f32::INFINITY),
            Err(Error::InvalidBounds { index: 0 })
        );
    }

    #[test]
    fn uniform_samples_and_clamp_stay_inside() {
        let b = Bounds::<4>::try_new(
            [-1.0, 0.0, 1e-3, -1e6].into(),
            [1.0, 1e-6, 2e-3, 1e6].into(),
        )
        .unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
        for _ in 0..10_000 {
            assert!(b.contains(&b.sample_uniform(&mut rng)));
        }
        let wild = Vector::<4>::from([f32::NAN, f32::INFINITY, -f32::INFINITY, 0.0]);
        let c = b.clamp(&wild);
        assert!(b.contains(&c));
        assert_eq!(b.check(&wild, "theta"), Err(Error::NonFinite("theta")));
        assert_eq!(
            b.check(&Vector::from([2.0, 0.0, 1e-3, 0.0]), "theta"),
            Err(Error::OutOfBounds("theta"))
        );
    }

    /// An RNG that always returns the same word, to reach the ends of the uniform ranges.
    struct Constant(u32);

    impl RngCore for Constant {
        fn next_u32(&mut self) -> u32 {
            self.0
        }
        fn next_u64(&mut self) -> u64 {
            u64::from(self.0)
        }
        fn fill_bytes(&mut self, dst: &mut [u8]) {
            dst.fill(self.0 as u8);
        }
    }

    /// Checks: 200,000 polar-method draws have mean 0 ± 0.01, variance 1 ± 0.01, the
    /// normal's share within one σ (68.3 ± 0.5 %) and beyond 2σ (4.55 ± 0.2 %), the two
    /// draws of a pair are uncorrelated (|r| < 0.01), and RNGs stuck on one word (the
    /// extremes, which are always rejected, and accepted ones) give finite draws with radius
    /// at most √(92 ln 2).
    #[test]
    fn normal_pairs_are_standard_normal_and_finite() {
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(11);
        let draws: std::vec::Vec<f32> = (0..100_000)
            .flat_map(|_| normal_pair_f32(&mut rng))
            .collect();
        let n = draws.len() as f64;
        let mean = draws.iter().map(|&z| f64::from(z)).sum::<f64>() / n;
        let var = draws
            .iter()
            .map(|&z| (f64::from(z) - mean).powi(2))
            .sum::<f64>()
            / n;
        let within = draws.iter().filter(|z| z.abs() < 1.0).count() as f64 / n;
        assert!(
            mean.abs() < 0.01 && (var - 1.0).abs() < 0.01,
            "{mean} {var}"
        );
        assert!((within - 0.6827).abs() < 0.005, "{within}");
        let beyond = draws.iter().filter(|z| z.abs() > 2.0).count() as f64 / n;
        assert!((beyond - 0.0455).abs() < 0.002, "{beyond}");
        let r = draws
            .chunks_exact(2)
            .map(|p| f64::from(p[0]) * f64::from(p[1]))
            .sum::<f64>()
            / (n / 2.0);
        assert!(r.abs() < 0.01, "{r}");
        let limit = libm::sqrtf(92.0 * core::f32::consts::LN_2) * 1.0001;
        for word in [
            0,
            1,
            255,
            256,
            u32::MAX / 2,
            0x8000_0000,
            0x8000_0100,
            u32::MAX,
        ] {
            let [a, b] = normal_pair_f32(&mut Constant(word));
            assert!(a.is_finite() && b.is_finite(), "{word}: {a} {b}");
            assert!(libm::hypotf(a, b) <= limit, "{word}: {a} {b}");
        }
    }

    #[test]
    fn ledger_rejects_without_change() {
        let mut l = Ledger::<2>::new(3);
        assert_eq!(l.accept(1.0), Err(Error::NoPendingAsk));
        l.hand_out(Vector::from([0.5, 0.5]));
        let before = l;
        assert_eq!(l.accept(f32::NAN), Err(Error::NonFinite("cost")));
        assert_eq!(l.accept(f32::NEG_INFINITY), Err(Error::NonFinite("cost")));
        assert_eq!(l, before);
        assert!(l.accept(2.0).is_ok());
        assert_eq!(l.evaluations(), 1);
        assert_eq!(l.best().map(|b| b.cost), Some(2.0));
    }

    #[test]
    fn errors_display_their_parameter() {
        extern crate std;
        use std::string::ToString;
        assert_eq!(
            Error::InvalidParameter("sigma").to_string(),
            "invalid parameter: sigma"
        );
        assert_eq!(Error::NonFinite("cost").to_string(), "cost is not finite");
    }
}
