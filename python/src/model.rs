//! The library's plant model and model-based learner ([`ctrl_adapt::model`]) for a loop
//! written in Python (classes `ctrl_adapt._native.RlsModel` and `ctrl_adapt._native.ModelBased`,
//! exported by the package as `ctrl_adapt.RlsModel` and `ctrl_adapt.ModelBased`).
//!
//! The sizes are compiled in, over a bounded set to keep the package's build short:
//!
//! - `RlsModel<S, A, R>` with S from 1 to [`MAX_STATE`], A from 1 to [`MAX_ACTION`] and
//!   R = S + A + 1 + E, E (the user's extra regressors, computed by the caller and passed
//!   with each tick: the library's `AffineWith`) one of [`EXTRA_FEATURES`];
//! - `ModelBased<F, N>` with N from 1 to [`MAX_LEARNER_DIMENSION`] and the fallback F
//!   `CoordinateSearch<N>` or `Cmaes<N, λ>` (λ = 4 + ⌊3 ln n⌋, as the package's
//!   optimizers), the inner search, built afresh in each proposal, a coordinate search or
//!   `Cmaes<N, λ>`.
//!
//! The objects are the library's types, so their records are the records firmware loads,
//! and for the same ticks, seed and predictions they compute the same numbers bit for bit
//! (the package's tests check both against the Rust reference).

use core::cell::Cell;
use ctrl_adapt::model::{
    AffineWith, ModelBased, ModelBasedConfig, ModelConfig, Prediction, Proposal, RlsModel, Source,
    rollout,
};
use ctrl_adapt::optimizer::{Cmaes, CmaesConfig, CoordinateConfig, CoordinateSearch, Optimizer};
use ctrl_adapt::record::{self, Persistent, RecordError};
use ctrl_adapt::{Bounds, Error, Vector};
use rand_core::RngCore;
use rand_xoshiro::Xoshiro128PlusPlus;

use crate::dispatch::{configured, record_of};

pub mod classes;
pub use classes::register;

/// The largest state compiled for [`RlsModel`].
pub const MAX_STATE: usize = 8;
/// The largest command compiled for [`RlsModel`].
pub const MAX_ACTION: usize = 2;
/// The counts of user regressors compiled for [`RlsModel`].
pub const EXTRA_FEATURES: [usize; 3] = [0, 1, 2];
/// The largest dimension compiled for [`ModelBased`].
pub const MAX_LEARNER_DIMENSION: usize = 8;

// ---------------------------------------------------------------------------------------
// RlsModel at any compiled sizes.

/// A command for one tick, from the caller's policy; `Err` stops the rollout at once (the
/// policy is not called again).
pub type Policy<'a> = dyn FnMut(u32, &[f32]) -> Result<Vec<f32>, String> + 'a;

/// Why a rollout returned no states.
#[derive(Debug)]
pub enum RolloutError {
    /// The model has no rollout, or the policy failed (the message).
    Refused(String),
    /// The states do not fit in memory (an allocation was refused): nothing is kept.
    Memory,
}

/// How a rollout that returned its states ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rolled {
    /// Every tick was predicted: `ticks + 1` rows.
    Finished,
    /// A prediction left the finite numbers (or the start was not finite): the rows up to
    /// the last finite state, the rest of the rollout unknown.
    Diverged,
}

/// The values of a rollout's `ticks + 1` rows of `s` states (`None` beyond `usize`).
pub fn rollout_values(ticks: u32, s: usize) -> Option<usize> {
    usize::try_from(ticks).ok()?.checked_add(1)?.checked_mul(s)
}

/// The values a rollout's row buffer first holds (32 KiB as `f64`).
const FIRST_ROWS_VALUES: usize = 4096;

/// `row` appended to `out` as `f64`, `out` grown geometrically with a fallible allocation
/// (to at most `total` values, the whole rollout), so that a rollout too large for memory
/// is [`RolloutError::Memory`], not an abort, and memory grows with the ticks rolled out
/// rather than with the ticks asked for.
fn push_row(out: &mut Vec<f64>, row: &[f32], total: usize) -> Result<(), RolloutError> {
    if out.capacity() - out.len() < row.len() {
        let want = out
            .capacity()
            .saturating_mul(2)
            .max(FIRST_ROWS_VALUES)
            .min(total);
        let more = want.saturating_sub(out.len()).max(row.len());
        out.try_reserve_exact(more)
            .map_err(|_| RolloutError::Memory)?;
    }
    out.extend(row.iter().map(|&v| f64::from(v)));
    Ok(())
}

