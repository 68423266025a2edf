//! The via-point task of Stulp & Sigaud 2012, section 3.1 (taken there from Theodorou, Buchli
//! & Schaal 2010): a planar arm of D = 10 links, 1 m long, whose joint angles follow a
//! D-dimensional dynamic movement primitive (DMP) with B = 5 basis functions per joint, so
//! the policy has D·B = 50 parameters. Host (std) code, simulated in `f64`.
//!
//! # The task as the paper gives it
//! * The arm starts stretched along the x axis. Before learning, every joint follows a
//!   0.5 s minimum-jerk movement to the pose where the arm "touches" the y axis, and the
//!   DMP weights θ are obtained by fitting the DMP to that movement.
//! * The goal is that the end effector passes through (0.5, 0.5) at t = 0.3 s while keeping
//!   the joint accelerations small, the cost (24):
//!   J(τ_t) = δ(t − 0.3)·((x_t − 0.5)² + (y_t − 0.5)²) + Σ_d (D+1−d) ä_{d,t}² / Σ_d (D+1−d),
//!   where the weight D+1−d makes joints near the base more expensive to accelerate.
//! * Exploration is "constant" (section 3.2): θ is drawn once per episode and kept for the
//!   whole movement, so an episode has one cost J(θ), as the ask/tell optimizers need.
//!
//! # What the paper leaves open (documented choices)
//! * **The final pose.** Joint 1 turns by π/(2D) and every other joint by π/D, so the links
//!   point at the angles (2d − 1)π/(2D), d = 1..D: the arm becomes half a regular 20-gon and
//!   its tip lands exactly on the y axis, at (0, 0.1/sin(π/20)) ≈ (0, 0.639). This is "the
//!   pose where the arm touches the y axis" (the same pose as in Stulp's public `dmp_bbo` Matlab code).
//! * **The DMP.** The formulation of Ijspeert, Nakanishi, Hoffmann, Pastor & Schaal (2013):
//!   τ ż = α_z(β_z(g − y) − z) + f(x), τ ẏ = z, τ ẋ = −α_x x, with
//!   f(x) = Σ_b ψ_b(x) θ_b / Σ_b ψ_b(x) · x · (g − y₀), α_z = 25, β_z = α_z/4 (critically
//!   damped), τ = 0.5 s and α_x = ln 100 (the phase decays to 0.01 at t = τ). The B Gaussian
//!   basis functions ψ_b(x) = exp(−(x − c_b)²/(2w_b²)) have centres c_b = x(t_b) at times
//!   t_b equally spaced over [0, τ] and widths w_b half the distance to the next centre.
//!   With this scaling the minimum-jerk weights are of order 10²; the paper's initial
//!   exploration Σ = 10⁴·I (standard deviation 100 per weight) is of the same order, as it
//!   must be for the paper's λ_init sweep to mean what it means there.
//! * **Time.** Semi-implicit Euler at Δt = 1 ms over [0, τ] (500 steps; t = 0.3 s is step
//!   300 exactly); the phase x(t) uses its closed form.
//! * **The weights of (24).** Written literally, the via-point term (0.06 m² for the
//!   minimum-jerk start) would be negligible next to the acceleration term (40 rad²/s³
//!   integrated over the movement), and the learned motion would not pass through the via
//!   point as in the paper's figure 2. Theodorou et al. 2010, whose task this is, weight the
//!   via-point term by 10⁸ against per-time-step acceleration costs. We use
//!   J(θ) = [`VIA_WEIGHT`]·‖p(0.3) − (0.5, 0.5)‖² + ∫₀^τ Σ_d (D+1−d) ä_d² / Σ_d (D+1−d) dt,
//!   i.e. (24) integrated over time with the δ scaled by [`VIA_WEIGHT`] = 10⁸: the start
//!   costs 6.3·10⁶, the learned movements (`experiments/findings/via-point-arm.md`) cost 10³–10⁴ and miss the via
//!   point by a few millimetres, where the acceleration term matters again. Only the ratio
//!   of the two terms matters to the optimizers: CEM and CMA-ES weights are rank based and
//!   PI-BB normalises costs by their range.
//! * **A box.** The optimizers need one; every weight stays in ±[`WEIGHT_LIMIT`] = ±10⁴,
//!   ten standard deviations of the paper's largest exploration (λ = 10⁶) away from the
//!   minimum-jerk weights, so it almost never clips.

