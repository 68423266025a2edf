//! The Cholesky factorisation and the triangular solves of ROCK* and of the line search's
//! Gaussian process, on the leading `n × n` block of a fixed-size matrix (a GP holds a
//! varying number of points in a matrix sized for its capacity).
//!
//! Written out rather than taken from nalgebra's decompositions, whose panic sites LLVM does
//! not always remove (see [`Cmaes`](super::Cmaes)), and because nalgebra's `Cholesky` of
//! a block of run-time size needs a heap matrix. Every index is below `n.min(M)` by the
//! loop bounds, so no bounds check can fail.

use nalgebra::{SMatrix, SVector};

/// Overwrites the lower triangle of the leading `n × n` block of the symmetric `m` (only
/// that triangle is read) with L, L Lᵀ = m.
///
/// A pivot that is not positive and finite means `m` is not numerically positive definite:
/// with `floor` `None` the factorisation stops there and answers `false` (`m` then partly
/// overwritten); with `Some(f)` the pivot is replaced by `f` (the factor of a nearby
/// positive-definite matrix, as nalgebra's `Cholesky::new_with_substitute`) and the answer
/// is `false` too, with a complete factor.
pub(crate) fn cholesky_in_place<const M: usize>(
    m: &mut SMatrix<f32, M, M>,
    n: usize,
    floor: Option<f32>,
) -> bool {
    let n = n.min(M);
    let mut exact = true;
    for j in 0..n {
        let mut pivot = m[(j, j)];
        for k in 0..j {
            pivot -= m[(j, k)] * m[(j, k)];
        }
        if !(pivot > 0.0 && pivot.is_finite()) {
            exact = false;
            match floor {
                Some(f) => pivot = f,
                None => return false,
            }
        }
        let diagonal = libm::sqrtf(pivot);
        m[(j, j)] = diagonal;
        for i in j + 1..n {
            let mut v = m[(i, j)];
            for k in 0..j {
                v -= m[(i, k)] * m[(j, k)];
            }
            m[(i, j)] = v / diagonal;
        }
    }
    exact
}

/// x ← L⁻¹ x on the first `n` entries, for the lower triangle L of the leading `n × n`
/// block of `l` (positive diagonal), by forward substitution.
pub(crate) fn solve_lower<const M: usize>(
    l: &SMatrix<f32, M, M>,
    x: &mut SVector<f32, M>,
    n: usize,
) {
    for i in 0..n.min(M) {
        let mut v = x[i];
        for k in 0..i {
            v -= l[(i, k)] * x[k];
        }
        x[i] = v / l[(i, i)];
    }
}

/// x ← L⁻ᵀ x on the first `n` entries (as [`solve_lower`], by back substitution).
pub(crate) fn solve_lower_transposed<const M: usize>(
    l: &SMatrix<f32, M, M>,
    x: &mut SVector<f32, M>,
    n: usize,
) {
    let n = n.min(M);
    for i in (0..n).rev() {
        let mut v = x[i];
        for k in i + 1..n {
            v -= l[(k, i)] * x[k];
        }
        x[i] = v / l[(i, i)];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks, on a 3 × 3 positive-definite block inside a 5 × 5 matrix: L Lᵀ reproduces
    /// the block, L⁻¹ and L⁻ᵀ invert it, the entries outside the block are untouched, and a
    /// singular block fails without a floor and is completed with one.
    #[test]
    fn factor_and_solves_on_the_leading_block() {
        let a = SMatrix::<f32, 3, 3>::new(4.0, 2.0, 0.4, 2.0, 3.0, 0.5, 0.4, 0.5, 2.0);
        let mut m = SMatrix::<f32, 5, 5>::repeat(7.0);
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&a);
        assert!(cholesky_in_place(&mut m, 3, None));
        let l = m.fixed_view::<3, 3>(0, 0).lower_triangle();
        assert!((l * l.transpose() - a).abs().max() < 1e-5);
        assert_eq!(m[(3, 3)], 7.0);
        let mut x = SVector::<f32, 5>::new(1.0, -2.0, 0.5, 9.0, 9.0);
        let b = x;
        solve_lower(&m, &mut x, 3);
        solve_lower_transposed(&m, &mut x, 3);
        let ax = a * x.fixed_rows::<3>(0);
        assert!((ax - b.fixed_rows::<3>(0)).abs().max() < 1e-5);
        assert_eq!((x[3], x[4]), (9.0, 9.0));

        let mut singular = SMatrix::<f32, 2, 2>::repeat(1.0);
        assert!(!cholesky_in_place(&mut singular.clone(), 2, None));
        assert!(!cholesky_in_place(&mut singular, 2, Some(1e-4)));
        assert_eq!(singular[(1, 1)], 1e-2);
    }
}
