//! The Gaussian process of [`LineBo`](super::LineBo): a zero-mean GP on the cost minus a
//! prior mean, with a squared-exponential kernel on the normalised parameters, over at most
//! `M` remembered episodes (Rasmussen & Williams, "Gaussian Processes for Machine
//! Learning", 2006, algorithm 2.1, with the factor kept up to date point by point).
//!
//! The kernel, the factor's updates, the eviction rule and the clipping of extreme costs are
//! documented in the public module docs of [`LineBo`](super::LineBo), section "The Gaussian
//! process".

use nalgebra::{SMatrix, SVector};

#[cfg(feature = "serde")]
use crate::Error;
use crate::Vector;
use crate::optimizer::cholesky::{cholesky_in_place, solve_lower, solve_lower_transposed};
use crate::vector::zero;

/// Residuals are clipped to this many signal standard deviations.
const RESIDUAL_LIMIT: f32 = 1e6;

/// The kernel's hyperparameters, derived from the configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kernel {
    /// σ_f².
    pub(crate) signal: f32,
    /// 1 / (2ℓ²) in normalised units.
    pub(crate) inverse_width: f32,
    /// σ_n² + jitter·σ_f²: the observation variance and the floor of every pivot.
    pub(crate) noise: f32,
}

impl Kernel {
    /// k at squared distance `d2` (a negative `d2` from rounding counts as 0).
    #[inline]
    pub(crate) fn at(&self, d2: f32) -> f32 {
        self.signal * libm::expf(-d2.max(0.0) * self.inverse_width)
    }
}

/// The remembered episodes and the factor of their kernel matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub(crate) struct Gp<const N: usize, const M: usize> {
    /// x_i, normalised to [−1, 1]ⁿ; the first `len` are live.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    points: [Vector<N>; M],
    /// y_i − prior mean, clipped.
    residuals: SVector<f32, M>,
    /// L (lower triangle of the leading `len × len` block), L Lᵀ = K + σ²I.
    factor: SMatrix<f32, M, M>,
    /// α = (K + σ²I)⁻¹ y.
    weights: SVector<f32, M>,
    len: usize,
    /// The prior mean: the first cost told (the start's).
    prior: Option<f32>,
}

/// The terms of ‖o + t d − x_i‖² = a_i + 2t b_i + t² for a line o + t d (‖d‖ = 1):
/// a_i = ‖o − x_i‖², b_i = dᵀ(o − x_i), so that a point of the line costs O(n) kernel
/// evaluations instead of O(n·N).
pub(crate) struct LineTerms<const M: usize> {
    a: [f32; M],
    b: [f32; M],
}

impl<const M: usize> LineTerms<M> {
    /// All zero, to be filled by [`Gp::line_terms`].
    pub(crate) const ZERO: Self = Self {
        a: [0.0; M],
        b: [0.0; M],
    };
}