use ctrl_adapt::optimizer::{Bounds, CemConfig, DiagonalCem, Error, Optimizer, Status, Vector};
use nalgebra::{SMatrix, SVector};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

/// D: number of links and joints.
pub const LINKS: usize = 10;
/// B: basis functions per joint.
pub const BASIS: usize = 5;
/// D·B: parameters of the policy.
pub const PARAMS: usize = LINKS * BASIS;
/// Length of each link (m); the arm is 1 m long.
pub const LINK_LENGTH: f64 = 0.1;
/// τ: duration of the movement (s).
pub const DURATION: f64 = 0.5;
/// Integration step (s).
pub const DT: f64 = 1e-3;
/// Time at which the end effector should pass the via point (s).
pub const VIA_TIME: f64 = 0.3;
/// The via point (m).
pub const VIA_POINT: [f64; 2] = [0.5, 0.5];
/// Weight of the via-point term (1/m²); see "The weights of (24)" in the module docs.
pub const VIA_WEIGHT: f64 = 1e8;
/// Every DMP weight is kept in [−`WEIGHT_LIMIT`, `WEIGHT_LIMIT`]. The paper has no box; this
/// one is 10 standard deviations of its largest exploration (λ = 10⁶) away from the
/// minimum-jerk weights (|θ| < 400), so it almost never clips.
pub const WEIGHT_LIMIT: f32 = 1e4;

const ALPHA_Z: f64 = 25.0;
const BETA_Z: f64 = ALPHA_Z / 4.0;
/// α_x = ln 100: x(τ) = 0.01.
const ALPHA_X: f64 = 4.605_170_185_988_091;
const STEPS: usize = 500;
/// The integration step after which the via point is checked (t = 0.3 s).
pub const VIA_STEP: usize = 300;

/// The two terms of the episode cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CostTerms {
    /// ‖p(0.3 s) − via point‖² (m²), before weighting.
    pub via_distance2: f64,
    /// ∫ Σ_d (D+1−d) ä_d² / Σ_d (D+1−d) dt (rad²/s³).
    pub acceleration: f64,
}

impl CostTerms {
    /// The episode cost J(θ) = [`VIA_WEIGHT`]·via + acceleration.
    pub fn total(&self) -> f64 {
        VIA_WEIGHT * self.via_distance2 + self.acceleration
    }
}

/// The via-point arm: the DMP's basis features, precomputed per time step, plus the start
/// and goal poses. Evaluating θ is one episode.
#[derive(Debug, Clone)]
pub struct ViaPointArm {
    /// φ_b(t) = ψ_b(x_t)/Σψ(x_t) · x_t at each integration step (f = (g − y₀)·φ·θ).
    features: Vec<[f64; BASIS]>,
    start: [f64; LINKS],
    goal: [f64; LINKS],
}

impl Default for ViaPointArm {
    fn default() -> Self {
        Self::new()
    }
}

impl ViaPointArm {
    /// The task of the module docs.
    pub fn new() -> Self {
        let features = (0..STEPS).map(|i| features_at(i as f64 * DT)).collect();
        let mut goal = [std::f64::consts::PI / LINKS as f64; LINKS];
        goal[0] /= 2.0;
        Self {
            features,
            start: [0.0; LINKS],
            goal,
        }
    }

    /// The start joint angles y₀ (rad): the stretched arm.
    pub fn start(&self) -> &[f64; LINKS] {
        &self.start
    }

