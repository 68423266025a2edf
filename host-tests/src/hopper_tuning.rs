//! How a nominal hopping gait is tuned: the paper's "initial policy was found from
//! optimization in simulation with constant control gains" (Hwangbo et al., section IV).
//! [`NominalHopping::TUNED`] is this procedure's result for [`HopperConfig::SCARLETH`]
//! (`tests/hopper_tuning.rs`), [`NominalHopping::SEA_TUNED`] for
//! [`HopperConfig::SCARLETH_SEA`] (`examples/hopper_sea.rs`).
//!
//! 1. A coarse grid with T = 0.62 s, knee mean −0.85 rad, kd = 0.6 over kp ∈ {20, 30, 45},
//!    phase ∈ {0.6, 0.7}, amplitude ∈ {0.5, 0.65}; the best grid point by the cost below
//!    is the start.
//! 2. The library's `CoordinateSearch` over the 6 parameters (T, knee mean, amplitude, phase,
//!    kp, kd) normalised to [0, 1] over the box [`LOWER`]..[`UPPER`], initial step 0.1,
//!    tolerance 1e-3, at most 600 episodes.
//!
//! Cost of one 8 s episode on flat ground ([`cost`]), apexes a_k after the first three hops:
//! 100·mean((a_k − 0.6)²) + 100·var(a_k) + 0.01·(steps with a torque over its limit + steps
//! with a joint in a stop + steps with a series-elastic motor at its limit) + 1e-4·∫Σ|τ q̇| dt,
//! plus 10 if the leg collapses and 5 + (4 − n) if fewer than n = 4 apexes were counted.

use ctrl_adapt::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Error, Status, Vector};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

use crate::hopper::{Hopper, HopperConfig, NominalHopping};
use crate::run;

/// Lower corner of the tuning box: (T, knee mean, amplitude, phase, kp, kd).
pub const LOWER: [f64; 6] = [0.3, -2.0, 0.0, 0.0, 5.0, 0.1];
/// Upper corner of the tuning box.
pub const UPPER: [f64; 6] = [1.0, -0.3, 0.9, 1.0, 150.0, 5.0];
/// Episodes of the coordinate search, at most.
pub const BUDGET: u32 = 600;

/// The gait of parameters `p` = (T, knee mean, amplitude, phase, kp, kd).
pub fn nominal(p: [f64; 6]) -> NominalHopping {
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

/// One episode of `nominal` on `config` (plant seed 1), stopped at a collapse.
pub fn episode(config: HopperConfig, nominal: NominalHopping) -> Hopper {
    let mut hopper = Hopper::new(config, 1);
    for _ in 0..hopper.steps_per_episode() {
        hopper.step(nominal.torques(&config, &hopper.state()));
        if hopper.collapsed() {
            break;
        }
    }
    hopper
}

/// The tuning cost of an episode (module docs).
pub fn cost(hopper: &Hopper) -> f64 {
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
    let violations = s.torque_limit_steps + s.joint_limit_steps + s.motor_limit_steps;
    c + 0.01 * f64::from(violations) + 1e-4 * s.absolute_work
}

/// What [`tune`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tuning {
    /// The best grid point and its cost.
    pub start: ([f64; 6], f64),
    /// The tuned gait.
    pub nominal: NominalHopping,
    /// Its cost.
    pub cost: f32,
    /// Episodes of the coordinate search.
    pub episodes: usize,
    /// How the coordinate search ended.
    pub status: Status,
}

/// The procedure of the module docs for the leg `leg`, on flat ground, 8 s episodes.
pub fn tune(leg: HopperConfig) -> Result<Tuning, Error> {
    let config = HopperConfig {
        episode_duration: 8.0,
        ground_heights: &[0.0],
        ..leg
    };
    let mut start: Option<([f64; 6], f64)> = None;
    for kp in [20.0, 30.0, 45.0] {
        for phase in [0.6, 0.7] {
            for amplitude in [0.5, 0.65] {
                let p = [0.62, -0.85, amplitude, phase, kp, 0.6];
                let c = cost(&episode(config, nominal(p)));
                if start.is_none_or(|(_, best)| c < best) {
                    start = Some((p, c));
                }
            }
        }
    }
    let start = start.ok_or(Error::InvalidParameter("grid"))?;
    let search_config = CoordinateConfig {
        initial_step: 0.1,
        tolerance: 1e-3,
        max_evaluations: BUDGET,
        ..CoordinateConfig::DEFAULT
    };
    let mut search =
        CoordinateSearch::try_new(Bounds::uniform(0.0, 1.0)?, to_unit(start.0), search_config)?;
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(1);
    let result = run(
        &mut search,
        &mut rng,
        BUDGET as usize,
        |u, _| cost(&episode(config, nominal(from_unit(u)))) as f32,
        |_, _, _| {},
    )?;
    Ok(Tuning {
        start,
        nominal: nominal(from_unit(&result.best_theta)),
        cost: result.best_cost(),
        episodes: result.costs.len(),
        status: result.status,
    })
}
