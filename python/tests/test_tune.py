"""The Ray Tune searcher: its contract called directly (fast), then on a local Ray cluster of
two CPUs (one cluster for the session; trials of a few milliseconds, actors reused).

The objective is the shifted quadratic ``cost = |x - TARGET|²`` over ``[-1, 1]³``, from the
start 0 (cost 0.5); every optimizer is seeded, so each run is repeatable.
"""

import json
import math
import os
import pickle
import subprocess
import sys
import time

import numpy as np
import pytest
import ray
from ray import tune
from ray.tune.search import Searcher

import ctrl_adapt
import ctrl_adapt.tune as ctrl_adapt_tune
from ctrl_adapt.tune import CtrlAdaptSearch, write_record
from ctrl_adapt import Optimizer

TARGET = np.array([0.5, -0.4, 0.3])
SPACE = {"a": (-1.0, 1.0), "b": (-1.0, 1.0), "c": (-1.0, 1.0)}
HERE = os.path.dirname(os.path.abspath(__file__))
REFERENCE = os.environ.get("CTRL_ADAPT_REFERENCE") or os.path.join(
    HERE, "..", "..", "target", "release", "python-reference"
)


def optimizer(algorithm="cmaes", seed=1, **config):
    return Optimizer(algorithm, -np.ones(3), np.ones(3), np.zeros(3), seed=seed, **config)


def quadratic(config):
    x = np.array([config["a"], config["b"], config["c"]])
    return float(np.sum((x - TARGET) ** 2))


def searcher(opt=None, **kwargs):
    kwargs.setdefault("metric", "cost")
    kwargs.setdefault("mode", "min")
    return CtrlAdaptSearch(SPACE, optimizer=opt or optimizer(), **kwargs)


# -- the contract, called directly ----------------------------------------------------------


def test_a_configuration_names_the_candidate_and_keeps_constants():
    s = CtrlAdaptSearch({"gains": {"kp": (0.0, 2.0)}, "kd": (0.0, 1.0), "steps": 200},
                        optimizer=Optimizer("coordinate", np.zeros(2), np.array([2.0, 1.0])),
                        metric="cost", mode="min")
    theta = s.optimizer.copy().ask()  # the candidate the first suggest hands out
    config = s.suggest("t0")
    assert s.parameter_names == ["gains/kp", "kd"]  # the space's order is the vector's
    assert config == {"gains": {"kp": theta[0]}, "kd": theta[1], "steps": 200}


@pytest.mark.parametrize("algorithm", ["coordinate", "cmaes"])
def test_it_never_hands_out_more_than_the_optimizer_allows(algorithm):
    s = searcher(optimizer(algorithm))
    limit = s.optimizer.max_in_flight
    handed = []
    while (config := s.suggest(f"t{len(handed)}")) is not None:
        handed.append(config)
        assert len(handed) <= limit
    # All it allows are out: further trials wait until those are reported.
    assert len(handed) == limit == len(s.optimizer.in_flight)
    assert s.suggest("waiting") is None
    for i, config in enumerate(handed):
        s.on_trial_complete(f"t{i}", {"cost": quadratic(config)})
    assert s.optimizer.evaluations == limit and isinstance(s.suggest("next"), dict)


@pytest.mark.parametrize(
    "result, error",
    [(None, True), ({"other": 1.0}, False), ({"cost": float("nan")}, False),
     ({"cost": float("inf")}, False), ({"cost": 1e300}, False), ({"cost": "n/a"}, False)],
)
def test_a_failed_trial_hands_its_candidate_out_again(result, error):
    s = searcher()
    first = s.suggest("t0")
    s.on_trial_complete("t0", result, error=error)
    assert s.cancelled == 1 and s.optimizer.evaluations == 0 and s.history == []
    handed = {}
    while (config := s.suggest(f"t{len(handed) + 1}")) is not None:
        handed[f"t{len(handed) + 1}"] = config
    assert first in handed.values()  # the same candidate, to a later trial
    for trial_id, config in handed.items():
        s.on_trial_complete(trial_id, {"cost": quadratic(config)})
    assert s.optimizer.evaluations == len(handed) and s.cancelled == 1


def test_with_a_failure_value_a_failed_trial_is_reported_at_that_value():
    s = searcher(mode="max", metric="score", failure_value=-100.0, max_retries=0)
    first = s.suggest("t0")
    s.on_trial_complete("t0", None, error=True)
    assert s.cancelled == 0 and s.optimizer.evaluations == 1
    assert s.history == [("t0", -100.0)]
    assert s.suggest("t1") != first
    s.on_trial_complete("t1", {"score": -2.0})
    # mode="max": the better trial is the higher score, and best() says it in the metric.
    assert s.best()[1] == -2.0
    with pytest.raises(ValueError, match="failure_value"):
        searcher(failure_value=float("nan"))


