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
use crate::vector::zero;

/// Residuals are clipped to this many signal standard deviations.
const RESIDUAL_LIMIT: f32 = 1e6;

/// Grid points per block of a [`Sweep`]: each block starts from the kernel computed
/// directly, so the recurrence's rounding grows over at most this many steps.
pub(crate) const BLOCK: usize = 8;

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
    /// L, L Lᵀ = K + σ²I, stored by rows: row i of L (its entries 0..=i) is column i of
    /// the matrix, contiguous in nalgebra's column-major storage, so that the forward
    /// substitution of every posterior reads its rows in order. (The matrix holds Lᵀ.)
    factor: SMatrix<f32, M, M>,
    /// α = (K + σ²I)⁻¹ y.
    weights: SVector<f32, M>,
    len: usize,
    /// The prior mean: the first cost told (the start's).
    prior: Option<f32>,
}

/// The state of one pass along an evenly spaced grid t_g = t₀ + gΔ of a line o + t d
/// (‖d‖ = 1): on it, ‖o + t_g d − x_i‖² is a quadratic in g whose g² coefficient Δ² is the
/// same for every x_i, so that
///
/// k(x_i, t_{g₀+j}) = σ_f² e_i · r_iʲ · exp(−wΔ² j(j − 1)),
///
/// with e_i = exp(−w‖o + t_{g₀} d − x_i‖²) and r_i = exp(−wΔ(2dᵀ(o + t_{g₀} d − x_i) + Δ)):
/// two `expf` per remembered episode at the start g₀ of each block of [`BLOCK`] points,
/// a table of the last factor shared by all of them, and two multiplications per episode
/// and grid point for the rest. Each block starts again from the kernel computed directly,
/// so the products carry at most 2·`BLOCK` + 4 roundings and r's rounding raised to at
/// most the power `BLOCK` − 1 (a relative error of about 10⁻⁶ at worst, against the
/// rounding of ‖o − x‖² + t(2dᵀ(o − x) + t) before, which grows with w‖o − x‖²). Where a product could
/// leave f32's normal range (an e_i below 10⁻³⁰, or a table entry below e⁻⁸⁰ when the
/// grid is coarse against the length scale) the kernel is computed directly instead, and
/// where it stays below 10⁻³⁰ σ_f² over a whole block (an episode far from the line) it
/// is taken as 0 there: an absolute difference below 10⁻³⁰ σ_f².
pub(crate) struct Sweep<'a, const M: usize> {
    /// e_i r_iʲ for the current j, or −1 where the kernel is computed directly.
    carry: &'a mut SVector<f32, M>,
    /// r_i.
    ratio: &'a mut SVector<f32, M>,
    /// σ_f² exp(−wΔ² j(j − 1)), j < [`BLOCK`].
    table: [f32; BLOCK],
    /// Whether the table is usable (else every entry is computed directly).
    recur: bool,
    /// Δ.
    step: f32,
}

