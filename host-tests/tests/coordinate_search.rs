//! Drives the library's `CoordinateSearch` through the host harness, at the size of the AUV
//! policy (18 parameters), on noisy objectives like real episode costs.

use ctrl_adapt::optimizer::{
    Bounds, CoordinateConfig, CoordinateSearch, Optimizer, Status, Vector,
};
use host_tests::{functions::sphere, run};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const N: usize = 18;

fn search(start: f32) -> CoordinateSearch<N> {
    let bounds = Bounds::<N>::uniform(-1.0, 1.0).unwrap();
    let config = CoordinateConfig {
        initial_step: 0.25,
        tolerance: 1e-3,
        max_evaluations: 5_000,
        ..CoordinateConfig::DEFAULT
    };
    CoordinateSearch::try_new(bounds, Vector::repeat(start), config).unwrap()
}

/// Sphere centred on 0.2·1 plus uniform noise of amplitude 1e-3 drawn from the caller's RNG.
fn noisy(theta: &Vector<N>, rng: &mut Xoshiro128PlusPlus) -> f32 {
    sphere(theta, 0.2) + 1e-3 * ctrl_adapt::optimizer::unit_f32(rng)
}

/// Checks: from the zero correction, on a noisy 18-D sphere (noise 1e-3), the search stops
/// by its own test within 5,000 evaluations with a best cost below 1e-2 (the start costs
/// 18·0.04 = 0.72), every candidate stayed in the box, and the best-cost curve never rose.
#[test]
fn learns_an_18_parameter_noisy_quadratic() {
    let mut s = search(0.0);
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2012);
    let bounds = *s.bounds();
    let result = run(
        &mut s,
        &mut rng,
        usize::MAX,
        |t, r| {
            assert!(bounds.contains(t));
            noisy(t, r)
        },
        |_, _, _| {},
    )
    .unwrap();
    assert_eq!(result.status, Status::Converged);
    assert!(result.costs[0] > 0.7);
    assert!(result.best_cost() < 1e-2, "best {}", result.best_cost());
    assert!(result.best_costs.windows(2).all(|w| w[1] <= w[0]));
}

/// Checks: a warm start closer to the optimum (as the global phase will hand over) reaches
/// cost 0.05 in fewer evaluations than the zero start, with the same seed.
#[test]
fn a_warm_start_reaches_the_threshold_sooner() {
    let episodes_to = |start: f32| {
        let mut s = search(start);
        let mut rng = Xoshiro128PlusPlus::seed_from_u64(7);
        let r = run(&mut s, &mut rng, 5_000, noisy, |_, _, _| {}).unwrap();
        r.best_costs
            .iter()
            .position(|&c| c < 0.05)
            .expect("threshold reached")
    };
    let (cold, warm) = (episodes_to(0.0), episodes_to(0.15));
    assert!(warm < cold, "warm {warm} vs cold {cold}");
}
