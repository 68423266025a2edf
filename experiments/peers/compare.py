#!/usr/bin/env python3
"""Side by side: the library's optimizers and its model-based learner against pycma, ZOOpt,
nevergrad, SafeOpt, bayesian-optimization and BoTorch on the robots' own tasks (AUV survey,
also with the current turned by 45°, hopping leg, via-point arm), with the same budgets, seeds
and episodes.

Every method scores θ through the `oracle` binary (experiments/src/bin/oracle.rs): the
library's methods run inside it (`run`), the peers ask it for one episode at a time (`eval`).
Peers search the box mapped to [-1, 1]^n, starting from the task's start θ where they take one,
with the library's step sizes (σ₀ = a quarter of the AUV box, a sixth of the hopper's, 1 % of
the arm's, in half-widths).

Per task and method: success rate, median and IQR of the episodes to the success threshold
(a run that never succeeds counts as beyond the budget), the median best cost, the median
deployed cost (the returned θ re-run on 5 fresh episodes: the figure a user gets) and the
optimizer's own time per evaluation (oracle time excluded), and the unsafe episodes summed
over the seeds: the oracle judges each episode (on the hopper an episode off the gait,
elsewhere a cost above the bare controller's by more than 20 %, the bound that the safe
methods, `linebo-safe` and `safeopt`, are given). The library's methods: `coordinate`,
`sracos`, `crs`, `cmaes`, `rockstar`, `linebo`, `linebo-safe`, and `model`, the model-based
learner (`ctrl_adapt::model::ModelBased`, experiments/src/model_learner.rs: a plant model
fitted on every episode's ticks, CMA-ES on imagined episodes, a coordinate-search fallback;
on the AUV tasks, the hopper and the arm only; its optimizer time includes its imagined
episodes, and its rows count the episodes its fallback proposed).

    python3 -m venv .venv-peers && .venv-peers/bin/pip install -r experiments/peers/requirements.txt
    cargo build --release -p experiments --bin oracle
    .venv-peers/bin/python experiments/peers/compare.py --tasks auv --seeds 1-20
    .venv-peers/bin/python experiments/peers/compare.py --table a.json b.json   # merge runs
    python3 experiments/peers/compare.py --table a.json --paired model   # seed by seed

The library through its Python package, like a peer (`py-cmaes`, `py-crs`, `py-rockstar`:
the package installed in the same environment, `pip install ./python`):

    .venv-peers/bin/python experiments/peers/compare.py --tasks auv --methods cmaes,py-cmaes

The library's rows run without the peers installed (plain `python3`, no numpy). BoTorch
(`botorch`: GP-BO, `run_botorch`) pulls torch, several GB: it has a venv and a requirements
file of its own (numpy, scipy, BoTorch), and the other rows run without it:

    python3 -m venv .venv-botorch
    .venv-botorch/bin/pip install -r experiments/peers/requirements-botorch.txt
    .venv-botorch/bin/python experiments/peers/compare.py --tasks auv --methods botorch --budget 30

Outside `cargo test` and CI: the peers come from PyPI.
"""

import argparse
import contextlib
import io
import json
import math
import multiprocessing
import os
import statistics
import subprocess
import sys
import time
import warnings

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

try:
    import numpy as np  # noqa: E402  (the peers need it; the library's rows run without it)
except ImportError:
    np = None

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ORACLE = os.path.join(ROOT, "target", "release", "oracle")
LIBRARY = ["coordinate", "sracos", "crs", "cmaes", "rockstar", "linebo", "linebo-safe", "model"]
PEERS = ["zoopt-sracos", "pycma", "ng-oneplusone", "ng-ngopt", "safeopt", "bayes-opt"]
# Peers run on request only: BoTorch needs torch (requirements-botorch.txt).
ON_REQUEST = ["botorch"]
# The library through its Python package (`ctrl_adapt`, python/README.md), episodes from the
# oracle like a peer's. `py-cmaes` has the oracle's `cmaes` sizes and settings (Cmaes<n, λ>,
# σ₀ the task's step), so its rows equal that row's; `py-crs` and `py-rockstar` have the
# package's sizes (M = 10(n + 1), M = 5n; the oracle's: 100 and 160).
BINDING = ["py-cmaes", "py-crs", "py-rockstar"]
STEP = {
    "auv": 0.25,
    "auv-calm": 0.25,
    "auv-rotated": 0.25,
    "hopper": 1.0 / 6.0,
    "arm": 0.01,
    "sphere": 0.3,
    "ackley": 0.3,
}


