//! The runtime guard: a supervisor between the corrected controller and the robot that hands
//! the rest of an episode back to the nominal controller when a candidate θ misbehaves.
//!
//! A safety filter in the sense of Brunke et al., "Safe Learning in Robotics", Annual Review
//! of Control, Robotics, and Autonomous Systems 5 (2022), section 4: a monitor of a safety
//! signal switches to a known-safe backup before harm is done. Here the backup is the user's
//! own nominal controller (or [`Controller::safe_action`](super::Controller::safe_action)
//! when even that is not finite).
//!
//! Every tick of a guarded episode ([`Mode::Learn`] or [`Mode::Deploy`]) the guard checks
//! 1. **limits**: a box per coordinate on a state coordinate or on a safety signal the user
//!    computes and passes with
//!    [`EpisodeRunner::control_with_signal`](super::EpisodeRunner::control_with_signal)
//!    (the pole's angle, the depth, the tracking error). A value outside its box, or not
//!    finite, or a signal index beyond the signal passed, violates its limit;
//! 2. **the envelope**: the running cost ([`Shaper::cost`](crate::cost::Shaper::cost) after
//!    this tick's observation) against the per-tick maximum of the running cost of the bare
//!    episodes ([`Mode::Nominal`]) the guard has seen, plus a margin:
//!    `threshold(t) = e(t) + w(t)·(relative_margin·|e(t)| + absolute_margin)`, where the
//!    weight `w(t)` is 1 unless [`GuardConfig::margin_taper`] tapers the margins linearly
//!    towards the last tick (the margin and the sum saturate at `f32::MAX` instead of
//!    overflowing: see [`Guard::threshold`]; a NaN cost counts as above). Ticks that no bare
//!    episode reached (beyond `T`, or beyond the longest bare episode) are not checked
//!    against it, nor is any tick before the first bare episode.
//!
//! **Hysteresis**: the guard trips after `limit_ticks` consecutive ticks violating some
//! limit, or `envelope_ticks` consecutive ticks above the envelope (each count is reset by a
//! tick without its violation). With a count of K ≥ 2 one noisy tick never trips it; the
//! price is a reaction at most K − 1 ticks late. The tick that trips already runs the
//! nominal controller, and so do all the ticks after it in that episode.
//!
//! **What the learner is told** about a tripped learning episode: see [`tripped_cost`].
//!
//! ```
//! use ctrl_adapt::controller::guard::{Guard, GuardConfig, Limit, Source, TripReason};
//! use ctrl_adapt::controller::{
//!     AdapterConfig, CorrectedPd, EpisodeRunner, LinearPolicy, Mode, Pd, StateFeatures,
//! };
//! use ctrl_adapt::cost::QuadraticCost;
//! use ctrl_adapt::Vector;
//!
//! let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5))?;
//! let policy = LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(1.0))?;
//! let controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
//! let config = AdapterConfig { dt: 0.1, failure_cost: 10.0, max_faulty_ticks: 0, learning_episodes: 1 };
//! // One limit: the position (state coordinate 0) within ±1; trip after 2 ticks beyond it.
//! let guard = Guard::<1, 0>::try_new(GuardConfig {
//!     limits: [Limit { source: Source::State(0), low: -1.0, high: 1.0 }],
//!     ..GuardConfig::DEFAULT
//! })?;
//! let shaper = QuadraticCost::try_new(Vector::<1>::repeat(1.0))?;
//! let mut runner = EpisodeRunner::try_new(controller, shaper, config)?.with_guard(guard)?;
//! runner.begin_episode(Vector::from([0.5, 0.0]), Mode::Learn)?;
//! let beyond = Vector::from([1.5, 0.0]);
//! assert_eq!(runner.control(&beyond, &Vector::repeat(0.0)), Vector::<1>::repeat(3.75)); // one tick: corrected
//! assert_eq!(runner.control(&beyond, &Vector::repeat(0.0)), Vector::<1>::repeat(3.0)); // tripped: nominal
//! let report = runner.end_episode()?;
//! let trip = report.trip.unwrap();
//! assert_eq!((trip.tick, trip.reason), (1, TripReason::Limit(0)));
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```

use super::Mode;
use crate::error::{Error, require};
use crate::vector::{Vector, unrolled};

/// Where a [`Limit`] reads its value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Source {
    /// The state coordinate of this index (checked against the state's size when the guard
    /// is fitted to a runner).
    State(u16),
    /// The entry of this index of the signal passed with the tick
    /// ([`EpisodeRunner::control_with_signal`](super::EpisodeRunner::control_with_signal));
    /// a tick whose signal has no such entry violates the limit.
    Signal(u16),
}

/// A box `low ≤ value ≤ high` on one coordinate.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Limit {
    /// The coordinate checked.
    pub source: Source,
    /// Lowest allowed value (may be `-∞`).
    pub low: f32,
    /// Highest allowed value (may be `+∞`).
    pub high: f32,
}

impl Limit {
    /// No limit: any finite value of state coordinate 0 passes.
    pub const NONE: Self = Self {
        source: Source::State(0),
        low: f32::NEG_INFINITY,
        high: f32::INFINITY,
    };
}

/// Parameters of a [`Guard`] with `L` limits.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GuardConfig<const L: usize> {
    /// The limits, one per coordinate checked.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    pub limits: [Limit; L],
    /// Consecutive ticks beyond some limit that trip the guard (≥ 1).
    pub limit_ticks: u32,
    /// Consecutive ticks above the envelope that trip the guard (≥ 1).
    pub envelope_ticks: u32,
    /// Margin of the envelope relative to its value (≥ 0, finite).
    pub relative_margin: f32,
    /// Margin of the envelope in units of the cost (≥ 0, finite).
    pub absolute_margin: f32,
    /// The fraction of both margins left at the envelope's last tick, in [0, 1]: the margins
    /// shrink linearly from their full value at tick 0 to this fraction of it at tick
    /// `T − 1`. 1 (the default) keeps them constant. Below 1 the guard is lenient early,
    /// where a good candidate may still lag the nominal controller, and strict late, where a
    /// candidate still far above the envelope will end the episode there while the nominal
    /// controller could still recover (see `experiments/findings/guard.md`).
    pub margin_taper: f32,
    /// The span of the tripped cost above the failure cost (> 0, finite; see
    /// [`tripped_cost`]).
    pub tripped_cost_span: f32,
}

impl<const L: usize> GuardConfig<L> {
    /// No limit, a hysteresis of 2 ticks for both checks, margins of 10 % and 0, and a
    /// tripped-cost span of 1.
    pub const DEFAULT: Self = Self {
        limits: [Limit::NONE; L],
        limit_ticks: 2,
        envelope_ticks: 2,
        relative_margin: 0.1,
        absolute_margin: 0.0,
        margin_taper: 1.0,
        tripped_cost_span: 1.0,
    };

    /// `Ok` when every field is in range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        for limit in &self.limits {
            require(!limit.low.is_nan() && !limit.high.is_nan(), "limits")?;
            require(limit.low <= limit.high, "limits")?;
        }
        require(self.limit_ticks >= 1, "limit_ticks")?;
        require(self.envelope_ticks >= 1, "envelope_ticks")?;
        let margin = |m: f32| m.is_finite() && m >= 0.0;
        require(margin(self.relative_margin), "relative_margin")?;
        require(margin(self.absolute_margin), "absolute_margin")?;
        let taper = self.margin_taper;
        require((0.0..=1.0).contains(&taper), "margin_taper")?;
        let span = self.tripped_cost_span;
        require(span.is_finite() && span > 0.0, "tripped_cost_span")?;
        Ok(())
    }
}

/// Why the guard tripped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TripReason {
    /// The limit of this index (in [`GuardConfig::limits`]) was violated for `limit_ticks`
    /// ticks (the first violated limit on the tripping tick).
    Limit(u16),
    /// The running cost was above the envelope for `envelope_ticks` ticks.
    Envelope,
}

/// When and why the guard handed an episode back to the nominal controller.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Trip {
    /// The tick (from 0) that tripped; it and every later tick ran the nominal controller,
    /// every earlier tick the corrected one.
    pub tick: u32,
    /// Why.
    pub reason: TripReason,
    /// The running cost after the tripping tick's observation.
    pub cost: f32,
}

/// What a guard has counted over its life; saved with the adapter's record.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct GuardCounters {
    /// Episodes the guard watched ([`Mode::Learn`] and [`Mode::Deploy`]).
    pub guarded_episodes: u32,
    /// Bare episodes ([`Mode::Nominal`]) the envelope learned from.
    pub bare_episodes: u32,
    /// Episodes tripped by a limit.
    pub limit_trips: u32,
    /// Episodes tripped by the envelope.
    pub envelope_trips: u32,
    /// Ticks (of any episode, bare ones included) with some limit violated.
    pub ticks_beyond_limits: u32,
}

/// The cost told to the optimizer for a learning episode that the guard tripped at tick
/// `tick` (from 0) of an episode of `ticks` ticks:
///
/// ```text
/// told = failure_cost + span · (ticks − tick) / ticks
/// ```
///
/// the failure cost plus a share of `span` that is the share of the episode the nominal
/// controller had to run. It is above the failure cost, so above every untripped episode
/// (whose cost, failed or not, is at most the failure cost when that is chosen as the
/// configuration asks), and it decreases as the trip comes later: a θ that tripped at the
/// last tick ranks better than one that tripped at the first. Where f32 rounding would bring
/// it down to the failure cost (a huge failure cost, a trip at the last tick of a long
/// episode) it is the next f32 above. `tick` beyond `ticks` is read as the last tick.
///
/// ```
/// use ctrl_adapt::controller::guard::tripped_cost;
/// assert_eq!(tripped_cost(100.0, 10.0, 0, 200), 110.0);
/// assert_eq!(tripped_cost(100.0, 10.0, 150, 200), 102.5);
/// assert!(tripped_cost(100.0, 10.0, 199, 200) > 100.0);
/// ```
pub fn tripped_cost(failure_cost: f32, span: f32, tick: u32, ticks: u32) -> f32 {
    let ticks = ticks.max(1);
    let tick = tick.min(ticks - 1);
    let remaining = (ticks - tick) as f32 / ticks as f32;
    let told = failure_cost + span * remaining;
    if told > failure_cost {
        told.min(f32::MAX)
    } else {
        failure_cost.next_up().min(f32::MAX)
    }
}

