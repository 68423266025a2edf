"""The runtime guard: hand the rest of an episode back to the nominal controller when a
candidate θ misbehaves, tick by tick, in a loop you write.

The guard is the firmware library's own ``Guard<L, T>`` (``guard.rust_type`` names it),
driven from Python: each tick your loop asks :meth:`Guard.check` whether the nominal
controller must run, with the state, the running cost and, if you declared limits on it,
a safety signal. It checks

1. **limits**: a box ``low ≤ value ≤ high`` per coordinate, on a state coordinate
   (``Limit.state(k, ...)``) or on an entry of a signal you compute
   (``Limit.signal(k, ...)``). A value outside its box, not finite, or missing (a signal
   shorter than the index) violates the limit;
2. **the envelope** (with ``horizon > 0``): the running cost against the highest running
   cost at the same tick of the bare episodes (``begin("nominal")``) it has seen, plus the
   margins: ``threshold(t) = e(t) + w(t)·(relative_margin·|e(t)| + absolute_margin)``, the
   weight ``w(t)`` falling linearly from 1 at the first tick to ``margin_taper`` at the last
   (1, constant margins, by default). Ticks no bare episode reached are not checked, nor is
   any tick before the first bare episode.

It trips after ``limit_ticks`` consecutive ticks beyond some limit, or ``envelope_ticks``
consecutive ticks above the envelope (hysteresis: with 2 or more, one noisy tick never
trips it). The tripping tick and every later tick of the episode return ``True``: run your
nominal controller. A bare episode is never handed over (it teaches the envelope).

A tripped learning episode should be told :meth:`GuardReport.told`: the failure cost plus
a share of ``tripped_cost_span`` that is the share of the episode the nominal controller had
to run, so it ranks worse than any untripped episode and still says how far the θ got.

>>> import ctrl_adapt
>>> guard = ctrl_adapt.Guard([ctrl_adapt.Limit.state(1, -0.2, 0.2)], limit_ticks=2)
>>> guard.rust_type
'Guard<1, 0>'
>>> guard.begin("learn")
>>> [guard.check([0.0, a]) for a in (0.1, 0.3, 0.1, 0.3, 0.3, 0.0)]
[False, False, False, False, True, True]
>>> report = guard.end()
>>> report.trip
Trip(tick=4, reason='limit', limit=0, cost=nan)
>>> report.told(cost=0.4, failure_cost=1.0)   # 1 + 1.0 · (6 - 4) / 6
1.3333333730697632
"""

import math as _math
from typing import NamedTuple, Optional

from ._native import GUARD_HORIZONS as HORIZONS
from ._native import GUARD_MAX_HORIZON as MAX_HORIZON
from ._native import GUARD_MAX_LIMITS as MAX_LIMITS
from ._native import GUARD_MAX_STATE as MAX_STATE
from ._native import Guard as _Native
from ._native import GuardError

__all__ = [
    "Guard",
    "GuardCounters",
    "GuardError",
    "GuardReport",
    "Limit",
    "Trip",
    "HORIZONS",
    "MAX_HORIZON",
    "MAX_LIMITS",
    "MAX_STATE",
]


class Limit(NamedTuple):
    """A box ``low ≤ value ≤ high`` on one coordinate: ``source`` ``"state"`` (the state's
    coordinate ``index``, below ``MAX_STATE``) or ``"signal"`` (the entry ``index`` of the
    signal passed to :meth:`Guard.check`). ``-inf`` / ``inf`` leave a side open; a NaN bound
    or ``low > high`` raises :class:`GuardError` when the guard is built.

    >>> Limit.state(1, -0.2, 0.2)
    Limit(source='state', index=1, low=-0.2, high=0.2)
    >>> Limit.signal(0, high=1.5).low
    -inf
    """

    source: str
    index: int
    low: float = -_math.inf
    high: float = _math.inf

    @classmethod
    def state(cls, index, low=-_math.inf, high=_math.inf):
        """A limit on the state's coordinate ``index``."""
        return cls("state", int(index), float(low), float(high))

    @classmethod
    def signal(cls, index, low=-_math.inf, high=_math.inf):
        """A limit on the signal's entry ``index``."""
        return cls("signal", int(index), float(low), float(high))


