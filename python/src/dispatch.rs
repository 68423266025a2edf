//! The library's const-generic optimizers reached at a dimension chosen at run time.
//!
//! Python cannot name `CoordinateSearch<18>`: the dimension arrives as a number. Every
//! algorithm is therefore compiled once per dimension from 1 to [`MAX_DIMENSION`], and
//! [`build`] picks the instance (a `match` over the dimension, written out by a macro). The
//! object behind the [`Dynamic`] trait *is* the firmware's type, so for the same seed,
//! configuration and costs it proposes the same candidates bit for bit, and its record is
//! the record the firmware type loads ([`Dynamic::save`], [`load`]).
//!
//! The sizes other than the dimension are fixed per algorithm, at the library's
//! recommendations ([`rust_type`] names the exact type, for the firmware to declare):
//!
//! | name | Rust type at dimension n |
//! | --- | --- |
//! | `coordinate` | `CoordinateSearch<n>` |
//! | `sracos` | `Sracos<n>` (ZOOpt's default set sizes) |
//! | `cem` | `DiagonalCem<n, 10, 5>` |
//! | `crs` | `ControlledRandomSearch<n, {10(n + 1)}>` (Price's set size) |
//! | `two-phase` | `TwoPhase<ControlledRandomSearch<n, {10(n + 1)}>, n>` |
//! | `cmaes` | `Cmaes<n, λ>`, λ = 4 + ⌊3 ln n⌋ ([`default_population`]) |
//! | `rockstar` | `Rockstar<n, {5n}>` (its recommended memory) |
//! | `linebo` | `LineBo<n, 64>` |
//!
//! Each is held in an [`InFlight`] with room for [`IN_FLIGHT`] candidates, for Python's
//! `suggest`/`report`: its record is the optimizer's own while nothing is in flight (the
//! firmware type loads it), the `InFlight`'s with tickets outstanding ([`load`] reads
//! both).

use ctrl_adapt::optimizer::cmaes::default_population;
use ctrl_adapt::optimizer::{
    Best, CemConfig, Cmaes, CmaesConfig, ControlledRandomSearch, CoordinateConfig,
    CoordinateSearch, CrsConfig, DiagonalCem, Generation, InFlight, LineBo, LineBoConfig,
    Optimizer, Rockstar, RockstarConfig, Sracos, SracosConfig, Status, Ticket, TwoPhase,
};
use ctrl_adapt::record::{self, Persistent, RecordError};
use ctrl_adapt::{Bounds, Error, Vector};
use rand_xoshiro::Xoshiro128PlusPlus;
use serde::Serialize;
use serde::de::DeserializeOwned;

pub use ctrl_adapt_python_hot::{
    CEM_ELITES, CEM_SAMPLES, IN_FLIGHT, LINE_BO_MEMORY, MAX_DIMENSION,
};
use ctrl_adapt_python_hot::{Steps, every_dimension};

/// The algorithms, by the names Python uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Algorithm {
    /// `CoordinateSearch`.
    Coordinate,
    /// `Sracos`.
    Sracos,
    /// `DiagonalCem`.
    Cem,
    /// `ControlledRandomSearch`.
    Crs,
    /// `TwoPhase` over a controlled random search.
    TwoPhase,
    /// `Cmaes`.
    Cmaes,
    /// `Rockstar`.
    Rockstar,
    /// `LineBo`.
    LineBo,
}

impl Algorithm {
    /// Every algorithm, in the order of the module table.
    pub const ALL: [Self; 8] = [
        Self::Coordinate,
        Self::Sracos,
        Self::Cem,
        Self::Crs,
        Self::TwoPhase,
        Self::Cmaes,
        Self::Rockstar,
        Self::LineBo,
    ];

