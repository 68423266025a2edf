//! The parameter box `lower <= θ <= upper`: the region every candidate lies in and the first
//! layer of the safety envelope.

use rand_core::RngCore;

use crate::error::Error;
use crate::random::unit_f32;
use crate::vector::Vector;

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
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Bounds<const N: usize> {
    lower: Vector<N>,
    upper: Vector<N>,
}

impl<const N: usize> Bounds<N> {
    /// The box `[lower, upper]`; every bound must be finite, `lower[i] < upper[i]` (a
    /// coordinate with no room to move should not be a parameter) and the width
    /// `upper[i] − lower[i]` finite in `f32` (at most `f32::MAX`: the optimizers sample and
    /// normalise through it).
    pub fn try_new(lower: Vector<N>, upper: Vector<N>) -> Result<Self, Error> {
        const { assert!(N > 0, "an optimizer needs at least one parameter") };
        let bounds = Self { lower, upper };
        bounds.check_decoded()?;
        Ok(bounds)
    }

    /// The checks of [`Bounds::try_new`], also run on a box decoded from a record.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        for i in 0..N {
            let (lo, hi) = (self.lower[i], self.upper[i]);
            if !(lo.is_finite() && hi.is_finite() && lo < hi && (hi - lo).is_finite()) {
                return Err(Error::InvalidBounds { index: i });
            }
        }
        Ok(())
    }

    /// The box [−1, 1]^N: the box of [`Corrected`](crate::controller::Corrected)'s
    /// dimensionless weights.
    pub fn unit() -> Self {
        const { assert!(N > 0, "an optimizer needs at least one parameter") };
        Self {
            lower: Vector::repeat(-1.0),
            upper: Vector::repeat(1.0),
        }
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
        let mut projected = *theta;
        self.project(&mut projected);
        projected
    }

    /// [`Bounds::clamp`] in place: every optimizer's `ask` passes through it, so it works
    /// on the slices (nalgebra's strided iterators and `from_fn` cost several times more
    /// per coordinate on a Cortex-M) and writes only coordinates outside the box.
    pub(crate) fn project(&self, theta: &mut Vector<N>) {
        let box_ = self.lower.as_slice().iter().zip(self.upper.as_slice());
        for (v, (&lower, &upper)) in theta.as_mut_slice().iter_mut().zip(box_) {
            // Comparisons, not `f32::clamp` (its `min <= max` assertion is a panic path the
            // compiler cannot remove) nor `max`/`min` (library calls on a Cortex-M4F, which
            // has no VMAXNM). Both ordered tests are false for NaN, which goes to `lower`.
            if !(*v >= lower && *v <= upper) {
                *v = if *v > upper { upper } else { lower };
            }
        }
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
            let upper = self.upper[i];
            let v = self.lower[i] + unit_f32(rng) * (upper - self.lower[i]);
            // `lower + u·width` can round up to just past `upper` (a comparison: `min` is a
            // library call on a Cortex-M4F).
            if v > upper { upper } else { v }
        })
    }
}

/// A box with its affine map to [−1, 1]ⁿ, x = (θ − centre) / half-width, for the
/// optimizers that search in normalised coordinates (`Cmaes`, `Rockstar`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(crate) struct UnitMap<const N: usize> {
    /// The box.
    pub(crate) bounds: Bounds<N>,
    centre: Vector<N>,
    half: Vector<N>,
}

impl<const N: usize> UnitMap<N> {
    /// The map of `bounds`. Halves first: `upper − lower` would overflow near ±f32::MAX. The
    /// floor keeps the division of [`Self::unit_of`] finite for boxes narrower than two
    /// subnormals.
    pub(crate) fn new(bounds: Bounds<N>) -> Self {
        let (lo, up) = (bounds.lower(), bounds.upper());
        Self {
            centre: Vector::from_fn(|i, _| 0.5 * up[i] + 0.5 * lo[i]),
            half: Vector::from_fn(|i, _| (0.5 * up[i] - 0.5 * lo[i]).max(f32::MIN_POSITIVE)),
            bounds,
        }
    }

    /// x = (θ − centre) / half-width, not clamped.
    #[inline(always)]
    pub(crate) fn unit_of(&self, theta: &Vector<N>) -> Vector<N> {
        // Inlined, in place and with the fields by reference: a call returns its vector
        // through a temporary, and `self.centre` by value is a copy (4n bytes of stack
        // each, counted on the firmware).
        let mut x = *theta;
        x -= &self.centre;
        x.component_div_assign(&self.half);
        x
    }

    /// x = (θ − centre) / half-width, clamped to [−1, 1]ⁿ: the unit point of a θ inside the
    /// box. Without the clamp, rounding puts it past ±1 on a box narrow relative to its
    /// offset ([100, 100.001] maps 100 to about −1.02 in `f32`): a searcher that stores such
    /// a point writes a state its own record validation refuses.
    #[inline(always)]
    pub(crate) fn unit_in_box(&self, theta: &Vector<N>) -> Vector<N> {
        let mut x = self.unit_of(theta);
        // `clamp`'s `min <= max` assertion holds for these constants and is optimised away;
        // NaN stays NaN.
        x.apply(|v| *v = v.clamp(-1.0, 1.0));
        x
    }

    /// θ = centre + half-width ∘ x, projected onto the box (rounding, or x outside
    /// [−1, 1]ⁿ).
    pub(crate) fn theta_of(&self, x: &Vector<N>) -> Vector<N> {
        let mut theta = self.half.component_mul(x);
        theta += &self.centre;
        self.bounds.clamp(&theta)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    /// Checks: a box whose width `upper − lower` overflows f32 is rejected, naming the
    /// coordinate (every algorithm measures and samples through the width; such a box made
    /// `sample_uniform` return the upper corner every time); the widest box still accepted,
    /// [−f32::MAX/2, f32::MAX/2], samples points spread inside it.
    #[test]
    fn bounds_reject_a_width_that_overflows() {
        assert_eq!(
            Bounds::<1>::uniform(f32::MIN, f32::MAX),
            Err(Error::InvalidBounds { index: 0 })
        );
        let lower = Vector::<2>::from([0.0, -3e38]);
        let upper = Vector::<2>::from([1.0, 3e38]);
        assert_eq!(
            Bounds::try_new(lower, upper),
            Err(Error::InvalidBounds { index: 1 })
        );
        let wide = Bounds::<1>::uniform(-f32::MAX / 2.0, f32::MAX / 2.0).unwrap();
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
        let draws: std::vec::Vec<f32> =
            (0..100).map(|_| wide.sample_uniform(&mut rng)[0]).collect();
        assert!(draws.iter().all(|&v| wide.contains(&Vector::from([v]))));
        assert!(draws.iter().any(|&v| v < -1e37) && draws.iter().any(|&v| v > 1e37));
    }

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
        // NaN → lower, ±∞ → the nearer bound, inside → unchanged (bit for bit).
        assert_eq!(c, Vector::from([-1.0, 1e-6, 1e-3, 0.0]));
        let inside = Vector::<4>::from([-0.0, 5e-7, 1.5e-3, -1e6]);
        let kept = b.clamp(&inside);
        assert!(
            kept.iter()
                .zip(inside.iter())
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert_eq!(b.check(&wild, "theta"), Err(Error::NonFinite("theta")));
        assert_eq!(
            b.check(&Vector::from([2.0, 0.0, 1e-3, 0.0]), "theta"),
            Err(Error::OutOfBounds("theta"))
        );
    }
}
