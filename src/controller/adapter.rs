//! The episodic adapter: owns an optimizer, a controller with a correction policy and a
//! cost shaper, and runs the learning loop one episode at a time.
//!
//! ```text
//! begin_episode(rng)  → θ (optimizer.ask, or the best θ when deploying)
//!   or begin_seeded_episode::<R>(seed): the RNG derived from a device seed and the
//!   learning episodes told, so that a checkpoint of the adapter needs no RNG state
//! control(state, obs) → action, every tick (and obs → shaper)
//! end_episode()       → cost = shaper.cost() → optimizer.tell(cost)
//! ```
//!
//! # The safety envelope
//! 1. **Parameters in their box**: every θ comes from the optimizer, which only proposes
//!    inside its [`Bounds`](crate::optimizer::Bounds); the initial θ is checked against them.
//! 2. **Correction clamp**: the controller's correction is clamped (see
//!    [`LinearPolicy`](super::LinearPolicy)).
//! 3. **Non-finite state or action**: that tick gets the nominal action (or, if even that is
//!    not finite, [`Controller::safe_action`]) and counts as a *faulty tick*.
//! 4. **Failed episodes**: an episode with more than `max_faulty_ticks` faulty ticks, a
//!    non-finite cost from the shaper, or one ended by [`Adapter::abort_episode`] (a watchdog,
//!    the operator) is told `failure_cost` instead: a finite penalty that the configuration
//!    documents. No NaN ever reaches an optimizer.
//! 5. **Runtime guard** (optional, [`EpisodeRunner::with_guard`], [`Adapter::with_guard`]):
//!    limits on the state or a safety signal, and the running cost against an envelope
//!    learned from the bare episodes; on a trip the rest of the episode runs the nominal
//!    controller and a learning episode is told the
//!    [tripped cost](super::guard::tripped_cost) (see [`guard`](super::guard)).
//!
//! # The plant model
//! Optional too ([`EpisodeRunner::with_model`], [`Adapter::with_model`]): every tick of
//! every episode, the state and the command sent are handed to a
//! [`TickModel`], e.g. an [`OnlineModel`](crate::model::OnlineModel)
//! fitting an [`RlsModel`](crate::model::RlsModel) (see [`model::online`](crate::model::online)).
//! 6. **Rollback**: after `learning_episodes` learning episodes, when the optimizer stops,
//!    or on demand ([`Adapter::set_mode`]), the adapter runs the best θ found
//!    ([`Mode::Deploy`]) and explores no more. [`Mode::Nominal`] runs the bare controller.

use core::fmt;

use rand_core::{RngCore, SeedableRng};

use super::Controller;
use super::guard::{Guard, Supervisor, Trip, Unguarded};
use crate::cost::Shaper;
use crate::error::{Error, require};
use crate::model::{TickModel, Unmodelled};
use crate::optimizer::Optimizer;
use crate::random::episode_rng;
use crate::vector::Vector;

/// What the adapter does with episodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Mode {
    /// Explore: each episode runs the optimizer's next candidate and tells its cost.
    Learn,
    /// Never explore: run the best θ found (or the initial θ before any), tell nothing.
    Deploy,
    /// Run the bare nominal controller (a baseline, or a safe mode), tell nothing.
    Nominal,
}

/// Parameters of an [`Adapter`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct AdapterConfig {
    /// Control period in seconds (> 0): the time step of the shaper and of `time` for the
    /// controller.
    pub dt: f32,
    /// The cost told for a failed episode (finite). Choose it worse than any real episode's
    /// cost (for the survey cost, more than the start's distance to the target).
    pub failure_cost: f32,
    /// An episode with more faulty ticks than this has failed.
    pub max_faulty_ticks: u32,
    /// Learning episodes before the adapter rolls back to the best θ (≥ 1).
    pub learning_episodes: u32,
}

impl AdapterConfig {
    /// `Ok` when every field is in range, else the first offending field.
    pub fn validate(&self) -> Result<(), Error> {
        require(self.dt.is_finite() && self.dt > 0.0, "dt")?;
        require(self.failure_cost.is_finite(), "failure_cost")?;
        require(self.learning_episodes != 0, "learning_episodes")?;
        Ok(())
    }
}

/// What an episode was and what was told.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EpisodeReport<const P: usize> {
    /// The parameters the episode ran.
    pub theta: Vector<P>,
    /// The mode it ran in.
    pub mode: Mode,
    /// The shaper's cost (may be non-finite).
    pub cost: f32,
    /// The cost told to the optimizer, if the episode was a learning one.
    pub told: Option<f32>,
    /// Whether it failed (and so was told the failure cost).
    pub failed: bool,
    /// Ticks whose state or action was not finite.
    pub faulty_ticks: u32,
    /// Ticks run.
    pub ticks: u32,
    /// When and why the guard handed the episode to the nominal controller (`None` without
    /// a guard or when it did not trip).
    pub trip: Option<Trip>,
    /// Ticks with some guard limit violated (0 without a guard).
    pub ticks_beyond_limits: u32,
}

/// Why an [`Adapter`] or [`EpisodeRunner`] call was refused: the call order, or the
/// optimizer's own error. The refused call changes nothing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum AdapterError {
    /// An episode is running: end it before beginning another or changing mode.
    EpisodeInProgress,
    /// No episode is running: begin one first.
    NoEpisode,
    /// The optimizer refused (a parameter outside the box, a stopped search, ...).
    Optimizer(Error),
}

impl From<Error> for AdapterError {
    fn from(error: Error) -> Self {
        Self::Optimizer(error)
    }
}

impl fmt::Display for AdapterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EpisodeInProgress => f.write_str("an episode is in progress"),
            Self::NoEpisode => f.write_str("no episode is in progress"),
            Self::Optimizer(e) => write!(f, "optimizer: {e}"),
        }
    }
}

impl core::error::Error for AdapterError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Optimizer(e) => Some(e),
            _ => None,
        }
    }
}

/// The episode in progress.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
struct Episode<const P: usize> {
    theta: Vector<P>,
    mode: Mode,
    ticks: u32,
    faulty_ticks: u32,
}