    /// The name Python uses.
    pub fn name(self) -> &'static str {
        match self {
            Self::Coordinate => "coordinate",
            Self::Sracos => "sracos",
            Self::Cem => "cem",
            Self::Crs => "crs",
            Self::TwoPhase => "two-phase",
            Self::Cmaes => "cmaes",
            Self::Rockstar => "rockstar",
            Self::LineBo => "linebo",
        }
    }

    /// The algorithm called `name`.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|a| a.name() == name)
    }
}

/// The exact Rust type of `algorithm` at dimension `n` (module table).
pub fn rust_type(algorithm: Algorithm, n: usize) -> String {
    let crs = format!("ControlledRandomSearch<{n}, {}>", 10 * (n + 1));
    match algorithm {
        Algorithm::Coordinate => format!("CoordinateSearch<{n}>"),
        Algorithm::Sracos => format!("Sracos<{n}>"),
        Algorithm::Cem => format!("DiagonalCem<{n}, {CEM_SAMPLES}, {CEM_ELITES}>"),
        Algorithm::Crs => crs,
        Algorithm::TwoPhase => format!("TwoPhase<{crs}, {n}>"),
        Algorithm::Cmaes => match compiled_population(n) {
            Some(lambda) => format!("Cmaes<{n}, {lambda}>"),
            None => format!("Cmaes<{n}, {}>", default_population(n)),
        },
        Algorithm::Rockstar => format!("Rockstar<{n}, {}>", 5 * n),
        Algorithm::LineBo => format!("LineBo<{n}, {LINE_BO_MEMORY}>"),
    }
}

/// Why an optimizer could not be built.
#[derive(Debug, Clone, PartialEq)]
pub enum BuildError {
    /// The library refused a value (its message names the field).
    Library(Error),
    /// The dimension is outside 1..=[`MAX_DIMENSION`], or the vectors disagree with it.
    Dimension(String),
    /// The configuration does not decode (an unknown field, a wrong type).
    Config(String),
}

impl core::fmt::Display for BuildError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Library(e) => write!(f, "{e}"),
            Self::Dimension(s) | Self::Config(s) => f.write_str(s),
        }
    }
}

impl From<Error> for BuildError {
    fn from(e: Error) -> Self {
        Self::Library(e)
    }
}

/// What to build: the algorithm, the box, the start (for the algorithms that take one;
/// the box's centre when `None`) and the configuration as a JSON object whose fields
/// override the algorithm's `DEFAULT` configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Spec<'a> {
    /// The algorithm.
    pub algorithm: Algorithm,
    /// Lower bounds, one per parameter.
    pub lower: &'a [f32],
    /// Upper bounds, one per parameter.
    pub upper: &'a [f32],
    /// θ⁰.
    pub start: Option<&'a [f32]>,
    /// The configuration's fields to change, a JSON object (`{}` for the defaults). For
    /// `two-phase`: `{"global": {CrsConfig fields}, "global_budget": 150, "local":
    /// {CoordinateConfig fields}}`.
    pub config: &'a str,
}

