"""Wall time of the pendulum example (python/examples/pendulum_pd.py, full run) with 1 and
then 2 Ray workers, one after the other in the same invocation, and the ratio. Each run is a
fresh process with its own local Ray cluster; the time is the tuning's (``tuner.fit()``),
Ray's start-up apart.

    python python/bench/ray_workers.py [--short] [--out DIR]
"""

import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLE = os.path.join(HERE, "..", "examples", "pendulum_pd.py")
LINE = re.compile(r"^workers: (\d+); trials: (\d+) .*tuning wall time: ([\d.]+) s \(after ([\d.]+) s")
COSTS = re.compile(r"bare PD cost: ([\d.]+) \(survived (\d+) of (\d+) steps\); tuned cost: ([\d.e+-]+)")


def run(workers, short, out):
    args = [sys.executable, EXAMPLE, "--workers", str(workers), "--out", os.path.join(out, f"workers-{workers}")]
    if short:
        args.append("--short")
    text = subprocess.run(args, check=True, capture_output=True, text=True).stdout
    found = next(LINE.match(line) for line in text.splitlines() if LINE.match(line))
    costs = COSTS.search(text)
    return {"trials": int(found[2]), "wall": float(found[3]), "startup": float(found[4]),
            "bare": costs[2], "steps": costs[3], "tuned": costs[4]}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--short", action="store_true", help="the example's --short run")
    p.add_argument("--out", default=os.path.join("target", "ray-workers"))
    a = p.parse_args()
    print(f"command: python python/bench/ray_workers.py {' '.join(sys.argv[1:])}".rstrip())
    runs = {workers: run(workers, a.short, a.out) for workers in (1, 2)}
    print("| Ray workers | trials | tuning wall time (s) | Ray start-up (s) | tuned cost |")
    print("| ---: | ---: | ---: | ---: | ---: |")
    for workers, r in runs.items():
        print(f"| {workers} | {r['trials']} | {r['wall']:.1f} | {r['startup']:.1f} | {r['tuned']} |")
    print(f"\nspeed-up with 2 workers: {runs[1]['wall'] / runs[2]['wall']:.2f}x")
    print(f"bare PD: survived {runs[1]['bare']} of {runs[1]['steps']} steps")


if __name__ == "__main__":
    main()