/// `Ok` when a guard's `tripped_cost_span` fits a runner's `failure_cost`: their sum, the
/// highest [`tripped_cost`], is a finite number above the failure cost (else
/// [`Error::InvalidParameter`]`("tripped_cost_span")`). Checked by
/// [`EpisodeRunner::with_guard`](super::EpisodeRunner::with_guard) and on every decoded
/// guarded runner or adapter, so a record holds no pair the constructor refuses.
///
/// ```
/// use ctrl_adapt::controller::guard::fit_tripped_cost_span;
/// assert!(fit_tripped_cost_span(100.0, 10.0).is_ok());
/// assert!(fit_tripped_cost_span(100.0, 1e-6).is_err()); // absorbed by 100 in f32
/// assert!(fit_tripped_cost_span(3e38, 1e38).is_err()); // overflows
/// ```
pub fn fit_tripped_cost_span(failure_cost: f32, span: f32) -> Result<(), Error> {
    let top = failure_cost + span;
    require(top.is_finite() && top > failure_cost, "tripped_cost_span")
}

/// What an [`EpisodeRunner`](super::EpisodeRunner) asks of its supervisor each tick:
/// implemented by [`Unguarded`] (no supervision, no bytes, no instructions) and by
/// [`Guard`].
pub trait Supervisor<const S: usize> {
    /// `Ok` when the supervisor fits a state in R^S.
    fn fit(&self) -> Result<(), Error> {
        Ok(())
    }
    /// `Ok` when the supervisor fits a runner whose failure cost is `failure_cost` (for a
    /// [`Guard`]: see [`fit_tripped_cost_span`]).
    fn fit_failure_cost(&self, failure_cost: f32) -> Result<(), Error> {
        let _ = failure_cost;
        Ok(())
    }
    /// An episode in `mode` begins.
    fn begin(&mut self, mode: Mode) {
        let _ = mode;
    }
    /// Tick `tick` of an episode in `mode`: whether the nominal controller must run it. The
    /// running cost is asked for only when the envelope needs it.
    fn check(
        &mut self,
        mode: Mode,
        tick: u32,
        state: &Vector<S>,
        signal: &[f32],
        running_cost: impl FnOnce() -> f32,
    ) -> bool {
        let _ = (mode, tick, state, signal, running_cost);
        false
    }
    /// The episode ends: its trip, if any, and its ticks beyond limits.
    fn finish(&mut self) -> (Option<Trip>, u32) {
        (None, 0)
    }
    /// The cost to tell for a learning episode tripped as `trip`, of `ticks` ticks.
    fn told(&self, failure_cost: f32, trip: &Trip, ticks: u32) -> f32 {
        let _ = (trip, ticks);
        failure_cost
    }
    /// Extra checks of a decoded supervisor.
    fn validate_decoded(&self) -> Result<(), Error> {
        Ok(())
    }
}

