//! A sequential change detector for a deployed correction: after θ is deployed, every episode
//! ends with one cost (and, optionally, the plant model's prediction error for that episode),
//! and the detector says when the plant has changed, that is when the costs have shifted up
//! and stay up, at a documented false-alarm rate, in 56 bytes and O(1) work per episode.
//!
//! # The test: Page's CUSUM
//! One-sided cumulative sum of E. S. Page, "Continuous inspection schemes", Biometrika 41
//! (1954), in the form of the Page–Hinkley test for an increase of the mean (D. V. Hinkley,
//! "Inference about the change-point from cumulative sum tests", Biometrika 58 (1971);
//! Basseville & Nikiforov, "Detection of Abrupt Changes", Prentice Hall 1993, section 2.2).
//! With zₜ the episode's cost standardised against the in-control reference (below), drift k
//! and threshold h:
//!
//! ```text
//! gₜ = max(0, gₜ₋₁ + zₜ − k),   g₀ = 0;      alarm at the first t with gₜ > h
//! ```
//!
//! It is the likelihood-ratio test for a shift of the mean from μ to μ + 2k·σ, and among all
//! detectors with the same false-alarm rate it has the least worst-case delay (Lorden,
//! "Procedures for reacting to a change in distribution", Ann. Math. Statist. 42 (1971)).
//! Only an increase raises g: a plant on which the deployed θ does better needs no alarm.
//!
//! # The reference: self-starting, with the excursions left out
//! The first [`reference_episodes`](ChangeConfig::reference_episodes) episodes after
//! [`reset`](ChangeDetector::reset) only measure the in-control mean x̄ and spread s
//! (Welford's update). A CUSUM that then froze them would not have the false-alarm rate of
//! the formulas below: ten Gaussian costs estimate the mean only to ±0.32 σ, and such
//! detectors raise far more early false alarms than with the true mean and spread (Jones,
//! Champ & Rigdon, "The
//! run length distribution of the CUSUM with estimated parameters", J. Quality Technology 36
//! (2004), report the same effect). So the reference keeps growing, as in Hawkins'
//! self-starting CUSUM (D. M. Hawkins, "Self-starting cusum charts for location and scale",
//! The Statistician 36 (1987)): each episode is standardised against the n reference
//! episodes before it,
//!
//! ```text
//! t = (x − x̄ₙ) / (σₙ·√(1 + 1/n))     Student's t with ν = n − 1 degrees of freedom
//! z = sign(t)·(8ν + 1)/(8ν + 3)·√(ν·ln(1 + t²/ν))     ≈ N(0, 1)
//! ```
//!
//! where the second line is D. L. Wallace's normalising transformation ("Bounds on normal
//! approximations to Student's and the chi-square distributions", Ann. Math. Statist. 30
//! (1959)): for ν ≥ 3 it maps the t quantiles to normal ones within 2 % out to the 99.9 %
//! tail (3.03 for 3.09 at ν = 3), on the low side, so it errs towards fewer alarms. When
//! every episode joins the reference, Hawkins shows that for Gaussian costs the successive z
//! are independent standard normals (with the exact t-to-normal map), so that his CUSUM has,
//! from its first episode, the run lengths of one with known mean and spread.
//!
//! An episode joins the reference (after it has been scored) only if it arrived while g was
//! 0. Hawkins adds every episode; but then a change soon after the reference is learnt as
//! the new normal before it is detected, and many shifts that begin right after a short
//! reference are missed. Leaving out the episodes of an excursion of g keeps the changed costs
//! out of the reference, and because the choice depends only on earlier episodes, the
//! episodes that do join are still independent draws of the in-control cost. The price is
//! paid early: the episodes of one excursion share the reference they are scored against,
//! and a small reference that happens to be low is not corrected by them, so the chance of
//! a false alarm within 100 episodes of the reference is higher than with Hawkins' chart,
//! while the long-run rate stays under one per 1,000 episodes. The unit test
//! `the_reference_rule_against_the_alternatives` measures the three rules (frozen, Hawkins',
//! this one) on the same Gaussian costs; the figures are in `docs/in-service.md`.
//!
//! # The spread floor
//! σₙ = max(s, `min_relative_spread`·|x̄ₙ| + `min_spread`): nearly constant costs (a
//! deterministic simulator, a cost that saturates) would otherwise make every rounding
//! wobble a many-σ event. Where the default floor of 1 % of the mean is in force, a cost
//! less than 0.5 % above the reference mean never moves g at all.
//!
//! # The cost itself, not its logarithm
//! The test runs on the cost as given. Costs may be zero or negative (a shaper that
//! subtracts a baseline), and a persistent rise of the mean is what the learner cares
//! about. A caller whose costs are positive and vary multiplicatively (a time to reach a
//! goal, a squared error whose spread grows with its level) can pass `ln(cost)` instead, and
//! the same for the prediction error.
//!
//! # Defaults, false alarms and delays
//! A reference of 10 episodes (5 halves the blind start but misses a third of the 1 σ shifts
//! that follow it at once, and 3 % of the 2 σ ones); k = 0.5 tunes the test to a shift of
//! 2k = 1 σ; h = 5.3 gives an in-control average run length ARL₀ of at least 1,000 episodes,
//! with a margin, both by Siegmund's approximation for Gaussian costs with known mean and
//! spread (D. Siegmund, "Sequential Analysis", Springer 1985)
//!
//! ```text
//! ARL(δ) ≈ (exp(−2Δb) + 2Δb − 1) / (2Δ²),   Δ = δ − k,  b = h + 1.166
//! ARL₀ = ARL(0) = (exp(2k·b) − 2k·b − 1) / (2k²)
//! ```
//!
//! ([`ChangeConfig::average_run_length`]) and as measured with the self-starting reference.
//! With the true mean and spread, by that approximation and exactly (Page's integral
//! equation, solved by Gauss–Legendre quadrature; the delays too), in episodes:
//!
//! | h   | ARL₀ Siegmund | ARL₀ exact | exact ARL at a 1 σ shift | at 2 σ | at 3 σ |
//! |-----|---------------|------------|--------------------|--------|--------|
//! | 5.0 | 938           | 931        | 10.4               | 4.0    | 2.6    |
//! | 5.1 | 1,038         | 1,030      | 10.6               | 4.1    | 2.6    |
//! | 5.3 | 1,271         | 1,261      | 11.0               | 4.2    | 2.7    |
//!
//! h = 5.1 already has ARL₀ ≥ 1,000 with known parameters, but the self-starting detector's
//! early excess (above) left no margin below one false alarm per 1,000 episodes there; 5.3
//! keeps one, at about 0.1 episode of delay. The unit tests measure on
//! Gaussian costs from fixed seeds the false alarms over 1,000 runs of 1,000 episodes, and
//! the delays of 1, 2 and 3 σ shifts; `cargo test --lib controller::change -- --nocapture`
//! prints them (the measured figures: `docs/in-service.md`).
//!
//! No detector
//! with ARL₀ ≥ 1,000 can do much better: Lorden's bound puts the delay near ln(ARL₀)/I, with
//! I = δ²/2 = 2 the information per episode of a 2 σ shift, that is 3.5 episodes. Detecting
//! it within two episodes (median) would take a CUSUM with ARL₀ of about 300 at most
//! (k = 1, h = 2: 277 by Siegmund's approximation; k = 0.5, h = 3: 119).
//!
//! # The prediction error
//! A change of the plant can leave the deployed θ's cost unchanged (a correction that
//! happens to compensate, a change along a direction the task does not excite) while the
//! plant model, which keeps fitting every tick, predicts worse. A second CUSUM of the same
//! form, with its own self-starting reference, watches the prediction error the caller
//! passes with the cost (e.g. the RMS of
//! [`RlsModel::episode_error`](crate::model::RlsModel::episode_error), reduced to one
//! number). Episodes without one leave it untouched. Either statistic crossing h raises the
//! alarm, and the [`Signal`] says which. With both watched, the false-alarm rate is at most
//! the sum of the two.
//!
//! # After an alarm
//! The detector stays alarmed: every later [`observe`](ChangeDetector::observe) returns the
//! same [`Verdict::Changed`] and changes nothing. The caller relearns the correction for the
//! changed plant, deploys it, and then calls [`reset`](ChangeDetector::reset), which starts
//! a new reference phase (costs measured during relearning are not those of a deployed θ).
//!
//! # Cost
//! The state is 56 bytes (the configuration, two references of 16 bytes and an episode
//! count). An episode costs, per watched input, two square roots, one `log1pf` and a few
//! divisions: no loop, no history, no allocation.
//!
//! ```
//! use ctrl_adapt::controller::change::{ChangeConfig, ChangeDetector, Input, Signal, Verdict};
//! let mut detector = ChangeDetector::try_new(ChangeConfig::DEFAULT)?;
//! // The reference: the first ten episodes of the deployed θ (mean 10, spread 0.26).
//! let reference = [10.0, 10.4, 9.7, 10.1, 9.8, 10.2, 9.9, 10.3, 9.6, 10.0];
//! for (measured, cost) in (1..).zip(&reference[..9]) {
//!     assert_eq!(detector.observe(*cost, None)?, Verdict::Learning { episodes: measured });
//! }
//! assert_eq!(detector.observe(reference[9], None)?, Verdict::Steady); // complete: watching
//! assert_eq!(detector.observe(10.1, None)?, Verdict::Steady);
//! assert_eq!(detector.statistic(Input::Cost), 0.0); // 10.1 is within k σ of the mean
//! assert_eq!(detector.observe(10.4, None)?, Verdict::Steady);
//! assert!(detector.statistic(Input::Cost) > 0.0); // 10.4 is not, but one is no change
//! // The plant changes: the costs rise by 1.2, about 4.6 σ of the reference.
//! let mut changed = 0;
//! let signal = loop {
//!     changed += 1;
//!     if let Verdict::Changed(signal) = detector.observe(11.2, None)? {
//!         break signal;
//!     }
//! };
//! assert_eq!(changed, 2); // the second changed episode (g had already risen with 10.4)
//! assert!(matches!(signal, Signal::Cost(g) if g > ChangeConfig::DEFAULT.threshold));
//! // It stays alarmed until the caller has relearnt and resets it.
//! assert_eq!(detector.observe(10.0, None)?, Verdict::Changed(signal));
//! detector.reset();
//! assert_eq!(detector.observe(11.2, None)?, Verdict::Learning { episodes: 1 });
//! # Ok::<(), ctrl_adapt::Error>(())
//! ```

