//! The Cholesky factorisation and the forward substitution of ROCK*, on the leading `n × n`
//! block of a fixed-size matrix (a model that holds a varying number of points in a matrix
//! sized for its capacity). LineBO's Gaussian process keeps its factor by rows and has
//! its own (`line_bo/gp.rs`).
//!
//! Written out rather than taken from nalgebra's decompositions, whose panic sites LLVM does
//! not always remove (see [`Cmaes`](super::Cmaes)), and because nalgebra's `Cholesky` of
//! a block of run-time size needs a heap matrix. Every index is below `n.min(M)` by the
//! loop bounds; the loops still read through slices, `get` and iterators, so that no
//! bounds check is left for the compiler to prove wherever they are inlined (the
//! firmware's panic-freedom proof).

use nalgebra::{SMatrix, SVector};

/// Overwrites the lower triangle of the leading `n × n` block of the symmetric `m` (only
/// that triangle is read) with L, L Lᵀ = m.
///
/// A pivot that is not positive and finite means `m` is not numerically positive definite:
/// with `floor` `None` the factorisation stops there and answers `false` (`m` then partly
/// overwritten); with `Some(f)` the pivot is replaced by `f` (the factor of a nearby
/// positive-definite matrix, as nalgebra's `Cholesky::new_with_substitute`) and the answer
/// is `false` too, with a complete factor.
///
/// On the column-major storage, entry (i, k) at `i + k·M`, read through `get` and
/// iterators: the loops stay free of bounds checks and panic paths wherever the compiler
/// inlines them (the firmware's panic-freedom proof), in the same order of operations as
/// the textbook loops.
pub(crate) fn cholesky_in_place<const M: usize>(
    m: &mut SMatrix<f32, M, M>,
    n: usize,
    floor: Option<f32>,
) -> bool {
    let n = n.min(M);
    let a = m.as_mut_slice();
    let mut exact = true;
    for j in 0..n {
        // Row j left of the diagonal: (j, 0), (j, 1), …, (j, j − 1).
        let row_j = |a: &[f32]| -> f32 {
            let mut sum = a.get(j + j * M).copied().unwrap_or(0.0);
            for v in a.get(j..).unwrap_or(&[]).iter().step_by(M).take(j) {
                sum -= v * v;
            }
            sum
        };
        let mut pivot = row_j(a);
        if !(pivot > 0.0 && pivot.is_finite()) {
            exact = false;
            match floor {
                Some(f) => pivot = f,
                None => return false,
            }
        }
        let diagonal = libm::sqrtf(pivot);
        if let Some(d) = a.get_mut(j + j * M) {
            *d = diagonal;
        }
        for i in j + 1..n {
            let mut v = a.get(i + j * M).copied().unwrap_or(0.0);
            let row_i = a.get(i..).unwrap_or(&[]).iter().step_by(M);
            let row_j = a.get(j..).unwrap_or(&[]).iter().step_by(M);
            for (x, y) in row_i.zip(row_j).take(j) {
                v -= x * y;
            }
            if let Some(e) = a.get_mut(i + j * M) {
                *e = v / diagonal;
            }
        }
    }
    exact
}

/// x ← L⁻¹ x on the first `n` entries, for the lower triangle L of the leading `n × n`
/// block of `l` (positive diagonal), by forward substitution (row by row, as the textbook
/// loop; slices and iterators as in [`cholesky_in_place`]).
pub(crate) fn solve_lower<const M: usize>(
    l: &SMatrix<f32, M, M>,
    x: &mut SVector<f32, M>,
    n: usize,
) {
    let a = l.as_slice();
    let x = x.as_mut_slice();
    for i in 0..n.min(M) {
        let Some((solved, rest)) = x.split_at_mut_checked(i) else {
            return;
        };
        let Some(xi) = rest.first_mut() else { return };
        let mut v = *xi;
        let row = a.get(i..).unwrap_or(&[]).iter().step_by(M);
        for (l, x) in row.zip(solved.iter()) {
            v -= l * x;
        }
        *xi = v / a.get(i + i * M).copied().unwrap_or(1.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks, on a 3 × 3 positive-definite block inside a 5 × 5 matrix: L Lᵀ reproduces
    /// the block, L⁻¹ inverts L, the entries outside the block are untouched, and a
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
        let lx = l * x.fixed_rows::<3>(0);
        assert!((lx - b.fixed_rows::<3>(0)).abs().max() < 1e-5);
        assert_eq!((x[3], x[4]), (9.0, 9.0));

        let mut singular = SMatrix::<f32, 2, 2>::repeat(1.0);
        assert!(!cholesky_in_place(&mut singular.clone(), 2, None));
        assert!(!cholesky_in_place(&mut singular, 2, Some(1e-4)));
        assert_eq!(singular[(1, 1)], 1e-2);
    }
}
