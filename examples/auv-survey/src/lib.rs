//! The AUV survey controller of Leonetti et al. 2012 (section 5) as the PIL firmware runs it
//! and as the host's pure-host reference rebuilds it: one `no_std` place for the
//! configuration, so the two sides cannot drift apart.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
//!
//! * The vehicle's position PD producing velocity commands, k_p = 0.3 1/s, k_d = 0.2, each
//!   component saturated to ±0.5 m/s, corrected by the 18-parameter linear policy
//!   c = clamp(W·φ, ±0.5 m/s) with φ = state = [target − p (3) | v (3)] and W 3×6 row-major,
//!   θ[6r + c] ([`AuvController`]).
//! * W ∈ [−1, 1]^18 ([`bounds`]), the survey reward with D = 1 m ([`RADIUS`]), 10 Hz
//!   ([`DT`]), 240-tick episodes ([`TICKS`]); these are the documented nominal values of
//!   `docs/plants.md`.
//! * The learners: [`coordinate_search`] (initial step 0.25, tolerance 1e-3: the paper's local
//!   phase), and the build options [`sracos`], [`cem`] and [`line_bo`].
//! * [`AuvLearner`]: the [`Adapter`] behind the PIL [`Session`](pil_link::Session),
//!   implementing [`pil_link::Learner`].
//!
//! # The learner in the PIL protocol
//! * **Start** → [`Adapter::begin_episode`]. The Start frame may carry one value, the
//!   [`Mode`] the host asks for (learn, deploy the best θ, or run the bare PD; wire code
//!   [`pil_link::mode_code`]); none
//!   keeps the adapter's mode. The Started frame carries the θ the episode runs. A Start
//!   while an episode is still running (the host gave it up) first ends that one with
//!   [`Adapter::abort_episode`], so a learning episode is told the failure cost.
//! * **State** → [`Adapter::control`] with the state as the policy's state and its first
//!   three values, the position error, as the survey reward's observation. A state of the
//!   wrong length is treated like a missing one.
//! * **Fallback** (corrupted or missing state frame) → the nominal PD on the last valid state
//!   of the episode (zero, the safe action, when there is none or the nominal action is not
//!   finite). The adapter does not see that tick: the reward observes only the states the
//!   firmware received, and the fallback is not a faulty tick of the controller (the link
//!   failed, not the sensors); the session counts it.
//! * **End** → [`Adapter::end_episode`]; the Report frame carries a [`Report`].

use ctrl_adapt::controller::{
    Adapter, AdapterConfig, Controller as _, CorrectedPd, EpisodeReport, IdentityFeatures,
    LinearPolicy, Mode, Pd,
};
use ctrl_adapt::cost::SurveyCost;
use ctrl_adapt::optimizer::{
    CemConfig, ControlledRandomSearch, CoordinateConfig, CoordinateSearch, CrsConfig, DiagonalCem,
    LineBo, LineBoConfig, Optimizer, Sracos, SracosConfig, Weighting,
};
use ctrl_adapt::{Bounds, Error, Vector};
use rand_core::{RngCore, SeedableRng};
use rand_xoshiro::SplitMix64;

use pil_link::{Values, mode_code, mode_from_code};

/// Parameters of the policy: W is 3×6.
pub const P: usize = 18;
/// State: [target − p (3) | v (3)].
pub const S: usize = 6;
/// Action: the velocity command (3).
pub const A: usize = 3;
/// Nominal PD gain on the position error (1/s), all axes.
pub const KP: f32 = 0.3;
/// Nominal PD gain on the velocity, all axes.
pub const KD: f32 = 0.2;
/// Saturation of each velocity-command component (m/s).
pub const V_MAX: f32 = 0.5;
/// Clamp of each component of the learned correction (m/s).
pub const C_MAX: f32 = 0.5;
/// Box of every entry of W: [−W_BOUND, W_BOUND]^18.
pub const W_BOUND: f32 = 1.0;
/// The survey radius D of the paper's reward (m).
pub const RADIUS: f32 = 1.0;
/// Control period (s): 10 Hz.
pub const DT: f32 = 0.1;
/// Control ticks per episode: 24 s.
pub const TICKS: u16 = 240;
/// Initial step of the coordinate search on every weight (an eighth of the box width).
pub const LOCAL_STEP: f32 = 0.25;
/// Tolerance of the coordinate search.
pub const LOCAL_TOLERANCE: f32 = 1e-3;
/// The cost told for a failed episode: more than the start's 7.2 m distance to the target,
/// so worse than any real episode.
pub const FAILURE_COST: f32 = 10.0;
/// Seed of the learner's RNG in the PIL firmware and in the host's reference run.
pub const SEED: u64 = 1;
/// Samples per update of the [`cem`] build option.
pub const CEM_SAMPLES: usize = 10;
/// Samples of each batch the [`cem`] build option keeps and weights.
pub const CEM_ELITE: usize = 5;
/// Points of the controlled random search of the paper's global phase.
pub const CRS_POINTS: usize = 100;

