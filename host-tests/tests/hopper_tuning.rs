//! How [`NominalHopping::TUNED`] was found: the paper's "initial policy was found from
//! optimization in simulation with constant control gains". About 200 episodes of 8 s
//! (5 s in release, much longer in debug), so it is compiled in release builds only (debug
//! `cargo test` skips it) and CI runs it in release:
//!
//! ```text
//! cargo test --release -p host-tests --test hopper_tuning -- --nocapture
//! ```
//!
//! 1. A coarse grid with T = 0.62 s, knee mean −0.85 rad, kd = 0.6 over kp ∈ {20, 30, 45},
//!    phase ∈ {0.6, 0.7}, amplitude ∈ {0.5, 0.65}; the best grid point by the cost below
//!    is the start.
//! 2. The library's `CoordinateSearch` over the 6 parameters (T, knee mean, amplitude, phase,
//!    kp, kd) normalised to [0, 1] over the box `LOWER..UPPER`, initial step 0.1, tolerance
//!    1e-3, at most 600 episodes.
//!
//! Cost of one 8 s episode on flat ground, apexes a_k after the first three hops:
//! 100·mean((a_k − 0.6)²) + 100·var(a_k) + 0.01·(steps with a torque over its limit + steps
//! with a joint in a stop) + 1e-4·∫Σ|τ q̇| dt, plus 10 if the leg collapses and 5 + (4 − n)
//! if fewer than n = 4 apexes were counted. `TUNED` is the result rounded to two significant
//! decimals.

#![cfg(not(debug_assertions))]

use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Vector};
use host_tests::hopper::{Hopper, HopperConfig, NominalHopping};
use host_tests::run;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

const LOWER: [f64; 6] = [0.3, -2.0, 0.0, 0.0, 5.0, 0.1];
const UPPER: [f64; 6] = [1.0, -0.3, 0.9, 1.0, 150.0, 5.0];

fn controller(p: [f64; 6]) -> NominalHopping {
    NominalHopping {
        period: p[0],
        knee_mean: p[1],
        knee_amplitude: p[2],
        phase: p[3],
        kp: p[4],
        kd: p[5],
    }
}

fn from_unit(u: &Vector<6>) -> [f64; 6] {
    core::array::from_fn(|i| LOWER[i] + f64::from(u[i]) * (UPPER[i] - LOWER[i]))
}

fn to_unit(p: [f64; 6]) -> Vector<6> {
    Vector::from_fn(|i, _| ((p[i] - LOWER[i]) / (UPPER[i] - LOWER[i])) as f32)
}

fn episode(config: HopperConfig, nominal: NominalHopping) -> Hopper {
    let mut hopper = Hopper::new(config, 1);
    for _ in 0..hopper.steps_per_episode() {
        hopper.step(nominal.torques(&config, &hopper.state()));
        if hopper.collapsed() {
            break;
        }
    }
    hopper
}

fn cost(hopper: &Hopper) -> f64 {
    let mut c = if hopper.collapsed() { 10.0 } else { 0.0 };
    let a: Vec<f64> = hopper.apex_heights().iter().skip(3).copied().collect();
    if a.len() < 4 {
        return c + 5.0 + (4 - a.len()) as f64;
    }
    let n = a.len() as f64;
    let mse = a.iter().map(|x| (x - 0.6).powi(2)).sum::<f64>() / n;
    let mean = a.iter().sum::<f64>() / n;
    let var = a.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    let s = hopper.stats();
    c += 100.0 * mse + 100.0 * var;
    c + 0.01 * f64::from(s.torque_limit_steps + s.joint_limit_steps) + 1e-4 * s.absolute_work
}

/// Checks: the tuning procedure above ends on a controller that hops on flat ground with
/// every apex (after three hops) within 1 cm of 0.6 m, without limit violations, and prints
/// it next to `TUNED`, which must meet the same test.
#[test]
fn reproduce_the_nominal_hopping_tuning() {
    let config = HopperConfig {
        episode_duration: 8.0,
        ..HopperConfig::flat()
    };
    let mut start = None;
    for kp in [20.0, 30.0, 45.0] {
        for phase in [0.6, 0.7] {
            for amplitude in [0.5, 0.65] {
                let p = [0.62, -0.85, amplitude, phase, kp, 0.6];
                let c = cost(&episode(config, controller(p)));
                if start.is_none_or(|(_, best)| c < best) {
                    start = Some((p, c));
                }
            }
        }
    }
    let (start, start_cost) = start.unwrap();
    println!("grid start {start:?} (cost {start_cost:.4})");
    let bounds = Bounds::<6>::uniform(0.0, 1.0).unwrap();
    let search_config = CoordinateConfig {
        initial_step: 0.1,
        tolerance: 1e-3,
        max_evaluations: 600,
        ..CoordinateConfig::DEFAULT
    };
    let mut search = CoordinateSearch::try_new(bounds, to_unit(start), search_config).unwrap();
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let result = run(
        &mut search,
        &mut rng,
        600,
        |u, _| cost(&episode(config, controller(from_unit(u)))) as f32,
        |_, _, _| {},
    )
    .unwrap();
    let tuned = controller(from_unit(&result.best_theta));
    println!(
        "coordinate search: {} episodes, status {:?}, cost {:.4}\n  found {tuned:?}\n  TUNED {:?}",
        result.costs.len(),
        result.status,
        result.best_cost(),
        NominalHopping::TUNED
    );
    for nominal in [tuned, NominalHopping::TUNED] {
        let hopper = episode(HopperConfig::flat(), nominal);
        let a = &hopper.apex_heights()[3..];
        let max = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = a.iter().copied().fold(f64::INFINITY, f64::min);
        let s = hopper.stats();
        println!("  apex {min:.4}..{max:.4} m over {} hops", a.len());
        assert!(max - min < 0.01 && (max - 0.6).abs() < 0.01 && (min - 0.6).abs() < 0.01);
        assert_eq!((s.torque_limit_steps, s.joint_limit_steps), (0, 0));
    }
}
