"""The optimizers of the ctrl-adapt firmware library, bit for bit, from Python.

Each :class:`Optimizer` *is* the Rust type the firmware runs (``opt.rust_type`` names it):
for the same seed, configuration and costs it proposes the same candidates, and its
:meth:`Optimizer.save` record is the one the firmware loads with
``ctrl_adapt::record::load``. Use it for the global phase in a simulator, then hand the
record to the board.

>>> import numpy as np, ctrl_adapt
>>> opt = ctrl_adapt.Optimizer("coordinate", lower=-np.ones(2), upper=np.ones(2),
...                            start=np.zeros(2), seed=1, initial_step=0.5)
>>> for _ in range(40):
...     theta = opt.ask()
...     opt.tell(float(np.sum((theta - 0.25) ** 2)))
>>> theta, cost = opt.best()
>>> bool(cost < 1e-3)
True
"""

import json as _json

import numpy as _np

from ._native import FORMAT_VERSION, MAX_DIMENSION, MAX_IN_FLIGHT, OptimizerError, RecordError
from ._native import Optimizer as _Native
from ._native import algorithms, rust_type
from .guard import Guard, GuardCounters, GuardError, GuardReport, Limit, Trip
from .model import ModelBased, ModelError, RlsModel

__all__ = [
    "Optimizer",
    "MinimizeResult",
    "minimize",
    "OptimizerError",
    "RecordError",
    "algorithms",
    "rust_type",
    "MAX_DIMENSION",
    "MAX_IN_FLIGHT",
    "FORMAT_VERSION",
    # The runtime guard (ctrl_adapt.guard).
    "Guard",
    "GuardCounters",
    "GuardError",
    "GuardReport",
    "Limit",
    "Trip",
    # The plant model and the model-based learner (ctrl_adapt.model).
    "RlsModel",
    "ModelBased",
    "ModelError",
]


def _vector(values, name):
    if values is None:
        return None
    array = _np.ascontiguousarray(values, dtype=_np.float64).reshape(-1)
    return array


