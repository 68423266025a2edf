"""The runtime guard, from Python, on Gymnasium's MuJoCo InvertedPendulum-v5 with a heavier
pole and a push: every learner of the package, with and without the guard.

The plant: InvertedPendulum-v5 (1,000 steps of 0.04 s), the pole's mass and inertia ×2
(``env.unwrapped.model.body_mass``/``body_inertia``), a constant 20 N push on the cart
(``xfrc_applied``, re-applied after each reset). The pole falls when |angle| > 0.2 rad
(Gymnasium's termination), which ends the episode.

The controllers. The nominal controller (the robot's existing one, and the guard's backup):
``u_nom = 10·θ + 1·θ̇ + 0.5·x + 0.5·ẋ`` (the PD on the pole's angle of
``python/examples/pendulum_pd.py`` plus a cart term; the example's PD alone cannot hold
the cart against the push: the bare PD falls after 79–83 steps with this pole, so it is no
backup to hand an episode to). It holds the pole with the heavier pole and the push, with the
cart pushed off centre (cost ≈ 0.133). The learned correction, as in the example:
``u = u_nom + clamp(W·(x, ẋ, 1), ±2)``, ``W ∈ [-2, 2] × [-2, 2] × [-1, 1]``, from ``W = 0``.

The cost of an episode (executed; what the learner is told unguarded): the steps not
survived over 1,000 plus the mean of ``min(x², 1)`` over the survived steps (the example's),
at most 1. The guard's running cost: that mean so far (``Σ min(x², 1) / 1000`` up to this
tick).

A run: 3 bare episodes (``begin("nominal")``: they teach the guard's envelope; their mean
cost is the run's *bare cost*), then ``--budget`` learning episodes of the learner from
``W = 0`` (default config of each; one episode per candidate, each from its own initial
state, the same in both arms). With the guard, a tripped episode runs ``u_nom`` from the
tripping tick on and is told ``report.told(cost, failure_cost=1.0, ticks=1000)`` (above 1,
lower the later the trip); without, the executed cost.

Measures per run: **falls** (learning episodes whose pole fell), **unsafe episodes**
(executed cost > 1.2 × the bare cost, or a fall), **ticks beyond the limits** (the guard's
limits, counted in both arms: unguarded by a guard checked and ignored), **episodes
tripped** (unguarded: would have tripped), **episodes to success** (the first learning
episode, counted from 1, that did not trip, did not fall and cost at most 0.25 × the bare
cost) and whether it succeeded within the budget.

The predictive trip (settings with ``forecast_angle``/``forecast_cart``): a plant model
``ctrl_adapt.RlsModel(4, 1)`` fitted on every tick of the run (bare episodes included; not on
ticks that end within 5 cm of the rail's stops or beyond the fall angle, which no linear
model holds) forecasts, every ``every`` ticks from the measured state, ``every`` ticks of the
candidate then ``horizon`` ticks of the nominal controller alone (``RlsModel.rollout``); the
forecast's largest |angle| and |x| are the guard's signal (``Limit.signal(0)``, ``(1)``).

    python experiments/peers/pendulum_guard.py tune     # seeds 101–110, the settings' grid
    python experiments/peers/pendulum_guard.py report   # seeds 1–10, the chosen setting
    python experiments/peers/pendulum_guard.py tune --grid 2 --arm on --save on.jsonl  # one setting, one arm
    python experiments/peers/pendulum_guard.py tune --grid 2 --arm none --load on.jsonl,off.jsonl  # tables
"""

import argparse
import itertools
import json
import math
import multiprocessing as mp
import os
import statistics
import sys
import time
from typing import NamedTuple, Optional

import gymnasium as gym
import mujoco
import numpy as np

import ctrl_adapt
from ctrl_adapt import Guard, Limit

KP, KD = 10.0, 1.0  # the PD on the pole's angle
KX, KV = 0.5, 0.5  # the nominal cart term
PUSH = 20.0  # N
POLE = 2.0  # pole mass and inertia factor
CLAMP = 2.0
STEPS = 1000
LOWER, UPPER = np.array([-2.0, -2.0, -1.0]), np.array([2.0, 2.0, 1.0])
BARE_EPISODES = 3
FAILURE_COST = 1.0  # every episode's executed cost is at most 1
UNSAFE = 1.2
SUCCESS = 0.25
RAIL = 0.95  # m: the cart's stops are at ±1 m
FALL = 0.2  # rad: Gymnasium's termination
# `two-phase` is left out: within its global budget (150 episodes by default) it is the CRS
# it wraps, candidate for candidate, so its rows would repeat `crs`'s.
LEARNERS = ["coordinate", "sracos", "cem", "crs", "cmaes", "rockstar", "linebo"]
STARTS = {"coordinate", "cem", "cmaes", "rockstar", "linebo"}

