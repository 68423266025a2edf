//! Cost shapers: turn what happens during an episode into the one cost the optimizer sees.
//!
//! A shaper is fed an observation every control tick ([`Shaper::observe`]) and gives the
//! episode's cost at the end ([`Shaper::cost`]); lower is better, as every optimizer here
//! minimises. A reward from a paper is negated into a cost.
//!
//! Non-finite observations (a sensor glitch) are skipped and counted
//! ([`Shaper::skipped`]); a shaper that has nothing valid to score returns a non-finite
//! cost, which the [`Adapter`](crate::controller::Adapter) turns into its failure penalty
//! rather than hand a NaN to an optimizer.

use crate::error::{Error, require};
use crate::vector::Vector;

/// Accumulates a cost over an episode.
pub trait Shaper {
    /// What the shaper needs each tick.
    type Observation;

    /// Forgets the previous episode.
    fn reset(&mut self);

    /// One control period of `dt` seconds ended with `observation`.
    fn observe(&mut self, observation: &Self::Observation, dt: f32);

    /// The episode's cost so far; non-finite if nothing valid was observed.
    fn cost(&self) -> f32;

    /// How many observations were skipped because they were not finite.
    fn skipped(&self) -> u32;
}

/// The survey reward of Leonetti et al. 2012 (section 5) as a cost:
/// J = −d if d ≥ D, t_D − D if d < D (d the minimum distance to the target, t_D the time
/// spent within D of it), so cost = −J = d if d ≥ D, D − t_D if d < D.
///
/// Far from the target the cost is the distance (a heuristic that pulls towards it); once
/// within D it rewards the time kept there. The two branches meet at cost D when d = D.
///
/// ```
/// use ctrl_adapt::cost::{Shaper, SurveyCost};
/// use ctrl_adapt::optimizer::Vector;
/// let mut survey = SurveyCost::try_new(1.0)?;
/// survey.observe(&Vector::from([3.0, 0.0, 4.0]), 0.1); // 5 m away
/// assert_eq!(survey.cost(), 5.0);
/// for _ in 0..20 {
///     survey.observe(&Vector::from([0.5, 0.0, 0.0]), 0.1); // 2 s within 1 m
/// }
/// assert!((survey.cost() - (1.0 - 2.0)).abs() < 1e-5);
/// # Ok::<(), ctrl_adapt::optimizer::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SurveyCost {
    radius: f32,
    min_distance: f32,
    time_within: f32,
    skipped: u32,
}

impl SurveyCost {
    /// A survey with distance threshold D = `radius` metres (> 0; the paper uses 1 m).
    pub fn try_new(radius: f32) -> Result<Self, Error> {
        let cost = Self {
            radius,
            min_distance: f32::INFINITY,
            time_within: 0.0,
            skipped: 0,
        };
        cost.check_decoded()?;
        Ok(cost)
    }

    /// The check of [`SurveyCost::try_new`], plus, for a decoded shaper, running figures
    /// that are not NaN nor negative (the minimum distance is +∞ before any observation).
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        require(self.radius.is_finite() && self.radius > 0.0, "radius")?;
        require(self.min_distance >= 0.0, "min_distance")?;
        require(self.time_within >= 0.0, "time_within")
    }

    /// d, the minimum distance so far (∞ before any valid observation).
    pub fn min_distance(&self) -> f32 {
        self.min_distance
    }

    /// t_D, the time spent within D so far.
    pub fn time_within(&self) -> f32 {
        self.time_within
    }

    /// The paper's reward J = −cost.
    pub fn reward(&self) -> f32 {
        -self.cost()
    }
}

impl Shaper for SurveyCost {
    /// The position error (target − position) in metres.
    type Observation = Vector<3>;

    fn reset(&mut self) {
        self.min_distance = f32::INFINITY;
        self.time_within = 0.0;
        self.skipped = 0;
    }

    fn observe(&mut self, error: &Vector<3>, dt: f32) {
        let d = error.norm();
        if !d.is_finite() || !dt.is_finite() || dt < 0.0 {
            self.skipped = self.skipped.saturating_add(1);
            return;
        }
        // `self.min_distance.min(d)` for a finite d (minNum keeps d on a tie), without the
        // call of `fminf` that `f32::min` is on a Cortex-M4F.
        if d <= self.min_distance || self.min_distance.is_nan() {
            self.min_distance = d;
        }
        if d < self.radius {
            self.time_within += dt;
        }
    }

