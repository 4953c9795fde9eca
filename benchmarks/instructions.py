"""Instructions, not seconds: one step of ``auvsim/AUV-v0`` and one physics step of
``generate``'s loop, counted by valgrind's callgrind, for the working tree and optionally
a revision before it.

A count is the same whatever else the machine runs, where timings on these machines swing
by up to 60 % from one second to the next: two revisions then compare exactly, and a
change of a few per cent shows. (Seconds per instruction are not fixed: code that misses
the caches runs fewer instructions a second, so ``benchmarks/env.py`` still gives the
steps per second.)

Each figure is a difference of two runs of this script's ``--child`` under callgrind, one
with N steps and one with none after the same warm-up (numba loading its cache, the IMU's
first refill of errors drawn ahead), so start-up cancels:

* ``env step``: the default environment (paper-sim, frame skip 10) flying straight at a
  fixed action, as ``benchmarks/env.py`` does;
* ``physics step``: ``Vehicle.run`` of 6,000-step calls (60 s, ``generate``'s blocks) under
  the autopilots.

    .venv/bin/python benchmarks/instructions.py [--before REV] [--steps 500]

Six runs a tree, two at a time; with ``--before``, about 35 minutes on 2 cores, most of it
numba compiling each tree's cache for valgrind's CPU on the first runs (a tree's later runs
take a minute or two). Needs valgrind (Debian's package).
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import perf_page
from same_data import RunError, Trees, resolve  # the sibling script

REPO = Path(__file__).resolve().parent.parent
PHYSICS_BLOCK = 6000  # physics steps per call, as generate's 60 s blocks
ENV_WARMUP = 250  # env steps before counting: past the IMU's first refill (1,024 samples)


def child(mode: str, steps: int) -> None:
    """Warm up, then run ``steps`` env steps (mode ``env``) or physics steps (``physics``)."""
    import gymnasium as gym

    import auvsim  # noqa: F401  (registers auvsim/AUV-v0)
    from auvsim.runs.mission import MissionRun
    from auvsim.runs.presets import preset

    if mode == "env":
        env = gym.make("auvsim/AUV-v0")
        action = np.array([0.6, 0.0, 0.0], dtype=np.float32)
        for n in (ENV_WARMUP, steps):
            env.reset(seed=0)
            for _ in range(n):
                env.step(action)
    else:
        config = preset("paper-sim")
        run = MissionRun(config, config.missions[0])
        run.vehicle.reset(**run.scenario.initial_state())
        references = np.tile([1.5, 0.0, 20.0], (PHYSICS_BLOCK, 1))
        run.vehicle.run(references[:10])
        for _ in range(steps // PHYSICS_BLOCK):
            run.vehicle.run(references)


def collected(tree: Path, mode: str, steps: int) -> int:
    """Instructions callgrind counted for one child run with ``tree``'s code."""
    out = subprocess.run(
        ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", sys.executable,
         __file__, "--child", mode, str(steps)],
        env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"}, cwd=tree,
        capture_output=True, text=True)
    found = re.search(r"Collected : (\d+)", out.stderr)
    if out.returncode or not found:
        raise RunError(f"{tree}: the {mode} run failed: {out.stderr.strip()[-300:]}")
    return int(found.group(1))


def per_step(tree: Path, mode: str, steps: int) -> float:
    collected(tree, mode, 0)  # numba's cache for valgrind's CPU, compiled on a first run
    return (collected(tree, mode, steps) - collected(tree, mode, 0)) / steps


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", help="a revision to count beside the working tree")
    parser.add_argument("--steps", type=int, default=500, help="env steps counted (at "
                        "least 250; physics steps: 6,000 per 250 env steps)")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    perf_page.add_write_option(parser, "instructions")
    args = parser.parse_args()
    if args.child:
        child(args.child[0], int(args.child[1]))
        return 0
    if args.steps < ENV_WARMUP:
        print(f"instructions.py: --steps {args.steps}: expected at least {ENV_WARMUP}",
              file=sys.stderr)
        return 2
    if shutil.which("valgrind") is None:
        print("instructions.py: valgrind not found; expected it on PATH (apt-get install "
              "valgrind)", file=sys.stderr)
        return 2
    trees = Trees()
    try:
        sides = [("after (working tree)", REPO)]
        if args.before:
            sides.insert(0, (f"before ({args.before})", trees.add("before",
                                                                  resolve(args.before))))
        # Whole 6,000-step calls of physics, which child() runs (steps // PHYSICS_BLOCK).
        physics = PHYSICS_BLOCK * (args.steps // ENV_WARMUP)
        jobs = [(tree, mode, physics if mode == "physics" else args.steps)
                for _, tree in sides for mode in ("env", "physics")]
        with ThreadPoolExecutor(max_workers=2) as pool:  # valgrind runs one core each
            counts = list(pool.map(lambda job: per_step(*job), jobs))
    except RunError as e:
        print(f"instructions.py: {e}", file=sys.stderr)
        return 2
    finally:
        trees.close()
    print(f"{'':24s}{'env step':>14s}{'physics step':>14s}")
    for i, (label, _) in enumerate(sides):
        print(f"{label:24s}{counts[2 * i]:14,.0f}{counts[2 * i + 1]:14,.0f}")
    if args.before:
        print(f"{'after / before':24s}{counts[2] / counts[0]:14.3f}{counts[3] / counts[1]:14.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
