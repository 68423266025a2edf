"""The runtime guard from Python (ctrl_adapt.Guard, the library's Guard<L, T>): limits with
hysteresis, the envelope learned from bare episodes, the tripped cost, counters, records
that round-trip bit for bit, and every refusal a GuardError instead of a crash."""

import doctest
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

import ctrl_adapt
from ctrl_adapt import Guard, GuardError, Limit, RecordError
from ctrl_adapt import guard as guard_module


def angle_guard(**kw):
    return Guard([Limit.state(1, -0.2, 0.2)], **kw)


def test_one_noisy_tick_does_not_trip_two_do_and_the_rest_is_nominal():
    g = angle_guard(limit_ticks=2)
    assert g.rust_type == "Guard<1, 0>"
    g.begin("learn")
    angles = [0.1, 0.3, 0.1, 0.3, 0.3, 0.0, 0.0]
    verdicts = [g.check(np.array([0.0, a, 0.0, 0.0])) for a in angles]
    assert verdicts == [False, False, False, False, True, True, True]
    assert g.ticks == 7 and g.mode == "learn"
    report = g.end()
    assert report.trip == ctrl_adapt.Trip(tick=4, reason="limit", limit=0, cost=report.trip.cost)
    assert math.isnan(report.trip.cost)  # no envelope: the running cost was not read
    assert (report.mode, report.ticks, report.ticks_beyond_limits) == ("learn", 7, 3)
    assert g.counters == ctrl_adapt.GuardCounters(1, 0, 1, 0, 3)
    # The next episode starts untripped.
    g.begin("deploy")
    assert g.check([0.0, 0.1]) is False
    assert g.end().trip is None


def test_the_first_violated_limit_is_named_and_signals_trip_when_missing_or_not_finite():
    g = Guard([Limit.state(0, -1.0, 1.0), Limit.signal(1, high=2.0)], limit_ticks=1)
    for signal in ([0.0], [0.0, float("nan")], [0.0, 3.0], None):
        g.begin("learn")
        assert g.check([0.0], signal=signal) is True
        assert g.end().trip.limit == 1
    g.begin("learn")
    assert g.check([0.0], signal=[9.0, 1.5]) is False
    assert g.check([5.0], signal=[9.0, 9.0]) is True
    assert g.end().trip.limit == 0  # both violated: the first one


def test_non_finite_states_violate_their_limit_and_unlimited_coordinates_are_not_read():
    g = angle_guard(limit_ticks=1)
    g.begin("learn")
    assert g.check([float("nan"), 0.0, float("inf")]) is False
    assert g.check([0.0, float("inf")]) is True
    g.end()
    g.begin("learn")
    assert g.check(np.array([0.0, 1e300, 0.0])) is True  # beyond float32: infinite
    g.end()


def test_the_envelope_is_learned_from_bare_episodes_and_trips_a_costly_one():
    g = Guard(horizon=8, relative_margin=0.5, envelope_ticks=2, tripped_cost_span=10.0)
    assert (g.rust_type, g.horizon) == ("Guard<0, 64>", 64)
    # Before any bare episode, nothing is checked.
    g.begin("learn")
    assert not any(g.check([0.0], cost=50.0) for _ in range(8))
    g.end()
    for costs in ([1.0] * 8, [2.0] + [0.5] * 7):
        g.begin("nominal")
        running = np.cumsum(costs)
        assert not any(g.check([0.0], cost=c) for c in running)
        assert g.end().trip is None
    envelope = g.envelope()
    assert envelope.shape == (64,) and list(envelope[:8]) == [2, 2.5, 3, 4, 5, 6, 7, 8]
    assert np.all(envelope[8:] == -np.inf)
    assert list(g.thresholds()[:3]) == [3.0, 3.75, 4.5] and np.all(g.thresholds()[8:] == np.inf)
    # Costly from tick 5: above at ticks 5 and 6, tripped at tick 6.
    g.begin("learn")
    running = np.cumsum([1.0] * 5 + [10.0] * 3)
    verdicts = [g.check([0.0], cost=c) for c in running]
    report = g.end()
    assert verdicts == [False] * 6 + [True] * 2
    assert (report.trip.tick, report.trip.reason, report.trip.limit, report.trip.cost) == (6, "envelope", None, 25.0)
    assert report.told(cost=0.3, failure_cost=100.0) == np.float32(100.0 + 10.0 * 2 / 8)
    # A one-tick excursion is forgiven.
    g.begin("learn")
    assert not any(g.check([0.0], cost=c) for c in [1.0, 2.0, 9.0, 4.0, 5.0])
    g.end()
    c = g.counters
    assert (c.bare_episodes, c.guarded_episodes, c.envelope_trips, c.limit_trips) == (2, 3, 1, 0)
    g.clear_envelope()
    assert np.all(g.envelope() == -np.inf) and g.counters.bare_episodes == 0