    fn cost(&self) -> f32 {
        if self.min_distance >= self.radius {
            self.min_distance
        } else {
            self.radius - self.time_within
        }
    }

    fn skipped(&self) -> u32 {
        self.skipped
    }
}

/// A quadratic tracking cost ∫ Σ_i q_i e_i² dt over the episode.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct QuadraticCost<const K: usize> {
    weights: Vector<K>,
    total: f32,
    observed: u32,
    skipped: u32,
}

impl<const K: usize> QuadraticCost<K> {
    /// Weights q_i ≥ 0, finite.
    pub fn try_new(weights: Vector<K>) -> Result<Self, Error> {
        let cost = Self {
            weights,
            total: 0.0,
            observed: 0,
            skipped: 0,
        };
        cost.check_decoded()?;
        Ok(cost)
    }

    /// The check of [`QuadraticCost::try_new`], plus, for a decoded shaper, a running total
    /// that is not NaN nor negative (+∞ after an overflow is a cost like any other).
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        require(
            self.weights.iter().all(|q| q.is_finite() && *q >= 0.0),
            "weights",
        )?;
        require(self.total >= 0.0, "total")
    }
}

impl<const K: usize> Shaper for QuadraticCost<K> {
    /// The tracking error.
    type Observation = Vector<K>;

    fn reset(&mut self) {
        self.total = 0.0;
        self.observed = 0;
        self.skipped = 0;
    }

    fn observe(&mut self, error: &Vector<K>, dt: f32) {
        let c = self.weights.dot(&error.component_mul(error)) * dt;
        if !c.is_finite() || dt < 0.0 {
            self.skipped = self.skipped.saturating_add(1);
            return;
        }
        self.total += c;
        self.observed = self.observed.saturating_add(1);
    }

    fn cost(&self) -> f32 {
        if self.observed == 0 {
            f32::NAN
        } else {
            self.total
        }
    }

    fn skipped(&self) -> u32 {
        self.skipped
    }
}

/// One tick of a hopping robot, as [`ApexHeightCost`] needs it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HopSample {
    /// Body height above the reference floor (m).
    pub height: f32,
    /// Body vertical velocity (m/s, up positive).
    pub vertical_velocity: f32,
    /// Mechanical power spent by the actuators, Σ |τ_i q̇_i| (W).
    pub power: f32,
    /// Whether a torque or joint limit was exceeded (commanded over the limit) this tick.
    pub limit_violation: bool,
}

/// Parameters of [`ApexHeightCost`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ApexConfig {
    /// The apex height to hold (m; the paper: 0.6 m).
    pub set_height: f32,
    /// An apex lower than this is not a hop (the body bouncing in stance), m.
    pub min_apex: f32,
    /// Hops an episode should contain; each missing one costs `missing_hop_cost`.
    pub expected_hops: u32,
    /// Cost of each missing hop (a fall or a stall is expensive).
    pub missing_hop_cost: f32,
    /// Weight of the energy per second, J/s → cost.
    pub energy_weight: f32,
    /// Cost of each tick with a limit violation.
    pub violation_cost: f32,
    /// Apexes at the start of an episode that are counted as hops but left out of the
    /// deviation and spread terms: the landing from the start (a drop from rest) or the
    /// first hops under a newly deployed θ, which are transients of the episode rather than
    /// of the policy. 0 keeps every apex (the paper's cost).
    pub transient_hops: u32,
    /// Weight of the squared apex spread (m²): (highest − lowest counted apex)². 0 is the
    /// paper's cost; a positive weight ranks policies by the worst-case variation the robot
    /// shows over the episode, not only its mean square (see [`ApexHeightCost`]).
    pub spread_weight: f32,
}