class Oracle:
    """One oracle process serving one task and seed."""

    def __init__(self, task, seed):
        self.task, self.seconds = task, 0.0
        self.proc = subprocess.Popen(
            [ORACLE], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1
        )
        n, budget, threshold, safe = self.ask(f"task {task} {seed}").split()[1:]
        self.n, self.budget, self.threshold = int(n), int(budget), float(threshold)
        # The safe methods' cost bound: the bare controller's cost plus the margin.
        self.safe_threshold = float(safe)
        vector = (lambda v: np.array(v, dtype=float)) if np else (lambda v: [float(x) for x in v])
        self.lower = vector(self.ask("lower").split())
        self.upper = vector(self.ask("upper").split())
        self.start = vector(self.ask("start").split())

    def ask(self, line):
        t0 = time.perf_counter()
        self.proc.stdin.write(line + "\n")
        answer = self.proc.stdout.readline().strip()
        self.seconds += time.perf_counter() - t0
        if answer.startswith("err"):
            raise RuntimeError(f"oracle: {answer} (after {line[:40]!r})")
        return answer

    def close(self):
        self.proc.stdin.write("quit\n")
        self.proc.stdin.close()
        self.proc.wait()

    def box(self, u):
        """[-1, 1]^n → the task's box."""
        half = (self.upper - self.lower) / 2
        return self.lower + half * (np.clip(u, -1.0, 1.0) + 1.0)

    def unit(self, x):
        half = (self.upper - self.lower) / 2
        return (x - self.lower) / half - 1.0


class Budget(Exception):
    pass


class Scorer:
    """f(u) for a peer: one episode of the oracle, recorded; stops at the budget."""

    def __init__(self, oracle, budget):
        self.oracle, self.budget, self.costs, self.unsafe = oracle, budget, [], 0

    def __call__(self, u):
        return self.at(self.oracle.box(np.asarray(u, dtype=float)))

    def at(self, x):
        """The cost of θ = x in the task's box."""
        if len(self.costs) >= self.budget:
            raise Budget()
        c, safety = self.oracle.ask("eval " + " ".join(f"{v:.9e}" for v in x)).split()
        self.costs.append(float(c))
        self.unsafe += safety == "unsafe"
        return float(c)


def run_peer(method, oracle, budget, seed):
    """Runs a peer; returns (costs, returned θ in the box)."""
    if np is None:
        raise SystemExit("the peers need numpy: see experiments/peers/requirements.txt")
    f = Scorer(oracle, budget)
    n, step, x0 = oracle.n, STEP[oracle.task], oracle.unit(oracle.start)
    returned = None
    if method == "zoopt-sracos":
        from zoopt import Dimension, Objective, Opt, Parameter

        dim = Dimension(n, [[-1.0, 1.0]] * n, [True] * n)
        objective = Objective(lambda s: f(s.get_x()), dim)
        # Budget-based set sizes (auto_set), exploration 0.01, uncertain bits 1: the defaults.
        parameter = Parameter(budget=budget, seed=seed)
        with contextlib.redirect_stdout(io.StringIO()):
            solution = Opt.min(objective, parameter)
        returned = np.array(solution.get_x())
    elif method == "pycma":
        import cma

        es = cma.CMAEvolutionStrategy(
            x0, step, {"bounds": [-1, 1], "seed": seed, "maxfevals": budget, "verbose": -9}
        )
        try:
            while not es.stop():
                xs = es.ask()
                es.tell(xs, [f(x) for x in xs])
        except Budget:
            pass
        returned = np.array(es.result.xbest if es.result.xbest is not None else x0)
    elif method.startswith("ng-"):
        import nevergrad as ng

        param = ng.p.Array(init=x0).set_bounds(-1.0, 1.0).set_mutation(sigma=step)
        param.random_state = np.random.RandomState(seed)
        name = {"ng-oneplusone": "OnePlusOne", "ng-ngopt": "NGOpt"}[method]
        opt = ng.optimizers.registry[name](parametrization=param, budget=budget)
        for _ in range(budget):
            cand = opt.ask()
            opt.tell(cand, f(cand.value))
        returned = np.array(opt.provide_recommendation().value)
    elif method in BINDING:
        returned = run_binding(method[len("py-"):], f, oracle, budget, seed)
    elif method == "safeopt":
        returned = run_safeopt(f, oracle, x0, budget)
    elif method == "bayes-opt":
        returned = run_bayes_opt(f, x0, budget, seed)
    elif method == "botorch":
        returned = run_botorch(f, x0, budget, seed)
    else:
        raise ValueError(method)
    return f, oracle.box(returned)


