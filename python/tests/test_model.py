"""The plant model and the model-based learner: the firmware's Rust types from Python.

Checked: the records and proposals are those of the Rust reference (the `python-reference`
binary of host-tests, the library's concrete types written out) bit for bit; records load
back bit-identical; every bad input raises a ValueError subclass and changes nothing; an
exception or NaN inside the learner's `predict` does not crash the interpreter. Fixed seeds
throughout.
"""

import copy
import json
import os
import subprocess

import numpy as np
import pytest

import ctrl_adapt
from ctrl_adapt import ModelBased, ModelError, RecordError, RlsModel

HERE = os.path.dirname(os.path.abspath(__file__))
REFERENCE = os.environ.get("CTRL_ADAPT_REFERENCE") or os.path.join(
    HERE, "..", "..", "target", "release", "python-reference"
)
F32 = np.float32


def reference(*args):
    out = subprocess.run([REFERENCE, *map(str, args)], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def bits(values):
    return [int(v) for v in np.asarray(values, dtype=np.float32).view(np.uint32)]


def fitted(ticks=300):
    """The reference's plant in float32: both models fitted, as `python-reference rls`."""
    affine, dragged = RlsModel(2, 1), RlsModel(2, 1, features=1)
    x = np.zeros(2, dtype=np.float32)
    for k in range(ticks):
        u = F32((k * 37) % 11) / F32(5.0) - F32(1.0)
        drag = np.abs(x[1]) * x[1]
        nxt = np.array([x[0] + F32(0.1) * x[1],
                        F32(0.95) * x[1] + F32(0.2) * u + F32(0.05) - F32(0.1) * drag],
                       dtype=np.float32)
        affine.update(x, [u], nxt)
        dragged.update(x, [u], nxt, features=[drag])
        x = nxt
    return affine, dragged


def bowl(theta):
    """Σᵢ (1 + i)(θᵢ − 0.25)² in float32, as the reference computes it."""
    total = F32(0.0)
    for i, t in enumerate(theta):
        d = F32(t) - F32(0.25)
        total = total + F32(1.0 + i) * (d * d)
    return total


def learner(fallback, seed):
    l = ModelBased(-np.ones(3), np.ones(3), fallback, "cmaes", seed=seed, margin=0.1,
                   inner_evaluations=60, inner_config={"max_evaluations": 60})
    l.record(np.zeros(3), float(bowl(np.zeros(3))))
    l.set_reference(float(bowl(np.zeros(3))))
    return l


def drive(l, episodes):
    seen = []
    for _ in range(episodes):
        theta, source, predicted = l.propose(lambda t: float(bowl(t) + F32(0.01)))
        seen.append([bits(theta), None if predicted is None else bits([predicted])[0]])
        assert (source == "model") == (predicted is not None)
        l.tell(float(bowl(theta)))
    return seen


def test_the_models_records_are_the_rust_types():
    ref = reference("rls", 300)
    affine, dragged = fitted(300)
    assert affine.save().hex() == ref["affine"]
    assert dragged.save().hex() == ref["features"]
    assert (affine.rust_type, dragged.rust_type) == ("RlsModel<2, 1, 4>", "RlsModel<2, 1, 5>")


@pytest.mark.parametrize("fallback", ["coordinate", "cmaes"])
def test_the_learners_proposals_and_record_are_the_rust_types(fallback):
    ref = reference("model-based", fallback, 7, 12)
    l = learner(fallback, 7)
    assert drive(l, 12) == ref["proposals"]
    assert l.save().hex() == ref["record"]
    # The model did propose (the screen passes a model right up to an offset).
    assert any(p[1] is not None for p in ref["proposals"])


def test_the_model_learns_a_plant_and_predicts_it():
    affine, dragged = fitted(2000)
    x, u = np.array([0.5, -0.2]), np.array([0.7])
    true = np.array([0.5 + 0.1 * -0.2, 0.95 * -0.2 + 0.2 * 0.7 + 0.05 - 0.1 * (0.2 * -0.2)])
    assert np.max(np.abs(dragged.predict(x, u, features=[0.2 * -0.2]) - true)) < 1e-3
    # The affine model cannot express the drag: its error stays larger.
    assert dragged.one_step_error.max() < affine.one_step_error.max()
    assert affine.ticks == 2000 and affine.weights.shape == (4, 2)
    assert affine.covariance.shape == (4, 4)


def test_rollout_and_episode_error():
    model = RlsModel(1, 1)
    x = np.zeros(1)
    for k in range(100):  # an integrator: x' = x + 0.1 u
        u = np.array([1.0 if k % 7 < 3 else -0.5])
        _ = model.update(x, u, x + 0.1 * u)
        x = x + 0.1 * u
    states = model.rollout([0.0], 10, lambda s: [1.0])
    assert states.shape == (11, 1) and abs(states[-1, 0] - 1.0) < 1e-2
    # Each row is the prediction from the one before under the policy.
    assert np.array_equal(states[3], model.predict(states[2], [1.0]))
    ticks = model.rollout([0.0], 3, lambda k, s: [float(k)], with_tick=True)
    assert abs(ticks[-1, 0] - 0.3) < 1e-2
    actions = np.ones((10, 1))
    assert model.episode_error(states, actions).max() < 1e-6
    with pytest.raises(ModelError):
        model.episode_error(states[:5], actions)


def test_a_diverging_rollout_is_nan_not_an_error():
    model = RlsModel(1, 1)
    x = np.array([1.0])
    for k in range(50):  # x' = 3 x
        u = np.array([float(k % 3)])
        _ = model.update(x, u, 3.0 * x + 0.01 * u)
        x = np.array([float(k % 5) - 2.0])
    states = model.rollout([1.0], 200, lambda s: [0.0])
    assert states.shape == (201, 1)
    assert np.isfinite(states[0, 0]) and np.isnan(states[-1, 0])


def test_a_rollout_is_the_chain_of_predictions():
    """The rows are the model's predictions chained under the policy, bit for bit (as the
    library's `rollout` computes them); a diverging rollout's finite rows, then NaN."""
    affine, _ = fitted(300)

    def policy(k, s):
        return [float(F32(-0.8) * F32(s[0]) + F32(0.3) * F32(np.sin(F32(0.2) * F32(k))))]

    states = affine.rollout([0.4, -0.1], 64, policy, with_tick=True)
    assert states.shape == (65, 2) and states.dtype == np.float64
    x, chain = np.array([0.4, -0.1]), []
    for k in range(65):
        chain.append(bits(x))
        x = affine.predict(x, policy(k, x))
    assert [bits(row) for row in states] == chain
    calls = []

    def push(s):
        calls.append(1)
        return [3e38]

    # The commands push the state past float32 within a few ticks: the finite rows are
    # the chained predictions, the rows from the first non-finite prediction on NaN, and
    # the policy is not called after it.
    diverged = affine.rollout([0.4, -0.1], 100, push)
    finite = int(np.isfinite(diverged).all(axis=1).sum())
    assert diverged.shape == (101, 2) and 1 < finite < 100 and len(calls) == finite
    assert np.isnan(diverged[finite:]).all()
    x = np.array([0.4, -0.1])
    for row in diverged[:finite]:
        assert bits(row) == bits(x)
        x = affine.predict(x, [3e38])
    assert not np.isfinite(x).all()


def test_model_records_round_trip_and_copies():
    affine, dragged = fitted(100)
    for m in (affine, dragged):
        again = RlsModel.load(m.save())
        assert again.save() == m.save() and again.rust_type == m.rust_type
        for c in (m.copy(), copy.copy(m), copy.deepcopy(m)):
            assert c.save() == m.save()
        c = m.copy()
        c.update([0.1, 0.2], [0.3], [0.1, 0.2], **({"features": [0.0]} if m.features else {}))
        assert c.save() != m.save()  # a copy is independent
    assert "ticks=100" in repr(affine)


def test_model_bad_input_raises_and_changes_nothing():
    m, _ = fitted(50)
    before = m.save()
    for args in [
        ([np.nan, 0.0], [0.1], [0.0, 0.0]),
        ([0.0, 0.0], [np.inf], [0.0, 0.0]),
        ([0.0, 0.0], [0.1], [0.0, np.nan]),
        ([0.0], [0.1], [0.0, 0.0]),  # wrong shapes
        ([0.0, 0.0], [0.1, 0.2], [0.0, 0.0]),
        ([0.0, 0.0], "a", [0.0, 0.0]),
        ([3e38, -3e38], [0.1], [-3e38, 3e38]),  # the fit would overflow float32
    ]:
        with pytest.raises(ValueError):
            m.update(*args)
        assert m.save() == before
    with pytest.raises(ModelError):
        m.update([0, 0], [0], [0, 0], features=[1.0])  # no extra regressors
    _, d = fitted(10)
    with pytest.raises(ModelError):
        d.update([0, 0], [0], [0, 0])  # its feature is missing
    with pytest.raises(ModelError):
        d.rollout([0, 0], 3, lambda s: [0.0])
    with pytest.raises(ModelError):
        m.rollout([np.nan, 0], 3, lambda s: [0.0])
    with pytest.raises(ModelError):
        m.rollout([0, 0], 3, lambda s: [0.0, 1.0])  # the policy's action has the wrong size
    with pytest.raises(ZeroDivisionError):
        m.rollout([0, 0], 3, lambda s: 1 / 0)  # the policy's exception propagates
    assert m.save() == before
    for bad in [dict(state_dim=0, action_dim=1), dict(state_dim=9, action_dim=1),
                dict(state_dim=2, action_dim=3), dict(state_dim=2, action_dim=1, features=3),
                dict(state_dim=2, action_dim=1, forgetting=1.5),
                dict(state_dim=2, action_dim=1, prior_variance=0.0),
                dict(state_dim=2, action_dim=1, max_variance=1.0)]:
        with pytest.raises(ModelError):
            RlsModel(**bad)
    for record in [b"", b"junk", m.save()[:-1], ctrl_adapt.Optimizer("coordinate", [-1], [1]).save()]:
        with pytest.raises(RecordError):
            RlsModel.load(record)


def test_learner_records_round_trip_and_copies():
    for fallback in ("coordinate", "cmaes"):
        l = learner(fallback, 3)
        drive(l, 4)
        again = ModelBased.load(l.save(), seed=5)
        assert again.save() == l.save() and again.rust_type == l.rust_type
        # A pending proposal survives a record and is handed out again.
        theta, source, predicted = l.propose(lambda t: float(bowl(t)))
        again = ModelBased.load(l.save())
        assert again.save() == l.save()
        assert np.array_equal(again.pending[0], theta) and again.pending[1] == source
        assert np.array_equal(again.propose(lambda t: 1 / 0)[0], theta)
        c = l.copy()
        c.tell(1.0)
        assert c.save() != l.save() and l.pending is not None
        assert copy.deepcopy(l).save() == l.save()
    assert l.rust_type == "ModelBased<Cmaes<3, 7>, 3>"
    assert "evaluations=5" in repr(l)


def test_the_copy_continues_as_the_original():
    a = learner("cmaes", 11)
    drive(a, 3)
    b = a.copy()
    assert drive(a, 5) == drive(b, 5)


def test_learner_bad_input_raises_and_changes_nothing():
    l = learner("coordinate", 1)
    drive(l, 2)
    before = l.save()
    checks = [
        lambda: l.tell(1.0),  # no pending proposal
        lambda: l.record(np.zeros(2), 1.0),  # wrong shape
        lambda: l.record(np.full(3, 2.0), 1.0),  # outside the box
        lambda: l.record(np.zeros(3), float("nan")),
        lambda: l.record(np.zeros(3), 1e39),  # beyond float32
        lambda: l.set_reference(float("inf")),
    ]
    for check in checks:
        with pytest.raises(ModelError):
            check()
        assert l.save() == before
    l.propose(lambda t: float(bowl(t)))
    pending = l.save()
    for check in [lambda: l.tell(float("nan")), lambda: l.record(np.zeros(3), 1.0)]:
        with pytest.raises(ModelError):
            check()
        assert l.save() == pending
    for bad in [dict(margin=-1.0), dict(initial_radius=0.0), dict(inner_evaluations=0),
                dict(nonsense=1.0), dict(fallback="sracos"), dict(inner="linebo"),
                dict(inner_config={"initial_sigma": -1.0}), dict(fallback_config={"bad": 1}),
                dict(upper=np.ones(2)), dict(lower=np.ones(3))]:
        kwargs = dict(lower=-np.ones(3), upper=np.ones(3))
        kwargs.update(bad)
        with pytest.raises(ModelError):
            ModelBased(**kwargs)
    with pytest.raises(ModelError):
        ModelBased(-np.ones(9), np.ones(9))  # beyond the compiled dimensions
    for record in [b"", l.save()[:-1], RlsModel(2, 1).save()]:
        with pytest.raises(RecordError):
            ModelBased.load(record)


@pytest.mark.parametrize("fallback", ["coordinate", "cmaes"])
def test_an_exception_in_predict_changes_nothing(fallback):
    l = learner(fallback, 2)
    drive(l, 2)
    before, twin = l.save(), l.copy()
    calls = []

    def failing(theta):
        calls.append(1)
        if len(calls) == 5:
            raise RuntimeError("the simulator broke")
        return float(bowl(theta))

    with pytest.raises(RuntimeError, match="the simulator broke"):
        l.propose(failing)
    assert len(calls) == 5  # not called again after the exception
    assert l.save() == before and l.pending is None
    with pytest.raises(TypeError):
        l.propose(lambda t: "not a number")
    assert l.save() == before
    # RNG restored too: the next proposals are those of the untouched copy.
    assert drive(l, 3) == drive(twin, 3)


@pytest.mark.parametrize("inner", ["coordinate", "cmaes"])
def test_an_exception_in_predict_stops_the_inner_search_at_once(inner):
    # 2³² − 1 inner evaluations and the smallest tolerances: the inner search ends at the
    # first exception (it went on, its predictions refused, until it converged), `predict`
    # called once.
    l = ModelBased(-np.ones(2), np.ones(2), "coordinate", inner, seed=1,
                   inner_evaluations=2**32 - 1,
                   inner_config={"tolerance": 0.0 if inner == "cmaes" else 1e-30})
    before = l.save()
    calls = []

    def failing(theta):
        calls.append(1)
        raise KeyError("predict")

    with pytest.raises(KeyError, match="predict"):
        l.propose(failing)
    assert len(calls) == 1 and l.save() == before and l.pending is None


def test_nan_predictions_fall_back_and_never_raise():
    l = learner("coordinate", 4)
    theta, source, predicted = l.propose(lambda t: float("nan"))
    assert source == "fallback" and predicted is None
    assert np.all(np.abs(theta) <= 1.0)
    l.tell(1.0)
    theta, source, _ = l.propose(lambda t: float("inf") if t[0] > 0 else float(bowl(t)))
    l.tell(float(bowl(theta)))
    assert l.evaluations == 3


def test_the_learner_improves_on_a_real_task():
    """With a model that is the real cost plus an offset, the learner reaches the minimum."""
    l = learner("coordinate", 9)
    for _ in range(10):
        theta, source, _ = l.propose(lambda t: float(bowl(t) + F32(0.01)))
        l.tell(float(bowl(theta)))
    theta, cost = l.best
    assert cost < 0.01 and l.evaluations == 11
    assert 0.0 < l.radius and l.prediction_error >= 0.0
    assert l.fallback == "coordinate" and l.inner == "cmaes" and l.dimension == 3
    assert l.config["margin"] == pytest.approx(0.1)


def test_the_module_docs_examples_run():
    import doctest

    import ctrl_adapt.model as model_module

    result = doctest.testmod(model_module)
    assert result.attempted > 0 and result.failed == 0


def test_the_cmaes_fallback_has_the_packages_population_at_every_dimension():
    """The learner's CMA-ES sizes are the package optimizers' (λ = 4 + ⌊3 ln n⌋)."""
    for n in range(1, ctrl_adapt.model.MODEL_BASED_MAX_DIMENSION + 1):
        l = ModelBased(-np.ones(n), np.ones(n), "cmaes", seed=1)
        assert l.rust_type == f"ModelBased<{ctrl_adapt.rust_type('cmaes', n)}, {n}>"
        assert ModelBased.load(l.save()).rust_type == l.rust_type


def test_restart_after_restarts_a_stalled_trust_region_and_round_trips():
    """``restart_after=3``: the third proposal made at the minimum radius that does not
    improve the best restarts the trust region at its initial radius; the stall count and the
    restarts are in the record, so a reloaded learner (its RNG seeded anew) restarts on the
    same episode as the original, and both then hold the same state (the measured error
    statistic, which their different candidates fed, starts afresh)."""
    l = ModelBased(-np.ones(2), np.ones(2), seed=3, restart_after=3, inner_evaluations=30,
                   inner_config={"max_evaluations": 30})
    assert l.config["restart_after"] == 3 and (l.stalled, l.restarts) == (0, 0)
    l.record(np.zeros(2), 0.0)  # no cost told below beats it
    seen = []
    for _ in range(5):
        # A model that promises every θ but the best to be better: its candidates propose.
        l.propose(lambda t: -float(np.sum(np.square(t))))
        l.tell(1.0)
        seen.append((np.float32(l.radius), l.stalled, l.restarts))
    # 0.15 → × 0.6 → × 0.6 → 0.05 (proposals made above the minimum; float32 products, as
    # the learner computes them), then two stalled at the minimum.
    shrunk = F32(0.15) * F32(0.6)
    assert seen == [(shrunk, 0, 0), (shrunk * F32(0.6), 0, 0), (F32(0.05), 0, 0),
                    (F32(0.05), 1, 0), (F32(0.05), 2, 0)]
    again = ModelBased.load(l.save(), seed=4)
    assert again.save() == l.save() and (again.stalled, again.restarts) == (2, 0)
    assert again.config["restart_after"] == 3
    for m in (l, again):
        m.propose(lambda t: -float(np.sum(np.square(t))))
        m.tell(1.0)
        assert (np.float32(m.radius), m.stalled, m.restarts) == (F32(0.15), 0, 1)
    assert again.save() == l.save()
    # Without it, the same proposals never restart.
    never = ModelBased(-np.ones(2), np.ones(2), seed=3, inner_evaluations=30,
                       inner_config={"max_evaluations": 30})
    never.record(np.zeros(2), 0.0)
    for _ in range(6):
        never.propose(lambda t: -float(np.sum(np.square(t))))
        never.tell(1.0)
    assert (np.float32(never.radius), never.stalled, never.restarts) == (F32(0.05), 3, 0)
    for bad in (-1, 1.5, "3"):
        with pytest.raises(ModelError):
            ModelBased(-np.ones(2), np.ones(2), restart_after=bad)


def test_a_cost_and_uncertainty_pair_bounds_the_search():
    """``predict`` may return ``(cost, uncertainty)``: with ``uncertainty_weight`` 0 the pair
    is the cost alone (the same proposals, bit for bit, as returning the float); with a
    weight, the search and the screen use cost + k_u × uncertainty, so a model that promises
    much where it is unsure proposes where it is sure instead (the firmware's
    ``propose_bounded``). A return value of neither form raises a TypeError and changes
    nothing."""
    def promise(t):
        # The bowl, promised 1 lower for θ₀ > 0.05, where the model has no data (the first
        # trust box is ±0.15 around θ = 0).
        unsure = float(t[0]) > 0.05
        return float(bowl(t)) - (1.0 if unsure else 0.0), (10.0 if unsure else 0.0)

    point, paired = learner("coordinate", 5), learner("coordinate", 5)
    for _ in range(4):
        a = point.propose(lambda t: promise(t)[0])
        b = paired.propose(promise)
        assert bits(a[0]) == bits(b[0]) and a[1:] == b[1:]
        point.tell(float(bowl(a[0])))
        paired.tell(float(bowl(b[0])))
    assert point.save() == paired.save()

    def bounded(weight):
        l = ModelBased(-np.ones(3), np.ones(3), "coordinate", "cmaes", seed=5, margin=0.1,
                       inner_evaluations=60, inner_config={"max_evaluations": 60},
                       uncertainty_weight=weight)
        l.record(np.zeros(3), float(bowl(np.zeros(3))))
        l.set_reference(float(bowl(np.zeros(3))))
        return l

    greedy, careful = bounded(0.0), bounded(1.0)
    theta, source, _ = greedy.propose(promise)
    assert source == "model" and theta[0] > 0.05  # lured where the model is unsure
    theta, source, _ = careful.propose(promise)
    assert source == "model" and theta[0] <= 0.05
    careful.tell(float(bowl(theta)))
    before = careful.save()
    with pytest.raises(TypeError, match="pair"):
        careful.propose(lambda t: (1.0, 2.0, 3.0))
    assert careful.save() == before and careful.pending is None
