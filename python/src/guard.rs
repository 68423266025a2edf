//! The library's runtime guard ([`ctrl_adapt::controller::guard`]) as a per-tick supervisor
//! for a loop written in Python (class `ctrl_adapt._native.Guard`; the Python package wraps
//! it as `ctrl_adapt.Guard`).
//!
//! A Python user runs their own simulator loop, so the guard is not inside an adapter here:
//! each tick the loop asks [`Guard::check`](Supervisor::check) of the library's own
//! `Guard<L, T>` whether the nominal controller must run, with the state, the safety
//! signal and the running cost. The sizes are compiled in:
//!
//! - `L`, the limits: every count from 0 to [`MAX_LIMITS`], so that the record names the
//!   limits the user declared (`Guard<2, 1024>`), as firmware would declare the type;
//! - `T`, the envelope's ticks: the smallest of [`HORIZONS`] at least the horizon asked for
//!   (the envelope is bfloat16, 2 bytes a tick: 8 KiB at 4,096 ticks);
//! - the state: the guard reads it as a `Vector<MAX_STATE>` whose first coordinates are the
//!   state passed (a limit on a state coordinate beyond [`MAX_STATE`] is refused: pass that
//!   value as a signal, which has no such bound).
//!
//! Building, loading and copying run on the package's large-stack thread
//! ([`on_large_stack`]), as the optimizers' do; a tick runs on the caller's thread (it holds
//! no state by value).

use ctrl_adapt::controller::Mode;
use ctrl_adapt::controller::guard::{
    Guard, GuardConfig, GuardCounters, Limit, Source, Supervisor, Trip, TripReason, tripped_cost,
};
use ctrl_adapt::record::{self, RecordError};
use ctrl_adapt::{Error, Vector};

use crate::dispatch::on_large_stack;

/// The most limits a guard of the package holds.
pub const MAX_LIMITS: usize = 8;
/// The envelope lengths compiled in (ticks); 0 is no envelope.
pub const HORIZONS: [usize; 8] = [0, 64, 128, 256, 512, 1024, 2048, 4096];
/// The largest horizon (ticks).
pub const MAX_HORIZON: usize = 4096;
/// The state coordinates a limit can read (`Source::State(k)`, k < `MAX_STATE`).
pub const MAX_STATE: usize = 64;

/// A guard's parameters as Python passes them (sizes not yet chosen).
#[derive(Debug, Clone)]
pub struct Config {
    /// The limits, at most [`MAX_LIMITS`].
    pub limits: Vec<Limit>,
    /// The horizon asked for (ticks); rounded up to one of [`HORIZONS`].
    pub horizon: usize,
    /// `GuardConfig::limit_ticks`.
    pub limit_ticks: u32,
    /// `GuardConfig::envelope_ticks`.
    pub envelope_ticks: u32,
    /// `GuardConfig::relative_margin`.
    pub relative_margin: f32,
    /// `GuardConfig::absolute_margin`.
    pub absolute_margin: f32,
    /// `GuardConfig::margin_taper`.
    pub margin_taper: f32,
    /// `GuardConfig::tripped_cost_span`.
    pub tripped_cost_span: f32,
}

/// Why a guard cannot be built.
#[derive(Debug)]
pub enum BuildError {
    /// The library refused the configuration.
    Library(Error),
    /// A size or index outside what the package compiles, or a thread that could not run.
    Size(String),
}

impl core::fmt::Display for BuildError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Library(e) => write!(f, "{e}"),
            Self::Size(why) => f.write_str(why),
        }
    }
}