impl<const N: usize, const M: usize> Gp<N, M> {
    /// No points.
    pub(crate) const EMPTY: Self = Self {
        points: [const { zero() }; M],
        residuals: SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; 1])),
        factor: SMatrix::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; M])),
        weights: SVector::from_array_storage(nalgebra::ArrayStorage([[0.0; M]; 1])),
        len: 0,
        prior: None,
    };

    /// How many points the model holds.
    pub(crate) fn len(&self) -> usize {
        self.len
    }

    /// The prior mean (0 before the first point).
    pub(crate) fn prior(&self) -> f32 {
        self.prior.unwrap_or(0.0)
    }

    /// Adds the observation (x, y); when full, first evicts the point farthest from
    /// `around` (module docs).
    pub(crate) fn append(&mut self, x: &Vector<N>, y: f32, kernel: &Kernel, around: &Vector<N>) {
        let prior = *self.prior.get_or_insert(y);
        let limit = RESIDUAL_LIMIT * libm::sqrtf(kernel.signal);
        // max/min rather than `f32::clamp`, whose check of its bounds is a panic path; the
        // same value for the limit, positive by the configuration's validation.
        let residual = (y - prior).max(-limit).min(limit);
        let n = self.len.min(M);
        if n == M {
            let farthest = (0..n)
                .max_by(|&i, &j| {
                    let (di, dj) = (self.distance2(i, around), self.distance2(j, around));
                    di.total_cmp(&dj)
                })
                .unwrap_or(0);
            if let (Some(p), Some(r)) = (
                self.points.get_mut(farthest),
                self.residuals.get_mut(farthest),
            ) {
                *p = *x;
                *r = residual;
            }
            self.refactor(kernel);
            return;
        }
        let mut row = self.kernel_column(x, kernel);
        solve_lower(&self.factor, &mut row, n);
        let pivot = kernel.signal + kernel.noise - dot(live(&row, n), live(&row, n));
        if let (Some(p), Some(r)) = (self.points.get_mut(n), self.residuals.get_mut(n)) {
            *p = *x;
            *r = residual;
        }
        self.len = n + 1;
        if pivot >= 0.5 * kernel.noise && pivot.is_finite() {
            // Row n of L: L⁻¹k left of the diagonal, the pivot's root on it.
            let entries = row.iter().take(n).copied().chain([libm::sqrtf(pivot)]);
            for (k, value) in entries.enumerate() {
                if let Some(f) = self.factor.get_mut((n, k)) {
                    *f = value;
                }
            }
            self.update_weights();
        } else {
            self.refactor(kernel);
        }
    }

    /// L and α from scratch, pivots below the noise floored to it.
    pub(crate) fn refactor(&mut self, kernel: &Kernel) {
        let n = self.len.min(M);
        for (j, pj) in self.points.iter().enumerate().take(n) {
            for (i, pi) in self.points.iter().enumerate().take(n).skip(j) {
                let d2 = (pi - pj).norm_squared();
                if let Some(f) = self.factor.get_mut((i, j)) {
                    *f = kernel.at(d2) + if i == j { kernel.noise } else { 0.0 };
                }
            }
        }
        cholesky_in_place(&mut self.factor, n, Some(kernel.noise));
        self.update_weights();
    }

    fn update_weights(&mut self) {
        let n = self.len.min(M);
        self.weights = self.residuals;
        solve_lower(&self.factor, &mut self.weights, n);
        solve_lower_transposed(&self.factor, &mut self.weights, n);
    }

    fn distance2(&self, i: usize, x: &Vector<N>) -> f32 {
        self.points.get(i).map_or(0.0, |p| (p - x).norm_squared())
    }

    /// k(x_i, x) for the live points, 0 beyond.
    pub(crate) fn kernel_column(&self, x: &Vector<N>, kernel: &Kernel) -> SVector<f32, M> {
        let mut k = SVector::<f32, M>::zeros();
        for (k, p) in k.iter_mut().zip(&self.points).take(self.len.min(M)) {
            *k = kernel.at((p - x).norm_squared());
        }
        k
    }

    /// The posterior mean of the latent cost at the point whose kernel column is `k`.
    pub(crate) fn mean(&self, k: &SVector<f32, M>) -> f32 {
        let n = self.len.min(M);
        self.prior() + dot(live(k, n), live(&self.weights, n))
    }

    /// The posterior mean and variance of the latent cost at the point whose kernel
    /// column is `k`; `k` is overwritten with L⁻¹k (for [`Gp::covariance`]).
    pub(crate) fn posterior(&self, k: &mut SVector<f32, M>, kernel: &Kernel) -> (f32, f32) {
        let n = self.len.min(M);
        let mean = self.mean(k);
        solve_lower(&self.factor, k, n);
        let variance = (kernel.signal - dot(live(k, n), live(k, n))).max(0.0);
        (mean, variance)
    }

    /// The posterior covariance of two points from their prior covariance `prior` and
    /// their whitened columns L⁻¹k (from [`Gp::posterior`]).
    pub(crate) fn covariance(&self, prior: f32, a: &SVector<f32, M>, b: &SVector<f32, M>) -> f32 {
        let n = self.len.min(M);
        prior - dot(live(a, n), live(b, n))
    }

    /// Fills `terms` with the [`LineTerms`] of the line through `origin` along the unit
    /// vector `direction`. Entry by entry into the caller's terms, with no vector
    /// temporaries: they are on the stack of every posterior pass, which a
    /// microcontroller's RAM bounds.
    pub(crate) fn line_terms(
        &self,
        origin: &Vector<N>,
        direction: &Vector<N>,
        terms: &mut LineTerms<M>,
    ) {
        for ((point, a), b) in self
            .points
            .iter()
            .zip(terms.a.iter_mut())
            .zip(terms.b.iter_mut())
            .take(self.len.min(M))
        {
            (*a, *b) = (0.0, 0.0);
            for ((o, x), d) in origin.iter().zip(point.iter()).zip(direction.iter()) {
                let offset = o - x;
                *a += offset * offset;
                *b += d * offset;
            }
        }
    }

    /// k(x_i, o + t d) for the live points, from the point itself (O(n) per entry; for the
    /// few columns of the expander test, which need no [`LineTerms`] on the stack).
    pub(crate) fn column_on_line(
        &self,
        origin: &Vector<N>,
        direction: &Vector<N>,
        t: f32,
        kernel: &Kernel,
    ) -> SVector<f32, M> {
        let mut k = SVector::<f32, M>::zeros();
        for (point, k) in self.points.iter().zip(k.iter_mut()).take(self.len.min(M)) {
            let mut d2 = 0.0;
            for ((o, x), d) in origin.iter().zip(point.iter()).zip(direction.iter()) {
                let offset = o + t * d - x;
                d2 += offset * offset;
            }
            *k = kernel.at(d2);
        }
        k
    }

    /// Writes k(x_i, o + t d) for the live points into the first entries of `k`, from the
    /// line's terms (in place: one column's buffer serves the whole grid).
    pub(crate) fn line_column(
        &self,
        terms: &LineTerms<M>,
        t: f32,
        kernel: &Kernel,
        k: &mut SVector<f32, M>,
    ) {
        let live = self.len.min(M);
        for ((k, a), b) in k.iter_mut().zip(&terms.a).zip(&terms.b).take(live) {
            *k = kernel.at(a + t * (2.0 * b + t));
        }
    }

    /// The checks of a decoded model: the live points inside [−1, 1]ⁿ (with rounding
    /// room), residuals, weights and factor finite, the factor's diagonal positive, and a
    /// prior exactly when there are points.
    #[cfg(feature = "serde")]
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        use crate::error::{require, require_finite};
        require(self.len <= M, "len")?;
        require(self.prior.is_some() == (self.len > 0), "prior")?;
        require_finite(self.prior.iter(), "prior")?;
        let n = self.len;
        for p in &self.points[..n] {
            require_finite(p.iter(), "points")?;
            require(p.iter().all(|v| v.abs() <= 1.0 + 1e-3), "points")?;
        }
        require_finite(self.residuals.iter(), "residuals")?;
        require_finite(self.weights.iter(), "weights")?;
        require_finite(self.factor.iter(), "factor")?;
        require((0..n).all(|i| self.factor[(i, i)] > 0.0), "factor")
    }
}

