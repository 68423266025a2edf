//! The Python classes `RlsModel` and `ModelBased` over [`DynModel`] and [`DynLearner`], and
//! the exception `ModelError`.

use super::*;

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyFloat, PyList};
use rand_core::SeedableRng;

use crate::guard::values_as;

create_exception!(
    ctrl_adapt,
    ModelError,
    PyValueError,
    "A model's or model-based learner's configuration, input or call refused (the message says which)."
);

fn model_error(e: impl core::fmt::Display) -> PyErr {
    ModelError::new_err(e.to_string())
}

fn model_error_of(why: String) -> PyErr {
    ModelError::new_err(why)
}

fn floats(py: Python<'_>, values: &Bound<'_, PyAny>, name: &str, n: usize) -> PyResult<Vec<f32>> {
    // A float (a one-dimensional command) or a list skips NumPy's conversion: a policy in a
    // rollout returns one per tick.
    let v = if let Ok(x) = values.downcast::<PyFloat>() {
        vec![x.value() as f32]
    } else if let Ok(list) = values.downcast::<PyList>()
        && let Ok(list) = list.extract::<Vec<f64>>()
    {
        list.into_iter().map(|x| x as f32).collect()
    } else {
        values_as(py, values, name, model_error_of)?
    };
    if v.len() != n {
        return Err(model_error(format!(
            "{name} has {} values, expected {n}",
            v.len()
        )));
    }
    Ok(v)
}

/// How many ticks of a rollout, or predictions of a proposal, run between two checks for
/// Ctrl-C.
const SIGNAL_PERIOD: u32 = 1024;

/// The `MemoryError` of a rollout whose `ticks + 1` rows of `s` states do not fit.
fn rollout_memory(ticks: u32, s: usize) -> PyErr {
    let rows = u64::from(ticks) + 1;
    let bytes = u128::from(rows) * s as u128 * 8;
    PyMemoryError::new_err(format!(
        "rollout: ticks={ticks} needs {rows} rows of {s} states ({bytes} bytes as float64), \
         more than this process can allocate: ask for fewer ticks"
    ))
}

/// The rows of a diverged rollout after its last finite state, NaN: `values` filled to
/// `ticks + 1` rows of `s` with one fallible allocation (`MemoryError` when refused), in
/// chunks with a check for Ctrl-C between them.
fn nan_rows(py: Python<'_>, values: &mut Vec<f64>, ticks: u32, s: usize) -> PyResult<()> {
    const CHUNK: usize = 1 << 20;
    let total = rollout_values(ticks, s).ok_or_else(|| rollout_memory(ticks, s))?;
    values
        .try_reserve_exact(total.saturating_sub(values.len()))
        .map_err(|_| rollout_memory(ticks, s))?;
    while values.len() < total {
        let end = values.len() + (total - values.len()).min(CHUNK);
        values.resize(end, f64::NAN);
        py.check_signals()?;
    }
    Ok(())
}

fn matrix<'py>(
    py: Python<'py>,
    rows: &[Vec<f32>],
    columns: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let flat: Vec<f64> = rows.iter().flatten().map(|&v| f64::from(v)).collect();
    PyArray1::from_vec(py, flat).reshape([rows.len(), columns])
}

/// The fields of a JSON object made from keyword arguments (`None` for none).
fn json_of(py: Python<'_>, config: Option<&Bound<'_, PyDict>>) -> PyResult<String> {
    match config {
        None => Ok("{}".into()),
        Some(d) => py
            .import("json")?
            .call_method1("dumps", (d,))?
            .extract::<String>(),
    }
}

/// A plant model fitted tick by tick, the firmware's `RlsModel<S, A, R>`:
/// x' = x + Wᵀ·z, z = [state, action, 1, features], by regularised recursive least squares
/// with forgetting.
///
/// `RlsModel(state_dim, action_dim, features=0, *, forgetting=0.9995, prior_variance=100.0,
/// max_variance=1e4, error_window=1000)` (the library's `ModelConfig` defaults); `features`
/// extra regressors of your own are passed with each tick. Raises `ModelError` (a
/// `ValueError`) for sizes not compiled (state 1 to 8, action 1 to 2, features 0 to 2) or a
/// configuration out of range. See `ctrl_adapt.model` for an example.
#[pyclass(module = "ctrl_adapt._native", name = "RlsModel")]
pub struct PyRlsModel {
    inner: Box<dyn DynModel>,
}