/// A `Guard<L, T>` of any compiled sizes.
pub trait DynGuard: Send + Sync {
    /// `L`.
    fn limit_count(&self) -> usize;
    /// `T`.
    fn horizon(&self) -> usize;
    /// The configuration, limits as a list.
    fn config(&self) -> Config;
    /// `Supervisor::begin`.
    fn begin(&mut self, mode: Mode);
    /// `Supervisor::check` (the running cost `cost`).
    fn check(
        &mut self,
        mode: Mode,
        tick: u32,
        state: &Vector<MAX_STATE>,
        signal: &[f32],
        cost: f32,
    ) -> bool;
    /// `Supervisor::finish`.
    fn finish(&mut self) -> (Option<Trip>, u32);
    /// The counters.
    fn counters(&self) -> GuardCounters;
    /// The envelope at every tick (`-∞` where no bare episode reached).
    fn envelope(&self) -> Vec<f32>;
    /// The threshold at every tick (`+∞` where unchecked).
    fn thresholds(&self) -> Vec<f32>;
    /// `Guard::clear_envelope`.
    fn clear_envelope(&mut self);
    /// The record of `Guard<L, T>`.
    fn save(&self) -> Result<Vec<u8>, RecordError>;
    /// A copy.
    fn boxed_clone(&self) -> Box<dyn DynGuard>;
}

impl<const L: usize, const T: usize> DynGuard for Guard<L, T> {
    fn limit_count(&self) -> usize {
        L
    }

    fn horizon(&self) -> usize {
        T
    }

    fn config(&self) -> Config {
        let c = self.config();
        Config {
            limits: c.limits.to_vec(),
            horizon: T,
            limit_ticks: c.limit_ticks,
            envelope_ticks: c.envelope_ticks,
            relative_margin: c.relative_margin,
            absolute_margin: c.absolute_margin,
            margin_taper: c.margin_taper,
            tripped_cost_span: c.tripped_cost_span,
        }
    }

    fn begin(&mut self, mode: Mode) {
        Supervisor::<MAX_STATE>::begin(self, mode);
    }

    fn check(
        &mut self,
        mode: Mode,
        tick: u32,
        state: &Vector<MAX_STATE>,
        signal: &[f32],
        cost: f32,
    ) -> bool {
        Supervisor::<MAX_STATE>::check(self, mode, tick, state, signal, || cost)
    }

    fn finish(&mut self) -> (Option<Trip>, u32) {
        Supervisor::<MAX_STATE>::finish(self)
    }

    fn counters(&self) -> GuardCounters {
        *Guard::counters(self)
    }

    fn envelope(&self) -> Vec<f32> {
        (0..T as u32)
            .map(|t| Guard::envelope(self, t).unwrap_or(f32::NEG_INFINITY))
            .collect()
    }

    fn thresholds(&self) -> Vec<f32> {
        (0..T as u32)
            .map(|t| self.threshold(t).unwrap_or(f32::INFINITY))
            .collect()
    }

    fn clear_envelope(&mut self) {
        Guard::clear_envelope(self);
    }

    fn save(&self) -> Result<Vec<u8>, RecordError> {
        // A guard is at most a few kilobytes: 2·T + 12·L + 68 bytes, and its record no
        // longer than that plus the header and varint slack.
        let mut buf = vec![0u8; core::mem::size_of::<Self>() * 2 + 256];
        record::save(self, &mut buf).map(|bytes| bytes.to_vec())
    }

    fn boxed_clone(&self) -> Box<dyn DynGuard> {
        Box::new(*self)
    }
}

/// `Guard<L, T>` of `config`.
fn make<const L: usize, const T: usize>(config: &Config) -> Result<Box<dyn DynGuard>, BuildError> {
    let limits: [Limit; L] = core::array::from_fn(|i| config.limits[i]);
    let guard = Guard::<L, T>::try_new(GuardConfig {
        limits,
        limit_ticks: config.limit_ticks,
        envelope_ticks: config.envelope_ticks,
        relative_margin: config.relative_margin,
        absolute_margin: config.absolute_margin,
        margin_taper: config.margin_taper,
        tripped_cost_span: config.tripped_cost_span,
    })
    .map_err(BuildError::Library)?;
    Ok(Box::new(guard))
}

/// Calls `$f::<L, T>($args)` for the compiled `T` equal to `$t` (`None` for another).
macro_rules! at_horizon {
    ($t:expr, $f:ident, $l:ident, ($($arg:expr),*)) => {
        match $t {
            0 => Some($f::<$l, 0>($($arg),*)),
            64 => Some($f::<$l, 64>($($arg),*)),
            128 => Some($f::<$l, 128>($($arg),*)),
            256 => Some($f::<$l, 256>($($arg),*)),
            512 => Some($f::<$l, 512>($($arg),*)),
            1024 => Some($f::<$l, 1024>($($arg),*)),
            2048 => Some($f::<$l, 2048>($($arg),*)),
            4096 => Some($f::<$l, 4096>($($arg),*)),
            _ => None,
        }
    };
}