/// The vehicle's controller: PD on position producing velocity commands, corrected by W·φ.
pub type AuvController = CorrectedPd<A, S, S, P, IdentityFeatures>;

/// The adapter over optimizer `O`.
pub type AuvAdapter<O> = Adapter<O, AuvController, SurveyCost, P, S, A>;

/// The [`cem`] build option's optimizer.
pub type AuvCem = DiagonalCem<P, CEM_SAMPLES, CEM_ELITE>;

/// Episodes the [`line_bo`] build option's Gaussian process remembers: 64, the recommended
/// capacity at 18 parameters (its state is about 23 KB).
pub const LINE_BO_MEMORY: usize = 64;

/// The [`line_bo`] build option's optimizer.
pub type AuvLineBo = LineBo<P, LINE_BO_MEMORY>;

/// The paper's global-phase optimizer (for the footprint; not a PIL build option: its
/// 100 points of 18 floats are 7.6 KB).
pub type AuvCrs = ControlledRandomSearch<P, CRS_POINTS>;

/// k_p = 0.3, k_d = 0.2, |v_cmd| ≤ 0.5 m/s per component, correction within ±0.5 m/s.
pub fn controller() -> Result<AuvController, Error> {
    let pd = Pd::<A>::try_new(Vector::repeat(KP), Vector::repeat(KD))?
        .with_limit(Vector::repeat(V_MAX))?;
    let policy = LinearPolicy::try_new(IdentityFeatures, Vector::repeat(C_MAX))?;
    Ok(CorrectedPd::new(pd, policy))
}

/// The box [−1, 1]^18 of W.
pub fn bounds() -> Result<Bounds<P>, Error> {
    Bounds::uniform(-W_BOUND, W_BOUND)
}

/// The adapter's configuration for `learning_episodes` learning episodes before it rolls
/// back to the best θ. A single faulty tick (non-finite state or action) fails an episode.
pub const fn adapter_config(learning_episodes: u32) -> AdapterConfig {
    AdapterConfig {
        dt: DT,
        failure_cost: FAILURE_COST,
        max_faulty_ticks: 0,
        learning_episodes,
    }
}

/// An adapter over `optimizer` for the AUV, deploying W = 0 (the bare PD) before anything
/// is told.
pub fn adapter<O: Optimizer<P>>(
    optimizer: O,
    learning_episodes: u32,
) -> Result<AuvAdapter<O>, Error> {
    Adapter::try_new(
        optimizer,
        controller()?,
        SurveyCost::try_new(RADIUS)?,
        adapter_config(learning_episodes),
        Vector::zeros(),
    )
}

/// The paper's local phase: coordinate search from W = 0, initial step 0.25, tolerance 1e-3,
/// at most `max_evaluations` episodes.
pub fn coordinate_search(max_evaluations: u32) -> Result<CoordinateSearch<P>, Error> {
    CoordinateSearch::try_new(
        bounds()?,
        Vector::zeros(),
        CoordinateConfig {
            initial_step: LOCAL_STEP,
            tolerance: LOCAL_TOLERANCE,
            max_evaluations,
            ..CoordinateConfig::DEFAULT
        },
    )
}

