"""Inputs and environments that once crashed the interpreter or misbehaved: every algorithm
built, saved and loaded at the largest dimensions and on a small thread stack (in a
subprocess, so that a crash fails the test instead of killing pytest), bounds near the f32
limits, write_record's temporary files, durability and mode, and model rollouts of 2³² − 1
ticks (a diverging one aborted the interpreter allocating its NaN rows; one whose policy
raised ran every tick before raising, deaf to Ctrl-C)."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import ctrl_adapt
from ctrl_adapt.tune import write_record

STACK_SCRIPT = textwrap.dedent(
    """
    import threading, numpy as np, ctrl_adapt as c

    def work():
        for n in (1, 18, 62, 64):
            for a in c.algorithms():
                o = c.Optimizer(a, -np.ones(n), np.ones(n), seed=1)
                o.tell(float(np.sum(o.ask() ** 2)))
                loaded = c.Optimizer.load(o.save())
                assert loaded.rust_type == o.rust_type, (a, n)
                loaded.copy()
                loaded.ask()  # pending: the record of InFlight-free state with a pending candidate
                c.Optimizer.load(loaded.save())
                if o.max_in_flight > 1:
                    o.suggest()
                    c.Optimizer.load(o.save())  # the InFlight record, tickets outstanding
        print("done", threading.current_thread().name, flush=True)

    if {thread}:
        threading.stack_size(512 * 1024)
        t = threading.Thread(target=work)
        t.start()
        t.join()
    else:
        work()
    """
)


@pytest.mark.parametrize("thread", [False, True], ids=["main-thread", "512KiB-thread"])
def test_every_algorithm_builds_saves_and_loads_at_every_size_on_any_stack(thread):
    run = subprocess.run(
        [sys.executable, "-c", STACK_SCRIPT.format(thread=thread)],
        capture_output=True, text=True, timeout=600,
    )
    assert run.returncode == 0, f"exit {run.returncode}: {run.stderr[-2000:]}"
    assert "done" in run.stdout


def test_bounds_near_the_f32_limits_have_a_finite_default_start():
    opt = ctrl_adapt.Optimizer("cmaes", [1e38], [3e38])
    assert 1e38 <= opt.recommend()[0] <= 3e38
    theta = opt.ask()
    assert np.all(np.isfinite(theta)) and 1e38 <= theta[0] <= 3e38
    wide = ctrl_adapt.Optimizer("cem", [1e38, -3e38], [3e38, -1e38], seed=1)
    assert np.all(np.isfinite(wide.ask()))


def test_write_record_is_durable_with_the_umask_mode_and_leaves_no_temporary(tmp_path):
    opt = ctrl_adapt.Optimizer("cmaes", -np.ones(2), np.ones(2), seed=1)
    # A temporary file left by a writer killed mid-write (its process is gone).
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    stale = tmp_path / f".global.rec.record-{int(dead.stdout)}-x1y2"
    stale.write_bytes(b"partial")
    old = os.umask(0o027)
    try:
        assert write_record(opt, tmp_path / "global.rec") == "Cmaes<2, 6>"
    finally:
        os.umask(old)
    path = tmp_path / "global.rec"
    assert path.read_bytes() == opt.save()
    assert (path.stat().st_mode & 0o777) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ["global.rec"]


def test_write_record_removes_its_temporary_on_an_exception(tmp_path, monkeypatch):
    opt = ctrl_adapt.Optimizer("cmaes", -np.ones(2), np.ones(2), seed=1)

    def fail(*args):
        raise OSError("disk full")

    monkeypatch.setattr(os, "fsync", fail)
    with pytest.raises(OSError, match="disk full"):
        write_record(opt, tmp_path / "global.rec")
    assert list(tmp_path.iterdir()) == []


# The rollout of the report: its prediction diverges at once, and its 2³² rows of NaN (32 GiB
# as float64 at one state, 256 GiB at eight) were allocated at once, the failure an abort
# (exit 134). The address space is limited, so that the rows are refused on any machine
# rather than allocated and filled where the memory exists.
ROLLOUT_MEMORY_SCRIPT = textwrap.dedent(
    """
    import resource
    _, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, hard))
    import ctrl_adapt

    for s in (1, 8):
        try:
            ctrl_adapt.RlsModel(s, 1).rollout([0.0] * s, 2**32 - 1, lambda x: float("nan"))
        except MemoryError as e:
            print("MemoryError:", e, flush=True)
        else:
            print("no exception", flush=True)
    print("alive", flush=True)
    """
)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS bounds mmap on Linux")
def test_a_rollout_too_large_for_memory_raises_memory_error_not_an_abort():
    run = subprocess.run(
        [sys.executable, "-c", ROLLOUT_MEMORY_SCRIPT], capture_output=True, text=True,
        timeout=300, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    assert run.returncode == 0, f"exit {run.returncode}: {run.stderr[-2000:]}"
    lines = run.stdout.splitlines()
    assert lines[-1] == "alive" and len(lines) == 3, run.stdout
    for line, s in zip(lines, (1, 8)):
        assert line.startswith("MemoryError: rollout: ticks=4294967295 needs 4294967296 rows"), line
        assert f"rows of {s} states ({2**32 * s * 8} bytes as float64)" in line, line


# In a subprocess with a timeout: the rollout that ran every remaining tick after the
# policy's exception (2³² − 1 of them) fails the test instead of hanging pytest.
RAISING_POLICY_SCRIPT = textwrap.dedent(
    """
    import ctrl_adapt

    class Stop(Exception):
        pass

    model = ctrl_adapt.RlsModel(1, 1)
    for with_tick, fails_at in [(False, 0), (True, 0), (True, 5)]:
        calls, raised = [], Stop("the policy's own")

        def policy(*args):
            calls.append(args)
            if len(calls) > fails_at:
                raise raised
            return 0.0

        try:
            model.rollout([0.0], 2**32 - 1, policy, with_tick=with_tick)
        except Stop as e:
            assert e is raised, e
        else:
            raise AssertionError("no exception")
        assert len(calls) == fails_at + 1, (with_tick, fails_at, len(calls))
        if with_tick:
            assert [k for k, _ in calls] == list(range(fails_at + 1)), calls
    calls = []

    def wrong_size(x):
        calls.append(1)
        return [0.0, 1.0]

    try:
        model.rollout([0.0], 2**32 - 1, wrong_size)
    except ctrl_adapt.ModelError as e:
        assert "the policy's action has 2 values" in str(e), e
    assert len(calls) == 1, len(calls)
    print("done", flush=True)
    """
)


def test_a_policy_exception_stops_a_long_rollout_at_once():
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-c", RAISING_POLICY_SCRIPT], capture_output=True, text=True,
        timeout=120,
    )
    assert run.returncode == 0, f"exit {run.returncode}: {run.stderr[-2000:]}"
    assert run.stdout.split() == ["done"]
    assert time.monotonic() - start < 60


# A policy that runs no Python bytecode (a NumPy ufunc) never lets the interpreter see
# Ctrl-C: the rollout checks for it itself.
INTERRUPT_SCRIPT = textwrap.dedent(
    """
    import signal
    import ctrl_adapt, numpy as np

    # A process started in the background of a non-interactive shell (as CI starts this
    # suite) inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler:
    # install Python's own, as an interactive interpreter has it.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    model = ctrl_adapt.RlsModel(1, 1)
    try:
        print("rolling out", flush=True)
        model.rollout([0.0], 2**32 - 1, np.negative)  # x' = x: never diverges
    except KeyboardInterrupt:
        print("interrupted", flush=True)
    """
)


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_ctrl_c_interrupts_a_long_rollout():
    child = subprocess.Popen([sys.executable, "-c", INTERRUPT_SCRIPT], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline() == "rolling out\n"
        time.sleep(0.5)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 0, f"exit {child.returncode}: {err[-2000:]}"
    assert out == "interrupted\n"