/// One episode at a time of a controller with a fixed θ, inside the safety envelope (items
/// 2–4 of the [module docs](self)), scored by a cost shaper; no optimizer.
///
/// The [`Adapter`] runs its episodes through one of these. Use it on its own to run a θ
/// computed elsewhere (a host simulation, a checkpoint) or to score a θ again. `G` is the
/// runtime guard ([`Unguarded`] unless [`EpisodeRunner::with_guard`] added one), `M` the
/// plant model fed every tick ([`Unmodelled`] unless [`EpisodeRunner::with_model`] added
/// one).
///
/// ```
/// use ctrl_adapt::controller::{
///     AdapterConfig, CorrectedPd, EpisodeRunner, LinearPolicy, Mode, Pd, StateFeatures,
/// };
/// use ctrl_adapt::cost::QuadraticCost;
/// use ctrl_adapt::Vector;
///
/// let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5))?;
/// let policy = LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(1.0))?;
/// let controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
/// let config = AdapterConfig { dt: 0.1, failure_cost: 10.0, max_faulty_ticks: 0, learning_episodes: 1 };
/// let mut runner = EpisodeRunner::try_new(controller, QuadraticCost::try_new(Vector::<1>::repeat(1.0))?, config)?;
/// runner.begin_episode(Vector::from([0.5, 0.0]), Mode::Deploy)?;
/// let u = runner.control(&Vector::from([1.0, 0.0]), &Vector::repeat(1.0));
/// assert_eq!(u, Vector::<1>::repeat(2.5)); // PD 2·1 plus the correction 0.5·1
/// let report = runner.end_episode()?;
/// assert_eq!((report.ticks, report.told, report.failed), (1, None, false));
/// # Ok::<(), Box<dyn core::error::Error>>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EpisodeRunner<
    C,
    Sh,
    const P: usize,
    const S: usize,
    const A: usize,
    G = Unguarded,
    M = Unmodelled,
> {
    controller: C,
    shaper: Sh,
    config: AdapterConfig,
    episode: Option<Episode<P>>,
    guard: G,
    model: M,
}

impl<C, Sh, const P: usize, const S: usize, const A: usize> EpisodeRunner<C, Sh, P, S, A>
where
    C: Controller<P, S, A>,
    Sh: Shaper,
{
    /// A runner between episodes (`config.learning_episodes` plays no part here), without a
    /// guard ([`EpisodeRunner::with_guard`] adds one).
    pub fn try_new(controller: C, shaper: Sh, config: AdapterConfig) -> Result<Self, Error> {
        config.validate()?;
        Ok(Self {
            controller,
            shaper,
            config,
            episode: None,
            guard: Unguarded,
            model: Unmodelled,
        })
    }
}

impl<C, Sh, const P: usize, const S: usize, const A: usize, M>
    EpisodeRunner<C, Sh, P, S, A, Unguarded, M>
where
    C: Controller<P, S, A>,
    Sh: Shaper,
{
    /// This runner with the runtime `guard` (see [`guard`](super::guard)); between episodes.
    /// Errors if a limit reads a state coordinate beyond `S`, or if the failure cost plus
    /// the guard's tripped-cost span is not a finite number above the failure cost.
    pub fn with_guard<const L: usize, const T: usize>(
        self,
        guard: Guard<L, T>,
    ) -> Result<EpisodeRunner<C, Sh, P, S, A, Guard<L, T>, M>, AdapterError> {
        if self.episode.is_some() {
            return Err(AdapterError::EpisodeInProgress);
        }
        check_guard::<S, _>(&guard, &self.config)?;
        Ok(EpisodeRunner {
            controller: self.controller,
            shaper: self.shaper,
            config: self.config,
            episode: None,
            guard,
            model: self.model,
        })
    }
}

impl<C, Sh, const P: usize, const S: usize, const A: usize, G>
    EpisodeRunner<C, Sh, P, S, A, G, Unmodelled>
where
    C: Controller<P, S, A>,
    Sh: Shaper,
{
    /// This runner feeding `model` every tick of every episode (see the [module
    /// docs](self) and [`model::online`](crate::model::online)); between episodes.
    pub fn with_model<M: TickModel<S, A>>(
        self,
        model: M,
    ) -> Result<EpisodeRunner<C, Sh, P, S, A, G, M>, AdapterError> {
        if self.episode.is_some() {
            return Err(AdapterError::EpisodeInProgress);
        }
        Ok(EpisodeRunner {
            controller: self.controller,
            shaper: self.shaper,
            config: self.config,
            episode: None,
            guard: self.guard,
            model,
        })
    }
}

impl<C, Sh, const P: usize, const S: usize, const A: usize, G, M>
    EpisodeRunner<C, Sh, P, S, A, G, M>
