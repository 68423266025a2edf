//! The RACOS classifier and its sampler, shared by [`Sracos`](super::Sracos) and
//! [`Racos`](super::Racos): an axis-parallel box around one positive sample that holds no
//! negative sample (Yu, Qian & Hu 2016, "Derivative-free optimization via classification";
//! ZOOpt's `RacosClassification.mixed_classification` and `rand_sample`, continuous case).
//!
//! **Learning.** Start from the whole search box. Repeatedly pick a coordinate k and a negative
//! x⁻ still inside the box, both uniformly at random, and cut the box between the positive x⁺
//! and x⁻ at r ~ U(x⁺_k, x⁻_k): if x⁺_k < x⁻_k the upper face of k moves down to r and every
//! negative with x_k ≥ r leaves the box, otherwise the lower face moves up to r and every
//! negative with x_k ≤ r leaves. Stop when no negative is left inside.
//!
//! **Sampling.** Copy x⁺ and redraw only a few randomly chosen "uncertain" coordinates
//! uniformly inside the box's faces on those coordinates; every other coordinate keeps x⁺'s
//! value. (ZOOpt picks the uncertain coordinates after learning, independently of it; they are
//! picked first here, which is the same distribution.)
//!
//! **Only the uncertain coordinates' faces are stored** (3 floats per coordinate, at most
//! [`MAX_UNCERTAIN_BITS`](super::MAX_UNCERTAIN_BITS)) instead of the whole 2·N-float box:
//! the faces on other coordinates never reach the sample, and their only other use in ZOOpt,
//! the test "the cut r lies strictly inside the current face" before cutting, gives the same
//! answer against the *search box's* face. Proof: a negative still inside the box lies strictly
//! inside every face that has been cut (the cut removed every negative on or beyond it), and r
//! lies between x⁺_k and that negative's x⁻_k, so r is strictly inside a cut face; on an uncut
//! coordinate the current face is the search box's face.
//!
//! **Termination.** Each cut removes at least the chosen negative, so learning takes at most
//! M cuts, except that a cut falling exactly on the search box's face (possible only when
//! x⁻_k lies on that face and rounding puts r there, or when a negative equals x⁺ on a corner)
//! does nothing. ZOOpt loops until done; here learning stops after 4·M + 32 cut attempts
//! and the box is used as it is (it may then still hold a negative). With distinct samples
//! that takes, in practice, an event of probability zero.

use rand_core::RngCore;

use super::{MAX_UNCERTAIN_BITS, below};
use crate::optimizer::{Best, Bounds, Vector, unit_f32};

/// The cap on cut attempts while learning against `m` negatives (see "Termination").
pub(super) const fn max_cut_attempts(m: usize) -> usize {
    4 * m + 32
}

/// A point between `a` and `b` at fraction `u ∈ [0, 1)`, kept inside `[min(a,b), max(a,b)]`.
/// The convex form `a(1−u) + bu` cannot overflow for finite `a`, `b` (unlike `a + u(b−a)`
/// on a box as wide as the f32 range); the final clamp guards against rounding.
fn between(a: f32, b: f32, u: f32) -> f32 {
    let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
    (a * (1.0 - u) + b * u).max(lo).min(hi)
}

/// The learned sampling region, restricted to the uncertain coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Region {
    /// The uncertain coordinates (distinct), first `count` entries valid.
    dims: [usize; MAX_UNCERTAIN_BITS],
    /// The box's faces on those coordinates.
    lower: [f32; MAX_UNCERTAIN_BITS],
    upper: [f32; MAX_UNCERTAIN_BITS],
    count: usize,
}