/// An `RlsModel<S, A, R>` of any compiled sizes. Slices are checked for length by the
/// caller ([`DynModel::sizes`]).
pub trait DynModel: Send + Sync {
    /// (S, A, E).
    fn sizes(&self) -> (usize, usize, usize);
    /// `RlsModel::update` with the extra regressors `extra`.
    fn update(
        &mut self,
        state: &[f32],
        action: &[f32],
        next: &[f32],
        extra: &[f32],
    ) -> Result<Vec<f32>, Error>;
    /// `RlsModel::predict`.
    fn predict(&self, state: &[f32], action: &[f32], extra: &[f32]) -> Vec<f32>;
    /// The states of a rollout from `start` under `policy` (E = 0), appended to `out` row
    /// by row (S values each, as `f64`): `ticks + 1` rows when [`Rolled::Finished`], the
    /// rows up to the last finite state when a prediction leaves the finite numbers
    /// ([`Rolled::Diverged`]). The first failure of `policy` stops the rollout; `out`
    /// grows with fallible allocations ([`RolloutError::Memory`] when one is refused).
    fn rollout(
        &self,
        start: &[f32],
        ticks: u32,
        policy: &mut Policy<'_>,
        out: &mut Vec<f64>,
    ) -> Result<Rolled, RolloutError>;
    /// `RlsModel::episode_error` (E = 0).
    fn episode_error(&self, states: &[Vec<f32>], actions: &[Vec<f32>]) -> Result<Vec<f32>, Error>;
    /// `RlsModel::one_step_error`.
    fn one_step_error(&self) -> Vec<f32>;
    /// `RlsModel::ticks`.
    fn ticks(&self) -> u32;
    /// W, R rows of S.
    fn weights(&self) -> Vec<Vec<f32>>;
    /// P, R rows of R.
    fn covariance(&self) -> Vec<Vec<f32>>;
    /// `RlsModel::config`.
    fn config(&self) -> ModelConfig;
    /// `RlsModel::reset`.
    fn reset(&mut self);
    /// The record of `RlsModel<S, A, R>`.
    fn save(&self) -> Result<Vec<u8>, RecordError>;
    /// A copy.
    fn boxed_clone(&self) -> Box<dyn DynModel>;
}

/// `RlsModel<S, A, R>` with E = R − S − A − 1 user regressors.
#[derive(Clone, Copy)]
struct Model<const S: usize, const A: usize, const R: usize, const E: usize>(RlsModel<S, A, R>);

/// The rows of a matrix of `rows` × `columns` read by `at`.
fn rows(rows: usize, columns: usize, at: impl Fn(usize, usize) -> f32) -> Vec<Vec<f32>> {
    (0..rows)
        .map(|i| (0..columns).map(|j| at(i, j)).collect())
        .collect()
}