where
    C: Controller<P, S, A>,
    Sh: Shaper,
    G: Supervisor<S>,
    M: TickModel<S, A>,
{
    /// The guard ([`Unguarded`] without one): its counters and envelope.
    pub fn guard(&self) -> &G {
        &self.guard
    }

    /// The guard, mutable (to clear its envelope); between episodes.
    pub fn guard_mut(&mut self) -> Result<&mut G, AdapterError> {
        if self.episode.is_some() {
            return Err(AdapterError::EpisodeInProgress);
        }
        Ok(&mut self.guard)
    }

    /// The plant model ([`Unmodelled`] without one).
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The plant model, mutable (to reset it); between episodes.
    pub fn model_mut(&mut self) -> Result<&mut M, AdapterError> {
        if self.episode.is_some() {
            return Err(AdapterError::EpisodeInProgress);
        }
        Ok(&mut self.model)
    }

    /// Starts an episode that runs `theta` (or, in [`Mode::Nominal`], the bare controller).
    /// The runner does not check `theta` against a box: the [`Adapter`] does.
    pub fn begin_episode(&mut self, theta: Vector<P>, mode: Mode) -> Result<(), AdapterError> {
        if self.episode.is_some() {
            return Err(AdapterError::EpisodeInProgress);
        }
        self.shaper.reset();
        self.controller.reset();
        self.guard.begin(mode);
        self.model.begin();
        self.episode = Some(Episode {
            theta,
            mode,
            ticks: 0,
            faulty_ticks: 0,
        });
        Ok(())
    }

    /// One control tick: the action for `state`, with `observation` fed to the shaper.
    ///
    /// Never fails: a non-finite state or corrected action gives the nominal action (or the
    /// safe action) and counts a faulty tick. Outside an episode the nominal controller runs
    /// and nothing is recorded.
    pub fn control(&mut self, state: &Vector<S>, observation: &Sh::Observation) -> Vector<A> {
        self.control_with_signal(state, observation, &[])
    }

    /// [`EpisodeRunner::control`] with the safety `signal` the guard's
    /// [`Source::Signal`](super::guard::Source::Signal) limits read (ignored without a
    /// guard).
    pub fn control_with_signal(
        &mut self,
        state: &Vector<S>,
        observation: &Sh::Observation,
        signal: &[f32],
    ) -> Vector<A> {
        let Some(episode) = self.episode.as_mut() else {
            let nominal = self.controller.nominal(state, 0.0);
            return finite_or(nominal, || self.controller.safe_action());
        };
        let time = episode.ticks as f32 * self.config.dt;
        let state_ok = state.iter().all(|v| v.is_finite());
        // The shaper observes first, so that the guard compares the running cost with this
        // tick's observation in it and can hand this very tick over.
        self.shaper.observe(observation, self.config.dt);
        let shaper = &self.shaper;
        let handed_over = self
            .guard
            .check(episode.mode, episode.ticks, state, signal, || shaper.cost());
        // One call of the controller per tick (it may keep state), except for the fallback
        // after a non-finite corrected action (see `Controller`).
        let correcting = state_ok && episode.mode != Mode::Nominal && !handed_over;
        let action = if correcting {
            self.controller.corrected(&episode.theta, state, time)
        } else {
            self.controller.nominal(state, time)
        };
        let action_ok = action.iter().all(|v| v.is_finite());
        let action = if state_ok && action_ok {
            action
        } else {
            episode.faulty_ticks = episode.faulty_ticks.saturating_add(1);
            let nominal = if correcting {
                self.controller.nominal(state, time)
            } else {
                action
            };
            finite_or(nominal, || self.controller.safe_action())
        };
        episode.ticks = episode.ticks.saturating_add(1);
        self.model.tick(state, &action);
        action
    }

    /// Ends the episode and scores it; `told` is `None` in the report (nothing to tell).
    pub fn end_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError> {
        self.finish(false)
    }

    /// Ends the episode as failed (a watchdog fired, the operator stopped the robot).
    pub fn abort_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError> {
        self.finish(true)
    }

    fn finish(&mut self, aborted: bool) -> Result<EpisodeReport<P>, AdapterError> {
        let episode = self.episode.ok_or(AdapterError::NoEpisode)?;
        let cost = self.shaper.cost();
        let failed =
            aborted || !cost.is_finite() || episode.faulty_ticks > self.config.max_faulty_ticks;
        let (trip, ticks_beyond_limits) = self.guard.finish();
        self.episode = None;
        Ok(EpisodeReport {
            theta: episode.theta,
            mode: episode.mode,
            cost,
            told: None,
            failed,
            faulty_ticks: episode.faulty_ticks,
            ticks: episode.ticks,
            trip,
            ticks_beyond_limits,
        })
    }

    /// Whether an episode is running.
    pub fn in_episode(&self) -> bool {
        self.episode.is_some()
    }

    /// The mode of the running episode, if any.
    fn episode_mode(&self) -> Option<Mode> {
        self.episode.map(|e| e.mode)
    }

    /// The controller.
    pub fn controller(&self) -> &C {
        &self.controller
    }

    /// The controller, mutable: to change its gains between episodes, or to run its nominal
    /// law outside the tick loop (a link fault's fallback). Calls made here are not ticks:
    /// they are not counted, and a stateful controller sees them.
    pub fn controller_mut(&mut self) -> &mut C {
        &mut self.controller
    }

    /// The cost shaper (its running figures, e.g. the survey's minimum distance).
    pub fn shaper(&self) -> &Sh {
        &self.shaper
    }

    /// The configuration.
    pub fn config(&self) -> &AdapterConfig {
        &self.config
    }
}

/// The episodic learning loop with its safety envelope (see the [module docs](self)).
///
/// `O` optimizes θ ∈ R^P; `C` maps a state in R^S to an action in R^A; `Sh` (a cost
/// [`Shaper`]) scores episodes; `G` is the runtime guard, [`Unguarded`] (no bytes, no
/// instructions) unless [`Adapter::with_guard`] added a [`Guard`]; `M` the plant model fed
/// every tick, [`Unmodelled`] (no bytes, no instructions) unless [`Adapter::with_model`]
/// added one.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Adapter<
    O,
    C,
    Sh,
    const P: usize,
    const S: usize,
    const A: usize,
    G = Unguarded,
    M = Unmodelled,
> {
    optimizer: O,
    runner: EpisodeRunner<C, Sh, P, S, A, G, M>,
    mode: Mode,
    initial: Vector<P>,
    learning_episodes: u32,
}

impl<O, C, Sh, const P: usize, const S: usize, const A: usize> Adapter<O, C, Sh, P, S, A>
where
    O: Optimizer<P>,
    C: Controller<P, S, A>,
    Sh: Shaper,
{
    /// An adapter in [`Mode::Learn`]. `initial` is the θ deployed before any episode has
    /// been told (zero correction, or a θ learned elsewhere); it must lie in the optimizer's
    /// bounds.
    pub fn try_new(
        optimizer: O,
        controller: C,
        shaper: Sh,
        config: AdapterConfig,
        initial: Vector<P>,
    ) -> Result<Self, Error> {
        let runner = EpisodeRunner::try_new(controller, shaper, config)?;
        optimizer.bounds().check(&initial, "initial")?;
        Ok(Self {
            optimizer,
            runner,
            mode: Mode::Learn,
            initial,
            learning_episodes: 0,
        })
    }
}

impl<O, C, Sh, const P: usize, const S: usize, const A: usize, M>
    Adapter<O, C, Sh, P, S, A, Unguarded, M>
where
    O: Optimizer<P>,
    C: Controller<P, S, A>,
    Sh: Shaper,
{
    /// This adapter with the runtime `guard` (see [`guard`](super::guard) and
    /// [`EpisodeRunner::with_guard`]); between episodes.
    ///
    /// ```
    /// use ctrl_adapt::controller::guard::{Guard, GuardConfig};
    /// use ctrl_adapt::controller::{Adapter, AdapterConfig, CorrectedPd, LinearPolicy, Mode, Pd, StateFeatures};
    /// use ctrl_adapt::cost::QuadraticCost;
    /// use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Vector};
    /// # use rand_core::SeedableRng;
    /// # let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
    ///
    /// let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5))?;
    /// let policy = LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(1.0))?;
    /// let controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
    /// let search = CoordinateSearch::try_new(Bounds::uniform(-1.0, 1.0)?, Vector::zeros(), CoordinateConfig::DEFAULT)?;
    /// let config = AdapterConfig { dt: 0.1, failure_cost: 10.0, max_faulty_ticks: 0, learning_episodes: 20 };
    /// let shaper = QuadraticCost::try_new(Vector::<1>::repeat(1.0))?;
    /// // No limit; an envelope of 50 ticks with a 20 % margin.
    /// let guard = Guard::<0, 50>::try_new(GuardConfig { relative_margin: 0.2, ..GuardConfig::DEFAULT })?;
    /// let mut adapter = Adapter::try_new(search, controller, shaper, config, Vector::zeros())?
    ///     .with_guard(guard)?;
    /// // The envelope learns from bare episodes first.
    /// adapter.set_mode(Mode::Nominal)?;
    /// adapter.begin_episode(&mut rng)?;
    /// for _ in 0..50 {
    ///     adapter.control(&Vector::from([0.1, 0.0]), &Vector::repeat(0.1));
    /// }
    /// adapter.end_episode()?;
    /// assert_eq!(adapter.guard().counters().bare_episodes, 1);
    /// adapter.set_mode(Mode::Learn)?;
    /// # Ok::<(), Box<dyn core::error::Error>>(())
    /// ```
    pub fn with_guard<const L: usize, const T: usize>(
        self,
        guard: Guard<L, T>,
    ) -> Result<Adapter<O, C, Sh, P, S, A, Guard<L, T>, M>, AdapterError> {
        Ok(Adapter {
            optimizer: self.optimizer,
            runner: self.runner.with_guard(guard)?,
            mode: self.mode,
            initial: self.initial,
            learning_episodes: self.learning_episodes,
        })
    }
}