class Trip(NamedTuple):
    """When and why the guard handed an episode to the nominal controller: ``tick`` (from 0;
    it and every later tick ran the nominal controller), ``reason`` (``"limit"`` or
    ``"envelope"``), ``limit`` (the index in the guard's limits of the first one violated on
    the tripping tick, ``None`` for the envelope), ``cost`` (the running cost at that tick
    as float32; NaN when the envelope did not read it)."""

    tick: int
    reason: str
    limit: Optional[int]
    cost: float


class GuardCounters(NamedTuple):
    """What a guard has counted over its life (saved in its record): episodes guarded
    (``learn``, ``deploy``), bare episodes (``nominal``), episodes tripped by a limit and by
    the envelope, and ticks with some limit violated (of any episode, bare ones and ticks
    after a trip included)."""

    guarded_episodes: int
    bare_episodes: int
    limit_trips: int
    envelope_trips: int
    ticks_beyond_limits: int


class GuardReport:
    """One episode as the guard saw it (:meth:`Guard.end`): ``mode``, ``ticks`` (the ticks
    checked), ``trip`` (a :class:`Trip` or ``None``), ``ticks_beyond_limits``."""

    __slots__ = ("mode", "ticks", "trip", "ticks_beyond_limits", "_guard")

    def __init__(self, guard, mode, ticks, trip, beyond):
        self._guard = guard
        self.mode = mode
        self.ticks = ticks
        self.trip = None if trip is None else Trip(*trip)
        self.ticks_beyond_limits = beyond

    @property
    def tripped(self):
        """Whether the guard handed the episode over."""
        return self.trip is not None

    def told(self, cost, failure_cost, ticks=None):
        """The cost to tell the optimizer for this episode: ``cost`` (the episode's own) if
        the guard did not trip, else the library's tripped cost,
        ``failure_cost + tripped_cost_span · (ticks − trip.tick) / ticks`` (float32), above
        ``failure_cost`` and lower the later the trip.

        ``ticks`` is the episode's length for that share: by default the ticks checked; pass
        the planned length if the episode can end early (a fall that ends a simulator
        episode would otherwise make an early trip look late). Choose ``failure_cost`` at
        least the cost of any untripped episode, so that a tripped one ranks worse.

        Raises :class:`GuardError` for a non-finite ``failure_cost``, or one that the span
        cannot be added to in float32.

        >>> g = Guard([Limit.state(0, high=1.0)], limit_ticks=1, tripped_cost_span=2.0)
        >>> g.begin("learn"); g.check([5.0]); r = g.end()
        True
        >>> r.told(cost=0.7, failure_cost=3.0, ticks=100)
        5.0
        """
        if self.trip is None:
            return float(cost)
        return self._guard.tripped_cost(failure_cost, self.trip.tick,
                                        self.ticks if ticks is None else ticks)

    def __repr__(self):
        return (f"GuardReport(mode={self.mode!r}, ticks={self.ticks}, trip={self.trip!r}, "
                f"ticks_beyond_limits={self.ticks_beyond_limits})")


def _limit(value):
    if isinstance(value, Limit):
        return value
    try:
        limit = Limit(*value)
    except TypeError as e:
        raise GuardError(
            f"a limit must be a Limit or a tuple (source, index[, low[, high]]), got {value!r}"
        ) from e
    return limit


def _int(value, name):
    if isinstance(value, bool) or not isinstance(value, int) and not hasattr(value, "__index__"):
        raise GuardError(f"{name} must be an integer, got {value!r}")
    return int(value)


