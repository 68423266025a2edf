//! The parameter vector θ, shared by the optimizers (which propose it) and the controllers
//! (which apply it).

use nalgebra::{ArrayStorage, SMatrix, SVector};

/// A parameter vector θ ∈ R^N in the on-target number type (`f32`: the Cortex-M4F FPU is
/// single precision, `f64` would be emulated in software).
pub type Vector<const N: usize> = SVector<f32, N>;

/// The zero vector, usable in constants (`Vector::zeros` is not a `const fn`): the empty
/// entries of a constant such as SRACOS's empty archive, which is copied into place rather
/// than assembled on the stack. (A repeat expression `[const { zero() }; M]` inside a
/// constructor is still built on the stack and copied, measured on CRS; a constant is not.)
pub(crate) const fn zero<const N: usize>() -> Vector<N> {
    SVector::from_array_storage(ArrayStorage([[0.0; N]; 1]))
}

/// The N × N identity at compile time, for the same reason as [`zero`]: as a constant
/// (`const { identity() }`) it is copied into place, where `SMatrix::identity()` in a
/// constructor is assembled on the stack first and then moved in.
pub(crate) const fn identity<const N: usize>() -> SMatrix<f32, N, N> {
    let mut columns = [[0.0; N]; N];
    let mut j = 0;
    while j < N {
        columns[j][j] = 1.0;
        j += 1;
    }
    SMatrix::from_array_storage(ArrayStorage(columns))
}

/// M v, column by column (y = Σ_j m_j v_j): `m * v` with `m` a matrix held by value (a
/// field of a `Copy` type) copies it onto the stack first (1.3 KB at N = 18, 3.8 KB at
/// N = 31) before multiplying.
/// Inlined, so that the product is written straight into the caller's vector (a call
/// returns it through a temporary of its own).
#[inline(always)]
pub(crate) fn times<const N: usize>(m: &SMatrix<f32, N, N>, v: &Vector<N>) -> Vector<N> {
    let mut y = Vector::<N>::zeros();
    times_into(m, v, &mut y);
    y
}

/// y ← M v, as [`times`] but into the caller's `y` (no vector returned on the stack).
pub(crate) fn times_into<const N: usize>(m: &SMatrix<f32, N, N>, v: &Vector<N>, y: &mut Vector<N>) {
    y.fill(0.0);
    for (m_j, v_j) in m.column_iter().zip(v.iter()) {
        unrolled::<N>(|i| y[i] += m_j[i] * v_j);
    }
}

/// Calls `body(i)` for every i in 0..N, in order, as straight-line code when N ≤ 32.
///
/// Firmware ships at opt-level "s", where LLVM keeps short loops rolled: the policy
/// correction's 18 multiply-adds cost 310 instructions there as loops (counter, bounds,
/// iterator state per term) against 85 unrolled. Each of the 32 calls below is guarded
/// by a comparison of two constants, which the compiler folds away, so exactly N calls remain
/// with constant indices (their bounds checks fold too). Beyond 32 it is an ordinary loop.
#[inline(always)]
pub(crate) fn unrolled<const N: usize>(mut body: impl FnMut(usize)) {
    macro_rules! guarded {
        ($($i:literal)*) => { $( if $i < N { body($i); } )* };
    }
    if N <= 32 {
        guarded!(0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31);
    } else {
        (0..N).for_each(body);
    }
}