fn make_at<const L: usize>(
    config: &Config,
    t: usize,
) -> Option<Result<Box<dyn DynGuard>, BuildError>> {
    at_horizon!(t, make, L, (config))
}

fn load_one<const L: usize, const T: usize>(
    bytes: &[u8],
) -> Result<Box<dyn DynGuard>, RecordError> {
    record::load::<Guard<L, T>>(bytes).map(|g| Box::new(g) as Box<dyn DynGuard>)
}

fn load_at<const L: usize>(
    bytes: &[u8],
    t: usize,
) -> Option<Result<Box<dyn DynGuard>, RecordError>> {
    at_horizon!(t, load_one, L, (bytes))
}

/// Calls `$f::<L>($args)` for the compiled `L` equal to `$l`.
macro_rules! at_limits {
    ($l:expr, $f:ident, ($($arg:expr),*)) => {
        match $l {
            0 => $f::<0>($($arg),*),
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            5 => $f::<5>($($arg),*),
            6 => $f::<6>($($arg),*),
            7 => $f::<7>($($arg),*),
            8 => $f::<8>($($arg),*),
            _ => None,
        }
    };
}

/// The compiled envelope length for a horizon of `ticks` (the smallest at least `ticks`).
pub fn horizon_for(ticks: usize) -> Option<usize> {
    HORIZONS.iter().copied().find(|&t| t >= ticks)
}

/// Builds the guard of `config` (on the large-stack thread).
pub fn build(config: &Config) -> Result<Box<dyn DynGuard>, BuildError> {
    let l = config.limits.len();
    if l > MAX_LIMITS {
        return Err(BuildError::Size(format!(
            "{l} limits: the package holds at most {MAX_LIMITS}"
        )));
    }
    let Some(t) = horizon_for(config.horizon) else {
        return Err(BuildError::Size(format!(
            "a horizon of {} ticks: the package's envelope holds at most {MAX_HORIZON}",
            config.horizon
        )));
    };
    for (i, limit) in config.limits.iter().enumerate() {
        if let Source::State(k) = limit.source
            && k as usize >= MAX_STATE
        {
            return Err(BuildError::Size(format!(
                "limit {i} reads state[{k}]: the guard reads the first {MAX_STATE} state \
                 coordinates; pass that value as a signal"
            )));
        }
    }
    on_large_stack(|| at_limits!(l, make_at, (config, t)))
        .map_err(BuildError::Size)?
        .unwrap_or_else(|| {
            Err(BuildError::Size(format!(
                "{l} limits, {t} ticks: not compiled"
            )))
        })
}

/// The guard a record holds, of any compiled sizes (on the large-stack thread).
pub fn load(bytes: &[u8]) -> Result<Box<dyn DynGuard>, Result<RecordError, String>> {
    on_large_stack(|| {
        for l in 0..=MAX_LIMITS {
            for t in HORIZONS {
                match at_limits!(l, load_at, (bytes, t)) {
                    Some(Ok(g)) => return Ok(g),
                    Some(Err(RecordError::Shape)) | None => {}
                    Some(Err(e)) => return Err(e),
                }
            }
        }
        Err(RecordError::Shape)
    })
    .map_err(Err)?
    .map_err(Ok)
}

/// A copy of `guard` (on the large-stack thread).
pub fn copy(guard: &dyn DynGuard) -> Result<Box<dyn DynGuard>, String> {
    on_large_stack(|| guard.boxed_clone())
}

/// The library's tripped cost with `span`, after the checks `EpisodeRunner::with_guard` makes
/// of the failure cost and the span.
pub fn told(failure_cost: f32, span: f32, tick: u32, ticks: u32) -> Result<f32, Error> {
    if !failure_cost.is_finite() {
        return Err(Error::NonFinite("failure_cost"));
    }
    let top = failure_cost + span;
    if !(top.is_finite() && top > failure_cost) {
        return Err(Error::InvalidParameter("tripped_cost_span"));
    }
    Ok(tripped_cost(failure_cost, span, tick, ticks))
}