def test_it_says_finished_once_the_optimizer_stops():
    s = searcher(optimizer("coordinate", max_evaluations=3))
    for i in range(3):
        config = s.suggest(f"t{i}")
        s.on_trial_complete(f"t{i}", {"cost": quadratic(config)})
    assert s.optimizer.status == "budget_spent"
    assert s.suggest("t3") == Searcher.FINISHED


def test_a_checkpoint_with_a_trial_in_flight_resumes_it(tmp_path):
    s = searcher()
    for i in range(5):
        s.on_trial_complete(f"t{i}", {"cost": quadratic(s.suggest(f"t{i}"))})
    running = s.suggest("t5")
    path = tmp_path / "searcher.pkl"
    s.save(str(path))
    again = searcher(optimizer(seed=99))  # a fresh searcher, as after a crash
    again.restore(str(path))
    assert again.optimizer.evaluations == 5 and again.history == s.history
    assert again.optimizer.in_flight == s.optimizer.in_flight
    assert again.optimizer.best()[1] == s.optimizer.best()[1]
    again.on_trial_complete("t5", {"cost": quadratic(running)})  # the trial that was running
    assert again.optimizer.evaluations == 6 and again.history[-1][0] == "t5"
    again.on_trial_complete("unknown", {"cost": 0.0})  # not one of ours: ignored
    assert again.optimizer.evaluations == 6
    # The searcher crosses processes (pickle) the same way.
    copy = pickle.loads(pickle.dumps(again))
    assert copy.optimizer.evaluations == 6 and copy.history == again.history


def test_bad_spaces_are_refused_with_the_parameter_named():
    with pytest.raises(ValueError, match="`k`"):
        CtrlAdaptSearch({"k": tune.choice([1, 2])}, optimizer=optimizer())
    with pytest.raises(ValueError, match="grid_search"):
        CtrlAdaptSearch({"k": tune.grid_search([1.0, 2.0])}, optimizer=optimizer())
    with pytest.raises(ValueError, match="3 parameters, the space 2"):
        CtrlAdaptSearch({"a": (0, 1), "b": (0, 1)}, optimizer=optimizer())
    with pytest.raises(RuntimeError, match="search space"):
        CtrlAdaptSearch(metric="cost", mode="min").suggest("t0")


def test_a_list_is_refused_as_a_range_instead_of_passed_as_a_constant():
    with pytest.raises(ValueError, match=r"`b` is a list \[0.0, 1.0\]: a range is a tuple"):
        CtrlAdaptSearch({"a": (0.0, 1.0), "b": [0.0, 1.0]}, algorithm="cmaes")
    # Other values stay constants.
    s = CtrlAdaptSearch({"a": (0.0, 1.0), "env": "pendulum"}, algorithm="cmaes",
                        metric="cost", mode="min")
    assert s.parameter_names == ["a"] and s.suggest("t0")["env"] == "pendulum"


def test_a_loguniform_parameter_is_searched_as_its_logarithm():
    s = CtrlAdaptSearch({"lr": tune.loguniform(1e-4, 1e-1), "kp": tune.quniform(0.0, 4.0, 0.5)},
                        algorithm="cmaes", seed=2, start={"lr": 1e-2, "kp": 1.0},
                        metric="cost", mode="min")
    opt = s.optimizer
    assert np.allclose(opt.recommend(), [math.log(1e-2), 1.0], atol=1e-6)
    configs = [s.suggest(f"t{i}") for i in range(opt.max_in_flight)]
    for i, c in enumerate(configs):
        assert 1e-4 * (1 - 1e-6) <= c["lr"] <= 1e-1 * (1 + 1e-6)
        assert c["kp"] % 0.5 == 0
        s.on_trial_complete(f"t{i}", {"cost": (math.log10(c["lr"]) + 3) ** 2})
    assert opt.evaluations == len(configs)


def test_points_to_evaluate_run_first_and_count_in_best():
    s = searcher(points_to_evaluate=[{"a": 0.5, "b": -0.4, "c": 0.3}])
    assert s.suggest("p0") == {"a": 0.5, "b": -0.4, "c": 0.3}
    s.on_trial_complete("p0", {"cost": 0.0})
    config = s.suggest("t1")
    s.on_trial_complete("t1", {"cost": quadratic(config)})
    assert s.best() == ({"a": 0.5, "b": -0.4, "c": 0.3}, 0.0)
    s.add_evaluated_point({"a": 0.0, "b": 0.0, "c": 0.0}, 0.5)
    assert s.evaluated_points[-1] == ({"a": 0.0, "b": 0.0, "c": 0.0}, 0.5)
    assert s.optimizer.evaluations == 1  # they do not enter the firmware's state