    /// The goal joint angles g (rad): the arm touches the y axis.
    pub fn goal(&self) -> &[f64; LINKS] {
        &self.goal
    }

    /// θ fitted to the 0.5 s minimum-jerk movement from the stretched arm to the goal pose
    /// (least squares over the 500 time steps). The movement is the same shape for every
    /// joint and f is scaled by g − y₀, so every joint gets the same B weights.
    pub fn minimum_jerk_theta(&self) -> Vector<PARAMS> {
        let mut ata = SMatrix::<f64, BASIS, BASIS>::zeros();
        let mut atb = SVector::<f64, BASIS>::zeros();
        for (i, phi) in self.features.iter().enumerate() {
            // Unit amplitude: y₀ = 0, g = 1.
            let s = i as f64 * DT / DURATION;
            let y = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
            let yd = 30.0 * s * s * (1.0 - s) * (1.0 - s) / DURATION;
            let ydd = 60.0 * s * (1.0 - 3.0 * s + 2.0 * s * s) / (DURATION * DURATION);
            // τ² ÿ = α_z(β_z(g − y) − τ ẏ) + f.
            let target = DURATION * DURATION * ydd - ALPHA_Z * (BETA_Z * (1.0 - y) - DURATION * yd);
            let phi = SVector::<f64, BASIS>::from(*phi);
            ata += phi * phi.transpose();
            atb += phi * target;
        }
        ata += SMatrix::<f64, BASIS, BASIS>::identity() * 1e-10;
        let weights = ata
            .cholesky()
            .expect("the basis features are linearly independent")
            .solve(&atb);
        Vector::from_fn(|k, _| weights[k % BASIS] as f32)
    }

    /// Integrates the DMPs with parameters θ (joint d uses θ[d·B..(d+1)·B]) and returns the
    /// cost terms of the episode.
    pub fn evaluate(&self, theta: &Vector<PARAMS>) -> CostTerms {
        self.simulate(theta, |_, _, _, _| {})
    }

    /// One episode's ticks for a model of the arm's DMPs: the state [y, z] (joint angles,
    /// scaled velocities) at every step, from the start to the end (501 states), and the
    /// forcing term of each joint at each of the 500 steps, with the episode's cost terms.
    pub fn ticks(
        &self,
        theta: &Vector<PARAMS>,
    ) -> (Vec<[f64; 2 * LINKS]>, Vec<[f64; LINKS]>, CostTerms) {
        let mut states = vec![[0.0; 2 * LINKS]];
        states[0][..LINKS].copy_from_slice(&self.start);
        let mut forcings = Vec::with_capacity(STEPS);
        let terms = self.simulate(theta, |_, y, z, forcing| {
            let mut state = [0.0; 2 * LINKS];
            state[..LINKS].copy_from_slice(y);
            state[LINKS..].copy_from_slice(z);
            states.push(state);
            forcings.push(*forcing);
        });
        (states, forcings, terms)
    }

    /// The forcing terms of θ at each of the 500 steps: joint d's is (g_d − y₀_d)·φ(t)·θ_d.
    pub fn forcings(&self, theta: &Vector<PARAMS>) -> Vec<[f64; LINKS]> {
        self.features
            .iter()
            .map(|phi| {
                std::array::from_fn(|d| {
                    let w = (0..BASIS).map(|b| phi[b] * f64::from(theta[d * BASIS + b]));
                    w.sum::<f64>() * (self.goal[d] - self.start[d])
                })
            })
            .collect()
    }

    /// J(θ) as the `f32` the optimizers take.
    pub fn cost(&self, theta: &Vector<PARAMS>) -> f32 {
        self.evaluate(theta).total() as f32
    }