/// The name of a trip's reason and the limit's index.
pub fn reason(trip: &Trip) -> (&'static str, Option<u16>) {
    match trip.reason {
        TripReason::Limit(i) => ("limit", Some(i)),
        TripReason::Envelope => ("envelope", None),
    }
}

// ---------------------------------------------------------------------------------------
// The Python class.

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

create_exception!(
    ctrl_adapt,
    GuardError,
    PyValueError,
    "A guard's configuration, input or call refused (the message says which)."
);

fn guard_error(e: impl core::fmt::Display) -> PyErr {
    GuardError::new_err(e.to_string())
}

/// `v` as f32, a finite `v` beyond f32 refused as `name`.
fn narrow(v: f64, name: &str) -> PyResult<f32> {
    let x = v as f32;
    if v.is_finite() && !x.is_finite() {
        return Err(guard_error(format!("{name} is outside the float32 range")));
    }
    Ok(x)
}

fn count(v: i64, name: &str) -> PyResult<u32> {
    u32::try_from(v)
        .ok()
        .filter(|&n| n >= 1)
        .ok_or_else(|| guard_error(format!("{name} must be an integer from 1 to {}", u32::MAX)))
}

fn mode_of(name: &str) -> PyResult<Mode> {
    match name {
        "learn" => Ok(Mode::Learn),
        "deploy" => Ok(Mode::Deploy),
        "nominal" => Ok(Mode::Nominal),
        other => Err(guard_error(format!(
            "unknown mode `{other}` (one of: learn, deploy, nominal)"
        ))),
    }
}

fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Learn => "learn",
        Mode::Deploy => "deploy",
        Mode::Nominal => "nominal",
    }
}

/// A 1-D float64 view of `values` (NumPy's own conversion for anything but a contiguous
/// float64 vector), as float32 values; `error` makes the exception for what is not numbers.
pub(crate) fn values_as(
    py: Python<'_>,
    values: &Bound<'_, PyAny>,
    name: &str,
    error: fn(String) -> PyErr,
) -> PyResult<Vec<f32>> {
    if let Ok(a) = values.extract::<PyReadonlyArray1<'_, f64>>()
        && let Ok(s) = a.as_slice()
    {
        return Ok(s.iter().map(|&v| v as f32).collect());
    }
    let np = py.import("numpy")?;
    let converted = np
        .call_method1("ascontiguousarray", (values, "float64"))
        .map_err(|e| error(format!("{name}: not an array of numbers ({e})")))?
        .call_method1("reshape", (-1,))?;
    let a: PyReadonlyArray1<'_, f64> = converted.extract()?;
    Ok(a.as_slice()?.iter().map(|&v| v as f32).collect())
}

fn values_of(py: Python<'_>, values: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<f32>> {
    values_as(py, values, name, guard_error)
}

/// The running episode.
#[derive(Clone, Copy)]
struct Episode {
    mode: Mode,
    ticks: u32,
}

/// The library's runtime guard, `Guard<L, T>`, driven tick by tick (see the package docs).
#[pyclass(module = "ctrl_adapt._native", name = "Guard")]
pub struct PyGuard {
    inner: Box<dyn DynGuard>,
    episode: Option<Episode>,
    /// The state coordinates the limits need (1 + the largest state index read).
    state_needed: usize,
}

impl PyGuard {
    fn wrap(inner: Box<dyn DynGuard>) -> Self {
        let state_needed = inner
            .config()
            .limits
            .iter()
            .filter_map(|l| match l.source {
                Source::State(k) => Some(k as usize + 1),
                Source::Signal(_) => None,
            })
            .max()
            .unwrap_or(0);
        Self {
            inner,
            episode: None,
            state_needed,
        }
    }
}

