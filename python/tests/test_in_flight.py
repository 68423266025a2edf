"""Several candidates in flight: `suggest` / `report` / `cancel`.

Checks that reporting a generation's costs in any order leaves every optimizer in exactly
the state (its record, byte for byte) of the sequential `ask`/`tell` with the same costs,
that a record saved with tickets outstanding restores them, and the errors.
"""

import random

import numpy as np
import pytest

import ctrl_adapt
from ctrl_adapt import Optimizer, OptimizerError

ALGORITHMS = ctrl_adapt.algorithms()


def new(algorithm, n, seed, **config):
    start = None if algorithm in ("sracos", "crs", "two-phase") else np.full(n, 0.2)
    return Optimizer(algorithm, -np.ones(n), np.ones(n), start, seed=seed, **config)


def cost(theta):
    """A sphere rounded to quarters: many ties, so the order of equal costs matters."""
    return round(float(np.sum((theta - 0.3) ** 2)) * 4) / 4


def generation(opt):
    """Every candidate `suggest` hands out now, as (ticket, theta)."""
    out = []
    while (pair := opt.suggest()) is not None:
        out.append(pair)
    return out


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("n", [3, 18])
def test_any_report_order_gives_the_sequential_state(algorithm, n):
    par, seq = new(algorithm, n, 4), new(algorithm, n, 4)
    shuffle = random.Random(n)
    widest = 0
    while par.status == "running" and par.evaluations < 240:
        out = generation(par)
        assert 1 <= len(out) <= par.max_in_flight
        widest = max(widest, len(out))
        assert par.in_flight == [t for t, _ in out] and par.capacity == 0
        for _, theta in out:  # the sequential run, in hand-out order
            assert np.array_equal(seq.ask(), theta)
            seq.tell(cost(theta))
        order = list(out)
        shuffle.shuffle(order)
        for ticket, theta in order:
            par.report(ticket, cost(theta))
        assert par.in_flight == []
        assert par.save() == seq.save(), "the record after a generation, byte for byte"
    assert par.evaluations == seq.evaluations and par.status == seq.status
    assert widest == par.max_in_flight or par.evaluations >= 240


def test_max_in_flight_per_algorithm():
    n = 18
    expected = {
        "coordinate": 1,
        "sracos": 1,
        "cem": 10,
        "crs": ctrl_adapt.MAX_IN_FLIGHT,  # 190 points to sample, 64 at a time
        # Its CRS's initial set within the global budget (150 of 190 points), 64 at a time.
        "two-phase": ctrl_adapt.MAX_IN_FLIGHT,
        "cmaes": 12,
        "rockstar": 2,
        "linebo": 1,
    }
    for algorithm in ALGORITHMS:
        opt = new(algorithm, n, 1)
        assert opt.max_in_flight == expected[algorithm], algorithm
        assert opt.capacity == expected[algorithm], algorithm


def test_two_phase_hands_out_its_global_set_together_and_hands_over_with_nothing_out():
    config = {"global_budget": 30}  # within CRS's initial set of 40 points at n = 3
    par, seq = new("two-phase", 3, 5, **config), new("two-phase", 3, 5, **config)
    assert par.max_in_flight == 30
    out = generation(par)
    assert len(out) == 30
    for _, theta in out:
        assert np.array_equal(seq.ask(), theta)
        seq.tell(cost(theta))
    for ticket, theta in reversed(out):
        par.report(ticket, cost(theta))
    # The hand-over to the local coordinate search: one at a time from there.
    assert par.save() == seq.save() and par.capacity == 1
    assert np.array_equal(par.suggest()[1], seq.ask())


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_record_saved_mid_generation_restores_the_tickets(algorithm):
    opt = new(algorithm, 5, 2)
    for _ in range(3):  # a few generations in, so the state is not the initial one
        for ticket, theta in generation(opt):
            opt.report(ticket, cost(theta))
    out = generation(opt)
    held, rest = out[-1:], out[:-1]
    for ticket, theta in held:  # held until the earlier ones come back (when any are out)
        opt.report(ticket, cost(theta))
    if rest:
        opt.cancel(rest[0][0])
    record = opt.save()
    again = Optimizer.load(record, seed=9)
    assert again.in_flight == opt.in_flight and again.capacity == opt.capacity
    for o in (opt, again):
        if rest:
            ticket, theta = o.suggest()  # the cancelled candidate, again
            assert np.array_equal(theta, rest[0][1])
            o.report(ticket, cost(theta))
        for ticket, theta in reversed(rest[1:]):
            o.report(ticket, cost(theta))
        assert o.in_flight == []
    assert again.save() == opt.save()


def test_errors_change_nothing():
    opt = new("cem", 4, 3, max_evaluations=12)
    out = generation(opt)
    assert len(out) == 10
    record = opt.save()
    for bad in (lambda: opt.report(out[0][0], float("nan")),
                lambda: opt.report(out[0][0], 1e300),
                lambda: opt.report(12345, 1.0),
                lambda: opt.report(-1, 1.0),
                lambda: opt.report(2**40, 1.0),
                lambda: opt.cancel(12345),
                lambda: opt.cancel(-1),
                lambda: opt.ask(),
                lambda: opt.tell(1.0)):
        with pytest.raises(OptimizerError):
            bad()
        assert opt.save() == record and len(opt.in_flight) == 10
    with pytest.raises(OptimizerError, match="unknown ticket"):
        opt.report(-1 & 0xFFFFFFFF, 1.0)
    opt.report(out[3][0], 1.0)
    with pytest.raises(OptimizerError, match="unknown ticket"):
        opt.report(out[3][0], 1.0)  # reported already
    for ticket, theta in out:
        if ticket != out[3][0]:
            opt.report(ticket, cost(theta))
    assert opt.capacity == 2  # the budget of 12 leaves two
    for ticket, theta in generation(opt):
        opt.report(ticket, cost(theta))
    assert opt.status == "budget_spent"
    with pytest.raises(OptimizerError, match="stopped"):
        opt.suggest()


def test_the_sequential_calls_and_suggest_do_not_mix():
    opt = new("cmaes", 3, 5)
    theta = opt.ask()
    assert opt.capacity == 0
    with pytest.raises(OptimizerError, match="pending"):
        opt.suggest()
    opt.tell(cost(theta))
    ticket, _ = opt.suggest()
    with pytest.raises(OptimizerError, match="in flight"):
        opt.ask()
    opt.cancel(ticket)
    with pytest.raises(OptimizerError, match="in flight"):
        opt.ask()  # the cancelled candidate waits to be suggested again