/// An optimizer of any algorithm and dimension, with the calls Python needs. Costs and
/// candidates are the library's `f32`.
pub trait Dynamic: Send + Sync {
    /// The dimension n.
    fn dimension(&self) -> usize;
    /// The next candidate.
    fn ask(&mut self, rng: &mut Xoshiro128PlusPlus) -> Result<Vec<f32>, Error>;
    /// The pending candidate's cost.
    fn tell(&mut self, cost: f32) -> Result<(), Error>;
    /// The best candidate told so far and its cost.
    fn best(&self) -> Option<(Vec<f32>, f32)>;
    /// The candidate asked and not yet told.
    fn pending(&self) -> Option<Vec<f32>>;
    /// What to deploy: the model's estimate of the minimum where the algorithm keeps one
    /// ([`Recommend`]), else the best candidate told (`None` before any).
    fn recommend(&self) -> Option<Vec<f32>>;
    /// Costs told so far.
    fn evaluations(&self) -> u32;
    /// Running, converged or out of budget.
    fn status(&self) -> Status;
    /// A candidate and its ticket, `None` while nothing more can be handed out.
    fn suggest(&mut self, rng: &mut Xoshiro128PlusPlus) -> Result<Option<(u32, Vec<f32>)>, Error>;
    /// The pending candidate (a start) under a ticket ([`InFlight::adopt_pending`]).
    fn adopt_pending(&mut self) -> Option<(u32, Vec<f32>)>;
    /// The cost of a ticket's candidate.
    fn report(&mut self, ticket: u32, cost: f32) -> Result<(), Error>;
    /// Gives a ticket back: its candidate is handed out again.
    fn cancel(&mut self, ticket: u32) -> Result<(), Error>;
    /// The outstanding tickets, in hand-out order.
    fn in_flight(&self) -> Vec<u32>;
    /// Whether nothing is in flight: no ticket out, no cancelled candidate waiting, every
    /// reported cost told (then [`Dynamic::save`] writes the firmware type's record).
    fn idle(&self) -> bool;
    /// How many more `suggest` calls return a candidate now.
    fn capacity(&self) -> usize;
    /// The most candidates the optimizer can ever have in flight.
    fn max_in_flight(&self) -> usize;
    /// The state as a record ([`ctrl_adapt::record`]): of its Rust type while nothing is
    /// in flight, of `InFlight<T, n, IN_FLIGHT>` otherwise.
    fn save(&self) -> Result<Vec<u8>, RecordError>;
    /// Another object in the same state.
    fn boxed_clone(&self) -> Box<dyn Dynamic>;
}

/// The point an algorithm's model recommends deploying, apart from the best candidate
/// measured: a sampling distribution's mean (CEM, CMA-ES), ROCK*'s θ*, LineBo's posterior
/// minimum. `None` for the algorithms without such a model (their best candidate is it).
pub trait Recommend<const N: usize> {
    /// The recommended θ, in parameter units.
    fn recommend(&self) -> Option<Vector<N>> {
        None
    }
}

impl<const N: usize> Recommend<N> for CoordinateSearch<N> {}
impl<const N: usize> Recommend<N> for Sracos<N> {}
impl<const N: usize, const S: usize> Recommend<N> for ControlledRandomSearch<N, S> {}
impl<const N: usize, const S: usize> Recommend<N> for TwoPhase<ControlledRandomSearch<N, S>, N> {}

impl<const N: usize, const S: usize, const E: usize> Recommend<N> for DiagonalCem<N, S, E> {
    fn recommend(&self) -> Option<Vector<N>> {
        Some(*self.mean())
    }
}

impl<const N: usize, const L: usize> Recommend<N> for Cmaes<N, L> {
    fn recommend(&self) -> Option<Vector<N>> {
        Some(self.mean())
    }
}

impl<const N: usize, const M: usize> Recommend<N> for Rockstar<N, M> {
    fn recommend(&self) -> Option<Vector<N>> {
        Some(self.theta_star())
    }
}

impl<const N: usize, const M: usize> Recommend<N> for LineBo<N, M> {
    fn recommend(&self) -> Option<Vector<N>> {
        Some(self.origin())
    }
}

/// An optimizer of dimension `N` behind [`Dynamic`], with room for [`IN_FLIGHT`]
/// candidates in flight.
#[derive(Clone)]
struct Held<O, const N: usize>(InFlight<O, N, IN_FLIGHT>);

/// `value`'s record, in a buffer grown until it fits: the record is at most the postcard
/// encoding (never longer than the in-memory size for these types, plus varint slack) and
/// a header.
pub(crate) fn record_of<T: Persistent>(value: &T) -> Result<Vec<u8>, RecordError> {
    let mut room = core::mem::size_of::<T>() * 2 + 256;
    loop {
        let mut buf = vec![0u8; room];
        match record::save(value, &mut buf) {
            Ok(bytes) => return Ok(bytes.to_vec()),
            Err(RecordError::BufferTooSmall) if room < (1 << 26) => room *= 2,
            Err(e) => return Err(e),
        }
    }
}

