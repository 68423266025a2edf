//! A stand-in for the controller layer (issue 5), so the PIL link can be exercised end to
//! end before `Pd`, `LinearPolicy` and `Adapter` exist: a PD position controller for a 1-D
//! double integrator plus a linear correction whose three parameters the coordinate search
//! tunes episode by episode,
//!
//! ```text
//! u = clamp(u_pd + clamp(θ·φ, ±c), ±u_max),   u_pd = −k_p x − k_d v,   φ = (1, x, v)
//! ```
//!
//! with the episode cost Σ (x² + w u²) Δt accumulated in the firmware from the states it
//! receives. Against a constant disturbance the PD alone keeps a steady offset d/k_p; the
//! bias θ₀ can cancel it and θ₁, θ₂ reshape the transient. To be replaced by an
//! implementation of [`Controller`] for the `Adapter` (see `docs/firmware.md`).

use ctrl_adapt::{Best, Bounds, CoordinateConfig, CoordinateSearch, Error, Optimizer, Vector};
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

use crate::frame::Values;
use crate::session::Controller;

/// Number of tuned parameters (θ₀, θ₁, θ₂).
pub const PARAMETERS: usize = 3;

/// Seed of the learner's RNG in the PIL firmware and in the host's reference run (the
/// coordinate search draws no random numbers; other optimizers will).
pub const SEED: u64 = 1;

/// Gains, limits and learner settings of the stand-in.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StandinConfig {
    /// Proportional gain k_p.
    pub kp: f32,
    /// Derivative gain k_d.
    pub kd: f32,
    /// Control period Δt in seconds (cost weighting only).
    pub dt: f32,
    /// |u| ≤ u_max.
    pub action_limit: f32,
    /// |θ·φ| ≤ c.
    pub correction_limit: f32,
    /// Weight w of u² in the cost.
    pub action_weight: f32,
    /// Every θ_i lies in [−limit, limit].
    pub parameter_limit: f32,
    /// The coordinate search's settings.
    pub search: CoordinateConfig,
}

impl StandinConfig {
    /// The configuration of the PIL demo.
    pub const DEFAULT: Self = Self {
        kp: 4.0,
        kd: 2.0,
        dt: 0.05,
        action_limit: 5.0,
        correction_limit: 2.0,
        action_weight: 0.01,
        parameter_limit: 2.0,
        search: CoordinateConfig {
            initial_step: 0.5,
            tolerance: 1e-3,
            ..CoordinateConfig::DEFAULT
        },
    };
}

/// PD + optimizer-tuned linear correction (see the [module docs](self)).
#[derive(Debug, Clone)]
pub struct PdCorrection {
    config: StandinConfig,
    search: CoordinateSearch<PARAMETERS>,
    rng: Xoshiro128PlusPlus,
    theta: Vector<PARAMETERS>,
    /// Whether θ came from `ask` (so its cost is told) or is the best θ after the search
    /// stopped (exploitation).
    exploring: bool,
    cost: f32,
}

impl PdCorrection {
    /// Starts from θ = 0 (the bare PD), with `seed` for the optimizer's RNG.
    pub fn try_new(config: StandinConfig, seed: u64) -> Result<Self, Error> {
        let bounds = Bounds::uniform(-config.parameter_limit, config.parameter_limit)?;
        Ok(Self {
            config,
            search: CoordinateSearch::try_new(bounds, Vector::zeros(), config.search)?,
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
            theta: Vector::zeros(),
            exploring: false,
            cost: 0.0,
        })
    }

    /// The nominal PD action, clamped.
    pub fn nominal(&self, x: f32, v: f32) -> f32 {
        self.limit(
            -self.config.kp * x - self.config.kd * v,
            self.config.action_limit,
        )
    }

    /// The corrected action for parameters `theta`.
    pub fn corrected(&self, theta: &Vector<PARAMETERS>, x: f32, v: f32) -> f32 {
        let correction = theta[0] + theta[1] * x + theta[2] * v;
        let correction = self.limit(correction, self.config.correction_limit);
        self.limit(
            -self.config.kp * x - self.config.kd * v + correction,
            self.config.action_limit,
        )
    }

    /// The best parameters and cost the search has seen.
    pub fn best(&self) -> Option<Best<PARAMETERS>> {
        self.search.best()
    }

    /// The parameters of the current episode.
    pub fn theta(&self) -> &Vector<PARAMETERS> {
        &self.theta
    }