impl Region {
    /// Learns the box around `positive` against all `negatives` and picks
    /// `uncertain_bits.min(N)` distinct uncertain coordinates. `positive` and the negatives
    /// must lie inside `bounds` (they are past candidates).
    pub(super) fn learn<const N: usize, const M: usize, R: RngCore + ?Sized>(
        bounds: &Bounds<N>,
        positive: &Vector<N>,
        negatives: &[Best<N>; M],
        uncertain_bits: usize,
        rng: &mut R,
    ) -> Self {
        let mut region = Self {
            dims: [0; MAX_UNCERTAIN_BITS],
            lower: [0.0; MAX_UNCERTAIN_BITS],
            upper: [0.0; MAX_UNCERTAIN_BITS],
            count: 0,
        };
        // Floyd's algorithm: `ub` distinct coordinates with exactly `ub` draws.
        let ub = uncertain_bits.min(N).min(MAX_UNCERTAIN_BITS);
        for j in (N - ub)..N {
            let t = below(rng, j + 1);
            let d = if region.dims().contains(&t) { j } else { t };
            // count < ub ≤ MAX_UNCERTAIN_BITS and d ≤ j < N: every `get` succeeds (they
            // spare bounds checks, i.e. panic paths).
            let i = region.count;
            if let (Some(dim), Some(lower), Some(upper), Some(&lo), Some(&hi)) = (
                region.dims.get_mut(i),
                region.lower.get_mut(i),
                region.upper.get_mut(i),
                bounds.lower().get(d),
                bounds.upper().get(d),
            ) {
                (*dim, *lower, *upper) = (d, lo, hi);
                region.count += 1;
            }
        }

        // `inside[..remaining]` indexes the negatives still inside the box.
        let mut inside: [usize; M] = core::array::from_fn(|i| i);
        let mut remaining = M;
        let mut attempts = 0;
        // `inside` holds indices < M and remaining ≤ M: the `get`s below always succeed
        // and only spare bounds checks (panic paths); k < N by `below`.
        let coordinate = |i: usize, k: usize| negatives.get(i).map_or(0.0, |e| e.theta[k]);
        while remaining > 0 && attempts < max_cut_attempts(M) {
            attempts += 1;
            let k = below(rng, N);
            let chosen = inside.get(below(rng, remaining)).copied().unwrap_or(0);
            let (p, q) = (positive[k], coordinate(chosen, k));
            let r = between(p, q, unit_f32(rng));
            // Which side of the cut a negative must be on to leave the box.
            let leaves_above = p < q;
            if leaves_above {
                if r >= bounds.upper()[k] {
                    continue;
                }
                region.cut(k, |face| face.1 = r);
            } else {
                if r <= bounds.lower()[k] {
                    continue;
                }
                region.cut(k, |face| face.0 = r);
            }
            let mut i = 0;
            while let Some(&n) = inside.get(i).filter(|_| i < remaining) {
                let x = coordinate(n, k);
                let leaves = if leaves_above { x >= r } else { x <= r };
                if leaves {
                    remaining -= 1;
                    // i ≤ remaining < M: the test only spares `swap`'s bounds checks.
                    if remaining < M {
                        inside.swap(i, remaining);
                    }
                } else {
                    i += 1;
                }
            }
        }
        region
    }

    /// Applies a cut on coordinate `k` to the stored faces, if `k` is uncertain.
    fn cut(&mut self, k: usize, apply: impl FnOnce(&mut (f32, f32))) {
        if let Some(i) = self.dims().iter().position(|&d| d == k)
            && let (Some(lower), Some(upper)) = (self.lower.get_mut(i), self.upper.get_mut(i))
        {
            let mut face = (*lower, *upper);
            apply(&mut face);
            (*lower, *upper) = face;
        }
    }

    /// A candidate: `positive` with each uncertain coordinate redrawn uniformly between its
    /// faces. Inside the search box whenever `positive` is.
    pub(super) fn sample<const N: usize, R: RngCore + ?Sized>(
        &self,
        positive: &Vector<N>,
        rng: &mut R,
    ) -> Vector<N> {
        let mut x = *positive;
        let faces = self.lower.iter().zip(self.upper.iter());
        for (&d, (&lower, &upper)) in self.dims().iter().zip(faces) {
            // d < N always (an uncertain coordinate); the RNG advances either way.
            let value = between(lower, upper, unit_f32(rng));
            if let Some(v) = x.get_mut(d) {
                *v = value;
            }
        }
        x
    }

    /// The uncertain coordinates.
    pub(super) fn dims(&self) -> &[usize] {
        self.dims.get(..self.count).unwrap_or(&[])
    }

