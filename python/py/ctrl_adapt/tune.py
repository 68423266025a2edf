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
        search_alg=search, num_samples=200, reuse_actors=True)).fit()
    search.write_record("global.rec")   # -> "Cmaes<2, 6>", the type the firmware loads

``reuse_actors=True`` keeps Ray's cost per trial at a fraction of a second; without it,
each trial starts a worker process (seconds).

Failed trials. A trial that raised, or whose result lacks the metric or holds a non-finite
one (NaN, ±inf, or beyond float32), did not measure its candidate. By default its ticket is
*cancelled*: the optimizer hands the same candidate out again to a later trial, so a crash
of one simulator worker loses no candidate and biases nothing (a candidate that fails every
time is retried until Tune's ``num_samples`` runs out). With ``penalty=`` a value of the
metric, the failed trial is *reported* with that value instead (for simulators where a
failure means the candidate is bad, e.g. a physics blow-up).
"""

from __future__ import annotations

import logging
import math
import os
import pickle
import tempfile
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
from ray.tune.search import UNDEFINED_METRIC_MODE, UNDEFINED_SEARCH_SPACE, Searcher
from ray.tune.search.sample import Float, Uniform
from ray.tune.search.variant_generator import parse_spec_vars
from ray.tune.utils.util import unflatten_dict

import ctrl_adapt

__all__ = ["CtrlAdaptSearch", "write_record"]

logger = logging.getLogger(__name__)

_F32_MAX = float(np.finfo(np.float32).max)
_STATE_VERSION = 1

#: A search space: each parameter's name (``"a/b"`` for a nested one) and either its
#: ``(lower, upper)`` bounds or a ``tune.uniform(lower, upper)``; other values are passed
#: through to every trial's configuration unchanged.
Space = Mapping[str, Any]


def write_record(optimizer: "ctrl_adapt.Optimizer", path: Union[str, os.PathLike]) -> str:
    """Write ``optimizer``'s state, a record of its Rust type, to ``path`` for the firmware,
    atomically (a temporary file renamed over ``path``), and return the Rust type's name.

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
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".record-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise
    return optimizer.rust_type


def _finite_cost(value: Any) -> Optional[float]:
    """``value`` as a cost the library accepts (finite in float32), or ``None``."""
    try:
        cost = float(value)
    except (TypeError, ValueError):
        return None
    return cost if math.isfinite(cost) and abs(cost) <= _F32_MAX else None


def _parse_space(space: Space) -> Tuple[List[str], List[float], List[float], Dict[str, Any]]:
    """Names, lower and upper bounds of the searched parameters, and the constant entries."""

    def ranges(value: Any) -> Any:  # (lower, upper) → a uniform float domain, at any depth
        if isinstance(value, Mapping):
            return {name: ranges(v) for name, v in value.items()}
        if isinstance(value, tuple) and len(value) == 2:
            return Float(float(value[0]), float(value[1])).uniform()
        return value

    constants, domains, grids = parse_spec_vars(ranges(space))
    if grids:
        raise ValueError("CtrlAdaptSearch: grid_search parameters cannot be searched")
    names, lower, upper = [], [], []
    for path, domain in domains:
        name = "/".join(path)
        if not (isinstance(domain, Float) and isinstance(domain.get_sampler(), Uniform)):
            raise ValueError(
                f"CtrlAdaptSearch: parameter `{name}` must be a float range, (lower, upper) or "
                f"tune.uniform(lower, upper); got {type(domain).__name__}"
            )
        names.append(name)
        lower.append(float(domain.lower))
        upper.append(float(domain.upper))
    return names, lower, upper, {"/".join(map(str, path)): value for path, value in constants}


class CtrlAdaptSearch(Searcher):
    """A Ray Tune searcher handing out the candidates of a :class:`ctrl_adapt.Optimizer`.

    ``space`` maps parameter names to ``(lower, upper)`` or ``tune.uniform(lower, upper)``
    (or comes from the Tuner's ``param_space``). The optimizer is either given
    (``optimizer=``, built over the same box, its dimension the number of parameters) or
    built from ``algorithm``, the space's bounds, ``start`` (a dict by name or a vector),
    ``seed`` and ``config`` (fields of the algorithm's configuration, as for
    :class:`ctrl_adapt.Optimizer`). ``mode="max"`` reports ``-metric`` as the cost.

    ``suggest`` returns a trial's configuration, ``None`` while the optimizer has
    ``max_in_flight`` candidates out (or cannot hand out more before some are reported), and
    ``Searcher.FINISHED`` once it has stopped (converged or its budget spent). A failed trial
    is cancelled (its candidate handed out again) or, with ``penalty``, reported with that
    value of the metric. ``save``/``restore`` go through the optimizer's record and the
    trial → ticket map, so trials still running at a checkpoint are accepted after it.
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
        penalty: Optional[float] = None,
        **config: Any,
    ) -> None:
        super().__init__(metric=metric, mode=mode)
        if penalty is not None and _finite_cost(penalty) is None:
            raise ValueError(f"CtrlAdaptSearch: penalty must be finite in float32, got {penalty!r}")
        self._optimizer = optimizer
        self._algorithm = algorithm
        self._start = start
        self._seed = int(seed)
        self._config = config
        self._penalty = penalty
        self._names: List[str] = []
        self._constants: Dict[str, Any] = {}
        self._trials: Dict[str, int] = {}
        #: ``(trial_id, metric)`` of every reported trial, in the order reported.
        self.history: List[Tuple[str, float]] = []
        #: Trials whose candidate was cancelled (failed, no finite metric) and handed out again.
        self.cancelled = 0
        #: The most candidates that were out at once.
        self.peak_in_flight = 0
        if space:
            self._set_space(space)

    # -- setting up -----------------------------------------------------------------------

    def _set_space(self, space: Space) -> None:
        names, lower, upper, constants = _parse_space(space)
        if not names:
            raise ValueError("CtrlAdaptSearch: the space has no parameter to search")
        if self._optimizer is None:
            start = self._start
            if isinstance(start, Mapping):
                missing = set(names) - set(start)
                if missing:
                    raise ValueError(f"CtrlAdaptSearch: start has no value for {sorted(missing)}")
                start = [start[name] for name in names]
            self._optimizer = ctrl_adapt.Optimizer(
                self._algorithm, np.array(lower), np.array(upper), start, seed=self._seed, **self._config
            )
        elif self._optimizer.dimension != len(names):
            raise ValueError(
                f"CtrlAdaptSearch: the optimizer has {self._optimizer.dimension} parameters, "
                f"the space {len(names)} ({names})"
            )
        self._names, self._constants = names, constants

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
        if opt.status != "running":
            return Searcher.FINISHED
        if len(opt.in_flight) >= opt.max_in_flight:
            return None
        handed = opt.suggest()
        if handed is None:
            return None
        ticket, theta = handed
        self._trials[trial_id] = ticket
        self.peak_in_flight = max(self.peak_in_flight, len(opt.in_flight))
        return self._configuration(theta)

    def _configuration(self, theta: Sequence[float]) -> Dict[str, Any]:
        flat = dict(self._constants)
        flat.update(zip(self._names, (float(x) for x in theta)))
        return unflatten_dict(flat)

    def _sign(self) -> float:
        return -1.0 if self._mode == "max" else 1.0

    def on_trial_complete(self, trial_id: str, result: Optional[Dict] = None, error: bool = False) -> None:
        ticket = self._trials.pop(trial_id, None)
        if ticket is None:  # not handed out by this searcher (or already completed)
            return
        opt = self._optimizer
        value = None if error or not result else result.get(self._metric)
        cost = _finite_cost(value)
        if cost is None and self._penalty is None:
            opt.cancel(ticket)
            self.cancelled += 1
            return
        if cost is None:
            value = cost = float(self._penalty)
        try:
            opt.report(ticket, self._sign() * cost)
        except ctrl_adapt.OptimizerError:
            if opt.status == "running":
                raise
            logger.info("CtrlAdaptSearch: trial %s completed after the optimizer stopped", trial_id)
            return
        self.history.append((trial_id, float(value)))

    def best(self) -> Optional[Tuple[Dict[str, Any], float]]:
        """The best configuration reported so far and its metric, or ``None``."""
        best = self._optimizer.best() if self._optimizer is not None else None
        if best is None:
            return None
        theta, cost = best
        return self._configuration(theta), self._sign() * cost

    def write_record(self, path: Union[str, os.PathLike]) -> str:
        """Write the optimizer's state as a record for the firmware (see :func:`write_record`)
        and return its Rust type. Raises ``ValueError`` while a trial is running or a
        cancelled candidate waits to be handed out again: the optimizer's record then holds
        its tickets, which the firmware's type does not load."""
        return write_record(self._optimizer, path)

    # -- checkpoints ----------------------------------------------------------------------

    def get_state(self) -> Dict[str, Any]:
        opt = self._optimizer
        state = {k: v for k, v in self.__dict__.items() if k != "_optimizer"}
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