impl<O, const N: usize> Dynamic for Held<O, N>
where
    O: Generation<N> + Recommend<N> + Persistent + Clone + Send + Sync + 'static,
    InFlight<O, N, IN_FLIGHT>: Steps<N>,
{
    fn dimension(&self) -> usize {
        N
    }

    fn ask(&mut self, rng: &mut Xoshiro128PlusPlus) -> Result<Vec<f32>, Error> {
        self.0.step_ask(rng).map(|theta| theta.as_slice().to_vec())
    }

    fn tell(&mut self, cost: f32) -> Result<(), Error> {
        self.0.step_tell(cost)
    }

    fn best(&self) -> Option<(Vec<f32>, f32)> {
        self.0
            .best()
            .map(|Best { theta, cost }| (theta.as_slice().to_vec(), cost))
    }

    fn recommend(&self) -> Option<Vec<f32>> {
        match self.0.optimizer().recommend() {
            Some(theta) => Some(theta.as_slice().to_vec()),
            None => self.best().map(|(theta, _)| theta),
        }
    }

    fn pending(&self) -> Option<Vec<f32>> {
        self.0.pending().map(|theta| theta.as_slice().to_vec())
    }

    fn evaluations(&self) -> u32 {
        self.0.evaluations()
    }

    fn status(&self) -> Status {
        self.0.status()
    }

    fn suggest(&mut self, rng: &mut Xoshiro128PlusPlus) -> Result<Option<(u32, Vec<f32>)>, Error> {
        Ok(self
            .0
            .step_suggest(rng)?
            .map(|(ticket, theta)| (ticket.get(), theta.as_slice().to_vec())))
    }

    fn adopt_pending(&mut self) -> Option<(u32, Vec<f32>)> {
        self.0
            .adopt_pending()
            .map(|(ticket, theta)| (ticket.get(), theta.as_slice().to_vec()))
    }

    fn report(&mut self, ticket: u32, cost: f32) -> Result<(), Error> {
        self.0.step_report(Ticket::new(ticket), cost)
    }

    fn cancel(&mut self, ticket: u32) -> Result<(), Error> {
        self.0.cancel(Ticket::new(ticket))
    }

    fn in_flight(&self) -> Vec<u32> {
        self.0.in_flight().map(Ticket::get).collect()
    }

    fn idle(&self) -> bool {
        self.0.idle()
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }

    fn max_in_flight(&self) -> usize {
        self.0.max_in_flight()
    }

    fn save(&self) -> Result<Vec<u8>, RecordError> {
        if self.0.idle() {
            record_of(self.0.optimizer())
        } else {
            record_of(&self.0)
        }
    }

    fn boxed_clone(&self) -> Box<dyn Dynamic> {
        Box::new(self.clone())
    }
}

/// `default` with the fields of the JSON object `json` put over it.
pub(crate) fn configured<C: Serialize + DeserializeOwned>(
    default: C,
    json: &str,
) -> Result<C, BuildError> {
    let bad = |e: serde_json::Error| BuildError::Config(format!("configuration: {e}"));
    let mut value = serde_json::to_value(default).map_err(bad)?;
    let given: serde_json::Value = serde_json::from_str(json).map_err(bad)?;
    let (Some(fields), serde_json::Value::Object(given)) = (value.as_object_mut(), given) else {
        return Err(BuildError::Config(
            "configuration: expected an object of field names and values".into(),
        ));
    };
    for (key, v) in given {
        let Some(slot) = fields.get_mut(&key) else {
            let mut known: Vec<&str> = fields.keys().map(String::as_str).collect();
            known.sort_unstable();
            return Err(BuildError::Config(format!(
                "configuration: unknown field `{key}` (fields: {})",
                known.join(", ")
            )));
        };
        *slot = v;
    }
    serde_json::from_value(value).map_err(bad)
}

