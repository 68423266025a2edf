//! Helpers shared by the unit tests: one home instead of a copy in each test module.

extern crate std;
use std::vec::Vec;

use proptest::prelude::*;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

use crate::optimizer::{
    AnyOptimizer, Best, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
    CoordinateSearch, CrsConfig, DiagonalCem, LineBo, LineBoConfig, LineDirections, Optimizer,
    Rockstar, RockstarConfig, Sracos, SracosConfig, Status, TwoPhase,
};
use crate::random::unit_f32;
use nalgebra::SMatrix;

use crate::{Bounds, Error, Vector};

/// The tests' RNG, seeded (xoshiro128++, as in the firmware examples).
pub(crate) fn rng(seed: u64) -> Xoshiro128PlusPlus {
    Xoshiro128PlusPlus::seed_from_u64(seed)
}

/// Checks the call-order contract on `s`, a fresh optimizer with a budget of exactly 3:
/// `tell` without `ask` is refused, a second `ask` repeats the pending candidate, a second
/// `tell` is refused, the budget stops the search and `ask` then says so; the best is the
/// first candidate (told 1.0, the others 2.0). Returns that first candidate.
pub(crate) fn check_call_order<const N: usize, O: Optimizer<N>>(s: &mut O) -> Vector<N> {
    let mut r = rng(0);
    assert_eq!(s.tell(1.0), Err(Error::NoPendingAsk));
    let first = s.ask(&mut r).unwrap();
    assert_eq!(
        s.ask(&mut r).unwrap(),
        first,
        "a second ask repeats the pending one"
    );
    assert_eq!(s.pending(), Some(&first));
    s.tell(1.0).unwrap();
    assert_eq!(s.tell(1.0), Err(Error::NoPendingAsk));
    for _ in 0..2 {
        s.ask(&mut r).unwrap();
        s.tell(2.0).unwrap();
    }
    assert_eq!(s.status(), Status::BudgetSpent);
    assert_eq!(s.evaluations(), 3);
    assert_eq!(s.ask(&mut r), Err(Error::Stopped));
    assert_eq!(
        s.best().unwrap(),
        Best {
            theta: first,
            cost: 1.0
        }
    );
    first
}

/// Checks, over `evaluations` asks and tells of the sphere ‖θ‖²: `tell` without a pending
/// candidate, and NaN or infinite costs, are errors that leave the whole state unchanged
/// (the candidate stays pending and is told afterwards); a repeated `ask` returns the
/// pending candidate.
pub(crate) fn check_rejected_calls_change_nothing<const N: usize, O>(s: &mut O, evaluations: u32)
where
    O: Optimizer<N> + Clone + PartialEq + core::fmt::Debug,
{
    let mut r = rng(7);
    for _ in 0..evaluations {
        let before = s.clone();
        assert_eq!(s.tell(1.0), Err(Error::NoPendingAsk));
        assert_eq!(*s, before);
        let t = s.ask(&mut r).unwrap();
        assert_eq!(
            s.ask(&mut r).unwrap(),
            t,
            "a second ask repeats the pending one"
        );
        assert_eq!(s.pending(), Some(&t));
        let pending = s.clone();
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(s.tell(bad), Err(Error::NonFinite("cost")));
            assert_eq!(*s, pending);
        }
        s.tell(t.norm_squared()).unwrap();
    }
}

/// The (candidate, cost) sequence of `s` from `seed` until it stops, with the cost
/// `objective(θ)` plus noise `noise`·U[0, 1) drawn from the same RNG (so a run depends on the
/// seed through both).
pub(crate) fn trace<const N: usize, O: Optimizer<N>>(
    mut s: O,
    seed: u64,
    noise: f32,
    objective: impl Fn(&Vector<N>) -> f32,
) -> Vec<(Vector<N>, f32)> {
    let mut r = rng(seed);
    let mut out = Vec::new();
    while let Ok(t) = s.ask(&mut r) {
        let cost = objective(&t) + noise * unit_f32(&mut r);
        s.tell(cost).unwrap();
        out.push((t, cost));
    }
    out
}

/// Checks that a run (see [`trace`]) depends on the seed only: seed 42 twice gives the same
/// candidates and costs, seed 43 others. Returns the run's length.
pub(crate) fn check_seeded<const N: usize, O: Optimizer<N> + Clone>(
    s: &O,
    noise: f32,
    objective: impl Fn(&Vector<N>) -> f32 + Copy,
) -> usize {
    let run = |seed: u64| trace(s.clone(), seed, noise, objective);
    let first = run(42);
    assert_eq!(first, run(42), "the same seed, the same run");
    assert_ne!(first, run(43), "another seed, another run");
    first.len()
}