    /// The end-effector path sampled every `every` steps (for plots and checks).
    pub fn end_effector_path(&self, theta: &Vector<PARAMS>, every: usize) -> Vec<[f64; 2]> {
        let mut path = vec![end_effector(&self.start)];
        self.simulate(theta, |step, angles, _, _| {
            if step % every.max(1) == 0 {
                path.push(end_effector(angles));
            }
        });
        path
    }

    /// Semi-implicit Euler integration of the D transformation systems; `visit(step, y, z,
    /// forcing)` sees the joint angles and scaled velocities after each step (step 1 is
    /// t = Δt) and the forcing terms of that step.
    fn simulate(
        &self,
        theta: &Vector<PARAMS>,
        mut visit: impl FnMut(usize, &[f64; LINKS], &[f64; LINKS], &[f64; LINKS]),
    ) -> CostTerms {
        let weight_sum: f64 = (1..=LINKS).map(|d| (LINKS + 1 - d) as f64).sum();
        let theta: [f64; PARAMS] = std::array::from_fn(|k| f64::from(theta[k]));
        let mut y = self.start;
        let mut z = [0.0; LINKS];
        let mut acceleration = 0.0;
        let mut via_distance2 = f64::NAN;
        for (step, phi) in self.features.iter().enumerate() {
            let mut weighted = 0.0;
            let mut forcings = [0.0; LINKS];
            for d in 0..LINKS {
                let w = &theta[d * BASIS..(d + 1) * BASIS];
                let mut forcing = 0.0;
                for b in 0..BASIS {
                    forcing += phi[b] * w[b];
                }
                forcing *= self.goal[d] - self.start[d];
                forcings[d] = forcing;
                let zd = (ALPHA_Z * (BETA_Z * (self.goal[d] - y[d]) - z[d]) + forcing) / DURATION;
                z[d] += zd * DT;
                y[d] += z[d] / DURATION * DT;
                // ÿ = ż/τ.
                let ydd = zd / DURATION;
                weighted += (LINKS - d) as f64 * ydd * ydd;
            }
            acceleration += weighted / weight_sum * DT;
            visit(step + 1, &y, &z, &forcings);
            if step + 1 == VIA_STEP {
                let [px, py] = end_effector(&y);
                via_distance2 = (px - VIA_POINT[0]).powi(2) + (py - VIA_POINT[1]).powi(2);
            }
        }
        CostTerms {
            via_distance2,
            acceleration,
        }
    }
}

/// Forward kinematics: the end-effector position of the planar arm with joint angles `q`
/// (link d points at the angle q_1 + … + q_d).
pub fn end_effector(q: &[f64; LINKS]) -> [f64; 2] {
    let mut angle = 0.0;
    let mut p = [0.0, 0.0];
    for &qd in q {
        angle += qd;
        p[0] += LINK_LENGTH * angle.cos();
        p[1] += LINK_LENGTH * angle.sin();
    }
    p
}

/// The DMP's phase x(t) = exp(−α_x t/τ).
fn phase(t: f64) -> f64 {
    (-ALPHA_X * t / DURATION).exp()
}

/// φ_b(t) = ψ_b(x)/Σψ(x)·x at time t.
fn features_at(t: f64) -> [f64; BASIS] {
    let centre = |b: usize| phase(b as f64 * DURATION / (BASIS - 1) as f64);
    let x = phase(t);
    let mut psi = [0.0; BASIS];
    for (b, p) in psi.iter_mut().enumerate() {
        let next = if b + 1 < BASIS { b + 1 } else { b - 1 };
        let width = 0.5 * (centre(next) - centre(b)).abs();
        *p = (-(x - centre(b)).powi(2) / (2.0 * width * width)).exp();
    }
    let sum: f64 = psi.iter().sum();
    psi.map(|p| p / sum * x)
}

/// The parameter box of the task: every weight in [−[`WEIGHT_LIMIT`], [`WEIGHT_LIMIT`]].
pub fn bounds() -> Bounds<PARAMS> {
    Bounds::uniform(-WEIGHT_LIMIT, WEIGHT_LIMIT).expect("a valid box")
}

