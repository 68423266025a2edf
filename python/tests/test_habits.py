"""The Python habits: one candidate at a time with ask, documented methods, minimize,
recommend, and the process pool."""

import pydoc

import numpy as np
import pytest

import ctrl_adapt
import ctrl_adapt.pool


def sphere(theta):
    return float(np.sum((np.asarray(theta) - 0.25) ** 2))


@pytest.mark.parametrize("algorithm", ctrl_adapt.algorithms())
def test_a_second_ask_before_tell_raises_naming_suggest(algorithm):
    opt = ctrl_adapt.Optimizer(algorithm, -np.ones(3), np.ones(3), seed=1)
    theta = opt.ask()
    with pytest.raises(ctrl_adapt.OptimizerError, match="suggest"):
        opt.ask()
    assert np.array_equal(opt.pending(), theta)
    opt.tell(sphere(theta))
    opt.ask()


def test_every_public_method_has_a_docstring_with_an_example_or_its_errors():
    text = pydoc.render_doc(ctrl_adapt.Optimizer, renderer=pydoc.plaintext)
    for name in ["ask", "tell", "suggest", "report", "cancel", "save", "load", "best",
                 "recommend", "pending", "copy"]:
        doc = getattr(ctrl_adapt.Optimizer, name).__doc__
        assert doc and len(doc) > 60, name
        assert name in text
    for name in ["ask", "tell", "suggest", "load", "best", "recommend"]:
        assert ">>>" in getattr(ctrl_adapt.Optimizer, name).__doc__, name
    for name in ["ask", "tell", "suggest", "report", "cancel", "load"]:
        assert "raises" in getattr(ctrl_adapt.Optimizer, name).__doc__.lower(), name
    assert ctrl_adapt.minimize.__doc__ and ctrl_adapt.pool.minimize.__doc__


def test_minimize_returns_the_best_its_cost_and_the_optimizer():
    result = ctrl_adapt.minimize(sphere, -np.ones(2), np.ones(2), algorithm="cmaes",
                                 budget=300, seed=1)
    theta, cost = result
    assert cost < 1e-6 and np.allclose(theta, 0.25, atol=1e-3)
    assert result.optimizer.evaluations == result.evaluations <= 300
    # The same as the loop it replaces.
    opt = ctrl_adapt.Optimizer("cmaes", -np.ones(2), np.ones(2), seed=1)
    for _ in range(result.evaluations):
        t = opt.ask()
        opt.tell(sphere(t))
    assert opt.best()[1] == cost and np.array_equal(opt.best()[0], theta)
    with pytest.raises(ValueError, match="budget"):
        ctrl_adapt.minimize(sphere, [-1.0], [1.0], budget=0)


@pytest.mark.parametrize("algorithm, model", [("cmaes", True), ("cem", True), ("rockstar", True),
                                              ("linebo", True), ("coordinate", False),
                                              ("crs", False)])
def test_recommend_is_the_models_point_apart_from_the_best(algorithm, model):
    opt = ctrl_adapt.Optimizer(algorithm, -np.ones(2), np.ones(2), seed=3)
    assert (opt.recommend() is not None) == model
    for _ in range(80):
        if opt.status != "running":
            break
        opt.tell(sphere(opt.ask()))
    recommended = opt.recommend()
    assert recommended is not None and np.all(np.abs(recommended) <= 1)
    if not model:
        assert np.array_equal(recommended, opt.best()[0])
    if algorithm == "cmaes":  # the mean, near the minimum, not a sample
        assert sphere(recommended) < 1e-3


@pytest.mark.parametrize("algorithm", ["sracos", "crs", "two-phase"])
def test_a_start_is_the_first_sample_where_the_algorithm_samples_the_box(algorithm):
    start = np.array([0.25, -0.5])
    opt = ctrl_adapt.Optimizer(algorithm, -np.ones(2), np.ones(2), start=start, seed=3)
    # The record saved at once holds the start (the firmware's ask hands it out first).
    again = ctrl_adapt.Optimizer.load(opt.save(), seed=3)
    assert np.array_equal(opt.ask(), start)
    with pytest.raises(ctrl_adapt.OptimizerError, match="suggest"):
        opt.ask()  # the start is now asked: a second ask raises as usual
    opt.tell(sphere(start))
    # In flight: the start goes out first, then the rest as the sequential run draws it.
    first = again.suggest()
    assert np.array_equal(first[1], start)
    out = [first] + [again.suggest() for _ in range(again.capacity)]
    again.report(first[0], sphere(start))
    for ticket, theta in out[1:]:
        assert np.array_equal(opt.ask(), theta)
        opt.tell(sphere(theta))
        again.report(ticket, sphere(theta))
    assert again.save() == opt.save()
    assert opt.best()[1] <= sphere(start)
    with pytest.raises(ctrl_adapt.OptimizerError, match="start"):
        ctrl_adapt.Optimizer(algorithm, -np.ones(2), np.ones(2), start=np.full(2, 2.0))


@pytest.mark.parametrize("workers", [1, 2])
def test_the_pool_searches_as_the_sequential_loop_does(workers):
    # 10 CMA-ES generations (λ = 6 at n = 2): bit for bit the sequential search.
    pooled = ctrl_adapt.pool.minimize(sphere, -np.ones(2), np.ones(2), algorithm="cmaes",
                                      budget=60, workers=workers, seed=4)
    alone = ctrl_adapt.minimize(sphere, -np.ones(2), np.ones(2), algorithm="cmaes",
                                budget=60, seed=4)
    assert pooled.evaluations == alone.evaluations == 60
    assert pooled.cost == alone.cost and np.array_equal(pooled.theta, alone.theta)
    assert pooled.optimizer.save() == alone.optimizer.save()


def failing(theta):
    raise RuntimeError("simulator crashed")


def test_the_pool_propagates_an_evaluations_exception():
    with pytest.raises(RuntimeError, match="simulator crashed"):
        ctrl_adapt.pool.minimize(failing, -np.ones(2), np.ones(2), budget=12, workers=2)
