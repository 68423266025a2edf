#!/usr/bin/env python3
"""Runs ZOOpt's SRACOS on the SRACOS paper's synthetic set-up, for comparison with
`cargo bench -p experiments --bench sracos`. Not part of CI.

Set-up (Hu, Qian & Yu 2017): Sphere and Ackley shifted to 0.2 on [-1, 1]^n, budget 20n,
ZOOpt's defaults (sequential RACOS, WR, budget-based set sizes, automatic uncertain bits),
seeds 1..15 (ZOOpt ignores seed 0). Prints, per function and n, the mean +- population std
of the best value over the seeds and ZOOpt's own time per evaluation (wall time of
`Opt.min` minus the time spent in the objective, divided by the budget).

    python3 -m venv /tmp/zoopt-venv && /tmp/zoopt-venv/bin/pip install zoopt
    /tmp/zoopt-venv/bin/python scripts/zoopt_compare.py            # n = 10, 100
    /tmp/zoopt-venv/bin/python scripts/zoopt_compare.py 10 100 1000 --seeds 15
"""

import argparse
import contextlib
import io
import math
import time

from importlib.metadata import version

import numpy as np
from zoopt import Dimension, Objective, Opt, Parameter


def sphere(x):
    x = np.asarray(x)
    return float(np.sum((x - 0.2) ** 2))


def ackley(x):
    x = np.asarray(x) - 0.2
    n = len(x)
    return float(
        -20.0 * math.exp(-0.2 * math.sqrt(np.sum(x * x) / n))
        - math.exp(np.sum(np.cos(2.0 * math.pi * x)) / n)
        + math.e
        + 20.0
    )


def run(f, n, seed):
    """Best value and overhead seconds per evaluation of one ZOOpt SRACOS run."""
    spent = [0.0]

    def timed(solution):
        start = time.perf_counter()
        value = f(solution.get_x())
        spent[0] += time.perf_counter() - start
        return value

    budget = 20 * n
    dim = Dimension(n, [[-1.0, 1.0]] * n, [True] * n)
    parameter = Parameter(budget=budget, seed=seed)
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        solution = Opt.min(Objective(timed, dim), parameter)
    total = time.perf_counter() - start
    return solution.get_value(), (total - spent[0]) / budget


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dims", nargs="*", type=int, default=[10, 100])
    parser.add_argument("--seeds", type=int, default=15)
    args = parser.parse_args()
    print(f"ZOOpt {version('zoopt')} SRACOS, "
          f"{args.seeds} seeds (1..{args.seeds}), budget 20n")
    print("| function | n | budget | ZOOpt SRACOS best (mean ± std) | ZOOpt µs/eval (overhead) |")
    print("|---|---:|---:|---:|---:|")
    for n in args.dims:
        for name, f in (("Sphere", sphere), ("Ackley", ackley)):
            results = [run(f, n, seed) for seed in range(1, args.seeds + 1)]
            best = np.array([r[0] for r in results])
            overhead = np.array([r[1] for r in results])
            print(
                f"| {name} | {n} | {20 * n} | {best.mean():.4f} ± {best.std():.4f} | "
                f"{1e6 * np.median(overhead):.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