def test_a_candidate_that_always_fails_is_retried_a_bounded_number_of_times():
    s = searcher(optimizer("coordinate"), max_retries=2)
    config = s.suggest("t0")
    s.on_trial_complete("t0", {"cost": 1.0})  # a measured cost: the worst so far is 1.0
    bad = s.suggest("t1")
    trials = 1
    for attempt in range(3):  # the first failure and two retries
        s.on_trial_complete(f"t{trials}", None, error=True)
        trials += 1
        again = s.suggest(f"t{trials}")
        if attempt < 2:
            assert again == bad
    assert again != bad  # after two retries it was reported at the worst metric seen
    assert s.cancelled == 2 and len(s.penalised) == 1 and s.penalised[0][1] == 1.0
    assert s.optimizer.evaluations == 2


def test_the_concurrency_limit_is_the_optimizers_within_tunes():
    s = searcher(optimizer("cmaes"))
    assert s.max_concurrent == s.optimizer.max_in_flight > 2
    assert s.set_max_concurrency(2) is True and s.max_concurrent == 2
    assert s.suggest("t0") and s.suggest("t1") and s.suggest("t2") is None
    s.on_trial_complete("t0", {"cost": 1.0})
    assert s.suggest("t3") is not None


class FakeBroker:
    """Stands in for the searcher's Ray actor: keeps what it is handed for each deferred trial."""

    def __init__(self):
        self.handed = {}
        self.put = self

    def remote(self, slot, assigned):
        self.handed[slot] = assigned


def test_with_the_trainable_wrapped_a_free_worker_waits_for_the_next_generation():
    s = searcher(optimizer("cmaes"))  # λ = 7 at n = 3
    s.set_max_concurrency(2)
    s._broker = FakeBroker()
    bare = searcher(optimizer("cmaes"))
    bare.set_max_concurrency(2)
    wrapped = s.trainable(quadratic)
    assert wrapped.__name__ == "quadratic" and wrapped({"a": 0.5, "b": -0.4, "c": 0.3}) == 0.0
    alone = optimizer("cmaes")
    # The first generation, two at a time, until its last candidate is out.
    for i in range(7):
        config = s.suggest(f"t{i}")
        assert config == bare.suggest(f"t{i}") and ctrl_adapt_tune.DEFERRED not in config
        alone.ask()
        alone.tell(quadratic(config))
        if i < 6:
            s.on_trial_complete(f"t{i}", {"cost": quadratic(config)})
            bare.on_trial_complete(f"t{i}", {"cost": quadratic(config)})
    # A worker is free while the generation's last trial runs: unwrapped, Tune gets nothing
    # (and stops the idle worker); wrapped, a deferred trial that holds the worker.
    assert bare.suggest("w") is None
    deferred = s.suggest("w")
    assert deferred == {ctrl_adapt_tune.DEFERRED: "w"} and s.deferred_trials == 1
    assert s.suggest("x") is None  # Tune's limit: t6 and w
    assert s.optimizer.evaluations == 6
    s.on_trial_complete("t6", {"cost": quadratic(config)})
    # The generation is complete: the deferred trial gets the next generation's first
    # candidate, the one ask gives the sequential optimizer.
    handed, stopped = s._broker.handed["w"]
    theta = alone.ask()
    assert stopped is None and [handed[k] for k in "abc"] == list(theta)
    s.on_trial_complete("w", {"cost": quadratic(handed)})
    alone.tell(quadratic(handed))
    assert s.optimizer.save() == alone.save()
    # A deferred trial that ends before its candidate came (an error) costs nothing.
    s.on_trial_complete("never", None, error=True)
    assert s.optimizer.evaluations == 8


def test_cmaes_own_penalty_setting_reaches_the_optimizer():
    s = CtrlAdaptSearch(SPACE, algorithm="cmaes", penalty=3.0, metric="cost", mode="min")
    assert s.optimizer.evaluations == 0
    with pytest.raises(ctrl_adapt.OptimizerError, match="penalty"):
        CtrlAdaptSearch(SPACE, algorithm="cmaes", penalty=-1.0)


