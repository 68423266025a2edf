//! The symmetric eigendecomposition of CMA-ES's covariance by cyclic Jacobi rotations,
//! warm-started in the previous eigenbasis (Golub and Van Loan, "Matrix Computations",
//! section 8.5, the cyclic Jacobi method; the rotation as in Press et al., "Numerical
//! Recipes", section 11.1).
//!
//! Why Jacobi rather than nalgebra's QR iteration: between two decompositions C changes by
//! the small rank-μ and rank-one updates of one generation (c₁ + c_μ ≈ 0.015 at n = 18), so
//! in the old basis B the matrix Bᵀ C B is already nearly diagonal and a few sweeps finish
//! it. And this code has no panic path: every index is a loop variable below N, which the
//! compiler proves, where nalgebra's decomposition kept four panic sites in the firmware.
//! The eigenvectors come out as B·J₁·J₂·… (the rotations applied to B's columns); one
//! Gram–Schmidt pass before each decomposition keeps that product from drifting away from
//! orthonormal over many warm starts.

use nalgebra::SMatrix;

use crate::Vector;
use crate::vector::unrolled;

/// Sweeps before giving up on full convergence (the result is used anyway: it is C's
/// decomposition up to the off-diagonal rest, which only shrinks with each sweep).
const MAX_SWEEPS: usize = 24;

/// λ with C = B' diag(λ) B'ᵀ, where B' replaces `basis` (on entry orthonormal columns, the
/// previous eigenvectors or the identity; rotated in place, which spares a 1.3 KB copy on
/// the stack at N = 18). The eigenvalues are in no particular order; column j of B' belongs
/// to λ_j. `None` if anything turns non-finite; `basis` is then not usable.
pub(super) fn symmetric_eigen<const N: usize>(
    covariance: &SMatrix<f32, N, N>,
    basis: &mut SMatrix<f32, N, N>,
) -> Option<Vector<N>> {
    // Rounding in the rotations leaves B orthonormal only to a few units of rounding per
    // decomposition; warm start after warm start that would add up, and Bᵀ C B would no
    // longer be a similarity. So B is re-orthonormalised first (its columns are nearly
    // orthonormal, so one Gram–Schmidt pass suffices). V starts as B, A = Bᵀ C B is stored
    // by columns (a[j][i] = A_ij, only i ≤ j used).
    if !orthonormalise(&mut basis.data.0) {
        basis.fill_with_identity();
    }
    let v: &mut [[f32; N]; N] = &mut basis.data.0;
    // Written by `in_basis` (its upper triangle, all that is read) rather than returned,
    // which would copy it.
    let mut a = [[0.0; N]; N];
    in_basis(&covariance.data.0, v, &mut a);
    for _ in 0..MAX_SWEEPS {
        let mut rotated_any = false;
        for p in 0..N {
            for q in p + 1..N {
                if rotate(&mut a, v, p, q) {
                    rotated_any = true;
                }
            }
        }
        if !rotated_any {
            break;
        }
    }
    let values = Vector::<N>::from_fn(|j, _| a[j][j]);
    let finite = values
        .iter()
        .chain(v.iter().flatten())
        .all(|x| x.is_finite());
    finite.then_some(values)
}

/// Modified Gram–Schmidt on the columns of `v`, in place; `false` if a column vanishes (or
/// turns non-finite) on the way.
fn orthonormalise<const N: usize>(v: &mut [[f32; N]; N]) -> bool {
    for j in 0..N {
        let (done, rest) = v.split_at_mut(j);
        let Some(v_j) = rest.first_mut() else {
            return false;
        };
        for v_i in done.iter() {
            let mut dot = 0.0;
            unrolled::<N>(|k| dot += v_i[k] * v_j[k]);
            unrolled::<N>(|k| v_j[k] -= dot * v_i[k]);
        }
        let mut norm_squared = 0.0;
        unrolled::<N>(|k| norm_squared += v_j[k] * v_j[k]);
        let norm = libm::sqrtf(norm_squared);
        if !(norm.is_finite() && norm > 0.0) {
            return false;
        }
        unrolled::<N>(|k| v_j[k] /= norm);
    }
    true
}

/// A = Bᵀ C B from C (symmetric) and B, both by columns, into `a`, by columns too
/// (a[j][i] = A_ij). The columns of C B are sums of C's columns (C b_j = Σ_k B_kj c_k), so
/// every inner loop runs over contiguous memory, in straight-line code for N ≤ 32. Only
/// the upper triangle (i ≤ j) is computed: the rotations read nothing else.
fn in_basis<const N: usize>(c: &[[f32; N]; N], b: &[[f32; N]; N], a: &mut [[f32; N]; N]) {
    for (j, (b_j, a_j)) in b.iter().zip(a.iter_mut()).enumerate() {
        let mut m_j = [0.0f32; N];
        for (c_k, &b_kj) in c.iter().zip(b_j) {
            unrolled::<N>(|i| m_j[i] += c_k[i] * b_kj);
        }
        for (b_i, a_ij) in b.iter().zip(a_j.iter_mut()).take(j + 1) {
            let mut dot = 0.0;
            unrolled::<N>(|k| dot += b_i[k] * m_j[k]);
            *a_ij = dot;
        }
    }
}