/// The `two-phase` configuration: `{"global", "global_budget", "local"}`.
fn two_phase_config(json: &str) -> Result<(CrsConfig, u32, CoordinateConfig), BuildError> {
    #[derive(serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct TwoPhaseJson {
        #[serde(default)]
        global: Option<serde_json::Value>,
        global_budget: Option<u32>,
        #[serde(default)]
        local: Option<serde_json::Value>,
    }
    let parsed: TwoPhaseJson = serde_json::from_str(json)
        .map_err(|e| BuildError::Config(format!("configuration: {e}")))?;
    let part = |v: Option<serde_json::Value>| v.map_or_else(|| "{}".to_string(), |v| v.to_string());
    Ok((
        configured(CrsConfig::DEFAULT, &part(parsed.global))?,
        parsed.global_budget.unwrap_or(150),
        configured(CoordinateConfig::DEFAULT, &part(parsed.local))?,
    ))
}

fn vector<const N: usize>(values: &[f32], name: &str) -> Result<Vector<N>, BuildError> {
    if values.len() != N {
        return Err(BuildError::Dimension(format!(
            "{name} has {} values, the bounds {N}",
            values.len()
        )));
    }
    Ok(Vector::from_column_slice(values))
}

fn held<O, const N: usize>(o: O) -> Box<dyn Dynamic>
where
    O: Generation<N> + Recommend<N> + Persistent + Clone + Send + Sync + 'static,
    InFlight<O, N, IN_FLIGHT>: Steps<N>,
{
    Box::new(Held::<O, N>(InFlight::new(o)))
}

/// Loads `bytes` as the record of `O` or, saved with tickets outstanding, of
/// `InFlight<O, N, IN_FLIGHT>`.
fn held_record<O, const N: usize>(bytes: &[u8]) -> Result<Box<dyn Dynamic>, RecordError>
where
    O: Generation<N> + Recommend<N> + Persistent + Clone + Send + Sync + 'static,
    InFlight<O, N, IN_FLIGHT>: Steps<N>,
{
    match record::load::<O>(bytes) {
        Ok(o) => Ok(held(o)),
        Err(RecordError::Shape) => {
            let flight = record::load::<InFlight<O, N, IN_FLIGHT>>(bytes)?;
            Ok(Box::new(Held(flight)))
        }
        Err(e) => Err(e),
    }
}

/// The instances at dimension `N`: `CRS` = 10(N + 1), `LAMBDA` = the CMA-ES population,
/// `MEMORY` = 5N (ROCK*'s rollouts). Their steps are compiled in `python/hot` (the bounds).
struct At<const N: usize, const CRS: usize, const LAMBDA: usize, const MEMORY: usize>;

impl<const N: usize, const CRS: usize, const LAMBDA: usize, const MEMORY: usize>
    At<N, CRS, LAMBDA, MEMORY>
