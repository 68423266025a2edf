"""Optimizer overhead per ask + tell from Python, at n = 18, for every algorithm: the
median over repeats of the mean time per pair (the cost function is a sphere, excluded).

    python python/bench/overhead.py [--n 18] [--pairs 2000] [--repeats 5]

With `--peers`, instead: the same figure for the Python peers, in an environment that has
them (experiments/peers/requirements.txt: ZOOpt, pycma, nevergrad), each driven the way its
documentation shows on the same sphere in [-1, 1]^n, from 0 where it takes a start, with
σ₀ = 0.25 where it takes one; the time spent in the cost function is excluded.
"""

import argparse
import statistics
import time

import numpy as np

import ctrl_adapt


def per_pair(algorithm, n, pairs, seed):
    start = None if algorithm in ("sracos", "crs", "two-phase") else np.zeros(n)
    opt = ctrl_adapt.Optimizer(algorithm, -np.ones(n), np.ones(n), start, seed=seed)
    thetas, spent = 0, 0.0
    cost = 1.0
    for _ in range(pairs):
        if opt.status != "running":
            break
        t0 = time.perf_counter()
        theta = opt.ask()
        opt.tell(cost)
        spent += time.perf_counter() - t0
        cost = float(theta @ theta)  # outside the timed part; told on the next pair
        thetas += 1
    return spent / max(thetas, 1) * 1e6


def peer_per_evaluation(peer, n, evaluations, seed):
    """µs of the peer's own time per evaluation over `evaluations` evaluations."""
    spent_in_f = [0.0, 0]

    def f(x):
        t0 = time.perf_counter()
        x = np.asarray(x, dtype=float)
        c = float(x @ x)
        spent_in_f[0] += time.perf_counter() - t0
        spent_in_f[1] += 1
        return c

    t0 = time.perf_counter()
    if peer == "zoopt-sracos":
        import contextlib
        import io

        from zoopt import Dimension, Objective, Opt, Parameter

        dim = Dimension(n, [[-1.0, 1.0]] * n, [True] * n)
        objective = Objective(lambda s: f(s.get_x()), dim)
        with contextlib.redirect_stdout(io.StringIO()):
            Opt.min(objective, Parameter(budget=evaluations, seed=seed))
    elif peer == "pycma":
        import cma

        es = cma.CMAEvolutionStrategy(
            np.zeros(n), 0.25, {"bounds": [-1, 1], "seed": seed + 1, "verbose": -9}
        )
        while spent_in_f[1] < evaluations:
            xs = es.ask()
            es.tell(xs, [f(x) for x in xs])
    else:
        import nevergrad as ng

        param = ng.p.Array(init=np.zeros(n)).set_bounds(-1.0, 1.0).set_mutation(sigma=0.25)
        param.random_state = np.random.RandomState(seed)
        name = {"ng-oneplusone": "OnePlusOne", "ng-ngopt": "NGOpt"}[peer]
        opt = ng.optimizers.registry[name](parametrization=param, budget=evaluations)
        for _ in range(evaluations):
            cand = opt.ask()
            opt.tell(cand, f(cand.value))
    total = time.perf_counter() - t0
    return (total - spent_in_f[0]) / max(spent_in_f[1], 1) * 1e6


def peers(a):
    import importlib.metadata as meta
    import warnings

    # Imported before any timing (the first import costs seconds); nevergrad warns that
    # σ₀ = 0.25 of a width-2 box is close to the bounds: it is the figure asked for.
    import cma  # noqa: F401
    import nevergrad  # noqa: F401
    import zoopt  # noqa: F401

    warnings.filterwarnings("ignore", module="nevergrad")

    versions = {
        "zoopt-sracos": "zoopt",
        "pycma": "cma",
        "ng-oneplusone": "nevergrad",
        "ng-ngopt": "nevergrad",
    }
    print(f"| peer (n = {a.n}) | package | µs per evaluation (median of {a.repeats}) |")
    print("| --- | --- | ---: |")
    for peer, package in versions.items():
        times = [peer_per_evaluation(peer, a.n, a.pairs, s) for s in range(a.repeats)]
        version = meta.version(package)
        print(f"| {peer} | {package} {version} | {statistics.median(times):.1f} |")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=18)
    p.add_argument("--pairs", type=int, default=2000)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--peers", action="store_true", help="the Python peers instead")
    a = p.parse_args()
    if a.peers:
        peers(a)
        return
    print(f"| algorithm (n = {a.n}) | Rust type | µs per ask + tell (median of {a.repeats}) |")
    print("| --- | --- | ---: |")
    for algorithm in ctrl_adapt.algorithms():
        times = [per_pair(algorithm, a.n, a.pairs, s) for s in range(a.repeats)]
        print(f"| {algorithm} | `{ctrl_adapt.rust_type(algorithm, a.n)}` | {statistics.median(times):.1f} |")


if __name__ == "__main__":
    main()