impl<const S: usize, const A: usize, const R: usize, const E: usize> DynModel
    for Model<S, A, R, E>
{
    fn sizes(&self) -> (usize, usize, usize) {
        (S, A, E)
    }

    fn update(
        &mut self,
        state: &[f32],
        action: &[f32],
        next: &[f32],
        extra: &[f32],
    ) -> Result<Vec<f32>, Error> {
        let g = Vector::<E>::from_column_slice(extra);
        let map = AffineWith::new(|_: &Vector<S>, _: &Vector<A>| g);
        self.0
            .update(
                &map,
                &Vector::from_column_slice(state),
                &Vector::from_column_slice(action),
                &Vector::from_column_slice(next),
            )
            .map(|e| e.as_slice().to_vec())
    }

    fn predict(&self, state: &[f32], action: &[f32], extra: &[f32]) -> Vec<f32> {
        let g = Vector::<E>::from_column_slice(extra);
        let map = AffineWith::new(|_: &Vector<S>, _: &Vector<A>| g);
        let x = Vector::<S>::from_column_slice(state);
        let u = Vector::<A>::from_column_slice(action);
        self.0.predict(&map, &x, &u).as_slice().to_vec()
    }

    fn rollout(
        &self,
        start: &[f32],
        ticks: u32,
        policy: &mut Policy<'_>,
        out: &mut Vec<f64>,
    ) -> Result<Rolled, RolloutError> {
        if E > 0 {
            return Err(RolloutError::Refused(
                "a rollout needs the caller's extra regressors".into(),
            ));
        }
        let total = rollout_values(ticks, S).ok_or(RolloutError::Memory)?;
        let map = no_extra::<S, A, E>();
        let mut state = Vector::<S>::from_column_slice(start);
        push_row(out, state.as_slice(), total)?;
        for k in 0..ticks {
            let command = policy(k, state.as_slice()).map_err(RolloutError::Refused)?;
            let command = Vector::<A>::from_column_slice(&command);
            // The library's rollout one tick at a time (the same predictions and checks as
            // one call over every tick), so that the policy's failure stops it at once.
            state = match rollout(&self.0, &map, &state, 1, |_, _| command) {
                Ok(next) => next,
                // The prediction left the finite numbers (or the start is not finite): the
                // rest of the rollout is unknown.
                Err(_) => return Ok(Rolled::Diverged),
            };
            push_row(out, state.as_slice(), total)?;
        }
        Ok(Rolled::Finished)
    }

    fn episode_error(&self, states: &[Vec<f32>], actions: &[Vec<f32>]) -> Result<Vec<f32>, Error> {
        let states: Vec<Vector<S>> = states
            .iter()
            .map(|s| Vector::from_column_slice(s))
            .collect();
        let actions: Vec<Vector<A>> = actions
            .iter()
            .map(|u| Vector::from_column_slice(u))
            .collect();
        if E > 0 {
            return Err(Error::InvalidParameter("features"));
        }
        self.0
            .episode_error(&no_extra::<S, A, E>(), &states, &actions)
            .map(|e| e.as_slice().to_vec())
    }

    fn one_step_error(&self) -> Vec<f32> {
        self.0.one_step_error().as_slice().to_vec()
    }

    fn ticks(&self) -> u32 {
        self.0.ticks()
    }

    fn weights(&self) -> Vec<Vec<f32>> {
        rows(R, S, |i, j| self.0.weights()[(i, j)])
    }

    fn covariance(&self) -> Vec<Vec<f32>> {
        let p = self.0.covariance();
        rows(R, R, |i, j| p[(i, j)])
    }

    fn config(&self) -> ModelConfig {
        *self.0.config()
    }

    fn reset(&mut self) {
        self.0.reset();
    }

    fn save(&self) -> Result<Vec<u8>, RecordError> {
        record_of(&self.0)
    }

    fn boxed_clone(&self) -> Box<dyn DynModel> {
        Box::new(*self)
    }
}

/// The affine regressors [x, u, 1] (as the library's `Affine`; with E = 0, the only case
/// in which it is used, nothing is appended).
fn no_extra<const S: usize, const A: usize, const E: usize>()
-> AffineWith<E, impl Fn(&Vector<S>, &Vector<A>) -> Vector<E>> {
    AffineWith::new(|_: &Vector<S>, _: &Vector<A>| Vector::<E>::zeros())
}

/// What to do at sizes (S, A, E): build with a config, or load a record.
enum ModelWork<'a> {
    Build(ModelConfig),
    Load(&'a [u8]),
}

fn model_at<const S: usize, const A: usize, const R: usize, const E: usize>(
    work: &ModelWork<'_>,
) -> Result<Box<dyn DynModel>, Result<Error, RecordError>> {
    let model = match work {
        ModelWork::Build(config) => RlsModel::<S, A, R>::try_new(*config).map_err(Ok)?,
        ModelWork::Load(bytes) => record::load::<RlsModel<S, A, R>>(bytes).map_err(Err)?,
    };
    Ok(Box::new(Model::<S, A, R, E>(model)))
}

/// `model_at::<S, A, S + A + 1 + E, E>` for the compiled E equal to `$e`.
macro_rules! model_extra {
    ($s:literal, $a:literal, $e:expr, $work:expr) => {
        match $e {
            0 => Some(model_at::<$s, $a, { $s + $a + 1 }, 0>($work)),
            1 => Some(model_at::<$s, $a, { $s + $a + 2 }, 1>($work)),
            2 => Some(model_at::<$s, $a, { $s + $a + 3 }, 2>($work)),
            _ => None,
        }
    };
}

