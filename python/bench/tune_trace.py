"""A traced Ray Tune run of pool_workers.py's CMA-ES search (n = 2, λ = 6, two generations of
trials that burn a fixed CPU time), to see where the workers go: each trial's worker process
and its start and end, how long two trials overlapped, what the searcher's ``suggest``
answered (a configuration, ``None`` or ``FINISHED``) and when, and Tune's actor events
(actors requested, started, reused, cached, stopped).

    python python/bench/tune_trace.py [--trial-cpu 0.5] [--workers 1 2] [--unwrapped]

``--unwrapped`` passes the bare trainable to Tune instead of ``search.trainable(...)``: then,
at the end of the first generation, Tune stops the idle worker, and the second generation
runs in one process (``_remove_actor`` counted for each trial). Diagnostic only: the actor
events come from wrapping private methods of Ray Tune's ``TuneController`` (as in Ray 2.60);
under another Ray version those names may not exist (the script then says so).
"""

import argparse
import collections
import os
import tempfile
import time

import numpy as np
import ray
from ray import tune
from ray.tune.execution import tune_controller
from ray.tune.search import Searcher

from ctrl_adapt.tune import CtrlAdaptSearch

EVENTS = []
T0 = [time.time()]
ACTOR_EVENTS = ["_schedule_trial_actor", "_actor_started", "_maybe_reuse_cached_actor",
                "_maybe_cache_trial_actor", "_remove_actor", "_actor_stopped"]


def event(kind, **what):
    EVENTS.append((round(time.time() - T0[0], 3), kind, what))


def trace_controller():
    for name in ACTOR_EVENTS:
        original = getattr(tune_controller.TuneController, name, None)
        if original is None:
            print(f"(TuneController.{name} not found in this Ray version: not traced)")
            continue

        def traced(self, *args, _original=original, _name=name, **kwargs):
            result = _original(self, *args, **kwargs)
            event(_name, on=str(args[0])[:40] if args else "", returned=result if isinstance(result, bool) else None)
            return result

        setattr(tune_controller.TuneController, name, traced)


class TracedSearch(CtrlAdaptSearch):
    def suggest(self, trial_id):
        answer = super().suggest(trial_id)
        kind = "FINISHED" if answer == Searcher.FINISHED else ("None" if answer is None else "configuration")
        event("suggest", trial=trial_id, answer=kind, in_flight=len(self.optimizer.in_flight))
        return answer

    def on_trial_complete(self, trial_id, result=None, error=False):
        event("on_trial_complete", trial=trial_id)
        return super().on_trial_complete(trial_id, result, error)


def burn(cpu):
    t0 = time.process_time()
    x = 0.0
    while time.process_time() - t0 < cpu:
        for _ in range(1000):
            x += 1.0


def trial(config):
    start = time.time()
    burn(config["cpu"])
    theta = np.array([config[f"x{i}"] for i in range(config["n"])])
    return {"cost": float(np.sum(theta**2)), "pid": os.getpid(), "start": start, "end": time.time()}


def run(workers, cpu, wrapped, n=2, budget=12):
    EVENTS.clear()
    search = TracedSearch({f"x{i}": (-1.0, 1.0) for i in range(n)}, algorithm="cmaes", seed=1,
                          metric="cost", mode="min")
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        tuner = tune.Tuner(
            search.trainable(trial) if wrapped else trial,
            param_space={"n": n, "cpu": cpu},
            tune_config=tune.TuneConfig(search_alg=search, num_samples=budget, reuse_actors=True,
                                        max_concurrent_trials=workers),
            run_config=tune.RunConfig(verbose=0, storage_path=tempfile.mkdtemp(prefix="tune-trace-")),
        )
        T0[0] = time.time()
        results = tuner.fit()
        wall = time.time() - T0[0]
    finally:
        ray.shutdown()
    rows = sorted((r.metrics["start"] - T0[0], r.metrics["end"] - T0[0], r.metrics["pid"])
                  for r in results if "pid" in r.metrics)
    print(f"\n{workers} worker(s), trainable {'wrapped' if wrapped else 'unwrapped'}: fit {wall:.2f} s "
          f"(worker start-up included), {len({pid for *_, pid in rows})} worker processes, "
          f"{search.deferred_trials} deferred trials")
    for start, end, pid in rows:
        print(f"  trial {start:7.3f} -> {end:7.3f} s  process {pid}")
    marks = sorted([(s, 1) for s, _, _ in rows] + [(e, -1) for _, e, _ in rows])
    running, both, last = 0, 0.0, None
    for t, step in marks:
        if running >= 2:
            both += t - last
        running, last = running + step, t
    print(f"  two trials at once: {both:.2f} s")
    print("  events:", dict(collections.Counter(kind for _, kind, _ in EVENTS)))
    for e in EVENTS:  # the answers None and the failed reuses (every loop of Tune's) left out
        quiet = (e[1] == "suggest" and e[2]["answer"] == "None") or (
            e[1] == "_maybe_reuse_cached_actor" and e[2]["returned"] is False)
        if not quiet:
            print("   ", e)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trial-cpu", type=float, default=0.5)
    p.add_argument("--workers", type=int, nargs="+", default=[2])
    p.add_argument("--unwrapped", action="store_true")
    a = p.parse_args()
    trace_controller()
    for workers in a.workers:
        run(workers, a.trial_cpu, not a.unwrapped)


if __name__ == "__main__":
    main()