#[pymethods]
impl PyGuard {
    /// `Guard(limits, horizon, limit_ticks, envelope_ticks, relative_margin,
    /// absolute_margin, margin_taper, tripped_cost_span)`; `limits` a list of
    /// `(source, index, low, high)` with `source` `"state"` or `"signal"`.
    #[new]
    #[pyo3(signature = (limits, horizon, limit_ticks, envelope_ticks, relative_margin, absolute_margin, margin_taper, tripped_cost_span))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        limits: Vec<(String, i64, f64, f64)>,
        horizon: i64,
        limit_ticks: i64,
        envelope_ticks: i64,
        relative_margin: f64,
        absolute_margin: f64,
        margin_taper: f64,
        tripped_cost_span: f64,
    ) -> PyResult<Self> {
        if limits.len() > MAX_LIMITS {
            return Err(guard_error(format!(
                "{} limits: the package holds at most {MAX_LIMITS}",
                limits.len()
            )));
        }
        let mut parsed = Vec::with_capacity(limits.len());
        for (i, (source, index, low, high)) in limits.iter().enumerate() {
            let bad = |why: String| guard_error(format!("limit {i}: {why}"));
            let index = u16::try_from(*index)
                .map_err(|_| bad(format!("index {index} is not from 0 to {}", u16::MAX)))?;
            let source = match source.as_str() {
                "state" => Source::State(index),
                "signal" => Source::Signal(index),
                other => return Err(bad(format!("source `{other}` (one of: state, signal)"))),
            };
            if low.is_nan() || high.is_nan() {
                return Err(bad("a bound is NaN (use -inf or inf for no bound)".into()));
            }
            if low > high {
                return Err(bad(format!("low {low} is above high {high}")));
            }
            parsed.push(Limit {
                source,
                low: *low as f32,
                high: *high as f32,
            });
        }
        let horizon = usize::try_from(horizon)
            .map_err(|_| guard_error(format!("horizon {horizon} is negative")))?;
        let config = Config {
            limits: parsed,
            horizon,
            limit_ticks: count(limit_ticks, "limit_ticks")?,
            envelope_ticks: count(envelope_ticks, "envelope_ticks")?,
            relative_margin: narrow(relative_margin, "relative_margin")?,
            absolute_margin: narrow(absolute_margin, "absolute_margin")?,
            margin_taper: narrow(margin_taper, "margin_taper")?,
            tripped_cost_span: narrow(tripped_cost_span, "tripped_cost_span")?,
        };
        build(&config).map(Self::wrap).map_err(guard_error)
    }

    /// Starts an episode in `mode` (`"learn"`, `"deploy"` or `"nominal"`).
    fn begin(&mut self, mode: &str) -> PyResult<()> {
        let mode = mode_of(mode)?;
        if self.episode.is_some() {
            return Err(guard_error("begin: an episode is running: end() it first"));
        }
        self.inner.begin(mode);
        self.episode = Some(Episode { mode, ticks: 0 });
        Ok(())
    }

    /// One tick: whether the nominal controller must run it.
    #[pyo3(signature = (state, cost=None, signal=None))]
    fn check(
        &mut self,
        py: Python<'_>,
        state: &Bound<'_, PyAny>,
        cost: Option<f64>,
        signal: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        let Some(episode) = self.episode else {
            return Err(guard_error(
                "check: no episode is running: begin(mode) first",
            ));
        };
        let values = values_of(py, state, "state")?;
        if values.len() < self.state_needed {
            return Err(guard_error(format!(
                "check: the state has {} values, a limit reads state[{}]",
                values.len(),
                self.state_needed - 1
            )));
        }
        let cost = match cost {
            Some(c) => c as f32,
            None if self.inner.horizon() > 0 => {
                return Err(guard_error(
                    "check: this guard has an envelope: pass the running cost (cost=...)",
                ));
            }
            None => f32::NAN,
        };
        let signal = match signal {
            Some(s) => values_of(py, s, "signal")?,
            None => Vec::new(),
        };
        let mut padded = Vector::<MAX_STATE>::zeros();
        for (slot, v) in padded.iter_mut().zip(&values) {
            *slot = *v;
        }
        let nominal = self
            .inner
            .check(episode.mode, episode.ticks, &padded, &signal, cost);
        if let Some(e) = self.episode.as_mut() {
            e.ticks = e.ticks.saturating_add(1);
        }
        Ok(nominal)
    }

    /// Ends the episode: `(mode, ticks, trip, ticks_beyond_limits)`, `trip` `None` or
    /// `(tick, reason, limit, cost)`.
    #[allow(clippy::type_complexity)]
    fn end(
        &mut self,
    ) -> PyResult<(
        &'static str,
        u32,
        Option<(u32, &'static str, Option<u16>, f32)>,
        u32,
    )> {
        let Some(episode) = self.episode.take() else {
            return Err(guard_error("end: no episode is running"));
        };
        let (trip, beyond) = self.inner.finish();
        let trip = trip.map(|t| {
            let (why, limit) = reason(&t);
            (t.tick, why, limit, t.cost)
        });
        Ok((mode_name(episode.mode), episode.ticks, trip, beyond))
    }

    /// The cost to tell for a learning episode tripped at `tick` of `ticks`.
    fn tripped_cost(&self, failure_cost: f64, tick: i64, ticks: i64) -> PyResult<f64> {
        let failure = narrow(failure_cost, "failure_cost")?;
        let tick = u32::try_from(tick.max(0)).unwrap_or(u32::MAX);
        let ticks = u32::try_from(ticks.max(0)).unwrap_or(u32::MAX);
        told(failure, self.inner.config().tripped_cost_span, tick, ticks)
            .map(f64::from)
            .map_err(guard_error)
    }

    /// `(guarded_episodes, bare_episodes, limit_trips, envelope_trips,
    /// ticks_beyond_limits)`.
    fn counters(&self) -> (u32, u32, u32, u32, u32) {
        let c = self.inner.counters();
        (
            c.guarded_episodes,
            c.bare_episodes,
            c.limit_trips,
            c.envelope_trips,
            c.ticks_beyond_limits,
        )
    }

    /// The envelope per tick (`-inf` where no bare episode reached).
    fn envelope<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        crate::array(py, &self.inner.envelope())
    }

    /// The threshold per tick (`inf` where unchecked).
    fn thresholds<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        crate::array(py, &self.inner.thresholds())
    }

    /// Forgets the envelope; between episodes.
    fn clear_envelope(&mut self) -> PyResult<()> {
        if self.episode.is_some() {
            return Err(guard_error("clear_envelope: an episode is running"));
        }
        self.inner.clear_envelope();
        Ok(())
    }

    /// `(limits, horizon, limit_ticks, envelope_ticks, relative_margin, absolute_margin,
    /// margin_taper, tripped_cost_span)` as the guard holds them (float32 values, the
    /// compiled horizon).
    #[allow(clippy::type_complexity)]
    fn config(
        &self,
    ) -> (
        Vec<(&'static str, u16, f32, f32)>,
        usize,
        u32,
        u32,
        f32,
        f32,
        f32,
        f32,
    ) {
        let c = self.inner.config();
        let limits = c
            .limits
            .iter()
            .map(|l| match l.source {
                Source::State(k) => ("state", k, l.low, l.high),
                Source::Signal(k) => ("signal", k, l.low, l.high),
            })
            .collect();
        (
            limits,
            c.horizon,
            c.limit_ticks,
            c.envelope_ticks,
            c.relative_margin,
            c.absolute_margin,
            c.margin_taper,
            c.tripped_cost_span,
        )
    }

    /// The Rust type, `Guard<L, T>`.
    #[getter]
    fn rust_type(&self) -> String {
        format!(
            "Guard<{}, {}>",
            self.inner.limit_count(),
            self.inner.horizon()
        )
    }

    /// The running episode's mode, or `None`.
    #[getter]
    fn mode(&self) -> Option<&'static str> {
        self.episode.map(|e| mode_name(e.mode))
    }

    /// The running episode's ticks so far (0 between episodes).
    #[getter]
    fn ticks(&self) -> u32 {
        self.episode.map_or(0, |e| e.ticks)
    }

    /// The record of `Guard<L, T>`; between episodes.
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        if self.episode.is_some() {
            return Err(guard_error("save: an episode is running: end() it first"));
        }
        let bytes = self.inner.save().map_err(crate::record_error)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The guard in a record (of any compiled sizes).
    #[staticmethod]
    fn load(record: &[u8]) -> PyResult<Self> {
        let inner = load(record).map_err(|e| match e {
            Ok(e) => crate::record_error(e),
            Err(why) => crate::record_error(why),
        })?;
        Ok(Self::wrap(inner))
    }

    /// A copy in the same state (a running episode included).
    fn copy(&self) -> PyResult<Self> {
        Ok(Self {
            inner: copy(self.inner.as_ref()).map_err(guard_error)?,
            episode: self.episode,
            state_needed: self.state_needed,
        })
    }
}