/// Boxes with corners in ±10³ and widths from `min_width` to 10³, for property tests.
pub(crate) fn any_bounds<const N: usize>(min_width: f32) -> impl Strategy<Value = Bounds<N>> {
    prop::array::uniform::<_, N>((-1e3f32..1e3, min_width..1e3)).prop_map(|pairs| {
        let lower = Vector::from(pairs.map(|(lo, _)| lo));
        let upper = Vector::from(pairs.map(|(lo, w)| lo + w));
        Bounds::try_new(lower, upper).unwrap()
    })
}

/// Boxes with corners in ±10³ and widths log-uniform from 10⁻² to 10³⁰, for property tests
/// of optimizers that normalise the box.
pub(crate) fn any_wide_bounds<const N: usize>() -> impl Strategy<Value = Bounds<N>> {
    prop::array::uniform::<_, N>((-1e3f32..1e3, -2.0f32..30.0)).prop_map(|pairs| {
        let lower = Vector::from(pairs.map(|(lo, _)| lo));
        let upper = Vector::from(pairs.map(|(lo, e)| lo + libm::powf(10.0, e)));
        Bounds::try_new(lower, upper).unwrap()
    })
}

/// A box drawn by `boxes` and a start drawn uniformly inside it, for property tests.
pub(crate) fn with_start<const N: usize>(
    boxes: impl Strategy<Value = Bounds<N>>,
) -> impl Strategy<Value = (Bounds<N>, Vector<N>)> {
    (boxes, prop::array::uniform::<_, N>(0.0f32..=1.0)).prop_map(|(bounds, frac)| {
        let start = Vector::from_fn(|i, _| {
            let (lo, hi) = (bounds.lower()[i], bounds.upper()[i]);
            (lo + frac[i] * (hi - lo)).clamp(lo, hi)
        });
        (bounds, start)
    })
}

/// A fixed rotation of R¹⁰ (for the ill-conditioned test problems of `Cmaes` and `Rockstar`): the product of two Householder reflections.
pub(crate) fn rotation() -> SMatrix<f32, 10, 10> {
    let reflect = |v: Vector<10>| {
        SMatrix::<f32, 10, 10>::identity() - v * v.transpose() * (2.0 / v.norm_squared())
    };
    let a = Vector::<10>::from_fn(|i, _| (i + 1) as f32);
    let b = Vector::<10>::from_fn(|i, _| (10 - i) as f32 * if i % 2 == 0 { 1.0 } else { -0.5 });
    reflect(a) * reflect(b)
}

/// The rotated ellipsoid Σ cond^{i/9} (R(θ − 0.3))_i²: condition number `cond`, axes
/// not aligned with the coordinates, minimum 0 at θ = 0.3·1.
pub(crate) fn ellipsoid(cond: f32) -> impl Fn(&Vector<10>) -> f32 {
    let r = rotation();
    move |t: &Vector<10>| {
        let z = r * (t - Vector::repeat(0.3));
        (0..10)
            .map(|i| libm::powf(cond, i as f32 / 9.0) * z[i] * z[i])
            .sum()
    }
}

/// Runs `opt` on `f` until it stops (its RNG seeded with `seed`); returns the evaluations at
/// which the best cost first fell below `target`, if it did.
pub(crate) fn evaluations_to_target<const N: usize, O: Optimizer<N>>(
    opt: &mut O,
    f: impl Fn(&Vector<N>) -> f32,
    seed: u64,
    target: f32,
) -> Option<u32> {
    let mut r = rng(seed);
    let mut hit = None;
    while let Ok(t) = opt.ask(&mut r) {
        opt.tell(f(&t)).unwrap();
        if hit.is_none() && opt.best().is_some_and(|b| b.cost < target) {
            hit = Some(opt.evaluations());
        }
    }
    hit
}

/// Drives `s` through `costs` (any f32) with the RNG seeded by `seed` and checks after every
/// step: the candidate is inside `bounds`; a finite cost is accepted, a non-finite one refused
/// with the state unchanged; the best cost never rises; and `invariant(s, cost)`, the
/// optimizer's own, given the cost just told. Stops early when the search stops.
pub(crate) fn check_any_costs<const N: usize, O>(
    s: &mut O,
    bounds: &Bounds<N>,
    costs: &[f32],
    seed: u64,
    mut invariant: impl FnMut(&O, f32) -> Result<(), TestCaseError>,
) -> Result<(), TestCaseError>
where
    O: Optimizer<N> + Clone + PartialEq + core::fmt::Debug,
{
    let mut r = rng(seed);
    let mut best = f32::INFINITY;
    for &cost in costs {
        let Ok(theta) = s.ask(&mut r) else { break };
        prop_assert!(bounds.contains(&theta), "{theta:?} outside {bounds:?}");
        let before = s.clone();
        let told = s.tell(cost);
        if cost.is_finite() {
            prop_assert!(told.is_ok());
        } else {
            prop_assert_eq!(told, Err(Error::NonFinite("cost")));
            prop_assert_eq!(&*s, &before);
        }
        invariant(s, cost)?;
        let now = s.best().map_or(f32::INFINITY, |b| b.cost);
        prop_assert!(now <= best);
        best = now;
    }
    Ok(())
}