class Setting(NamedTuple):
    """A guard's setting: limits on the measured state (``None``: none), hysteresis, an
    envelope margin (``None``: no envelope) and an optional predictive trip: every ``every``
    ticks the plant model, fitted on every tick of the run, forecasts ``every`` ticks of the
    candidate followed by ``horizon`` ticks of the nominal controller from the measured
    state; the guard trips when the forecast's largest |angle| exceeds ``forecast_angle``
    (or its largest |x| exceeds ``forecast_cart``)."""

    name: str
    angle: Optional[float]
    cart: Optional[float]
    ticks: int
    margin: Optional[float] = None
    forecast_angle: Optional[float] = None
    forecast_cart: Optional[float] = None
    every: int = 5
    horizon: int = 25


# The settings tried on seeds 101–110. B and C: limits on the measured state alone (the
# first grid); P*: the predictive trip (the second grid), the cart's state limit kept.
GRID = [
    Setting("angle 0.05 + cart 0.8, 1 tick", 0.05, 0.8, 1),
    Setting("angle 0.03 + cart 0.8, 1 tick", 0.03, 0.8, 1),
    Setting("forecast angle 0.1 + cart 0.9 (5 + 25 ticks), cart 0.8, 1 tick", None, 0.8, 1,
            forecast_angle=0.1, forecast_cart=0.9, every=5, horizon=25),
    Setting("forecast angle 0.1 + cart 0.9 (5 + 50 ticks), cart 0.8, 1 tick", None, 0.8, 1,
            forecast_angle=0.1, forecast_cart=0.9, every=5, horizon=50),
]
CHOSEN = 1  # by the rule of the findings page, from `tune` on seeds 101–110


_env = None


def env():
    global _env
    if _env is None:
        e = gym.make("InvertedPendulum-v5", max_episode_steps=STEPS)
        p = e.unwrapped
        pole = mujoco.mj_name2id(p.model, mujoco.mjtObj.mjOBJ_BODY, "pole")
        p.model.body_mass[pole] *= POLE
        p.model.body_inertia[pole] *= POLE
        cart = mujoco.mj_name2id(p.model, mujoco.mjtObj.mjOBJ_BODY, "cart")
        _env = (e, cart)
    return _env


def make_guard(setting):
    limits = []
    if setting.angle is not None:
        limits.append(Limit.state(1, -setting.angle, setting.angle))
    if setting.cart is not None:
        limits.append(Limit.state(0, -setting.cart, setting.cart))
    if setting.forecast_angle is not None:
        limits.append(Limit.signal(0, high=setting.forecast_angle))
    if setting.forecast_cart is not None:
        limits.append(Limit.signal(1, high=setting.forecast_cart))
    margin = setting.margin
    return Guard(limits, horizon=STEPS if margin is not None else 0, limit_ticks=setting.ticks,
                 envelope_ticks=2, relative_margin=margin if margin is not None else 0.1,
                 absolute_margin=0.0, tripped_cost_span=1.0)


def nominal(x, angle, velocity, rate):
    return KP * angle + KD * rate + KX * x + KV * velocity


def correction(w, x, velocity):
    return min(max(w[0] * x + w[1] * velocity + w[2], -CLAMP), CLAMP)


DIVERGED = 1e6  # the forecast's signal when the model's prediction is not finite


def forecast(model, obs, w, candidate_ticks, horizon):
    """The predictive trip's signal: (largest |angle|, largest |x|) of the states the model
    predicts from `obs` for `candidate_ticks` ticks of the correction `w` (none if `w` is
    None), then `horizon` ticks of the nominal controller alone (the guard's rescue)."""
    def policy(k, s):
        x, angle, velocity, rate = s.tolist()
        u = nominal(x, angle, velocity, rate)
        if w is not None and k < candidate_ticks:
            u += correction(w, x, velocity)
        return [min(max(u, -3.0), 3.0)]

    states = model.rollout(obs, candidate_ticks + horizon, policy, with_tick=True)[1:]
    peak = np.abs(states[:, :2]).max(axis=0)
    if not np.all(np.isfinite(peak)) or len(states) < candidate_ticks + horizon:
        return [DIVERGED, DIVERGED]
    return [float(peak[1]), float(peak[0])]


