//! Python bindings of ctrl-adapt's optimizers: the firmware's algorithms, bit for bit, on
//! NumPy arrays (module `ctrl_adapt._native`; the Python package `ctrl_adapt` wraps it).
//!
//! The library stays `no_std` and unchanged: this crate reaches its const-generic types at a
//! dimension chosen at run time through [`dispatch`], owns the RNG each optimizer draws
//! from (xoshiro128++, seeded as the Rust examples seed it), and turns the library's errors
//! into Python exceptions carrying the library's messages.

pub mod dispatch;
pub mod guard;
pub mod model;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::create_exception;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro128PlusPlus;

use ctrl_adapt::optimizer::Status;
use dispatch::{Algorithm, BuildError, Dynamic, Spec};

create_exception!(
    ctrl_adapt,
    OptimizerError,
    PyValueError,
    "A value or call the library refused; the message names the field."
);
create_exception!(
    ctrl_adapt,
    RecordError,
    PyValueError,
    "A record that cannot be saved or loaded (corrupt, another version, another type or sizes, or an invalid state)."
);

fn optimizer_error(e: impl core::fmt::Display) -> PyErr {
    OptimizerError::new_err(e.to_string())
}

fn record_error(e: impl core::fmt::Display) -> PyErr {
    RecordError::new_err(e.to_string())
}

fn f32s(values: &[f64], name: &str) -> PyResult<Vec<f32>> {
    values
        .iter()
        .map(|&v| {
            let x = v as f32;
            if v.is_finite() && !x.is_finite() {
                Err(optimizer_error(format!(
                    "invalid parameter: {name} (outside the f32 range)"
                )))
            } else {
                Ok(x)
            }
        })
        .collect()
}

/// A cost as the firmware holds it: rounded to float32, a finite cost beyond float32
/// refused like an infinite one (NaN).
fn narrow(cost: f64) -> f32 {
    let narrow = cost as f32;
    if cost.is_finite() && !narrow.is_finite() {
        f32::NAN
    } else {
        narrow
    }
}

/// A ticket as the library numbers it; a number no ticket has (negative, beyond u32) is
/// the library's unknown ticket.
fn ticket_number(ticket: i64) -> PyResult<u32> {
    u32::try_from(ticket).map_err(|_| optimizer_error(ctrl_adapt::Error::UnknownTicket))
}

fn array<'py>(py: Python<'py>, values: &[f32]) -> Bound<'py, PyArray1<f64>> {
    let wide: Vec<f64> = values.iter().map(|&v| f64::from(v)).collect();
    PyArray1::from_vec(py, wide)
}

fn status_name(status: Status) -> &'static str {
    match status {
        Status::Running => "running",
        Status::Converged => "converged",
        Status::BudgetSpent => "budget_spent",
    }
}

/// One of the library's optimizers at any dimension from 1 to 64 (see the package docs).
#[pyclass(module = "ctrl_adapt._native", name = "Optimizer")]
struct PyOptimizer {
    algorithm: Algorithm,
    inner: Box<dyn Dynamic>,
    rng: Xoshiro128PlusPlus,
    /// The pending candidate was not handed out by this object (a start given to `sracos`,
    /// `crs` or `two-phase`, or a record's): the next `ask` or `suggest` hands it out.
    waiting: bool,
}

#[pymethods]
impl PyOptimizer {
    /// `Optimizer(algorithm, lower, upper, start=None, seed=0, config="{}")`.
    #[new]
    #[pyo3(signature = (algorithm, lower, upper, start=None, seed=0, config="{}"))]
    fn new(
        algorithm: &str,
        lower: PyReadonlyArray1<'_, f64>,
        upper: PyReadonlyArray1<'_, f64>,
        start: Option<PyReadonlyArray1<'_, f64>>,
        seed: u64,
        config: &str,
    ) -> PyResult<Self> {
        let algorithm = Algorithm::parse(algorithm).ok_or_else(|| {
            let names: Vec<&str> = Algorithm::ALL.iter().map(|a| a.name()).collect();
            optimizer_error(format!(
                "unknown algorithm `{algorithm}` (one of: {})",
                names.join(", ")
            ))
        })?;
        let lower = f32s(lower.as_slice()?, "lower")?;
        let upper = f32s(upper.as_slice()?, "upper")?;
        let start = match &start {
            Some(s) => Some(f32s(s.as_slice()?, "start")?),
            None => None,
        };
        let spec = Spec {
            algorithm,
            lower: &lower,
            upper: &upper,
            start: start.as_deref(),
            config,
        };
        let inner = dispatch::build(&spec).map_err(|e| match e {
            BuildError::Library(e) => optimizer_error(e),
            other => optimizer_error(other),
        })?;
        let waiting = inner.pending().is_some();
        Ok(Self {
            algorithm,
            inner,
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
            waiting,
        })
    }