macro_rules! model_action {
    ($s:literal, $a:expr, $e:expr, $work:expr) => {
        match $a {
            1 => model_extra!($s, 1, $e, $work),
            2 => model_extra!($s, 2, $e, $work),
            _ => None,
        }
    };
}

fn model_sizes(
    s: usize,
    a: usize,
    e: usize,
    work: &ModelWork<'_>,
) -> Option<Result<Box<dyn DynModel>, Result<Error, RecordError>>> {
    match s {
        1 => model_action!(1, a, e, work),
        2 => model_action!(2, a, e, work),
        3 => model_action!(3, a, e, work),
        4 => model_action!(4, a, e, work),
        5 => model_action!(5, a, e, work),
        6 => model_action!(6, a, e, work),
        7 => model_action!(7, a, e, work),
        8 => model_action!(8, a, e, work),
        _ => None,
    }
}

/// Why a model or a learner cannot be built.
#[derive(Debug)]
pub enum BuildError {
    /// The library refused a value.
    Library(Error),
    /// Sizes or a configuration the package does not have.
    Other(String),
}

impl core::fmt::Display for BuildError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Library(e) => write!(f, "{e}"),
            Self::Other(why) => f.write_str(why),
        }
    }
}

/// An `RlsModel` with S state, A command and E extra regressors.
pub fn build_model(
    s: usize,
    a: usize,
    e: usize,
    config: ModelConfig,
) -> Result<Box<dyn DynModel>, BuildError> {
    match model_sizes(s, a, e, &ModelWork::Build(config)) {
        Some(Ok(m)) => Ok(m),
        Some(Err(Ok(e))) => Err(BuildError::Library(e)),
        Some(Err(Err(e))) => Err(BuildError::Other(e.to_string())),
        None => Err(BuildError::Other(format!(
            "state_dim {s}, action_dim {a}, features {e}: the package compiles state_dim 1 to \
             {MAX_STATE}, action_dim 1 to {MAX_ACTION}, features one of {EXTRA_FEATURES:?}"
        ))),
    }
}

/// The model in a record of any compiled sizes.
pub fn load_model(bytes: &[u8]) -> Result<Box<dyn DynModel>, RecordError> {
    let work = ModelWork::Load(bytes);
    for s in 1..=MAX_STATE {
        for a in 1..=MAX_ACTION {
            for e in EXTRA_FEATURES {
                match model_sizes(s, a, e, &work) {
                    Some(Ok(m)) => return Ok(m),
                    Some(Err(Err(RecordError::Shape))) | None => {}
                    Some(Err(Err(e))) => return Err(e),
                    Some(Err(Ok(_))) => return Err(RecordError::Shape),
                }
            }
        }
    }
    Err(RecordError::Shape)
}

// ---------------------------------------------------------------------------------------
// ModelBased at any compiled dimension.

/// The optimizers a learner can use as its fallback and its inner search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Search {
    /// `CoordinateSearch<N>` with this configuration.
    Coordinate(CoordinateConfig),
    /// `Cmaes<N, λ>` with this configuration.
    Cmaes(CmaesConfig),
}

impl Search {
    /// The names Python uses.
    pub const NAMES: [&'static str; 2] = ["coordinate", "cmaes"];

    /// The search called `name` with the fields of the JSON object `json` over the default
    /// configuration.
    pub fn parse(name: &str, json: &str) -> Result<Self, BuildError> {
        // Checked here, so that an inner search's bad field is refused at construction
        // rather than at the first proposal.
        let config = |e: crate::dispatch::BuildError| BuildError::Other(e.to_string());
        match name {
            "coordinate" => {
                let c: CoordinateConfig =
                    configured(CoordinateConfig::DEFAULT, json).map_err(config)?;
                c.validate().map_err(BuildError::Library)?;
                Ok(Self::Coordinate(c))
            }
            "cmaes" => {
                let c: CmaesConfig = configured(CmaesConfig::DEFAULT, json).map_err(config)?;
                c.validate().map_err(BuildError::Library)?;
                Ok(Self::Cmaes(c))
            }
            other => Err(BuildError::Other(format!(
                "unknown search `{other}` (one of: {})",
                Self::NAMES.join(", ")
            ))),
        }
    }

    /// Its name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Coordinate(_) => "coordinate",
            Self::Cmaes(_) => "cmaes",
        }
    }
}