where
    InFlight<CoordinateSearch<N>, N, IN_FLIGHT>: Steps<N>,
    InFlight<Sracos<N>, N, IN_FLIGHT>: Steps<N>,
    InFlight<DiagonalCem<N, CEM_SAMPLES, CEM_ELITES>, N, IN_FLIGHT>: Steps<N>,
    InFlight<ControlledRandomSearch<N, CRS>, N, IN_FLIGHT>: Steps<N>,
    InFlight<TwoPhase<ControlledRandomSearch<N, CRS>, N>, N, IN_FLIGHT>: Steps<N>,
    InFlight<Cmaes<N, LAMBDA>, N, IN_FLIGHT>: Steps<N>,
    InFlight<LineBo<N, LINE_BO_MEMORY>, N, IN_FLIGHT>: Steps<N>,
{
    /// Builds `spec`.
    fn build(spec: &Spec<'_>) -> Result<Box<dyn Dynamic>, BuildError> {
        let bounds =
            Bounds::<N>::try_new(vector(spec.lower, "lower")?, vector(spec.upper, "upper")?)?;
        // SRACOS, CRS and two-phase sample the box: a given start is their first sample.
        let first = match spec.start {
            Some(start) => Some(vector::<N>(start, "start")?),
            None => None,
        };
        let start = match first {
            Some(start) => start,
            // Halves first: `(lower + upper) * 0.5` overflows f32 for bounds near its
            // limits (the same value otherwise, halving being exact).
            None => bounds.lower() * 0.5 + bounds.upper() * 0.5,
        };
        let crs = |config: CrsConfig| match first {
            Some(start) => ControlledRandomSearch::<N, CRS>::try_with_start(bounds, config, start),
            None => ControlledRandomSearch::<N, CRS>::try_new(bounds, config),
        };
        let json = spec.config;
        Ok(match spec.algorithm {
            Algorithm::Coordinate => held(CoordinateSearch::<N>::try_new(
                bounds,
                start,
                configured(CoordinateConfig::DEFAULT, json)?,
            )?),
            Algorithm::Sracos => {
                let config = configured(SracosConfig::DEFAULT, json)?;
                held(match first {
                    Some(start) => Sracos::<N>::try_with_start(bounds, config, start)?,
                    None => Sracos::<N>::try_new(bounds, config)?,
                })
            }
            Algorithm::Cem => held(DiagonalCem::<N, CEM_SAMPLES, CEM_ELITES>::try_new(
                bounds,
                start,
                configured(CemConfig::DEFAULT, json)?,
            )?),
            Algorithm::Crs => held(crs(configured(CrsConfig::DEFAULT, json)?)?),
            Algorithm::TwoPhase => {
                let (global, budget, local) = two_phase_config(json)?;
                held(TwoPhase::try_new(crs(global)?, budget, local)?)
            }
            Algorithm::Cmaes => held(Cmaes::<N, LAMBDA>::try_new(
                bounds,
                start,
                configured(CmaesConfig::DEFAULT, json)?,
            )?),
            Algorithm::Rockstar => held(Rockstar::<N, MEMORY>::try_new(
                bounds,
                start,
                configured(RockstarConfig::DEFAULT, json)?,
            )?),
            Algorithm::LineBo => held(LineBo::<N, LINE_BO_MEMORY>::try_new(
                bounds,
                start,
                configured(LineBoConfig::DEFAULT, json)?,
            )?),
        })
    }

    /// Loads a record of `algorithm`.
    fn load(algorithm: Algorithm, bytes: &[u8]) -> Result<Box<dyn Dynamic>, RecordError> {
        match algorithm {
            Algorithm::Coordinate => held_record::<CoordinateSearch<N>, N>(bytes),
            Algorithm::Sracos => held_record::<Sracos<N>, N>(bytes),
            Algorithm::Cem => held_record::<DiagonalCem<N, CEM_SAMPLES, CEM_ELITES>, N>(bytes),
            Algorithm::Crs => held_record::<ControlledRandomSearch<N, CRS>, N>(bytes),
            Algorithm::TwoPhase => {
                held_record::<TwoPhase<ControlledRandomSearch<N, CRS>, N>, N>(bytes)
            }
            Algorithm::Cmaes => held_record::<Cmaes<N, LAMBDA>, N>(bytes),
            Algorithm::Rockstar => held_record::<Rockstar<N, MEMORY>, N>(bytes),
            Algorithm::LineBo => held_record::<LineBo<N, LINE_BO_MEMORY>, N>(bytes),
        }
    }

    /// `LAMBDA`, the CMA-ES population compiled in.
    fn population() -> usize {
        LAMBDA
    }
}

/// `Some(At::<n, 10(n + 1), λ, 5n>::$method(args))` for the dimension `$n`, `None` outside
/// 1..=[`MAX_DIMENSION`], over the table of [`every_dimension`] (λ = 4 + ⌊3 ln n⌋, written
/// out).
macro_rules! at_dimension {
    ($n:expr, $method:ident, $($arg:expr),*) => {
        every_dimension!(at_dimension_arms!($n, $method, ($($arg),*)))
    };
}