/// SRACOS over the AUV box with ZOOpt's defaults (2 positive, 10 negative samples, one
/// uncertain coordinate per candidate), at most `max_evaluations` episodes. Its first
/// 12 candidates are uniform in the box.
pub fn sracos(max_evaluations: u32) -> Result<Sracos<P>, Error> {
    Sracos::try_new(
        bounds()?,
        SracosConfig {
            max_evaluations,
            ..SracosConfig::DEFAULT
        },
    )
}

/// Diagonal CEM with CMA-ES weights over the AUV box, as the host experiments run it:
/// 10 samples per update (the first the mean), the best 5 weighted, from W = 0 with
/// σ₀ = 0.25 (the coordinate search's step), σ at most 0.5, variance floor 1e-6.
pub fn cem(max_evaluations: u32) -> Result<AuvCem, Error> {
    DiagonalCem::try_with_variances(
        bounds()?,
        Vector::zeros(),
        Vector::repeat(LOCAL_STEP * LOCAL_STEP),
        CemConfig {
            weighting: Weighting::CmaEs,
            initial_variance: LOCAL_STEP * LOCAL_STEP,
            exploration_floor: 1e-6,
            max_variance: 0.5 * 0.5,
            max_evaluations,
            ..CemConfig::DEFAULT
        },
    )
}

/// The bare controller's cost on the AUV survey, about: 3.1 to 3.4 over the plant's seeds
/// (the LineBO experiments' `auv` trial). [`line_bo`] sets its GP's scale from it.
pub const BARE_COST: f32 = 3.2;

/// LineBO without a threshold over the AUV box from W = 0, with the host experiments'
/// earlier settings (LineBO's rule: σ_f = the bare controller's cost, σ_n = 5 % of it;
/// ℓ = 0.15 of the box, β = 2, coordinate lines of one episode each; the experiments now
/// recommend ℓ = 0.1, chosen on seeds 101–110: experiments/findings/line-bo.md), remembering
/// [`LINE_BO_MEMORY`] episodes, at most `max_evaluations` episodes.
pub fn line_bo(max_evaluations: u32) -> Result<AuvLineBo, Error> {
    let noise = 0.05 * BARE_COST;
    LineBo::try_new(
        bounds()?,
        Vector::zeros(),
        LineBoConfig {
            signal_variance: BARE_COST * BARE_COST,
            noise_variance: noise * noise,
            length_scale: 0.15,
            evaluations_per_line: 1,
            max_evaluations,
            ..LineBoConfig::DEFAULT
        },
    )
}

/// The paper's global phase: CRS with 100 points over the AUV box.
pub fn crs(max_evaluations: u32) -> Result<AuvCrs, Error> {
    ControlledRandomSearch::try_new(
        bounds()?,
        CrsConfig {
            max_evaluations,
            ..CrsConfig::DEFAULT
        },
    )
}

/// The Report frame's values: what the adapter made of the episode.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Report {
    /// The survey reward's cost (d if d ≥ D, else D − t_D); NaN if no episode ran.
    pub cost: f32,
    /// The cost told to the optimizer (NaN if nothing was told: deploy or nominal).
    pub told: f32,
    /// The best cost told so far (NaN before any).
    pub best: f32,
    /// The mode the episode ran in (NaN if no episode ran).
    pub mode: Option<Mode>,
    /// Ticks whose state or action was not finite (the adapter's faulty ticks).
    pub faulty_ticks: u32,
}

impl Report {
    /// Values in a frame.
    pub const LEN: usize = 5;

    /// Writes the report as [cost, told, best, mode, faulty ticks].
    pub fn write(&self, values: &mut Values) {
        values.clear();
        let mode = self.mode.map_or(f32::NAN, mode_code);
        for v in [
            self.cost,
            self.told,
            self.best,
            mode,
            self.faulty_ticks as f32,
        ] {
            let _ = values.push(v);
        }
    }

    /// Reads a report written by [`Report::write`]; `None` if the length is wrong.
    pub fn read(values: &[f32]) -> Option<Self> {
        match *values {
            [cost, told, best, mode, faulty] => Some(Self {
                cost,
                told,
                best,
                mode: mode_from_code(mode),
                faulty_ticks: faulty as u32,
            }),
            _ => None,
        }
    }
}

/// A finite-or-not state of the right length.
fn state_vector(values: &[f32]) -> Option<Vector<S>> {
    (values.len() == S).then(|| Vector::from_fn(|i, _| values.get(i).copied().unwrap_or(0.0)))
}