/// The model's cost of θ and its uncertainty about θ (0 for a point prediction; a
/// non-finite cost where the model cannot say); `Err` stops the proposal (the caller's
/// prediction failed): it is not called again and the inner search asks no more.
pub type Predict<'a> = dyn FnMut(&[f32]) -> Result<Prediction, Error> + 'a;

/// A proposal as plain values: θ, and the model's prediction when the model proposed it
/// (`None` from the fallback).
pub type Proposed = (Vec<f32>, Option<f32>);

/// A `ModelBased<F, N>` of any compiled fallback and dimension.
pub trait DynLearner: Send + Sync {
    /// N.
    fn dimension(&self) -> usize;
    /// The fallback's name.
    fn fallback(&self) -> &'static str;
    /// `ModelBased::propose_bounded` with `inner` as the inner search (with point
    /// predictions and any `uncertainty_weight`, or with a zero weight, `ModelBased::propose`).
    /// After an `Err` from `predict` the inner search stops: the learner is then in an
    /// unspecified state, for the caller to restore.
    fn propose(
        &mut self,
        rng: &mut Xoshiro128PlusPlus,
        inner: Search,
        predict: &mut Predict<'_>,
    ) -> Result<Proposed, Error>;
    /// `ModelBased::tell`.
    fn tell(&mut self, cost: f32) -> Result<(), Error>;
    /// `ModelBased::record`.
    fn record(&mut self, theta: &[f32], cost: f32) -> Result<(), Error>;
    /// `ModelBased::set_reference`.
    fn set_reference(&mut self, cost: f32) -> Result<(), Error>;
    /// `ModelBased::best`.
    fn best(&self) -> Option<(Vec<f32>, f32)>;
    /// `ModelBased::pending`.
    fn pending(&self) -> Option<Proposed>;
    /// `ModelBased::prediction_error`.
    fn prediction_error(&self) -> f32;
    /// `ModelBased::radius`.
    fn radius(&self) -> f32;
    /// `ModelBased::evaluations`.
    fn evaluations(&self) -> u32;
    /// `ModelBased::stalled`.
    fn stalled(&self) -> u32;
    /// `ModelBased::restarts`.
    fn restarts(&self) -> u32;
    /// `ModelBased::config`.
    fn config(&self) -> ModelBasedConfig;
    /// The box.
    fn bounds(&self) -> (Vec<f32>, Vec<f32>);
    /// The record of `ModelBased<F, N>`.
    fn save(&self) -> Result<Vec<u8>, RecordError>;
    /// A copy.
    fn boxed_clone(&self) -> Box<dyn DynLearner>;
}

/// The fallbacks' names.
pub trait Named {
    /// `coordinate` or `cmaes`.
    const NAME: &'static str;
}

impl<const N: usize> Named for CoordinateSearch<N> {
    const NAME: &'static str = "coordinate";
}

impl<const N: usize, const L: usize> Named for Cmaes<N, L> {
    const NAME: &'static str = "cmaes";
}

/// An inner search that stops (asks [`Error::Stopped`]) once `stopped` is set, and is
/// otherwise `search` itself.
struct Stoppable<'a, O> {
    search: O,
    stopped: &'a Cell<bool>,
}

impl<const N: usize, O: Optimizer<N>> Optimizer<N> for Stoppable<'_, O> {
    fn ask<R: RngCore + ?Sized>(&mut self, rng: &mut R) -> Result<Vector<N>, Error> {
        if self.stopped.get() {
            return Err(Error::Stopped);
        }
        self.search.ask(rng)
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        self.search.tell(cost)
    }

    fn best(&self) -> Option<ctrl_adapt::optimizer::Best<N>> {
        self.search.best()
    }

    fn pending(&self) -> Option<&Vector<N>> {
        self.search.pending()
    }

    fn evaluations(&self) -> u32 {
        self.search.evaluations()
    }

    fn status(&self) -> ctrl_adapt::optimizer::Status {
        self.search.status()
    }

    fn bounds(&self) -> &Bounds<N> {
        self.search.bounds()
    }
}

/// `ModelBased<F, N>` beside the CMA-ES population `L` its inner CMA-ES uses.
#[derive(Clone)]
struct Learner<F, const N: usize, const L: usize>(ModelBased<F, N>);

