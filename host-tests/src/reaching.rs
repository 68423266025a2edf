//! The via-point reaching task of [`arm`](crate::arm) for any number of links D and DMP
//! basis functions B per joint, sized at run time: the 50-link arm with B = 10 (500
//! parameters) of Hwangbo, Gehring, Sommer, Siegwart & Buchli, "ROCK*: Efficient black-box
//! optimization for policy learning" (Humanoids 2014), section III, whose task is that of
//! Theodorou, Buchli & Schaal, "A generalized path integral control approach to
//! reinforcement learning" (JMLR 2010). Host (std) code, simulated in `f64`.
//!
//! Everything is the 10-link task of [`arm`](crate::arm) with D and B as parameters: the arm
//! is 1 m long (links of 1/D m) and starts stretched along the x axis; the goal pose puts
//! link d at the angle (2d − 1)π/(2D) (half a regular 2D-gon, the tip on the y axis); the
//! DMP (α_z = 25, β_z = α_z/4, τ = 0.5 s, α_x = ln 100, B Gaussian basis functions centred
//! at equally spaced times) is integrated by semi-implicit Euler at 1 ms; the cost is
//! J(θ) = [`VIA_WEIGHT`](crate::arm::VIA_WEIGHT)·‖p(0.3 s) − (0.5, 0.5)‖² + ∫₀^τ Σ_d (D+1−d) ä_d² / Σ_d (D+1−d) dt.
//! With D = 10 and B = 5 the cost is the one of [`arm::ViaPointArm`] bit for bit (checked by
//! `experiments/tests/rockstar_arm.rs`).
//!
//! # What the ROCK* paper leaves open (documented choices)
//! * **The cost J₁.** The paper gives it only in its figure 2c), which the text does not
//!   reproduce; it says the cost penalises "the actuation cost and the distance to the
//!   via-points", "motivated by" Theodorou et al. 2010 and Stulp & Sigaud 2012. We use the
//!   cost of [`arm`](crate::arm) (Stulp & Sigaud's (24) with the via-point term weighted by
//!   10⁸, as in Theodorou et al.), so absolute costs are not comparable with the paper's
//!   table, only the ratios between optimizers.
//! * **The via point** G = (0.5, 0.5) at t = 0.3 s, the arm's length (1 m) and the goal pose
//!   are those of the 10-link task; the paper's figure 2a) shows the same geometry.
//! * **The initial policy** is the least-squares fit of the DMP to the minimum-jerk movement
//!   to the goal pose, as for the 10-link arm.
//!
//! [`arm`]: crate::arm
//! [`arm::ViaPointArm`]: crate::arm::ViaPointArm

use crate::arm::{CostTerms, DT, DURATION, VIA_POINT, VIA_STEP};

const ALPHA_Z: f64 = 25.0;
const BETA_Z: f64 = ALPHA_Z / 4.0;
/// α_x = ln 100: x(τ) = 0.01.
const ALPHA_X: f64 = 4.605_170_185_988_091;
const STEPS: usize = 500;

/// The paper's reaching arm: 50 links.
pub const PAPER_LINKS: usize = 50;
/// The paper's basis functions per joint: 10.
pub const PAPER_BASIS: usize = 10;
/// 50 · 10 = 500 parameters.
pub const PAPER_PARAMS: usize = PAPER_LINKS * PAPER_BASIS;

/// The via-point reaching arm with D links and B basis functions per joint (D·B
/// parameters; joint d uses θ[d·B..(d+1)·B]).
#[derive(Debug, Clone)]
pub struct ReachingArm {
    links: usize,
    basis: usize,
    link_length: f64,
    /// φ_b(t) at each integration step, `basis` values per step.
    features: Vec<f64>,
    goal: Vec<f64>,
}

impl ReachingArm {
    /// The arm of the module docs with `links` ≥ 1 links and `basis` ≥ 2 basis functions.
    ///
    /// # Panics
    /// If `links` is 0 or `basis` < 2.
    pub fn new(links: usize, basis: usize) -> Self {
        assert!(
            links >= 1 && basis >= 2,
            "at least one link and two basis functions"
        );
        let mut features = Vec::with_capacity(STEPS * basis);
        for i in 0..STEPS {
            features.extend(features_at(i as f64 * DT, basis));
        }
        let mut goal = vec![std::f64::consts::PI / links as f64; links];
        goal[0] /= 2.0;
        Self {
            links,
            basis,
            link_length: 1.0 / links as f64,
            features,
            goal,
        }
    }

    /// The paper's arm: 50 links, 10 basis functions (500 parameters).
    pub fn paper() -> Self {
        Self::new(PAPER_LINKS, PAPER_BASIS)
    }

    /// D·B, the number of parameters.
    pub fn params(&self) -> usize {
        self.links * self.basis
    }

    /// D, the number of links.
    pub fn links(&self) -> usize {
        self.links
    }

