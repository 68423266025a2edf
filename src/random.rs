//! Uniform and normal `f32` draws from the caller's [`RngCore`], without `f64` and without
//! trigonometry (both are software routines on a Cortex-M4F), and [`episode_rng`], the RNG
//! of one learning episode derived from a device seed, which leaves a checkpoint no RNG
//! state to save.

use rand_core::{RngCore, SeedableRng};

/// The RNG of learning episode `episode` on a device seeded with `seed`:
/// `R::seed_from_u64(seed · 2³² + episode)`.
///
/// An optimizer draws only inside `ask`, so an episode's candidate depends on the
/// optimizer's state and on this RNG alone. Derived afresh for every episode from a counter
/// the checkpoint holds anyway (the adapter's [`learning_episodes`] or the optimizer's
/// [`evaluations`]), the RNG needs no saving: a run resumed from a checkpoint draws what the
/// uninterrupted run draws, bit for bit, and an episode a power cut interrupted is run
/// again with the same candidate. [`Adapter::begin_seeded_episode`] does this for the
/// adapter.
///
/// Every (seed, episode) pair is a distinct `u64`, so every episode of every device gets its
/// own seed. With `rand_xoshiro`'s generators, whose `seed_from_u64` fills the state from
/// SplitMix64 started at that `u64`, the episodes of one device share no SplitMix64 output
/// (their starts differ by less than 2³², never by SplitMix64's increment or its negative,
/// both above 2³²): their states are distinct and as independent as SplitMix64 makes any
/// two seeds.
///
/// [`learning_episodes`]: crate::controller::Adapter::learning_episodes
/// [`evaluations`]: crate::Optimizer::evaluations
/// [`Adapter::begin_seeded_episode`]: crate::controller::Adapter::begin_seeded_episode
///
/// ```
/// use ctrl_adapt::random::episode_rng;
/// use rand_core::RngCore;
/// use rand_xoshiro::Xoshiro128PlusPlus;
///
/// let mut a = episode_rng::<Xoshiro128PlusPlus>(7, 3);
/// let mut b = episode_rng::<Xoshiro128PlusPlus>(7, 3);
/// assert_eq!(a.next_u64(), b.next_u64()); // the same episode: the same draws
/// let mut c = episode_rng::<Xoshiro128PlusPlus>(7, 4);
/// assert_ne!(a.next_u64(), c.next_u64()); // the next episode: other draws
/// ```
pub fn episode_rng<R: SeedableRng>(seed: u32, episode: u32) -> R {
    R::seed_from_u64((u64::from(seed) << 32) | u64::from(episode))
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

/// z ~ N(0, I) in `N` dimensions: ⌈N/2⌉ [`normal_pair_f32`] draws, always (the second
/// value of the last pair is dropped when N is odd).
pub(crate) fn normal_vector_f32<const N: usize, R: RngCore + ?Sized>(
    rng: &mut R,
) -> crate::Vector<N> {
    let mut z = crate::Vector::<N>::zeros();
    let mut pair = [0.0f32; 2];
    for (i, v) in z.iter_mut().enumerate() {
        if i % 2 == 0 {
            pair = normal_pair_f32(rng);
        }
        *v = pair[i % 2];
    }
    z
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

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

    /// Checks: the same (seed, episode) gives the same stream; each of 64 episodes of two
    /// seeds starts a stream of its own (no two of the 128 share a first draw or a state).
    #[test]
    fn episode_rngs_are_reproducible_and_distinct() {
        let first = |seed, episode| {
            let mut r = episode_rng::<Xoshiro128PlusPlus>(seed, episode);
            [r.next_u64(), r.next_u64()]
        };
        assert_eq!(first(3, 9), first(3, 9));
        let mut seen = std::collections::BTreeSet::new();
        for seed in [0, u32::MAX] {
            for episode in (0..32).chain(u32::MAX - 31..=u32::MAX) {
                assert!(seen.insert(first(seed, episode)), "{seed} {episode}");
            }
        }
        assert_eq!(seen.len(), 128);
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
}