impl ApexConfig {
    /// The paper's terms with neutral weights, to be completed with `..`: set height 0.6 m,
    /// an apex above 0.3 m, no expected hops, no energy, violation or spread cost, every apex
    /// counted.
    pub const DEFAULT: Self = Self {
        set_height: 0.6,
        min_apex: 0.3,
        expected_hops: 0,
        missing_hop_cost: 0.0,
        energy_weight: 0.0,
        violation_cost: 0.0,
        transient_hops: 0,
        spread_weight: 0.0,
    };
}

impl Default for ApexConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The hopping apex-height cost (Hwangbo et al., section IV: "penalizes deviations from the
/// predefined apex height (0.6 m) and the number of hops, energy consumption and any command
/// over the torque and joint limits"):
///
/// cost = mean over apexes of (h_apex − h_set)² + spread_weight·(max h_apex − min h_apex)²
/// \+ missing_hop_cost·max(0, hops_expected − hops) + energy_weight·(∫ power dt)/T +
/// violation_cost·(ticks over a limit),
///
/// the deviation and spread taken over the apexes after the first
/// [`ApexConfig::transient_hops`] (every apex counts as a hop).
///
/// The spread term is ours, not the paper's (its weight defaults to 0): the paper reports the
/// learned policy by its apex *fluctuation*, and when a new block sequence is drawn every
/// episode the mean square alone ranks policies mostly by how hard the episode's blocks were
/// and by their energy; weighting the worst case of the episode aims the search at the
/// variation itself.
///
/// Two loopholes to close when setting the weights (both seen on a simulated hopping leg):
/// * **Low apexes.** Apexes at or below `min_apex` are neither hops nor in the deviation and
///   spread terms. Set `min_apex` low (e.g. the height at which the robot counts as fallen),
///   so that a gait dropping into low hops pays for them in the spread, not only as missing
///   hops.
/// * **Hopping lower.** The deviation term (weight 1) is the set-height term. A gait Δ below
///   the set height pays Δ² there and gains `spread_weight`·(s₁² − s₂²) if its spread
///   shrinks from s₁ to s₂; with `spread_weight` = 10 a 5 cm lower gait paid as soon as it
///   cut a 4 cm spread to 3.7 cm. Keep `spread_weight` near 1 (the other weights scaled
///   with it) for the set height to hold.
///
/// An apex is the top of a flight: the vertical velocity changes sign from + to − with the
/// body above `min_apex`. The squared deviation is in m², so a 5 cm spread of apexes costs
/// about 6e-4 and 1 cm about 2.5e-5: weights of the other terms should be set against that.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ApexHeightCost {
    config: ApexConfig,
    previous_velocity: f32,
    apexes: u32,
    squared_deviation: f32,
    apex_min: f32,
    apex_max: f32,
    energy: f32,
    duration: f32,
    violations: u32,
    skipped: u32,
}

impl ApexHeightCost {
    /// Validates `config` (finite, non-negative weights; positive heights).
    pub fn try_new(config: ApexConfig) -> Result<Self, Error> {
        check_apex_config(&config)?;
        let mut cost = Self {
            config,
            previous_velocity: 0.0,
            apexes: 0,
            squared_deviation: 0.0,
            apex_min: f32::INFINITY,
            apex_max: f32::NEG_INFINITY,
            energy: 0.0,
            duration: 0.0,
            violations: 0,
            skipped: 0,
        };
        cost.reset();
        Ok(cost)
    }

    /// The checks of [`ApexHeightCost::try_new`], plus, for a decoded shaper, the last
    /// vertical velocity finite and the running figures not NaN (the sums not negative).
    #[cfg(feature = "serde")]
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        check_apex_config(&self.config)?;
        require(self.previous_velocity.is_finite(), "previous_velocity")?;
        require(self.squared_deviation >= 0.0, "squared_deviation")?;
        require(
            !(self.apex_min.is_nan() || self.apex_max.is_nan()),
            "apex_min",
        )?;
        require(self.energy >= 0.0, "energy")?;
        require(self.duration >= 0.0, "duration")
    }

    /// Apexes detected so far.
    pub fn apexes(&self) -> u32 {
        self.apexes
    }

    /// Apexes in the deviation and spread terms: those after the first
    /// [`ApexConfig::transient_hops`].
    pub fn counted_apexes(&self) -> u32 {
        self.apexes.saturating_sub(self.config.transient_hops)
    }

    /// Highest minus lowest counted apex so far (0 with fewer than two).
    pub fn apex_spread(&self) -> f32 {
        if self.counted_apexes() < 2 {
            0.0
        } else {
            self.apex_max - self.apex_min
        }
    }
}