def episode(w, seed, guards, settings, mode, obey, model=None):
    """One episode: (executed cost, fell, reports). `w` None: the bare controller. Every
    guard is checked (each counts its ticks beyond limits and its trips); the first one's
    verdict is obeyed if `obey`. `model` (given when a setting forecasts) is fitted on every
    tick and forecasts for the settings' predictive trips."""
    e, cart = env()
    obs, _ = e.reset(seed=seed)
    e.unwrapped.data.xfrc_applied[cart, 0] = PUSH
    for g in guards:
        g.begin(mode)
    signals = [None] * len(guards)
    offset = 0.0
    handed = False
    fell = False
    for t in range(STEPS):
        x, angle, velocity, rate = obs
        offset += min(x * x, 1.0)
        running = offset / STEPS
        verdicts = []
        for i, (g, s) in enumerate(zip(guards, settings)):
            if s.forecast_angle is not None or s.forecast_cart is not None:
                if t % s.every == 0:
                    live = w if not (handed and i == 0) else None
                    signals[i] = forecast(model, obs, live, s.every, s.horizon)
                verdicts.append(g.check(obs, cost=running if g.horizon else None, signal=signals[i]))
            else:
                verdicts.append(g.check(obs, cost=running) if g.horizon else g.check(obs))
        handed = handed or (obey and verdicts[0])
        u = nominal(x, angle, velocity, rate)
        if w is not None and not handed:
            u += correction(w, x, velocity)
        u = min(max(u, -3.0), 3.0)
        nxt, _, fell, _, _ = e.step(np.array([u], dtype=np.float32))
        # The model is linear: a tick that ends on the rail's stop or beyond the fall angle
        # (dynamics no linear model holds) is not fitted, or one fall would spoil it.
        if model is not None and abs(nxt[0]) < RAIL and abs(nxt[1]) < FALL:
            model.update(obs, [u], nxt)
        obs = nxt
        if fell:
            break
    cost = (offset + STEPS - (t + 1)) / STEPS if fell else offset / STEPS
    return cost, bool(fell), [g.end() for g in guards]


def run(job):
    """One run of `learner` on `seed`: guarded by `settings[0]` if `guarded`, else unguarded
    with every setting's guard counting. Returns one result per setting."""
    learner, seed, settings, guarded, budget = job
    guards = [make_guard(s) for s in settings]
    predictive = any(s.forecast_angle is not None or s.forecast_cart is not None for s in settings)
    model = ctrl_adapt.RlsModel(4, 1) if predictive else None
    bare = [episode(None, 10_000 * seed + k, guards, settings, "nominal", False, model)[0]
            for k in range(BARE_EPISODES)]
    bare_cost = float(np.mean(bare))
    start = np.zeros(3) if learner in STARTS else None
    opt = ctrl_adapt.Optimizer(learner, LOWER, UPPER, start, seed=seed)
    falls = unsafe = 0
    tripped = [0] * len(guards)
    success = None
    for k in range(budget):
        if opt.status != "running":
            break
        w = opt.ask()
        cost, fell, reports = episode(w, 10_000 * seed + 100 + k, guards, settings, "learn", guarded,
                                      model)
        for i, r in enumerate(reports):
            tripped[i] += r.tripped
        falls += fell
        unsafe += fell or cost > UNSAFE * bare_cost
        told = reports[0].told(cost, FAILURE_COST, ticks=STEPS) if guarded else cost
        opt.tell(told)
        if (success is None and not fell and not (guarded and reports[0].tripped)
                and cost <= SUCCESS * bare_cost):
            success = k + 1
    return [dict(learner=learner, seed=seed, guarded=guarded, setting=s.name, bare=bare_cost,
                 falls=falls, unsafe=unsafe, beyond=g.counters.ticks_beyond_limits,
                 tripped=tripped[i], success=success)
            for i, (s, g) in enumerate(zip(settings, guards))]