fn proposed<const N: usize>(p: &Proposal<N>) -> Proposed {
    let predicted = match p.source {
        Source::Model(c) => Some(c),
        Source::Fallback => None,
    };
    (p.theta.as_slice().to_vec(), predicted)
}

impl<F, const N: usize, const L: usize> DynLearner for Learner<F, N, L>
where
    F: Optimizer<N> + Persistent + Named + Clone + Send + Sync + 'static,
{
    fn dimension(&self) -> usize {
        N
    }

    fn fallback(&self) -> &'static str {
        F::NAME
    }

    fn propose(
        &mut self,
        rng: &mut Xoshiro128PlusPlus,
        inner: Search,
        predict: &mut Predict<'_>,
    ) -> Result<Proposed, Error> {
        // The first failure of `predict` stops the inner search (its remaining
        // `inner_evaluations` would each be a refused prediction) and further predictions.
        let stopped = Cell::new(false);
        let mut predict = |theta: &Vector<N>| {
            if stopped.get() {
                return Err(Error::Stopped);
            }
            let p = predict(theta.as_slice());
            stopped.set(p.is_err());
            p
        };
        let proposal = match inner {
            Search::Coordinate(c) => self.0.propose_bounded(
                rng,
                |b, start| {
                    CoordinateSearch::try_new(b, start, c).map(|search| Stoppable {
                        search,
                        stopped: &stopped,
                    })
                },
                &mut predict,
            ),
            Search::Cmaes(c) => self.0.propose_bounded(
                rng,
                |b, start| {
                    Cmaes::<N, L>::try_new(b, start, c).map(|search| Stoppable {
                        search,
                        stopped: &stopped,
                    })
                },
                &mut predict,
            ),
        }?;
        Ok(proposed(&proposal))
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        self.0.tell(cost)
    }

    fn record(&mut self, theta: &[f32], cost: f32) -> Result<(), Error> {
        self.0.record(Vector::from_column_slice(theta), cost)
    }

    fn set_reference(&mut self, cost: f32) -> Result<(), Error> {
        self.0.set_reference(cost)
    }

    fn best(&self) -> Option<(Vec<f32>, f32)> {
        self.0.best().map(|b| (b.theta.as_slice().to_vec(), b.cost))
    }

    fn pending(&self) -> Option<Proposed> {
        self.0.pending().map(proposed)
    }

    fn prediction_error(&self) -> f32 {
        self.0.prediction_error()
    }

    fn radius(&self) -> f32 {
        self.0.radius()
    }

    fn evaluations(&self) -> u32 {
        self.0.evaluations()
    }

    fn stalled(&self) -> u32 {
        self.0.stalled()
    }

    fn restarts(&self) -> u32 {
        self.0.restarts()
    }

    fn config(&self) -> ModelBasedConfig {
        *self.0.config()
    }

    fn bounds(&self) -> (Vec<f32>, Vec<f32>) {
        let b = self.0.fallback().bounds();
        (b.lower().as_slice().to_vec(), b.upper().as_slice().to_vec())
    }

    fn save(&self) -> Result<Vec<u8>, RecordError> {
        record_of(&self.0)
    }

    fn boxed_clone(&self) -> Box<dyn DynLearner> {
        Box::new(self.clone())
    }
}

/// What to do at dimension N: build, or load a record of the fallback named.
enum LearnerWork<'a> {
    Build {
        lower: &'a [f32],
        upper: &'a [f32],
        start: Option<&'a [f32]>,
        fallback: Search,
        config: ModelBasedConfig,
    },
    Load(&'a [u8], &'static str),
}