    /// The algorithm's name.
    #[getter]
    fn algorithm(&self) -> &'static str {
        self.algorithm.name()
    }

    /// The number of parameters.
    #[getter]
    fn dimension(&self) -> usize {
        self.inner.dimension()
    }

    /// The Rust type this object is, as firmware declares it to load its records.
    #[getter]
    fn rust_type(&self) -> String {
        dispatch::rust_type(self.algorithm, self.inner.dimension())
    }

    /// The next candidate (float64 values of the library's float32 ones). Raises
    /// `OptimizerError` while a candidate is pending (asked, not yet told: `tell` its cost
    /// first; `suggest`/`report` hold several in flight) or tickets are outstanding.
    fn ask<'py>(&mut self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        if self.waiting
            && let Some(theta) = self.inner.pending()
        {
            self.waiting = false;
            return Ok(array(py, &theta));
        }
        if self.inner.pending().is_some() {
            return Err(optimizer_error(
                "ask: a candidate is pending (asked, not told): tell its cost first, or use \
                 suggest/report to have several candidates in flight (pending() returns it)",
            ));
        }
        let theta = self.inner.ask(&mut self.rng).map_err(optimizer_error)?;
        Ok(array(py, &theta))
    }

    /// The pending candidate's cost (rounded to float32, as the firmware holds it).
    fn tell(&mut self, cost: f64) -> PyResult<()> {
        self.inner.tell(narrow(cost)).map_err(optimizer_error)?;
        self.waiting = false;
        Ok(())
    }

    /// `(ticket, candidate)`: the next candidate to evaluate in parallel with the others
    /// in flight, or `None` while nothing more can be handed out before outstanding
    /// tickets are reported. Raises `OptimizerError` once the optimizer has stopped.
    fn suggest<'py>(
        &mut self,
        py: Python<'py>,
    ) -> PyResult<Option<(u32, Bound<'py, PyArray1<f64>>)>> {
        if self.waiting
            && let Some((ticket, theta)) = self.inner.adopt_pending()
        {
            self.waiting = false;
            return Ok(Some((ticket, array(py, &theta))));
        }
        let suggested = self.inner.suggest(&mut self.rng).map_err(optimizer_error)?;
        Ok(suggested.map(|(ticket, theta)| (ticket, array(py, &theta))))
    }

    /// The cost of `ticket`'s candidate (rounded to float32), in any order; the optimizer
    /// takes the costs of a generation in the order they were handed out, so the result
    /// is the sequential one. Raises `OptimizerError` for a ticket not outstanding or a
    /// non-finite cost, changing nothing.
    fn report(&mut self, ticket: i64, cost: f64) -> PyResult<()> {
        self.inner
            .report(ticket_number(ticket)?, narrow(cost))
            .map_err(optimizer_error)
    }

    /// Gives `ticket` back (a failed trial): its candidate is handed out again by a later
    /// `suggest`, under a new ticket.
    fn cancel(&mut self, ticket: i64) -> PyResult<()> {
        self.inner
            .cancel(ticket_number(ticket)?)
            .map_err(optimizer_error)
    }

    /// The outstanding tickets, in hand-out order.
    #[getter]
    fn in_flight(&self) -> Vec<u32> {
        self.inner.in_flight()
    }

    /// Whether nothing is in flight: no ticket out, no cancelled candidate waiting to be
    /// handed out again, every reported cost told; then `save()` is the firmware type's
    /// record.
    #[getter]
    fn idle(&self) -> bool {
        self.inner.idle()
    }

    /// How many more `suggest` calls would return a candidate now.
    #[getter]
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }

    /// The most candidates this optimizer can ever have outstanding at once (1 for the
    /// sequential algorithms).
    #[getter]
    fn max_in_flight(&self) -> usize {
        self.inner.max_in_flight()
    }

    /// `(theta, cost)` of the best candidate told so far, or `None`.
    fn best<'py>(&self, py: Python<'py>) -> Option<(Bound<'py, PyArray1<f64>>, f64)> {
        self.inner
            .best()
            .map(|(theta, cost)| (array(py, &theta), f64::from(cost)))
    }

    /// The point to deploy: the sampling distribution's mean (CEM, CMA-ES), ROCK*'s θ*,
    /// LineBo's posterior minimum; the best candidate told for the other algorithms (`None`
    /// before any).
    fn recommend<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.recommend().map(|theta| array(py, &theta))
    }

    /// The candidate asked and not yet told, or `None`.
    fn pending<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.pending().map(|theta| array(py, &theta))
    }

    /// Costs told so far.
    #[getter]
    fn evaluations(&self) -> u32 {
        self.inner.evaluations()
    }

    /// `"running"`, `"converged"` or `"budget_spent"`.
    #[getter]
    fn status(&self) -> &'static str {
        status_name(self.inner.status())
    }

    /// The optimizer's state as a record of its Rust type: the bytes firmware loads with
    /// `ctrl_adapt::record::load::<T>` for `T` = [`rust_type`](Self::rust_type). With
    /// tickets outstanding (or costs held, or a cancelled candidate waiting) the record of
    /// `InFlight<T, n, 64>` instead, which `load` restores with the tickets. The RNG is not
    /// in it (firmware owns its own).
    fn save<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let bytes = self.inner.save().map_err(record_error)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The optimizer in a record (of any algorithm and dimension the package has), with a
    /// new RNG seeded by `seed`.
    #[staticmethod]
    #[pyo3(signature = (record, seed=0))]
    fn load(record: &[u8], seed: u64) -> PyResult<Self> {
        let (algorithm, inner) = dispatch::load(record).map_err(|e| match e {
            Ok(e) => record_error(e),
            Err(why) => record_error(why),
        })?;
        // A record's pending candidate (with nothing in flight) goes out with the next ask
        // or suggest, as the firmware's ask hands it out again.
        let waiting = inner.pending().is_some() && inner.idle();
        Ok(Self {
            algorithm,
            inner,
            rng: Xoshiro128PlusPlus::seed_from_u64(seed),
            waiting,
        })
    }

    /// A copy in the same state, RNG included.
    fn copy(&self) -> PyResult<Self> {
        Ok(Self {
            algorithm: self.algorithm,
            inner: dispatch::copy(self.inner.as_ref()).map_err(optimizer_error)?,
            rng: self.rng.clone(),
            waiting: self.waiting,
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Optimizer('{}', n={}, evaluations={}, status='{}')",
            self.algorithm.name(),
            self.inner.dimension(),
            self.inner.evaluations(),
            status_name(self.inner.status())
        )
    }

    fn __copy__(&self) -> PyResult<Self> {
        self.copy()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> PyResult<Self> {
        self.copy()
    }
}

/// The names of the algorithms.
#[pyfunction]
fn algorithms() -> Vec<&'static str> {
    Algorithm::ALL.iter().map(|a| a.name()).collect()
}

/// The exact Rust type of `algorithm` at dimension `n`.
#[pyfunction]
fn rust_type(algorithm: &str, n: usize) -> PyResult<String> {
    let a = Algorithm::parse(algorithm)
        .ok_or_else(|| PyTypeError::new_err(format!("unknown algorithm `{algorithm}`")))?;
    Ok(dispatch::rust_type(a, n))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyOptimizer>()?;
    m.add_function(wrap_pyfunction!(algorithms, m)?)?;
    m.add_function(wrap_pyfunction!(rust_type, m)?)?;
    m.add("OptimizerError", m.py().get_type::<OptimizerError>())?;
    m.add("RecordError", m.py().get_type::<RecordError>())?;
    m.add("MAX_DIMENSION", dispatch::MAX_DIMENSION)?;
    m.add("MAX_IN_FLIGHT", dispatch::IN_FLIGHT)?;
    m.add("FORMAT_VERSION", ctrl_adapt::record::FORMAT_VERSION)?;
    guard::register(m)?;
    model::register(m)?;
    Ok(())
}