/// Finite, non-negative weights and heights, a positive set height.
fn check_apex_config(config: &ApexConfig) -> Result<(), Error> {
    let finite_nonneg = |v: f32| v.is_finite() && v >= 0.0;
    require(
        config.set_height.is_finite() && config.set_height > 0.0,
        "set_height",
    )?;
    require(finite_nonneg(config.min_apex), "min_apex")?;
    require(finite_nonneg(config.missing_hop_cost), "missing_hop_cost")?;
    require(finite_nonneg(config.energy_weight), "energy_weight")?;
    require(finite_nonneg(config.violation_cost), "violation_cost")?;
    require(finite_nonneg(config.spread_weight), "spread_weight")
}

impl Shaper for ApexHeightCost {
    type Observation = HopSample;

    fn reset(&mut self) {
        self.previous_velocity = 0.0;
        self.apexes = 0;
        self.squared_deviation = 0.0;
        self.apex_min = f32::INFINITY;
        self.apex_max = f32::NEG_INFINITY;
        self.energy = 0.0;
        self.duration = 0.0;
        self.violations = 0;
        self.skipped = 0;
    }

    fn observe(&mut self, s: &HopSample, dt: f32) {
        if !(s.height.is_finite()
            && s.vertical_velocity.is_finite()
            && s.power.is_finite()
            && dt.is_finite()
            && dt >= 0.0)
        {
            self.skipped = self.skipped.saturating_add(1);
            return;
        }
        if self.previous_velocity > 0.0
            && s.vertical_velocity <= 0.0
            && s.height > self.config.min_apex
        {
            self.apexes = self.apexes.saturating_add(1);
            if self.apexes > self.config.transient_hops {
                let dev = s.height - self.config.set_height;
                self.squared_deviation += dev * dev;
                self.apex_min = self.apex_min.min(s.height);
                self.apex_max = self.apex_max.max(s.height);
            }
        }
        self.previous_velocity = s.vertical_velocity;
        self.energy += s.power.abs() * dt;
        self.duration += dt;
        if s.limit_violation {
            self.violations = self.violations.saturating_add(1);
        }
    }

    fn cost(&self) -> f32 {
        let c = &self.config;
        let missing = c.expected_hops.saturating_sub(self.apexes) as f32;
        let counted = self.counted_apexes();
        let deviation = if counted == 0 {
            0.0
        } else {
            self.squared_deviation / counted as f32
        };
        let spread = self.apex_spread();
        let power = if self.duration > 0.0 {
            self.energy / self.duration
        } else {
            0.0
        };
        deviation
            + c.spread_weight * spread * spread
            + c.missing_hop_cost * missing
            + c.energy_weight * power
            + c.violation_cost * self.violations as f32
    }

