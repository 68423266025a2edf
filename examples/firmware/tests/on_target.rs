//! The library's core invariants, run on the emulated Cortex-M4F (thumbv7em-none-eabihf,
//! hardware `f32`, libm) under QEMU with defmt-test: `cargo test` in `examples/firmware/`.
//!
//! These mirror the host unit and property tests of `src/optimizer.rs` and
//! `src/optimizer/coordinate.rs` (the proptest properties become loops over seeded random
//! cases, as proptest needs std), so target-specific numerics are covered: f32 rounding at
//! the box faces, NaN handling, libm's `powf` in the objective.
#![no_std]
#![no_main]

use ctrl_adapt_firmware as _; // defmt logger, panic and HardFault handlers that exit QEMU

use ctrl_adapt::optimizer::unit_f32;
use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Error, Optimizer, Status, Vector};
use ctrl_adapt_firmware::functions::{ellipsoid, ellipsoid_minimiser};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::Xoshiro128PlusPlus;

fn rng(seed: u64) -> Xoshiro128PlusPlus {
    Xoshiro128PlusPlus::seed_from_u64(seed)
}

/// A uniform f32 in [lo, hi).
fn uniform(r: &mut Xoshiro128PlusPlus, lo: f32, hi: f32) -> f32 {
    lo + unit_f32(r) * (hi - lo)
}

/// A cost that is sometimes NaN, ±inf, huge, tiny or subnormal, else ordinary.
fn wild_cost(r: &mut Xoshiro128PlusPlus) -> f32 {
    match r.next_u32() % 10 {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::NEG_INFINITY,
        3 => f32::MAX,
        4 => -f32::MAX,
        5 => f32::MIN_POSITIVE / 4.0,
        _ => uniform(r, -1e3, 1e3),
    }
}

fn config(initial_step: f32, tolerance: f32) -> CoordinateConfig {
    CoordinateConfig {
        initial_step,
        tolerance,
        ..CoordinateConfig::DEFAULT
    }
}