class Guard:
    """The runtime guard ``Guard<L, T>`` of the library (see the module docs), for a loop
    you write: ``begin(mode)``, then :meth:`check` every tick, then :meth:`end`.

    Arguments: ``limits`` (up to ``MAX_LIMITS`` = 8 :class:`Limit`\\ s, or tuples
    ``(source, index, low, high)``); ``horizon`` (the ticks the envelope covers, up to
    ``MAX_HORIZON`` = 4096; 0, the default, is no envelope and no running cost to pass; the
    package rounds it up to one of ``HORIZONS``, which is the ``T`` of the Rust type);
    ``limit_ticks`` and ``envelope_ticks`` (the hysteresis: consecutive ticks beyond a limit
    / above the envelope that trip it, at least 1; default 2); ``relative_margin`` and
    ``absolute_margin`` (the envelope's margins, finite, at least 0; default 0.1 and 0);
    ``margin_taper`` (the fraction of both margins left at the envelope's last tick, from 0
    to 1; default 1, constant margins: below 1 the guard is lenient early, where a good
    candidate may still lag the nominal controller, and strict late); ``tripped_cost_span`` (what a trip at tick 0 adds to the failure cost, finite, above 0;
    default 1). The defaults are the library's ``GuardConfig::DEFAULT``.

    Raises :class:`GuardError` (a ``ValueError``) naming the argument for more limits or a
    longer horizon than the package holds, a state index from ``MAX_STATE`` = 64 on (pass
    that value as a signal), an unknown source, a NaN bound or ``low > high``, a count below
    1, a negative or non-finite margin, a taper outside [0, 1], a span not above 0.

    In a Gymnasium loop (the nominal controller ``pd``, the learned correction ``corr``)::

        guard = Guard([Limit.state(1, -0.1, 0.1)], horizon=1000)  # the pole's angle
        for mode in ("nominal",) * 3 + ("learn",) * 50:           # bare episodes first
            theta = opt.ask() if mode == "learn" else None
            guard.begin(mode)
            obs, _ = env.reset(seed=...); running = 0.0
            for t in range(1000):
                running += stage_cost(obs)
                handed = guard.check(obs, cost=running)  # every tick, bare ones too
                if handed or mode == "nominal":
                    u = pd(obs)                   # handed back (or a bare episode)
                else:
                    u = pd(obs) + corr(theta, obs)
                obs, _, fell, _, _ = env.step(u)
                ...
            report = guard.end()
            if mode == "learn":
                opt.tell(report.told(episode_cost, failure_cost=2.0, ticks=1000))

    (Call :meth:`check` in bare episodes too: they teach the envelope and count ticks
    beyond the limits; it then always returns ``False``.)

    >>> g = Guard([Limit.signal(0, high=1.0)], horizon=3, relative_margin=0.0, limit_ticks=1)
    >>> g.rust_type, g.horizon
    ('Guard<1, 64>', 64)
    >>> g.begin("nominal")
    >>> [g.check([0.0], cost=c, signal=[0.0]) for c in (1.0, 2.0, 3.0)]
    [False, False, False]
    >>> g.end().trip is None
    True
    >>> g.begin("learn")
    >>> [g.check([0.0], cost=c, signal=[0.0]) for c in (1.0, 5.0, 9.0)]
    [False, False, True]
    >>> g.end().trip.reason
    'envelope'
    """

    # The instance binds the native check over the documented one (no Python frame per tick).
    __slots__ = ("_native", "__dict__")

    def __init__(self, limits=(), *, horizon=0, limit_ticks=2, envelope_ticks=2,
                 relative_margin=0.1, absolute_margin=0.0, margin_taper=1.0,
                 tripped_cost_span=1.0):
        limits = [_limit(l) for l in limits]
        raw = []
        for i, l in enumerate(limits):
            if not isinstance(l.source, str):
                raise GuardError(f"limit {i}: source must be 'state' or 'signal', got {l.source!r}")
            try:
                raw.append((l.source, _int(l.index, f"limit {i}: index"), float(l.low), float(l.high)))
            except (TypeError, ValueError) as e:
                if isinstance(e, GuardError):
                    raise
                raise GuardError(f"limit {i}: {e}") from e
        self._bind(_Native(
            raw,
            _int(horizon, "horizon"),
            _int(limit_ticks, "limit_ticks"),
            _int(envelope_ticks, "envelope_ticks"),
            float(relative_margin),
            float(absolute_margin),
            float(margin_taper),
            float(tripped_cost_span),
        ))

    def _bind(self, native):
        self._native = native
        # The native method itself: no Python frame per tick.
        self.check = native.check

    def begin(self, mode="learn"):
        """Starts an episode: ``"learn"`` (a candidate θ: guarded), ``"deploy"`` (the θ
        learned: guarded), or ``"nominal"`` (the bare nominal controller: never handed over;
        its running costs teach the envelope). Raises :class:`GuardError` for another mode
        or while an episode is running."""
        self._native.begin(mode)

    def check(self, state, cost=None, signal=None):
        """One tick: ``True`` if the nominal controller must run it (the guard tripped on
        this tick or an earlier one of the episode), ``False`` to run the corrected one.

        ``state``: the state (a vector; at least as long as the state limits need, any
        longer part is not read). ``cost``: the episode's running cost including this tick
        (required with an envelope, ignored without one); compute it the same way in bare
        and guarded episodes. ``signal``: the values the ``"signal"`` limits read.

        Non-finite values are data, not errors, as in the library: a NaN or infinite state
        or signal value violates its limit (a simulator that diverged trips the guard), a
        NaN running cost counts as above the envelope (in a bare episode it leaves that tick
        unchecked). Raises :class:`GuardError` outside an episode, for a state shorter than
        a limit reads, a missing cost with an envelope, or values that are not numbers.

        >>> g = Guard([Limit.state(0, -1.0, 1.0)], limit_ticks=1)
        >>> g.begin("deploy"); g.check([float("nan")])
        True
        """
        return self._native.check(state, cost, signal)

    def end(self):
        """Ends the episode and returns its :class:`GuardReport` (whether, when and why it
        tripped; its ticks beyond limits). Raises :class:`GuardError` without an episode."""
        return GuardReport(self._native, *self._native.end())

    @property
    def counters(self):
        """The :class:`GuardCounters` over the guard's life."""
        return GuardCounters(*self._native.counters())

    def envelope(self):
        """The learned envelope, one value per tick of the compiled horizon: the highest
        running cost of the bare episodes at that tick, rounded up to bfloat16 (at most
        0.8 % looser, never tighter); ``-inf`` where no bare episode reached."""
        return self._native.envelope()

    def thresholds(self):
        """The running cost allowed per tick, margins included; ``inf`` where unchecked."""
        return self._native.thresholds()

    def clear_envelope(self):
        """Forgets the envelope (a new plant, a new nominal controller: run bare episodes
        again). Raises :class:`GuardError` during an episode."""
        self._native.clear_envelope()

    def _config(self):
        return self._native.config()

    @property
    def limits(self):
        """The limits, as held (float32 bounds)."""
        return [Limit(*l) for l in self._config()[0]]

    @property
    def horizon(self):
        """The envelope's ticks, ``T`` (the horizon asked for, rounded up to ``HORIZONS``)."""
        return self._config()[1]

    @property
    def limit_ticks(self):
        """Consecutive ticks beyond some limit that trip the guard."""
        return self._config()[2]

    @property
    def envelope_ticks(self):
        """Consecutive ticks above the envelope that trip the guard."""
        return self._config()[3]

    @property
    def relative_margin(self):
        """The envelope's relative margin."""
        return self._config()[4]

    @property
    def absolute_margin(self):
        """The envelope's absolute margin."""
        return self._config()[5]

    @property
    def margin_taper(self):
        """The fraction of the margins left at the envelope's last tick (1: constant)."""
        return self._config()[6]

    @property
    def tripped_cost_span(self):
        """What a trip at tick 0 adds to the failure cost."""
        return self._config()[7]

    @property
    def rust_type(self):
        """The Rust type, ``Guard<L, T>``: what firmware declares to load :meth:`save`'s
        record."""
        return self._native.rust_type

    @property
    def mode(self):
        """The running episode's mode, or ``None`` between episodes."""
        return self._native.mode

    @property
    def ticks(self):
        """Ticks checked so far in the running episode (0 between episodes)."""
        return self._native.ticks

    def tripped_cost(self, failure_cost, tick, ticks):
        """The library's ``tripped_cost(failure_cost, tripped_cost_span, tick, ticks)``
        (see :meth:`GuardReport.told`)."""
        return self._native.tripped_cost(failure_cost, tick, ticks)

    def save(self):
        """The guard's state (configuration, envelope, counters) as a record of
        :attr:`rust_type`, which :meth:`load` and firmware
        (``ctrl_adapt::record::load::<Guard<L, T>>``) read. Raises :class:`GuardError`
        during an episode."""
        return self._native.save()

    @classmethod
    def load(cls, record):
        """The guard a record holds (from :meth:`save`, or saved by firmware, of any sizes
        the package compiles). Raises :class:`RecordError` for a corrupt, foreign or invalid
        record.

        >>> g = Guard([Limit.state(0, -1.0, 1.0)], horizon=100)
        >>> Guard.load(g.save()).save() == g.save()
        True
        """
        self = cls.__new__(cls)
        self._bind(_Native.load(bytes(record)))
        return self

    def copy(self):
        """A copy in the same state (a running episode included)."""
        other = type(self).__new__(type(self))
        other._bind(self._native.copy())
        return other

    def __copy__(self):
        return self.copy()

    def __deepcopy__(self, memo):
        return self.copy()

    def __repr__(self):
        c = self.counters
        return (f"Guard({self.rust_type}, limits={len(self.limits)}, horizon={self.horizon}, "
                f"guarded_episodes={c.guarded_episodes}, bare_episodes={c.bare_episodes})")