impl PyRlsModel {
    fn extra(&self, py: Python<'_>, features: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<f32>> {
        let (_, _, e) = self.inner.sizes();
        match features {
            Some(f) => floats(py, f, "features", e),
            None if e == 0 => Ok(Vec::new()),
            None => Err(model_error(format!(
                "this model has {e} extra regressors: pass features=..."
            ))),
        }
    }
}

#[pymethods]
impl PyRlsModel {
    /// `RlsModel(state_dim, action_dim, features=0, *, forgetting=0.9995,
    /// prior_variance=100.0, max_variance=1e4, error_window=1000)`.
    #[new]
    #[pyo3(signature = (state_dim, action_dim, features=0, *, forgetting=0.9995, prior_variance=100.0, max_variance=1e4, error_window=1000))]
    fn new(
        state_dim: usize,
        action_dim: usize,
        features: usize,
        forgetting: f32,
        prior_variance: f32,
        max_variance: f32,
        error_window: u32,
    ) -> PyResult<Self> {
        let config = ModelConfig {
            forgetting,
            prior_variance,
            max_variance,
            error_window,
        };
        build_model(state_dim, action_dim, features, config)
            .map(|inner| Self { inner })
            .map_err(model_error)
    }

    /// Fits one tick: `state` and `action` led to `next_state`; returns the a-priori
    /// one-step error (next − prediction before the fit). A non-finite value is refused
    /// (`ModelError`) and the model is unchanged.
    #[pyo3(signature = (state, action, next_state, features=None))]
    fn update<'py>(
        &mut self,
        py: Python<'py>,
        state: &Bound<'py, PyAny>,
        action: &Bound<'py, PyAny>,
        next_state: &Bound<'py, PyAny>,
        features: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (s, a, _) = self.inner.sizes();
        let x = floats(py, state, "state", s)?;
        let u = floats(py, action, "action", a)?;
        let next = floats(py, next_state, "next_state", s)?;
        let g = self.extra(py, features)?;
        let e = self.inner.update(&x, &u, &next, &g).map_err(model_error)?;
        Ok(crate::array(py, &e))
    }

    /// The predicted next state (non-finite inputs give a non-finite prediction).
    #[pyo3(signature = (state, action, features=None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        state: &Bound<'py, PyAny>,
        action: &Bound<'py, PyAny>,
        features: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (s, a, _) = self.inner.sizes();
        let x = floats(py, state, "state", s)?;
        let u = floats(py, action, "action", a)?;
        let g = self.extra(py, features)?;
        Ok(crate::array(py, &self.inner.predict(&x, &u, &g)))
    }

    /// The states of a closed-loop rollout on the model: `ticks + 1` rows, from `start`,
    /// each tick's action `policy(state)` (`policy(k, state)` with `with_tick=True`). Rows
    /// after a prediction that leaves the finite numbers are NaN. Models with extra
    /// regressors have no rollout (their features are the caller's).
    ///
    /// An exception raised by `policy` (or an action of the wrong size) stops the rollout
    /// at that tick and propagates; Ctrl-C interrupts a long rollout (`KeyboardInterrupt`,
    /// checked every 1024 ticks even when the policy runs no Python code). The rows are
    /// allocated as the rollout goes: a rollout whose rows do not fit in memory (as
    /// float64) raises `MemoryError` naming `ticks`, not an abort.
    #[pyo3(signature = (start, ticks, policy, with_tick=false))]
    fn rollout<'py>(
        &self,
        py: Python<'py>,
        start: &Bound<'py, PyAny>,
        ticks: u32,
        policy: &Bound<'py, PyAny>,
        with_tick: bool,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (s, a, e) = self.inner.sizes();
        if e > 0 {
            return Err(model_error(
                "rollout: this model has extra regressors; roll it out with predict(..., features=...)",
            ));
        }
        let x0 = floats(py, start, "start", s)?;
        if x0.iter().any(|v| !v.is_finite()) {
            return Err(model_error("start is not finite"));
        }
        let mut raised: Option<PyErr> = None;
        let mut step = |k: u32, x: &[f32]| -> Result<Vec<f32>, String> {
            // Ctrl-C, seen even when the policy runs no Python bytecode (a NumPy ufunc, a
            // builtin) or none at all for a while.
            let signals = if k.is_multiple_of(SIGNAL_PERIOD) {
                py.check_signals()
            } else {
                Ok(())
            };
            let u = signals
                .and_then(|()| {
                    let state = crate::array(py, x);
                    if with_tick {
                        policy.call1((k, state))
                    } else {
                        policy.call1((state,))
                    }
                })
                .and_then(|u| floats(py, &u, "the policy's action", a));
            u.map_err(|err| {
                let why = err.to_string();
                raised = Some(err);
                why
            })
        };
        let mut values = Vec::new();
        match self.inner.rollout(&x0, ticks, &mut step, &mut values) {
            Ok(Rolled::Finished) => {}
            // The rows after the first non-finite prediction are unknown: NaN.
            Ok(Rolled::Diverged) => nan_rows(py, &mut values, ticks, s)?,
            Err(RolloutError::Refused(why)) => {
                return Err(raised.unwrap_or_else(|| model_error(why)));
            }
            Err(RolloutError::Memory) => return Err(rollout_memory(ticks, s)),
        }
        let rows = values.len() / s;
        PyArray1::from_vec(py, values).reshape([rows, s])
    }

    /// The root-mean-square error per state dimension of an open-loop prediction of a
    /// recorded episode (`states` T + 1 rows, `actions` T rows); the model is unchanged.
    fn episode_error<'py>(
        &self,
        py: Python<'py>,
        states: &Bound<'py, PyAny>,
        actions: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let (s, a, e) = self.inner.sizes();
        if e > 0 {
            return Err(model_error(
                "episode_error: this model has extra regressors (the caller's)",
            ));
        }
        let table = |v: &Bound<'py, PyAny>, name: &str, width: usize| -> PyResult<Vec<Vec<f32>>> {
            let flat = values_as(py, v, name, model_error_of)?;
            if width == 0 || flat.len() % width != 0 {
                return Err(model_error(format!(
                    "{name}: rows of {width} values expected"
                )));
            }
            Ok(flat.chunks(width).map(<[f32]>::to_vec).collect())
        };
        let xs = table(states, "states", s)?;
        let us = table(actions, "actions", a)?;
        let rms = self.inner.episode_error(&xs, &us).map_err(model_error)?;
        Ok(crate::array(py, &rms))
    }

    /// The running root-mean-square one-step error per state dimension (0 before any tick).
    #[getter]
    fn one_step_error<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        crate::array(py, &self.inner.one_step_error())
    }

    /// Ticks fitted since the model was made or reset.
    #[getter]
    fn ticks(&self) -> u32 {
        self.inner.ticks()
    }

    /// W, R × S: the predicted increment is Wᵀ·z, z = [state, action, 1, features].
    #[getter]
    fn weights<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, &self.inner.weights(), self.inner.sizes().0)
    }

    /// P, R × R: the weights' covariance up to the noise variance, computed from the factors
    /// U·D·Uᵀ the model keeps (symmetric and positive definite by construction).
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let p = self.inner.covariance();
        let r = p.len();
        matrix(py, &p, r)
    }

    /// The state's size S.
    #[getter]
    fn state_dim(&self) -> usize {
        self.inner.sizes().0
    }

    /// The action's (command's) size A.
    #[getter]
    fn action_dim(&self) -> usize {
        self.inner.sizes().1
    }

    /// E, the extra regressors passed with each tick.
    #[getter]
    fn features(&self) -> usize {
        self.inner.sizes().2
    }

    /// `{forgetting, prior_variance, max_variance, error_window}` (float32 values).
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.inner.config();
        let d = PyDict::new(py);
        d.set_item("forgetting", c.forgetting)?;
        d.set_item("prior_variance", c.prior_variance)?;
        d.set_item("max_variance", c.max_variance)?;
        d.set_item("error_window", c.error_window)?;
        Ok(d)
    }

    /// The Rust type, `RlsModel<S, A, R>`.
    #[getter]
    fn rust_type(&self) -> String {
        let (s, a, e) = self.inner.sizes();
        format!("RlsModel<{s}, {a}, {}>", s + a + 1 + e)
    }

    /// Forgets everything learned (the covariance-reset count stays).
    fn reset(&mut self) {
        self.inner.reset();
    }

    /// The record of `RlsModel<S, A, R>` (firmware loads it with `ctrl_adapt::record::load`).
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.inner.save().map_err(crate::record_error)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The model in a record of any compiled sizes.
    #[staticmethod]
    fn load(record: &[u8]) -> PyResult<Self> {
        load_model(record)
            .map(|inner| Self { inner })
            .map_err(crate::record_error)
    }

    /// A copy in the same state.
    fn copy(&self) -> Self {
        Self {
            inner: self.inner.boxed_clone(),
        }
    }

    fn __copy__(&self) -> Self {
        self.copy()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.copy()
    }

    fn __repr__(&self) -> String {
        let (s, a, e) = self.inner.sizes();
        format!(
            "RlsModel(state_dim={s}, action_dim={a}, features={e}, ticks={})",
            self.inner.ticks()
        )
    }
}