def test_bare_episodes_are_never_handed_over_but_count_ticks_beyond():
    g = angle_guard(limit_ticks=1)
    g.begin("nominal")
    assert not any(g.check([0.0, 1.0]) for _ in range(5))
    report = g.end()
    assert report.trip is None and report.ticks_beyond_limits == 5


def test_the_tripped_cost_ranks_above_failure_and_by_the_tick_reached():
    g = angle_guard(limit_ticks=1, tripped_cost_span=5.0)
    told = []
    for trip_at in (0, 10, 99):
        g.begin("learn")
        for t in range(100):
            g.check([0.0, 1.0 if t >= trip_at else 0.0])
        told.append(g.end().told(cost=0.1, failure_cost=2.0))
    assert told[0] == 7.0 and told[0] > told[1] > told[2] > 2.0
    assert g.tripped_cost(2.0, 10, 100) == told[1]
    g.begin("learn")
    g.check([0.0, 0.0])
    assert g.end().told(cost=0.1, failure_cost=2.0) == 0.1  # untripped: its own cost
    with pytest.raises(GuardError, match="failure_cost"):
        g.tripped_cost(float("nan"), 0, 10)
    with pytest.raises(GuardError, match="tripped_cost_span"):
        Guard(tripped_cost_span=1e-6).tripped_cost(1e6, 0, 10)  # absorbed in float32


@pytest.mark.parametrize(
    "args, kwargs, message",
    [
        (([Limit.state(0)] * 9,), {}, "9 limits"),
        ((), {"horizon": 4097}, "4097 ticks"),
        ((), {"horizon": -1}, "negative"),
        (([Limit.state(64)],), {}, "state\\[64\\].*signal"),
        (([Limit.signal(70000)],), {}, "index 70000"),
        (([Limit.signal(-1)],), {}, "index -1"),
        (([("wrench", 0, -1.0, 1.0)],), {}, "source `wrench`"),
        (([Limit.state(0, float("nan"), 1.0)],), {}, "NaN"),
        (([Limit.state(0, 1.0, -1.0)],), {}, "above high"),
        (([("state",)],), {}, "a limit must be"),
        ((), {"limit_ticks": 0}, "limit_ticks"),
        ((), {"envelope_ticks": -3}, "envelope_ticks"),
        ((), {"limit_ticks": 2**40}, "limit_ticks"),
        ((), {"limit_ticks": 1.5}, "limit_ticks"),
        ((), {"relative_margin": -0.1}, "relative_margin"),
        ((), {"absolute_margin": float("inf")}, "absolute_margin"),
        ((), {"absolute_margin": 1e300}, "absolute_margin"),
        ((), {"relative_margin": float("nan")}, "relative_margin"),
        ((), {"margin_taper": -0.1}, "margin_taper"),
        ((), {"margin_taper": 1.5}, "margin_taper"),
        ((), {"margin_taper": float("nan")}, "margin_taper"),
        ((), {"tripped_cost_span": 0.0}, "tripped_cost_span"),
        ((), {"tripped_cost_span": float("inf")}, "tripped_cost_span"),
    ],
)
def test_bad_configurations_are_guard_errors(args, kwargs, message):
    with pytest.raises(GuardError, match=message):
        Guard(*args, **kwargs)
    assert issubclass(GuardError, ValueError)


def test_a_margin_taper_shrinks_the_margins_linearly_to_the_last_tick():
    # Envelope 4 at each of the 64 ticks; margins 0.5·4 + 1 = 3 at tick 0, a quarter of that
    # at tick 63, as the library's Guard computes them.
    g = Guard(horizon=64, relative_margin=0.5, absolute_margin=1.0, margin_taper=0.25)
    assert g.margin_taper == 0.25
    g.begin("nominal")
    for _ in range(64):
        g.check([0.0], cost=4.0)
    g.end()
    t = g.thresholds()
    assert t[0] == 7.0 and t[63] == 4.75
    assert np.all(np.diff(t) < 0)
    assert Guard.load(g.save()).margin_taper == 0.25


