"""A pure-Python stand-in for the in-flight API (``suggest``/``report``/``cancel``) over the
sequential ``ask``/``tell``, with capacity 1, for testing the Ray Tune searcher until the
package's own in-flight API is there. Tests only.

The ticket is the number of costs told before it; ``save`` is the library's record, and a
candidate pending in a loaded record is in flight (a record saved after a ``cancel`` would
not say so: no test does that)."""

import ctrl_adapt
from ctrl_adapt import Optimizer as _Optimizer


class SequentialStandIn:
    """``ctrl_adapt.Optimizer`` seen through the in-flight API, one ticket at a time."""

    max_in_flight = 1

    def __init__(self, *args, **kwargs):
        self._opt = _Optimizer(*args, **kwargs)
        self._out = None

    def suggest(self):
        if self._opt.status != "running":
            raise ctrl_adapt.OptimizerError(f"the optimizer has stopped ({self._opt.status})")
        if self._out is not None:
            return None
        pending = self._opt.pending()  # a cancelled candidate is handed out again
        theta = pending if pending is not None else self._opt.ask()
        self._out = self._opt.evaluations
        return self._out, theta

    def report(self, ticket, cost):
        if ticket != self._out:
            raise ctrl_adapt.OptimizerError(f"ticket {ticket} is not in flight")
        self._opt.tell(cost)
        self._out = None

    def cancel(self, ticket):
        if ticket != self._out:
            raise ctrl_adapt.OptimizerError(f"ticket {ticket} is not in flight")
        self._out = None

    @property
    def in_flight(self):
        return [] if self._out is None else [self._out]

    @property
    def capacity(self):
        return int(self._out is None and self._opt.status == "running")

    def save(self):
        return self._opt.save()

    @classmethod
    def load(cls, record, seed=0):
        self = cls.__new__(cls)
        self._opt = _Optimizer.load(record, seed)
        self._out = None if self._opt.pending() is None else self._opt.evaluations
        return self

    def __getattr__(self, name):  # best, status, evaluations, dimension, rust_type, ...
        return getattr(self._opt, name)