/// The model-based learner, the firmware's `ModelBased<F, N>`: between real episodes, an
/// inner search of your model's predicted cost in a trust region around the best real θ,
/// screened against a reference cost, with a model-free fallback.
///
/// `ModelBased(lower, upper, fallback="coordinate", inner="cmaes", *, seed=0, start=None,
/// fallback_config=None, inner_config=None, **config)`: 1 to 8 parameters; `fallback` and
/// `inner` each `"coordinate"` or `"cmaes"`, their configurations dicts of the Rust
/// configurations' fields (`CoordinateConfig`, `CmaesConfig`); `**config` fields of
/// `ModelBasedConfig` (`initial_radius`, `min_radius`, `max_radius`, `grow`, `shrink`,
/// `margin`, `inner_evaluations`, `error_weight`, `initial_error`, `uncertainty_weight`
/// (used when `predict` returns a `(cost, uncertainty)` pair: see `propose`),
/// `restart_after`); `start` the fallback's θ⁰ (the box's centre by default). Raises
/// `ModelError` (a `ValueError`) for an unknown name or field, a value out of range,
/// mismatched lengths. See `ctrl_adapt.model` for an example.
#[pyclass(module = "ctrl_adapt._native", name = "ModelBased")]
pub struct PyModelBased {
    inner: Box<dyn DynLearner>,
    search: Search,
    rng: Xoshiro128PlusPlus,
}

