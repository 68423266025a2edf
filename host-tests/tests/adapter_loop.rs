//! The full episodic loop (adapter + PD + linear policy + optimizer) on a double integrator
//! with an unmodelled constant disturbance: the learned correction must beat the bare PD.

use ctrl_adapt::controller::{
    Adapter, AdapterConfig, CorrectedPd, LinearPolicy, Mode, Pd, StateFeatures,
};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::optimizer::{
    Bounds, ControlledRandomSearch, CoordinateConfig, CoordinateSearch, CrsConfig, Optimizer,
    TwoPhase, Vector,
};
use host_tests::double_integrator::DoubleIntegrator;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const DT: f32 = 0.02;
const TICKS: u32 = 500; // 10 s episodes
const SETPOINT: f64 = 1.0;
const DISTURBANCE: f64 = -1.5; // m/s², pushes back towards the origin

type Plant = CorrectedPd<1, 2, 2, 2, StateFeatures<2>>;

fn controller() -> Plant {
    // PD tuned for the undisturbed plant: ω = 2 rad/s, ζ ≈ 0.9; acceleration limit 5 m/s².
    let pd = Pd::<1>::try_new(Vector::repeat(4.0), Vector::repeat(3.6))
        .unwrap()
        .with_limit(Vector::repeat(5.0))
        .unwrap();
    // Correction of the acceleration linear in [error, velocity], at most ±3 m/s².
    let policy = LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(3.0)).unwrap();
    CorrectedPd::new(pd, policy)
}

const CONFIG: AdapterConfig = AdapterConfig {
    dt: DT,
    failure_cost: 100.0,
    max_faulty_ticks: 0,
    learning_episodes: 60,
};

fn bounds() -> Bounds<2> {
    Bounds::uniform(-20.0, 20.0).unwrap()
}

/// Runs one episode through the adapter; returns the reported cost (∫ e² dt).
fn episode<O: Optimizer<2>>(
    adapter: &mut Adapter<O, Plant, QuadraticCost<1>, 2, 2, 1>,
    rng: &mut Xoshiro128PlusPlus,
) -> f32 {
    adapter.begin_episode(rng).unwrap();
    let mut plant = DoubleIntegrator::new(DISTURBANCE, f64::from(DT));
    for _ in 0..TICKS {
        let error = (SETPOINT - plant.position) as f32;
        let state = Vector::from([error, plant.velocity as f32]);
        let u = adapter.control(&state, &Vector::repeat(error));
        plant.step(f64::from(u[0]));
    }
    let report = adapter.end_episode().unwrap();
    assert!(!report.failed);
    report.cost
}

fn run<O: Optimizer<2>>(optimizer: O) -> (f32, f32, Vec<f32>) {
    let shaper = QuadraticCost::try_new(Vector::repeat(1.0)).unwrap();
    let mut adapter =
        Adapter::try_new(optimizer, controller(), shaper, CONFIG, Vector::zeros()).unwrap();
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2012);
    adapter.set_mode(Mode::Nominal).unwrap();
    let bare = episode(&mut adapter, &mut rng);
    adapter.set_mode(Mode::Learn).unwrap();
    let curve: Vec<f32> = (0..CONFIG.learning_episodes)
        .map(|_| episode(&mut adapter, &mut rng))
        .collect();
    // The learning budget is spent: the adapter rolls back to the best θ and keeps it.
    let deployed = episode(&mut adapter, &mut rng);
    assert_eq!(adapter.mode(), Mode::Deploy);
    (bare, deployed, curve)
}

/// Checks: with the coordinate search (60 episodes), the deployed correction's tracking cost
/// is at most 35 % of the bare PD's (the PD's steady error is d/k_p = 0.375 m).
#[test]
fn coordinate_search_correction_beats_the_bare_pd() {
    let config = CoordinateConfig {
        initial_step: 2.0,
        tolerance: 1e-3,
        ..CoordinateConfig::DEFAULT
    };
    let search = CoordinateSearch::try_new(bounds(), Vector::zeros(), config).unwrap();
    let (bare, deployed, curve) = run(search);
    println!("coordinate search: bare {bare:.4}, deployed {deployed:.4}, curve {curve:.3?}");
    assert!(deployed <= 0.35 * bare, "bare {bare}, deployed {deployed}");
}

/// Checks: the two-phase strategy (CRS for 30 episodes, then coordinate search from its
/// best) through the same adapter also gets the cost to at most 35 % of the bare PD's.
#[test]
fn two_phase_correction_beats_the_bare_pd() {
    let crs = ControlledRandomSearch::<2, 10>::try_new(bounds(), CrsConfig::DEFAULT).unwrap();
    let local = CoordinateConfig {
        initial_step: 1.0,
        tolerance: 1e-3,
        ..CoordinateConfig::DEFAULT
    };
    let two = TwoPhase::try_new(crs, 30, local).unwrap();
    let (bare, deployed, curve) = run(two);
    println!("two-phase: bare {bare:.4}, deployed {deployed:.4}, curve {curve:.3?}");
    assert!(deployed <= 0.35 * bare, "bare {bare}, deployed {deployed}");
}