    fn skipped(&self) -> u32 {
        self.skipped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn survey_cost_is_the_negated_paper_reward() {
        let mut s = SurveyCost::try_new(1.0).unwrap();
        assert!(s.cost().is_infinite(), "nothing observed: not finite");
        s.observe(&Vector::from([0.0, 0.0, 2.5]), 0.1);
        s.observe(&Vector::from([f32::NAN, 0.0, 0.0]), 0.1);
        assert_eq!((s.cost(), s.reward(), s.skipped()), (2.5, -2.5, 1));
        s.observe(&Vector::from([0.0, 1.2, 0.0]), 0.1);
        assert!((s.cost() - 1.2).abs() < 1e-6);
        for _ in 0..30 {
            s.observe(&Vector::from([0.0, 0.3, 0.0]), 0.1);
        }
        // d < D: reward t_D − D = 3 − 1 = 2, cost −2.
        assert!((s.cost() + 2.0).abs() < 1e-4);
        s.reset();
        assert!(s.cost().is_infinite());
    }

    #[test]
    fn quadratic_cost_integrates_weighted_squares() {
        let mut q = QuadraticCost::<2>::try_new(Vector::from([1.0, 4.0])).unwrap();
        assert!(q.cost().is_nan());
        q.observe(&Vector::from([1.0, 0.5]), 0.5);
        q.observe(&Vector::from([f32::INFINITY, 0.0]), 0.5);
        assert_eq!((q.cost(), q.skipped()), (1.0, 1));
        assert_eq!(
            QuadraticCost::<1>::try_new(Vector::repeat(-1.0)),
            Err(Error::InvalidParameter("weights"))
        );
    }

    #[test]
    fn apex_cost_detects_flight_apexes() {
        let config = ApexConfig {
            set_height: 0.6,
            min_apex: 0.3,
            expected_hops: 3,
            missing_hop_cost: 1.0,
            energy_weight: 0.0,
            violation_cost: 0.5,
            ..ApexConfig::DEFAULT
        };
        let mut c = ApexHeightCost::try_new(config).unwrap();
        // Ballistic hops to 0.62 m and 0.55 m: v goes + → − at the top.
        let sample = |h: f32, v: f32| HopSample {
            height: h,
            vertical_velocity: v,
            power: 1.0,
            limit_violation: false,
        };
        for (h, v) in [
            (0.5, 1.0),
            (0.62, 0.1),
            (0.62, -0.1),
            (0.4, -2.0),
            (0.35, 0.0),
        ] {
            c.observe(&sample(h, v), 0.01);
        }
        for (h, v) in [(0.4, 1.0), (0.55, 0.05), (0.55, -0.05)] {
            c.observe(&sample(h, v), 0.01);
        }
        assert_eq!(c.apexes(), 2);
        assert!((c.apex_spread() - 0.07).abs() < 1e-6);
        let expected = (0.02f32 * 0.02 + 0.05 * 0.05) / 2.0 + 1.0; // one hop missing
        assert!((c.cost() - expected).abs() < 1e-6);
        c.observe(
            &HopSample {
                limit_violation: true,
                ..sample(0.3, -1.0)
            },
            0.01,
        );
        assert!((c.cost() - expected - 0.5).abs() < 1e-6);
    }

    /// The first `transient_hops` apexes count as hops but not in the deviation or the
    /// spread; the spread term is `spread_weight` · (max − min)² over the counted apexes.
    #[test]
    fn apex_cost_skips_transient_hops_and_weights_the_spread() {
        let config = ApexConfig {
            expected_hops: 3,
            missing_hop_cost: 1.0,
            transient_hops: 1,
            spread_weight: 2.0,
            ..ApexConfig::DEFAULT
        };
        let mut c = ApexHeightCost::try_new(config).unwrap();
        // Three ballistic tops: 0.9 m (the transient), then 0.62 m and 0.55 m.
        for top in [0.9f32, 0.62, 0.55] {
            for v in [1.0f32, -1.0] {
                let sample = HopSample {
                    height: top,
                    vertical_velocity: v,
                    power: 0.0,
                    limit_violation: false,
                };
                c.observe(&sample, 0.01);
            }
        }
        assert_eq!((c.apexes(), c.counted_apexes()), (3, 2));
        assert!((c.apex_spread() - 0.07).abs() < 1e-6);
        let deviation = (0.02f32 * 0.02 + 0.05 * 0.05) / 2.0;
        let expected = deviation + 2.0 * 0.07 * 0.07; // no hop missing
        assert!((c.cost() - expected).abs() < 1e-6, "{}", c.cost());
        // One counted apex: no spread yet.
        c.reset();
        for v in [1.0f32, -1.0, 1.0, -1.0] {
            let sample = HopSample {
                height: 0.7,
                vertical_velocity: v,
                power: 0.0,
                limit_violation: false,
            };
            c.observe(&sample, 0.01);
        }
        assert_eq!((c.counted_apexes(), c.apex_spread()), (1, 0.0));
        assert_eq!(
            ApexHeightCost::try_new(ApexConfig {
                spread_weight: f32::NAN,
                ..ApexConfig::DEFAULT
            }),
            Err(Error::InvalidParameter("spread_weight"))
        );
    }
}