/// One Jacobi rotation in the (p, q) plane, p < q < N, that zeroes A_pq: A ← Jᵀ A J and
/// V ← V J. `false` (nothing done) when A_pq is already negligible: below one unit of
/// rounding of the geometric mean of the two diagonal entries, or zero.
///
/// No square root on the common path: libm's `sqrtf` is software on a Cortex-M4F (about a
/// hundred instructions) and Rust's `core` does not reach the FPU's `vsqrt`.
// k indexes two columns of `a` at once, one of them mutably: no iterator expresses that.
#[allow(clippy::needless_range_loop)]
fn rotate<const N: usize>(
    a: &mut [[f32; N]; N],
    v: &mut [[f32; N]; N],
    p: usize,
    q: usize,
) -> bool {
    if !(p < q && q < N) {
        return false;
    }
    let (a_pq, a_pp, a_qq) = (a[q][p], a[p][p], a[q][q]);
    // Rotate only if |A_pq| > ε √|A_pp A_qq| (squared); never on NaN (the caller's
    // finiteness check catches it).
    let (size, limit) = (
        a_pq * a_pq,
        f32::EPSILON * f32::EPSILON * (a_pp * a_qq).abs(),
    );
    if size.is_nan() || limit.is_nan() || size <= limit {
        return false;
    }
    let (t, c) = rotation(a_qq - a_pp, a_pq);
    let s = t * c;
    // The 2 × 2 block: A_pp − t A_pq, A_qq + t A_pq, and A_pq = 0 (exactly, in exact
    // arithmetic; set so, as the method assumes).
    a[p][p] = a_pp - t * a_pq;
    a[q][q] = a_qq + t * a_pq;
    a[q][p] = 0.0;
    // The rest of rows and columns p and q: x_p ← c x_p − s x_q, x_q ← s x_p + c x_q for
    // x = A_kp, A_kq (k ≠ p, q). Only the upper triangle is read and kept (A_ij in
    // a[j][i], i < j), so the three ranges of k address A_kp and A_kq differently.
    let turn = |x_p: f32, x_q: f32| (c * x_p - s * x_q, s * x_p + c * x_q);
    for k in 0..p {
        (a[p][k], a[q][k]) = turn(a[p][k], a[q][k]);
    }
    for k in p + 1..q {
        (a[k][p], a[q][k]) = turn(a[k][p], a[q][k]);
    }
    for k in q + 1..N {
        (a[k][p], a[k][q]) = turn(a[k][p], a[k][q]);
    }
    // Columns p and q of V.
    let (left, right) = v.split_at_mut(q);
    if let (Some(col_p), Some(col_q)) = (left.get_mut(p), right.first_mut()) {
        for (x_p, x_q) in col_p.iter_mut().zip(col_q.iter_mut()) {
            (*x_p, *x_q) = turn(*x_p, *x_q);
        }
    }
    true
}