use crate::error::{Error, require, require_finite};

/// The constants of a [`ChangeDetector`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ChangeConfig {
    /// Episodes after a reset that only measure the reference (≥ 3): no alarm before them.
    /// Each input's reference keeps growing afterwards (see the [module docs](self)), so
    /// this is the detector's blind start rather than the size of its reference.
    pub reference_episodes: u32,
    /// The drift k, in reference spreads (finite, ≥ 0): the CUSUM is tuned to a shift of
    /// the mean by 2k σ, and a cost less than k σ above the reference never raises g.
    pub drift: f32,
    /// The threshold h, in reference spreads (finite, > 0): the alarm is g > h. See
    /// [`ChangeConfig::average_run_length`] for the false-alarm rate it gives.
    pub threshold: f32,
    /// The absolute part of the spread's floor, in the input's units (finite, > 0). Where the
    /// floor is in force (nearly constant inputs), a persistent rise of one floor is found in
    /// about 11 episodes with the default drift and threshold: set the floor near the
    /// smallest rise worth an alarm. Applies to both inputs.
    pub min_spread: f32,
    /// The part of the spread's floor proportional to the reference mean's magnitude
    /// (finite, ≥ 0). Applies to both inputs.
    pub min_relative_spread: f32,
}

impl ChangeConfig {
    /// Reference of 10 episodes, k = 0.5 (a 1 σ shift), h = 5.3 (ARL₀ ≈ 1,271 episodes by
    /// Siegmund's approximation), spread floor 1 % of the mean plus 10⁻⁶. See the
    /// [module docs](self) for how they were chosen.
    pub const DEFAULT: Self = Self {
        reference_episodes: 10,
        drift: 0.5,
        threshold: 5.3,
        min_spread: 1e-6,
        min_relative_spread: 0.01,
    };

    /// Checks every field (named in the error).
    pub fn validate(&self) -> Result<(), Error> {
        require(self.reference_episodes >= 3, "reference_episodes")?;
        require(self.drift.is_finite() && self.drift >= 0.0, "drift")?;
        require(
            self.threshold.is_finite() && self.threshold > 0.0,
            "threshold",
        )?;
        require(
            self.min_spread.is_finite() && self.min_spread > 0.0,
            "min_spread",
        )?;
        require(
            self.min_relative_spread.is_finite() && self.min_relative_spread >= 0.0,
            "min_relative_spread",
        )
    }

