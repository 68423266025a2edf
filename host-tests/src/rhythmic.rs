//! The rhythmic via-point task of Hwangbo, Gehring, Sommer, Siegwart & Buchli, "ROCK*:
//! Efficient black-box optimization for policy learning" (Humanoids 2014), section III: the
//! end effector of a 50-link planar arm, 1 m long, should pass rhythmically through two
//! via points G₁ and G₂ with a period T = 1 s, each joint following a rhythmic movement
//! primitive (RMP) of 8 kernels (400 parameters). Host (std) code, simulated in `f64`.
//!
//! # The task as the paper gives it
//! "The RMP is essentially a mixture of Gaussian kernels that are repeated with the
//! predefined period T"; the cost J₂ (given only in the paper's figure 2c, not in its text)
//! penalises the actuation and the distance to the via points at predefined times.
//!
//! # What the paper leaves open (documented choices)
//! * **The RMP.** Joint d's angle is the normalised kernel mixture
//!   q_d(t) = Σ_k θ_{d,k} ψ_k(t) / Σ_k ψ_k(t), with the periodic Gaussian (von Mises)
//!   kernels ψ_k(t) = exp(h (cos(2πt/T − c_k) − 1)), centres c_k = 2πk/K, k = 0..K−1, and
//!   h = 2.5 K (the width of Ijspeert et al.'s rhythmic DMPs; neighbouring kernels overlap at
//!   ≈ 0.5 of their peak for K = 8). The mixture *is* the joint trajectory (the paper's
//!   description); there is no transformation system and hence no transient, so one period
//!   is the whole steady-state cycle.
//! * **The cost J₂.** As for the reaching task ([`arm`](crate::arm)):
//!   J(θ) = [`VIA_WEIGHT`]·(‖p(t₁) − G₁‖² + ‖p(t₂) − G₂‖²) +
//!   ∫₀^T Σ_d (D+1−d) q̈_d² / Σ_d (D+1−d) dt, the accelerations by the periodic central
//!   difference on a 1 ms grid over one period (1000 points, the grid wraps around).
//! * **The via points**: G₁ = (0.6, 0.4) m at t₁ = 0.25 s and G₂ = (0.6, 0.2) m at
//!   t₂ = 0.75 s (the paper's figure 2d shows two points in front of the arm; their
//!   coordinates are not given). Both are reachable and 0.2 m apart.
//! * **The initial policy**: θ = 0, the arm stretched along the x axis and still (tip at
//!   (1, 0)), costing [`VIA_WEIGHT`]·(0.32 + 0.20) = 5.2·10⁷.
//! * **A box.** Every weight (a joint angle, rad) in ±[`WEIGHT_LIMIT`] = ±π.
//!
//! Absolute costs are not comparable with the paper's table (its J₂ is unknown), only the
//! ratios between optimizers.

use crate::arm::VIA_WEIGHT;

/// D: links and joints.
pub const LINKS: usize = 50;
/// K: kernels per joint.
pub const KERNELS: usize = 8;
/// D·K: parameters.
pub const PARAMS: usize = LINKS * KERNELS;
/// T: the period (s).
pub const PERIOD: f64 = 1.0;
/// Grid step (s).
pub const DT: f64 = 1e-3;
/// The via points (m) and the times (s) the end effector should pass them.
pub const VIA_POINTS: [([f64; 2], f64); 2] = [([0.6, 0.4], 0.25), ([0.6, 0.2], 0.75)];
/// Every weight stays in [−`WEIGHT_LIMIT`, `WEIGHT_LIMIT`] (rad).
pub const WEIGHT_LIMIT: f32 = std::f32::consts::PI;

const STEPS: usize = 1000;

/// The two terms of the rhythmic cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RhythmicTerms {
    /// Σ_j ‖p(t_j) − G_j‖² (m²), before weighting.
    pub via_distance2: f64,
    /// ∫₀^T Σ_d (D+1−d) q̈_d² / Σ_d (D+1−d) dt (rad²/s³).
    pub acceleration: f64,
}