/// FNV-1a over the bits of every candidate and cost of a run with a noisy objective whose
/// noise comes from the caller's RNG; also returns the number of evaluations.
fn run_fingerprint(seed: u64) -> (u64, u32) {
    let b = Bounds::<3>::uniform(-2.0, 2.0).unwrap();
    let mut s = CoordinateSearch::try_new(b, Vector::zeros(), config(0.5, 1e-4)).unwrap();
    let mut r = rng(seed);
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    let mut mix = |v: f32| {
        for byte in v.to_bits().to_le_bytes() {
            hash = (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    while let Ok(t) = s.ask(&mut r) {
        let cost = ellipsoid(&t) + 0.01 * unit_f32(&mut r);
        s.tell(cost).unwrap();
        t.iter().for_each(|&v| mix(v));
        mix(cost);
    }
    (hash, s.evaluations())
}

/// An RNG that always returns the largest value, the edge case of `unit_f32`.
struct Saturated;
impl RngCore for Saturated {
    fn next_u32(&mut self) -> u32 {
        u32::MAX
    }
    fn next_u64(&mut self) -> u64 {
        u64::MAX
    }
    fn fill_bytes(&mut self, dst: &mut [u8]) {
        dst.fill(0xff);
    }
}

#[defmt_test::tests]
mod tests {
    use super::*;
    use defmt::{assert, assert_eq};

    /// Checks, over 64 seeded random boxes (widths 1e-3..1e3), starts, step sizes and cost
    /// sequences with NaN/inf/extreme values: every candidate lies inside the box, a
    /// non-finite cost is rejected, and the best cost never increases.
    #[test]
    fn candidates_stay_inside_random_boxes() {
        let mut r = rng(11);
        for _ in 0..64 {
            let lower = Vector::<4>::from_fn(|_, _| uniform(&mut r, -1e3, 1e3));
            let upper = Vector::<4>::from_fn(|i, _| {
                lower[i] + libm::powf(10.0, uniform(&mut r, -3.0, 3.0))
            });
            let bounds = Bounds::try_new(lower, upper).unwrap();
            let start = Vector::<4>::from_fn(|i, _| {
                (lower[i] + unit_f32(&mut r) * (upper[i] - lower[i])).min(upper[i])
            });
            let cfg = CoordinateConfig {
                initial_step: libm::powf(10.0, uniform(&mut r, -3.0, 3.0)),
                contraction: uniform(&mut r, 0.05, 0.95),
                expansion: uniform(&mut r, 1.05, 4.0),
                tolerance: 1e-4,
                ..CoordinateConfig::DEFAULT
            };
            let mut s = CoordinateSearch::try_new(bounds, start, cfg).unwrap();
            let mut best = f32::INFINITY;
            for _ in 0..300 {
                let Ok(theta) = s.ask(&mut r) else { break };
                assert!(bounds.contains(&theta));
                let cost = wild_cost(&mut r);
                let told = s.tell(cost);
                assert_eq!(told.is_ok(), cost.is_finite());
                let now = s.best().map_or(f32::INFINITY, |b| b.cost);
                assert!(now <= best);
                best = now;
            }
        }
    }

    /// Checks: NaN, +inf and -inf costs return `NonFinite("cost")` and leave the whole
    /// optimizer unchanged (the candidate stays pending); a `tell` without `ask` returns
    /// `NoPendingAsk` and changes nothing either.
    #[test]
    fn non_finite_cost_is_rejected_without_state_change() {
        let b = Bounds::<18>::uniform(-2.0, 2.0).unwrap();
        let mut s = CoordinateSearch::try_new(b, Vector::zeros(), config(0.5, 1e-4)).unwrap();
        let mut r = rng(3);
        let fresh = s;
        assert_eq!(s.tell(1.0), Err(Error::NoPendingAsk));
        assert!(s == fresh);
        // Move into the middle of the state machine first.
        for _ in 0..50 {
            let t = s.ask(&mut r).unwrap();
            s.tell(ellipsoid(&t)).unwrap();
        }
        let pending = s.ask(&mut r).unwrap();
        let before = s;
        for cost in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::NAN] {
            assert_eq!(s.tell(cost), Err(Error::NonFinite("cost")));
            assert!(s == before);
        }
        assert_eq!(s.pending(), Some(&pending));
        assert!(s.tell(ellipsoid(&pending)).is_ok());
        assert_eq!(s.evaluations(), 51);
    }

    /// Checks: on the 5-D and 18-D ellipsoids (condition number 1e3, f32 with libm `powf`),
    /// from two starts, the search stops by its own test with cost < 1e-6 and every
    /// coordinate within 2e-3 of the minimiser.
    #[test]
    fn converges_on_ill_conditioned_quadratic() {
        fn check<const N: usize>(start: f32) {
            let b = Bounds::<N>::uniform(-2.0, 2.0).unwrap();
            let mut s =
                CoordinateSearch::try_new(b, Vector::repeat(start), config(0.5, 1e-5)).unwrap();
            let mut r = rng(0);
            while s.status() == Status::Running {
                let t = s.ask(&mut r).unwrap();
                s.tell(ellipsoid(&t)).unwrap();
            }
            assert_eq!(s.status(), Status::Converged);
            let best = s.best().unwrap();
            assert!(
                best.cost < 1e-6,
                "N={} start={}: cost {}",
                N,
                start,
                best.cost
            );
            for i in 0..N {
                let err = libm::fabsf(best.theta[i] - ellipsoid_minimiser::<N>(i));
                assert!(
                    err < 2e-3,
                    "N={} start={}: theta[{}] off by {}",
                    N,
                    start,
                    i,
                    err
                );
            }
        }
        check::<5>(-1.0);
        check::<5>(1.5);
        check::<18>(-1.0);
        check::<18>(1.5);
    }

    /// Checks: `Bounds::try_new` rejects NaN, infinite and empty or inverted intervals,
    /// naming the first bad coordinate; `clamp` maps NaN and ±inf into the box; uniform
    /// samples stay inside even for boxes whose width is near f32 resolution.
    #[test]
    fn bounds_validation_and_projection() {
        let one = Vector::<3>::repeat(1.0);
        assert!(Bounds::try_new(Vector::zeros(), one).is_ok());
        let bad = |i: usize, v: f32| {
            let mut lo = Vector::<3>::zeros();
            lo[i] = v;
            Bounds::try_new(lo, one)
        };
        assert_eq!(bad(2, f32::NAN), Err(Error::InvalidBounds { index: 2 }));
        assert_eq!(bad(1, 1.0), Err(Error::InvalidBounds { index: 1 }));
        assert_eq!(bad(0, 2.0), Err(Error::InvalidBounds { index: 0 }));
        assert_eq!(
            bad(0, f32::NEG_INFINITY),
            Err(Error::InvalidBounds { index: 0 })
        );
        assert_eq!(
            Bounds::<2>::uniform(0.0, f32::INFINITY),
            Err(Error::InvalidBounds { index: 0 })
        );

        let b = Bounds::<4>::try_new(
            [-1.0, 0.0, 1e-3, 1e6].into(),
            [1.0, 1e-6, 2e-3, 1e6 + 0.0625].into(),
        )
        .unwrap();
        let wild = Vector::<4>::from([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0]);
        assert!(b.contains(&b.clamp(&wild)));
        assert_eq!(b.clamp(&wild)[0], -1.0);
        assert_eq!(b.check(&wild, "theta"), Err(Error::NonFinite("theta")));
        let mut r = rng(5);
        for _ in 0..10_000 {
            assert!(b.contains(&b.sample_uniform(&mut r)));
        }
    }

    /// Checks: every out-of-range configuration field is rejected by name, and a start
    /// outside the box or non-finite is rejected.
    #[test]
    fn config_and_start_validation() {
        let b = Bounds::<2>::uniform(-1.0, 1.0).unwrap();
        let z = Vector::<2>::zeros();
        let bad = |f: fn(&mut CoordinateConfig)| {
            let mut c = CoordinateConfig::DEFAULT;
            f(&mut c);
            CoordinateSearch::try_new(b, z, c).err()
        };
        assert_eq!(
            bad(|c| c.initial_step = 0.0),
            Some(Error::InvalidParameter("initial_step"))
        );
        assert_eq!(
            bad(|c| c.initial_step = f32::NAN),
            Some(Error::InvalidParameter("initial_step"))
        );
        assert_eq!(
            bad(|c| c.contraction = 1.0),
            Some(Error::InvalidParameter("contraction"))
        );
        assert_eq!(
            bad(|c| c.expansion = 1.0),
            Some(Error::InvalidParameter("expansion"))
        );
        assert_eq!(
            bad(|c| c.sufficient_decrease = 0.0),
            Some(Error::InvalidParameter("sufficient_decrease"))
        );
        assert_eq!(
            bad(|c| c.tolerance = -1.0),
            Some(Error::InvalidParameter("tolerance"))
        );
        assert_eq!(
            bad(|c| c.max_evaluations = 0),
            Some(Error::InvalidParameter("max_evaluations"))
        );
        let c = CoordinateConfig::DEFAULT;
        assert_eq!(
            CoordinateSearch::try_new(b, [2.0, 0.0].into(), c).err(),
            Some(Error::OutOfBounds("start"))
        );
        assert_eq!(
            CoordinateSearch::try_new(b, [f32::NAN, 0.0].into(), c).err(),
            Some(Error::NonFinite("start"))
        );
    }

    /// Checks: the same seed gives the same sequence of candidates and costs, bit for bit;
    /// another seed gives a different one.
    #[test]
    fn same_seed_same_run() {
        let a = run_fingerprint(42);
        assert!(a.1 > 20);
        assert_eq!(a, run_fingerprint(42));
        assert!(a != run_fingerprint(43));
    }

    /// Checks: `unit_f32` stays in [0, 1) in target f32 arithmetic, including for the
    /// largest u32 (where rounding to 1.0 would be the bug).
    #[test]
    fn unit_f32_is_in_the_half_open_unit_interval() {
        assert!(unit_f32(&mut Saturated) < 1.0);
        let mut r = rng(9);
        for _ in 0..10_000 {
            let u = unit_f32(&mut r);
            assert!((0.0..1.0).contains(&u));
        }
    }
}
