"""Inputs and environments that once crashed the interpreter or misbehaved: every algorithm
built, saved and loaded at the largest dimensions and on a small thread stack (in a
subprocess, so that a crash fails the test instead of killing pytest), bounds near the f32
limits, and write_record's temporary files, durability and mode."""

import os
import subprocess
import sys
import textwrap

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