/// (t, c) = (tan φ, cos φ) of the rotation that zeroes the off-diagonal entry `off` of a
/// 2 × 2 symmetric block whose diagonal differs by `gap` = A_qq − A_pp: cot 2φ = θ =
/// gap / (2 off), t the root of t² + 2θt − 1 = 0 of smaller magnitude (|φ| ≤ π/4).
fn rotation(gap: f32, off: f32) -> (f32, f32) {
    let theta = gap / (2.0 * off);
    let size = theta.abs();
    let (t, c) = if size >= 16.0 {
        // √(θ² + 1) = |θ| (1 + 1/(2θ²) − 1/(8θ⁴) + …) and c = 1/√(1 + t²) = 1 − t²/2 +
        // 3t⁴/8 − …: for |θ| ≥ 16 the first terms left out are below f32's rounding (the
        // common case once the basis is close: a generation changes C little).
        let inverse = 1.0 / size;
        let u = inverse * inverse;
        let t = inverse / (2.0 + u * (0.5 - 0.125 * u));
        let tt = t * t;
        (t, 1.0 + tt * (-0.5 + 0.375 * tt))
    } else {
        let t = 1.0 / (size + libm::sqrtf(theta * theta + 1.0));
        (t, 1.0 / libm::sqrtf(t * t + 1.0))
    };
    (if theta < 0.0 { -t } else { t }, c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// (B', λ) from C and a starting basis, the basis left as it was.
    fn eig<const N: usize>(
        c: &SMatrix<f32, N, N>,
        basis: &SMatrix<f32, N, N>,
    ) -> Option<(SMatrix<f32, N, N>, Vector<N>)> {
        let mut b = *basis;
        symmetric_eigen(c, &mut b).map(|values| (b, values))
    }

    /// ‖C − B diag(λ) Bᵀ‖_max and ‖BᵀB − I‖_max.
    fn errors<const N: usize>(
        c: &SMatrix<f32, N, N>,
        b: &SMatrix<f32, N, N>,
        values: &Vector<N>,
    ) -> (f32, f32) {
        let rebuilt = b * SMatrix::from_diagonal(values) * b.transpose();
        let orthogonality = b.transpose() * b - SMatrix::<f32, N, N>::identity();
        ((c - rebuilt).amax(), orthogonality.amax())
    }

    #[test]
    fn a_diagonal_matrix_needs_no_rotation() {
        let c = SMatrix::<f32, 3, 3>::from_diagonal(&Vector::<3>::new(3.0, 1.0, 2.0));
        let (b, values) = eig(&c, &SMatrix::identity()).unwrap();
        assert_eq!(b, SMatrix::<f32, 3, 3>::identity());
        assert_eq!(values, Vector::<3>::new(3.0, 1.0, 2.0));
    }

    #[test]
    fn a_two_by_two_rotation_is_exact() {
        // Checks: [[2, 1], [1, 2]] has eigenvalues 1 and 3 along (1, −1)/√2 and (1, 1)/√2.
        let c = SMatrix::<f32, 2, 2>::new(2.0, 1.0, 1.0, 2.0);
        let (b, values) = eig(&c, &SMatrix::identity()).unwrap();
        let mut sorted = [values[0], values[1]];
        sorted.sort_by(f32::total_cmp);
        assert!((sorted[0] - 1.0).abs() < 1e-6 && (sorted[1] - 3.0).abs() < 1e-6);
        let (rebuilt, orthogonality) = errors(&c, &b, &values);
        assert!(rebuilt < 1e-6 && orthogonality < 1e-6);
    }

    #[test]
    fn non_finite_entries_give_none() {
        let mut c = SMatrix::<f32, 3, 3>::identity();
        c[(0, 1)] = f32::NAN;
        c[(1, 0)] = f32::NAN;
        assert_eq!(eig(&c, &SMatrix::identity()), None);
    }

    #[test]
    fn warm_starts_keep_the_basis_orthonormal() {
        // Checks: 400 decompositions in a row, each warm-started from the last basis, of a C
        // that changes by a rank-one update of weight 0.015 each time (as a generation of
        // CMA-ES at n = 18 does), keep BᵀB = I to 1e-5 and rebuild C to 1e-5 relative.
        // Without re-orthonormalising B, rounding builds up and both fail.
        use rand_core::SeedableRng;
        let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(9);
        let mut c = SMatrix::<f32, 18, 18>::identity();
        let mut b = SMatrix::<f32, 18, 18>::identity();
        for generation in 0..400 {
            let y = crate::random::normal_vector_f32::<18, _>(&mut rng);
            c = c * 0.985 + y * y.transpose() * 0.015;
            let (basis, values) = eig(&c, &b).unwrap();
            let (rebuilt, orthogonality) = errors(&c, &basis, &values);
            assert!(
                orthogonality <= 1e-5,
                "generation {generation}: {orthogonality}"
            );
            assert!(
                rebuilt <= 1e-5 * c.amax(),
                "generation {generation}: {rebuilt}"
            );
            b = basis;
        }
    }

    proptest! {
        /// Checks: for random symmetric positive semi-definite 18 × 18 matrices G Gᵀ (entries
        /// of G in [−1, 1]), from the identity and warm-started from a perturbed basis, the
        /// decomposition rebuilds C to 2e-5 of its largest entry with orthonormal
        /// eigenvectors (to 1e-5), and it agrees with nalgebra's eigenvalues (f64) to 1e-4
        /// of the largest.
        #[test]
        fn rebuilds_random_covariances(
            g in prop::collection::vec(-1.0f32..1.0, 18 * 18),
        ) {
            let g = SMatrix::<f32, 18, 18>::from_column_slice(&g);
            let c = g * g.transpose();
            let (b, values) = eig(&c, &SMatrix::identity()).unwrap();
            let (rebuilt, orthogonality) = errors(&c, &b, &values);
            prop_assert!(rebuilt <= 2e-5 * c.amax(), "{rebuilt}");
            prop_assert!(orthogonality <= 1e-5, "{orthogonality}");
            // Warm start: the eigenbasis of a nearby matrix (one generation's change).
            let nearby = c * 0.985 + g.column(0) * g.column(0).transpose() * 0.015;
            let (b2, values2) = eig(&nearby, &b).unwrap();
            let (rebuilt, orthogonality) = errors(&nearby, &b2, &values2);
            prop_assert!(rebuilt <= 2e-5 * nearby.amax(), "{rebuilt}");
            prop_assert!(orthogonality <= 1e-5, "{orthogonality}");
            let mut ours: std::vec::Vec<f64> = values2.iter().map(|&x| f64::from(x)).collect();
            let mut theirs: std::vec::Vec<f64> =
                nearby.map(f64::from).symmetric_eigenvalues().iter().copied().collect();
            ours.sort_by(f64::total_cmp);
            theirs.sort_by(f64::total_cmp);
            let largest = theirs.last().copied().unwrap_or(1.0);
            for (x, y) in ours.iter().zip(&theirs) {
                prop_assert!((x - y).abs() <= 1e-4 * largest, "{x} vs {y}");
            }
        }
    }
}