def table(results, learners, counted_off=True):
    """The results' table; `counted_off` False: the unguarded runs counted another setting's
    limits, so their ticks beyond limits and would-be trips are not shown."""
    rows = ["| learner | falls per run off / on | unsafe episodes off / on | ticks beyond limits off / on "
            "| tripped (on; off: would have) | successes off / on | median episodes to success off / on |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    summary = {}
    for learner in learners:
        arm = {g: [r for r in results if r["learner"] == learner and r["guarded"] == g] for g in (False, True)}
        def tot(g, key):
            return sum(r[key] for r in arm[g])
        def med(g):
            s = [r["success"] for r in arm[g] if r["success"] is not None]
            return statistics.median(s) if s else math.nan
        n = {g: len(arm[g]) or 1 for g in (False, True)}
        succ = {g: sum(r["success"] is not None for r in arm[g]) for g in (False, True)}
        summary[learner] = dict(falls_on=tot(True, "falls") / n[True], falls_off=tot(False, "falls") / n[False],
                                succ_off=succ[False], succ_on=succ[True], med_off=med(False), med_on=med(True),
                                unsafe_on=tot(True, "unsafe"))
        beyond_off, tripped_off = (tot(False, "beyond"), tot(False, "tripped")) if counted_off else ("–", "–")
        rows.append(f"| {learner} | {tot(False, 'falls') / n[False]:.1f} / {tot(True, 'falls') / n[True]:.1f} "
                    f"| {tot(False, 'unsafe')} / {tot(True, 'unsafe')} | {beyond_off} / {tot(True, 'beyond')} "
                    f"| {tot(True, 'tripped')} ({tripped_off}) | {succ[False]} / {succ[True]} "
                    f"| {med(False):g} / {med(True):g} |")
    return "\n".join(rows), summary


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=["tune", "report"])
    p.add_argument("--budget", type=int, default=40)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--learners", default="coordinate,cem,cmaes,linebo",
                   help=f"comma-separated, of {', '.join(LEARNERS)} (default the four the setting was chosen on; the study reports the other three with --learners sracos,crs,rockstar)")
    p.add_argument("--setting", type=int, default=None, help="index in GRID (report; default the chosen one)")
    p.add_argument("--grid", default=None,
                   help="comma-separated indices in GRID (tune and the unguarded arm; default all)")
    p.add_argument("--seeds", default=None,
                   help="comma-separated seeds instead of the block's (a pilot; not for the tables)")
    p.add_argument("--arm", choices=["both", "off", "on", "none"], default="both",
                   help="run only the unguarded arm (for every setting's counts) or the guarded "
                        "one, or none (print the tables of --load)")
    p.add_argument("--save", default=None, help="append the runs' results to this JSON-lines file")
    p.add_argument("--load", default=None,
                   help="add the results of these comma-separated JSON-lines files (other arms)")
    a = p.parse_args(argv)
    learners = a.learners.split(",")
    seeds = range(101, 111) if a.what == "tune" else range(1, 11)
    if a.seeds:
        seeds = [int(s) for s in a.seeds.split(",")]
    if a.what == "tune" or a.arm == "off" or (a.arm == "none" and a.setting is None and CHOSEN is None):
        settings = GRID if a.grid is None else [GRID[int(i)] for i in a.grid.split(",")]
    else:
        index = a.setting if a.setting is not None else CHOSEN
        if index is None:
            sys.exit("report: no setting chosen yet (run tune, then set CHOSEN or pass --setting)")
        settings = [GRID[index]]
    print(f"command: python {' '.join([os.path.relpath(sys.argv[0])] + list(argv or sys.argv[1:]))}")
    print(f"seeds {seeds[0]}–{seeds[-1]}, budget {a.budget} learning episodes, "
          f"{BARE_EPISODES} bare episodes a run", flush=True)
    started = time.time()
    jobs = []
    if a.arm in ("both", "off"):
        jobs += [(l, s, settings, False, a.budget) for l, s in itertools.product(learners, seeds)]
    if a.arm in ("both", "on"):
        jobs += [(l, s, [setting], True, a.budget) for setting in settings
                 for l, s in itertools.product(learners, seeds)]
    results = []
    with mp.Pool(max(1, a.workers)) as pool:
        for i, rs in enumerate(pool.imap_unordered(run, jobs), 1):
            results += rs
            print(f"  {i}/{len(jobs)} runs ({time.time() - started:.0f} s)", file=sys.stderr, flush=True)
    if jobs:
        print(f"({time.time() - started:.0f} s)")
    if a.save:
        with open(a.save, "a") as f:
            for r in results:
                f.write(json.dumps({k: (int(v) if isinstance(v, (bool, np.bool_, np.integer)) and k != "guarded" else v)
                                    for k, v in r.items()}) + "\n")
    for path in a.load.split(",") if a.load else []:
        with open(path) as f:
            results += [json.loads(line) for line in f if line.strip()]
    print(f"bare cost per run: {min(r['bare'] for r in results):.4f}–{max(r['bare'] for r in results):.4f}")
    for setting in settings:
        chosen = [r for r in results if r["setting"] == setting.name]
        counted_off = any(not r["guarded"] for r in chosen)
        if not counted_off:
            # The unguarded runs do not depend on the setting, only their counts do: take
            # those counted against another one.
            off = {}
            for r in results:
                if not r["guarded"]:
                    off.setdefault((r["learner"], r["seed"]), r)
            chosen += list(off.values())
        text, _ = table(chosen, learners, counted_off)
        print(f"\n### {setting.name}\n")
        print(text, flush=True)


if __name__ == "__main__":
    main()
