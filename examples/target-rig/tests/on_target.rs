//! The library's core invariants, run on the emulated Cortex-M4F (thumbv7em-none-eabihf,
//! hardware `f32`, libm) under QEMU with defmt-test: `cargo test` in `examples/target-rig/`.
//!
//! These mirror the host unit and property tests of `src/optimizer.rs`,
//! `src/optimizer/coordinate.rs`, the controller layer (the policy's envelope, the adapter's
//! fallbacks) and SRACOS / the diagonal CEM / ROCK* / LineBO (the proptest properties become loops over seeded
//! random cases, as proptest needs std), so target-specific numerics are covered: f32
//! rounding at the box faces, NaN handling, libm's `powf`, `logf`, `cosf`, `expf` and `sqrtf`.
#![no_std]
#![no_main]

use ctrl_adapt_firmware as _; // defmt logger, panic and HardFault handlers that exit QEMU

use auv_survey as auv;
use ctrl_adapt::controller::{Controller, Mode};
use ctrl_adapt::optimizer::unit_f32;
use ctrl_adapt::{
    Bounds, CemConfig, CoordinateConfig, CoordinateSearch, DiagonalCem, Error, LineBo,
    LineBoConfig, LineDirections, Optimizer, Replacement, Rockstar, RockstarConfig, Sracos,
    SracosConfig, Status, Suppression, Vector, Weighting,
};
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

/// A value from anywhere in f32 one time in four (NaN, ±inf, subnormals, huge), else
/// uniform in [−range, range).
fn wild(r: &mut Xoshiro128PlusPlus, range: f32) -> f32 {
    match r.next_u32() % 8 {
        0 => f32::from_bits(r.next_u32()),
        1 => [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::NAN][(r.next_u32() % 4) as usize],
        _ => uniform(r, -range, range),
    }
}

/// Asks and tells `optimizer` `evaluations` times with wild costs; checks that every
/// candidate is inside the box, that a non-finite cost is rejected without any change of
/// state, and that the best cost never increases.
fn candidates_in_bounds<const N: usize, O>(
    mut optimizer: O,
    r: &mut Xoshiro128PlusPlus,
    evaluations: u32,
) where
    O: Optimizer<N> + Clone + PartialEq,
{
    let bounds = *optimizer.bounds();
    let mut best = f32::INFINITY;
    for _ in 0..evaluations {
        let Ok(theta) = optimizer.ask(r) else { break };
        defmt::assert!(bounds.contains(&theta));
        let cost = wild_cost(r);
        let before = optimizer.clone();
        let told = optimizer.tell(cost);
        defmt::assert_eq!(told.is_ok(), cost.is_finite());
        if told.is_err() {
            defmt::assert!(optimizer == before);
            defmt::assert!(optimizer.tell(uniform(r, 0.0, 10.0)).is_ok());
        }
        let now = optimizer.best().map_or(f32::INFINITY, |b| b.cost);
        defmt::assert!(now <= best);
        best = now;
    }
}

/// The quadratic of LineBO's host tests: minimum 0 at (0.4, −0.3, 0.2, −0.1), curvature
/// i + 1 along θ_i. (Its tests run on the Cortex-M4F only.)
#[cfg(target_abi = "eabihf")]
fn line_bo_quadratic(t: &Vector<4>) -> f32 {
    let c = [0.4, -0.3, 0.2, -0.1];
    (0..4)
        .map(|i| (i as f32 + 1.0) * (t[i] - c[i]) * (t[i] - c[i]))
        .sum()
}

