"""Environment speed: ``auvsim/AUV-v0`` steps per second per core, against ``auvsim
generate`` of the same simulated time, and a 2-env ``AsyncVectorEnv`` against one env.

Runs, side by side and alternating (these machines are noisy), the default environment
(paper-sim config, frame skip 10: dt = 0.1 s) flying one straight episode at a fixed
action (shaft at 0.6 of its limit, fins centred; it holds its 20 m depth):

* ``env``: ``gymnasium.make("auvsim/AUV-v0")``, reset and stepped through the episode;
  CPU seconds of this process (``time.process_time``), so steps/s per core;
* ``generate``: ``auvsim generate`` (one worker, HDF5 writing included) of a mission of
  the same scenario and length, CPU seconds too;
* ``1 env`` and ``async x2``: wall-clock seconds of the same episode in one env, and in
  each env of ``gymnasium.make_vec(..., num_envs=2, vectorization_mode="async")``; the
  speed-up is total env steps/s of the two over the one (2 at best on two idle cores).

The first call of each (numba loading its cache, gymnasium's checks) is not timed.

    .venv/bin/python benchmarks/env.py [--seconds 300] [--repeats 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np
from generation import (  # the sibling script (its directory is on sys.path)
    cpu_seconds,
    wall_seconds,
)

import auvsim  # noqa: F401  (registers auvsim/AUV-v0)
from auvsim.config import MissionConfig
from auvsim.generate import generate

ACTION = np.array([0.6, 0.0, 0.0], dtype=np.float32)
TARGET = 5000.0  # env steps/s per core at the default frame skip (issue 12, item 9)


def episode(env: gym.Env, seconds: float) -> int:
    """Reset ``env`` and fly one episode of ``seconds`` (its ``max_episode_seconds``) at
    ``ACTION``; the number of steps taken."""
    env.reset(seed=0)
    steps = 0
    while True:
        *_, terminated, truncated, _ = env.step(ACTION)
        steps += 1
        if terminated or truncated:
            return steps


def vector_episode(env: gym.vector.VectorEnv, seconds: float) -> int:
    """The same in every env of a vector env, at once; the total env steps taken."""
    env.reset(seed=0)
    actions = np.tile(ACTION, (env.num_envs, 1))
    steps = 0
    while True:
        *_, terminated, truncated, _ = env.step(actions)
        steps += env.num_envs
        if (terminated | truncated).all():
            return steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=300.0,
                        help="simulated seconds per episode (and of the generated mission)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    env = gym.make("auvsim/AUV-v0", max_episode_seconds=args.seconds)
    vector = gym.make_vec("auvsim/AUV-v0", num_envs=2, vectorization_mode="async",
                          max_episode_seconds=args.seconds)
    unwrapped = env.unwrapped
    start = unwrapped.start
    config = dataclasses.replace(unwrapped.config, missions=(MissionConfig(
        name="straight", scenario=dataclasses.replace(start, duration=args.seconds)),))
    steps = round(args.seconds / unwrapped.dt)
    load = os.getloadavg()[0]

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.h5"

        def full() -> None:
            generate(config, out, workers=1, progress=False)

        full()  # the first calls load (or compile) every kernel, so that none is timed
        episode(env, args.seconds)
        vector_episode(vector, args.seconds)
        times: dict[str, list[float]] = {"env": [], "generate": [], "1 env": [],
                                         "async x2": []}
        counts = {"env": steps, "generate": steps, "1 env": steps, "async x2": 2 * steps}
        for _ in range(args.repeats):
            times["env"].append(cpu_seconds(lambda: episode(env, args.seconds)))
            times["generate"].append(cpu_seconds(full))
            times["1 env"].append(wall_seconds(lambda: episode(env, args.seconds)))
            times["async x2"].append(wall_seconds(lambda: vector_episode(vector,
                                                                         args.seconds)))
    vector.close()
    env.close()

    med = {k: statistics.median(v) for k, v in times.items()}
    rate = {k: counts[k] / t for k, t in med.items()}
    print(f"straight episode of {args.seconds:g} s at dt {unwrapped.dt:g} s ({steps} env "
          f"steps, frame skip {unwrapped.frame_skip}), median of {args.repeats}; "
          f"{os.cpu_count()} cores, load average {load:.2f} before the run")
    print(f"{'':10s} {'clock':>6s} {'seconds':>8s} {'steps/s':>9s} {'x real time':>12s}")
    for name, t in med.items():
        clock = "CPU" if name in ("env", "generate") else "wall"
        print(f"{name:10s} {clock:>6s} {t:8.3f} {rate[name]:9.0f} "
              f"{counts[name] * unwrapped.dt / t:12.0f}")
    print("(generate's steps/s: env steps of the same simulated time per CPU second)")
    print(f"env / generate CPU per simulated second: {med['env'] / med['generate']:.2f}")
    print(f"async x2 / 1 env (total env steps/s, wall): "
          f"{rate['async x2'] / rate['1 env']:.2f}")
    print(f"target: env >= {TARGET:.0f} steps/s per core -> "
          f"{'met' if rate['env'] >= TARGET else 'MISSED'} ({rate['env']:.0f})")


if __name__ == "__main__":
    main()