    /// The uncertain coordinates and their faces `(dim, lower, upper)`.
    #[cfg(test)]
    pub(super) fn faces(&self) -> impl Iterator<Item = (usize, f32, f32)> + '_ {
        (0..self.count).map(|i| (self.dims[i], self.lower[i], self.upper[i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    /// Replays the learning with the same RNG but keeping the *whole* box (ZOOpt's
    /// bookkeeping, with its "cut strictly inside the current face" test) and returns it.
    fn full_box<const N: usize, const M: usize>(
        bounds: &Bounds<N>,
        positive: &Vector<N>,
        negatives: &[Best<N>; M],
        ub: usize,
        rng: &mut Xoshiro128PlusPlus,
    ) -> (Vector<N>, Vector<N>, usize) {
        for j in (N - ub)..N {
            below(rng, j + 1);
        }
        let (mut lo, mut hi) = (*bounds.lower(), *bounds.upper());
        let mut inside: Vec<usize> = (0..M).collect();
        let mut attempts = 0;
        while !inside.is_empty() && attempts < max_cut_attempts(M) {
            attempts += 1;
            let k = below(rng, N);
            let chosen = inside[below(rng, inside.len())];
            let (p, q) = (positive[k], negatives[chosen].theta[k]);
            let r = between(p, q, unit_f32(rng));
            let leaves: Box<dyn Fn(f32) -> bool> = if p < q {
                if r >= hi[k] {
                    continue;
                }
                hi[k] = r;
                Box::new(move |x| x >= r)
            } else {
                if r <= lo[k] {
                    continue;
                }
                lo[k] = r;
                Box::new(move |x| x <= r)
            };
            // ZOOpt's swap-with-last removal (the order decides later random picks).
            let mut i = 0;
            while i < inside.len() {
                if leaves(negatives[inside[i]].theta[k]) {
                    inside.swap_remove(i);
                } else {
                    i += 1;
                }
            }
        }
        (lo, hi, inside.len())
    }

    fn points<const N: usize, const M: usize>(
        bounds: &Bounds<N>,
        rng: &mut Xoshiro128PlusPlus,
    ) -> [Best<N>; M] {
        core::array::from_fn(|_| Best {
            theta: bounds.sample_uniform(rng),
            cost: 0.0,
        })
    }

    /// Checks: on random data the learned faces equal those of ZOOpt's full-box bookkeeping
    /// run on the same random numbers (the equivalence argued in the module docs), the full
    /// box holds the positive and no negative, and learning needed no cap.
    #[test]
    fn stored_faces_match_the_full_box() {
        let bounds = Bounds::<6>::uniform(-1.0, 1.0).unwrap();
        for seed in 0..500 {
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            let negatives: [Best<6>; 9] = points(&bounds, &mut rng);
            let positive = bounds.sample_uniform(&mut rng);
            let ub = 1 + seed as usize % 6;
            let mut a = rng.clone();
            let region = Region::learn(&bounds, &positive, &negatives, ub, &mut a);
            let (lo, hi, left) = full_box(&bounds, &positive, &negatives, ub, &mut rng);
            assert_eq!(a, rng, "same number of draws");
            assert_eq!(left, 0);
            assert_eq!(region.faces().count(), ub);
            for (d, l, u) in region.faces() {
                assert_eq!((l, u), (lo[d], hi[d]), "seed {seed} dim {d}");
            }
            for i in 0..6 {
                assert!(lo[i] <= positive[i] && positive[i] <= hi[i]);
            }
            for n in &negatives {
                assert!((0..6).any(|i| n.theta[i] < lo[i] || n.theta[i] > hi[i]));
            }
        }
    }

    /// Checks: a negative equal to the positive, with the positive on the lower corner of
    /// the box, cannot be cut away; learning stops at the cap instead of looping forever.
    #[test]
    fn an_uncuttable_negative_stops_at_the_cap() {
        let bounds = Bounds::<2>::uniform(0.0, 1.0).unwrap();
        let corner = Vector::<2>::zeros();
        let negatives = [Best {
            theta: corner,
            cost: 1.0,
        }];
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(3);
        let region = Region::learn(&bounds, &corner, &negatives, 1, &mut rng);
        let x = region.sample(&corner, &mut rng);
        assert!(bounds.contains(&x));
    }

    proptest! {
        /// Checks, for random boxes, points and uncertain-bit counts: a sample differs from
        /// the positive only on the uncertain coordinates, lies between their faces, and is
        /// inside the search box.
        #[test]
        fn samples_change_only_uncertain_coordinates(seed in any::<u64>(), ub in 1usize..=5,
                                                    lo in -1e3f32..1e3, width in 1e-3f32..1e3) {
            let bounds = Bounds::<5>::uniform(lo, lo + width).unwrap();
            let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
            let negatives: [Best<5>; 4] = points(&bounds, &mut rng);
            let positive = bounds.sample_uniform(&mut rng);
            let region = Region::learn(&bounds, &positive, &negatives, ub, &mut rng);
            for _ in 0..20 {
                let x = region.sample(&positive, &mut rng);
                prop_assert!(bounds.contains(&x));
                for i in 0..5 {
                    match region.faces().find(|f| f.0 == i) {
                        Some((_, l, u)) => prop_assert!(l <= x[i] && x[i] <= u),
                        None => prop_assert_eq!(x[i], positive[i]),
                    }
                }
            }
        }
    }
}