def run_binding(algorithm, f, oracle, budget, seed):
    """The library's `algorithm` through its Python package, in the task's box, from the
    task's start, with the oracle's settings (experiments/src/peers.rs, `run_library`): σ₀
    the task's step in half-widths where the algorithm has one, the budget. Candidates come
    from `suggest` (a whole generation where the algorithm allows it) and are reported in
    order. Returns the best θ told, mapped to [-1, 1]^n for the Scorer."""
    import ctrl_adapt

    config = {"max_evaluations": budget}
    if algorithm in ("cmaes", "rockstar"):
        config["initial_sigma"] = STEP[oracle.task]
    # CRS samples the box first and takes no start.
    start = None if algorithm == "crs" else oracle.start
    opt = ctrl_adapt.Optimizer(algorithm, oracle.lower, oracle.upper, start, seed=seed, **config)
    try:
        while opt.status == "running":
            batch = []
            while (handed := opt.suggest()) is not None:
                batch.append(handed)
            for ticket, theta in batch:
                # As the oracle's own runs tell it: an infinite cost as f32::MAX.
                opt.report(ticket, min(f.at(theta), 3.4028234663852886e38))
    except Budget:
        pass
    best = opt.best()
    return oracle.unit(best[0] if best is not None else oracle.start)


# The GP LineBO had when the SafeOpt rows were measured (experiments/src/peers.rs,
# `line_bo_config`, before its settings were re-chosen on seeds 101-110), given to SafeOpt:
# the cost minus the start's first cost, in units of it; a squared-exponential kernel of
# signal σ_f = 1, length scale 0.15 of the box (0.3 in the [-1, 1] box), noise σ_n = 0.05;
# β = 2 (`linebo-safe` now has the same ℓ and β = 3).
LENGTH_SCALE, NOISE, BETA = 0.3, 0.05, 2.0
# Residuals clipped like LineBO's (a rejected θ scores +∞).
CLIP = 1e6