class Optimizer:
    """One of the library's optimizers (``algorithms()`` lists the names) over the box
    ``[lower, upper]`` (1 to ``MAX_DIMENSION`` parameters).

    Arguments: ``algorithm`` (a name from :func:`algorithms`); ``lower``, ``upper`` (the
    bounds, one per parameter); ``start`` (θ⁰ for ``coordinate``, ``cem``, ``cmaes``,
    ``rockstar`` and ``linebo``; default the box's centre). For ``sracos``, ``crs`` and
    ``two-phase``, which begin with a uniform sample of the box, a ``start`` is their
    first sample only: the first ``ask`` (or ``suggest``) hands it out, then they sample
    the box as without it (it is the Rust type's pending candidate, so a record saved
    before it is asked holds it). ``seed`` seeds the optimizer's own
    xoshiro128++ RNG, as ``Xoshiro128PlusPlus::seed_from_u64`` does in Rust. Keyword
    arguments set fields of the algorithm's Rust configuration (e.g. ``CoordinateConfig``'s
    ``initial_step``, ``max_evaluations``); for ``"two-phase"``: ``global_budget``,
    ``global`` (a dict of ``CrsConfig`` fields) and ``local`` (a dict of
    ``CoordinateConfig`` fields).

    Raises :class:`OptimizerError` (a ``ValueError``) with the library's message for an
    unknown algorithm or field, a value out of its range, mismatched vector lengths.

    Sequentially: ``theta = opt.ask()``, run the episode, ``opt.tell(cost)``. In parallel
    (a generation evaluated by several workers): ``ticket, theta = opt.suggest()`` as long
    as it returns a pair (``None``: report outstanding tickets first), then
    ``opt.report(ticket, cost)`` in any order, or ``opt.cancel(ticket)`` for a failed
    trial (its candidate is suggested again). The costs reach the optimizer in hand-out
    order, so the result is bit for bit the sequential one. ``ask``/``tell`` raise while
    tickets are outstanding; :meth:`save` works at any time. :func:`minimize` runs a whole
    search; :mod:`ctrl_adapt.pool` evaluates generations on a process pool.

    >>> import numpy as np, ctrl_adapt
    >>> opt = ctrl_adapt.Optimizer("cmaes", -np.ones(3), np.ones(3), seed=1)
    >>> opt.rust_type
    'Cmaes<3, 7>'
    """

    # No __slots__ for the methods: each instance binds the native methods over the
    # documented ones below (no Python frame per call); help(Optimizer) shows these.
    __slots__ = ("_native", "__dict__")

    def __init__(self, algorithm, lower, upper, start=None, *, seed=0, **config):
        native = _Native(
            algorithm,
            _vector(lower, "lower"),
            _vector(upper, "upper"),
            _vector(start, "start"),
            int(seed),
            _json.dumps(config),
        )
        self._bind(native)

    def _bind(self, native):
        self._native = native
        # The native methods themselves: no Python frame per call.
        self.ask = native.ask
        self.tell = native.tell
        self.best = native.best
        self.recommend = native.recommend
        self.pending = native.pending
        self.suggest = native.suggest
        self.report = native.report
        self.cancel = native.cancel

    # The methods below document the native ones each instance binds in their place.

    def ask(self):
        """The next candidate θ to evaluate, a float64 array (the library's float32 values).

        One candidate at a time: raises :class:`OptimizerError` while a candidate is
        pending (asked and not yet told; :meth:`pending` returns it) and while tickets of
        :meth:`suggest` are outstanding. Use :meth:`suggest`/:meth:`report` to have
        several candidates in flight.

        >>> opt = Optimizer("coordinate", [-1.0], [1.0], seed=1)
        >>> theta = opt.ask(); opt.tell(float(theta[0] ** 2))
        """
        return self._native.ask()

    def tell(self, cost):
        """The cost of the pending candidate (a float; rounded to float32 as the firmware
        holds it; minimised).

        Raises :class:`OptimizerError`, changing nothing, without a pending candidate or
        for a non-finite cost (NaN, ±inf, beyond float32).

        >>> opt = Optimizer("cem", [-1.0, -1.0], [1.0, 1.0], seed=1)
        >>> opt.tell(float(sum(opt.ask() ** 2)))
        """
        return self._native.tell(cost)

    def best(self):
        """``(theta, cost)`` of the best candidate told so far, or ``None`` before any.

        >>> opt = Optimizer("coordinate", [-1.0], [1.0], seed=1)
        >>> opt.best() is None
        True
        """
        return self._native.best()

    def recommend(self):
        """The θ to deploy, which may not have been evaluated: the sampling distribution's
        mean for ``cem`` and ``cmaes``, ROCK*'s θ* (the regression's minimum) for
        ``rockstar``, the posterior mean's minimiser on the last line for ``linebo``; the
        best candidate told (as :meth:`best`) for the others, ``None`` before any.

        >>> opt = Optimizer("cmaes", [-1.0, -1.0], [1.0, 1.0], start=[0.5, 0.5], seed=1)
        >>> opt.recommend().tolist()
        [0.5, 0.5]
        """
        return self._native.recommend()

    def pending(self):
        """The candidate asked and not yet told, or ``None`` (e.g. after :meth:`load` of a
        record saved between ``ask`` and ``tell``)."""
        return self._native.pending()

    def suggest(self):
        """``(ticket, theta)``: a candidate to evaluate in parallel with the others in
        flight, or ``None`` while nothing more can be handed out before outstanding tickets
        are reported (a CMA-ES generation, a CEM batch: at most :attr:`max_in_flight`).

        Raises :class:`OptimizerError` once the optimizer has stopped, or while a
        candidate of :meth:`ask` is pending.

        >>> opt = Optimizer("cmaes", [-1.0, -1.0], [1.0, 1.0], seed=1)
        >>> out = [opt.suggest() for _ in range(opt.capacity)]
        >>> for ticket, theta in out: opt.report(ticket, float(sum(theta ** 2)))
        """
        return self._native.suggest()

    def report(self, ticket, cost):
        """The cost of ``ticket``'s candidate (from :meth:`suggest`), in any order; the
        optimizer takes a generation's costs in hand-out order, so the result is bit for
        bit the sequential one.

        Raises :class:`OptimizerError`, changing nothing, for a ticket not outstanding or a
        non-finite cost."""
        return self._native.report(ticket, cost)

    def cancel(self, ticket):
        """Gives ``ticket`` back (a failed evaluation): its candidate is handed out again by
        a later :meth:`suggest`, under a new ticket. Raises :class:`OptimizerError` for a
        ticket not outstanding."""
        return self._native.cancel(ticket)

    @classmethod
    def load(cls, record, seed=0):
        """The optimizer a record holds (bytes from :meth:`save`, or saved by firmware),
        with a new RNG seeded by ``seed``.

        Raises :class:`RecordError` for a record that is corrupt, of another format
        version, of a type or sizes this package does not have, or whose state is invalid.

        >>> opt = Optimizer("cmaes", [-1.0, -1.0], [1.0, 1.0], seed=1)
        >>> Optimizer.load(opt.save()).rust_type
        'Cmaes<2, 6>'
        """
        self = cls.__new__(cls)
        self._bind(_Native.load(bytes(record), int(seed)))
        return self

    def save(self):
        """The state as a record of :attr:`rust_type` (bytes; the RNG is not in it). With
        tickets outstanding it also holds them (``InFlight<rust_type, n, 64>``, which
        :meth:`load` restores, ready for their ``report``); firmware loads records saved
        with nothing in flight (:attr:`idle`). Raises :class:`RecordError` if the state
        cannot be encoded."""
        return self._native.save()

    def copy(self):
        """A copy in the same state, RNG included (``copy.copy`` and ``copy.deepcopy`` too)."""
        other = type(self).__new__(type(self))
        other._bind(self._native.copy())
        return other

    def __copy__(self):
        return self.copy()

    def __deepcopy__(self, memo):
        return self.copy()

    @property
    def algorithm(self):
        """The algorithm's name (one of :func:`algorithms`)."""
        return self._native.algorithm

    @property
    def dimension(self):
        """The number of parameters n."""
        return self._native.dimension

    @property
    def rust_type(self):
        """The Rust type this object is, as firmware declares it to load the records."""
        return self._native.rust_type

    @property
    def evaluations(self):
        """Costs told so far."""
        return self._native.evaluations

    @property
    def status(self):
        """``"running"``, ``"converged"`` or ``"budget_spent"``."""
        return self._native.status

    @property
    def in_flight(self):
        """The outstanding tickets (handed out by :meth:`suggest`, not yet reported or
        cancelled), in hand-out order."""
        return self._native.in_flight

    @property
    def idle(self):
        """Whether nothing is in flight: no ticket out, no cancelled candidate waiting to be
        handed out again, every reported cost told to the optimizer. Only then is
        :meth:`save` the record of :attr:`rust_type` that firmware loads (after a
        :meth:`cancel`, :attr:`in_flight` is empty but the candidate still waits)."""
        return self._native.idle

    @property
    def capacity(self):
        """How many more :meth:`suggest` calls would return a candidate now."""
        return self._native.capacity

    @property
    def max_in_flight(self):
        """The most candidates this optimizer can ever have outstanding at once: a CEM
        batch, a CMA-ES generation, CRS's initial set, ROCK*'s initial samples (at most
        ``MAX_IN_FLIGHT``); 1 for the sequential algorithms."""
        return self._native.max_in_flight

    def __repr__(self):
        return repr(self._native)