/// The settings of LineBO's host tests on [`line_bo_quadratic`]: σ_f² = 4, small noise and
/// jitter (the cost is exact).
#[cfg(target_abi = "eabihf")]
fn line_bo_config(
    threshold: Option<f32>,
    directions: LineDirections,
    max_evaluations: u32,
) -> LineBoConfig {
    LineBoConfig {
        signal_variance: 4.0,
        noise_variance: 1e-4,
        jitter: 1e-6,
        threshold,
        directions,
        max_evaluations,
        ..LineBoConfig::DEFAULT
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

/// Writes and reads a local array of `WORDS` words, so its frame holds at least 4·`WORDS`
/// bytes; never inlined, so that the frame is its own.
#[inline(never)]
fn frame_of<const WORDS: usize>() -> u32 {
    let mut words = [0u32; WORDS];
    for (i, w) in words.iter_mut().enumerate() {
        *w = core::hint::black_box(i as u32);
    }
    core::hint::black_box(&mut words)
        .iter()
        .fold(0, |a, &w| a ^ w)
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

    /// Checks, for the AUV policy (18 weights, state [target − p, v]): for θ and states from
    /// anywhere in f32 (NaN and infinities included), every correction component is finite
    /// and within ±0.5 m/s (the envelope); the action is within ±0.5 m/s or NaN (a NaN
    /// state, for the adapter to catch), and finite for finite states of moderate size;
    /// θ = 0 gives exactly the nominal PD.
    #[test]
    fn policy_correction_stays_in_its_envelope() {
        let mut controller = auv::controller().unwrap();
        let policy = *controller.policy();
        let mut r = rng(21);
        for _ in 0..2_000 {
            let theta = Vector::<18>::from_fn(|_, _| wild(&mut r, 2.0));
            let state = Vector::<6>::from_fn(|_, _| wild(&mut r, 8.0));
            let c = policy.correction(&theta, &state, 0.0);
            assert!(
                c.iter()
                    .all(|v| v.is_finite() && libm::fabsf(*v) <= auv::C_MAX)
            );
            let u = controller.corrected(&theta, &state, 0.0);
            assert!(
                u.iter()
                    .all(|v| v.is_nan() || libm::fabsf(*v) <= auv::V_MAX)
            );
            if state.iter().all(|v| v.is_finite() && libm::fabsf(*v) < 1e6) {
                assert!(u.iter().all(|v| v.is_finite()));
            }
            let zero = controller.corrected(&Vector::zeros(), &state, 0.0);
            let nominal = controller.nominal(&state, 0.0);
            for (a, b) in zero.iter().zip(nominal.iter()) {
                assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
            }
        }
    }

    /// Checks the AUV adapter's fallbacks over 120 episodes (learning, deploying, nominal,
    /// some aborted) with NaN and infinite states and observations: every action is finite
    /// and within ±0.5 m/s; a non-finite state gets the nominal PD (or zero when that is not
    /// finite either); every learning episode tells a finite cost, the failure cost exactly
    /// when the episode failed (a faulty tick, a cost with nothing valid observed, an abort),
    /// and the optimizer counts exactly the learning episodes.
    #[test]
    fn adapter_fallbacks_never_tell_a_non_finite_cost() {
        let mut a = auv::adapter(auv::coordinate_search(u32::MAX).unwrap(), u32::MAX).unwrap();
        let mut controller = *a.controller();
        let mut r = rng(22);
        let mut learned = 0;
        for episode in 0..120u32 {
            let mode = match r.next_u32() % 6 {
                0 => Mode::Deploy,
                1 => Mode::Nominal,
                _ => Mode::Learn,
            };
            a.set_mode(mode).unwrap();
            a.begin_episode(&mut r).unwrap();
            let mut faulty = false;
            for _ in 0..(r.next_u32() % 30) {
                let bad = r.next_u32().is_multiple_of(5);
                let x = Vector::<6>::from_fn(|_, _| {
                    if bad {
                        wild(&mut r, 8.0)
                    } else {
                        uniform(&mut r, -8.0, 8.0)
                    }
                });
                let error = Vector::<3>::new(x[0], x[1], x[2]);
                let u = a.control(&x, &error);
                assert!(
                    u.iter()
                        .all(|v| v.is_finite() && libm::fabsf(*v) <= auv::V_MAX)
                );
                if !x.iter().all(|v| v.is_finite()) {
                    faulty = true; // in every mode: a non-finite state is a faulty tick
                    let nominal = controller.nominal(&x, 0.0);
                    let expected = if nominal.iter().all(|v| v.is_finite()) {
                        nominal
                    } else {
                        Vector::zeros()
                    };
                    assert!(u == expected);
                }
            }
            let aborted = episode % 9 == 4;
            let report = if aborted {
                a.abort_episode()
            } else {
                a.end_episode()
            }
            .unwrap();
            let failed = aborted || faulty || !report.cost.is_finite();
            assert_eq!(report.failed, failed);
            match report.told {
                Some(told) => {
                    learned += 1;
                    assert!(told.is_finite());
                    assert_eq!(
                        told,
                        if failed {
                            auv::FAILURE_COST
                        } else {
                            report.cost
                        }
                    );
                }
                None => assert!(report.mode != Mode::Learn),
            }
            assert_eq!(a.optimizer().evaluations(), learned);
        }
        assert!(learned > 50);
    }

    /// Checks the PIL learner's fallback (a corrupted or missing state frame): the nominal
    /// PD on the last valid state; zero without one, or when it is not finite.
    #[test]
    fn pil_fallback_is_the_nominal_pd() {
        use pil_link::Learner as _;
        let mut l =
            auv::AuvLearner::try_new(auv::coordinate_search(u32::MAX).unwrap(), u32::MAX, 1)
                .unwrap();
        let mut controller = auv::controller().unwrap();
        let mut theta = pil_link::Values::new();
        l.start_episode(0, &[], &mut theta);
        let mut u = pil_link::Values::new();
        let mut r = rng(23);
        for _ in 0..200 {
            let x = Vector::<6>::from_fn(|_, _| uniform(&mut r, -8.0, 8.0));
            l.fallback(Some(x.as_slice()), &mut u);
            assert_eq!(u.as_slice(), controller.nominal(&x, 0.0).as_slice());
        }
        for last in [None, Some(&[f32::NAN; 6][..]), Some(&[1.0; 5][..])] {
            l.fallback(last, &mut u);
            assert_eq!(u.as_slice(), &[0.0; 3]);
        }
    }

    /// Checks SRACOS (every replacement strategy, with value suppression) and the diagonal
    /// CEM (every weighting) at N = 18 over the AUV box and at N = 4 over random boxes
    /// (widths 1e-3..1e3), with NaN/inf/extreme costs: every candidate inside the box, a
    /// non-finite cost rejected with the state unchanged, the best never increasing.
    #[test]
    fn sracos_and_cem_candidates_stay_in_bounds() {
        let mut r = rng(24);
        candidates_in_bounds::<18, _>(auv::sracos(400).unwrap(), &mut r, 400);
        candidates_in_bounds::<18, _>(auv::cem(400).unwrap(), &mut r, 400);
        for k in 0..12u32 {
            let lower = Vector::<4>::from_fn(|_, _| uniform(&mut r, -1e3, 1e3));
            let upper = Vector::<4>::from_fn(|i, _| {
                lower[i] + libm::powf(10.0, uniform(&mut r, -3.0, 3.0))
            });
            let bounds = Bounds::try_new(lower, upper).unwrap();
            let replacement = [
                Replacement::Worst,
                Replacement::Random,
                Replacement::LargestMargin,
            ][(k % 3) as usize];
            let suppression = (k % 2 == 1).then_some(Suppression {
                non_update_allowed: 4,
                resample_times: 2,
                balance_rate: 0.5,
            });
            let config = SracosConfig {
                replacement,
                suppression,
                uncertain_bits: Some(2),
                ..SracosConfig::DEFAULT
            };
            candidates_in_bounds::<4, _>(
                Sracos::<4, 2, 6>::try_new(bounds, config).unwrap(),
                &mut r,
                150,
            );
            let weighting = [
                Weighting::Cem,
                Weighting::CmaEs,
                Weighting::PiBb { h: 10.0 },
            ][(k % 3) as usize];
            let mean = bounds.sample_uniform(&mut r);
            let width = (upper - lower).min();
            let config = CemConfig {
                weighting,
                initial_variance: width * width,
                max_variance: 4.0 * width * width,
                ..CemConfig::DEFAULT
            };
            candidates_in_bounds::<4, _>(
                DiagonalCem::<4, 8, 4>::try_new(
                    bounds,
                    mean,
                    CemConfig {
                        elite: Some(4),
                        ..config
                    },
                )
                .unwrap(),
                &mut r,
                150,
            );
        }
    }

    /// ROCK* over seeded random boxes (widths 1e-3..1e30: it works in the box's unit
    /// coordinates), σ₀ and λ, with NaN/inf/extreme costs: every candidate and θ* inside the
    /// box, a non-finite cost rejected with the state unchanged, the best never increasing;
    /// and on a 4-D sphere it converges (σ ≤ tolerance) with θ* near the minimum. (Not the
    /// ill-conditioned ellipsoid: ROCK*'s σ rule shrinks σ when θ* stalls, and at condition
    /// 10³ about one run in three stops early; see the module docs.)
    #[test]
    fn rockstar_candidates_stay_in_bounds_and_it_converges() {
        let mut r = rng(31);
        for k in 0..12u32 {
            let lower = Vector::<4>::from_fn(|_, _| uniform(&mut r, -1e3, 1e3));
            let upper = Vector::<4>::from_fn(|i, _| {
                lower[i] + libm::powf(10.0, uniform(&mut r, -3.0, 30.0))
            });
            let bounds = Bounds::try_new(lower, upper).unwrap();
            let config = RockstarConfig {
                initial_sigma: libm::powf(10.0, uniform(&mut r, -4.0, 0.0)),
                lambda: uniform(&mut r, 0.1, 0.9),
                ..RockstarConfig::DEFAULT
            };
            let start = bounds.sample_uniform(&mut r);
            let rock = Rockstar::<4, 20>::try_new(bounds, start, config).unwrap();
            candidates_in_bounds::<4, _>(rock.clone(), &mut r, 120);
            let mut rock = rock;
            for _ in 0..60 {
                let Ok(_) = rock.ask(&mut r) else { break };
                rock.tell(wild_cost(&mut r)).ok();
                rock.tell(uniform(&mut r, 0.0, 10.0)).ok();
                assert!(bounds.contains(&rock.theta_star()), "box {}", k);
            }
        }
        let bounds = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let config = RockstarConfig {
            tolerance: 1e-3,
            max_evaluations: 3_000,
            ..RockstarConfig::DEFAULT
        };
        let mut rock = Rockstar::<4, 20>::try_new(bounds, Vector::zeros(), config).unwrap();
        let sphere = |theta: &Vector<4>| {
            (0..4)
                .map(|i| libm::powf(theta[i] - ellipsoid_minimiser::<4>(i), 2.0))
                .sum::<f32>()
        };
        while let Ok(theta) = rock.ask(&mut r) {
            rock.tell(sphere(&theta)).unwrap();
        }
        assert_eq!(rock.status(), Status::Converged);
        let star = rock.theta_star();
        for i in 0..4 {
            assert!(
                (star[i] - ellipsoid_minimiser::<4>(i)).abs() < 0.05,
                "θ*[{}] = {}",
                i,
                star[i]
            );
        }
    }

    /// `Rockstar<18, 90>` (the recommended memory, 5n) over the AUV box with wild costs: the
    /// same invariants at the size a firmware would deploy. Cortex-M4F only: the micro:bit's
    /// 16 KiB RAM cannot hold the two 10.6 KB copies the check compares.
    #[cfg(target_abi = "eabihf")]
    #[test]
    fn rockstar_at_the_auv_size_stays_in_bounds() {
        let mut r = rng(32);
        let rock = Rockstar::<18, 90>::try_new(
            auv::bounds().unwrap(),
            Vector::zeros(),
            RockstarConfig::DEFAULT,
        )
        .unwrap();
        candidates_in_bounds::<18, _>(rock, &mut r, 300);
    }

    /// LineBO (`LineBo<3, 8>`: the GP full and evicting after 8 episodes) over 16 seeded
    /// random boxes (widths 1e-3..1e3), starts and settings (length scale, signal variance,
    /// coordinate or random lines, 1 to 5 episodes per line, with and without a threshold),
    /// with NaN/inf/extreme costs: every candidate inside the box, a non-finite cost rejected
    /// with the whole state unchanged, the best never increasing, at most 8 episodes
    /// remembered.
    #[test]
    fn line_bo_candidates_stay_in_bounds_and_bad_costs_change_nothing() {
        let mut r = rng(41);
        for _ in 0..16 {
            let lower = Vector::<3>::from_fn(|_, _| uniform(&mut r, -1e3, 1e3));
            let upper = Vector::<3>::from_fn(|i, _| {
                lower[i] + libm::powf(10.0, uniform(&mut r, -3.0, 3.0))
            });
            let bounds = Bounds::try_new(lower, upper).unwrap();
            let config = LineBoConfig {
                length_scale: libm::powf(10.0, uniform(&mut r, -3.0, 1.0)),
                signal_variance: libm::powf(10.0, uniform(&mut r, -6.0, 6.0)),
                directions: if r.next_u32() % 2 == 0 {
                    LineDirections::Coordinate
                } else {
                    LineDirections::Random
                },
                evaluations_per_line: 1 + r.next_u32() % 5,
                threshold: (r.next_u32() % 2 == 0).then(|| uniform(&mut r, -1e3, 1e3)),
                ..LineBoConfig::DEFAULT
            };
            let start = bounds.sample_uniform(&mut r);
            let search = LineBo::<3, 8>::try_new(bounds, start, config).unwrap();
            candidates_in_bounds::<3, _>(search, &mut r, 40);
            let mut search = search;
            for _ in 0..20 {
                let Ok(_) = search.ask(&mut r) else { break };
                search.tell(uniform(&mut r, -1e3, 1e3)).unwrap();
            }
            assert!(search.remembered() <= 8);
        }
    }

    /// LineBO learns the 4-D quadratic of its host tests (`LineBo<4, 64>`, σ_f² = 4): from
    /// the corner (−1, …, −1) (cost 10.5) it reaches a cost below 10⁻² within 60 episodes
    /// with coordinate lines, and below 5·10⁻² within 100 with random lines; three seeds
    /// each, as on the host. Cortex-M4F only: the state (about 17 KB) exceeds the
    /// micro:bit's 16 KiB of RAM.
    #[cfg(target_abi = "eabihf")]
    #[test]
    fn line_bo_learns_a_quadratic() {
        let b = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        for (directions, budget, target) in [
            (LineDirections::Coordinate, 60, 1e-2),
            (LineDirections::Random, 100, 5e-2),
        ] {
            for seed in 0..3 {
                let config = line_bo_config(None, directions, budget);
                let mut s = LineBo::<4, 64>::try_new(b, Vector::repeat(-1.0), config).unwrap();
                let mut r = rng(seed);
                while let Ok(t) = s.ask(&mut r) {
                    s.tell(line_bo_quadratic(&t)).unwrap();
                }
                let best = s.best().unwrap().cost;
                assert!(best < target, "seed {}: best {}", seed, best);
            }
        }
    }

    /// LineBO with the threshold h = J(θ⁰) + 0.5 on the same quadratic (a well-specified
    /// model), as the host tests check it: every candidate other than θ⁰ has an upper
    /// confidence bound ≤ h when it is proposed (the library's own `upper_bound`, with 10⁻⁴
    /// (1 + |h|) of slack for rounding; `ask` does not change the GP), no episode's cost
    /// exceeds h, and the search still learns (coordinate lines below 2·10⁻², random lines
    /// below 1) within 60 episodes; three seeds each. Cortex-M4F only (the state's size).
    #[cfg(target_abi = "eabihf")]
    #[test]
    fn line_bo_safe_variant_stays_below_the_threshold() {
        let b = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let start = Vector::from([-0.5, 0.5, -0.5, 0.5]);
        let h = line_bo_quadratic(&start) + 0.5;
        for (directions, target) in [
            (LineDirections::Coordinate, 2e-2),
            (LineDirections::Random, 1.0),
        ] {
            for seed in 0..3 {
                let config = line_bo_config(Some(h), directions, 60);
                let mut s = LineBo::<4, 64>::try_new(b, start, config).unwrap();
                let mut r = rng(seed);
                while let Ok(t) = s.ask(&mut r) {
                    if t != start {
                        let u = s.upper_bound(&t);
                        assert!(u <= h + 1e-4 * (1.0 + h.abs()), "u = {} > h = {}", u, h);
                    }
                    let cost = line_bo_quadratic(&t);
                    assert!(cost <= h, "seed {}: cost {} > h = {}", seed, cost, h);
                    s.tell(cost).unwrap();
                }
                let best = s.best().unwrap().cost;
                assert!(best < target, "seed {}: best {}", seed, best);
            }
        }
    }

    /// `stack::measure` (the paint and scan of `scripts/sizes`) counts a call's frame: a call
    /// holding a 1 KiB array measures at least 1 KiB and not much more (its frame's saved
    /// registers and the paint guard: under 256 B more); a 2 KiB one 1 KiB more than that,
    /// to within a few words; measuring again after a deeper call forgets the deeper one.
    #[test]
    fn stack_measure_counts_a_call_frame() {
        let (_, one) = ctrl_adapt_firmware::stack::measure(frame_of::<256>);
        let (_, two) = ctrl_adapt_firmware::stack::measure(frame_of::<512>);
        let (_, again) = ctrl_adapt_firmware::stack::measure(frame_of::<256>);
        defmt::info!(
            "stack::measure: 1 KiB frame {=u32} B, 2 KiB frame {=u32} B",
            one,
            two
        );
        assert!(
            (1024..1024 + 256).contains(&one),
            "1 KiB frame measured {}",
            one
        );
        assert!(
            (i64::from(two) - i64::from(one) - 1024).abs() <= 16,
            "2 KiB frame {}, 1 KiB frame {}",
            two,
            one
        );
        assert_eq!(again, one);
    }

    /// Checks, in the target's f32: the plant model identifies x' = A x + B u + c from the
    /// ticks an AUV-sized adapter feeds it (a 1-D double integrator in each of 3 axes) to
    /// within 1e-2 at a random point (1.5e-3 measured on QEMU) and validates; a tick that would overflow is refused without change; and
    /// the model-based learner's proposals stay in its box, its radius in its range, and a
    /// non-finite cost changes nothing, with predictions that are sometimes NaN or errors.
    #[test]
    fn plant_model_and_model_based_learner() {
        use ctrl_adapt::model::{
            Affine, ModelBased, ModelBasedConfig, ModelConfig, OnlineModel, RlsModel,
        };
        use ctrl_adapt::{Cmaes, CmaesConfig};
        let plant = |x: &Vector<6>, u: &Vector<3>| {
            Vector::<6>::from_fn(|i, _| {
                if i < 3 {
                    x[i] - 0.1 * x[i + 3]
                } else {
                    0.9 * x[i] + 0.2 * u[i - 3] + 0.01
                }
            })
        };
        let model = RlsModel::<6, 3, 10>::try_new(ModelConfig::DEFAULT).unwrap();
        let mut adapter = auv::adapter(auv::coordinate_search(400).unwrap(), 60)
            .unwrap()
            .with_model(OnlineModel::new(model, Affine))
            .unwrap();
        let mut r = rng(21);
        for _ in 0..4 {
            adapter.begin_episode(&mut r).unwrap();
            let mut x = Vector::<6>::from_fn(|_, _| uniform(&mut r, -4.0, 4.0));
            for _ in 0..60 {
                let u = adapter.control(&x, &Vector::<3>::new(x[0], x[1], x[2]));
                x = plant(&x, &u);
            }
            adapter.end_episode().unwrap();
        }
        let fed = adapter.model();
        assert_eq!(fed.model().ticks(), 4 * 59);
        assert!(fed.model().validate().is_ok());
        let x = Vector::<6>::from_fn(|_, _| uniform(&mut r, -1.0, 1.0));
        let u = Vector::<3>::from_fn(|_, _| uniform(&mut r, -0.5, 0.5));
        let error = (fed.model().predict(&Affine, &x, &u) - plant(&x, &u)).amax();
        defmt::info!("model prediction error {=f32}", error);
        // Closed-loop ticks (the command follows the state) identify the plant less well
        // than an excitation would; the model without data (W = 0) errs by about 0.1.
        assert!(error < 1e-2, "prediction error {}", error);
        let mut model = *fed.model();
        let before = model;
        let huge = Vector::<6>::repeat(f32::MAX);
        assert!(model.update(&Affine, &huge, &u, &-huge).is_err());
        assert!(model == before);

        let bounds = Bounds::<4>::uniform(-1.0, 1.0).unwrap();
        let fallback =
            CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT).unwrap();
        let config = ModelBasedConfig {
            inner_evaluations: 40,
            ..ModelBasedConfig::DEFAULT
        };
        let mut learner = ModelBased::try_new(bounds, fallback, config).unwrap();
        learner.record(Vector::zeros(), 1.0).unwrap();
        learner.set_reference(1.0).unwrap();
        let inner = |b: Bounds<4>, start: Vector<4>| {
            let config = CmaesConfig {
                max_evaluations: 40,
                ..CmaesConfig::DEFAULT
            };
            Cmaes::<4, 6>::try_new(b, start, config)
        };
        let mut p = rng(22);
        for k in 0..30u32 {
            let proposal = learner
                .propose(&mut r, inner, |t| match p.next_u32() % 8 {
                    0 => Ok(f32::NAN),
                    1 => Err(Error::NonFinite("prediction")),
                    _ => Ok((t - Vector::repeat(0.3)).norm_squared()),
                })
                .unwrap();
            assert!(bounds.contains(&proposal.theta));
            let before = learner;
            assert_eq!(learner.tell(f32::NAN), Err(Error::NonFinite("cost")));
            assert!(learner == before);
            let cost = if k % 5 == 4 {
                wild_cost(&mut r)
            } else {
                (proposal.theta - Vector::repeat(0.3)).norm_squared()
            };
            if cost.is_finite() {
                learner.tell(cost).unwrap();
            } else {
                learner.tell(1e3).unwrap();
            }
            let radius = learner.radius();
            assert!(radius >= config.min_radius && radius <= config.max_radius);
        }
        assert!(learner.best().unwrap().cost < 0.05);
    }
}