macro_rules! at_dimension_arms {
    (($n:expr, $method:ident, $args:tt); $($dim:literal $lambda:literal),+) => {
        match $n {
            $($dim => Some(At::<$dim, { 10 * ($dim + 1) }, $lambda, { 5 * $dim }>::$method $args),)+
            _ => None,
        }
    };
}

/// The CMA-ES population compiled in at dimension `n` (the table of [`every_dimension`];
/// the package's tests check it against the library's rule).
fn compiled_population(n: usize) -> Option<usize> {
    at_dimension!(n, population,)
}

/// The stack of the thread that builds, loads and copies the optimizers ([`on_large_stack`]).
/// Reserved address space, committed only as far as it is touched.
pub const LARGE_STACK: usize = 256 << 20;

/// `work` run on a thread of its own with a stack of [`LARGE_STACK`] bytes, whatever the
/// caller's thread has.
///
/// The library's constructors and `record::load` return the state by value (it is
/// `#![forbid(unsafe_code)]`, so nothing constructs it in place on the heap), and this
/// crate is compiled unoptimised (the table of instances is large; the steps are optimised
/// in `python/hot`): its frames then hold several whole copies of a state, which is up to
/// hundreds of kilobytes at n = 64 (a CRS set of 10(n + 1) points, a CMA-ES covariance,
/// LineBo's GP). Boxing the result does not remove those temporaries, and a secondary
/// thread's stack may be 512 KiB (macOS) or less: building, loading and copying therefore
/// run here, at the cost of one thread start (tens of microseconds) per call.
pub fn on_large_stack<T: Send>(work: impl FnOnce() -> T + Send) -> Result<T, String> {
    std::thread::scope(|scope| {
        let handle = std::thread::Builder::new()
            .name("ctrl-adapt-build".into())
            .stack_size(LARGE_STACK)
            .spawn_scoped(scope, work)
            .map_err(|e| format!("cannot start the thread that builds the optimizer: {e}"))?;
        handle
            .join()
            .map_err(|_| "the thread that builds the optimizer panicked".to_string())
    })
}

/// Builds `spec` at the dimension of its bounds (on a large stack: [`on_large_stack`]).
pub fn build(spec: &Spec<'_>) -> Result<Box<dyn Dynamic>, BuildError> {
    on_large_stack(|| build_here(spec)).unwrap_or_else(|e| Err(BuildError::Config(e)))
}

/// A copy of `optimizer` in the same state (on a large stack: [`on_large_stack`]).
pub fn copy(optimizer: &dyn Dynamic) -> Result<Box<dyn Dynamic>, String> {
    on_large_stack(|| optimizer.boxed_clone())
}

fn build_here(spec: &Spec<'_>) -> Result<Box<dyn Dynamic>, BuildError> {
    let n = spec.lower.len();
    at_dimension!(n, build, spec).unwrap_or_else(|| {
        Err(BuildError::Dimension(format!(
            "{n} parameters: the package is compiled for 1 to {MAX_DIMENSION}"
        )))
    })
}

/// Loads a record of any compiled algorithm and dimension: the one whose type the record
/// names (its shape), with its algorithm (on a large stack: [`on_large_stack`]; `Err(Err(why))`
/// if that thread could not run).
pub fn load(bytes: &[u8]) -> Result<(Algorithm, Box<dyn Dynamic>), Result<RecordError, String>> {
    on_large_stack(|| load_here(bytes))
        .map_err(Err)?
        .map_err(Ok)
}

fn load_here(bytes: &[u8]) -> Result<(Algorithm, Box<dyn Dynamic>), RecordError> {
    // Every other error than a mismatched shape is the record's own: report it at once.
    for n in 1..=MAX_DIMENSION {
        for algorithm in Algorithm::ALL {
            match at_dimension!(n, load, algorithm, bytes) {
                Some(Ok(o)) => return Ok((algorithm, o)),
                Some(Err(RecordError::Shape)) | None => {}
                Some(Err(e)) => return Err(e),
            }
        }
    }
    Err(RecordError::Shape)
}