def test_the_written_record_is_the_firmware_types_state(tmp_path):
    s = searcher(optimizer(seed=3))
    for i in range(20):
        s.on_trial_complete(f"t{i}", {"cost": quadratic(s.suggest(f"t{i}"))})
    path = tmp_path / "best.rec"
    s.suggest("t20")  # in flight: not a record for the firmware yet
    with pytest.raises(ValueError, match="in flight"):
        s.write_record(path)
    assert not path.exists()
    s.on_trial_complete("t20", None, error=True)  # cancelled: it waits to be handed out again
    with pytest.raises(ValueError, match="cancelled candidate"):
        s.write_record(path)
    s.on_trial_complete("t21", {"cost": quadratic(s.suggest("t21"))})
    rust_type = s.write_record(path)
    assert rust_type == "Cmaes<3, 7>"
    loaded = ctrl_adapt.Optimizer.load(path.read_bytes())
    assert loaded.evaluations == 21 and loaded.best()[1] == s.optimizer.best()[1]
    assert np.array_equal(loaded.best()[0], s.optimizer.best()[0])
    # The firmware's Rust loader (`Cmaes<3, 7>`) continues from the file as Python does.
    out = subprocess.run([REFERENCE, "cmaes", "3", "0", "30", "--from", str(path), "--seed-after", "5"],
                         check=True, capture_output=True, text=True)
    rust = json.loads(out.stdout)
    again = ctrl_adapt.Optimizer.load(path.read_bytes(), seed=5)
    for candidate, cost in zip(rust["candidates"], rust["costs"]):
        theta = again.ask()
        assert [int(b) for b in theta.astype(np.float32).view(np.uint32)] == candidate
        again.tell(cost)
    assert write_record(again, path) == "Cmaes<3, 7>" and path.read_bytes() == again.save()


def test_write_record_refuses_while_a_cancelled_candidate_waits(tmp_path):
    """After a cancel nothing is in flight, but the candidate waits to be handed out again:
    the state is not the firmware type's yet. `idle` says so and `write_record` refuses
    (before, it wrote an `InFlight` record that the firmware's loader rejects)."""
    opt = optimizer(seed=4)
    path = tmp_path / "x.rec"
    assert opt.idle
    ticket, _ = opt.suggest()
    assert not opt.idle
    opt.cancel(ticket)
    assert opt.in_flight == [] and not opt.idle
    with pytest.raises(ValueError, match="cancelled candidate"):
        write_record(opt, path)
    assert not path.exists()
    ticket, theta = opt.suggest()  # the same candidate again
    opt.report(ticket, float(np.sum((theta - TARGET) ** 2)))
    assert opt.idle
    assert write_record(opt, path) == "Cmaes<3, 7>"
    assert ctrl_adapt.Optimizer.load(path.read_bytes()).evaluations == opt.evaluations


# -- on a local Ray cluster -------------------------------------------------------------------


@pytest.fixture(scope="session")
def cluster():
    # The trainables below travel to the workers by value (this module is not installed).
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield ray.cluster_resources()
    ray.shutdown()


def timed_quadratic(config):
    start = time.time()
    cost = quadratic(config)
    time.sleep(0.05)  # long enough for two trials to overlap if both were handed out
    return {"cost": cost, "start": start, "end": time.time()}


def fit(s, trainable, samples, tmp_path, param_space=None):
    tuner = tune.Tuner(
        trainable,
        param_space=param_space,
        tune_config=tune.TuneConfig(search_alg=s, num_samples=samples, reuse_actors=True),
        run_config=tune.RunConfig(storage_path=str(tmp_path), verbose=0),
    )
    return tuner.fit()


def most_at_once(results):
    """The most trials whose [start, end] overlapped, from the workers' own clocks."""
    events = sorted([(r.metrics["start"], 1) for r in results] + [(r.metrics["end"], -1) for r in results])
    running = peak = 0
    for _, step in events:
        running += step
        peak = max(peak, running)
    return peak


# The sequential search's run (30 trials one at a time, about 50 s of Ray) is a slow test:
# `CTRL_ADAPT_SLOW=1 bash scripts/python-ci` (`scripts/research python-slow`) runs it. Its
# limit of one in flight is checked without a cluster above
# (test_it_never_hands_out_more_than_the_optimizer_allows), and CMA-ES's run below checks the
# same searcher on the cluster.
SLOW = pytest.mark.skipif(
    os.environ.get("CTRL_ADAPT_SLOW") != "1", reason="slow: set CTRL_ADAPT_SLOW=1 (scripts/research python-slow)"
)