/// The first `n` entries of `v` (all of them if `n` is larger).
fn live<const M: usize>(v: &SVector<f32, M>, n: usize) -> &[f32] {
    let all = v.as_slice();
    all.get(..n).unwrap_or(all)
}

/// aᵀb over the shorter of the two, summed in the order of nalgebra's `dot` for vectors of
/// run-time length (eight interleaved partial sums, then the rest), so that the results
/// are bit-identical to `rows(0, n).dot(..)`; written out because that `dot` asserts the
/// shapes match, a panic path the compiler keeps where it does not inline the call.
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (chunks_a, chunks_b) = (a.chunks_exact(8), b.chunks_exact(8));
    // Slices of one length (always the case here) leave remainders of one length.
    let (rest_a, rest_b) = (chunks_a.remainder(), chunks_b.remainder());
    for (x, y) in chunks_a.zip(chunks_b) {
        for ((acc, x), y) in acc.iter_mut().zip(x).zip(y) {
            *acc += x * y;
        }
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    let mut sum = 0.0;
    sum += a0 + a4;
    sum += a1 + a5;
    sum += a2 + a6;
    sum += a3 + a7;
    for (x, y) in rest_a.iter().zip(rest_b) {
        sum += x * y;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kernel() -> Kernel {
        Kernel {
            signal: 2.0,
            inverse_width: 1.0 / (2.0 * 0.6 * 0.6),
            noise: 0.05,
        }
    }

    const POINTS: [[f32; 2]; 4] = [[0.1, -0.3], [0.5, 0.5], [-0.7, 0.2], [0.12, -0.25]];
    const COSTS: [f32; 4] = [3.0, 1.0, 4.5, 2.5];

    /// The posterior at `x` by a direct solve in f64 of (K + σ²I) α = y (the textbook
    /// formulas, no incremental factor), prior mean the first cost.
    fn direct(points: &[[f32; 2]], costs: &[f32], x: [f32; 2]) -> (f64, f64) {
        let kern = kernel();
        let k = |a: [f32; 2], b: [f32; 2]| {
            let d2 = f64::from((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2));
            f64::from(kern.signal) * (-d2 * f64::from(kern.inverse_width)).exp()
        };
        let n = points.len();
        let mut big = SMatrix::<f64, 4, 4>::identity();
        let mut y = SVector::<f64, 4>::zeros();
        let mut kx = SVector::<f64, 4>::zeros();
        for i in 0..n {
            for j in 0..n {
                big[(i, j)] =
                    k(points[i], points[j]) + if i == j { f64::from(kern.noise) } else { 0.0 };
            }
            y[i] = f64::from(costs[i] - costs[0]);
            kx[i] = k(points[i], x);
        }
        let inv = big.try_inverse().unwrap();
        let mean = f64::from(costs[0]) + (kx.transpose() * inv * y)[0];
        let var = k(x, x) - (kx.transpose() * inv * kx)[0];
        // The padding (identity rows, zero y and k) leaves the first n unknowns as they are.
        (mean, var)
    }

    /// Checks: after each incremental append (and after a refactorisation from scratch),
    /// the posterior mean and variance at three query points equal a direct f64 solve to
    /// within 1e-4 (relative to σ_f² = 2).
    #[test]
    fn posterior_equals_a_direct_solve() {
        let kern = kernel();
        let mut gp = Gp::<2, 4>::EMPTY;
        for n in 1..=4 {
            let x = Vector::from(POINTS[n - 1]);
            gp.append(&x, COSTS[n - 1], &kern, &x);
            for refactored in [false, true] {
                if refactored {
                    let mut again = gp;
                    again.refactor(&kern);
                    assert!((again.factor - gp.factor).abs().max() < 1e-5);
                }
                for q in [[0.0, 0.0], [0.11, -0.28], [0.9, -0.9]] {
                    let mut k = gp.kernel_column(&Vector::from(q), &kern);
                    let (mean, var) = gp.posterior(&mut k, &kern);
                    let (m, v) = direct(&POINTS[..n], &COSTS[..n], q);
                    assert!(
                        (f64::from(mean) - m).abs() < 1e-4,
                        "n={n} {q:?}: {mean} vs {m}"
                    );
                    assert!(
                        (f64::from(var) - v).abs() < 1e-4,
                        "n={n} {q:?}: {var} vs {v}"
                    );
                }
            }
        }
    }

    /// Checks: with the model full, a new point evicts the one farthest from `around`, and
    /// the posterior then equals a direct solve on the points kept.
    #[test]
    fn eviction_drops_the_farthest_point_and_refactors() {
        let kern = kernel();
        let mut gp = Gp::<2, 3>::EMPTY;
        for n in 0..3 {
            let x = Vector::from(POINTS[n]);
            gp.append(&x, COSTS[n], &kern, &x);
        }
        // Around (0.1, −0.3), the farthest of the three is (−0.7, 0.2), the third.
        let around = Vector::from(POINTS[0]);
        gp.append(&Vector::from(POINTS[3]), COSTS[3], &kern, &around);
        assert_eq!(gp.len(), 3);
        assert_eq!(gp.points[2], Vector::from(POINTS[3]));
        let kept = [POINTS[0], POINTS[1], POINTS[3]];
        let kept_costs = [COSTS[0], COSTS[1], COSTS[3]];
        let mut k = gp.kernel_column(&Vector::from([0.2, 0.1]), &kern);
        let (mean, var) = gp.posterior(&mut k, &kern);
        let (m, v) = direct(&kept, &kept_costs, [0.2, 0.1]);
        assert!((f64::from(mean) - m).abs() < 1e-4 && (f64::from(var) - v).abs() < 1e-4);
    }

    /// Checks: one point told 64 times (a pivot that rounding drives to the floor) and
    /// costs of ±f32::MAX keep the factor's diagonal positive and the weights finite.
    #[test]
    fn repeated_points_and_extreme_costs_stay_finite() {
        let kern = Kernel {
            noise: 1e-4 * 2.0,
            ..kernel()
        };
        let mut gp = Gp::<2, 64>::EMPTY;
        let x = Vector::from([0.3, 0.3]);
        for i in 0..64 {
            let y = if i % 2 == 0 { f32::MAX } else { -f32::MAX };
            gp.append(&x, y, &kern, &x);
        }
        assert!((0..64).all(|i| gp.factor[(i, i)] > 0.0));
        assert!(gp.weights.iter().all(|w| w.is_finite()));
        let mut k = gp.kernel_column(&x, &kern);
        let (mean, var) = gp.posterior(&mut k, &kern);
        assert!(mean.is_finite() && var.is_finite() && var >= 0.0);
    }
}
