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

/// Σᵢ term(i) over i in 0..N, added in the order of nalgebra's `dot` (and so of `tr_mul`,
/// whose entries are such dots), as straight-line code when N ≤ 32: the results are those
/// of nalgebra bit for bit, where nalgebra's loops stay rolled at opt-level "s". The plant
/// model's prediction is 6 such dots of 14 terms per imagined AUV tick.
///
/// nalgebra sums two, three and four terms directly: ((t₀ + t₁) + t₂) for three,
/// ((t₀ + t₂) + (t₁ + t₃)) for four. Beyond, term i of the first ⌊N/8⌋·8 goes to
/// accumulator i mod 8, the accumulators are added in pairs (0 and 4, 1 and 5, 2 and 6,
/// 3 and 7) onto a sum that starts at +0.0, and the remaining terms follow one by one.
/// nalgebra starts its accumulators at +0.0 and adds the first block's terms to them; here
/// the first block's terms are the accumulators, without that addition. The two differ only
/// in the sign of a zero accumulator, which the sum's +0.0 start absorbs (+0.0 + ±0.0 =
/// +0.0, and a sum that started at +0.0 is never −0.0 again under rounding to nearest).
#[inline(always)]
pub(crate) fn dot<const N: usize>(mut term: impl FnMut(usize) -> f32) -> f32 {
    match N {
        2 => term(0) + term(1),
        3 => term(0) + term(1) + term(2),
        4 => {
            let (t0, t1, t2, t3) = (term(0), term(1), term(2), term(3));
            (t0 + t2) + (t1 + t3)
        }
        _ => {
            let blocks = N / 8 * 8;
            let mut acc = [0.0f32; 8];
            unrolled::<N>(|i| {
                if i < 8.min(blocks) {
                    acc[i] = term(i);
                } else if i < blocks {
                    acc[i % 8] += term(i);
                }
            });
            let mut sum = 0.0 + (acc[0] + acc[4]);
            sum += acc[1] + acc[5];
            sum += acc[2] + acc[6];
            sum += acc[3] + acc[7];
            unrolled::<N>(|i| {
                if i >= blocks {
                    sum += term(i);
                }
            });
            sum
        }
    }
}

/// Whether every entry of `v` is finite, as straight-line code when N ≤ 32 (see
/// [`unrolled`]; `v.iter().all(..)` stays a loop at opt-level "s").
#[inline(always)]
pub(crate) fn all_finite<const N: usize>(v: &Vector<N>) -> bool {
    let mut finite = true;
    unrolled::<N>(|i| finite &= v[i].is_finite());
    finite
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Entries of one scale, where the order of the additions shows in the rounding, and
    /// now and then a signed zero, an infinity or NaN.
    fn entry() -> impl Strategy<Value = f32> {
        prop_oneof![
            20 => -1f32..1.0,
            1 => Just(0.0f32),
            1 => Just(-0.0f32),
            1 => Just(f32::INFINITY),
            1 => Just(f32::NAN),
            1 => proptest::num::f32::NORMAL,
        ]
    }

    /// `dot::<N>` of the first N entries of `a` and `b` against nalgebra's `dot`.
    fn check<const N: usize>(a: &[f32; 40], b: &[f32; 40]) -> Result<(), TestCaseError> {
        let x = Vector::<N>::from_fn(|i, _| a[i]);
        let y = Vector::<N>::from_fn(|i, _| b[i]);
        let expected = x.dot(&y);
        let got = dot::<N>(|i| x[i] * y[i]);
        // Bit for bit (zeros' signs included); a NaN is any NaN.
        prop_assert!(
            got.to_bits() == expected.to_bits() || (got.is_nan() && expected.is_nan()),
            "N = {}: {:?} against nalgebra's {:?}",
            N,
            got,
            expected
        );
        Ok(())
    }

    proptest! {
        /// Checks: `dot` equals nalgebra's `dot` bit for bit at every length that takes a
        /// different path there (2, 3, 4 directly; below, at and between multiples of 8;
        /// beyond the unrolled 32).
        #[test]
        fn dot_is_nalgebras_bit_for_bit(
            a in prop::collection::vec(entry(), 40),
            b in prop::collection::vec(entry(), 40),
        ) {
            let a: [f32; 40] = a.try_into().unwrap();
            let b: [f32; 40] = b.try_into().unwrap();
            check::<1>(&a, &b)?;
            check::<2>(&a, &b)?;
            check::<3>(&a, &b)?;
            check::<4>(&a, &b)?;
            check::<5>(&a, &b)?;
            check::<7>(&a, &b)?;
            check::<8>(&a, &b)?;
            check::<9>(&a, &b)?;
            check::<14>(&a, &b)?;
            check::<16>(&a, &b)?;
            check::<18>(&a, &b)?;
            check::<32>(&a, &b)?;
            check::<33>(&a, &b)?;
            check::<40>(&a, &b)?;
        }
    }

    #[test]
    fn dot_of_zeros_has_nalgebras_sign() {
        // Checks: products that are all −0.0, all +0.0, or −0.0 with one +0.0 at each place,
        // sum to the zero nalgebra returns (its +0.0 start makes every such sum +0.0).
        let a = [-0.0f32; 40];
        let ones = [1.0f32; 40];
        check_all(&a, &ones);
        check_all(&[0.0; 40], &ones);
        for k in 0..40 {
            let mut b = [-1.0f32; 40];
            b[k] = 1.0;
            check_all(&[0.0; 40], &b);
            let mut b = [1.0f32; 40];
            b[k] = -1.0;
            check_all(&a, &b);
        }
    }

    fn check_all(a: &[f32; 40], b: &[f32; 40]) {
        check::<1>(a, b).unwrap();
        check::<2>(a, b).unwrap();
        check::<3>(a, b).unwrap();
        check::<4>(a, b).unwrap();
        check::<5>(a, b).unwrap();
        check::<8>(a, b).unwrap();
        check::<14>(a, b).unwrap();
        check::<16>(a, b).unwrap();
        check::<18>(a, b).unwrap();
        check::<33>(a, b).unwrap();
    }

    #[test]
    fn all_finite_finds_any_non_finite_entry() {
        // Checks: every position and kind of non-finite entry is found, signed zeros and
        // f32::MAX are finite.
        let finite = Vector::<7>::from([0.0, -0.0, f32::MAX, -f32::MAX, 1.0, 1e-40, -3.0]);
        assert!(all_finite(&finite));
        for i in 0..7 {
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut v = finite;
                v[i] = bad;
                assert!(!all_finite(&v), "{bad} at {i}");
            }
        }
    }
}