impl<O, C, Sh, const P: usize, const S: usize, const A: usize, G>
    Adapter<O, C, Sh, P, S, A, G, Unmodelled>
where
    O: Optimizer<P>,
    C: Controller<P, S, A>,
    Sh: Shaper,
{
    /// This adapter feeding `model` every tick of every episode, the bare ones included
    /// (see [`model::online`](crate::model::online), which has the example); between
    /// episodes.
    pub fn with_model<M: TickModel<S, A>>(
        self,
        model: M,
    ) -> Result<Adapter<O, C, Sh, P, S, A, G, M>, AdapterError> {
        Ok(Adapter {
            optimizer: self.optimizer,
            runner: self.runner.with_model(model)?,
            mode: self.mode,
            initial: self.initial,
            learning_episodes: self.learning_episodes,
        })
    }
}

impl<O, C, Sh, const P: usize, const S: usize, const A: usize, G, M>
    Adapter<O, C, Sh, P, S, A, G, M>
where
    O: Optimizer<P>,
    C: Controller<P, S, A>,
    Sh: Shaper,
    G: Supervisor<S>,
    M: TickModel<S, A>,
{
    /// Starts an episode and returns the θ it runs. In [`Mode::Learn`] this asks the
    /// optimizer; when the learning budget is spent or the optimizer has stopped, the
    /// adapter rolls back to [`Mode::Deploy`] first. Errors if an episode is running.
    pub fn begin_episode<R: RngCore + ?Sized>(
        &mut self,
        rng: &mut R,
    ) -> Result<Vector<P>, AdapterError> {
        if self.runner.in_episode() {
            return Err(AdapterError::EpisodeInProgress);
        }
        if self.mode == Mode::Learn
            && self.learning_episodes >= self.runner.config().learning_episodes
        {
            self.mode = Mode::Deploy;
        }
        let theta = match self.mode {
            Mode::Learn => match self.optimizer.ask(rng) {
                Ok(theta) => theta,
                Err(Error::Stopped) => {
                    self.mode = Mode::Deploy;
                    self.deployed_theta()
                }
                Err(e) => return Err(e.into()),
            },
            Mode::Deploy => self.deployed_theta(),
            Mode::Nominal => Vector::zeros(),
        };
        self.runner.begin_episode(theta, self.mode)?;
        Ok(theta)
    }

    /// [`Adapter::begin_episode`] with the RNG of this learning episode derived from the
    /// device's `seed` and the learning episodes told so far
    /// ([`random::episode_rng`](crate::random::episode_rng)).
    ///
    /// The adapter then is the whole learning state: a checkpoint of it (feature `serde`)
    /// holds no RNG, and a run resumed from one gives every θ of the uninterrupted run, bit
    /// for bit; an episode a power cut interrupted (nothing told) gets its candidate again.
    /// `R` is any seedable RNG, e.g. `rand_xoshiro::Xoshiro128PlusPlus`.
    pub fn begin_seeded_episode<R: RngCore + SeedableRng>(
        &mut self,
        seed: u32,
    ) -> Result<Vector<P>, AdapterError> {
        self.begin_episode(&mut episode_rng::<R>(seed, self.learning_episodes))
    }

    /// Starts an episode that runs `theta` (checked against the optimizer's box) and tells
    /// nothing, whatever the mode: to evaluate a θ handed over from elsewhere (a host
    /// simulation, an operator) inside the same envelope. Its report says [`Mode::Deploy`].
    pub fn begin_fixed_episode(&mut self, theta: Vector<P>) -> Result<(), AdapterError> {
        if self.runner.in_episode() {
            return Err(AdapterError::EpisodeInProgress);
        }
        self.optimizer.bounds().check(&theta, "theta")?;
        self.runner.begin_episode(theta, Mode::Deploy)
    }

    /// One control tick: the action for `state`, with `observation` fed to the shaper.
    ///
    /// Never fails: a non-finite state or corrected action gives the nominal action (or the
    /// safe action) and counts a faulty tick. Outside an episode the nominal controller runs
    /// and nothing is recorded.
    pub fn control(&mut self, state: &Vector<S>, observation: &Sh::Observation) -> Vector<A> {
        self.runner.control(state, observation)
    }

    /// [`Adapter::control`] with the safety `signal` of the guard's limits (see
    /// [`EpisodeRunner::control_with_signal`]).
    pub fn control_with_signal(
        &mut self,
        state: &Vector<S>,
        observation: &Sh::Observation,
        signal: &[f32],
    ) -> Vector<A> {
        self.runner.control_with_signal(state, observation, signal)
    }

    /// The guard ([`Unguarded`] without one): its counters and envelope.
    pub fn guard(&self) -> &G {
        self.runner.guard()
    }

    /// The guard, mutable (to clear its envelope); between episodes.
    pub fn guard_mut(&mut self) -> Result<&mut G, AdapterError> {
        self.runner.guard_mut()
    }

    /// The plant model ([`Unmodelled`] without one).
    pub fn model(&self) -> &M {
        self.runner.model()
    }

    /// The plant model, mutable (to reset it); between episodes.
    pub fn model_mut(&mut self) -> Result<&mut M, AdapterError> {
        self.runner.model_mut()
    }

    /// Ends the episode: scores it and, when learning, tells the optimizer (the
    /// [tripped cost](super::guard::tripped_cost) if the guard tripped, else the failure cost
    /// if the episode failed). Errors if no episode is running.
    pub fn end_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError> {
        self.finish(false)
    }

    /// Ends the episode as failed (a watchdog fired, the operator stopped the robot): a
    /// learning episode is told the failure cost (the tripped cost if the guard tripped).
    pub fn abort_episode(&mut self) -> Result<EpisodeReport<P>, AdapterError> {
        self.finish(true)
    }

    fn finish(&mut self, aborted: bool) -> Result<EpisodeReport<P>, AdapterError> {
        let learning = self.runner.episode_mode() == Some(Mode::Learn);
        let mut report = if aborted {
            self.runner.abort_episode()?
        } else {
            self.runner.end_episode()?
        };
        if learning {
            let failure_cost = self.runner.config().failure_cost;
            let value = match &report.trip {
                Some(trip) => self.runner.guard().told(failure_cost, trip, report.ticks),
                None if report.failed => failure_cost,
                None => report.cost,
            };
            // Cannot fail: `value` is finite (the failure cost is validated) and the
            // episode's candidate is pending (only this adapter asks its optimizer).
            self.optimizer.tell(value)?;
            self.learning_episodes = self.learning_episodes.saturating_add(1);
            report.told = Some(value);
        }
        Ok(report)
    }

    /// Switches mode between episodes ([`Mode::Deploy`] is the rollback to the best θ).
    /// Errors while an episode is running.
    pub fn set_mode(&mut self, mode: Mode) -> Result<(), AdapterError> {
        if self.runner.in_episode() {
            return Err(AdapterError::EpisodeInProgress);
        }
        self.mode = mode;
        Ok(())
    }

    /// Reopens learning with `optimizer` (built around [`Adapter::deployed_theta`], e.g. a
    /// coordinate search centred on it): after a change of the plant in service, or on an
    /// operator's request. The θ deployed until now becomes the initial θ (what
    /// [`Mode::Deploy`] runs until the new optimizer has a best), the mode [`Mode::Learn`], and
    /// the learning budget (`AdapterConfig::learning_episodes`) counts from zero again, so
    /// that [`Adapter::begin_seeded_episode`] derives the same episode RNGs as the first
    /// learning did (give it another device seed for other draws). The old optimizer's best
    /// is dropped with it: its costs were measured on the plant before the change, and
    /// "best" compares only costs measured in the same conditions. The guard's envelope and
    /// the model are kept (clear or re-measure them through [`Adapter::guard_mut`] and
    /// [`Adapter::model_mut`] if the change makes them stale).
    ///
    /// Errors while an episode is running, or if the deployed θ lies outside `optimizer`'s
    /// bounds; the adapter is then unchanged (and `optimizer` dropped).
    ///
    /// ```
    /// use ctrl_adapt::controller::{Adapter, AdapterConfig, CorrectedPd, LinearPolicy, Mode, Pd, StateFeatures};
    /// use ctrl_adapt::cost::QuadraticCost;
    /// use ctrl_adapt::{Bounds, CoordinateConfig, CoordinateSearch, Vector};
    /// # use rand_core::SeedableRng;
    /// # let mut rng = rand_xoshiro::Xoshiro128PlusPlus::seed_from_u64(1);
    /// let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5))?;
    /// let policy = LinearPolicy::try_new(StateFeatures::<2>::identity(), Vector::repeat(1.0))?;
    /// let controller: CorrectedPd<1, 2, 2, 2, _> = CorrectedPd::new(pd, policy);
    /// let bounds = Bounds::uniform(-1.0, 1.0)?;
    /// let search = CoordinateSearch::try_new(bounds, Vector::zeros(), CoordinateConfig::DEFAULT)?;
    /// let config = AdapterConfig { dt: 0.1, failure_cost: 10.0, max_faulty_ticks: 0, learning_episodes: 1 };
    /// let shaper = QuadraticCost::try_new(Vector::<1>::repeat(1.0))?;
    /// let mut adapter = Adapter::try_new(search, controller, shaper, config, Vector::zeros())?;
    /// adapter.begin_episode(&mut rng)?;
    /// adapter.control(&Vector::from([0.1, 0.0]), &Vector::repeat(0.1));
    /// adapter.end_episode()?;
    /// adapter.begin_episode(&mut rng)?; // the budget of one episode is spent: deployed
    /// adapter.end_episode()?;
    /// assert_eq!(adapter.mode(), Mode::Deploy);
    /// // The plant changed: search again, from what is deployed.
    /// let deployed = adapter.deployed_theta();
    /// let search = CoordinateSearch::try_new(bounds, deployed, CoordinateConfig::DEFAULT)?;
    /// adapter.relearn(search)?;
    /// assert_eq!((adapter.mode(), adapter.learning_episodes()), (Mode::Learn, 0));
    /// assert_eq!(adapter.deployed_theta(), deployed);
    /// # Ok::<(), Box<dyn core::error::Error>>(())
    /// ```
    pub fn relearn(&mut self, optimizer: O) -> Result<(), AdapterError> {
        if self.runner.in_episode() {
            return Err(AdapterError::EpisodeInProgress);
        }
        let deployed = self.deployed_theta();
        optimizer.bounds().check(&deployed, "initial")?;
        self.optimizer = optimizer;
        self.initial = deployed;
        self.mode = Mode::Learn;
        self.learning_episodes = 0;
        Ok(())
    }

    /// The current mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// The θ [`Mode::Deploy`] runs: the best told so far, else the initial θ.
    pub fn deployed_theta(&self) -> Vector<P> {
        self.optimizer.best().map_or(self.initial, |b| b.theta)
    }

    /// Learning episodes told so far.
    pub fn learning_episodes(&self) -> u32 {
        self.learning_episodes
    }

    /// Whether an episode is running.
    pub fn in_episode(&self) -> bool {
        self.runner.in_episode()
    }

    /// The optimizer.
    pub fn optimizer(&self) -> &O {
        &self.optimizer
    }

    /// The controller.
    pub fn controller(&self) -> &C {
        self.runner.controller()
    }

    /// The controller, mutable (see [`EpisodeRunner::controller_mut`]).
    pub fn controller_mut(&mut self) -> &mut C {
        self.runner.controller_mut()
    }

    /// The cost shaper (its running figures, e.g. the survey's minimum distance).
    pub fn shaper(&self) -> &Sh {
        self.runner.shaper()
    }

    /// The configuration.
    pub fn config(&self) -> &AdapterConfig {
        self.runner.config()
    }
}