    /// Siegmund's approximation of the average run length, in episodes, of a CUSUM with
    /// this drift and threshold on Gaussian inputs whose mean has shifted by `shift`
    /// reference spreads (see the [module docs](self)): `shift = 0` is the in-control run
    /// length ARL₀ (the mean number of episodes between false alarms), a positive shift the
    /// mean delay to detect it. It may be `+∞` (f32 overflow) for a large threshold.
    ///
    /// ```
    /// use ctrl_adapt::controller::change::ChangeConfig;
    /// let config = ChangeConfig::DEFAULT;
    /// let arl0 = config.average_run_length(0.0);
    /// assert!(arl0 >= 1000.0 && arl0 < 1300.0); // ≈ 1,271
    /// let delay = config.average_run_length(2.0);
    /// assert!(delay > 4.0 && delay < 4.2); // ≈ 4.09 episodes for a 2 σ shift
    /// ```
    pub fn average_run_length(&self, shift: f32) -> f32 {
        let b = self.threshold + 1.166;
        let delta = shift - self.drift;
        let x = delta * b;
        if libm::fabsf(x) < 5e-3 {
            // The series of (e^{−2x} + 2x − 1)/(2Δ²) = b²·(1 − 2x/3 + x²/3 − …): the
            // closed form cancels to nothing in f32 as Δ → 0.
            b * b * (1.0 - 2.0 * x / 3.0 + x * x / 3.0)
        } else {
            (libm::expm1f(-2.0 * x) + 2.0 * x) / (2.0 * delta * delta)
        }
    }
}

impl Default for ChangeConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// One of the two inputs the detector watches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Input {
    /// The episode's cost.
    Cost,
    /// The plant model's prediction error for the episode.
    PredictionError,
}

/// Which statistic raised the alarm, and its value g (> the threshold) at that episode.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Signal {
    /// The costs rose.
    Cost(f32),
    /// The prediction errors rose; the costs did not (yet).
    PredictionError(f32),
    /// Both rose, in the same episode.
    Both {
        /// The cost's statistic.
        cost: f32,
        /// The prediction error's statistic.
        prediction_error: f32,
    },
}

impl Signal {
    /// The statistic of `input` if it crossed the threshold, else `None`.
    pub fn statistic(&self, input: Input) -> Option<f32> {
        match (*self, input) {
            (Self::Cost(g), Input::Cost) | (Self::PredictionError(g), Input::PredictionError) => {
                Some(g)
            }
            (Self::Both { cost, .. }, Input::Cost) => Some(cost),
            (
                Self::Both {
                    prediction_error, ..
                },
                Input::PredictionError,
            ) => Some(prediction_error),
            _ => None,
        }
    }
}

/// What the detector concludes after an episode.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Verdict {
    /// Still measuring the cost's reference: `episodes` of
    /// [`reference_episodes`](ChangeConfig::reference_episodes) so far (the episode that
    /// completes it returns [`Verdict::Steady`]). No alarm yet.
    Learning {
        /// Reference episodes measured since the reset.
        episodes: u32,
    },
    /// No change detected.
    Steady,
    /// The plant has changed; the detector stays here until
    /// [`reset`](ChangeDetector::reset).
    Changed(Signal),
}

/// The in-control reference of one input, as the detector standardises with it now.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Reference {
    /// Episodes in the reference: the reference phase's, then those that arrived while the
    /// statistic was 0.
    pub episodes: u32,
    /// Their mean x̄.
    pub mean: f32,
    /// The spread σ used: their sample standard deviation, or the floor where that is
    /// larger (the floor alone below two episodes).
    pub spread: f32,
}

/// One input's reference (Welford's count, mean and sum of squared deviations) and its
/// CUSUM statistic: 16 bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Cusum {
    episodes: u32,
    mean: f32,
    /// Σ (x − x̄)² over the reference episodes.
    m2: f32,
    /// g ≥ 0, finite; above the threshold once alarmed.
    statistic: f32,
}

impl Cusum {
    const EMPTY: Self = Self {
        episodes: 0,
        mean: 0.0,
        m2: 0.0,
        statistic: 0.0,
    };

    fn learning(&self, config: &ChangeConfig) -> bool {
        self.episodes < config.reference_episodes
    }

    fn alarmed(&self, config: &ChangeConfig) -> bool {
        self.statistic > config.threshold
    }

    /// max(s, min_relative_spread·|x̄| + min_spread): finite and > 0 for a valid state (the
    /// floor's product may overflow: it is then f32::MAX).
    fn spread(&self, config: &ChangeConfig) -> f32 {
        let floor = config.min_relative_spread * libm::fabsf(self.mean) + config.min_spread;
        let floor = if floor < f32::MAX { floor } else { f32::MAX };
        let s = if self.episodes >= 2 {
            libm::sqrtf(self.m2 / (self.episodes - 1) as f32)
        } else {
            0.0
        };
        if s > floor { s } else { floor }
    }

    fn reference(&self, config: &ChangeConfig) -> Reference {
        Reference {
            episodes: self.episodes,
            mean: self.mean,
            spread: self.spread(config),
        }
    }

    /// Welford's update with `x`, or `None` if it overflows f32 (an input near f32::MAX,
    /// or far from the mean). A reference of u32::MAX episodes stays as it is.
    fn absorb(&self, x: f32) -> Option<Self> {
        if self.episodes == u32::MAX {
            return Some(*self);
        }
        let episodes = self.episodes + 1;
        let d = x - self.mean;
        let mean = self.mean + d / episodes as f32;
        let m2 = self.m2 + d * (x - mean);
        (mean.is_finite() && m2.is_finite()).then_some(Self {
            episodes,
            mean,
            m2,
            ..*self
        })
    }

    /// Hawkins' standardised score of `x` against the reference (n ≥ 2 episodes): the
    /// Student-t value with n − 1 degrees of freedom mapped to N(0, 1) by Wallace's
    /// transformation. ±∞ for an `x` so far out that t² overflows; never NaN.
    fn score(&self, x: f32, config: &ChangeConfig) -> f32 {
        let n = self.episodes as f32;
        let nu = n - 1.0;
        // σ is finite and > 0, so d is finite or ±∞ (x − x̄ overflowing), never NaN.
        let d = (x - self.mean) / self.spread(config);
        let t2 = d * d * (n / (n + 1.0));
        let z = (8.0 * nu + 1.0) / (8.0 * nu + 3.0) * libm::sqrtf(nu * libm::log1pf(t2 / nu));
        if d < 0.0 { -z } else { z }
    }

    /// This input's next state after an episode's value `x`: into the reference while it is
    /// learning; else g updated, and `x` added to the reference if g was 0 and no alarm
    /// follows. `Err(Overflow(name))` when the reference's update would overflow.
    fn step(&self, x: f32, config: &ChangeConfig, name: &'static str) -> Result<Self, Error> {
        if self.learning(config) {
            return self.absorb(x).ok_or(Error::Overflow(name));
        }
        let g = self.statistic + self.score(x, config) - config.drift;
        // max(0, g), with +∞ held at f32::MAX (an alarm all the same: the threshold is finite).
        let g = if g > 0.0 {
            if g < f32::MAX { g } else { f32::MAX }
        } else {
            0.0
        };
        let next = Self {
            statistic: g,
            ..*self
        };
        if self.statistic == 0.0 && !next.alarmed(config) {
            next.absorb(x).ok_or(Error::Overflow(name))
        } else {
            Ok(next)
        }
    }