impl<'a, const M: usize> Sweep<'a, M> {
    /// A sweep along a grid of spacing `step`, under `kernel`, keeping its per-episode
    /// state in `carry` and `ratio` (the optimizer's scratch, not the stack).
    pub(crate) fn new(
        step: f32,
        kernel: &Kernel,
        carry: &'a mut SVector<f32, M>,
        ratio: &'a mut SVector<f32, M>,
    ) -> Self {
        let exponent = kernel.inverse_width * step * step;
        let last = (BLOCK - 1) as f32 * (BLOCK - 2) as f32;
        let mut table = [0.0; BLOCK];
        for (j, entry) in table.iter_mut().enumerate() {
            let j = j as f32;
            *entry = kernel.signal * libm::expf(-exponent * j * (j - 1.0));
        }
        carry.fill(-1.0);
        Self {
            carry,
            ratio,
            table,
            recur: exponent * last <= 80.0 && step.is_finite(),
            step,
        }
    }
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
        if self.len >= M {
            let farthest = (0..M)
                .max_by(|&i, &j| {
                    let (di, dj) = (self.distance2(i, around), self.distance2(j, around));
                    di.total_cmp(&dj)
                })
                .unwrap_or(0);
            self.remove(farthest);
        }
        let n = self.len.min(M - 1);
        if let (Some(p), Some(r)) = (self.points.get_mut(n), self.residuals.get_mut(n)) {
            *p = *x;
            *r = residual;
        }
        // Row n of L, in place: k(X, x), then L⁻¹k left of the diagonal.
        let Some((done, rest)) = self.factor.as_mut_slice().split_at_mut_checked(n * M) else {
            return;
        };
        let Some(row) = rest.get_mut(..M) else { return };
        for (k, p) in row.iter_mut().zip(&self.points).take(n) {
            *k = kernel.at(distance2(p, x));
        }
        forward::<M>(done, row, n);
        let (left, diagonal) = row.split_at_mut_checked(n).unwrap_or((&mut [], &mut []));
        let pivot = kernel.signal + kernel.noise - dot(left, left);
        self.len = n + 1;
        match diagonal.first_mut() {
            Some(d) if pivot >= 0.5 * kernel.noise && pivot.is_finite() => {
                *d = libm::sqrtf(pivot);
                self.update_weights();
            }
            _ => self.refactor(kernel),
        }
    }

    /// Drops point `p`: its row and column leave L, and the trailing block absorbs the
    /// column by a rank-one update (L₃₃' L₃₃'ᵀ = L₃₃ L₃₃ᵀ + l₃₂ l₃₂ᵀ, Golub & Van Loan,
    /// "Matrix Computations", section 6.5.4, by rotations that only raise the pivots), so
    /// that the factor of the kept points costs O(n²), not a refactorisation's O(n³).
    fn remove(&mut self, p: usize) {
        let n = self.len.min(M);
        if p >= n {
            return;
        }
        let a = self.factor.as_mut_slice();
        let at = |i: usize, k: usize| k + i * M;
        let get = |a: &[f32], i: usize| a.get(i).copied().unwrap_or(0.0);
        // The update vector x_i = L_ip (i > p) lives in column p, which is dropped after.
        for k in p + 1..n {
            let (lkk, xk) = (get(a, at(k, k)), get(a, at(k, p)));
            let r = libm::sqrtf(lkk * lkk + xk * xk);
            let (c, s) = (r / lkk, xk / lkk);
            if let Some(d) = a.get_mut(at(k, k)) {
                *d = r;
            }
            for i in k + 1..n {
                let (lik, xi) = (get(a, at(i, k)), get(a, at(i, p)));
                let lik = (lik + s * xi) / c;
                if let Some(e) = a.get_mut(at(i, k)) {
                    *e = lik;
                }
                if let Some(e) = a.get_mut(at(i, p)) {
                    *e = c * xi - s * lik;
                }
            }
        }
        // Rows below p move up one, without their entry p.
        for i in p + 1..n {
            for j in 0..i {
                let v = get(a, at(i, if j < p { j } else { j + 1 }));
                if let Some(e) = a.get_mut(at(i - 1, j)) {
                    *e = v;
                }
            }
            if let (Some(&x), Some(&r)) = (self.points.get(i), self.residuals.get(i))
                && let (Some(px), Some(pr)) =
                    (self.points.get_mut(i - 1), self.residuals.get_mut(i - 1))
            {
                (*px, *pr) = (x, r);
            }
        }
        self.len = n - 1;
    }

    /// L and α from scratch, pivots below the noise (which exact arithmetic never gives)
    /// raised to it; by rows (Cholesky–Banachiewicz), as the factor is stored.
    pub(crate) fn refactor(&mut self, kernel: &Kernel) {
        let n = self.len.min(M);
        let a = self.factor.as_mut_slice();
        for (i, (row, pi)) in a.chunks_exact_mut(M).zip(&self.points).enumerate().take(n) {
            for (j, (f, pj)) in row.iter_mut().zip(&self.points).enumerate().take(i + 1) {
                *f = kernel.at(distance2(pi, pj)) + if i == j { kernel.noise } else { 0.0 };
            }
        }
        for i in 0..n {
            let Some((done, rest)) = a.split_at_mut_checked(i * M) else {
                return;
            };
            let Some(row) = rest.get_mut(..=i) else {
                return;
            };
            // Entries left of the diagonal: (K_ij − L_i,<j · L_j,<j) / L_jj.
            forward::<M>(done, row, i);
            let Some((left, diagonal)) = row.split_at_mut_checked(i) else {
                return;
            };
            if let Some(d) = diagonal.first_mut() {
                let pivot = *d - dot(left, left);
                let pivot = if pivot >= kernel.noise && pivot.is_finite() {
                    pivot
                } else {
                    kernel.noise
                };
                *d = libm::sqrtf(pivot);
            }
        }
        self.update_weights();
    }

    fn update_weights(&mut self) {
        let n = self.len.min(M);
        self.weights = self.residuals;
        let a = self.factor.as_slice();
        let w = self.weights.as_mut_slice();
        forward::<M>(a, w, n);
        backward::<M>(a, w, n);
    }

    fn distance2(&self, i: usize, x: &Vector<N>) -> f32 {
        self.points.get(i).map_or(0.0, |p| distance2(p, x))
    }

    /// k(x_i, x) for the live points, 0 beyond.
    pub(crate) fn kernel_column(&self, x: &Vector<N>, kernel: &Kernel) -> SVector<f32, M> {
        let mut k = SVector::<f32, M>::zeros();
        for (k, p) in k
            .as_mut_slice()
            .iter_mut()
            .zip(&self.points)
            .take(self.len.min(M))
        {
            *k = kernel.at(distance2(p, x));
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
        forward::<M>(self.factor.as_slice(), k.as_mut_slice(), n);
        let variance = (kernel.signal - dot(live(k, n), live(k, n))).max(0.0);
        (mean, variance)
    }

    /// The posterior covariance of two points from their prior covariance `prior` and
    /// their whitened columns L⁻¹k (from [`Gp::posterior`]).
    pub(crate) fn covariance(&self, prior: f32, a: &SVector<f32, M>, b: &SVector<f32, M>) -> f32 {
        let n = self.len.min(M);
        prior - dot(live(a, n), live(b, n))
    }

    /// Writes k(x_i, o + t d) for the live points into the first entries of `k`, from the
    /// points themselves (O(n) per entry).
    pub(crate) fn column_on_line(
        &self,
        origin: &Vector<N>,
        direction: &Vector<N>,
        t: f32,
        kernel: &Kernel,
        k: &mut SVector<f32, M>,
    ) {
        let column = k.as_mut_slice().iter_mut();
        for (point, k) in self.points.iter().zip(column).take(self.len.min(M)) {
            *k = kernel.at(offset_on_line(origin, direction, t, point).0);
        }
    }

    /// Writes the kernel column of grid point g = g₀ + j of the sweep along the line
    /// (o, d) into the first entries of `k`, where `t` is the grid's t_g and j = g mod [`BLOCK`]; the grid
    /// points must come in order, g = 0, 1, 2, … ([`Sweep`]).
    pub(crate) fn sweep_column(
        &self,
        (origin, direction): (&Vector<N>, &Vector<N>),
        t: f32,
        g: usize,
        kernel: &Kernel,
        sweep: &mut Sweep<'_, M>,
        k: &mut SVector<f32, M>,
    ) {
        let live = self.len.min(M);
        let j = g % BLOCK;
        let factor = sweep.table.get(j).copied().unwrap_or(0.0);
        let step = sweep.step;
        let w = kernel.inverse_width;
        let entries = k.as_mut_slice().iter_mut().zip(&self.points);
        let state = (sweep.carry.as_mut_slice().iter_mut()).zip(sweep.ratio.as_mut_slice());
        for ((k, point), (carry, ratio)) in entries.zip(state).take(live) {
            if j != 0 && *carry >= 0.0 {
                *carry *= *ratio;
                *k = *carry * factor;
                continue;
            }
            let (d2, along) = offset_on_line(origin, direction, t, point);
            let exponent = -d2.max(0.0) * w;
            let e = libm::expf(exponent);
            *k = kernel.signal * e;
            if j != 0 {
                continue;
            }
            // The start of a block: e and r from the point; zeros where the kernel stays
            // below 10⁻³⁰ σ_f² over the whole block; else, where e is that small, the
            // direct way to the block's end.
            let log_ratio = -w * step * (2.0 * along + step);
            (*carry, *ratio) = if !sweep.recur {
                (-1.0, 0.0)
            } else if e >= 1e-30 {
                (e, libm::expf(log_ratio))
            } else {
                let curvature = w * step * step;
                let peak = (1..BLOCK).fold(exponent, |m, j| {
                    let j = j as f32;
                    m.max(exponent + j * log_ratio - curvature * j * (j - 1.0))
                });
                if peak < -69.1 {
                    (0.0, 0.0)
                } else {
                    (-1.0, 0.0)
                }
            };
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

/// ‖o + t d − x‖² and dᵀ(o + t d − x).
fn offset_on_line<const N: usize>(
    origin: &Vector<N>,
    direction: &Vector<N>,
    t: f32,
    x: &Vector<N>,
) -> (f32, f32) {
    let (mut d2, mut along) = (0.0, 0.0);
    // Through slices: nalgebra's iterators over a vector cost about five times as many
    // instructions per entry in the firmware's size-optimised build.
    let (origin, x, direction) = (origin.as_slice(), x.as_slice(), direction.as_slice());
    for ((o, x), d) in origin.iter().zip(x).zip(direction) {
        let offset = o + t * d - x;
        d2 += offset * offset;
        along += d * offset;
    }
    (d2, along)
}

/// ‖a − b‖², through slices (see [`offset_on_line`]).
fn distance2<const N: usize>(a: &Vector<N>, b: &Vector<N>) -> f32 {
    let mut sum = 0.0;
    for (a, b) in a.as_slice().iter().zip(b.as_slice()) {
        sum += (a - b) * (a - b);
    }
    sum
}

/// x ← L⁻¹x on the first `n` entries of `x`, for the row-stored factor whose rows 0..n
/// start at multiples of M in `rows` (forward substitution, each row's sum a contiguous
/// [`dot`]).
fn forward<const M: usize>(rows: &[f32], x: &mut [f32], n: usize) {
    for (i, row) in rows.chunks_exact(M).enumerate().take(n) {
        let Some((solved, rest)) = x.split_at_mut_checked(i) else {
            return;
        };
        let (Some(xi), Some((left, diagonal))) = (rest.first_mut(), row.split_at_checked(i)) else {
            return;
        };
        *xi = (*xi - dot(left, solved)) / diagonal.first().copied().unwrap_or(1.0);
    }
}

/// x ← L⁻ᵀx on the first `n` entries (back substitution, column by column of Lᵀ: each step
/// subtracts a multiple of one contiguous row of L).
fn backward<const M: usize>(rows: &[f32], x: &mut [f32], n: usize) {
    // By index rather than a reversed `chunks_exact`, whose `nth_back` keeps a panic path.
    for k in (0..n).rev() {
        let (start, diagonal) = (k * M, rows.get(k * M + k).copied().unwrap_or(1.0));
        let (Some(left), Some((head, tail))) =
            (rows.get(start..start + k), x.split_at_mut_checked(k))
        else {
            return;
        };
        let Some(xk) = tail.first_mut() else { return };
        *xk /= diagonal;
        let v = *xk;
        for (h, l) in head.iter_mut().zip(left) {
            *h -= l * v;
        }
    }
}

/// The first `n` entries of `v` (all of them if `n` is larger).
fn live<const M: usize>(v: &SVector<f32, M>, n: usize) -> &[f32] {
    let all = v.as_slice();
    all.get(..n).unwrap_or(all)
}

/// aᵀb over the shorter of the two (of one length here), in four interleaved partial
/// sums, so that the firmware's size-optimised build keeps them in registers (a loop over
/// an array of sums there loads and stores each one per term: about 11 instructions per
/// multiply-add against 4).
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let ((quads_a, rest_a), (quads_b, rest_b)) = (a.as_chunks::<4>(), b.as_chunks::<4>());
    let (mut s0, mut s1, mut s2, mut s3) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for ([a0, a1, a2, a3], [b0, b1, b2, b3]) in quads_a.iter().zip(quads_b) {
        s0 += a0 * b0;
        s1 += a1 * b1;
        s2 += a2 * b2;
        s3 += a3 * b3;
    }
    let mut sum = (s0 + s2) + (s1 + s3);
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

    /// The posterior on a 64-point grid of the line o + t d, t = t₀ + gΔ, the way the
    /// model computed it before the factor was stored by rows: every kernel value by
    /// `expf`, the kernel matrix of the points held refactored from scratch
    /// (column-major, `cholesky_in_place`, as after every eviction), the forward
    /// substitution row by row through the column-major storage.
    fn reference_posterior<const N: usize, const M: usize>(
        gp: &Gp<N, M>,
        kern: &Kernel,
        line: (&Vector<N>, &Vector<N>, f32, f32),
    ) -> [(f32, f32); 64] {
        use crate::optimizer::cholesky::{cholesky_in_place, solve_lower};
        let (o, d, t0, step) = line;
        let n = gp.len();
        let mut big = SMatrix::<f32, M, M>::zeros();
        for i in 0..n {
            for j in 0..=i {
                let d2 = (gp.points[i] - gp.points[j]).norm_squared();
                big[(i, j)] = kern.at(d2) + if i == j { kern.noise } else { 0.0 };
            }
        }
        cholesky_in_place(&mut big, n, Some(kern.noise));
        let mut alpha = gp.residuals;
        solve_lower(&big, &mut alpha, n);
        for i in (0..n).rev() {
            let v = (i + 1..n).map(|k| big[(k, i)] * alpha[k]).sum::<f32>();
            alpha[i] = (alpha[i] - v) / big[(i, i)];
        }
        core::array::from_fn(|g| {
            let x = o + d * (t0 + g as f32 * step);
            let mut k = gp.kernel_column(&x, kern);
            let mean = gp.prior() + (0..n).map(|i| k[i] * alpha[i]).sum::<f32>();
            solve_lower(&big, &mut k, n);
            let var = kern.signal - (0..n).map(|i| k[i] * k[i]).sum::<f32>();
            (mean, var.max(0.0))
        })
    }

    /// Checks, on random data (fixed seed): 18-D points in [−1, 1]¹⁸ with costs of a
    /// random quadratic plus noise, M = 64, 100 episodes (36 evictions by the rank-one
    /// update), the kernel of the firmware benchmark (σ_f = 3, σ_n = 5 % of it, ℓ = 0.15
    /// of the box) and a longer one (ℓ = 0.3): after every append from the 20th on, the
    /// posterior mean and variance on a random line's 64-point grid, computed as the model
    /// does (factor kept up to date, kernel columns by [`Sweep`]), equal the reference
    /// computation of before within 10⁻⁵ σ_f on the mean and 10⁻⁵ σ_f² on the variance
    /// (f32 rounding through a factor whose condition number reaches n σ_f² / σ_n² ≈
    /// 2.5·10⁴; about 3·10⁻⁷ is seen).
    /// The largest differences seen are printed.
    #[test]
    fn posterior_equals_the_refactored_one_on_random_data() {
        extern crate std;
        use crate::random::unit_f32;
        let mut r = crate::testing::rng(7);
        for length in [0.15f32, 0.3] {
            let sigma = 3.0f32;
            let noise = 0.05 * sigma;
            let width = 2.0 * length;
            let kern = Kernel {
                signal: sigma * sigma,
                inverse_width: 1.0 / (2.0 * width * width),
                noise: noise * noise + 1e-4 * sigma * sigma,
            };
            let centre = Vector::<18>::from_fn(|_, _| 0.5 * (2.0 * unit_f32(&mut r) - 1.0));
            let mut gp = Gp::<18, 64>::EMPTY;
            let (mut worst_mean, mut worst_var) = (0.0f32, 0.0f32);
            for episode in 0..100 {
                // Points clustered around a moving origin, as the search makes them.
                let around = centre * (episode as f32 / 100.0);
                let x = Vector::<18>::from_fn(|i, _| {
                    (around[i] + 0.6 * (2.0 * unit_f32(&mut r) - 1.0)).clamp(-1.0, 1.0)
                });
                let y = 4.0 * (x - centre).norm_squared() + noise * (unit_f32(&mut r) - 0.5);
                gp.append(&x, y, &kern, &around);
                if episode < 20 {
                    continue;
                }
                let mut d = crate::random::normal_vector_f32::<18, _>(&mut r);
                d /= d.norm();
                let (t0, step) = (-1.0 + 0.01 * unit_f32(&mut r), 2.0 / 64.0);
                let old = reference_posterior(&gp, &kern, (&around, &d, t0, step));
                let (mut carry, mut ratio) = (SVector::zeros(), SVector::zeros());
                let mut sweep = Sweep::new(step, &kern, &mut carry, &mut ratio);
                let mut k = SVector::<f32, 64>::zeros();
                for (g, (m0, v0)) in old.iter().enumerate() {
                    let t = t0 + g as f32 * step;
                    gp.sweep_column((&around, &d), t, g, &kern, &mut sweep, &mut k);
                    let (m1, v1) = gp.posterior(&mut k, &kern);
                    worst_mean = worst_mean.max((m1 - m0).abs() / sigma);
                    worst_var = worst_var.max((v1 - v0).abs() / (sigma * sigma));
                }
            }
            std::println!(
                "ℓ = {length}: mean within {worst_mean:e} σ_f, variance {worst_var:e} σ_f²"
            );
            assert!(
                worst_mean < 1e-5 && worst_var < 1e-5,
                "{worst_mean} {worst_var}"
            );
        }
    }

    /// Checks, on random lines through random points (fixed seed), for length scales from
    /// 0.02 to 10 of the box: every kernel value of a [`Sweep`] along a 64-point grid
    /// equals the exact kernel (computed in f64) within f32's rounding of what the sweep
    /// computes: a relative ε each for its 2·[`BLOCK`] + 4 products and `expf`s, and 8ε
    /// times the size of each exponent it rounds (the block start's w‖o + t d − x‖², j
    /// times |ln r| and wΔ² j(j − 1): an exponent rounded by a few ε of its size moves
    /// exp by that much), plus 10⁻³⁰ σ_f² for values f32 cannot hold relative to σ_f².
    #[test]
    fn sweep_columns_equal_the_kernel() {
        use crate::random::unit_f32;
        let mut r = crate::testing::rng(11);
        let mut gp = Gp::<5, 16>::EMPTY;
        let flat = Kernel {
            signal: 1.0,
            inverse_width: 1.0,
            noise: 0.1,
        };
        for _ in 0..16 {
            let x = Vector::<5>::from_fn(|_, _| 2.0 * unit_f32(&mut r) - 1.0);
            gp.append(&x, unit_f32(&mut r), &flat, &x);
        }
        for length in [0.02f32, 0.05, 0.15, 0.25, 1.0, 10.0] {
            let kern = Kernel {
                signal: 2.5,
                inverse_width: 1.0 / (2.0 * 4.0 * length * length),
                noise: 0.1,
            };
            for _ in 0..20 {
                let o = Vector::<5>::from_fn(|_, _| 2.0 * unit_f32(&mut r) - 1.0);
                let mut d = crate::random::normal_vector_f32::<5, _>(&mut r);
                d /= d.norm();
                let (t0, step) = (-2.0 * unit_f32(&mut r), 4.0 * unit_f32(&mut r) / 64.0);
                let (mut carry, mut ratio) = (SVector::zeros(), SVector::zeros());
                let mut sweep = Sweep::new(step, &kern, &mut carry, &mut ratio);
                let mut k = SVector::<f32, 16>::zeros();
                for g in 0..64 {
                    let t = t0 + g as f32 * step;
                    gp.sweep_column((&o, &d), t, g, &kern, &mut sweep, &mut k);
                    for (i, p) in gp.points.iter().enumerate() {
                        let d2: f64 = (0..5)
                            .map(|c| {
                                let v = f64::from(o[c]) + f64::from(t) * f64::from(d[c])
                                    - f64::from(p[c]);
                                v * v
                            })
                            .sum();
                        let exact = 2.5 * (-d2 * f64::from(kern.inverse_width)).exp();
                        let error = (f64::from(k[i]) - exact).abs();
                        // The exponents the sweep rounds: w‖o + t_{g₀} d − x‖² at the
                        // block's start g₀ = g − j, j·|ln r| and wΔ² j(j − 1).
                        let (j, w) = ((g % BLOCK) as f64, f64::from(kern.inverse_width));
                        let anchor = f64::from(t0) + (g as f64 - j) * f64::from(step);
                        let (mut d0, mut s0) = (0.0, 0.0);
                        for c in 0..5 {
                            let v = f64::from(o[c]) + anchor * f64::from(d[c]) - f64::from(p[c]);
                            (d0, s0) = (d0 + v * v, s0 + f64::from(d[c]) * v);
                        }
                        let h = f64::from(step);
                        let exponents =
                            w * d0 + j * (w * h * (2.0 * s0 + h)).abs() + w * h * h * j * j;
                        let epsilon = f64::from(f32::EPSILON);
                        assert!(
                            error
                                <= (2.0 * BLOCK as f64 + 4.0 + 8.0 * exponents) * epsilon * exact
                                    + 2.5e-30,
                            "ℓ {length} g {g} i {i}: {} vs {exact}",
                            k[i]
                        );
                    }
                }
            }
        }
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