fn write_vector<const K: usize>(v: &Vector<K>, out: &mut Values) {
    out.clear();
    for &x in v.iter() {
        let _ = out.push(x);
    }
}

/// The learner's RNG: xoshiro128++, the very stream of `rand_xoshiro::Xoshiro128PlusPlus`
/// (seeded the same way), with a state that the `serde` feature saves (`rand_xoshiro`'s own
/// `serde` feature needs `std`).
#[derive(Debug, Clone, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AuvRng {
    s: [u32; 4],
}

impl AuvRng {
    /// The generator `Xoshiro128PlusPlus::seed_from_u64(seed)` is: its 16-byte seed drawn
    /// from SplitMix64.
    pub fn seed_from_u64(seed: u64) -> Self {
        let mut bytes = [0u8; 16];
        SplitMix64::seed_from_u64(seed).fill_bytes(&mut bytes);
        let word = |i: usize| {
            u32::from_le_bytes([
                bytes[4 * i],
                bytes[4 * i + 1],
                bytes[4 * i + 2],
                bytes[4 * i + 3],
            ])
        };
        let s = [word(0), word(1), word(2), word(3)];
        if s == [0; 4] {
            // As xoshiro does for the all-zero seed (never the case for SplitMix64's output
            // of a u64 seed in practice).
            return Self::seed_from_u64(0);
        }
        Self { s }
    }
}

impl RngCore for AuvRng {
    fn next_u32(&mut self) -> u32 {
        let s = &mut self.s;
        let result = s[0].wrapping_add(s[3]).rotate_left(7).wrapping_add(s[0]);
        let t = s[1] << 9;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(11);
        result
    }

    fn next_u64(&mut self) -> u64 {
        rand_core::impls::next_u64_via_u32(self)
    }

    fn fill_bytes(&mut self, dest: &mut [u8]) {
        rand_core::impls::fill_bytes_via_next(self, dest);
    }
}

/// The AUV adapter with its RNG, as the PIL firmware runs it (see the [module docs](self)).
/// With the `serde` feature its adapter and RNG are saved (the last episode's report is not).
#[derive(Debug, Clone)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(bound = "O: serde::Serialize + serde::de::DeserializeOwned")
)]
pub struct AuvLearner<O> {
    adapter: AuvAdapter<O>,
    rng: AuvRng,
    #[cfg_attr(feature = "serde", serde(skip))]
    last: Option<EpisodeReport<P>>,
}

impl<O: Optimizer<P>> AuvLearner<O> {
    /// The learner over `optimizer`, its RNG seeded with `seed`. The host decides how many
    /// episodes learn (see [`Mode`]); the adapter's own budget is `learning_episodes`.
    ///
    /// Never inlined, so that the adapter it assembles around `optimizer` is built in this
    /// function's frame and returned into the caller's place, instead of adding one more
    /// temporary copy to the caller's frame (firmware builds its learner once, and the stack
    /// it peaks at then is the figure that matters: docs/firmware.md).
    #[inline(never)]
    pub fn try_new(optimizer: O, learning_episodes: u32, seed: u64) -> Result<Self, Error> {
        Ok(Self {
            adapter: adapter(optimizer, learning_episodes)?,
            rng: AuvRng::seed_from_u64(seed),
            last: None,
        })
    }

    /// The learner over `adapter`, its RNG seeded with `seed`.
    pub fn from_adapter(adapter: AuvAdapter<O>, seed: u64) -> Self {
        Self {
            adapter,
            rng: AuvRng::seed_from_u64(seed),
            last: None,
        }
    }

    /// The adapter.
    pub fn adapter(&self) -> &AuvAdapter<O> {
        &self.adapter
    }

    /// The adapter's report of the last episode ended.
    pub fn last_episode(&self) -> Option<&EpisodeReport<P>> {
        self.last.as_ref()
    }

    /// The nominal PD on `state`, or the safe action (zero) if that is not finite.
    fn nominal(&mut self, state: &Vector<S>) -> Vector<A> {
        let controller = self.adapter.controller_mut();
        let u = controller.nominal(state, 0.0);
        if u.iter().all(|v| v.is_finite()) {
            u
        } else {
            controller.safe_action()
        }
    }
}

