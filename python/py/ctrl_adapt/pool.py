"""Parallel evaluation on a persistent process pool, without Ray.

:func:`minimize` evaluates the candidates an :class:`ctrl_adapt.Optimizer` hands out
together (a CMA-ES generation, a CEM batch: its ``max_in_flight``) on a
``concurrent.futures.ProcessPoolExecutor`` that is started once and lives for the whole run,
so each evaluation costs one task hand-off (well under a millisecond), not a process or a
Ray trial. It goes through ``suggest``/``report``: the costs reach the optimizer in hand-out
order, so the search is bit for bit the sequential one (:func:`ctrl_adapt.minimize` with
the same seed) whatever the number of workers and the order evaluations finish in.

The function must be picklable (defined at a module's top level) and return a float; to
pass a simulator's settings, use ``functools.partial``. Each worker process imports it once
and keeps it: expensive set-up (loading a model) belongs in a module-level cache the function
fills on its first call.

    import ctrl_adapt.pool, numpy as np
    result = ctrl_adapt.pool.minimize(episode_cost, lower, upper, algorithm="cmaes",
                                      budget=400, workers=2, seed=1)

A worker pays for itself when an evaluation takes much longer than the hand-off, several
milliseconds at least (run several episodes per evaluation if one episode is shorter), and
only for algorithms with more than one candidate in flight (``max_in_flight``: CMA-ES, CEM,
CRS's initial set, ROCK*'s initial samples); the sequential ones keep one worker busy.
"""

from __future__ import annotations

import concurrent.futures as _futures
import os
from typing import Any, Callable, Dict, Optional

import ctrl_adapt

__all__ = ["minimize"]


def minimize(
    f: Callable[[Any], float],
    lower,
    upper,
    *,
    algorithm: str = "cmaes",
    budget: int = 200,
    workers: Optional[int] = None,
    seed: int = 0,
    start=None,
    executor: Optional[_futures.Executor] = None,
    **config: Any,
) -> "ctrl_adapt.MinimizeResult":
    """Minimise ``f(theta) -> float`` over ``[lower, upper]`` with at most ``budget``
    evaluations, ``workers`` of them at a time (default: the CPUs, at most the optimizer's
    ``max_in_flight``), on one process pool for the whole run (or on ``executor``, which is
    then left running for the caller). Returns :class:`ctrl_adapt.MinimizeResult`.

    ``algorithm``, ``seed``, ``start`` and the keyword arguments are
    :class:`ctrl_adapt.Optimizer`'s. An exception raised by ``f`` cancels the outstanding
    evaluations and propagates; a cost that is not a finite float32 raises
    :class:`ctrl_adapt.OptimizerError`.

    >>> import numpy as np, ctrl_adapt.pool
    >>> r = ctrl_adapt.pool.minimize(np.linalg.norm, -np.ones(2), np.ones(2), budget=60,
    ...                              workers=1, seed=1)
    >>> r.evaluations
    60
    """
    budget = int(budget)
    if budget < 1:
        raise ValueError(f"pool.minimize: budget must be at least 1, got {budget}")
    opt = ctrl_adapt.Optimizer(algorithm, lower, upper, start, seed=seed, **config)
    if workers is None:
        workers = min(os.cpu_count() or 1, opt.max_in_flight)
    workers = int(workers)
    if workers < 1:
        raise ValueError(f"pool.minimize: workers must be at least 1, got {workers}")
    own = executor is None
    pool = _futures.ProcessPoolExecutor(max_workers=workers) if own else executor
    running: Dict[_futures.Future, int] = {}
    handed = 0
    try:
        while True:
            # Hand out what the optimizer allows, within the budget and the workers.
            while opt.status == "running" and handed < budget and len(running) < workers:
                suggested = opt.suggest()
                if suggested is None:
                    break
                ticket, theta = suggested
                running[pool.submit(f, theta)] = ticket
                handed += 1
            if not running:
                break
            done, _ = _futures.wait(running, return_when=_futures.FIRST_COMPLETED)
            for future in done:
                ticket = running.pop(future)
                opt.report(ticket, float(future.result()))
    except BaseException:
        for future, ticket in running.items():
            future.cancel()
            opt.cancel(ticket)
        raise
    finally:
        if own:
            pool.shutdown(wait=True, cancel_futures=True)
    return ctrl_adapt.MinimizeResult(opt)