#[cfg(feature = "serde")]
impl<C, Sh, const P: usize, const S: usize, const A: usize, G, M>
    EpisodeRunner<C, Sh, P, S, A, G, M>
where
    C: crate::record::Persistent,
    Sh: crate::record::Persistent,
    G: Supervisor<S>,
    M: TickModel<S, A>,
{
    /// The checks of a decoded runner ([`Persistent::validate`](crate::record::Persistent)):
    /// the configuration, the controller's and the shaper's own, and a running episode's θ
    /// finite.
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        self.config.validate()?;
        self.controller.validate()?;
        self.shaper.validate()?;
        check_guard(&self.guard, &self.config)?;
        self.model.validate_decoded()?;
        match &self.episode {
            Some(e) if e.theta.iter().any(|v| !v.is_finite()) => Err(Error::NonFinite("episode")),
            _ => Ok(()),
        }
    }
}

#[cfg(feature = "serde")]
impl<O, C, Sh, const P: usize, const S: usize, const A: usize, G, M>
    Adapter<O, C, Sh, P, S, A, G, M>
where
    O: Optimizer<P> + crate::record::Persistent,
    C: crate::record::Persistent,
    Sh: crate::record::Persistent,
    G: Supervisor<S>,
    M: TickModel<S, A>,
{
    /// The checks of a decoded adapter ([`Persistent::validate`](crate::record::Persistent)):
    /// the constructor's (the runner's and the optimizer's own checks, the initial θ inside
    /// the optimizer's box) and the envelope's: a running episode's θ inside the box (but
    /// in [`Mode::Nominal`], which runs no θ), and a learning episode only in
    /// [`Mode::Learn`], running the optimizer's pending candidate (the one it will be told).
    pub(crate) fn check_decoded(&self) -> Result<(), Error> {
        self.runner.check_decoded()?;
        self.optimizer.validate()?;
        let bounds = self.optimizer.bounds();
        bounds.check(&self.initial, "initial")?;
        if let Some(e) = &self.runner.episode {
            if e.mode != Mode::Nominal {
                bounds.check(&e.theta, "episode")?;
            }
            if e.mode == Mode::Learn {
                let told_next = self.optimizer.pending() == Some(&e.theta);
                require(self.mode == Mode::Learn && told_next, "episode")?;
            }
        }
        Ok(())
    }
}