fn learner_at<const N: usize, const L: usize>(
    work: &LearnerWork<'_>,
) -> Result<Box<dyn DynLearner>, Result<Error, RecordError>> {
    match work {
        LearnerWork::Build {
            lower,
            upper,
            start,
            fallback,
            config,
        } => {
            let bounds = Bounds::<N>::try_new(
                Vector::from_column_slice(lower),
                Vector::from_column_slice(upper),
            )
            .map_err(Ok)?;
            let start = match start {
                Some(s) => Vector::<N>::from_column_slice(s),
                None => bounds.lower() * 0.5 + bounds.upper() * 0.5,
            };
            match fallback {
                Search::Coordinate(c) => {
                    let f = CoordinateSearch::try_new(bounds, start, *c).map_err(Ok)?;
                    let l = ModelBased::try_new(bounds, f, *config).map_err(Ok)?;
                    Ok(Box::new(Learner::<_, N, L>(l)))
                }
                Search::Cmaes(c) => {
                    let f = Cmaes::<N, L>::try_new(bounds, start, *c).map_err(Ok)?;
                    let l = ModelBased::try_new(bounds, f, *config).map_err(Ok)?;
                    Ok(Box::new(Learner::<_, N, L>(l)))
                }
            }
        }
        LearnerWork::Load(bytes, "coordinate") => {
            let l = record::load::<ModelBased<CoordinateSearch<N>, N>>(bytes).map_err(Err)?;
            Ok(Box::new(Learner::<_, N, L>(l)))
        }
        LearnerWork::Load(bytes, _) => {
            let l = record::load::<ModelBased<Cmaes<N, L>, N>>(bytes).map_err(Err)?;
            Ok(Box::new(Learner::<_, N, L>(l)))
        }
    }
}

/// The dimensions compiled for the learner, with the CMA-ES population of each
/// (λ = 4 + ⌊3 ln n⌋, written out; a test checks it against the library's rule).
macro_rules! learner_dimension {
    ($n:expr, $work:expr) => {
        match $n {
            1 => Some(learner_at::<1, 4>($work)),
            2 => Some(learner_at::<2, 6>($work)),
            3 => Some(learner_at::<3, 7>($work)),
            4 => Some(learner_at::<4, 8>($work)),
            5 => Some(learner_at::<5, 8>($work)),
            6 => Some(learner_at::<6, 9>($work)),
            7 => Some(learner_at::<7, 9>($work)),
            8 => Some(learner_at::<8, 10>($work)),
            _ => None,
        }
    };
}

/// The CMA-ES population compiled at dimension `n` (for the Rust type's name).
pub fn learner_population(n: usize) -> usize {
    // ⌊3 ln n⌋ as the table writes it out.
    const TABLE: [usize; MAX_LEARNER_DIMENSION] = [4, 6, 7, 8, 8, 9, 9, 10];
    TABLE[n.clamp(1, MAX_LEARNER_DIMENSION) - 1]
}

/// A learner over [`lower`, `upper`] with `fallback`.
pub fn build_learner(
    lower: &[f32],
    upper: &[f32],
    start: Option<&[f32]>,
    fallback: Search,
    config: ModelBasedConfig,
) -> Result<Box<dyn DynLearner>, BuildError> {
    let n = lower.len();
    if upper.len() != n || start.is_some_and(|s| s.len() != n) {
        return Err(BuildError::Other(format!(
            "lower has {n} values, upper {}{}",
            upper.len(),
            start.map_or(String::new(), |s| format!(", start {}", s.len()))
        )));
    }
    let work = LearnerWork::Build {
        lower,
        upper,
        start,
        fallback,
        config,
    };
    match learner_dimension!(n, &work) {
        Some(Ok(l)) => Ok(l),
        Some(Err(Ok(e))) => Err(BuildError::Library(e)),
        Some(Err(Err(e))) => Err(BuildError::Other(e.to_string())),
        None => Err(BuildError::Other(format!(
            "{n} parameters: the package compiles the model-based learner for 1 to \
             {MAX_LEARNER_DIMENSION}"
        ))),
    }
}

/// The learner in a record of any compiled dimension and fallback.
pub fn load_learner(bytes: &[u8]) -> Result<Box<dyn DynLearner>, RecordError> {
    for n in 1..=MAX_LEARNER_DIMENSION {
        for fallback in Search::NAMES {
            match learner_dimension!(n, &LearnerWork::Load(bytes, fallback)) {
                Some(Ok(l)) => return Ok(l),
                Some(Err(Err(RecordError::Shape))) | None => {}
                Some(Err(Err(e))) => return Err(e),
                Some(Err(Ok(_))) => return Err(RecordError::Shape),
            }
        }
    }
    Err(RecordError::Shape)
}

/// The Rust type of a learner.
pub fn learner_type(fallback: &str, n: usize) -> String {
    match fallback {
        "coordinate" => format!("ModelBased<CoordinateSearch<{n}>, {n}>"),
        _ => format!("ModelBased<Cmaes<{n}, {}>, {n}>", learner_population(n)),
    }
}