    fn validate(&self, config: &ChangeConfig, name: &'static str) -> Result<(), Error> {
        require_finite(&[self.mean, self.m2, self.statistic], name)?;
        require(self.m2 >= 0.0 && self.statistic >= 0.0, name)?;
        require(self.episodes >= 2 || self.m2 == 0.0, name)?;
        require(self.episodes >= 1 || self.mean == 0.0, name)?;
        require(!self.learning(config) || self.statistic == 0.0, name)
    }
}

/// The change detector: a one-sided CUSUM on the deployed episodes' costs and another on
/// the plant model's prediction errors, each against a self-starting reference (see the
/// [module docs](self) for the method and its false-alarm rate). 56 bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ChangeDetector {
    config: ChangeConfig,
    cost: Cusum,
    prediction_error: Cusum,
    /// Episodes observed since the reset (saturating), the alarm's episode included.
    episodes: u32,
}

impl ChangeDetector {
    /// A detector at the start of its reference phase, or the field of `config` that is out
    /// of range ([`ChangeConfig::validate`]).
    pub fn try_new(config: ChangeConfig) -> Result<Self, Error> {
        config.validate()?;
        Ok(Self {
            config,
            cost: Cusum::EMPTY,
            prediction_error: Cusum::EMPTY,
            episodes: 0,
        })
    }

    /// The constants.
    pub fn config(&self) -> &ChangeConfig {
        &self.config
    }

    /// Reports a deployed episode: its `cost` and, if the model was fitted during it, its
    /// `prediction_error`; returns the verdict after it.
    ///
    /// Errors, after which nothing has changed: a NaN or infinite input
    /// ([`Error::NonFinite`]`("cost")` or `("prediction_error")`), and a finite one so far
    /// from the reference that its update would overflow f32 ([`Error::Overflow`] naming
    /// the input; e.g. 10³⁰ against a reference near 1). Once alarmed, the detector returns
    /// the same [`Verdict::Changed`] for every valid episode until [`reset`](Self::reset).
    pub fn observe(&mut self, cost: f32, prediction_error: Option<f32>) -> Result<Verdict, Error> {
        require_finite(&[cost], "cost")?;
        if let Some(e) = prediction_error {
            require_finite(&[e], "prediction_error")?;
        }
        if let Verdict::Changed(signal) = self.verdict() {
            return Ok(Verdict::Changed(signal));
        }
        let config = self.config;
        let next_cost = self.cost.step(cost, &config, "cost")?;
        let next_error = match prediction_error {
            Some(e) => self.prediction_error.step(e, &config, "prediction_error")?,
            None => self.prediction_error,
        };
        self.cost = next_cost;
        self.prediction_error = next_error;
        self.episodes = self.episodes.saturating_add(1);
        Ok(self.verdict())
    }

    /// The verdict after the last episode: [`Verdict::Learning`] with no episode yet.
    pub fn verdict(&self) -> Verdict {
        let config = &self.config;
        let (cost, error) = (self.cost.statistic, self.prediction_error.statistic);
        match (
            self.cost.alarmed(config),
            self.prediction_error.alarmed(config),
        ) {
            (true, true) => Verdict::Changed(Signal::Both {
                cost,
                prediction_error: error,
            }),
            (true, false) => Verdict::Changed(Signal::Cost(cost)),
            (false, true) => Verdict::Changed(Signal::PredictionError(error)),
            (false, false) if self.cost.learning(config) => Verdict::Learning {
                episodes: self.cost.episodes,
            },
            (false, false) => Verdict::Steady,
        }
    }

    /// True once a change has been detected (until [`reset`](Self::reset)).
    pub fn changed(&self) -> bool {
        matches!(self.verdict(), Verdict::Changed(_))
    }

    /// Starts a new reference phase, for both inputs: call it once the correction
    /// relearnt for the changed plant is deployed. The configuration stays.
    pub fn reset(&mut self) {
        self.cost = Cusum::EMPTY;
        self.prediction_error = Cusum::EMPTY;
        self.episodes = 0;
    }

    /// The CUSUM statistic g of `input` (0 while its reference is measured; in reference
    /// spreads, compare it with the threshold).
    pub fn statistic(&self, input: Input) -> f32 {
        self.cusum(input).statistic
    }

    /// The reference `input` is standardised against.
    pub fn reference(&self, input: Input) -> Reference {
        self.cusum(input).reference(&self.config)
    }

    /// Episodes observed since the reset (or since construction), the one that raised the
    /// alarm included; refused ones are not counted.
    pub fn episodes(&self) -> u32 {
        self.episodes
    }

    fn cusum(&self, input: Input) -> &Cusum {
        match input {
            Input::Cost => &self.cost,
            Input::PredictionError => &self.prediction_error,
        }
    }

    /// Checks a detector that was decoded rather than built: a valid configuration; finite
    /// references and statistics ([`Error::NonFinite`]); g ≥ 0, Σ(x − x̄)² ≥ 0 (and 0 below
    /// two episodes), g = 0 while a reference is measured; counts that fit (no reference
    /// holds more episodes than were observed, and the cost's holds all of them during its
    /// reference phase). The error names the field: `"cost"`, `"prediction_error"` or
    /// `"episodes"`.
    pub fn validate(&self) -> Result<(), Error> {
        self.config.validate()?;
        self.cost.validate(&self.config, "cost")?;
        self.prediction_error
            .validate(&self.config, "prediction_error")?;
        let episodes = self.episodes;
        require(self.cost.episodes <= episodes, "episodes")?;
        require(self.prediction_error.episodes <= episodes, "episodes")?;
        require(
            !self.cost.learning(&self.config) || self.cost.episodes == episodes,
            "episodes",
        )
    }
}