impl<O: Optimizer<P>> pil_link::Learner for AuvLearner<O> {
    fn start_episode(&mut self, _episode: u16, request: &[f32], theta: &mut Values) {
        if self.adapter.in_episode() {
            // The host gave the running episode up: it failed.
            self.last = self.adapter.abort_episode().ok();
        }
        if let Some(mode) = request.first().copied().and_then(mode_from_code) {
            // Cannot fail: no episode is running.
            let _ = self.adapter.set_mode(mode);
        }
        match self.adapter.begin_episode(&mut self.rng) {
            Ok(t) => write_vector(&t, theta),
            // No episode (an optimizer error): `control` runs the bare PD outside an
            // episode, which is what θ = 0 means.
            Err(_) => write_vector(&Vector::<P>::zeros(), theta),
        }
    }

    fn act(&mut self, state: &[f32], action: &mut Values) {
        let Some(x) = state_vector(state) else {
            return self.fallback(None, action);
        };
        let error = Vector::<3>::new(x[0], x[1], x[2]);
        let u = self.adapter.control(&x, &error);
        write_vector(&u, action);
    }

    fn fallback(&mut self, last_state: Option<&[f32]>, action: &mut Values) {
        let u = match last_state.and_then(state_vector) {
            Some(x) => self.nominal(&x),
            None => self.adapter.controller().safe_action(),
        };
        write_vector(&u, action);
    }

    fn end_episode(&mut self, report: &mut Values) {
        let ended = self.adapter.end_episode().ok();
        self.last = ended;
        let best = self.adapter.optimizer().best().map_or(f32::NAN, |b| b.cost);
        let r = match ended {
            Some(e) => Report {
                cost: e.cost,
                told: e.told.unwrap_or(f32::NAN),
                best,
                mode: Some(e.mode),
                faulty_ticks: e.faulty_ticks,
            },
            None => Report {
                cost: f32::NAN,
                told: f32::NAN,
                best,
                mode: None,
                faulty_ticks: 0,
            },
        };
        r.write(report);
    }
}

#[cfg(feature = "serde")]
pub mod checkpoint;
#[cfg(feature = "serde")]
pub use checkpoint::AuvCheckpoint;

#[cfg(test)]
mod tests {
    use super::*;

    /// Checks: the learner's RNG draws exactly `rand_xoshiro::Xoshiro128PlusPlus`'s stream.
    #[test]
    fn auv_rng_is_xoshiro128plusplus() {
        for seed in [0, 1, 2, 0xDEAD_BEEF, u64::MAX] {
            let mut ours = AuvRng::seed_from_u64(seed);
            let mut theirs = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(seed);
            for _ in 0..1000 {
                assert_eq!(ours.next_u32(), theirs.next_u32());
            }
            assert_eq!(ours.next_u64(), theirs.next_u64());
            let (mut a, mut b) = ([0u8; 13], [0u8; 13]);
            ours.fill_bytes(&mut a);
            theirs.fill_bytes(&mut b);
            assert_eq!(a, b);
        }
    }
    use pil_link::Learner;

    fn learner() -> AuvLearner<CoordinateSearch<P>> {
        AuvLearner::try_new(coordinate_search(u32::MAX).unwrap(), u32::MAX, SEED).unwrap()
    }

    /// Checks: every builder accepts the documented constants.
    #[test]
    fn builders_accept_the_documented_configuration() {
        assert!(coordinate_search(150).is_ok());
        assert!(sracos(150).is_ok());
        assert!(cem(150).is_ok());
        assert!(crs(150).is_ok());
        assert!(adapter(coordinate_search(150).unwrap(), 150).is_ok());
    }