    /// `value` limited to ±`limit` (max/min: no panic path, NaN maps to −limit).
    fn limit(&self, value: f32, limit: f32) -> f32 {
        value.max(-limit).min(limit)
    }

    fn accumulate(&mut self, x: f32, u: f32) {
        self.cost += (x * x + self.config.action_weight * u * u) * self.config.dt;
    }
}

/// A finite (x, v) from a state vector, if there is one.
fn position_velocity(state: &[f32]) -> Option<(f32, f32)> {
    match *state {
        [x, v, ..] if x.is_finite() && v.is_finite() => Some((x, v)),
        _ => None,
    }
}

impl Controller for PdCorrection {
    fn start_episode(&mut self, _episode: u16, theta: &mut Values) {
        match self.search.ask(&mut self.rng) {
            Ok(t) => {
                self.theta = t;
                self.exploring = true;
            }
            // The search has stopped: run its best parameters from now on.
            Err(_) => {
                self.theta = self.search.best().map_or_else(Vector::zeros, |b| b.theta);
                self.exploring = false;
            }
        }
        self.cost = 0.0;
        theta.clear();
        for &t in self.theta.iter() {
            let _ = theta.push(t);
        }
    }

    fn act(&mut self, state: &[f32], action: &mut Values) {
        // A non-finite or short state is treated like a missing one.
        let Some((x, v)) = position_velocity(state) else {
            return self.fallback(None, action);
        };
        let u = self.corrected(&self.theta.clone(), x, v);
        self.accumulate(x, u);
        action.clear();
        let _ = action.push(u);
    }

    fn fallback(&mut self, last_state: Option<&[f32]>, action: &mut Values) {
        let u = match last_state.and_then(position_velocity) {
            Some((x, v)) => {
                let u = self.nominal(x, v);
                self.accumulate(x, u);
                u
            }
            None => 0.0,
        };
        action.clear();
        let _ = action.push(u);
    }

    fn end_episode(&mut self, report: &mut Values) {
        if self.exploring {
            // A non-finite cost is rejected and the candidate stays pending: the next
            // episode runs it again.
            let _ = self.search.tell(self.cost);
        }
        let best = self.search.best().map_or(self.cost, |b| b.cost);
        report.clear();
        let _ = report.push(self.cost);
        let _ = report.push(best);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks: with θ = 0 the corrected action equals the nominal PD; the correction and the
    /// action respect their limits for extreme θ and states; NaN states give the fallback.
    #[test]
    fn correction_and_limits() {
        let c = PdCorrection::try_new(StandinConfig::DEFAULT, 0).unwrap();
        for (x, v) in [(0.3, -0.2), (-1.0, 2.0), (0.0, 0.0)] {
            assert_eq!(c.corrected(&Vector::zeros(), x, v), c.nominal(x, v));
        }
        let wild = Vector::from([2.0, 2.0, 2.0]);
        let (x, v) = (0.1, 0.1);
        let u = c.corrected(&wild, x, v);
        assert!(
            (u - c.nominal(x, v) - 2.0).abs() < 1e-6,
            "correction clamped to 2"
        );
        assert_eq!(c.corrected(&wild, 100.0, 100.0), -5.0);
        let mut s = PdCorrection::try_new(StandinConfig::DEFAULT, 0).unwrap();
        let mut a = Values::new();
        s.act(&[f32::NAN, 0.0], &mut a);
        assert_eq!(a[0], 0.0);
    }

    /// Checks: the first episode runs θ = 0 (the bare PD, the search's start) and its cost is
    /// told; a cost accumulates only over ticks with a usable state.
    #[test]
    fn first_episode_is_the_nominal_controller() {
        let mut s = PdCorrection::try_new(StandinConfig::DEFAULT, 0).unwrap();
        let mut theta = Values::new();
        s.start_episode(0, &mut theta);
        assert_eq!(theta.as_slice(), &[0.0, 0.0, 0.0]);
        let mut a = Values::new();
        s.act(&[1.0, 0.0], &mut a);
        assert_eq!(a[0], -4.0);
        s.fallback(Some(&[1.0, 0.0]), &mut a);
        assert_eq!(a[0], -4.0);
        s.fallback(None, &mut a);
        assert_eq!(a[0], 0.0);
        let mut report = Values::new();
        s.end_episode(&mut report);
        let expected = 2.0 * (1.0 + 0.01 * 16.0) * 0.05;
        assert!((report[0] - expected).abs() < 1e-6);
        assert_eq!(s.best().unwrap().cost, report[0]);
    }
}