/// No guard: the runner's default, zero bytes and no instructions per tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Unguarded;

impl<const S: usize> Supervisor<S> for Unguarded {}

/// The runtime guard with `L` limits and an envelope of `T` ticks (see the
/// [module docs](self)). `L = 0` checks no limit, `T = 0` no envelope.
///
/// State: the configuration, the envelope (`2·T` bytes), the counters and the running
/// episode's hysteresis counts, about `2·T + 12·L + 68` bytes (620 bytes for 6 limits and
/// 240 ticks).
///
/// The envelope is stored as bfloat16 (the upper half of an f32: its sign, exponent and 7
/// mantissa bits), rounded up: each tick's value is at most 2⁻⁷ (0.8 %) of itself looser than
/// the running cost learned, never tighter. This halves the largest part of the state.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Guard<const L: usize, const T: usize> {
    config: GuardConfig<L>,
    /// Per tick, the highest running cost of the bare episodes as bfloat16 rounded up;
    /// `-∞` where none reached.
    #[cfg_attr(feature = "serde", serde(with = "crate::record::array"))]
    envelope: [u16; T],
    counters: GuardCounters,
    limit_run: u32,
    envelope_run: u32,
    beyond: u32,
    /// The running episode's trip: (tick, reason code, cost); reason `u16::MAX` = envelope.
    trip: Option<(u32, u16, f32)>,
}

const ENVELOPE: u16 = u16::MAX;
/// `-∞` as bfloat16.
const NEG_INFINITY: u16 = 0xFF80;

/// `x` as bfloat16, rounded towards +∞ (NaN is not passed here).
fn bf16_up(x: f32) -> u16 {
    let bits = x.to_bits();
    let high = (bits >> 16) as u16;
    let exact = bits & 0xFFFF == 0;
    // Positive: a larger magnitude is larger; negative: the truncated magnitude is.
    if exact || x < 0.0 {
        high
    } else {
        high.wrapping_add(1)
    }
}

fn from_bf16(h: u16) -> f32 {
    f32::from_bits(u32::from(h) << 16)
}