/// The checks of `guard` in a runner of `config`, the same for
/// [`EpisodeRunner::with_guard`] and for a decoded runner (so that no record holds a guard
/// the constructor refuses): its own checks (its configuration's range checks, and a
/// decoded guard's state), its limits against the state's size `S`, and its tripped-cost
/// span against the failure cost ([`fit_tripped_cost_span`](super::guard::fit_tripped_cost_span)).
fn check_guard<const S: usize, G: Supervisor<S>>(
    guard: &G,
    config: &AdapterConfig,
) -> Result<(), Error> {
    guard.fit()?;
    guard.validate_decoded()?;
    guard.fit_failure_cost(config.failure_cost)
}

fn finite_or<const A: usize>(action: Vector<A>, safe: impl FnOnce() -> Vector<A>) -> Vector<A> {
    if action.iter().all(|v| v.is_finite()) {
        action
    } else {
        safe()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::{CorrectedPd, LinearPolicy, Pd, StateFeatures};
    use crate::optimizer::{Bounds, CoordinateConfig, CoordinateSearch, Status};
    use proptest::prelude::*;
    use rand_core::SeedableRng;
    use rand_xoshiro::Xoshiro128PlusPlus;

    /// A shaper whose cost is whatever the test sets (NaN included).
    #[derive(Debug, Clone, Copy, PartialEq)]
    struct SetCost(f32);

    impl Shaper for SetCost {
        type Observation = f32;
        fn reset(&mut self) {}
        fn observe(&mut self, cost: &f32, _dt: f32) {
            self.0 = *cost;
        }
        fn cost(&self) -> f32 {
            self.0
        }
        fn skipped(&self) -> u32 {
            0
        }
    }

    type Ctl = CorrectedPd<1, 2, 2, 2, StateFeatures<2>>;
    type Test = Adapter<CoordinateSearch<2>, Ctl, SetCost, 2, 2, 1>;

    const CONFIG: AdapterConfig = AdapterConfig {
        dt: 0.1,
        failure_cost: 100.0,
        max_faulty_ticks: 0,
        learning_episodes: 50,
    };

    fn adapter(config: AdapterConfig, budget: u32) -> Test {
        let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5)).unwrap();
        let policy = LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(1.0)).unwrap();
        let search = CoordinateSearch::try_new(
            Bounds::uniform(-1.0, 1.0).unwrap(),
            Vector::zeros(),
            CoordinateConfig {
                initial_step: 0.5,
                max_evaluations: budget,
                ..CoordinateConfig::DEFAULT
            },
        )
        .unwrap();
        Adapter::try_new(
            search,
            CorrectedPd::new(pd, policy),
            SetCost(0.0),
            config,
            Vector::zeros(),
        )
        .unwrap()
    }

    fn rng() -> Xoshiro128PlusPlus {
        Xoshiro128PlusPlus::seed_from_u64(5)
    }

    /// Checks `relearn`: refused during an episode and for a box that excludes the deployed
    /// θ (the adapter unchanged both times); otherwise learning reopens from the deployed θ
    /// with a fresh budget, and the new optimizer's first candidate (its centre) is that θ.
    #[test]
    fn relearn_reopens_learning_from_the_deployed_theta() {
        let mut a = adapter(CONFIG, 100);
        let mut r = rng();
        for cost in [3.0, 1.0, 2.0, 4.0] {
            a.begin_episode(&mut r).unwrap();
            a.control(&Vector::from([0.1, 0.0]), &cost);
            a.end_episode().unwrap();
        }
        a.set_mode(Mode::Deploy).unwrap();
        let deployed = a.deployed_theta();
        assert_ne!(deployed, Vector::<2>::zeros());
        let around = |lower: f32, upper: f32| {
            CoordinateSearch::try_new(
                Bounds::uniform(lower, upper).unwrap(),
                deployed.map(|t| t.clamp(lower, upper)),
                CoordinateConfig::DEFAULT,
            )
            .unwrap()
        };
        a.begin_episode(&mut r).unwrap();
        let before = a;
        assert_eq!(
            a.relearn(around(-1.0, 1.0)),
            Err(AdapterError::EpisodeInProgress)
        );
        a.end_episode().unwrap();
        let before_box = a;
        // A box that leaves the deployed θ out.
        let far = if deployed[0] > 0.0 {
            (-1.0, -0.9)
        } else {
            (0.9, 1.0)
        };
        assert_eq!(
            a.relearn(around(far.0, far.1)),
            Err(AdapterError::Optimizer(Error::OutOfBounds("initial")))
        );
        assert_eq!(a, before_box);
        assert_ne!(before, before_box);
        a.relearn(around(-1.0, 1.0)).unwrap();
        assert_eq!((a.mode(), a.learning_episodes()), (Mode::Learn, 0));
        assert_eq!(a.deployed_theta(), deployed);
        assert_eq!(a.begin_episode(&mut r).unwrap(), deployed);
    }

    #[test]
    fn non_finite_state_gets_the_nominal_or_safe_action_and_fails_the_episode() {
        let mut a = adapter(CONFIG, 100);
        let mut r = rng();
        a.begin_episode(&mut r).unwrap();
        // Finite state: the corrected action (θ is the start, zero, so nominal here).
        let u = a.control(&Vector::from([1.0, 0.0]), &1.0);
        assert_eq!(u, Vector::<1>::repeat(2.0));
        // NaN rate: nominal is NaN too, so the safe action (zero) is used.
        let u = a.control(&Vector::from([1.0, f32::NAN]), &1.0);
        assert_eq!(u, Vector::<1>::repeat(0.0));
        let report = a.end_episode().unwrap();
        assert!(report.failed);
        assert_eq!((report.faulty_ticks, report.ticks), (1, 2));
        assert_eq!(report.told, Some(100.0));
    }

    /// A controller whose correction is broken (NaN) while its nominal law is fine.
    #[derive(Debug, Clone, Copy)]
    struct BrokenCorrection;

    impl Controller<2, 2, 1> for BrokenCorrection {
        fn nominal(&mut self, state: &Vector<2>, _time: f32) -> Vector<1> {
            Vector::repeat(-state[0])
        }
        fn corrected(&mut self, _theta: &Vector<2>, _state: &Vector<2>, _time: f32) -> Vector<1> {
            Vector::repeat(f32::NAN)
        }
    }

    /// A PD that differentiates its own error (it keeps the previous one) and counts the
    /// calls it gets.
    #[derive(Debug, Clone, Copy, Default)]
    struct DifferentiatingPd {
        previous: Option<f32>,
        nominal_calls: u32,
        corrected_calls: u32,
        resets: u32,
    }

    impl DifferentiatingPd {
        /// u = 2e + 0.5 ė, ė by difference over the 0.1 s tick (0 on the first tick).
        fn pd(&mut self, error: f32) -> f32 {
            let rate = self.previous.map_or(0.0, |p| (error - p) / 0.1);
            self.previous = Some(error);
            2.0 * error + 0.5 * rate
        }
    }

    impl Controller<2, 2, 1> for DifferentiatingPd {
        fn nominal(&mut self, state: &Vector<2>, _time: f32) -> Vector<1> {
            self.nominal_calls += 1;
            Vector::repeat(self.pd(state[0]))
        }
        fn corrected(&mut self, theta: &Vector<2>, state: &Vector<2>, _time: f32) -> Vector<1> {
            self.corrected_calls += 1;
            Vector::repeat(self.pd(state[0]) + theta[0] * state[0])
        }
        fn reset(&mut self) {
            self.previous = None;
            self.resets += 1;
        }
    }

    /// Checks: a controller that keeps state gets one call per tick (corrected while
    /// learning, nominal in `Mode::Nominal` and outside episodes), sees its own previous
    /// error (the derivative term is the finite difference), and is reset when an episode
    /// begins.
    #[test]
    fn a_stateful_controller_gets_one_call_per_tick_and_a_reset_per_episode() {
        let search = *adapter(CONFIG, 100).optimizer();
        let mut a = Adapter::try_new(
            search,
            DifferentiatingPd::default(),
            SetCost(1.0),
            CONFIG,
            Vector::zeros(),
        )
        .unwrap();
        let mut r = rng();
        let theta = a.begin_episode(&mut r).unwrap();
        let u0 = a.control(&Vector::from([1.0, 0.0]), &1.0)[0];
        let u1 = a.control(&Vector::from([0.8, 0.0]), &1.0)[0];
        assert!(
            (u0 - (2.0 + theta[0])).abs() < 1e-6,
            "first tick: no rate yet"
        );
        let expected = 2.0 * 0.8 + 0.5 * (0.8 - 1.0) / 0.1 + theta[0] * 0.8;
        assert!((u1 - expected).abs() < 1e-5, "{u1} against {expected}");
        a.end_episode().unwrap();
        let c = *a.controller();
        assert_eq!((c.corrected_calls, c.nominal_calls, c.resets), (2, 0, 1));
        a.control(&Vector::from([0.8, 0.0]), &1.0); // between episodes: nominal, once
        a.set_mode(Mode::Nominal).unwrap();
        a.begin_episode(&mut r).unwrap();
        a.control(&Vector::from([0.5, 0.0]), &1.0);
        a.control(&Vector::from([f32::NAN, 0.0]), &1.0); // faulty, still one call
        a.end_episode().unwrap();
        let c = *a.controller();
        assert_eq!((c.corrected_calls, c.nominal_calls, c.resets), (2, 3, 2));
    }

    #[test]
    fn non_finite_corrected_action_falls_back_to_nominal() {
        let config = AdapterConfig {
            max_faulty_ticks: 1,
            ..CONFIG
        };
        let search = *adapter(CONFIG, 100).optimizer();
        let mut a = Adapter::try_new(
            search,
            BrokenCorrection,
            SetCost(0.0),
            config,
            Vector::zeros(),
        )
        .unwrap();
        let mut r = rng();
        a.begin_episode(&mut r).unwrap();
        assert_eq!(
            a.control(&Vector::from([0.25, 0.0]), &3.0),
            Vector::<1>::repeat(-0.25)
        );
        let report = a.end_episode().unwrap();
        assert!(
            !report.failed,
            "one faulty tick is tolerated with max_faulty_ticks = 1"
        );
        assert_eq!((report.faulty_ticks, report.told), (1, Some(3.0)));
    }

    #[test]
    fn call_order_is_checked() {
        let mut a = adapter(CONFIG, 100);
        let mut r = rng();
        assert_eq!(a.end_episode(), Err(AdapterError::NoEpisode));
        // Outside an episode the nominal controller runs and nothing is recorded.
        assert_eq!(
            a.control(&Vector::from([0.5, 0.0]), &3.0),
            Vector::<1>::repeat(1.0)
        );
        a.begin_episode(&mut r).unwrap();
        assert_eq!(
            a.begin_episode(&mut r),
            Err(AdapterError::EpisodeInProgress)
        );
        assert_eq!(
            a.set_mode(Mode::Deploy),
            Err(AdapterError::EpisodeInProgress)
        );
        a.end_episode().unwrap();
        let bad = Adapter::try_new(
            *a.optimizer(),
            *a.controller(),
            SetCost(0.0),
            CONFIG,
            Vector::from([2.0, 0.0]),
        );
        assert_eq!(bad.unwrap_err(), Error::OutOfBounds("initial"));
        let bad_cfg = AdapterConfig {
            failure_cost: f32::NAN,
            ..CONFIG
        };
        assert_eq!(
            Adapter::try_new(
                *a.optimizer(),
                *a.controller(),
                SetCost(0.0),
                bad_cfg,
                Vector::zeros()
            )
            .unwrap_err(),
            Error::InvalidParameter("failure_cost")
        );
    }

    #[test]
    fn rolls_back_to_the_best_after_the_learning_budget() {
        let mut a = adapter(
            AdapterConfig {
                learning_episodes: 6,
                ..CONFIG
            },
            100,
        );
        let mut r = rng();
        let mut best = (f32::INFINITY, Vector::<2>::zeros());
        for k in 0..6 {
            let theta = a.begin_episode(&mut r).unwrap();
            // Cost: distance of θ to (0.5, −0.5), reported through the shaper.
            let cost = (theta - Vector::from([0.5, -0.5])).norm() + k as f32 * 0.0;
            a.control(&Vector::zeros(), &cost);
            let report = a.end_episode().unwrap();
            assert_eq!(report.mode, Mode::Learn);
            if cost < best.0 {
                best = (cost, theta);
            }
        }
        let theta = a.begin_episode(&mut r).unwrap();
        assert_eq!(a.mode(), Mode::Deploy);
        assert_eq!(theta, best.1);
        a.control(&Vector::zeros(), &0.0);
        let report = a.end_episode().unwrap();
        assert_eq!((report.mode, report.told), (Mode::Deploy, None));
        assert_eq!(a.optimizer().evaluations(), 6, "deployment tells nothing");
        // Nominal mode runs θ = 0 through the nominal law.
        a.set_mode(Mode::Nominal).unwrap();
        a.begin_episode(&mut r).unwrap();
        assert_eq!(
            a.control(&Vector::from([1.0, 1.0]), &0.0),
            Vector::<1>::repeat(1.5)
        );
        a.end_episode().unwrap();
    }

    #[test]
    fn a_stopped_optimizer_means_deployment() {
        let mut a = adapter(CONFIG, 2);
        let mut r = rng();
        for _ in 0..2 {
            a.begin_episode(&mut r).unwrap();
            a.control(&Vector::zeros(), &1.0);
            a.end_episode().unwrap();
        }
        assert_eq!(a.optimizer().status(), Status::BudgetSpent);
        a.begin_episode(&mut r).unwrap();
        assert_eq!(a.mode(), Mode::Deploy);
    }

    /// Checks the seeded episodes with SRACOS (which draws in every `ask`): a copy of the
    /// adapter taken after each tell (what a checkpoint restores) and resumed, after an
    /// interrupted episode every third time, asks every θ of the uninterrupted run; another
    /// device seed asks other θ, and each episode's θ is the one `begin_episode` gets from
    /// `episode_rng(seed, learning episodes told)`.
    #[test]
    fn seeded_episodes_resume_from_a_copy_bit_for_bit() {
        use crate::optimizer::{Sracos, SracosConfig};
        use crate::random::episode_rng;
        let fresh = || {
            let pd = Pd::<1>::try_new(Vector::repeat(2.0), Vector::repeat(0.5)).unwrap();
            let policy =
                LinearPolicy::try_new(StateFeatures::identity(), Vector::repeat(1.0)).unwrap();
            let search: Sracos<2> =
                Sracos::try_new(Bounds::uniform(-1.0, 1.0).unwrap(), SracosConfig::DEFAULT)
                    .unwrap();
            let controller: Ctl = CorrectedPd::new(pd, policy);
            Adapter::try_new(search, controller, SetCost(0.0), CONFIG, Vector::zeros()).unwrap()
        };
        let cost = |t: &Vector<2>| (t[0] - 0.3).powi(2) + (t[1] + 0.2).powi(2);
        let run = |seed: u32, interrupt: bool| {
            let mut a = fresh();
            let mut thetas = std::vec::Vec::new();
            for k in 0..30u32 {
                let checkpoint = a;
                if interrupt && k % 3 == 1 {
                    // A power cut mid-episode: back to the copy, the episode runs again.
                    a.begin_seeded_episode::<Xoshiro128PlusPlus>(seed).unwrap();
                    a.control(&Vector::zeros(), &1.0);
                    a = checkpoint;
                }
                let mut direct = a;
                let expected = direct
                    .begin_episode(&mut episode_rng::<Xoshiro128PlusPlus>(seed, k))
                    .unwrap();
                let theta = a.begin_seeded_episode::<Xoshiro128PlusPlus>(seed).unwrap();
                assert_eq!(theta, expected);
                a.control(&Vector::zeros(), &cost(&theta));
                a.end_episode().unwrap();
                thetas.push(theta.map(f32::to_bits));
            }
            (thetas, a)
        };
        let (straight, end) = run(9, false);
        let (resumed, resumed_end) = run(9, true);
        assert_eq!(straight, resumed);
        assert_eq!(end, resumed_end);
        assert_ne!(straight, run(10, false).0);
    }

    proptest! {
        /// Checks: whatever cost the shaper reports (any f32) and however many faulty ticks,
        /// `end_episode` succeeds, tells a finite cost (the failure cost exactly when the
        /// episode failed), and the optimizer counts one more evaluation.
        #[test]
        fn never_tells_a_non_finite_cost(
            costs in prop::collection::vec(proptest::num::f32::ANY, 1..20),
            nan_ticks in prop::collection::vec(any::<bool>(), 1..20),
        ) {
            let mut a = adapter(CONFIG, 1000);
            let mut r = rng();
            for (k, cost) in costs.iter().enumerate() {
                a.begin_episode(&mut r).unwrap();
                let bad = nan_ticks[k % nan_ticks.len()];
                let state = if bad { Vector::from([f32::NAN, 0.0]) } else { Vector::zeros() };
                let u = a.control(&state, cost);
                prop_assert!(u.iter().all(|v| v.is_finite()));
                let report = a.end_episode().unwrap();
                let told = report.told.unwrap();
                prop_assert!(told.is_finite());
                prop_assert_eq!(report.failed, bad || !cost.is_finite());
                prop_assert_eq!(told, if report.failed { 100.0 } else { *cost });
                prop_assert_eq!(a.optimizer().evaluations(), k as u32 + 1);
            }
        }
    }
}