@pytest.mark.parametrize("algorithm", ["cmaes", pytest.param("coordinate", marks=SLOW)])
def test_it_learns_on_two_workers_within_the_optimizers_limit(cluster, algorithm, tmp_path):
    assert cluster["CPU"] == 2
    s = CtrlAdaptSearch(optimizer=optimizer(algorithm, seed=1), metric="cost", mode="min")
    # The space comes from the Tuner (set_search_properties), with a constant passed through.
    space = {"a": tune.uniform(-1, 1), "b": tune.uniform(-1, 1), "c": tune.uniform(-1, 1), "k": 7}
    results = fit(s, timed_quadratic, 30, tmp_path, space)
    assert not results.errors and len(results) == 30
    assert all(r.config["k"] == 7 for r in results)
    # Learns: from 0.5 at the start to a tenth of it or less within 30 episodes.
    assert s.optimizer.evaluations == 30
    assert s.best()[1] <= 0.05, s.best()
    # The same search as one at a time: the optimizer takes a generation's costs in the
    # order it handed the candidates out, whatever order the workers finished in.
    alone = optimizer(algorithm, seed=1)
    for _ in range(30):
        theta = alone.ask()
        alone.tell(quadratic(dict(zip("abc", theta))))
    assert np.array_equal(alone.best()[0], s.optimizer.best()[0])
    # Never more than the optimizer's limit out at once, by the searcher's count and by the
    # trials' own clocks: one at a time for a sequential search although the cluster had
    # room for two; more than one where the optimizer allows it.
    limit = s.optimizer.max_in_flight
    assert min(limit, 2) <= s.peak_in_flight <= limit
    assert most_at_once(results) <= min(limit, cluster["CPU"])


def worker_quadratic(config):
    time.sleep(0.05)
    return {"cost": quadratic(config), "pid": os.getpid()}


def test_the_wrapped_trainable_runs_the_same_search_with_deferred_trials(cluster, tmp_path):
    s = searcher(optimizer("cmaes", seed=2))
    tuner = tune.Tuner(
        s.trainable(worker_quadratic),
        tune_config=tune.TuneConfig(search_alg=s, num_samples=14, reuse_actors=True, max_concurrent_trials=2),
        run_config=tune.RunConfig(storage_path=str(tmp_path), verbose=0),
    )
    results = tuner.fit()
    # Two generations of λ = 7: a worker freed while the first one's last trial ran waited
    # for the second one's first candidate (a deferred trial), and it ran and was reported.
    assert not results.errors and len(results) == 14
    assert s.deferred_trials >= 1 and s.optimizer.evaluations == 14
    alone = optimizer("cmaes", seed=2)
    for _ in range(14):
        alone.tell(quadratic(dict(zip("abc", alone.ask()))))
    assert alone.save() == s.optimizer.save()


def failing_once(config):
    """Fails the first time it sees any candidate (the marker file says who has failed)."""
    marker = config["marker"]
    if not os.path.exists(marker):
        with open(marker, "w") as f:
            json.dump([config["a"], config["b"], config["c"]], f)
        raise RuntimeError("the simulator crashed")
    return {"cost": quadratic(config)}


def test_an_errored_trial_does_not_lose_its_candidate(cluster, tmp_path):
    s = searcher()
    results = fit(s, failing_once, 6, tmp_path, {"marker": str(tmp_path / "failed.json")})
    assert len(results.errors) == 1 and s.cancelled == 1
    with open(tmp_path / "failed.json") as f:
        failed = json.load(f)
    # The failed candidate ran again in a later trial, and was reported; nothing is lost.
    configs = [[r.config["a"], r.config["b"], r.config["c"]] for r in results if r.error is None]
    assert failed in configs
    assert s.optimizer.evaluations == len(configs) == 5
    assert any(math.isclose(cost, quadratic(dict(zip("abc", failed)))) for _, cost in s.history)


def test_save_and_restore_mid_run_resumes_the_search(cluster, tmp_path):
    s = searcher(optimizer(seed=4))
    first = fit(s, timed_quadratic, 12, tmp_path / "first")
    path = tmp_path / "searcher.pkl"
    s.save(str(path))
    best_at_checkpoint = s.best()[1]
    again = searcher(optimizer(seed=4))
    again.restore(str(path))
    assert again.optimizer.evaluations == 12
    second = fit(again, timed_quadratic, 12, tmp_path / "second")
    assert again.optimizer.evaluations == 24 and len(again.history) == 24
    assert again.best()[1] <= best_at_checkpoint
    # It continued, not started over: the second half's trials are better than the first's.
    mean = lambda results: np.mean([r.metrics["cost"] for r in results])  # noqa: E731
    assert mean(second) < mean(first)