impl<const L: usize, const T: usize> Guard<L, T> {
    /// A guard with an empty envelope (it learns it from the bare episodes it sees).
    pub fn try_new(config: GuardConfig<L>) -> Result<Self, Error> {
        config.validate()?;
        Ok(Self {
            config,
            envelope: [NEG_INFINITY; T],
            counters: GuardCounters::default(),
            limit_run: 0,
            envelope_run: 0,
            beyond: 0,
            trip: None,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &GuardConfig<L> {
        &self.config
    }

    /// The counters over the guard's life.
    pub fn counters(&self) -> &GuardCounters {
        &self.counters
    }

    /// The learned envelope at `tick`, before margins: the highest running cost of the bare
    /// episodes at that tick (as stored, rounded up to bfloat16), `-∞` where none reached
    /// it, `None` beyond `T`.
    pub fn envelope(&self, tick: u32) -> Option<f32> {
        self.envelope.get(tick as usize).map(|&h| from_bf16(h))
    }

    /// Forgets the envelope (after a change of plant or of nominal controller: run bare
    /// episodes again).
    pub fn clear_envelope(&mut self) {
        self.envelope = [NEG_INFINITY; T];
        self.counters.bare_episodes = 0;
    }

    /// The running cost allowed at `tick`, margins included (tapered by
    /// [`GuardConfig::margin_taper`]); `None` where unchecked.
    ///
    /// Never NaN, and finite wherever it is checked: the margin `relative_margin·|e| +
    /// absolute_margin` saturates at `f32::MAX` where it would overflow, so that a weight of
    /// 0 (the last tick under a taper of 0) leaves exactly the envelope `e` (not `0·∞`, NaN,
    /// which no cost is above), and the threshold saturates at `f32::MAX` too: a finite
    /// envelope never lets an infinite running cost pass.
    pub fn threshold(&self, tick: u32) -> Option<f32> {
        let e = self.envelope(tick)?;
        let c = &self.config;
        // Linear from 1 at tick 0 to the taper at tick T − 1 (T = 1: the taper); in [0, 1].
        let weight = if T > 1 {
            1.0 - (1.0 - c.margin_taper) * (tick as f32 / (T - 1) as f32)
        } else {
            c.margin_taper
        };
        // Finite, ≥ 0 (validated margins, finite e): at most f32::MAX after the `min`.
        let margin = (c.relative_margin * e.abs() + c.absolute_margin).min(f32::MAX);
        e.is_finite().then(|| (e + weight * margin).min(f32::MAX))
    }

    fn reset_episode(&mut self) {
        self.limit_run = 0;
        self.envelope_run = 0;
        self.beyond = 0;
        self.trip = None;
    }

    /// The index of the first limit `state`/`signal` violate.
    ///
    /// Up to 32 limits, every limit is checked without a branch on its outcome, into a bit
    /// mask, in straight-line code (a few instructions fewer per tick than the loop with an
    /// early exit on the Cortex-M4F).
    fn violated<const S: usize>(&self, state: &Vector<S>, signal: &[f32]) -> Option<u16> {
        let outside = |limit: &Limit| {
            // The source picks a slice (a select, not a branch, on the Cortex-M4F), then one
            // bounds check reads the value.
            let (values, k) = match limit.source {
                Source::State(k) => (state.as_slice(), k),
                Source::Signal(k) => (signal, k),
            };
            let k = usize::from(k);
            // A missing value is NaN, and `!(low <= v && v <= high)` holds for NaN.
            let v = if k < values.len() {
                values[k]
            } else {
                f32::NAN
            };
            !((limit.low <= v) & (v <= limit.high))
        };
        if L <= 32 {
            let mut mask = 0u32;
            unrolled::<L>(|i| mask |= u32::from(outside(&self.config.limits[i])) << i);
            (mask != 0).then(|| mask.trailing_zeros() as u16)
        } else {
            self.config
                .limits
                .iter()
                .position(outside)
                .map(|i| i as u16)
        }
    }
}

impl<const L: usize, const T: usize, const S: usize> Supervisor<S> for Guard<L, T> {
    fn fit(&self) -> Result<(), Error> {
        let fits = |l: &Limit| !matches!(l.source, Source::State(k) if k as usize >= S);
        require(self.config.limits.iter().all(fits), "limits")
    }

    fn begin(&mut self, mode: Mode) {
        let c = &mut self.counters;
        if mode == Mode::Nominal {
            c.bare_episodes = c.bare_episodes.saturating_add(1);
        } else {
            c.guarded_episodes = c.guarded_episodes.saturating_add(1);
        }
        self.reset_episode();
    }

    fn check(
        &mut self,
        mode: Mode,
        tick: u32,
        state: &Vector<S>,
        signal: &[f32],
        running_cost: impl FnOnce() -> f32,
    ) -> bool {
        if self.trip.is_some() {
            // Still count the ticks beyond limits after the hand-over.
            if L > 0 && self.violated(state, signal).is_some() {
                self.beyond = self.beyond.saturating_add(1);
            }
            return true;
        }
        let violated = if L > 0 {
            self.violated(state, signal)
        } else {
            None
        };
        if violated.is_some() {
            self.beyond = self.beyond.saturating_add(1);
            self.limit_run = self.limit_run.saturating_add(1);
        } else {
            self.limit_run = 0;
        }
        if mode == Mode::Nominal {
            // A bare episode: the envelope learns its running cost (non-finite costs leave
            // the tick unchecked: +∞).
            if let Some(e) = self.envelope.get_mut(tick as usize) {
                let cost = running_cost();
                let cost = if cost.is_nan() { f32::INFINITY } else { cost };
                if cost > from_bf16(*e) {
                    *e = bf16_up(cost);
                }
            }
            return false;
        }
        let mut cost = f32::NAN;
        if T > 0 {
            if let Some(threshold) = self.threshold(tick) {
                cost = running_cost();
                // A NaN on either side counts as above (the threshold is never NaN, but a
                // NaN there must trip, not pass).
                let within = cost <= threshold;
                if !within {
                    self.envelope_run = self.envelope_run.saturating_add(1);
                } else {
                    self.envelope_run = 0;
                }
            } else {
                self.envelope_run = 0;
            }
        }
        let reason = match violated {
            Some(i) if self.limit_run >= self.config.limit_ticks => i,
            _ if T > 0 && self.envelope_run >= self.config.envelope_ticks => ENVELOPE,
            _ => return false,
        };
        self.trip = Some((tick, reason, cost));
        true
    }

    fn finish(&mut self) -> (Option<Trip>, u32) {
        let c = &mut self.counters;
        c.ticks_beyond_limits = c.ticks_beyond_limits.saturating_add(self.beyond);
        let trip = self.trip.take().map(|(tick, code, cost)| Trip {
            tick,
            reason: if code == ENVELOPE {
                TripReason::Envelope
            } else {
                TripReason::Limit(code)
            },
            cost,
        });
        match trip.map(|t| t.reason) {
            Some(TripReason::Envelope) => c.envelope_trips = c.envelope_trips.saturating_add(1),
            Some(TripReason::Limit(_)) => c.limit_trips = c.limit_trips.saturating_add(1),
            None => {}
        }
        let beyond = self.beyond;
        self.reset_episode();
        (trip, beyond)
    }

    fn fit_failure_cost(&self, failure_cost: f32) -> Result<(), Error> {
        fit_tripped_cost_span(failure_cost, self.config.tripped_cost_span)
    }

    fn told(&self, failure_cost: f32, trip: &Trip, ticks: u32) -> f32 {
        tripped_cost(
            failure_cost,
            self.config.tripped_cost_span,
            trip.tick,
            ticks,
        )
    }

    fn validate_decoded(&self) -> Result<(), Error> {
        self.config.validate()?;
        require(
            self.envelope.iter().all(|&e| !from_bf16(e).is_nan()),
            "envelope",
        )?;
        require(
            self.trip
                .is_none_or(|(_, code, _)| code == ENVELOPE || (code as usize) < L),
            "trip",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{
        Adapter, AdapterConfig, CorrectedPd, EpisodeRunner, LinearPolicy, Pd, StateFeatures,
    };
    use crate::cost::Shaper;
    use crate::optimizer::{Bounds, CoordinateConfig, CoordinateSearch};
    use crate::testing::rng;
    use proptest::prelude::*;

    /// The running cost is the sum of the observations.
    #[derive(Debug, Clone, Copy, PartialEq)]
    #[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
    struct Sum(f32);

    impl Shaper for Sum {
        type Observation = f32;
        fn reset(&mut self) {
            self.0 = 0.0;
        }
        fn observe(&mut self, cost: &f32, _dt: f32) {
            self.0 += *cost;
        }
        fn cost(&self) -> f32 {
            self.0
        }
        fn skipped(&self) -> u32 {
            0
        }
    }

    #[cfg(feature = "serde")]
    impl crate::record::Persistent for Sum {
        const SHAPE: crate::record::Shape = crate::record::Shape::new(*b"SUM_", &[]);
        fn validate(&self) -> Result<(), Error> {
            Ok(())
        }
    }

    type Ctl = CorrectedPd<1, 2, 2, 2, StateFeatures<2>>;

    const CONFIG: AdapterConfig = AdapterConfig {
        dt: 0.1,
        failure_cost: 100.0,
        max_faulty_ticks: 0,
        learning_episodes: 50,
    };

    fn controller() -> Ctl {
        let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5)).unwrap();
        let policy = LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(1.0)).unwrap();
        CorrectedPd::new(pd, policy)
    }

    fn runner() -> EpisodeRunner<Ctl, Sum, 2, 2, 1> {
        EpisodeRunner::try_new(controller(), Sum(0.0), CONFIG).unwrap()
    }

    fn position_limit(ticks: u32) -> GuardConfig<1> {
        GuardConfig {
            limits: [Limit {
                source: Source::State(0),
                low: -1.0,
                high: 1.0,
            }],
            limit_ticks: ticks,
            ..GuardConfig::DEFAULT
        }
    }

    const THETA: [f32; 2] = [0.5, 0.0];
    /// The corrected action at position x (PD 2x plus 0.5x) and the nominal one.
    fn corrected(x: f32) -> Vector<1> {
        Vector::repeat(2.5 * x)
    }
    fn nominal(x: f32) -> Vector<1> {
        Vector::repeat(2.0 * x)
    }

    #[test]
    fn unguarded_costs_no_byte() {
        assert_eq!(size_of::<Unguarded>(), 0);
        // The runner without a guard is as large as its parts were before the guard.
        assert_eq!(
            size_of::<EpisodeRunner<Ctl, Sum, 2, 2, 1>>(),
            size_of::<EpisodeRunner<Ctl, Sum, 2, 2, 1, Unguarded>>()
        );
        // Six limits and a 240-tick envelope fit in 1 KB.
        assert!(
            size_of::<Guard<6, 240>>() <= 1024,
            "{}",
            size_of::<Guard<6, 240>>()
        );
    }

    #[test]
    fn the_envelope_is_stored_rounded_up_never_tighter() {
        for x in [
            0.0,
            -0.0,
            1.0,
            1.0 + f32::EPSILON,
            -1.0 - f32::EPSILON,
            3.3,
            -3.3,
            1e30,
            -1e-30,
        ] {
            let stored = from_bf16(bf16_up(x));
            assert!(
                stored >= x && stored - x <= x.abs() / 128.0,
                "{x} → {stored}"
            );
        }
        assert_eq!(from_bf16(bf16_up(f32::INFINITY)), f32::INFINITY);
        assert_eq!(from_bf16(NEG_INFINITY), f32::NEG_INFINITY);
    }

    #[test]
    fn one_noisy_tick_does_not_trip_two_do() {
        let guard = Guard::<1, 0>::try_new(position_limit(2)).unwrap();
        let mut r = runner().with_guard(guard).unwrap();
        r.begin_episode(Vector::from(THETA), Mode::Learn).unwrap();
        let (inside, beyond) = (Vector::from([0.5, 0.0]), Vector::from([1.5, 0.0]));
        assert_eq!(r.control(&beyond, &0.0), corrected(1.5));
        assert_eq!(r.control(&inside, &0.0), corrected(0.5));
        assert_eq!(r.control(&beyond, &0.0), corrected(1.5));
        // The second consecutive tick beyond trips: nominal from this tick on, even inside.
        assert_eq!(r.control(&beyond, &0.0), nominal(1.5));
        assert_eq!(r.control(&inside, &0.0), nominal(0.5));
        let report = r.end_episode().unwrap();
        let trip = report.trip.unwrap();
        assert_eq!((trip.tick, trip.reason), (3, TripReason::Limit(0)));
        assert_eq!((report.ticks, report.ticks_beyond_limits), (5, 3));
        assert!(!report.failed);
        let counters = *r.guard().counters();
        assert_eq!(
            (
                counters.guarded_episodes,
                counters.limit_trips,
                counters.ticks_beyond_limits
            ),
            (1, 1, 3)
        );
        // The next episode starts untripped.
        r.begin_episode(Vector::from(THETA), Mode::Learn).unwrap();
        assert_eq!(r.control(&inside, &0.0), corrected(0.5));
        assert_eq!(r.end_episode().unwrap().trip, None);
    }

    #[test]
    fn signal_limits_trip_on_missing_or_non_finite_values() {
        let mut config = position_limit(1);
        config.limits[0].source = Source::Signal(1);
        let guard = Guard::<1, 0>::try_new(config).unwrap();
        let mut r = runner().with_guard(guard).unwrap();
        let state = Vector::from([0.5, 0.0]);
        for signal in [&[0.0][..], &[0.0, f32::NAN], &[0.0, 2.0], &[]] {
            r.begin_episode(Vector::from(THETA), Mode::Learn).unwrap();
            assert_eq!(r.control_with_signal(&state, &0.0, signal), nominal(0.5));
            assert_eq!(r.end_episode().unwrap().trip.unwrap().tick, 0);
        }
        r.begin_episode(Vector::from(THETA), Mode::Learn).unwrap();
        assert_eq!(
            r.control_with_signal(&state, &0.0, &[9.0, 0.5]),
            corrected(0.5)
        );
        assert_eq!(r.end_episode().unwrap().trip, None);
    }

    #[test]
    fn bare_episodes_are_never_handed_over_but_count_their_ticks_beyond() {
        let guard = Guard::<1, 4>::try_new(position_limit(1)).unwrap();
        let mut r = runner().with_guard(guard).unwrap();
        r.begin_episode(Vector::zeros(), Mode::Nominal).unwrap();
        for _ in 0..3 {
            assert_eq!(r.control(&Vector::from([2.0, 0.0]), &1.0), nominal(2.0));
        }
        let report = r.end_episode().unwrap();
        assert_eq!((report.trip, report.ticks_beyond_limits), (None, 3));
        // Three ticks learned (running costs 1, 2, 3), the fourth never reached.
        let e = |t| r.guard().envelope(t);
        assert_eq!([e(0), e(1), e(2)], [Some(1.0), Some(2.0), Some(3.0)]);
        assert_eq!((e(3), e(4)), (Some(f32::NEG_INFINITY), None));
        assert_eq!(r.guard().threshold(1), Some(2.2));
        assert_eq!(r.guard().threshold(3), None);
        assert_eq!(r.guard().counters().bare_episodes, 1);
    }

    #[test]
    fn tapered_margins_shrink_linearly_to_the_taper_at_the_last_tick() {
        // Envelope 4 at every tick of 5 (running costs 4, then 0 added), margins 0.5·4 + 1 = 3
        // at tick 0, a quarter of that at tick 4, half way at tick 2.
        let guard = Guard::<0, 5>::try_new(GuardConfig {
            relative_margin: 0.5,
            absolute_margin: 1.0,
            margin_taper: 0.25,
            ..GuardConfig::DEFAULT
        })
        .unwrap();
        let mut r = runner().with_guard(guard).unwrap();
        r.begin_episode(Vector::zeros(), Mode::Nominal).unwrap();
        r.control(&Vector::zeros(), &4.0);
        for _ in 1..5 {
            r.control(&Vector::zeros(), &0.0);
        }
        r.end_episode().unwrap();
        let t = |k| r.guard().threshold(k).unwrap();
        assert_eq!([t(0), t(2), t(4)], [7.0, 5.875, 4.75]);
        // A running cost of 6 passes early and trips late (after the 2 ticks of hysteresis).
        r.begin_episode(Vector::from(THETA), Mode::Learn).unwrap();
        r.control(&Vector::zeros(), &6.0);
        for _ in 1..5 {
            r.control(&Vector::zeros(), &0.0);
        }
        let trip = r.end_episode().unwrap().trip.unwrap();
        assert_eq!((trip.tick, trip.reason), (3, TripReason::Envelope));
    }

    /// Regression: under a taper of 0 the margins' weight at the last tick is 0, and a
    /// margin that overflows f32 (10·1e38) made the threshold there `e + 0·∞` = NaN, which no
    /// running cost is above: a running cost of `f32::MAX` at that tick was never handed back.
    #[test]
    fn a_zero_weight_on_an_overflowing_margin_leaves_exactly_the_envelope() {
        let guard = Guard::<0, 2>::try_new(GuardConfig {
            relative_margin: 10.0,
            margin_taper: 0.0,
            envelope_ticks: 1,
            ..GuardConfig::DEFAULT
        })
        .unwrap();
        let mut r = runner().with_guard(guard).unwrap();
        // A bare episode at cost 1e38: running costs 1e38, 1e38.
        r.begin_episode(Vector::zeros(), Mode::Nominal).unwrap();
        r.control(&Vector::zeros(), &1e38);
        r.control(&Vector::zeros(), &0.0);
        r.end_episode().unwrap();
        let e = r.guard().envelope(1).unwrap();
        assert!(e.is_finite() && e >= 1e38, "{e}");
        let threshold = r.guard().threshold(1).unwrap();
        assert!(!threshold.is_nan());
        // Weight 0: exactly the envelope. Full weight (tick 0): the overflowing margin
        // saturates, and so does the threshold.
        assert_eq!(threshold, e);
        assert_eq!(r.guard().threshold(0), Some(f32::MAX));
        // A running cost of f32::MAX at tick 1 is above it and trips (hysteresis 1).
        let mut guard = *r.guard();
        Supervisor::<2>::begin(&mut guard, Mode::Learn);
        assert!(guard.check(Mode::Learn, 1, &Vector::<2>::zeros(), &[], || f32::MAX));
        // The same through the runner: tick 0 within (0), tick 1 at f32::MAX handed over.
        r.begin_episode(Vector::from(THETA), Mode::Learn).unwrap();
        let x = Vector::from([0.5, 0.0]);
        assert_eq!(r.control(&x, &0.0), corrected(0.5));
        assert_eq!(r.control(&x, &f32::MAX), nominal(0.5));
        let trip = r.end_episode().unwrap().trip.unwrap();
        assert_eq!(
            (trip.tick, trip.reason, trip.cost),
            (1, TripReason::Envelope, f32::MAX)
        );
        // At tick 0 the threshold is f32::MAX: an infinite running cost trips there too.
        let mut guard = *r.guard();
        Supervisor::<2>::begin(&mut guard, Mode::Learn);
        let zero = Vector::<2>::zeros();
        assert!(!guard.check(Mode::Learn, 0, &zero, &[], || f32::MAX));
        Supervisor::<2>::begin(&mut guard, Mode::Learn);
        assert!(guard.check(Mode::Learn, 0, &zero, &[], || f32::INFINITY));
    }

    fn guarded_adapter() -> Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1, Guard<0, 8>> {
        let search = CoordinateSearch::try_new(
            Bounds::uniform(-1.0, 1.0).unwrap(),
            Vector::zeros(),
            CoordinateConfig {
                initial_step: 0.5,
                ..CoordinateConfig::DEFAULT
            },
        )
        .unwrap();
        let guard = Guard::try_new(GuardConfig {
            relative_margin: 0.5,
            absolute_margin: 0.0,
            envelope_ticks: 2,
            tripped_cost_span: 10.0,
            ..GuardConfig::DEFAULT
        })
        .unwrap();
        Adapter::try_new(search, controller(), Sum(0.0), CONFIG, Vector::zeros())
            .unwrap()
            .with_guard(guard)
            .unwrap()
    }

    /// Runs an episode of 8 ticks observing `cost(tick)`; returns the report.
    fn episode(
        a: &mut Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1, Guard<0, 8>>,
        cost: impl Fn(u32) -> f32,
    ) -> crate::controller::EpisodeReport<2> {
        a.begin_episode(&mut rng(1)).unwrap();
        for t in 0..8 {
            a.control(&Vector::from([0.5, 0.0]), &cost(t));
        }
        a.end_episode().unwrap()
    }

    #[test]
    fn the_envelope_trips_a_costly_episode_and_the_learner_is_told_how_far_it_got() {
        let mut a = guarded_adapter();
        // Before any bare episode the envelope checks nothing.
        assert_eq!(episode(&mut a, |_| 50.0).trip, None);
        a.set_mode(Mode::Nominal).unwrap();
        episode(&mut a, |_| 1.0);
        episode(&mut a, |t| if t == 0 { 2.0 } else { 0.5 });
        // Envelope: per-tick max of the running costs, 2, 3, 4, ... ; thresholds ×1.5.
        assert_eq!(a.guard().envelope(0), Some(2.0));
        assert_eq!(a.guard().envelope(7), Some(8.0));
        a.set_mode(Mode::Learn).unwrap();
        // Within the margin: untripped, told its own cost.
        let ok = episode(&mut a, |_| 1.4);
        assert_eq!(ok.trip, None);
        assert_eq!(ok.told, Some(ok.cost));
        // One tick above the envelope (noise) is forgiven.
        let noisy = episode(&mut a, |t| if t == 3 { 4.0 } else { 0.0 });
        assert_eq!(noisy.trip, None);
        // Costly from tick 5 on: above the envelope at ticks 5 and 6, tripped at tick 6.
        let late = episode(&mut a, |t| if t >= 5 { 10.0 } else { 1.0 });
        let trip = late.trip.unwrap();
        assert_eq!((trip.tick, trip.reason), (6, TripReason::Envelope));
        assert_eq!(trip.cost, 25.0);
        assert_eq!(late.told, Some(tripped_cost(100.0, 10.0, 6, 8)));
        // Costly from the start: tripped at tick 1, told more.
        let early = episode(&mut a, |_| 10.0);
        assert_eq!(early.trip.unwrap().tick, 1);
        assert!(early.told > late.told && late.told > Some(100.0));
        assert_eq!(a.guard().counters().envelope_trips, 2);
        assert_eq!(a.guard().counters().guarded_episodes, 5);
    }

    #[test]
    fn fitting_checks_state_coordinates_and_the_span() {
        let mut config = position_limit(1);
        config.limits[0].source = Source::State(2);
        let guard = Guard::<1, 0>::try_new(config).unwrap();
        assert!(runner().with_guard(guard).is_err());
        let mut config = position_limit(1);
        config.tripped_cost_span = 1e-6; // absorbed by 100.0 in f32
        let guard = Guard::<1, 0>::try_new(config).unwrap();
        assert!(runner().with_guard(guard).is_err());
        let mut r = runner();
        r.begin_episode(Vector::zeros(), Mode::Learn).unwrap();
        let guard = Guard::<1, 0>::try_new(position_limit(1)).unwrap();
        assert!(r.with_guard(guard).is_err());
    }

    #[test]
    fn configurations_out_of_range_are_refused() {
        let base = position_limit(1);
        let bad = [
            GuardConfig {
                limit_ticks: 0,
                ..base
            },
            GuardConfig {
                envelope_ticks: 0,
                ..base
            },
            GuardConfig {
                relative_margin: -0.1,
                ..base
            },
            GuardConfig {
                absolute_margin: f32::NAN,
                ..base
            },
            GuardConfig {
                margin_taper: -0.1,
                ..base
            },
            GuardConfig {
                margin_taper: 1.5,
                ..base
            },
            GuardConfig {
                margin_taper: f32::NAN,
                ..base
            },
            GuardConfig {
                tripped_cost_span: 0.0,
                ..base
            },
            GuardConfig {
                tripped_cost_span: f32::INFINITY,
                ..base
            },
            GuardConfig {
                limits: [Limit {
                    source: Source::State(0),
                    low: 1.0,
                    high: -1.0,
                }],
                ..base
            },
            GuardConfig {
                limits: [Limit {
                    source: Source::State(0),
                    low: f32::NAN,
                    high: 1.0,
                }],
                ..base
            },
        ];
        for config in bad {
            assert!(Guard::<1, 4>::try_new(config).is_err(), "{config:?}");
        }
    }

    proptest! {
        /// A tripped episode ranks above the failure cost (so above every untripped one), and
        /// a later trip never ranks worse than an earlier one.
        #[test]
        fn tripped_costs_rank_above_failure_and_by_the_tick_reached(
            failure in -1e6f32..1e6,
            span in 1e-3f32..1e3,
            ticks in 1u32..100_000,
            a in 0u32..100_000,
            b in 0u32..100_000,
        ) {
            let (early, late) = (a.min(b), a.max(b));
            let told_early = tripped_cost(failure, span, early, ticks);
            let told_late = tripped_cost(failure, span, late, ticks);
            prop_assert!(told_late > failure && told_late.is_finite());
            prop_assert!(told_early >= told_late);
            // At most failure + span, or the next f32 above the failure cost where that sum
            // rounds down to it (a span below the failure cost's f32 spacing).
            prop_assert!(told_early <= (failure + span).max(failure.next_up()));
        }

        /// The threshold is never NaN, and finite, at least the envelope and at most
        /// `f32::MAX` wherever it is checked, for any valid margins and taper (huge ones
        /// and 0 included) and any envelope a bare episode can leave.
        #[test]
        fn thresholds_are_never_nan(
            relative in prop_oneof![Just(0.0f32), Just(f32::MAX), 0.0f32..1e3, 0.0f32..f32::MAX],
            absolute in prop_oneof![Just(0.0f32), Just(f32::MAX), 0.0f32..1e3, 0.0f32..f32::MAX],
            taper in prop_oneof![Just(0.0f32), Just(1.0f32), 0.0f32..=1.0],
            envelope in proptest::array::uniform5(any::<f32>()),
        ) {
            let mut guard = Guard::<0, 5>::try_new(GuardConfig {
                relative_margin: relative,
                absolute_margin: absolute,
                margin_taper: taper,
                ..GuardConfig::DEFAULT
            }).unwrap();
            for (stored, x) in guard.envelope.iter_mut().zip(envelope) {
                // As a bare episode learns it: NaN as +∞.
                *stored = bf16_up(if x.is_nan() { f32::INFINITY } else { x });
            }
            for t in 0..5 {
                let e = guard.envelope(t).unwrap();
                match guard.threshold(t) {
                    Some(threshold) => prop_assert!(
                        threshold.is_finite() && threshold >= e,
                        "tick {}: e {}, threshold {}", t, e, threshold
                    ),
                    None => prop_assert!(!e.is_finite()),
                }
            }
        }

        /// The guard never panics and never hands over a bare episode, whatever the state,
        /// the signal and the running cost.
        #[test]
        fn any_tick_is_handled(
            values in proptest::collection::vec(any::<f32>(), 1..40),
            nominal_mode in any::<bool>(),
        ) {
            let mut guard = Guard::<2, 8>::try_new(GuardConfig {
                limits: [
                    Limit { source: Source::State(1), low: -1.0, high: 1.0 },
                    Limit { source: Source::Signal(0), low: 0.0, high: f32::INFINITY },
                ],
                limit_ticks: 1,
                ..GuardConfig::DEFAULT
            }).unwrap();
            let mode = if nominal_mode { Mode::Nominal } else { Mode::Learn };
            Supervisor::<2>::begin(&mut guard, mode);
            for (t, v) in values.iter().enumerate() {
                let state = Vector::from([*v, -*v]);
                let over = guard.check(mode, t as u32, &state, &[*v], || *v);
                prop_assert!(!(nominal_mode && over));
            }
            let (trip, beyond) = Supervisor::<2>::finish(&mut guard);
            prop_assert!(beyond as usize <= values.len());
            prop_assert!(trip.is_none_or(|t| (t.tick as usize) < values.len()));
            prop_assert!(Supervisor::<2>::validate_decoded(&guard).is_ok());
        }
    }

    #[cfg(feature = "serde")]
    #[test]
    fn a_guarded_adapter_round_trips_with_its_counters_and_envelope() {
        use crate::record::{self, Persistent, RecordError};
        let mut a = guarded_adapter();
        a.set_mode(Mode::Nominal).unwrap();
        episode(&mut a, |_| 1.0);
        a.set_mode(Mode::Learn).unwrap();
        episode(&mut a, |_| 10.0);
        let mut buf = [0u8; 1024];
        let bytes = record::save(&a, &mut buf).unwrap();
        let back: Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1, Guard<0, 8>> =
            record::load(bytes).unwrap();
        assert_eq!(back, a);
        assert_eq!(back.guard().counters().envelope_trips, 1);
        // Another envelope length, or no guard, is another shape.
        let other =
            record::load::<Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1, Guard<0, 9>>>(bytes);
        assert_eq!(other, Err(RecordError::Shape));
        let bare = record::load::<Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1>>(bytes);
        assert_eq!(bare, Err(RecordError::Shape));
        // Without a guard the shape is the one of the versions before the guard.
        type Bare = Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1>;
        assert_eq!(
            Bare::SHAPE.as_slice().first(),
            Some(&u32::from_le_bytes(*b"ADPT"))
        );
        assert!(
            !Bare::SHAPE
                .as_slice()
                .contains(&u32::from_le_bytes(*b"GRD_"))
        );
        // A decoded guard with a NaN envelope is refused.
        let mut broken = Guard::<0, 8>::try_new(GuardConfig::DEFAULT).unwrap();
        broken.envelope[2] = 0x7FC0; // NaN
        let bytes = record::save_unchecked(&broken, &mut buf).unwrap();
        assert!(matches!(
            record::load::<Guard<0, 8>>(bytes),
            Err(RecordError::Invalid(_))
        ));
    }

    /// Regression: a guarded adapter's record whose failure cost (3e38) and tripped-cost
    /// span (1e38) overflow f32 together, the checksum recomputed, loaded, though
    /// [`Adapter::with_guard`] refuses that pair. The decoded adapter's checks now make the
    /// constructor's (one function), and refuse it with the same error.
    #[cfg(feature = "serde")]
    #[test]
    fn a_record_with_a_failure_cost_and_span_the_constructor_refuses_is_refused() {
        use crate::record::{self, RecordError};
        type Guarded = Adapter<CoordinateSearch<2>, Ctl, Sum, 2, 2, 1, Guard<0, 8>>;
        let search = || {
            CoordinateSearch::try_new(
                Bounds::uniform(-1.0, 1.0).unwrap(),
                Vector::zeros(),
                CoordinateConfig::DEFAULT,
            )
            .unwrap()
        };
        let guard = Guard::<0, 8>::try_new(GuardConfig {
            tripped_cost_span: 1e38,
            ..GuardConfig::DEFAULT
        })
        .unwrap();
        // The constructor: 3e38 + 1e38 overflows.
        let config = |failure_cost| AdapterConfig {
            failure_cost,
            ..CONFIG
        };
        let refused =
            Adapter::try_new(search(), controller(), Sum(0.0), config(3e38), THETA.into())
                .unwrap()
                .with_guard(guard)
                .unwrap_err();
        let expected = Error::InvalidParameter("tripped_cost_span");
        assert_eq!(
            refused,
            crate::controller::AdapterError::Optimizer(expected)
        );
        // The record of an accepted pair (failure cost 7), forged to hold 3e38.
        let accepted: Guarded =
            Adapter::try_new(search(), controller(), Sum(0.0), config(7.0), THETA.into())
                .unwrap()
                .with_guard(guard)
                .unwrap();
        let mut buf = [0u8; 1024];
        let record = record::save(&accepted, &mut buf).unwrap().to_vec();
        assert_eq!(record::load::<Guarded>(&record), Ok(accepted));
        let end = record.len() - 4;
        let seven = 7.0f32.to_le_bytes();
        let at: std::vec::Vec<usize> = (0..end - 3)
            .filter(|&i| record[i..i + 4] == seven)
            .collect();
        assert_eq!(at.len(), 1, "7.0 occurs once, as the failure cost");
        let mut forged = record.clone();
        forged[at[0]..at[0] + 4].copy_from_slice(&3e38f32.to_le_bytes());
        let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI).checksum(&forged[..end]);
        forged[end..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            record::load::<Guarded>(&forged),
            Err(RecordError::Invalid(expected))
        );
        // The runner alone too.
        let runner = runner().with_guard(guard).unwrap();
        let record = record::save(&runner, &mut buf).unwrap().to_vec();
        let end = record.len() - 4;
        let hundred = 100.0f32.to_le_bytes();
        let at = (0..end - 3).find(|&i| record[i..i + 4] == hundred).unwrap();
        let mut forged = record.clone();
        forged[at..at + 4].copy_from_slice(&3e38f32.to_le_bytes());
        let crc = crc::Crc::<u32>::new(&crc::CRC_32_ISCSI).checksum(&forged[..end]);
        forged[end..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            record::load::<EpisodeRunner<Ctl, Sum, 2, 2, 1, Guard<0, 8>>>(&forged),
            Err(RecordError::Invalid(expected))
        );
    }
}