class MinimizeResult:
    """What :func:`minimize` found: ``theta`` (the best θ evaluated), ``cost`` (its cost),
    ``recommended`` (:meth:`Optimizer.recommend` at the end, e.g. CMA-ES's mean, which may
    not have been evaluated), ``evaluations``, ``status`` and the ``optimizer`` itself
    (save it for the firmware with :func:`ctrl_adapt.tune.write_record`)."""

    __slots__ = ("theta", "cost", "recommended", "evaluations", "status", "optimizer")

    def __init__(self, optimizer):
        best = optimizer.best()
        self.theta, self.cost = best if best is not None else (None, None)
        self.recommended = optimizer.recommend()
        self.evaluations = optimizer.evaluations
        self.status = optimizer.status
        self.optimizer = optimizer

    def __iter__(self):  # theta, cost = minimize(...)
        return iter((self.theta, self.cost))

    def __repr__(self):
        return (
            f"MinimizeResult(cost={self.cost!r}, theta={self.theta!r}, "
            f"evaluations={self.evaluations}, status={self.status!r})"
        )


def minimize(f, lower, upper, *, algorithm="cmaes", budget=200, seed=0, start=None, **config):
    """Minimise ``f(theta) -> float`` over the box ``[lower, upper]`` with ``budget``
    evaluations at most (fewer if the optimizer converges or its own budget ends first),
    sequentially, and return a :class:`MinimizeResult` (it unpacks as ``theta, cost``).

    ``algorithm``, ``seed``, ``start`` and the keyword arguments (configuration fields) are
    :class:`Optimizer`'s. A cost that is not a finite float32 raises
    :class:`OptimizerError` (nothing is told). For parallel evaluation see
    :mod:`ctrl_adapt.pool`.

    >>> import numpy as np, ctrl_adapt
    >>> r = ctrl_adapt.minimize(lambda t: float(np.sum((t - 0.3) ** 2)), -np.ones(2),
    ...                         np.ones(2), algorithm="cmaes", budget=300, seed=1)
    >>> bool(r.cost < 1e-4), r.optimizer.rust_type
    (True, 'Cmaes<2, 6>')
    """
    budget = int(budget)
    if budget < 1:
        raise ValueError(f"minimize: budget must be at least 1, got {budget}")
    opt = Optimizer(algorithm, lower, upper, start, seed=seed, **config)
    for _ in range(budget):
        if opt.status != "running":
            break
        theta = opt.ask()
        opt.tell(float(f(theta)))
    return MinimizeResult(opt)
