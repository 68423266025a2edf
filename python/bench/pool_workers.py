"""Wall time of a CMA-ES search on ctrl_adapt.pool (a persistent process pool) with 1 and then
2 workers, and the ratio: trials that burn a fixed amount of CPU time each (a stand-in for a
simulator), so the figure is the pool's, not a plant's.

    python python/bench/pool_workers.py [--trial-cpu 0.5] [--dimension 2] [--generations 2] [--tune]

With ``--tune``, the same search also through Ray Tune (``CtrlAdaptSearch``, a local Ray
cluster of as many CPUs as workers, ``reuse_actors=True``, ``max_concurrent_trials`` the
workers, the trainable wrapped by ``search.trainable``; ``--unwrapped`` without that),
Ray's start-up apart, with the worker processes that ran trials, the time two trials ran
at once (the trials' own clocks) and the deferred trials.

At n = 2 CMA-ES's population is λ = 6: each generation is 6 trials, 3 per worker with two.
Prints a Markdown table with the cores the trials got (their CPU time over the wall time): on
a shared machine other processes take cores, and a second worker gains only if a second core
is free.
"""

import argparse
import os
import sys
import tempfile
import time

import numpy as np

import ctrl_adapt
import ctrl_adapt.pool


def burn(theta, cpu):
    """Busy for `cpu` seconds of this process's CPU time; returns the sphere cost."""
    t0 = time.process_time()
    x = 0.0
    while time.process_time() - t0 < cpu:
        for _ in range(1000):
            x += 1.0
    return float(np.sum(np.asarray(theta) ** 2))


class Trial:
    """Picklable: the CPU time per trial (or, with `sleep`, wall time spent sleeping)."""

    def __init__(self, cpu, sleep=False):
        self.cpu, self.sleep = cpu, sleep

    def __call__(self, theta):
        if self.sleep:
            time.sleep(self.cpu)
            return float(np.sum(np.asarray(theta) ** 2))
        return burn(theta, self.cpu)


def tune_trial(config):
    """A Ray trial: the candidate's CPU burn; its config carries the CPU time. Reports the
    worker process and its own start and end (wall clock)."""
    theta = [config[f"x{i}"] for i in range(config["n"])]
    start = time.time()
    cost = burn(theta, config["cpu"])
    return {"cost": cost, "pid": os.getpid(), "start": start, "end": time.time()}


def overlap(results):
    """Seconds during which two or more trials ran, from the trials' own clocks."""
    events = sorted([(r.metrics["start"], 1) for r in results if "start" in r.metrics]
                    + [(r.metrics["end"], -1) for r in results if "end" in r.metrics])
    running, total, last = 0, 0.0, None
    for t, step in events:
        if running >= 2:
            total += t - last
        running, last = running + step, t
    return total


def run_tune(n, budget, cpu, workers, wrapped=True):
    import ray
    from ray import tune

    from ctrl_adapt.tune import CtrlAdaptSearch

    space = {f"x{i}": (-1.0, 1.0) for i in range(n)}
    search = CtrlAdaptSearch(space, algorithm="cmaes", seed=1, metric="cost", mode="min")
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        tuner = tune.Tuner(
            search.trainable(tune_trial) if wrapped else tune_trial,
            param_space={"n": n, "cpu": cpu},
            tune_config=tune.TuneConfig(search_alg=search, num_samples=budget, reuse_actors=True,
                                        max_concurrent_trials=workers),
            run_config=tune.RunConfig(verbose=0, storage_path=tempfile.mkdtemp(prefix="pool-bench-")),
        )
        start = time.perf_counter()
        results = tuner.fit()
        wall = time.perf_counter() - start
    finally:
        ray.shutdown()
    pids = len({r.metrics["pid"] for r in results if "pid" in r.metrics})
    return wall, search, pids, overlap(results)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trial-cpu", type=float, default=0.5, help="CPU seconds per trial")
    p.add_argument("--dimension", type=int, default=2)
    p.add_argument("--generations", type=int, default=2)
    p.add_argument("--tune", action="store_true", help="also through Ray Tune")
    p.add_argument("--unwrapped", action="store_true",
                   help="through Tune without search.trainable (no deferred trials)")
    p.add_argument("--sleep", action="store_true",
                   help="trials sleep instead of burning CPU: the pool's overlap without the cores")
    a = p.parse_args(argv)
    n = a.dimension
    lam = int(ctrl_adapt.rust_type("cmaes", n).split(",")[1].strip(" >"))
    budget = lam * a.generations
    print(f"command: python {' '.join([os.path.relpath(sys.argv[0])] + list(argv or sys.argv[1:]))}")
    print(f"CMA-ES n = {n}, λ = {lam}, {budget} trials of {a.trial_cpu} s {'asleep' if a.sleep else 'CPU'}; {os.cpu_count()} CPUs\n")
    rows = []
    for workers in (1, 2):
        start = time.perf_counter()
        result = ctrl_adapt.pool.minimize(Trial(a.trial_cpu, a.sleep), -np.ones(n), np.ones(n), algorithm="cmaes",
                                          budget=budget, workers=workers, seed=1)
        rows.append((workers, time.perf_counter() - start, result))
    # Cores used: the trials' CPU time over the wall time. Below 1 with one worker, the
    # machine's other processes held the cores; a second worker gains only what it can get.
    print("| workers | trials | wall time (s) | ratio to 1 worker | cores used | best cost |")
    print("| --- | --- | --- | --- | --- | --- |")
    for workers, wall, result in rows:
        used = float("nan") if a.sleep else result.evaluations * a.trial_cpu / wall
        print(f"| {workers} | {result.evaluations} | {wall:.2f} | {wall / rows[0][1]:.2f} | {used:.2f} | {result.cost:.3e} |")
    same = rows[0][2].optimizer.save() == rows[1][2].optimizer.save()
    print(f"\nsame final state with 1 and 2 workers: {same}")
    if a.tune:
        tuned = [(workers, *run_tune(n, budget, a.trial_cpu, workers, not a.unwrapped)) for workers in (1, 2)]
        print("\n| Ray workers | trials | most in flight | deferred trials | worker processes | two at once (s) "
              "| tuning wall time (s) | ratio to 1 worker | best cost |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for workers, wall, search, pids, both in tuned:
            print(f"| {workers} | {search.optimizer.evaluations} | {search.peak_in_flight} | "
                  f"{search.deferred_trials} | {pids} | {both:.2f} | {wall:.2f} | "
                  f"{wall / tuned[0][1]:.2f} | {search.best()[1]:.3e} |")


if __name__ == "__main__":
    main()
