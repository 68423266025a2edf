"""Optimizer overhead per ask + tell from Python, at n = 18, for every algorithm: the
median over repeats of the mean time per pair (the cost function is a sphere, excluded).

    python python/bench/overhead.py [--n 18] [--pairs 2000] [--repeats 5]
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


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=18)
    p.add_argument("--pairs", type=int, default=2000)
    p.add_argument("--repeats", type=int, default=5)
    a = p.parse_args()
    print(f"| algorithm (n = {a.n}) | Rust type | µs per ask + tell (median of {a.repeats}) |")
    print("| --- | --- | ---: |")
    for algorithm in ctrl_adapt.algorithms():
        times = [per_pair(algorithm, a.n, a.pairs, s) for s in range(a.repeats)]
        print(f"| {algorithm} | `{ctrl_adapt.rust_type(algorithm, a.n)}` | {statistics.median(times):.1f} |")


if __name__ == "__main__":
    main()