def test_calls_out_of_order_and_bad_ticks_are_guard_errors_that_change_nothing():
    g = Guard([Limit.state(2, -1.0, 1.0)], horizon=10)
    with pytest.raises(GuardError, match="no episode"):
        g.check([0.0, 0.0, 0.0], cost=0.0)
    with pytest.raises(GuardError, match="no episode"):
        g.end()
    with pytest.raises(GuardError, match="unknown mode"):
        g.begin("explore")
    g.begin("learn")
    with pytest.raises(GuardError, match="end"):
        g.begin("learn")
    with pytest.raises(GuardError, match="state\\[2\\]"):
        g.check([0.0, 0.0], cost=0.0)
    with pytest.raises(GuardError, match="running cost"):
        g.check([0.0, 0.0, 0.0])
    with pytest.raises(GuardError, match="state"):
        g.check(["a", "b", "c"], cost=0.0)
    with pytest.raises(GuardError, match="episode is running"):
        g.save()
    with pytest.raises(GuardError, match="episode is running"):
        g.clear_envelope()
    assert g.ticks == 0  # none of the refused ticks counted
    assert g.check(np.zeros((1, 3)), cost=0.0) is False  # any shape, read flat
    assert g.end().ticks == 1


def test_records_round_trip_bit_for_bit_and_refuse_corruption():
    g = Guard([Limit.state(1, -0.2, 0.2), Limit.signal(0, 0.0, 5.0)], horizon=1000,
              limit_ticks=3, relative_margin=0.25, absolute_margin=0.01, tripped_cost_span=2.0)
    assert g.rust_type == "Guard<2, 1024>"
    rng = np.random.default_rng(3)
    for mode in ("nominal", "nominal", "learn", "learn", "deploy"):
        g.begin(mode)
        running = 0.0
        for _ in range(120):
            running += float(rng.uniform(0, 0.01))
            g.check(rng.normal(0, 0.15, 4), cost=running, signal=[rng.uniform(-0.1, 5)])
        g.end()
    record = g.save()
    back = Guard.load(record)
    assert back.save() == record and back.rust_type == g.rust_type
    assert back.counters == g.counters and np.array_equal(back.envelope(), g.envelope())
    assert back.limits == g.limits and back.limit_ticks == 3
    assert back.relative_margin == np.float32(0.25) and back.tripped_cost_span == 2.0
    # Loaded and original give the same verdicts.
    twin = g.copy()
    for guard in (g, back, twin):
        guard.begin("learn")
    for _ in range(200):
        state, cost, signal = rng.normal(0, 0.15, 4), float(rng.uniform(0, 3)), [rng.uniform(-1, 6)]
        assert g.check(state, cost=cost, signal=signal) == back.check(state, cost=cost, signal=signal) \
            == twin.check(state, cost=cost, signal=signal)
    reports = [guard.end() for guard in (g, back, twin)]
    assert reports[0].trip == reports[1].trip == reports[2].trip
    assert g.save() == back.save() == twin.save()
    corrupt = bytearray(record)
    corrupt[len(corrupt) // 2] ^= 0xFF
    with pytest.raises(RecordError):
        Guard.load(bytes(corrupt))
    for bad in (b"", record[:-1], ctrl_adapt.Optimizer("cmaes", -np.ones(2), np.ones(2)).save()):
        with pytest.raises(RecordError):
            Guard.load(bad)
    with pytest.raises(RecordError):
        ctrl_adapt.Optimizer.load(record)


def test_horizons_round_up_to_the_compiled_sizes():
    for asked, compiled in [(0, 0), (1, 64), (64, 64), (65, 128), (240, 256), (1000, 1024), (4096, 4096)]:
        assert Guard(horizon=asked).horizon == compiled
    assert guard_module.HORIZONS[-1] == guard_module.MAX_HORIZON == 4096
    assert guard_module.MAX_LIMITS == 8 and guard_module.MAX_STATE == 64
    for limits in range(9):
        g = Guard([Limit.signal(i, -1.0, 1.0) for i in range(limits)], horizon=4096)
        assert g.rust_type == f"Guard<{limits}, 4096>" and Guard.load(g.save()).save() == g.save()


STACK_SCRIPT = textwrap.dedent(
    """
    import threading, numpy as np, ctrl_adapt as c

    def work():
        g = c.Guard([c.Limit.state(k % 64, -1.0, 1.0) for k in range(8)], horizon=4096)
        g.begin("nominal")
        for t in range(100):
            g.check(np.zeros(64), cost=float(t))
        g.end()
        back = c.Guard.load(g.save())
        back.copy()
        assert back.save() == g.save()
        print("done", flush=True)

    threading.stack_size(512 * 1024)
    t = threading.Thread(target=work)
    t.start()
    t.join()
    """
)


def test_the_largest_guard_builds_saves_and_loads_on_a_small_thread_stack():
    run = subprocess.run([sys.executable, "-c", STACK_SCRIPT], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, f"exit {run.returncode}: {run.stderr[-2000:]}"
    assert "done" in run.stdout


def test_the_guard_docstring_examples_run():
    result = doctest.testmod(guard_module)
    assert result.attempted > 0 and result.failed == 0
