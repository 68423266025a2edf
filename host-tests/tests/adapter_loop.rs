//! The full episodic loop (adapter + PD + linear policy + optimizer) on a double integrator
//! with an unmodelled constant disturbance: the learned correction must beat the bare PD.

use ctrl_adapt::controller::{
    Adapter, AdapterConfig, CorrectedPd, EpisodeReport, LinearPolicy, Mode, Pd, StateFeatures,
};
use ctrl_adapt::cost::QuadraticCost;
use ctrl_adapt::optimizer::{
    Bounds, ControlledRandomSearch, CoordinateConfig, CoordinateSearch, CrsConfig, Optimizer,
    Phase, TwoPhase, Vector,
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
    episode_in(adapter, rng, DISTURBANCE).cost
}

/// Runs one episode through the adapter on a plant with `disturbance`; returns its report.
fn episode_in<O: Optimizer<2>>(
    adapter: &mut Adapter<O, Plant, QuadraticCost<1>, 2, 2, 1>,
    rng: &mut Xoshiro128PlusPlus,
    disturbance: f64,
) -> EpisodeReport<2> {
    adapter.begin_episode(rng).unwrap();
    let mut plant = DoubleIntegrator::new(disturbance, f64::from(DT));
    for _ in 0..TICKS {
        let error = (SETPOINT - plant.position) as f32;
        let state = Vector::from([error, plant.velocity as f32]);
        let u = adapter.control(&state, &Vector::repeat(error));
        plant.step(f64::from(u[0]));
    }
    let report = adapter.end_episode().unwrap();
    assert!(!report.failed);
    report
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

/// Checks: a two-phase adapter whose global phase runs in a simulator that differs from the
/// robot (a push of 0.5 m/s² instead of the robot's 1.5 m/s², so every simulator cost is
/// lower than any robot cost) deploys the θ that scored best *on the robot*, not the
/// simulator's best θ: costs from different conditions are never ranked against each other.
#[test]
fn two_phase_deploys_what_the_robot_measured() {
    const SIMULATOR_DISTURBANCE: f64 = -0.5;
    const GLOBAL: u32 = 30;
    let crs = ControlledRandomSearch::<2, 10>::try_new(bounds(), CrsConfig::DEFAULT).unwrap();
    let local = CoordinateConfig {
        initial_step: 1.0,
        tolerance: 1e-3,
        ..CoordinateConfig::DEFAULT
    };
    let two = TwoPhase::try_new(crs, GLOBAL, local).unwrap();
    let shaper = QuadraticCost::try_new(Vector::repeat(1.0)).unwrap();
    let mut adapter = Adapter::try_new(two, controller(), shaper, CONFIG, Vector::zeros()).unwrap();
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(2012);
    let mut robot = Vec::new();
    for _ in 0..CONFIG.learning_episodes {
        if adapter.optimizer().phase() == Phase::Global {
            episode_in(&mut adapter, &mut rng, SIMULATOR_DISTURBANCE);
        } else {
            robot.push(episode_in(&mut adapter, &mut rng, DISTURBANCE));
        }
    }
    assert_eq!(robot.len(), (CONFIG.learning_episodes - GLOBAL) as usize);
    let global = adapter.optimizer().global().best().unwrap();
    let robot_best = robot
        .iter()
        .min_by(|a, b| a.cost.total_cmp(&b.cost))
        .unwrap();
    // The premise: the simulator's best cost is below anything the robot measured, and the
    // robot found a better θ than the simulator's.
    assert!(robot.iter().all(|r| global.cost < r.cost), "{global:?}");
    assert_ne!(robot_best.theta, global.theta);
    assert_eq!(adapter.deployed_theta(), robot_best.theta);
    let deployed = episode_in(&mut adapter, &mut rng, DISTURBANCE);
    assert_eq!(adapter.mode(), Mode::Deploy);
    assert_eq!(deployed.theta, robot_best.theta);
    println!(
        "simulator best {:.4} at {:?}; robot best {:.4} at {:?}",
        global.cost, global.theta, robot_best.cost, robot_best.theta
    );
}