impl RhythmicTerms {
    /// J(θ) = [`VIA_WEIGHT`]·via + acceleration.
    pub fn total(&self) -> f64 {
        VIA_WEIGHT * self.via_distance2 + self.acceleration
    }
}

/// The rhythmic arm: the normalised kernel values at every grid point.
#[derive(Debug, Clone)]
pub struct RhythmicArm {
    /// ψ_k(t_i)/Σψ(t_i), `KERNELS` values per grid point.
    features: Vec<[f64; KERNELS]>,
}

impl Default for RhythmicArm {
    fn default() -> Self {
        Self::new()
    }
}

impl RhythmicArm {
    /// The task of the module docs.
    pub fn new() -> Self {
        let h = 2.5 * KERNELS as f64;
        let features = (0..STEPS)
            .map(|i| {
                let phase = 2.0 * std::f64::consts::PI * i as f64 * DT / PERIOD;
                let psi: [f64; KERNELS] = std::array::from_fn(|k| {
                    let c = 2.0 * std::f64::consts::PI * k as f64 / KERNELS as f64;
                    (h * ((phase - c).cos() - 1.0)).exp()
                });
                let sum: f64 = psi.iter().sum();
                psi.map(|p| p / sum)
            })
            .collect();
        Self { features }
    }

    /// The joint angles q_d(t_i) at grid point `i` (0 ≤ i < 1000).
    pub fn joint_angles(&self, theta: &[f32], i: usize) -> [f64; LINKS] {
        let phi = &self.features[i % STEPS];
        std::array::from_fn(|d| {
            let w = &theta[d * KERNELS..(d + 1) * KERNELS];
            (0..KERNELS).map(|k| phi[k] * f64::from(w[k])).sum()
        })
    }

    /// The cost terms of θ (length [`PARAMS`]; joint d uses θ[d·K..(d+1)·K]).
    ///
    /// # Panics
    /// If `theta.len()` is not [`PARAMS`].
    pub fn evaluate(&self, theta: &[f32]) -> RhythmicTerms {
        assert_eq!(theta.len(), PARAMS, "θ has D·K entries");
        let weight_sum: f64 = (1..=LINKS).map(|d| (LINKS + 1 - d) as f64).sum();
        let mut acceleration = 0.0;
        for d in 0..LINKS {
            let w: [f64; KERNELS] = std::array::from_fn(|k| f64::from(theta[d * KERNELS + k]));
            let q: Vec<f64> = self
                .features
                .iter()
                .map(|phi| (0..KERNELS).map(|k| phi[k] * w[k]).sum())
                .collect();
            let mut sum = 0.0;
            for i in 0..STEPS {
                let prev = q[(i + STEPS - 1) % STEPS];
                let next = q[(i + 1) % STEPS];
                let qdd = (next - 2.0 * q[i] + prev) / (DT * DT);
                sum += qdd * qdd;
            }
            acceleration += (LINKS - d) as f64 * sum * DT;
        }
        acceleration /= weight_sum;
        let via_distance2 = VIA_POINTS
            .iter()
            .map(|&(g, t)| {
                let i = (t / DT).round() as usize;
                let [px, py] = end_effector(&self.joint_angles(theta, i));
                (px - g[0]).powi(2) + (py - g[1]).powi(2)
            })
            .sum();
        RhythmicTerms {
            via_distance2,
            acceleration,
        }
    }

    /// J(θ) as the `f32` the optimizers take.
    pub fn cost(&self, theta: &[f32]) -> f32 {
        self.evaluate(theta).total() as f32
    }
}

/// The end-effector position of the 1 m arm of [`LINKS`] equal links for joint angles `q`.
pub fn end_effector(q: &[f64; LINKS]) -> [f64; 2] {
    let length = 1.0 / LINKS as f64;
    let mut angle = 0.0;
    let mut p = [0.0, 0.0];
    for &qd in q {
        angle += qd;
        p[0] += length * angle.cos();
        p[1] += length * angle.sin();
    }
    p
}
