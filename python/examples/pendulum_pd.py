"""Tune the correction of a PD controller on Gymnasium's MuJoCo InvertedPendulum-v5, with
the library's CMA-ES through Ray Tune on a local Ray cluster, and hand the result to the
firmware as a record.

The plant. A cart on a rail (±1 m) carries a pole. The nominal controller is the PD a first
design gives, on the pole's angle only: ``u_pd = 10·θ + 1·θ̇``. It balances the pole, but it
knows nothing of the cart, and a constant push on the cart (20 N, a slope or a wind the PD
was not designed for, applied as an external force the controller does not measure) drives
the cart to the end of the rail, where the pole falls: the bare PD survives 82 of 1,000
steps. What the PD lacks is exactly what the linear correction can add:

    u = u_pd + clamp(W·φ, ±2),   φ = (x, ẋ, 1)   (cart position, cart velocity, a bias)

with ``W`` in ``[-2, 2] × [-2, 2] × [-1, 1]``, from ``W = 0`` (the bare PD). The cost of a
trial, over its episodes: the fraction of the steps not survived plus the mean of
``min(x², 1)`` over the survived ones, so 0 is the pole up and the cart centred the whole
episode, 1 a fall at once.

Each Ray trial runs the episodes of one candidate ``W`` on a worker; the searcher
(:class:`ctrl_adapt.tune.CtrlAdaptSearch`) hands out CMA-ES candidates, a generation at a
time where workers are free. At the end the optimizer's state is written as a record of its
Rust type (``Cmaes<3, 7>``), which the firmware loads with ``ctrl_adapt::record::load`` and
continues from (the board's own episodes then count), and the learning curve is plotted.

    python python/examples/pendulum_pd.py            # 98 trials of 4 × 1,000 steps
    python python/examples/pendulum_pd.py --short    # 28 trials of 1 × 300 steps (CI)

Workers. The default is two (at most the machine's CPUs): the trainable is wrapped by
``search.trainable`` so that Tune keeps its workers between generations, and two workers
take about two thirds of one worker's wall time on the full run (python/README.md has the
measured times). A simulator whose trials take longer gains more, from ``--workers`` up to
the CMA-ES population (7 here); ``ctrl_adapt.pool`` is the cheaper path on one machine.

Options: ``--workers N`` (Ray CPUs, default 2), ``--out DIR`` (default
``target/pendulum-pd``), ``--seed S``. Everything is seeded: the initial states, the
optimizer; with the same seed the run proposes the same candidates whatever the number of
workers (reports in any order within a generation give the same state).
"""

import argparse
import os
import sys
import time

import gymnasium as gym
import matplotlib
import mujoco
import numpy as np
import ray
from ray import tune

from ctrl_adapt.tune import CtrlAdaptSearch

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after the backend is chosen)

KP, KD = 10.0, 1.0  # the nominal PD, on the pole's angle
PUSH = 20.0  # N, the constant push on the cart
CLAMP = 2.0  # the correction's clamp (actuator units; the actuator takes ±3)
SPACE = {"w_x": (-2.0, 2.0), "w_v": (-2.0, 2.0), "w_bias": (-1.0, 1.0)}


def episode_cost(w, steps, seed):
    """One episode of the corrected PD from the initial state ``seed``: the cost and the steps
    survived."""
    env = gym.make("InvertedPendulum-v5", max_episode_steps=steps)
    plant = env.unwrapped
    obs, _ = env.reset(seed=seed)
    cart = mujoco.mj_name2id(plant.model, mujoco.mjtObj.mjOBJ_BODY, "cart")
    plant.data.xfrc_applied[cart, 0] = PUSH  # after reset, which clears it
    offset = 0.0
    for t in range(steps):
        x, angle, velocity, rate = obs
        u_pd = KP * angle + KD * rate
        correction = np.clip(w[0] * x + w[1] * velocity + w[2], -CLAMP, CLAMP)
        obs, _, fell, _, _ = env.step(np.array([u_pd + correction], dtype=np.float32).clip(-3, 3))
        offset += min(obs[0] ** 2, 1.0)
        if fell:
            env.close()
            return (offset + steps - (t + 1)) / steps, t + 1
    env.close()
    return offset / steps, steps