def import_safeopt():
    """safeopt 0.16 (its last release, 2017) imports `collections.Sequence` (gone since
    Python 3.10) and uses `np.float` and `np.bool` (gone since numpy 1.24): restore the
    three old names, then import it."""
    import collections
    import collections.abc

    collections.Sequence = collections.abc.Sequence
    for name, alias in (("float", float), ("bool", bool)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            missing = not hasattr(np, name)
        if missing:
            setattr(np, name, alias)
    import safeopt

    return safeopt


def run_safeopt(f, oracle, x0, budget):
    """The authors' SafeOpt (`SafeOptSwarm`: the particle-swarm form for more than a few
    dimensions, as every task here has) with GPy, from the start θ (its first episode is
    the safe seed), maximising the negated residual with LineBO's GP and β, and the safety
    bound the oracle gives `linebo-safe`. Returns the best evaluated θ (`get_maximum`)."""
    safeopt = import_safeopt()
    import GPy

    c0 = f(x0)
    scale = max(abs(c0), 1e-30)
    y = lambda c: np.clip((c0 - c) / scale, -CLIP, CLIP)  # noqa: E731
    kernel = GPy.kern.RBF(input_dim=oracle.n, variance=1.0, lengthscale=LENGTH_SCALE)
    gp = GPy.models.GPRegression(
        np.array([x0]), np.array([[y(c0)]]), kernel, noise_var=NOISE**2
    )
    fmin = (c0 - oracle.safe_threshold) / scale
    opt = safeopt.SafeOptSwarm(gp, fmin=[fmin], bounds=[(-1.0, 1.0)] * oracle.n, beta=BETA)
    try:
        while True:
            x = opt.optimize()
            opt.add_new_data_point(x, np.array([[y(f(x))]]))
    except Budget:
        pass
    return np.array(opt.get_maximum()[0])


def run_bayes_opt(f, x0, budget, seed):
    """`bayesian-optimization` (the version nevergrad pins) with its defaults (a Matérn-5/2
    GP refitted every step, the UCB acquisition with κ = 2.576), the start θ registered as
    its first point. Returns its best evaluated θ."""
    from bayes_opt import BayesianOptimization, UtilityFunction

    keys = [f"x{i:03d}" for i in range(len(x0))]
    opt = BayesianOptimization(
        f=None,
        pbounds={k: (-1.0, 1.0) for k in keys},
        random_state=seed,
        verbose=0,
        allow_duplicate_points=True,
    )
    utility = UtilityFunction(kind="ucb", kappa=2.576)

    def target(x):
        c = f(x)
        return -min(c, CLIP * max(abs(f.costs[0]), 1.0))

    x = np.array(x0)
    try:
        while True:
            opt.register(params=dict(zip(keys, x)), target=target(x))
            suggestion = opt.suggest(utility)
            x = np.array([suggestion[k] for k in keys])
    except Budget:
        pass
    return np.array([opt.max["params"][k] for k in keys])


# BoTorch's acquisition optimiser: restarts and raw samples (modest: the host is shared).
BOTORCH_RESTARTS, BOTORCH_RAW_SAMPLES = 4, 128


def run_botorch(f, x0, budget, seed):
    """GP-BO with BoTorch (imported here, so that the other rows run without torch): a
    `SingleTaskGP` on the box normalised to [0, 1]^n with BoTorch's default kernel and
    priors (an RBF kernel with a dimension-scaled log-normal prior on its length scales,
    inferred noise), the outcomes standardised (`Standardize`), refitted by maximum
    a-posteriori (`fit_gpytorch_mll`) after every episode; the next θ maximises
    `qLogNoisyExpectedImprovement` (q = 1, the evaluated points as its baseline) by
    `optimize_acqf` with `BOTORCH_RESTARTS` restarts from `BOTORCH_RAW_SAMPLES` raw samples.
    The start θ is the first point and the only initial one (no space-filling design: the
    other methods start from it too, and 2n random points would be 36 of the AUV's episodes).
    It maximises the negated cost, clipped like `bayes-opt`'s; double precision, one torch
    thread, the torch RNG seeded with `seed`. Returns its best evaluated θ."""
    import torch
    from botorch.acquisition.logei import qLogNoisyExpectedImprovement
    from botorch.fit import fit_gpytorch_mll
    from botorch.models import SingleTaskGP
    from botorch.models.transforms.outcome import Standardize
    from botorch.optim import optimize_acqf
    from gpytorch.mlls import ExactMarginalLogLikelihood

    torch.set_num_threads(1)
    torch.manual_seed(seed)
    n = len(x0)
    unit = torch.stack([torch.zeros(n), torch.ones(n)]).double()
    xs, ys = [], []
    z = (torch.as_tensor(np.asarray(x0), dtype=torch.double) + 1.0) / 2.0
    try:
        while True:
            c = f((z * 2.0 - 1.0).numpy())
            xs.append(z)
            ys.append(-min(c, CLIP * max(abs(f.costs[0]), 1.0)))
            train_x = torch.stack(xs)
            train_y = torch.tensor(ys, dtype=torch.double).unsqueeze(-1)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                gp = SingleTaskGP(train_x, train_y, outcome_transform=Standardize(m=1))
                fit_gpytorch_mll(ExactMarginalLogLikelihood(gp.likelihood, gp))
                acq = qLogNoisyExpectedImprovement(gp, X_baseline=train_x, prune_baseline=True)
                candidate, _ = optimize_acqf(
                    acq,
                    bounds=unit,
                    q=1,
                    num_restarts=BOTORCH_RESTARTS,
                    raw_samples=BOTORCH_RAW_SAMPLES,
                )
            z = candidate.detach()[0].clamp(0.0, 1.0)
    except Budget:
        pass
    best = int(np.argmax(ys))
    return (xs[best] * 2.0 - 1.0).numpy()


def one(job):
    task, method, seed, budget = job
    oracle = Oracle(task, seed)
    budget = budget or oracle.budget
    if method in LIBRARY:
        answer = oracle.ask(f"run {method} {budget} {seed}").split()
        evals, first, best, deployed, ns, unsafe, fallback = answer
        result = dict(
            first=None if first == "-" else int(first),
            best=float(best),
            deployed=float(deployed),
            us_per_eval=float(ns) / 1e3,
            evaluations=int(evals),
            unsafe=int(unsafe),
            fallback=None if fallback == "-" else int(fallback),
        )
    else:
        t0 = time.perf_counter()
        oracle.seconds = 0.0
        scored, returned = run_peer(method, oracle, budget, seed)
        costs = scored.costs
        own = time.perf_counter() - t0 - oracle.seconds
        deployed = float(oracle.ask("deploy " + " ".join(f"{v:.9e}" for v in returned)))
        first = next((k + 1 for k, c in enumerate(costs) if c < oracle.threshold), None)
        result = dict(
            first=first,
            best=min(costs),
            deployed=deployed,
            us_per_eval=own / max(len(costs), 1) * 1e6,
            evaluations=len(costs),
            unsafe=scored.unsafe,
        )
    oracle.close()
    return dict(task=task, method=method, seed=seed, budget=budget, **result)


def quartiles(values):
    """The quartiles by linear interpolation (statistics.quantiles' "inclusive"), where a
    quartile between two failures (+∞), or on one, is +∞ rather than ∞ − ∞ = NaN."""
    values = sorted(values)

    def at(p):
        x = p * (len(values) - 1)
        i, f = int(x), x - int(x)
        after = values[min(i + 1, len(values) - 1)]
        return values[i] if f == 0 or after == values[i] else values[i] + f * (after - values[i])

    return at(0.25), at(0.5), at(0.75)


def table(results, tasks, methods):
    lines = [
        "| task | method | success | episodes to success, median (IQR) | best cost (median) "
        "| deployed cost (median) | optimizer µs / evaluation (median) "
        "| unsafe episodes (sum) | fallback episodes (sum) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for task in tasks:
        for method in methods:
            rows = [r for r in results if r["task"] == task and r["method"] == method]
            if not rows:
                continue
            budget = rows[0]["budget"]
            firsts = [r["first"] if r["first"] is not None else float("inf") for r in rows]
            q1, med, q3 = quartiles(firsts)
            show = lambda v: f"> {budget}" if v == float("inf") else f"{v:.4g}"  # noqa: E731
            ok = sum(r["first"] is not None for r in rows)
            # Only the model-based learner has a fallback (runs saved before it have none).
            fallback = [r.get("fallback") for r in rows]
            fell_back = "–" if None in fallback else str(sum(fallback))
            lines.append(
                f"| {task} | {method} | {ok}/{len(rows)} | {show(med)} ({show(q1)}–{show(q3)}) "
                f"| {statistics.median(r['best'] for r in rows):.3g} "
                f"| {statistics.median(r['deployed'] for r in rows):.3g} "
                f"| {statistics.median(r['us_per_eval'] for r in rows):.1f} "
                f"| {sum(r['unsafe'] for r in rows)} | {fell_back} |"
            )
    return "\n".join(lines)


def sign_test(wins, losses):
    """The two-sided sign test's p-value of `wins` against `losses` (ties left out)."""
    n, k = wins + losses, min(wins, losses)
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(k + 1)) / 2**n
    return min(1.0, 2 * tail)


def paired(results, tasks, methods, of):
    """Seed by seed, `of` against every other method: on how many seeds its episodes to
    success (a seed without success counts as beyond the budget) and its deployed cost are
    lower, equal, higher, with the sign test's p-value; only seeds both methods ran."""
    lines = [
        f"| task | {of} against | seeds | episodes to success: fewer / equal / more (p) "
        "| deployed cost: lower / equal / higher (p) |",
        "|---|---|---|---|---|",
    ]
    key = lambda r: r["first"] if r["first"] is not None else float("inf")  # noqa: E731
    for task in tasks:
        mine = {r["seed"]: r for r in results if r["task"] == task and r["method"] == of}
        for method in methods:
            if method == of:
                continue
            theirs = {r["seed"]: r for r in results if r["task"] == task and r["method"] == method}
            both = sorted(set(mine) & set(theirs))
            if not both:
                continue
            cells = []
            for field in (key, lambda r: r["deployed"]):
                a = [field(mine[s]) for s in both]
                b = [field(theirs[s]) for s in both]
                lower = sum(x < y for x, y in zip(a, b))
                higher = sum(x > y for x, y in zip(a, b))
                equal = len(both) - lower - higher
                cells.append(f"{lower} / {equal} / {higher} ({sign_test(lower, higher):.2g})")
            lines.append(f"| {task} | {method} | {len(both)} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines)


def seeds(text):
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--tasks", default="auv,hopper,arm")
    p.add_argument("--methods", default=",".join(LIBRARY + PEERS))  # BINDING, ON_REQUEST too
    p.add_argument(
        "--seeds", help="e.g. 1-20 or 1,2,5 (default 1-10; with --table: every saved seed)"
    )
    p.add_argument("--budget", type=int, default=0, help="episodes (default: the task's)")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--json", help="write every run's result here")
    p.add_argument(
        "--table",
        nargs="+",
        metavar="JSON",
        help="print the table of earlier runs' --json files (merged, of --seeds; no run)",
    )
    p.add_argument(
        "--paired",
        metavar="METHOD",
        help="with --table: also METHOD against every other method, seed by seed",
    )
    a = p.parse_args()
    if a.table:
        # A (task, method, seed) saved twice (overlapping runs) counts once: it is the same run.
        runs = {}
        for name in a.table:
            for r in json.load(open(name)):
                if a.seeds is None or r["seed"] in seeds(a.seeds):
                    runs.setdefault((r["task"], r["method"], r["seed"]), r)
        results = list(runs.values())
        tasks = list(dict.fromkeys(r["task"] for r in results))
        known = LIBRARY + BINDING + PEERS + ON_REQUEST
        methods = [m for m in known if any(r["method"] == m for r in results)]
        print(table(results, tasks, methods))
        if a.paired:
            print()
            print(paired(results, tasks, methods, a.paired))
        return
    if not os.path.exists(ORACLE):
        sys.exit("build the oracle first: cargo build --release -p experiments --bin oracle")
    tasks, methods = a.tasks.split(","), a.methods.split(",")
    run_seeds = seeds(a.seeds or "1-10")
    jobs = [(t, m, s, a.budget) for t in tasks for m in methods for s in run_seeds]
    with multiprocessing.Pool(a.jobs) as pool:
        results = []
        for r in pool.imap_unordered(one, jobs):
            results.append(r)
            print(f"{r['task']:6} {r['method']:14} seed {r['seed']:3}: first {r['first']}, "
                  f"best {r['best']:.4g}, deployed {r['deployed']:.4g}, unsafe {r['unsafe']}",
                  file=sys.stderr)
            if a.json:  # after every run, so that a long run stopped early keeps its rows
                with open(a.json, "w") as out:
                    json.dump(results, out, indent=1)
    print(table(results, tasks, methods))


if __name__ == "__main__":
    main()