/// One learning session: the noise-free cost and the exploration magnitude before each
/// update and after the last one.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// J(θ) of the distribution's mean before update u (index 0: the minimum-jerk start;
    /// last: after the final update). With `first_is_mean` this is the cost of the batch's
    /// noise-free trial, as in the paper's learning curves.
    pub curve: Vec<f32>,
    /// λ before update u: the mean of the 50 variances (the paper plots the eigenvalues of
    /// each joint's 5×5 covariance; with a diagonal Σ these are the variances).
    pub exploration: Vec<f32>,
    /// Episodes run (K per update).
    pub episodes: u32,
    /// The distribution's mean after the last update.
    pub mean: Vector<PARAMS>,
}

impl Session {
    /// The noise-free cost after the last update.
    pub fn final_cost(&self) -> f32 {
        self.curve.last().copied().unwrap_or(f32::NAN)
    }

    /// The exploration magnitude after the last update.
    pub fn final_exploration(&self) -> f32 {
        self.exploration.last().copied().unwrap_or(f32::NAN)
    }
}

/// Runs `updates` updates of `DiagonalCem<50, K, E>` on the task from the minimum-jerk
/// weights, seeded with `seed` (xoshiro128++), and records the learning curve.
pub fn learn<const K: usize, const E: usize>(
    arm: &ViaPointArm,
    config: CemConfig,
    updates: u32,
    seed: u64,
) -> Result<Session, Error> {
    let config = CemConfig {
        max_evaluations: updates.saturating_mul(K as u32),
        ..config
    };
    let mut cem = DiagonalCem::<PARAMS, K, E>::try_new(bounds(), arm.minimum_jerk_theta(), config)?;
    let mut rng = Xoshiro128PlusPlus::seed_from_u64(seed);
    let mut curve = Vec::with_capacity(updates as usize + 1);
    let mut exploration = Vec::with_capacity(updates as usize + 1);
    while cem.status() == Status::Running {
        let starts_batch = cem.told_in_batch() == 0;
        if starts_batch {
            exploration.push(cem.variances().mean());
            if !config.first_is_mean {
                curve.push(arm.cost(cem.mean()));
            }
        }
        let theta = cem.ask(&mut rng)?;
        let cost = arm.cost(&theta);
        if starts_batch && config.first_is_mean {
            curve.push(cost);
        }
        cem.tell(cost)?;
    }
    curve.push(arm.cost(cem.mean()));
    exploration.push(cem.variances().mean());
    Ok(Session {
        curve,
        exploration,
        episodes: cem.evaluations(),
        mean: *cem.mean(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The ticks of an episode are the episode `evaluate` scores: the same cost terms, the
    /// forcing of `forcings`, and states that follow the DMP's semi-implicit Euler step.
    #[test]
    fn ticks_are_the_evaluated_episode() {
        let arm = ViaPointArm::new();
        let theta = arm.minimum_jerk_theta() + Vector::<PARAMS>::from_fn(|i, _| i as f32);
        let (states, forcings, terms) = arm.ticks(&theta);
        assert_eq!(terms, arm.evaluate(&theta));
        assert_eq!(forcings, arm.forcings(&theta));
        assert_eq!((states.len(), forcings.len()), (STEPS + 1, STEPS));
        assert_eq!(&states[0][..LINKS], arm.start());
        for (k, f) in forcings.iter().enumerate() {
            for d in 0..LINKS {
                let (y, z) = (states[k][d], states[k][LINKS + d]);
                let zd = (ALPHA_Z * (BETA_Z * (arm.goal[d] - y) - z) + f[d]) / DURATION;
                let z_next = z + zd * DT;
                assert_eq!(states[k + 1][LINKS + d], z_next);
                assert_eq!(states[k + 1][d], y + z_next / DURATION * DT);
            }
        }
    }
}
