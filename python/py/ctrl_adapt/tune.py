"""A Ray Tune searcher over the library's optimizers.

:class:`CtrlAdaptSearch` is a ``ray.tune.search.Searcher``: Tune asks it for a trial's
configuration (``suggest``) and tells it the trial's result (``on_trial_complete``); it hands
out the candidates of a :class:`ctrl_adapt.Optimizer` (named parameters, a dict) and reports
their costs, several at once where the optimizer allows it (a CMA-ES generation, a CEM
population), never more than its ``max_in_flight``. The optimizer is the firmware's own type,
so the state the search ends in is a record the board loads (:meth:`CtrlAdaptSearch.write_record`).

Example (``episodes`` is your trainable, returning ``{"cost": ...}`` for a config)::

    from ray import tune
    from ctrl_adapt.tune import CtrlAdaptSearch

    search = CtrlAdaptSearch({"kp": (0.0, 4.0), "kd": (0.0, 1.0)}, algorithm="cmaes",
                             start={"kp": 1.0, "kd": 0.1}, seed=1, initial_sigma=0.3,
                             metric="cost", mode="min")
    tune.Tuner(episodes, tune_config=tune.TuneConfig(
        search_alg=search, num_samples=200, reuse_actors=True,
        max_concurrent_trials=2)).fit()   # your workers, at most search.max_concurrent
    search.write_record("global.rec")   # -> "Cmaes<2, 6>", the type the firmware loads

``reuse_actors=True`` keeps Ray's cost per trial at a fraction of a second; without it,
each trial starts a worker process (seconds). With several workers, wrap the trainable
(``tune.Tuner(search.trainable(episodes), ...)``): at a generation's end the searcher then
keeps the idle workers busy waiting for the next generation instead of letting Tune stop
them (see :meth:`CtrlAdaptSearch.trainable`).

Failed trials. A trial that raised, or whose result lacks the metric or holds a non-finite
one (NaN, ±inf, or beyond float32), did not measure its candidate. Its candidate is handed out
again to a later trial, up to ``max_retries`` times (default 2: a crash of one simulator worker
loses no candidate and biases nothing); a candidate that keeps failing is then reported at
``failure_value`` (a value of the metric) or, by default, at the worst metric seen so far, and
listed in ``search.penalised``, so that it cannot take every trial of the run.

Parallel trials. The searcher hands out at most the optimizer's ``max_in_flight`` candidates at
once (``search.max_concurrent``; 1 for the sequential algorithms) and honours Tune's
``max_concurrent_trials``. A trial is worth a worker only when it is long against Ray's cost
per trial (tens of milliseconds with ``reuse_actors=True``): run several episodes per trial.
Without Ray, :mod:`ctrl_adapt.pool` evaluates generations on a persistent process pool.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import math
import os
import pickle
import tempfile
import uuid
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
from ray.tune.search import UNDEFINED_METRIC_MODE, UNDEFINED_SEARCH_SPACE, Searcher
from ray.tune.search.sample import Float, LogUniform, Quantized, Uniform
from ray.tune.search.variant_generator import parse_spec_vars
from ray.tune.utils.util import flatten_dict, merge_dicts, unflatten_dict

import ctrl_adapt

__all__ = ["CtrlAdaptSearch", "write_record"]

logger = logging.getLogger(__name__)

_F32_MAX = float(np.finfo(np.float32).max)
_STATE_VERSION = 3
#: The configuration key of a trial started before its candidate exists (see
#: :meth:`CtrlAdaptSearch.trainable`).
DEFERRED = "ctrl_adapt_deferred"

#: A search space: each parameter's name (``"a/b"`` for a nested one) and either its
#: ``(lower, upper)`` bounds or a ``tune.uniform(lower, upper)``; other values are passed
#: through to every trial's configuration unchanged.
Space = Mapping[str, Any]


def write_record(optimizer: "ctrl_adapt.Optimizer", path: Union[str, os.PathLike]) -> str:
    """Write ``optimizer``'s state, a record of its Rust type, to ``path`` for the firmware,
    atomically and durably, and return the Rust type's name.

    The record goes to a temporary file ``.NAME.record-PID-*`` beside ``path``, which is
    fsync'ed, given the mode a plain ``open`` would (``0o666`` less the umask), renamed over
    ``path``, and the directory fsync'ed: after a crash or power cut ``path`` holds the old
    record or the new one, whole. On any exception the temporary file is removed; one left
    by a process killed mid-write (SIGKILL) is removed by the next ``write_record`` to the
    same path.

    On the board, ``ctrl_adapt::record::load::<T>(&bytes)`` with ``T`` the returned type
    (e.g. ``Cmaes<5, 8>``) continues from that state; ``best()`` is the best candidate.
    Firmware runs one episode at a time: unless the optimizer is
    :attr:`~ctrl_adapt.Optimizer.idle` (tickets outstanding, or a cancelled candidate waiting
    to be handed out again) this raises ``ValueError`` (report them, or run the cancelled
    one, first; :meth:`ctrl_adapt.Optimizer.save` still checkpoints them)."""
    if optimizer.in_flight:
        raise ValueError(
            f"write_record: tickets {list(optimizer.in_flight)} are in flight; the firmware loads "
            "records saved with nothing in flight (report or cancel them first)"
        )
    if not optimizer.idle:
        raise ValueError(
            "write_record: a cancelled candidate waits to be handed out again; the firmware "
            "loads records saved with nothing in flight (run it first)"
        )
    data = optimizer.save()
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    prefix = f".{os.path.basename(path)}.record-"
    _remove_stale_temporaries(directory, prefix)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f"{prefix}{os.getpid()}-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            # mkstemp makes the file 0600: give it the mode open() would (0666 less the umask).
            os.fchmod(f.fileno(), 0o666 & ~_umask())
            os.fsync(f.fileno())  # the data is on disk before the name points at it
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    _fsync_directory(directory)  # and the rename itself
    return optimizer.rust_type


def _umask() -> int:
    """The process's umask (read from /proc where it can be, which changes nothing)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _remove_stale_temporaries(directory: str, prefix: str) -> None:
    """Removes the temporary files of :func:`write_record`s to the same path that were
    killed mid-write (named ``.NAME.record-PID-*``; PID no longer running on this host)."""
    try:
        names = os.listdir(directory)
    except OSError:
        return
    for name in names:
        if not name.startswith(prefix):
            continue
        pid = name[len(prefix) :].split("-", 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid() or _running(int(pid)):
            continue
        try:
            os.unlink(os.path.join(directory, name))
        except OSError:
            pass


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. another user's process
        return True
    return True


def _fsync_directory(directory: str) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:  # not on every platform (Windows)
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _finite_cost(value: Any) -> Optional[float]:
    """``value`` as a cost the library accepts (finite in float32), or ``None``."""
    try:
        cost = float(value)
    except (TypeError, ValueError):
        return None
    return cost if math.isfinite(cost) and abs(cost) <= _F32_MAX else None


class _Scale:
    """How a searched parameter maps to the optimizer's coordinate: ``log`` (the optimizer
    searches its natural logarithm; ``tune.loguniform``) and ``q`` (the value handed to a
    trial is rounded to a multiple of ``q``; ``tune.quniform``/``qloguniform``)."""

    __slots__ = ("log", "q")

    def __init__(self, log: bool, q: Optional[float]) -> None:
        self.log, self.q = log, q

    def value(self, x: float) -> float:
        v = math.exp(x) if self.log else x
        if self.q:
            v = float(np.round(v / self.q) * self.q)
        return v

    def coordinate(self, v: float) -> float:
        return math.log(v) if self.log else v


def _parse_space(space: Space) -> Tuple[List[str], List[float], List[float], List[_Scale], Dict[str, Any]]:
    """Names, the optimizer's lower and upper bounds and the scale of each searched
    parameter, and the constant entries."""

    def ranges(value: Any, path: Tuple[str, ...]) -> Any:  # (lower, upper) → a uniform domain
        if isinstance(value, Mapping):
            return {name: ranges(v, path + (str(name),)) for name, v in value.items()}
        if isinstance(value, tuple) and len(value) == 2:
            return Float(float(value[0]), float(value[1])).uniform()
        if (
            isinstance(value, list)
            and len(value) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        ):
            raise ValueError(
                f"CtrlAdaptSearch: parameter `{'/'.join(path)}` is a list {value!r}: a range is "
                "a tuple (lower, upper) or tune.uniform(lower, upper); to pass two numbers "
                "unchanged to every trial, give them as a NumPy array"
            )
        return value

    constants, domains, grids = parse_spec_vars(ranges(space, ()))
    if grids:
        raise ValueError("CtrlAdaptSearch: grid_search parameters cannot be searched")
    names, lower, upper, scales = [], [], [], []
    for path, domain in domains:
        name = "/".join(map(str, path))
        sampler = domain.get_sampler() if isinstance(domain, Float) else None
        q = None
        if isinstance(sampler, Quantized):
            q, sampler = float(sampler.q), sampler.get_sampler()
        if not isinstance(sampler, (Uniform, LogUniform)):
            raise ValueError(
                f"CtrlAdaptSearch: parameter `{name}` must be a float range: (lower, upper), "
                "tune.uniform, tune.quniform, tune.loguniform or tune.qloguniform; got "
                f"{type(domain).__name__}"
                + (f" with a {type(sampler).__name__} sampler" if sampler is not None else "")
            )
        log = isinstance(sampler, LogUniform)
        lo, hi = float(domain.lower), float(domain.upper)
        if log and not (0 < lo < hi):
            raise ValueError(f"CtrlAdaptSearch: loguniform parameter `{name}` needs 0 < lower < upper")
        names.append(name)
        scales.append(_Scale(log, q))
        lower.append(math.log(lo) if log else lo)
        upper.append(math.log(hi) if log else hi)
    constants = {"/".join(map(str, path)): value for path, value in constants}
    return names, lower, upper, scales, constants


class _Broker:
    """The Ray actor through which the searcher hands a deferred trial (see
    :meth:`CtrlAdaptSearch.trainable`) its configuration once the optimizer has a candidate."""

    def __init__(self) -> None:
        self._ready: Dict[str, Any] = {}
        self._events: Dict[str, asyncio.Event] = {}

    def _event(self, slot: str) -> asyncio.Event:
        return self._events.setdefault(slot, asyncio.Event())

    async def put(self, slot: str, assigned: Any) -> None:
        self._ready[slot] = assigned
        self._event(slot).set()

    async def take(self, slot: str) -> Any:
        await self._event(slot).wait()
        self._events.pop(slot, None)
        return self._ready.pop(slot)


class CtrlAdaptSearch(Searcher):
    """A Ray Tune searcher handing out the candidates of a :class:`ctrl_adapt.Optimizer`.

    ``space`` maps parameter names to ``(lower, upper)``, ``tune.uniform``,
    ``tune.quniform``, ``tune.loguniform`` or ``tune.qloguniform`` (or comes from the
    Tuner's ``param_space``); other values are constants passed to every trial. A list
    ``[lower, upper]`` is refused (it would otherwise be a constant). A log-scaled
    parameter is searched as its natural logarithm: the optimizer's bounds, ``start`` and
    the record firmware loads are in that coordinate. The optimizer is either given
    (``optimizer=``, built over the same box, its dimension the number of parameters) or
    built from ``algorithm``, the space's bounds, ``start`` (a dict by name or a vector, in
    parameter units), ``seed`` and ``config`` (fields of the algorithm's configuration, as
    for :class:`ctrl_adapt.Optimizer`, e.g. CMA-ES's ``penalty``). ``mode="max"`` reports
    ``-metric`` as the cost.

    ``points_to_evaluate`` (a list of configurations, dicts by parameter name) are run
    first, as are points given to :meth:`add_evaluated_point`; the optimizer's state (the
    firmware's type) cannot take costs of points it did not propose, so they do not steer
    the search, but :meth:`best` compares them with its candidates.

    ``suggest`` returns a trial's configuration, ``None`` while the optimizer has
    ``max_in_flight`` candidates out (or Tune's limit, :meth:`set_max_concurrency`, is
    reached, or it cannot hand out more before some are reported), and
    ``Searcher.FINISHED`` once it has stopped (converged or its budget spent).

    Failed trials (raised, or no finite metric): the candidate is handed out again, up to
    ``max_retries`` times; after that it is reported at ``failure_value`` if given, else at
    the worst metric seen so far (retried again while no trial has succeeded), and listed
    in :attr:`penalised`. With ``failure_value`` set and ``max_retries=0`` a failure is
    reported at once. ``save``/``restore`` go through the optimizer's record and the trial
    → ticket map, so trials still running at a checkpoint are accepted after it.
    """

    def __init__(
        self,
        space: Optional[Space] = None,
        *,
        optimizer: Optional["ctrl_adapt.Optimizer"] = None,
        algorithm: str = "cmaes",
        start: Optional[Union[Mapping[str, float], Sequence[float]]] = None,
        seed: int = 0,
        metric: Optional[str] = None,
        mode: Optional[str] = None,
        points_to_evaluate: Optional[Sequence[Mapping[str, Any]]] = None,
        max_retries: int = 2,
        failure_value: Optional[float] = None,
        **config: Any,
    ) -> None:
        super().__init__(metric=metric, mode=mode)
        if failure_value is not None and _finite_cost(failure_value) is None:
            raise ValueError(
                f"CtrlAdaptSearch: failure_value must be finite in float32, got {failure_value!r}"
            )
        if int(max_retries) < 0:
            raise ValueError(f"CtrlAdaptSearch: max_retries must be ≥ 0, got {max_retries!r}")
        self._optimizer = optimizer
        self._algorithm = algorithm
        self._start = start
        self._seed = int(seed)
        self._config = config
        self._failure_value = failure_value
        self._max_retries = int(max_retries)
        self._max_concurrent: Optional[int] = None
        self._names: List[str] = []
        self._scales: List[_Scale] = []
        self._constants: Dict[str, Any] = {}
        self._trials: Dict[str, int] = {}
        self._failures: Dict[bytes, int] = {}
        self._thetas: Dict[int, bytes] = {}
        self._worst: Optional[float] = None
        self._points: List[Dict[str, Any]] = [dict(p) for p in (points_to_evaluate or [])]
        self._point_trials: Dict[str, Dict[str, Any]] = {}
        #: ``(trial_id, metric)`` of every reported trial, in the order reported.
        self.history: List[Tuple[str, float]] = []
        #: Failed trials whose candidate was handed out again.
        self.cancelled = 0
        #: ``(trial_id, metric)`` of the failed trials reported at a penalty (after
        #: ``max_retries`` retries): the metric is the one reported for them.
        self.penalised: List[Tuple[str, float]] = []
        #: ``(configuration, metric)`` of the points evaluated outside the optimizer
        #: (``points_to_evaluate``, :meth:`add_evaluated_point`).
        self.evaluated_points: List[Tuple[Dict[str, Any], float]] = []
        #: The most candidates that were out at once.
        self.peak_in_flight = 0
        #: Trials started before their candidate existed (:meth:`trainable`).
        self.deferred_trials = 0
        self._defer = False
        self._broker_name = f"ctrl_adapt_broker_{uuid.uuid4().hex}"
        self._broker: Any = None
        self._deferred: Dict[str, None] = {}
        if space:
            self._set_space(space)

    # -- setting up -----------------------------------------------------------------------

    def _set_space(self, space: Space) -> None:
        names, lower, upper, scales, constants = _parse_space(space)
        if not names:
            raise ValueError("CtrlAdaptSearch: the space has no parameter to search")
        if self._optimizer is None:
            start = self._start
            if isinstance(start, Mapping):
                missing = set(names) - set(start)
                if missing:
                    raise ValueError(f"CtrlAdaptSearch: start has no value for {sorted(missing)}")
                start = [start[name] for name in names]
            if start is not None:
                start = [scale.coordinate(float(v)) for scale, v in zip(scales, start)]
            self._optimizer = ctrl_adapt.Optimizer(
                self._algorithm, np.array(lower), np.array(upper), start, seed=self._seed, **self._config
            )
        elif self._optimizer.dimension != len(names):
            raise ValueError(
                f"CtrlAdaptSearch: the optimizer has {self._optimizer.dimension} parameters, "
                f"the space {len(names)} ({names})"
            )
        self._names, self._scales, self._constants = names, scales, constants

    def set_search_properties(
        self, metric: Optional[str], mode: Optional[str], config: Dict, **spec: Any
    ) -> bool:
        """Take the metric, mode and (unless the searcher has its space) the search space
        from the Tuner; ``False`` if both the searcher and ``param_space`` define one."""
        if self._names and parse_spec_vars(config)[1]:
            return False
        if metric and not self._metric:
            self._metric = metric
        if mode and not self._mode:
            self._mode = mode
        if not self._names and config:
            self._set_space(config)
        return True

    def set_max_concurrency(self, max_concurrent: int) -> bool:
        """Tune's limit on concurrent trials (``TuneConfig(max_concurrent_trials=...)`` or a
        ``ConcurrencyLimiter``): the searcher hands out at most this many candidates at
        once, and never more than the optimizer's :attr:`max_concurrent`. Returns ``True``
        (the searcher enforces it itself)."""
        self._max_concurrent = max(1, int(max_concurrent))
        return True

    @property
    def max_concurrent(self) -> Optional[int]:
        """The most trials worth running at once: the optimizer's ``max_in_flight`` (a
        CMA-ES generation, a CEM batch; 1 for the sequential algorithms), within Tune's
        limit if one was set; ``None`` until the space is known. Give Tune as many
        workers (``max_concurrent_trials``), more are idle."""
        if self._optimizer is None:
            return None
        limit = self._optimizer.max_in_flight
        return limit if self._max_concurrent is None else min(limit, self._max_concurrent)

    @property
    def optimizer(self) -> "ctrl_adapt.Optimizer":
        """The wrapped optimizer (``None`` until the search space is known)."""
        return self._optimizer

    @property
    def parameter_names(self) -> List[str]:
        """The searched parameters, in the optimizer's vector order."""
        return list(self._names)

    # -- the search ---------------------------------------------------------------------

    def suggest(self, trial_id: str) -> Optional[Union[Dict[str, Any], str]]:
        opt = self._optimizer
        if not self._names or opt is None:
            raise RuntimeError(UNDEFINED_SEARCH_SPACE.format(cls=type(self).__name__, space="space"))
        if not self._metric or not self._mode:
            raise RuntimeError(
                UNDEFINED_METRIC_MODE.format(cls=type(self).__name__, metric=self._metric, mode=self._mode)
            )
        if self._defer:
            # Started with the search, not at the first generation's end: a worker process
            # takes seconds to start, and the deferred trials would wait for it.
            self._broker_handle()
        running = len(opt.in_flight) + len(self._point_trials) + len(self._deferred)
        if self._max_concurrent is not None and running >= self._max_concurrent:
            return None
        if self._points:
            point = self._points.pop(0)
            self._point_trials[trial_id] = point
            flat = dict(self._constants)
            flat.update(flatten_dict(point, delimiter="/"))
            return unflatten_dict(flat)
        if opt.status != "running":
            return Searcher.FINISHED
        handed = None if self._deferred or len(opt.in_flight) >= opt.max_in_flight else opt.suggest()
        if handed is None:
            return self._defer_trial(trial_id, running)
        ticket, theta = handed
        self._trials[trial_id] = ticket
        self._thetas[ticket] = np.asarray(theta).tobytes()
        self.peak_in_flight = max(self.peak_in_flight, len(opt.in_flight))
        return self._configuration(theta)

    def trainable(self, function: Any) -> Any:
        """``function`` (a Tune function trainable, ``config -> result``) wrapped so that Tune
        keeps its workers between generations; pass it to ``tune.Tuner`` instead of
        ``function``.

        Why. A CMA-ES or CEM generation ends with one trial running and the other workers
        idle: the optimizer has no candidate until that trial's cost is in. Tune's actor
        cache (``reuse_actors=True``) keeps one idle worker when no trial is waiting and
        stops the others; the next generation then waits for new worker processes (seconds
        each), and a trial handed to a worker that frees first has Tune stop the one still
        starting, so with trials shorter than a worker's start every later generation ran
        on one worker (measured: all 6 trials of the second generation on one process with
        2 workers, ``python/bench/tune_trace.py --unwrapped``).

        With the trainable wrapped, the searcher answers such a ``suggest`` (a worker free,
        Tune's limit not reached, the optimizer waiting for costs) with a *deferred* trial:
        its configuration holds the constants and ``ctrl_adapt_deferred`` only, and the
        wrapper waits, on the worker Tune gave it, until the generation's last cost is in
        and the searcher hands it the next candidate (through a small Ray actor); it then
        calls ``function`` with the full configuration. If the optimizer stops meanwhile, the
        trial returns the metric as NaN without calling ``function`` (and counts as no
        evaluation). A deferred trial's ``config`` in Tune's results lacks the parameters;
        :meth:`best`, :attr:`history` and the optimizer hold the candidates."""
        self._defer = True
        name = self._broker_name

        @functools.wraps(function)
        def run(config):
            slot = config.get(DEFERRED) if isinstance(config, Mapping) else None
            if slot is None:
                return function(config)
            import ray

            assigned, metric = ray.get(ray.get_actor(name).take.remote(slot))
            if assigned is None:  # the search stopped before a candidate came
                return {metric or "cost": float("nan"), "ctrl_adapt_skipped": True}
            rest = {k: v for k, v in config.items() if k != DEFERRED}
            return function(merge_dicts(rest, assigned))

        return run

    def _defer_trial(self, trial_id: str, running: int) -> Optional[Dict[str, Any]]:
        """A deferred trial (:meth:`trainable`) for ``trial_id`` when the trainable is
        wrapped, candidates are in flight (so one will come) and the limit has room."""
        opt = self._optimizer
        limit = self._max_concurrent if self._max_concurrent is not None else opt.max_in_flight
        if not self._defer or not opt.in_flight or running >= limit:
            return None
        self._deferred[trial_id] = None
        self.deferred_trials += 1
        flat = dict(self._constants)
        flat[DEFERRED] = trial_id
        return unflatten_dict(flat)

    def _broker_handle(self) -> Any:
        """The broker actor of :meth:`trainable`, started (or found by name) on first use."""
        if self._broker is None:
            import ray

            self._broker = (
                ray.remote(num_cpus=0)(_Broker)
                .options(name=self._broker_name, get_if_exists=True)
                .remote()
            )
        return self._broker

    def _resolve_deferred(self) -> None:
        """Hands the deferred trials candidates, oldest first, as far as the optimizer has
        them (or tells them the search has stopped)."""
        opt = self._optimizer
        while self._deferred:
            trial_id = next(iter(self._deferred))
            if opt.status != "running":
                assigned = (None, self._metric)
            else:
                handed = opt.suggest() if len(opt.in_flight) < opt.max_in_flight else None
                if handed is None:
                    return
                ticket, theta = handed
                self._trials[trial_id] = ticket
                self._thetas[ticket] = np.asarray(theta).tobytes()
                self.peak_in_flight = max(self.peak_in_flight, len(opt.in_flight))
                assigned = (self._configuration(theta), None)
            del self._deferred[trial_id]
            self._broker_handle().put.remote(trial_id, assigned)

    def _configuration(self, theta: Sequence[float]) -> Dict[str, Any]:
        flat = dict(self._constants)
        flat.update((n, sc.value(float(x))) for n, sc, x in zip(self._names, self._scales, theta))
        return unflatten_dict(flat)

    def _sign(self) -> float:
        return -1.0 if self._mode == "max" else 1.0

    def on_trial_complete(self, trial_id: str, result: Optional[Dict] = None, error: bool = False) -> None:
        if self._deferred.pop(trial_id, 0) is None:  # ended before it had a candidate
            return
        try:
            self._complete(trial_id, result, error)
        finally:
            self._resolve_deferred()

    def _complete(self, trial_id: str, result: Optional[Dict], error: bool) -> None:
        if trial_id in self._point_trials:
            point = self._point_trials.pop(trial_id)
            value = None if error or not result else result.get(self._metric)
            self.add_evaluated_point(point, value, error=_finite_cost(value) is None)
            return
        ticket = self._trials.pop(trial_id, None)
        if ticket is None:  # not handed out by this searcher (or already completed)
            return
        opt = self._optimizer
        # A cancelled candidate comes back under a new ticket: failures are counted by θ.
        key = self._thetas.pop(ticket, b"")
        value = None if error or not result else result.get(self._metric)
        cost = _finite_cost(value)
        if cost is None:
            failures = self._failures.get(key, 0) + 1
            penalty = self._failure_value
            if penalty is None and self._worst is not None:
                penalty = self._sign() * self._worst
            if failures <= self._max_retries or penalty is None:
                self._failures[key] = failures
                opt.cancel(ticket)
                self.cancelled += 1
                return
            self._failures.pop(key, None)
            value = cost = float(penalty)
            self.penalised.append((trial_id, value))
            logger.warning(
                "CtrlAdaptSearch: trial %s failed %d times on one candidate; reported at %s",
                trial_id, failures, value,
            )
        try:
            opt.report(ticket, self._sign() * cost)
        except ctrl_adapt.OptimizerError:
            if opt.status == "running":
                raise
            logger.info("CtrlAdaptSearch: trial %s completed after the optimizer stopped", trial_id)
            return
        signed = self._sign() * cost
        self._worst = signed if self._worst is None else max(self._worst, signed)
        self.history.append((trial_id, float(value)))

    def add_evaluated_point(
        self,
        parameters: Dict,
        value: float,
        error: bool = False,
        pruned: bool = False,
        intermediate_values: Optional[List[float]] = None,
    ) -> None:
        """A configuration evaluated outside this searcher and its metric: kept in
        :attr:`evaluated_points` and compared by :meth:`best` (the optimizer's state, the
        firmware's type, takes costs only of the candidates it proposed, so it does not
        steer the search). Ignored if ``error`` or the value is not finite."""
        if error or _finite_cost(value) is None:
            return
        self.evaluated_points.append((dict(parameters), float(value)))

    def best(self) -> Optional[Tuple[Dict[str, Any], float]]:
        """The best configuration reported so far (the optimizer's candidates and the
        :attr:`evaluated_points`) and its metric, or ``None``."""
        found = []
        best = self._optimizer.best() if self._optimizer is not None else None
        if best is not None:
            theta, cost = best
            found.append((self._configuration(theta), cost))
        for point, value in self.evaluated_points:
            flat = dict(self._constants)
            flat.update(flatten_dict(point, delimiter="/"))
            found.append((unflatten_dict(flat), self._sign() * value))
        if not found:
            return None
        config, cost = min(found, key=lambda pair: pair[1])
        return config, self._sign() * cost

    def recommend(self) -> Optional[Dict[str, Any]]:
        """The configuration the optimizer recommends deploying
        (:meth:`ctrl_adapt.Optimizer.recommend`: CMA-ES's or CEM's mean, ROCK*'s θ*, ...),
        which may not have been run; ``None`` before any result."""
        theta = self._optimizer.recommend() if self._optimizer is not None else None
        return None if theta is None else self._configuration(theta)

    def write_record(self, path: Union[str, os.PathLike]) -> str:
        """Write the optimizer's state as a record for the firmware (see :func:`write_record`)
        and return its Rust type. Raises ``ValueError`` while a trial is running or a
        cancelled candidate waits to be handed out again: the optimizer's record then holds
        its tickets, which the firmware's type does not load."""
        return write_record(self._optimizer, path)

    # -- checkpoints ----------------------------------------------------------------------

    def get_state(self) -> Dict[str, Any]:
        opt = self._optimizer
        state = {k: v for k, v in self.__dict__.items() if k not in ("_optimizer", "_broker")}
        state["version"] = _STATE_VERSION
        state["record"] = None if opt is None else opt.save()
        state["evaluations"] = 0 if opt is None else opt.evaluations
        return state

    def set_state(self, state: Dict[str, Any]) -> None:
        kind = type(self._optimizer) if getattr(self, "_optimizer", None) is not None else ctrl_adapt.Optimizer
        self._apply_state(state, kind)

    def _apply_state(self, state: Dict[str, Any], kind: type) -> None:
        state = dict(state)
        if state.pop("version", None) != _STATE_VERSION:
            raise ValueError("CtrlAdaptSearch: not a checkpoint of this searcher version")
        record, evaluations = state.pop("record"), state.pop("evaluations")
        self.__dict__.update(state)
        self._broker = None  # found again by name when a deferred trial needs it
        # The RNG is not in the record: a restored search draws from seed + evaluations, so
        # it does not replay the draws it made before the checkpoint.
        self._optimizer = None if record is None else kind.load(record, self._seed + evaluations)

    def save(self, checkpoint_path: str) -> None:
        """The optimizer's record, the trial → ticket map and the search's settings, pickled."""
        with open(checkpoint_path, "wb") as f:
            pickle.dump(self.get_state(), f)

    def restore(self, checkpoint_path: str) -> None:
        """Continue from :meth:`save`'s file; trials in flight at the checkpoint are still
        accepted by ``on_trial_complete``."""
        with open(checkpoint_path, "rb") as f:
            self.set_state(pickle.load(f))

    def __getstate__(self) -> Dict[str, Any]:
        # The native optimizer crosses processes as its record.
        state = self.get_state()
        state["_kind"] = type(self._optimizer) if self._optimizer is not None else None
        return state

    def __setstate__(self, state: Dict[str, Any]) -> None:
        state = dict(state)
        kind = state.pop("_kind", None)
        self._apply_state(state, kind or ctrl_adapt.Optimizer)