/// After `warmup` (finite costs, told while the search runs), a `tell` of `cost` with
/// (`ask_first`) or without a pending candidate is accepted exactly when there is one and
/// the cost is finite, and never panics.
pub(crate) fn check_tell_after<const N: usize, O: Optimizer<N>>(
    s: &mut O,
    warmup: &[f32],
    ask_first: bool,
    cost: f32,
) -> Result<(), TestCaseError> {
    let mut r = rng(0);
    for &c in warmup {
        let Ok(_) = s.ask(&mut r) else { break };
        s.tell(c).unwrap();
    }
    if ask_first && s.ask(&mut r).is_ok() {
        prop_assert_eq!(s.tell(cost).is_ok(), cost.is_finite());
    } else {
        prop_assert_eq!(s.tell(cost), Err(Error::NoPendingAsk));
    }
    Ok(())
}

/// Asks and tells `f` of each candidate, `evaluations` times (`None`: until the search
/// stops), checking that every candidate is inside `bounds`.
pub(crate) fn tell_inside<const N: usize, O: Optimizer<N>>(
    opt: &mut O,
    bounds: &Bounds<N>,
    r: &mut Xoshiro128PlusPlus,
    f: impl Fn(&Vector<N>) -> f32,
    evaluations: Option<u32>,
) {
    let mut told = 0;
    while evaluations.is_none_or(|n| told < n) {
        let Ok(t) = opt.ask(r) else {
            assert!(evaluations.is_none(), "stopped after {told} evaluations");
            return;
        };
        assert!(bounds.contains(&t), "{t:?} outside {bounds:?}");
        opt.tell(f(&t)).unwrap();
        told += 1;
    }
}

/// One case of [`check_rejected_configs`]: a change to the default configuration and the
/// parameter the error must name.
pub(crate) type Rejection<C> = (fn(&mut C), &'static str);

/// Checks: `build` refuses each change of `default` with [`Error::InvalidParameter`] naming
/// the case's parameter.
pub(crate) fn check_rejected_configs<C: Copy, T>(
    default: C,
    build: impl Fn(C) -> Result<T, Error>,
    cases: &[Rejection<C>],
) {
    for (i, &(change, parameter)) in cases.iter().enumerate() {
        let mut config = default;
        change(&mut config);
        let error = build(config).err();
        assert_eq!(
            error,
            Some(Error::InvalidParameter(parameter)),
            "case {i} ({parameter})"
        );
    }
}

/// Checks: `build` refuses a start outside the box [−1, 1]² and a non-finite one, each
/// with the error naming `name`.
pub(crate) fn check_rejected_starts<T>(
    name: &'static str,
    build: impl Fn(Vector<2>) -> Result<T, Error>,
) {
    assert_eq!(
        build([2.0, 0.0].into()).err(),
        Some(Error::OutOfBounds(name))
    );
    assert_eq!(
        build([f32::NAN, 0.0].into()).err(),
        Some(Error::NonFinite(name))
    );
}

/// Every optimizer of the enum at N = 3 with its default configuration (CMA-ES with and
/// without the active update, LineBO with and without a threshold and with random
/// lines), for the contract that does not depend on the algorithm.
pub(crate) fn every_optimizer() -> [AnyOptimizer<3, 4, 2, 5, 8>; 11] {
    let b = Bounds::<3>::uniform(-1.0, 1.0).unwrap();
    let z = Vector::zeros();
    let crs = || ControlledRandomSearch::try_new(b, CrsConfig::DEFAULT).unwrap();
    let active = CmaesConfig {
        active: true,
        ..CmaesConfig::DEFAULT
    };
    let safe = LineBoConfig {
        threshold: Some(0.0),
        ..LineBoConfig::DEFAULT
    };
    let random = LineBoConfig {
        directions: LineDirections::Random,
        ..LineBoConfig::DEFAULT
    };
    [
        CoordinateSearch::try_new(b, z, CoordinateConfig::DEFAULT)
            .unwrap()
            .into(),
        crs().into(),
        TwoPhase::try_new(crs(), 8, CoordinateConfig::DEFAULT)
            .unwrap()
            .into(),
        Sracos::try_new(b, SracosConfig::DEFAULT).unwrap().into(),
        DiagonalCem::try_new(b, z, CemConfig::DEFAULT)
            .unwrap()
            .into(),
        Cmaes::try_new(b, z, CmaesConfig::DEFAULT).unwrap().into(),
        Cmaes::try_new(b, z, active).unwrap().into(),
        Rockstar::try_new(b, z, RockstarConfig::DEFAULT)
            .unwrap()
            .into(),
        LineBo::try_new(b, z, LineBoConfig::DEFAULT).unwrap().into(),
        LineBo::try_new(b, z, safe).unwrap().into(),
        LineBo::try_new(b, z, random).unwrap().into(),
    ]
}