/// The guard's class, exception and sizes, added to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyGuard>()?;
    m.add("GuardError", m.py().get_type::<GuardError>())?;
    m.add("GUARD_MAX_LIMITS", MAX_LIMITS)?;
    m.add("GUARD_MAX_HORIZON", MAX_HORIZON)?;
    m.add("GUARD_MAX_STATE", MAX_STATE)?;
    m.add("GUARD_HORIZONS", HORIZONS.to_vec())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The package's guard is the library's type: its record loads as `Guard<2, 1024>`, and
    /// it gives the verdicts of that type driven directly through `Supervisor`.
    #[test]
    fn the_package_guard_is_the_library_type() {
        let limits = vec![
            Limit {
                source: Source::State(1),
                low: -0.2,
                high: 0.2,
            },
            Limit {
                source: Source::Signal(0),
                low: 0.0,
                high: 5.0,
            },
        ];
        let config = Config {
            limits: limits.clone(),
            horizon: 1000,
            limit_ticks: 2,
            envelope_ticks: 2,
            relative_margin: 0.2,
            absolute_margin: 0.0,
            margin_taper: 1.0,
            tripped_cost_span: 1.0,
        };
        let mut ours = build(&config).unwrap();
        let mut theirs = Guard::<2, 1024>::try_new(GuardConfig {
            limits: [limits[0], limits[1]],
            limit_ticks: 2,
            envelope_ticks: 2,
            relative_margin: 0.2,
            absolute_margin: 0.0,
            margin_taper: 1.0,
            tripped_cost_span: 1.0,
        })
        .unwrap();
        let mut x = 0.3f32;
        for (episode, mode) in [Mode::Nominal, Mode::Learn, Mode::Learn]
            .into_iter()
            .enumerate()
        {
            ours.begin(mode);
            Supervisor::<4>::begin(&mut theirs, mode);
            let mut running = 0.0;
            for tick in 0..300u32 {
                // A deterministic wander, larger in the later episodes.
                x = (x * 3.7 * (1.0 - x)).clamp(0.01, 0.99);
                let angle = (x - 0.5) * 0.3 * (episode as f32 + 1.0);
                running += x * (episode as f32 + 1.0) * 0.01;
                let state = [0.0, angle, 0.0, 0.0];
                let mut padded = Vector::<MAX_STATE>::zeros();
                padded.as_mut_slice()[..4].copy_from_slice(&state);
                let signal = [x * 6.0];
                let a = ours.check(mode, tick, &padded, &signal, running);
                let b = Supervisor::<4>::check(
                    &mut theirs,
                    mode,
                    tick,
                    &Vector::from(state),
                    &signal,
                    || running,
                );
                assert_eq!(a, b, "tick {tick} of episode {episode}");
            }
            assert_eq!(ours.finish(), Supervisor::<4>::finish(&mut theirs));
        }
        let bytes = ours.save().unwrap();
        let loaded: Guard<2, 1024> = record::load(&bytes).unwrap();
        assert_eq!(loaded, theirs);
        assert_eq!(load(&bytes).unwrap().save().unwrap(), bytes);
    }

    #[test]
    fn sizes_beyond_the_compiled_ones_are_refused() {
        let base = Config {
            limits: vec![],
            horizon: 0,
            limit_ticks: 1,
            envelope_ticks: 1,
            relative_margin: 0.0,
            absolute_margin: 0.0,
            margin_taper: 1.0,
            tripped_cost_span: 1.0,
        };
        let many = Config {
            limits: vec![Limit::NONE; MAX_LIMITS + 1],
            ..base.clone()
        };
        assert!(matches!(build(&many), Err(BuildError::Size(_))));
        let long = Config {
            horizon: MAX_HORIZON + 1,
            ..base.clone()
        };
        assert!(matches!(build(&long), Err(BuildError::Size(_))));
        assert_eq!(horizon_for(1000), Some(1024));
        assert!(build(&base).is_ok());
    }
}
