"""The package's contract: names, dimensions, errors as exceptions, records, copies."""

import numpy as np
import pytest

import ctrl_adapt
from ctrl_adapt import Optimizer, OptimizerError, RecordError


def box(n):
    return -np.ones(n), np.ones(n)


def test_every_algorithm_at_every_dimension_stays_in_its_box():
    rng = np.random.default_rng(0)
    for algorithm in ctrl_adapt.algorithms():
        for n in (1, 2, 7, 31, ctrl_adapt.MAX_DIMENSION):
            lower = rng.uniform(-3, 0, n) - 0.1
            upper = rng.uniform(0, 3, n) + 0.1
            opt = Optimizer(algorithm, lower, upper, seed=n)
            assert opt.dimension == n and str(n) in opt.rust_type
            for _ in range(25):
                theta = opt.ask()
                assert np.all(theta >= lower.astype(np.float32)) and np.all(theta <= upper.astype(np.float32))
                opt.tell(float(np.sum(theta**2)))
            assert opt.evaluations == 25


def test_it_learns_a_quadratic():
    for algorithm in ("coordinate", "cmaes", "linebo", "cem"):
        opt = Optimizer(algorithm, *box(3), start=np.full(3, 0.8), seed=2)
        while opt.status == "running" and opt.evaluations < 300:
            theta = opt.ask()
            opt.tell(float(np.sum((theta - 0.1) ** 2)))
        assert opt.best()[1] < 1e-2, algorithm


def test_errors_carry_the_library_messages_and_change_nothing():
    opt = Optimizer("coordinate", *box(2), start=np.zeros(2))
    with pytest.raises(OptimizerError, match="tell"):
        opt.tell(1.0)  # no candidate asked
    theta = opt.ask()
    for bad in (float("nan"), float("inf"), 1e300):
        with pytest.raises(OptimizerError, match="cost"):
            opt.tell(bad)
    assert opt.evaluations == 0
    assert np.array_equal(opt.pending(), theta)
    opt.tell(0.5)
    assert opt.evaluations == 1


@pytest.mark.parametrize(
    "args, kwargs, message",
    [
        (("nope", *box(2)), {}, "unknown algorithm"),
        (("coordinate", np.ones(2), -np.ones(2)), {}, "bounds|lower|upper"),
        (("coordinate", *box(2)), {"start": np.full(2, 5.0)}, "start"),
        (("coordinate", *box(2)), {"start": np.zeros(3)}, "start"),
        (("coordinate", *box(2)), {"initial_step": -1.0}, "initial_step"),
        (("coordinate", *box(2)), {"sigma": 1.0}, "unknown field `sigma`"),
        (("crs", *box(2)), {"start": np.full(2, 5.0)}, "start"),
        (("coordinate", np.zeros(0), np.zeros(0)), {}, "0 parameters"),
        (("coordinate", *box(65)), {}, "65 parameters"),
    ],
)
def test_bad_construction_is_an_error(args, kwargs, message):
    with pytest.raises(OptimizerError, match=message):
        Optimizer(*args, **kwargs)


def test_records_round_trip_and_refuse_corruption():
    opt = Optimizer("cmaes", *box(5), start=np.zeros(5), seed=4)
    for _ in range(30):
        opt.tell(float(np.sum(opt.ask() ** 2)))
    record = opt.save()
    again = Optimizer.load(record)
    assert again.rust_type == opt.rust_type == "Cmaes<5, 8>"
    assert again.evaluations == 30 and again.best()[1] == opt.best()[1]
    corrupt = bytearray(record)
    corrupt[len(corrupt) // 2] ^= 0xFF
    with pytest.raises(RecordError):
        Optimizer.load(bytes(corrupt))
    with pytest.raises(RecordError):
        Optimizer.load(b"")


def test_a_copy_continues_identically():
    opt = Optimizer("sracos", *box(4), seed=9)
    for _ in range(20):
        opt.tell(float(np.sum(opt.ask() ** 2)))
    twin = opt.copy()
    for _ in range(20):
        a, b = opt.ask(), twin.ask()
        assert np.array_equal(a, b)
        opt.tell(float(np.sum(a**2)))
        twin.tell(float(np.sum(b**2)))


def test_configuration_fields_reach_the_algorithm():
    opt = Optimizer("coordinate", *box(2), start=np.zeros(2), max_evaluations=3)
    for _ in range(3):
        opt.tell(float(np.sum(opt.ask() ** 2)))
    assert opt.status == "budget_spent"
    with pytest.raises(OptimizerError):
        opt.ask()
    two = Optimizer("two-phase", *box(2), global_budget=30, local={"initial_step": 0.1})
    assert two.rust_type == "TwoPhase<ControlledRandomSearch<2, 30>, 2>"
    safe = Optimizer("linebo", *box(2), start=np.zeros(2), threshold=1.0, directions="Random")
    safe.tell(float(np.sum(safe.ask() ** 2)))


def test_the_compiled_cmaes_population_is_the_library_rule():
    # λ = 4 + ⌊3 ln n⌋ in float32, as ctrl_adapt::optimizer::cmaes::default_population.
    for n in range(1, ctrl_adapt.MAX_DIMENSION + 1):
        lam = 4 + int(np.floor(np.float32(3.0) * np.log(np.float32(n))))
        assert ctrl_adapt.rust_type("cmaes", n) == f"Cmaes<{n}, {lam}>"
        opt = Optimizer("cmaes", *box(n), start=np.zeros(n))
        assert opt.rust_type == f"Cmaes<{n}, {lam}>"


def test_the_package_docstring_example_runs():
    import doctest

    result = doctest.testmod(ctrl_adapt)
    assert result.attempted > 0 and result.failed == 0