def trial(config):
    """A Ray trial: the candidate's episodes, one per initial state."""
    w = (config["w_x"], config["w_v"], config["w_bias"])
    runs = [episode_cost(w, config["steps"], seed) for seed in config["initial_states"]]
    return {"cost": float(np.mean([c for c, _ in runs])), "survived": min(s for _, s in runs)}


def plot(history, bare, path):
    costs = np.array([cost for _, cost in history])
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    ax.plot(np.arange(1, len(costs) + 1), costs, ".", color="0.6", label="trial")
    ax.plot(np.arange(1, len(costs) + 1), np.minimum.accumulate(costs), color="C0", label="best so far")
    ax.axhline(bare, color="C3", linestyle="--", label="bare PD (W = 0)")
    ax.set_yscale("log")
    ax.set_xlabel("trial (in the order reported)")
    ax.set_ylabel("cost (log)")
    ax.set_title("InvertedPendulum-v5, 20 N push: the PD's correction tuned")
    ax.legend(loc="lower left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--short", action="store_true", help="28 trials of one 300-step episode (CI)")
    p.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                   help="CPUs of the local Ray cluster (default 2, at most the machine's)")
    p.add_argument("--out", default=os.path.join("target", "pendulum-pd"))
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args(argv)
    trials, steps, initial_states = (28, 300, [0]) if a.short else (98, 1000, [0, 1, 2, 3])
    os.makedirs(a.out, exist_ok=True)
    print(f"command: python {' '.join([os.path.relpath(sys.argv[0])] + list(argv or sys.argv[1:]))}")

    bare_runs = [episode_cost((0.0, 0.0, 0.0), steps, s) for s in initial_states]
    bare = np.mean([cost for cost, _ in bare_runs])
    search = CtrlAdaptSearch(SPACE, algorithm="cmaes", start={"w_x": 0.0, "w_v": 0.0, "w_bias": 0.0},
                             seed=a.seed, initial_sigma=0.5, metric="cost", mode="min")
    started = time.perf_counter()
    ray.init(num_cpus=a.workers, include_dashboard=False, log_to_driver=False, configure_logging=False)
    up = time.perf_counter()
    try:
        tuner = tune.Tuner(
            # Wrapped: a worker freed at a generation's end waits for the next one's first
            # candidate instead of being stopped by Tune (see CtrlAdaptSearch.trainable).
            search.trainable(trial),
            param_space={"steps": steps, "initial_states": initial_states},
            # max_concurrent_trials tells Tune how many trials to keep going (a searcher
            # gets one pending trial otherwise): the workers, within a CMA-ES generation.
            tune_config=tune.TuneConfig(search_alg=search, num_samples=trials, reuse_actors=True,
                                        max_concurrent_trials=min(a.workers, search.max_concurrent)),
            run_config=tune.RunConfig(storage_path=os.path.abspath(os.path.join(a.out, "ray")), verbose=0),
        )
        results = tuner.fit()
    finally:
        ray.shutdown()
    wall = time.perf_counter() - up

    config, cost = search.best()
    rust_type = search.write_record(os.path.join(a.out, "pendulum.rec"))
    plot(search.history, bare, os.path.join(a.out, "learning_curve.png"))
    final = trial({**config, "steps": steps, "initial_states": initial_states})
    tuned, survived = final["cost"], final["survived"]
    print(f"workers: {a.workers}; trials: {len(results)} ({len(results.errors)} errored); "
          f"most in flight: {search.peak_in_flight}; tuning wall time: {wall:.1f} s "
          f"(after {up - started:.1f} s of Ray start-up)")
    print(f"bare PD cost: {bare:.3f} (survived {min(n for _, n in bare_runs)} of {steps} steps); tuned cost: {tuned:.2e} (survived {survived} of {steps} steps)")
    print("best W: " + ", ".join(f"{name} = {config[name]:+.4f}" for name in search.parameter_names))
    print(f"record: {os.path.join(a.out, 'pendulum.rec')} ({rust_type}; on the board: "
          f"ctrl_adapt::record::load::<{rust_type}>(&bytes))")
    print(f"learning curve: {os.path.join(a.out, 'learning_curve.png')}")
    if not tuned < bare:
        sys.exit("the tuned correction is no better than the bare PD")
    return wall


if __name__ == "__main__":
    main()