    /// Checks: the first learning episode runs W = 0 and its actions are the bare PD's
    /// (saturated at 0.5 m/s far from the target); the report carries the survey cost
    /// (the distance, never within D here) and what was told.
    #[test]
    fn first_episode_is_the_bare_pd_and_is_told() {
        let mut l = learner();
        let mut theta = Values::new();
        l.start_episode(0, &[], &mut theta);
        assert_eq!(theta.as_slice(), &[0.0; P]);
        let mut action = Values::new();
        l.act(&[-5.0, -2.0, 4.8, 0.0, 0.0, 0.0], &mut action);
        assert_eq!(action.as_slice(), &[-0.5, -0.5, 0.5]);
        l.act(&[1.0, 0.0, 0.0, 0.5, 0.0, 0.0], &mut action);
        assert!((action[0] - (0.3 - 0.1)).abs() < 1e-6);
        let mut values = Values::new();
        l.end_episode(&mut values);
        let r = Report::read(&values).unwrap();
        assert_eq!((r.cost, r.told, r.best), (1.0, 1.0, 1.0));
        assert_eq!((r.mode, r.faulty_ticks), (Some(Mode::Learn), 0));
    }

    /// Checks the fallbacks: the nominal PD on the last valid state; zero without one, for a
    /// NaN last state or a state of the wrong length; a NaN state through `act` gets the
    /// safe action, fails the episode and the failure cost (finite) is told.
    #[test]
    fn fallbacks_are_nominal_or_safe_and_never_tell_a_nan() {
        let mut l = learner();
        let mut theta = Values::new();
        l.start_episode(0, &[mode_code(Mode::Learn)], &mut theta);
        let mut a = Values::new();
        l.fallback(Some(&[1.0, 0.0, -1.0, 0.0, 0.0, 0.0]), &mut a);
        assert!((a[0] - 0.3).abs() < 1e-6 && a[1] == 0.0 && (a[2] + 0.3).abs() < 1e-6);
        for last in [None, Some(&[f32::NAN; 6][..]), Some(&[1.0, 2.0][..])] {
            l.fallback(last, &mut a);
            assert_eq!(a.as_slice(), &[0.0; 3]);
        }
        l.act(&[1.0, 2.0], &mut a);
        assert_eq!(a.as_slice(), &[0.0; 3], "short state: no last valid state");
        l.act(&[f32::NAN, 0.0, 0.0, 0.0, 0.0, 0.0], &mut a);
        assert_eq!(a.as_slice(), &[0.0; 3]);
        let mut values = Values::new();
        l.end_episode(&mut values);
        let r = Report::read(&values).unwrap();
        assert!(r.cost.is_infinite(), "nothing valid observed");
        assert_eq!((r.told, r.faulty_ticks), (FAILURE_COST, 1));
    }

    /// Checks the requests: Nominal runs W = 0 and tells nothing; a Start during an episode
    /// aborts it (failure cost told); Deploy runs the best θ; no request keeps the mode.
    #[test]
    fn modes_follow_the_host_requests() {
        let mut l = learner();
        let mut theta = Values::new();
        let mut report = Values::new();
        let mut a = Values::new();
        l.start_episode(0, &[mode_code(Mode::Nominal)], &mut theta);
        l.act(&[3.0, 0.0, 0.0, 0.0, 0.0, 0.0], &mut a);
        l.end_episode(&mut report);
        let r = Report::read(&report).unwrap();
        assert_eq!((r.mode, r.cost), (Some(Mode::Nominal), 3.0));
        assert!(r.told.is_nan() && r.best.is_nan());
        l.start_episode(1, &[mode_code(Mode::Learn)], &mut theta);
        l.act(&[2.0, 0.0, 0.0, 0.0, 0.0, 0.0], &mut a);
        l.start_episode(2, &[], &mut theta);
        assert_eq!(l.last_episode().unwrap().told, Some(FAILURE_COST));
        assert_eq!(l.adapter().mode(), Mode::Learn);
        l.act(&[0.5, 0.0, 0.0, 0.0, 0.0, 0.0], &mut a);
        l.end_episode(&mut report);
        l.start_episode(3, &[mode_code(Mode::Deploy)], &mut theta);
        let best = l.adapter().optimizer().best().unwrap();
        assert_eq!(theta.as_slice(), best.theta.as_slice());
        l.end_episode(&mut report);
        assert_eq!(Report::read(&report).unwrap().mode, Some(Mode::Deploy));
    }

    /// Checks: a report of the wrong length does not decode.
    #[test]
    fn short_reports_are_rejected() {
        assert_eq!(Report::read(&[1.0, 2.0]), None);
    }
}