    /// θ fitted to the 0.5 s minimum-jerk movement to the goal pose (least squares over the
    /// 500 steps, normal equations with a 10⁻¹⁰ ridge, solved by Cholesky); every joint gets
    /// the same B weights.
    pub fn minimum_jerk_theta(&self) -> Vec<f32> {
        let b = self.basis;
        let mut ata = vec![0.0; b * b];
        let mut atb = vec![0.0; b];
        for (i, phi) in self.features.chunks_exact(b).enumerate() {
            let s = i as f64 * DT / DURATION;
            let y = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
            let yd = 30.0 * s * s * (1.0 - s) * (1.0 - s) / DURATION;
            let ydd = 60.0 * s * (1.0 - 3.0 * s + 2.0 * s * s) / (DURATION * DURATION);
            let target = DURATION * DURATION * ydd - ALPHA_Z * (BETA_Z * (1.0 - y) - DURATION * yd);
            for r in 0..b {
                for c in 0..b {
                    ata[r * b + c] += phi[r] * phi[c];
                }
                atb[r] += phi[r] * target;
            }
        }
        for r in 0..b {
            ata[r * b + r] += 1e-10;
        }
        let weights = cholesky_solve(&ata, &atb, b);
        (0..self.params()).map(|k| weights[k % b] as f32).collect()
    }

    /// Integrates the DMPs with parameters θ (length D·B) and returns the cost terms.
    ///
    /// # Panics
    /// If `theta.len()` is not D·B.
    pub fn evaluate(&self, theta: &[f32]) -> CostTerms {
        assert_eq!(theta.len(), self.params(), "θ has D·B entries");
        let (links, basis) = (self.links, self.basis);
        let weight_sum: f64 = (1..=links).map(|d| (links + 1 - d) as f64).sum();
        let theta: Vec<f64> = theta.iter().map(|&t| f64::from(t)).collect();
        let mut y = vec![0.0; links];
        let mut z = vec![0.0; links];
        let mut acceleration = 0.0;
        let mut via_distance2 = f64::NAN;
        for (step, phi) in self.features.chunks_exact(basis).enumerate() {
            let mut weighted = 0.0;
            for d in 0..links {
                let w = &theta[d * basis..(d + 1) * basis];
                let mut forcing = 0.0;
                for k in 0..basis {
                    forcing += phi[k] * w[k];
                }
                // f is scaled by g − y₀, and the start pose y₀ is 0 for every joint.
                forcing *= self.goal[d];
                let zd = (ALPHA_Z * (BETA_Z * (self.goal[d] - y[d]) - z[d]) + forcing) / DURATION;
                z[d] += zd * DT;
                y[d] += z[d] / DURATION * DT;
                let ydd = zd / DURATION;
                weighted += (links - d) as f64 * ydd * ydd;
            }
            acceleration += weighted / weight_sum * DT;
            if step + 1 == VIA_STEP {
                let [px, py] = self.end_effector(&y);
                via_distance2 = (px - VIA_POINT[0]).powi(2) + (py - VIA_POINT[1]).powi(2);
            }
        }
        CostTerms {
            via_distance2,
            acceleration,
        }
    }

    /// J(θ) as the `f32` the optimizers take.
    pub fn cost(&self, theta: &[f32]) -> f32 {
        self.evaluate(theta).total() as f32
    }

    /// The end-effector position for joint angles `q` (link d at q_1 + … + q_d).
    pub fn end_effector(&self, q: &[f64]) -> [f64; 2] {
        let mut angle = 0.0;
        let mut p = [0.0, 0.0];
        for &qd in q {
            angle += qd;
            p[0] += self.link_length * angle.cos();
            p[1] += self.link_length * angle.sin();
        }
        p
    }
}

/// φ_b(t) = ψ_b(x)/Σψ(x)·x at time t for B basis functions (as in [`arm`](crate::arm)).
fn features_at(t: f64, basis: usize) -> Vec<f64> {
    let phase = |t: f64| (-ALPHA_X * t / DURATION).exp();
    let centre = |b: usize| phase(b as f64 * DURATION / (basis - 1) as f64);
    let x = phase(t);
    let psi: Vec<f64> = (0..basis)
        .map(|b| {
            let next = if b + 1 < basis { b + 1 } else { b - 1 };
            let width = 0.5 * (centre(next) - centre(b)).abs();
            (-(x - centre(b)).powi(2) / (2.0 * width * width)).exp()
        })
        .collect();
    let sum: f64 = psi.iter().sum();
    psi.into_iter().map(|p| p / sum * x).collect()
}

/// Solves the symmetric positive definite system `a x = b` (`a` row-major n × n).
fn cholesky_solve(a: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let mut l = vec![0.0; n * n];
    for r in 0..n {
        for c in 0..=r {
            let mut s = a[r * n + c];
            for k in 0..c {
                s -= l[r * n + k] * l[c * n + k];
            }
            l[r * n + c] = if r == c {
                assert!(s > 0.0, "the basis features are linearly independent");
                s.sqrt()
            } else {
                s / l[c * n + c]
            };
        }
    }
    let mut y = vec![0.0; n];
    for r in 0..n {
        let s: f64 = (0..r).map(|k| l[r * n + k] * y[k]).sum();
        y[r] = (b[r] - s) / l[r * n + r];
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| l[k * n + r] * x[k]).sum();
        x[r] = (y[r] - s) / l[r * n + r];
    }
    x
}
