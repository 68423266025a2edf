"""The Python objects are the firmware's Rust types: same candidates, same records.

Each test runs the `python-reference` binary of host-tests (the library's concrete types
written out as firmware writes them, not the package's dispatch) and the package side by side on
the same seed, configuration and costs, and compares every candidate bit for bit.
"""

import json
import os
import random
import struct
import subprocess

import numpy as np
import pytest

import ctrl_adapt

HERE = os.path.dirname(os.path.abspath(__file__))
REFERENCE = os.environ.get("CTRL_ADAPT_REFERENCE") or os.path.join(
    HERE, "..", "..", "target", "release", "python-reference"
)
ALGORITHMS = ctrl_adapt.algorithms()
STEPS = 260  # past CRS's 190 initial points at n = 18 and several CEM / CMA-ES generations


def reference(*args):
    out = subprocess.run([REFERENCE, *map(str, args)], check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def f32(bits):
    return struct.unpack("<f", struct.pack("<I", bits))[0]


def bits(values):
    return [struct.unpack("<I", struct.pack("<f", float(v)))[0] for v in values]


def drive(opt, costs):
    """Asks and tells `costs` in order; returns the candidates as f32 bit patterns."""
    seen = []
    for c in costs:
        theta = opt.ask()
        assert theta.dtype == np.float64 and theta.shape == (opt.dimension,)
        seen.append(bits(theta))
        opt.tell(f32(c))
    return seen


def drive_in_flight(opt, costs, seed=0):
    """`costs` through `suggest`/`report`: each generation handed out whole, its costs
    (the k-th candidate handed out gets costs[k]) reported in a shuffled order; returns the
    candidates in hand-out order as f32 bit patterns."""
    shuffle = random.Random(seed)
    seen = []
    while len(seen) < len(costs):
        out = []
        while len(seen) < len(costs) and (pair := opt.suggest()) is not None:
            out.append((pair[0], len(seen)))
            seen.append(bits(pair[1]))
        shuffle.shuffle(out)
        for ticket, k in out:
            opt.report(ticket, f32(costs[k]))
    return seen


def new(algorithm, n, seed):
    return ctrl_adapt.Optimizer(algorithm, -np.ones(n), np.ones(n), np.zeros(n) if
                                algorithm not in ("sracos", "crs", "two-phase") else None, seed=seed)


def test_the_reference_is_built():
    assert os.path.exists(REFERENCE), "cargo build --release -p host-tests --bin python-reference"


@pytest.mark.parametrize("algorithm", ALGORITHMS)
@pytest.mark.parametrize("n", [3, 18])
def test_same_candidates_as_the_rust_type(algorithm, n):
    ref = reference(algorithm, n, 7, STEPS)
    assert len(ref["candidates"]) > 0
    opt = new(algorithm, n, 7)
    assert drive(opt, ref["costs"]) == ref["candidates"]
    assert opt.evaluations == len(ref["costs"])


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_shuffled_reports_give_the_rust_types_candidates(algorithm):
    ref = reference(algorithm, 18, 7, STEPS)
    opt = new(algorithm, 18, 7)
    assert drive_in_flight(opt, ref["costs"], seed=1) == ref["candidates"]
    assert opt.evaluations == len(ref["costs"]) and opt.in_flight == []


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_python_record_loads_into_the_firmware_type(algorithm, tmp_path):
    n, k = 18, 60
    first = reference(algorithm, n, 3, k)
    opt = new(algorithm, n, 3)
    drive(opt, first["costs"])
    path = tmp_path / "state.rec"
    path.write_bytes(opt.save())
    # The Rust loader with the firmware's concrete type continues from it ...
    rust = reference(algorithm, n, 3, 80, "--from", path, "--seed-after", 11)
    # ... exactly as the Python object continues, reloaded with the same new RNG.
    again = ctrl_adapt.Optimizer.load(path.read_bytes(), seed=11)
    assert again.rust_type == opt.rust_type
    assert drive(again, rust["costs"]) == rust["candidates"]


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_a_firmware_record_loads_in_python(algorithm, tmp_path):
    n, k = 18, 60
    path = tmp_path / "firmware.rec"
    rust = reference(algorithm, n, 5, k + 80, "--save-at", k, path, "--seed-after", 13)
    opt = ctrl_adapt.Optimizer.load(path.read_bytes(), seed=13)
    assert opt.algorithm == algorithm and opt.dimension == n
    assert opt.evaluations == k
    assert drive(opt, rust["costs"][k:]) == rust["candidates"][k:]