/// Compile-time proof that the public types implement `defmt::Format` with the feature.
#[cfg(feature = "defmt")]
const _: () = {
    const fn assert_format<T: defmt::Format>() {}
    assert_format::<ChangeConfig>();
    assert_format::<ChangeDetector>();
    assert_format::<Verdict>();
    assert_format::<Signal>();
    assert_format::<Reference>();
    assert_format::<Input>();
};

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::random::{normal_pair_f32, unit_f32};
    use crate::testing::rng;
    use proptest::prelude::*;
    use rand_xoshiro::Xoshiro128PlusPlus;

    /// The in-control mean of the simulated costs; their spread is 1.
    const MEAN: f32 = 10.0;

    /// Gaussian costs of spread 1 from one seed.
    struct Costs(Xoshiro128PlusPlus);

    impl Costs {
        fn new(seed: u64) -> Self {
            Self(rng(seed))
        }

        fn next(&mut self, mean: f32) -> f32 {
            mean + normal_pair_f32(&mut self.0)[0]
        }
    }

    /// Where a run of N(MEAN, 1) costs, shifted by `shift` from episode `at` on, raised the
    /// alarm: `Some(episode)` (from 0), or `None` within `episodes`.
    fn alarm(config: ChangeConfig, seed: u64, at: u32, shift: f32, episodes: u32) -> Option<u32> {
        let mut costs = Costs::new(seed);
        let mut detector = ChangeDetector::try_new(config).unwrap();
        (0..episodes).find(|&e| {
            let mean = if e >= at { MEAN + shift } else { MEAN };
            let verdict = detector.observe(costs.next(mean), None).unwrap();
            matches!(verdict, Verdict::Changed(_))
        })
    }

    /// Delays (changed episodes up to and including the alarm's) of a shift at episode
    /// `at`, over `runs` seeds: the sorted delays, the false alarms before the change and
    /// the changes not detected within `limit` episodes.
    fn delays(at: u32, shift: f32, runs: u64, limit: u32) -> (Vec<u32>, u32, u32) {
        let (mut delays, mut early, mut missed) = (Vec::new(), 0, 0);
        for seed in 0..runs {
            match alarm(ChangeConfig::DEFAULT, 1_000 + seed, at, shift, at + limit) {
                Some(e) if e >= at => delays.push(e - at + 1),
                Some(_) => early += 1,
                None => missed += 1,
            }
        }
        delays.sort_unstable();
        (delays, early, missed)
    }

    fn mean(values: &[u32]) -> f32 {
        values.iter().sum::<u32>() as f32 / values.len() as f32
    }

    #[test]
    fn the_detector_fits_in_64_bytes() {
        std::println!(
            "size_of::<ChangeDetector>() = {}",
            size_of::<ChangeDetector>()
        );
        assert!(size_of::<ChangeDetector>() <= 64);
        assert_eq!(size_of::<ChangeDetector>(), 56);
    }

    /// The documented false-alarm rate, measured: N(10, 1) costs, the detector reset after
    /// each alarm (a new reference phase, as a caller that relearns does).
    #[test]
    fn false_alarms_are_at_most_one_per_thousand_episodes() {
        let config = ChangeConfig::DEFAULT;
        let arl0 = config.average_run_length(0.0);
        let (runs, episodes) = (1_000u32, 1_000u32);
        let mut alarms = Vec::new();
        for seed in 0..runs {
            let mut costs = Costs::new(u64::from(seed));
            let mut detector = ChangeDetector::try_new(config).unwrap();
            let mut count = 0u32;
            for _ in 0..episodes {
                if let Verdict::Changed(_) = detector.observe(costs.next(MEAN), None).unwrap() {
                    count += 1;
                    detector.reset();
                }
            }
            alarms.push(count);
        }
        let first_ten: u32 = alarms[..10].iter().sum();
        let total: u32 = alarms.iter().sum();
        let per_thousand = total as f32 * 1_000.0 / (runs * episodes) as f32;
        std::println!(
            "false alarms: {first_ten} in 10 runs of {episodes} episodes; {total} in {runs} runs \
             ({per_thousand:.2} per 1,000 episodes; Siegmund's ARL0 = {arl0:.0} episodes, \
             {:.2} per 1,000 with the true mean and spread)",
            1_000.0 / (arl0 + config.reference_episodes as f32)
        );
        // Ten runs: at most one alarm per 1,000 episodes is a Poisson count of mean ≤ 10,
        // above 20 with probability 0.16 %.
        assert!(first_ten <= 20, "{first_ten}");
        // A million episodes: the claim itself (the count's spread is about 30).
        assert!(total <= runs * episodes / 1_000, "{total}");
        // ... and not an empty one: at least half the rate of known parameters.
        let known = (runs * episodes) as f32 / (arl0 + config.reference_episodes as f32);
        assert!(total as f32 >= 0.5 * known, "{total}");
    }

    /// Shifts beginning 50 episodes after the reference. A 2 σ shift is detected at its
    /// fourth changed episode (median): with ARL₀ ≥ 1,000 no detector can do much better
    /// (Lorden's bound: ln(ARL₀)/(δ²/2) ≈ 3.5 episodes; see the module docs).
    #[test]
    fn shifts_are_detected_within_the_cusum_delays() {
        let config = ChangeConfig::DEFAULT;
        let at = config.reference_episodes + 50;
        let mut medians = Vec::new();
        for shift in [1.0, 2.0, 3.0] {
            let (d, early, missed) = delays(at, shift, 500, 200);
            let median = d[d.len() / 2];
            std::println!(
                "{shift} σ shift at episode {at}: delay median {median}, mean {:.2} \
                 (Siegmund {:.2}), 90 % within {}, max {}; {early} false alarms before it, \
                 {missed} missed within 200 (500 runs)",
                mean(&d),
                config.average_run_length(shift),
                d[d.len() * 9 / 10],
                d[d.len() - 1],
            );
            assert!(missed <= 5, "{missed}");
            medians.push((median, mean(&d)));
        }
        assert!(medians[0].0 <= 12 && medians[0].1 <= 16.0, "{medians:?}");
        assert!(medians[1].0 <= 4 && medians[1].1 <= 5.0, "{medians:?}");
        assert!(medians[2].0 <= 3 && medians[2].1 <= 3.5, "{medians:?}");
    }

    /// A change that begins at the first episode after the reference is not learnt as the
    /// new normal: the episodes of the excursion stay out of the reference.
    #[test]
    fn a_change_right_after_the_reference_is_detected() {
        let at = ChangeConfig::DEFAULT.reference_episodes;
        let (d, _, missed) = delays(at, 2.0, 500, 300);
        let median = d[d.len() / 2];
        std::println!(
            "2 σ shift right after the reference: delay median {median}, mean {:.2}, \
             max {}; {missed} missed within 300 (500 runs)",
            mean(&d),
            d[d.len() - 1],
        );
        assert!(missed <= 5, "{missed}");
        assert!(median <= 7, "{median}");
    }

    /// How each input's reference grows after the reference phase.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Rule {
        /// Frozen after the reference phase, costs standardised by it directly.
        Frozen,
        /// Hawkins' self-starting CUSUM: every episode joins.
        Hawkins,
        /// This module's: the episodes that arrive while g = 0 join.
        Excursions,
    }

    /// The first alarm's episode of a run under `rule` (the same costs for every rule).
    fn alarm_under(rule: Rule, seed: u64, at: u32, shift: f32, episodes: u32) -> Option<u32> {
        let config = ChangeConfig::DEFAULT;
        let mut costs = Costs::new(seed);
        let mut c = Cusum::EMPTY;
        (0..episodes).find(|&e| {
            let x = costs.next(if e >= at { MEAN + shift } else { MEAN });
            if c.learning(&config) {
                c = c.absorb(x).unwrap();
                return false;
            }
            let z = match rule {
                Rule::Frozen => (x - c.mean) / c.spread(&config),
                Rule::Hawkins => c.score(x, &config),
                Rule::Excursions => {
                    c = c.step(x, &config, "cost").unwrap();
                    return c.alarmed(&config);
                }
            };
            c.statistic = (c.statistic + z - config.drift).max(0.0);
            if rule == Rule::Hawkins && !c.alarmed(&config) {
                c = c.absorb(x).unwrap();
            }
            c.alarmed(&config)
        })
    }

    /// The figures of the module docs' comparison: the chance of a false alarm within 100
    /// episodes of a 10-episode reference, and the 1 σ and 2 σ shifts beginning right after
    /// it that are not detected within 300 episodes.
    #[test]
    fn the_reference_rule_against_the_alternatives() {
        let m = ChangeConfig::DEFAULT.reference_episodes;
        let mut figures = Vec::new();
        for rule in [Rule::Frozen, Rule::Hawkins, Rule::Excursions] {
            let runs = 2_000u64;
            let early = (0..runs)
                .filter(|&seed| alarm_under(rule, 50_000 + seed, u32::MAX, 0.0, m + 100).is_some())
                .count() as f32
                / runs as f32;
            let missed = |shift: f32| {
                (0..1_000u64)
                    .filter(|&seed| alarm_under(rule, 90_000 + seed, m, shift, m + 300).is_none())
                    .count() as f32
                    / 1_000.0
            };
            let (missed_1, missed_2) = (missed(1.0), missed(2.0));
            std::println!(
                "{rule:?}: false alarm within 100 episodes {:.1} %, missed within 300: \
                 1 σ {:.1} %, 2 σ {:.1} %",
                100.0 * early,
                100.0 * missed_1,
                100.0 * missed_2
            );
            figures.push((early, missed_1, missed_2));
        }
        let [frozen, hawkins, ours] = figures[..] else {
            unreachable!()
        };
        assert!(frozen.0 > 0.25 && ours.0 < 0.17, "{figures:?}");
        assert!(hawkins.0 < 0.09, "{figures:?}");
        assert!(hawkins.1 > 0.4 && hawkins.2 > 0.05, "{figures:?}");
        assert!(ours.1 < 0.2 && ours.2 < 0.005, "{figures:?}");
    }

    /// A detector in each phase: fresh, learning, steady with g > 0, alarmed.
    fn detectors() -> [ChangeDetector; 4] {
        let fresh = ChangeDetector::try_new(ChangeConfig::DEFAULT).unwrap();
        let mut learning = fresh;
        learning.observe(10.0, Some(1.0)).unwrap();
        let mut steady = fresh;
        let mut costs = Costs::new(3);
        for _ in 0..20 {
            steady.observe(costs.next(MEAN), Some(1.0)).unwrap();
        }
        while steady.statistic(Input::Cost) == 0.0 {
            steady.observe(MEAN + 1.5, Some(1.0)).unwrap();
        }
        assert_eq!(steady.verdict(), Verdict::Steady);
        let mut alarmed = steady;
        while !alarmed.changed() {
            alarmed.observe(MEAN + 3.0, Some(1.0)).unwrap();
        }
        [fresh, learning, steady, alarmed]
    }

    #[test]
    fn a_non_finite_input_changes_nothing() {
        for mut detector in detectors() {
            let before = detector;
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let cost = Err(Error::NonFinite("cost"));
                assert_eq!(detector.observe(bad, None), cost);
                assert_eq!(detector.observe(bad, Some(1.0)), cost);
                assert_eq!(detector.observe(bad, Some(bad)), cost);
                // A valid cost is not taken without its valid prediction error.
                let error = Err(Error::NonFinite("prediction_error"));
                assert_eq!(detector.observe(10.0, Some(bad)), error);
                assert_eq!(detector, before);
            }
        }
    }

    #[test]
    fn an_update_that_would_overflow_is_refused_and_a_huge_cost_is_a_change() {
        let mut learning = ChangeDetector::try_new(ChangeConfig::DEFAULT).unwrap();
        learning.observe(1.0, None).unwrap();
        learning.observe(2.0, None).unwrap();
        let before = learning;
        // Σ(x − x̄)² would overflow: refused, and nothing changed.
        assert_eq!(learning.observe(1e30, None), Err(Error::Overflow("cost")));
        assert_eq!(
            learning.observe(1.0, Some(1e30)),
            Ok(Verdict::Learning { episodes: 3 })
        );
        assert_eq!(
            learning.observe(1.0, Some(-1e30)),
            Err(Error::Overflow("prediction_error"))
        );
        assert_eq!(learning.episodes(), 3);
        assert!(before.validate().is_ok() && learning.validate().is_ok());

        let [_, _, steady, _] = detectors();
        let mut fresh_g = steady;
        fresh_g.reset();
        for _ in 0..10 {
            fresh_g.observe(MEAN, None).unwrap();
        }
        // A cost far below the reference: g stays 0, so it would join the reference, whose
        // update overflows: refused.
        let before = fresh_g;
        assert_eq!(fresh_g.observe(-1e30, None), Err(Error::Overflow("cost")));
        assert_eq!(fresh_g, before);
        // Far above: a change, with g held finite.
        let mut huge = steady;
        assert_eq!(
            huge.observe(1e30, None),
            Ok(Verdict::Changed(Signal::Cost(f32::MAX)))
        );
        assert!(huge.validate().is_ok());
        let mut largest = steady;
        assert!(matches!(
            largest.observe(f32::MAX, Some(f32::MAX)),
            Ok(Verdict::Changed(Signal::Both { .. }))
        ));
        assert!(largest.validate().is_ok());
    }

    #[test]
    fn nearly_constant_costs_do_not_alarm_on_tiny_wobbles() {
        let config = ChangeConfig::DEFAULT;
        let mut detector = ChangeDetector::try_new(config).unwrap();
        for _ in 0..config.reference_episodes {
            detector.observe(MEAN, None).unwrap();
        }
        // Equal costs: the spread is the floor, 1 % of the mean plus 10⁻⁶.
        let reference = detector.reference(Input::Cost);
        assert_eq!(
            (reference.mean, reference.spread),
            (MEAN, 0.01 * MEAN + 1e-6)
        );
        // Wobbles up to ±0.4 % never move g (less than k·σ = 0.5 % above the mean).
        let mut r = rng(5);
        for _ in 0..10_000 {
            let wobble = 0.04 * (2.0 * unit_f32(&mut r) - 1.0);
            assert_eq!(detector.observe(MEAN + wobble, None), Ok(Verdict::Steady));
            assert_eq!(detector.statistic(Input::Cost), 0.0);
        }
        // A persistent 2 % rise is a change (2 floors), found within the CUSUM's delay.
        let changed = (1..=10)
            .find(|_| detector.observe(MEAN * 1.02, None).unwrap() != Verdict::Steady)
            .unwrap();
        assert!(changed <= 5, "{changed}");
        assert!(detector.changed());

        // All-zero costs: the absolute floor alone.
        let mut zero = ChangeDetector::try_new(config).unwrap();
        for _ in 0..1_000 {
            let verdict = zero.observe(0.0, Some(0.0)).unwrap();
            assert!(!matches!(verdict, Verdict::Changed(_)));
        }
        for wobble in [1e-7, -1e-7, 4e-7, 0.0] {
            assert_eq!(zero.observe(wobble, Some(wobble)), Ok(Verdict::Steady));
        }
        // The wobbles that joined moved the mean by less than 10⁻⁶: the floor is 10⁻⁶.
        let spread = zero.reference(Input::PredictionError).spread;
        assert!((1e-6..1.0001e-6).contains(&spread), "{spread}");
    }

    #[test]
    fn the_prediction_error_is_watched_on_its_own() {
        let config = ChangeConfig::DEFAULT;
        let mut detector = ChangeDetector::try_new(config).unwrap();
        let mut costs = Costs::new(8);
        let mut errors = Costs::new(9);
        // Episodes without a prediction error leave its reference alone.
        for e in 0..40 {
            let error = (e % 2 == 0).then(|| 0.1 * errors.next(10.0));
            let verdict = detector.observe(costs.next(MEAN), error).unwrap();
            assert!(!matches!(verdict, Verdict::Changed(_)), "{verdict:?}");
        }
        assert_eq!(detector.episodes(), 40);
        assert!(detector.reference(Input::PredictionError).episodes <= 20);
        assert!(detector.reference(Input::PredictionError).episodes >= config.reference_episodes);
        // The model's error rises by about 5 σ; the costs do not move.
        let signal = loop {
            match detector.observe(costs.next(MEAN), Some(1.5)).unwrap() {
                Verdict::Changed(signal) => break signal,
                verdict => assert_eq!(verdict, Verdict::Steady),
            }
        };
        let Signal::PredictionError(g) = signal else {
            panic!("{signal:?}")
        };
        assert!(g > config.threshold);
        assert_eq!(signal.statistic(Input::PredictionError), Some(g));
        assert_eq!(signal.statistic(Input::Cost), None);
        assert!(detector.statistic(Input::Cost) <= config.threshold);

        // Both at once.
        detector.reset();
        for e in 0..20 {
            detector
                .observe(MEAN + (e % 3) as f32, Some(1.0 + 0.1 * (e % 2) as f32))
                .unwrap();
        }
        let Ok(Verdict::Changed(both)) = detector.observe(1e6, Some(1e6)) else {
            panic!("{:?}", detector.verdict())
        };
        assert!(matches!(both, Signal::Both { .. }));
        assert!(both.statistic(Input::Cost).unwrap() > config.threshold);
        assert!(both.statistic(Input::PredictionError).unwrap() > config.threshold);
    }

    #[test]
    fn reset_starts_a_new_reference_phase() {
        let [_, _, _, mut alarmed] = detectors();
        let signal = alarmed.verdict();
        assert!(matches!(signal, Verdict::Changed(_)));
        let before = alarmed;
        assert_eq!(alarmed.observe(MEAN, None), Ok(signal));
        assert_eq!(alarmed, before, "an alarmed detector changes nothing");
        alarmed.reset();
        assert_eq!(alarmed.verdict(), Verdict::Learning { episodes: 0 });
        assert_eq!(
            alarmed,
            ChangeDetector::try_new(ChangeConfig::DEFAULT).unwrap()
        );
        for e in 1..ChangeConfig::DEFAULT.reference_episodes {
            assert_eq!(
                alarmed.observe(MEAN + 100.0, None),
                Ok(Verdict::Learning { episodes: e })
            );
        }
        assert_eq!(alarmed.observe(MEAN + 100.0, None), Ok(Verdict::Steady));
    }

    #[test]
    fn config_validation_names_the_field() {
        let base = ChangeConfig::DEFAULT;
        assert_eq!(base.validate(), Ok(()));
        assert_eq!(ChangeConfig::default(), base);
        let bad = [
            (
                ChangeConfig {
                    reference_episodes: 2,
                    ..base
                },
                "reference_episodes",
            ),
            (
                ChangeConfig {
                    drift: -0.1,
                    ..base
                },
                "drift",
            ),
            (
                ChangeConfig {
                    drift: f32::NAN,
                    ..base
                },
                "drift",
            ),
            (
                ChangeConfig {
                    drift: f32::INFINITY,
                    ..base
                },
                "drift",
            ),
            (
                ChangeConfig {
                    threshold: 0.0,
                    ..base
                },
                "threshold",
            ),
            (
                ChangeConfig {
                    threshold: f32::INFINITY,
                    ..base
                },
                "threshold",
            ),
            (
                ChangeConfig {
                    threshold: f32::NAN,
                    ..base
                },
                "threshold",
            ),
            (
                ChangeConfig {
                    min_spread: 0.0,
                    ..base
                },
                "min_spread",
            ),
            (
                ChangeConfig {
                    min_spread: f32::NAN,
                    ..base
                },
                "min_spread",
            ),
            (
                ChangeConfig {
                    min_relative_spread: -1e-3,
                    ..base
                },
                "min_relative_spread",
            ),
            (
                ChangeConfig {
                    min_relative_spread: f32::INFINITY,
                    ..base
                },
                "min_relative_spread",
            ),
        ];
        for (config, field) in bad {
            assert_eq!(config.validate(), Err(Error::InvalidParameter(field)));
            assert_eq!(
                ChangeDetector::try_new(config),
                Err(Error::InvalidParameter(field))
            );
        }
        // The edges are valid: no drift, no relative floor, the shortest reference.
        let edges = ChangeConfig {
            reference_episodes: 3,
            drift: 0.0,
            min_relative_spread: 0.0,
            ..base
        };
        assert!(ChangeDetector::try_new(edges).is_ok());
    }

    #[test]
    fn siegmunds_approximation_gives_the_tables_figures() {
        let at = |threshold: f32, shift: f32| {
            ChangeConfig {
                threshold,
                ..ChangeConfig::DEFAULT
            }
            .average_run_length(shift)
        };
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-3 * b;
        assert!(close(at(5.0, 0.0), 938.2), "{}", at(5.0, 0.0));
        assert!(close(at(5.1, 0.0), 1037.9), "{}", at(5.1, 0.0));
        assert!(close(at(5.3, 0.0), 1270.9), "{}", at(5.3, 0.0));
        assert!(close(at(5.3, 1.0), 10.94), "{}", at(5.3, 1.0));
        assert!(close(at(5.3, 2.0), 4.09), "{}", at(5.3, 2.0));
        // h = 5.3 is the first threshold in steps of 0.1 from 5 whose ARL₀ exceeds 1,000
        // with the self-starting reference's measured excess (see the module docs); 5.0
        // falls short even with known parameters.
        assert!(at(5.0, 0.0) < 1_000.0 && at(5.3, 0.0) >= 1_000.0);
        // Through Δ = 0 (shift = drift, where it is b²) and either side of the series' switch,
        // within 10⁻⁴ of the closed form in f64.
        let b = 5.3 + 1.166f32;
        assert_eq!(at(5.3, 0.5), b * b);
        for eps in [
            0.0f64, 1e-6, 1e-5, 1e-4, 7.7e-4, 7.8e-4, 1e-3, 1e-2, 0.1, 1.0,
        ] {
            for shift in [0.5 - eps, 0.5 + eps] {
                let (b, delta) = (f64::from(b), f64::from(shift as f32) - 0.5);
                let exact = if delta == 0.0 {
                    b * b
                } else {
                    ((-2.0 * delta * b).exp() + 2.0 * delta * b - 1.0) / (2.0 * delta * delta)
                };
                let approx = f64::from(at(5.3, shift as f32));
                assert!(
                    (approx / exact - 1.0).abs() < 1e-4,
                    "{shift}: {approx} {exact}"
                );
            }
        }
    }

    #[test]
    fn decoded_states_are_validated() {
        for detector in detectors() {
            assert_eq!(detector.validate(), Ok(()));
        }
        let [_, learning, steady, _] = detectors();
        let forged = |f: fn(&mut ChangeDetector), base: ChangeDetector| {
            let mut d = base;
            f(&mut d);
            d.validate()
        };
        let invalid = Err(Error::InvalidParameter("cost"));
        assert_eq!(
            forged(|d| d.cost.statistic = f32::NAN, steady),
            Err(Error::NonFinite("cost"))
        );
        assert_eq!(
            forged(|d| d.prediction_error.mean = f32::INFINITY, steady),
            Err(Error::NonFinite("prediction_error"))
        );
        assert_eq!(forged(|d| d.cost.statistic = -1.0, steady), invalid);
        assert_eq!(forged(|d| d.cost.m2 = -1.0, steady), invalid);
        assert_eq!(forged(|d| d.cost.m2 = 1.0, learning), invalid);
        assert_eq!(forged(|d| d.cost.statistic = 1.0, learning), invalid);
        let episodes = Err(Error::InvalidParameter("episodes"));
        assert_eq!(forged(|d| d.episodes = 0, learning), episodes);
        assert_eq!(forged(|d| d.episodes = 5, learning), episodes);
        assert_eq!(
            forged(|d| d.prediction_error.episodes = u32::MAX, steady),
            episodes
        );
        assert_eq!(
            forged(|d| d.config.threshold = -1.0, steady),
            Err(Error::InvalidParameter("threshold"))
        );
    }

    #[cfg(feature = "serde")]
    #[test]
    fn a_detector_round_trips_through_postcard() {
        let mut buf = [0u8; 128];
        for detector in detectors() {
            let bytes = postcard::to_slice(&detector, &mut buf).unwrap();
            let len = bytes.len();
            let back: ChangeDetector = postcard::from_bytes(&buf[..len]).unwrap();
            assert_eq!(back, detector);
            assert_eq!(back.validate(), Ok(()));
            assert_eq!(back.verdict(), detector.verdict());
        }
        // A record whose statistic is NaN decodes, and is refused by `validate`.
        let [_, _, mut steady, _] = detectors();
        steady.cost.statistic = f32::NAN;
        let len = postcard::to_slice(&steady, &mut buf).unwrap().len();
        let back: ChangeDetector = postcard::from_bytes(&buf[..len]).unwrap();
        assert_eq!(back.validate(), Err(Error::NonFinite("cost")));
    }

    fn any_f32() -> impl Strategy<Value = f32> {
        prop_oneof![
            4 => 9.0f32..11.0,
            1 => any::<f32>(),
            1 => Just(f32::NAN),
            1 => Just(f32::INFINITY),
            1 => Just(f32::MAX),
            1 => Just(-f32::MAX),
            1 => Just(1e30f32),
            1 => Just(0.0f32),
        ]
    }

    proptest! {
        /// Any sequence of inputs, finite or not, huge or not, with any valid configuration:
        /// no panic; a refused episode changes nothing; the verdict returned is the
        /// detector's; an alarm stays; the state validates.
        #[test]
        fn any_sequence_never_panics_and_stays_valid(
            episodes in proptest::collection::vec(
                (any_f32(), proptest::option::of(any_f32())), 1..80),
            reference_episodes in 3u32..8,
            drift in prop_oneof![Just(0.0f32), 0.0f32..3.0, Just(1e30f32)],
            threshold in prop_oneof![1e-6f32..20.0, Just(f32::MAX)],
            min_spread in prop_oneof![Just(f32::MIN_POSITIVE), 1e-6f32..1.0, Just(f32::MAX)],
            min_relative_spread in prop_oneof![Just(0.0f32), 0.0f32..1.0, Just(f32::MAX)],
        ) {
            let config = ChangeConfig {
                reference_episodes, drift, threshold, min_spread, min_relative_spread,
            };
            let mut detector = ChangeDetector::try_new(config).unwrap();
            for (cost, error) in episodes {
                let before = detector;
                match detector.observe(cost, error) {
                    Err(_) => prop_assert_eq!(detector, before),
                    Ok(verdict) => {
                        prop_assert_eq!(verdict, detector.verdict());
                        if before.changed() {
                            prop_assert_eq!(detector, before);
                        }
                    }
                }
                prop_assert_eq!(detector.validate(), Ok(()));
                for input in [Input::Cost, Input::PredictionError] {
                    let g = detector.statistic(input);
                    prop_assert!(g.is_finite() && g >= 0.0);
                    let reference = detector.reference(input);
                    prop_assert!(reference.spread.is_finite() && reference.spread > 0.0);
                }
            }
        }
    }
}
