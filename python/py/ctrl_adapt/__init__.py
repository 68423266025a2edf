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

__all__ = [
    "Optimizer",
    "OptimizerError",
    "RecordError",
    "algorithms",
    "rust_type",
    "MAX_DIMENSION",
    "MAX_IN_FLIGHT",
    "FORMAT_VERSION",
]


def _vector(values, name):
    if values is None:
        return None
    array = _np.ascontiguousarray(values, dtype=_np.float64).reshape(-1)
    return array


class Optimizer:
    """One of the library's optimizers (``algorithms()`` lists the names) over the box
    ``[lower, upper]`` (1 to ``MAX_DIMENSION`` parameters).

    ``start`` is θ⁰ for the algorithms that start from one (default: the box's centre);
    ``seed`` seeds the optimizer's own xoshiro128++ RNG, as ``Xoshiro128PlusPlus::
    seed_from_u64`` does in Rust. Keyword arguments set fields of the algorithm's Rust
    configuration (e.g. ``CoordinateConfig``'s ``initial_step``, ``max_evaluations``);
    for ``"two-phase"``: ``global_budget``, ``global`` (a dict of ``CrsConfig`` fields) and
    ``local`` (a dict of ``CoordinateConfig`` fields). An unknown field, a value out of its
    range or a non-finite cost raises :class:`OptimizerError` with the library's message.

    Sequentially: ``theta = opt.ask()``, run the episode, ``opt.tell(cost)``. In parallel
    (a generation evaluated by several workers): ``ticket, theta = opt.suggest()`` as long
    as it returns a pair (``None``: report outstanding tickets first), then
    ``opt.report(ticket, cost)`` in any order, or ``opt.cancel(ticket)`` for a failed
    trial (its candidate is suggested again). The costs reach the optimizer in hand-out
    order, so the result is bit for bit the sequential one. ``ask``/``tell`` raise while
    tickets are outstanding; :meth:`save` works at any time.
    """

    __slots__ = ("_native", "ask", "tell", "best", "pending", "suggest", "report", "cancel")

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
        self.pending = native.pending
        self.suggest = native.suggest
        self.report = native.report
        self.cancel = native.cancel

    @classmethod
    def load(cls, record, seed=0):
        """The optimizer a record holds (saved from Python or from firmware), with a new
        RNG seeded by ``seed``."""
        self = cls.__new__(cls)
        self._bind(_Native.load(bytes(record), int(seed)))
        return self

    def save(self):
        """The state as a record of :attr:`rust_type` (bytes; the RNG is not in it). With
        tickets outstanding it also holds them (``InFlight<rust_type, n, 64>``, which
        :meth:`load` restores, ready for their ``report``); firmware loads records saved
        with nothing in flight (:attr:`idle`)."""
        return self._native.save()

    def copy(self):
        """A copy in the same state, RNG included."""
        other = type(self).__new__(type(self))
        other._bind(self._native.copy())
        return other

    @property
    def algorithm(self):
        return self._native.algorithm

    @property
    def dimension(self):
        return self._native.dimension

    @property
    def rust_type(self):
        return self._native.rust_type

    @property
    def evaluations(self):
        return self._native.evaluations

    @property
    def status(self):
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