/// What a `predict` callable returned, as (cost, uncertainty): a float (a point prediction,
/// uncertainty 0) or a `(cost, uncertainty)` pair.
fn prediction_of(value: &Bound<'_, PyAny>) -> PyResult<(f64, f64)> {
    if let Ok(cost) = value.extract::<f64>() {
        return Ok((cost, 0.0));
    }
    value.extract::<(f64, f64)>().map_err(|_| {
        PyTypeError::new_err(
            "predict must return a float (the predicted cost) or a (cost, uncertainty) pair \
             of floats",
        )
    })
}

/// A proposal as Python receives it: `(theta, source, predicted)`.
type PyProposal<'py> = (Bound<'py, PyArray1<f64>>, &'static str, Option<f64>);

fn proposal<'py>(
    py: Python<'py>,
    p: Proposed,
) -> (Bound<'py, PyArray1<f64>>, &'static str, Option<f64>) {
    let source = if p.1.is_some() { "model" } else { "fallback" };
    (crate::array(py, &p.0), source, p.1.map(f64::from))
}

#[pymethods]
impl PyModelBased {
    /// `ModelBased(lower, upper, fallback="coordinate", inner="cmaes", *, seed=0,
    /// start=None, fallback_config=None, inner_config=None, **config)`.
    #[new]
    #[pyo3(signature = (lower, upper, fallback="coordinate", inner="cmaes", *, seed=0, start=None, fallback_config=None, inner_config=None, **config))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        lower: &Bound<'_, PyAny>,
        upper: &Bound<'_, PyAny>,
        fallback: &str,
        inner: &str,
        seed: u64,
        start: Option<&Bound<'_, PyAny>>,
        fallback_config: Option<&Bound<'_, PyDict>>,
        inner_config: Option<&Bound<'_, PyDict>>,
        config: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let lower = values_as(py, lower, "lower", model_error_of)?;
        let upper = values_as(py, upper, "upper", model_error_of)?;
        let start = match start {
            Some(s) => Some(values_as(py, s, "start", model_error_of)?),
            None => None,
        };
        let fallback =
            Search::parse(fallback, &json_of(py, fallback_config)?).map_err(model_error)?;
        let search = Search::parse(inner, &json_of(py, inner_config)?).map_err(model_error)?;
        let config =
            configured(ModelBasedConfig::DEFAULT, &json_of(py, config)?).map_err(model_error)?;
        let inner = build_learner(&lower, &upper, start.as_deref(), fallback, config)
            .map_err(model_error)?;
        Ok(Self {
            inner,
            search,
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
        })
    }

    /// `(theta, source, predicted)`: the θ of the next real episode, `source` `"model"`
    /// (with its predicted cost) or `"fallback"` (`predicted` None). `predict(theta)` is the
    /// model's cost of θ (a float; `nan` or `inf` where the model cannot say: ranked worse
    /// than every prediction seen), or a `(cost, uncertainty)` pair: with the
    /// `uncertainty_weight` k_u of the configuration, the inner search minimises and the
    /// screen judges cost + k_u × uncertainty (the firmware's `propose_bounded`; a pair is
    /// the cost alone when k_u is 0). Returns the pending proposal again until it is told.
    ///
    /// An exception raised inside `predict`, or a value that is neither, stops the
    /// proposal at once (`predict` is not called again): the learner and its RNG are left
    /// as before the call and the exception propagates. Ctrl-C interrupts a long proposal
    /// (`KeyboardInterrupt`, checked every 1024 predictions even when `predict` runs no
    /// Python code) the same way. Raises `ModelError` when the fallback has stopped and the
    /// model's candidate did not pass (nothing changes).
    fn propose<'py>(
        &mut self,
        py: Python<'py>,
        predict: &Bound<'py, PyAny>,
    ) -> PyResult<PyProposal<'py>> {
        let before = self.inner.boxed_clone();
        let rng = self.rng.clone();
        let mut raised: Option<PyErr> = None;
        let mut calls: u32 = 0;
        let mut call = |theta: &[f32]| -> Result<Prediction, Error> {
            if raised.is_some() {
                return Err(Error::NonFinite("prediction"));
            }
            // Ctrl-C, seen even when `predict` runs no Python bytecode.
            let signals = if calls.is_multiple_of(SIGNAL_PERIOD) {
                py.check_signals()
            } else {
                Ok(())
            };
            calls = calls.wrapping_add(1);
            let value = signals
                .and_then(|()| predict.call1((crate::array(py, theta),)))
                .and_then(|v| prediction_of(&v));
            match value {
                Ok((c, u)) => Ok(Prediction {
                    cost: crate::narrow(c),
                    uncertainty: crate::narrow(u),
                }),
                Err(e) => {
                    raised = Some(e);
                    Err(Error::NonFinite("prediction"))
                }
            }
        };
        let result = self.inner.propose(&mut self.rng, self.search, &mut call);
        match (raised, result) {
            (None, Ok(p)) => Ok(proposal(py, p)),
            (raised, result) => {
                // Nothing changes when the proposal fails: the learner and its RNG are
                // restored, and the exception is raised again.
                self.inner = before;
                self.rng = rng;
                Err(raised.unwrap_or_else(|| model_error(result.err().unwrap_or(Error::Stopped))))
            }
        }
    }

    /// The real cost of the pending proposal (rounded to float32). Raises `ModelError`
    /// without a pending proposal or for a cost that is not a finite float32 (nothing
    /// changes).
    fn tell(&mut self, cost: f64) -> PyResult<()> {
        self.inner.tell(crate::narrow(cost)).map_err(model_error)
    }

    /// Reports a real episode you chose yourself (the bare controller, an identification
    /// episode): it counts for the best θ, not for the fallback or the trust region.
    /// Raises `ModelError` while a proposal is pending, for θ of the wrong length or
    /// outside the box, or a cost that is not a finite float32 (nothing changes).
    fn record(&mut self, py: Python<'_>, theta: &Bound<'_, PyAny>, cost: f64) -> PyResult<()> {
        let theta = floats(py, theta, "theta", self.inner.dimension())?;
        self.inner
            .record(&theta, crate::narrow(cost))
            .map_err(model_error)
    }

    /// The reference cost of the screen (the bare controller's measured cost): a model
    /// candidate must be predicted at most `reference + margin`.
    fn set_reference(&mut self, cost: f64) -> PyResult<()> {
        self.inner
            .set_reference(crate::narrow(cost))
            .map_err(model_error)
    }

    /// `(theta, cost)` of the best real episode, or None.
    #[getter]
    fn best<'py>(&self, py: Python<'py>) -> Option<(Bound<'py, PyArray1<f64>>, f64)> {
        self.inner
            .best()
            .map(|(theta, cost)| (crate::array(py, &theta), f64::from(cost)))
    }

    /// The proposal handed out and not yet told, as `propose` returns it, or None.
    #[getter]
    fn pending<'py>(&self, py: Python<'py>) -> Option<PyProposal<'py>> {
        self.inner.pending().map(|p| proposal(py, p))
    }

    /// The measured prediction error of a real episode's cost (root mean square).
    #[getter]
    fn prediction_error(&self) -> f64 {
        f64::from(self.inner.prediction_error())
    }

    /// The trust region's half-width.
    #[getter]
    fn radius(&self) -> f64 {
        f64::from(self.inner.radius())
    }

    /// Real episodes reported (told and recorded).
    #[getter]
    fn evaluations(&self) -> u32 {
        self.inner.evaluations()
    }

    /// Consecutive told proposals made at the minimum radius that did not improve the best
    /// (below `restart_after` when it is set).
    #[getter]
    fn stalled(&self) -> u32 {
        self.inner.stalled()
    }

    /// The trust region's restarts so far (`restart_after`).
    #[getter]
    fn restarts(&self) -> u32 {
        self.inner.restarts()
    }

    /// The number of parameters.
    #[getter]
    fn dimension(&self) -> usize {
        self.inner.dimension()
    }

    /// The fallback's name.
    #[getter]
    fn fallback(&self) -> &'static str {
        self.inner.fallback()
    }

    /// The inner search's name.
    #[getter]
    fn inner(&self) -> &'static str {
        self.search.name()
    }

    /// The box, `(lower, upper)`.
    #[getter]
    fn bounds<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        let (l, u) = self.inner.bounds();
        (crate::array(py, &l), crate::array(py, &u))
    }

    /// The learner's constants (`ModelBasedConfig`'s fields, float32 values).
    #[getter]
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let json = serde_json::to_string(&self.inner.config()).map_err(model_error)?;
        py.import("json")?.call_method1("loads", (json,))
    }

    /// The Rust type, `ModelBased<F, N>`.
    #[getter]
    fn rust_type(&self) -> String {
        learner_type(self.inner.fallback(), self.inner.dimension())
    }

    /// The record of `ModelBased<F, N>`. The inner search and the RNG are not in it.
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.inner.save().map_err(crate::record_error)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The learner in a record (any compiled dimension and fallback), with the inner search
    /// `inner` and a new RNG seeded by `seed`.
    #[staticmethod]
    #[pyo3(signature = (record, inner="cmaes", *, seed=0, inner_config=None))]
    fn load(
        py: Python<'_>,
        record: &[u8],
        inner: &str,
        seed: u64,
        inner_config: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let search = Search::parse(inner, &json_of(py, inner_config)?).map_err(model_error)?;
        let learner = load_learner(record).map_err(crate::record_error)?;
        Ok(Self {
            inner: learner,
            search,
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
        })
    }

    /// A copy in the same state, RNG included.
    fn copy(&self) -> Self {
        Self {
            inner: self.inner.boxed_clone(),
            search: self.search,
            rng: self.rng.clone(),
        }
    }

    fn __copy__(&self) -> Self {
        self.copy()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Self {
        self.copy()
    }

    fn __repr__(&self) -> String {
        format!(
            "ModelBased(n={}, fallback='{}', inner='{}', evaluations={}, radius={})",
            self.inner.dimension(),
            self.inner.fallback(),
            self.search.name(),
            self.inner.evaluations(),
            self.inner.radius()
        )
    }
}

/// The classes, exception and sizes, added to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRlsModel>()?;
    m.add_class::<PyModelBased>()?;
    m.add("ModelError", m.py().get_type::<ModelError>())?;
    m.add("MODEL_MAX_STATE", MAX_STATE)?;
    m.add("MODEL_MAX_ACTION", MAX_ACTION)?;
    m.add("MODEL_FEATURES", EXTRA_FEATURES.to_vec())?;
    m.add("MODEL_BASED_MAX_DIMENSION", MAX_LEARNER_DIMENSION)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_learner_populations_are_the_library_rule() {
        for n in 1..=MAX_LEARNER_DIMENSION {
            assert_eq!(
                learner_population(n),
                ctrl_adapt::optimizer::cmaes::default_population(n),
                "n = {n}"
            );
        }
    }
}
