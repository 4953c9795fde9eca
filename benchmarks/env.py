"""Environment speed: ``auvsim/AUV-v0`` steps per second per core, against ``auvsim
generate`` of the same simulated time, and vector envs (gymnasium's ``AsyncVectorEnv``,
``auvsim.envs.vector.AuvVectorEnv``) against one env.

Runs, side by side and alternating (these machines are noisy), the default environment
(paper-sim config, frame skip 10: dt = 0.1 s) flying one straight episode at a fixed
action (shaft at 0.6 of its limit, fins centred; it holds its 20 m depth):

* ``env``: ``gymnasium.make("auvsim/AUV-v0")``, reset and stepped through the episode;
  CPU seconds of this process (``time.process_time``), so steps/s per core;
* ``generate``: ``auvsim generate`` (one worker, HDF5 writing included) of a mission of
  the same scenario and length, CPU seconds too;
* ``1 env`` and ``async x2``: wall-clock seconds of the same episode in one env, and in
  each env of ``gymnasium.make_vec(..., num_envs=2, vectorization_mode="async")``; the
  speed-up is total env steps/s of the two over the one (2 at best on two idle cores);
* ``2 lone``: two processes flying the episode in an env each, at the same time and not
  synchronised: what two cores of this machine give the env at most. The control line
  after the table does the same with ``small_loop`` (small numpy and Python operations on
  a few hundred bytes) against one run of it here: what the cores give to work that fits
  in each core's own caches;
* ``native 2``, ``native 8`` and ``native 32``: the same in each env of
  ``auvsim.envs.vector.AuvVectorEnv`` with its default workers (on 2 cores one worker process
  beside this one, each stepping half of the envs: 1, 4 or 16 each; the more envs per
  vector step, the less its fixed cost and its wait for the slower slice weigh).

For the vector envs, ``parent ms`` is the parent process's CPU time per vector step
(``time.process_time`` over the episode: for async, pickling, pipes and merging infos,
waiting costs none; for native, its own slice of envs too, and its polling for the
workers' answers), ``CPU x`` the CPU seconds of the parent and its workers
(``/proc/<pid>/stat``) per env step over ``env``'s (1 = no overhead; polling counts),
and ``noop ms`` the wall time per step of a native env whose envs do not step: the
parent's whole cost plus the round trip to the workers.

The first call of each (numba loading its cache, gymnasium's checks) is not timed.

    .venv/bin/python benchmarks/env.py [--seconds 300] [--repeats 3]
    .venv/bin/python benchmarks/env.py --profile   # where one env's step goes

``--profile`` flies the episode in one env with a timer around each part of the step
(``Vehicle.advance``, ``MissionRun.measure`` and in it each sensor and the altitude, the
env's ``_info`` and ``_observation``) and prints microseconds per step: the table in
``docs/ARCHITECTURE.md``. The timers cost a little each, so the parts add up to a bit more
than a step without them.

(The native envs' workers import this script: hence the ``__main__`` guard.)
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import perf_page
from generation import (  # the sibling script (its directory is on sys.path)
    cpu_seconds,
    wall_seconds,
)

import auvsim  # noqa: F401  (registers auvsim/AUV-v0)
from auvsim.config import MissionConfig
from auvsim.envs.vector import NOOP, AuvVectorEnv
from auvsim.runs.generate import generate

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


SMALL = 60_000  # iterations of the small loop: about as long as an episode


def small_loop(n: int = SMALL) -> int:
    """``n`` rounds of a few small numpy and Python operations on a few hundred bytes:
    work that fits in a core's own caches (the control line); returns ``n``."""
    a, m = np.zeros(3), np.eye(3)
    rng = np.random.default_rng(0)
    for _ in range(n):
        a = m @ (a * 0.5 + 1.0)
        np.clip(rng.standard_normal(3), -1.0, 1.0)
    return n


def _lone(conn, seconds: float | None) -> None:
    """A process flying the episode in an env of its own whenever asked (``TwoLone``), or,
    given no ``seconds``, running ``small_loop``."""
    if seconds is None:
        job = small_loop
    else:
        env = gym.make("auvsim/AUV-v0", max_episode_seconds=seconds)
        job = lambda: episode(env, seconds)  # noqa: E731
    job()  # loads every kernel
    conn.send(None)
    while conn.recv():
        conn.send(job())


class TwoLone:
    """Two processes, each flying the episode in its own env (or, with no ``seconds``,
    running ``small_loop``), started together and not synchronised: what two cores of this
    machine give at most (the ``2 lone`` row and the control line)."""

    def __init__(self, seconds: float | None) -> None:
        ctx = multiprocessing.get_context("forkserver")
        self.conns, self.processes = [], []
        for _ in range(2):
            parent, child = ctx.Pipe()
            process = ctx.Process(target=_lone, args=(child, seconds), daemon=True)
            process.start()
            self.conns.append(parent)
            self.processes.append(process)
        for conn in self.conns:
            conn.recv()

    def episodes(self) -> int:
        for conn in self.conns:
            conn.send(True)
        return sum(conn.recv() for conn in self.conns)

    def close(self) -> None:
        for conn, process in zip(self.conns, self.processes, strict=True):
            conn.send(False)
            process.join()


def worker_pids(vector: gym.vector.VectorEnv) -> list[int]:
    """The process ids of a vector env's workers (AsyncVectorEnv's or AuvVectorEnv's)."""
    if isinstance(vector, AuvVectorEnv):
        return vector.worker_pids
    return [process.pid for process in vector.processes]


def process_cpu(pid: int) -> float:
    """User and system CPU seconds of process ``pid`` so far (``/proc/<pid>/stat``)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def wall_and_cpu(fn, pids: list[int]) -> tuple[float, float, float]:
    """Wall-clock seconds of ``fn()``, this process's CPU seconds, and those of processes
    ``pids`` (the workers), together."""
    workers = sum(process_cpu(pid) for pid in pids)
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, cpu, sum(process_cpu(pid) for pid in pids) - workers


def noop_step_seconds(env: AuvVectorEnv, steps: int = 2000) -> float:
    """Wall seconds per vector step of ``env`` with no env stepping (the workers answer
    at once)."""
    env.reset(seed=0)
    actions = np.tile(ACTION, (env.num_envs, 1))
    start = time.perf_counter()
    for _ in range(steps):
        env._step(actions, NOOP)
    return (time.perf_counter() - start) / steps


def profile(seconds: float) -> None:
    """Print the microseconds per step of each part of ``AuvEnv.step`` (``--profile``)."""
    from auvsim.envs.env import AuvEnv
    from auvsim.physics.vehicle import Vehicle
    from auvsim.runs.mission import MissionRun
    from auvsim.sensors import registry

    spent: dict[str, float] = {}

    def timed(owner, name: str, label: str) -> None:
        inner = getattr(owner, name)
        spent[label] = 0.0  # printed in this order

        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return inner(*args, **kwargs)
            finally:
                spent[label] = spent.get(label, 0.0) + time.perf_counter() - start

        setattr(owner, name, wrapper)

    env = gym.make("auvsim/AUV-v0", max_episode_seconds=seconds)
    episode(env, seconds)  # loads every kernel
    timed(AuvEnv, "step", "whole step")
    timed(Vehicle, "advance", "Vehicle.advance (physics)")
    timed(MissionRun, "measure", "MissionRun.measure")
    for name, sensor in registry().items():
        timed(sensor, "measure", f"  {name}")
    timed(MissionRun, "_altitude", "  altitude")
    timed(AuvEnv, "_info", "_info")
    timed(AuvEnv, "_observation", "_observation")
    steps = episode(env, seconds)
    env.close()
    for label, total in spent.items():
        print(f"{label:28s} {1e6 * total / steps:7.1f} us per step")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=300.0,
                        help="simulated seconds per episode (and of the generated mission)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--profile", action="store_true",
                        help="time each part of one env's step instead")
    perf_page.add_write_option(parser, "env")
    args = parser.parse_args()
    if args.profile:
        profile(args.seconds)
        return

    env = gym.make("auvsim/AUV-v0", max_episode_seconds=args.seconds)
    vectors = {
        "async x2": gym.make_vec("auvsim/AUV-v0", num_envs=2, vectorization_mode="async",
                                 max_episode_seconds=args.seconds),
        "native 2": AuvVectorEnv(num_envs=2, max_episode_seconds=args.seconds),
        "native 8": AuvVectorEnv(num_envs=8, max_episode_seconds=args.seconds),
        "native 32": AuvVectorEnv(num_envs=32, max_episode_seconds=args.seconds),
    }
    two, two_small = TwoLone(args.seconds), TwoLone(None)
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
        for vector in vectors.values():
            vector_episode(vector, args.seconds)
        small_loop()
        # Each job: (clock, what it runs, its count: env steps, or small-loop rounds).
        jobs = {"env": ("CPU", lambda: episode(env, args.seconds), steps),
                "generate": ("CPU", full, steps),
                "1 env": ("wall", lambda: episode(env, args.seconds), steps),
                "2 lone": ("wall", two.episodes, 2 * steps),
                **{name: ("wall", lambda v=v: vector_episode(v, args.seconds),
                          v.num_envs * steps) for name, v in vectors.items()},
                "1 small": ("wall", small_loop, SMALL),
                "2 small": ("wall", two_small.episodes, 2 * SMALL)}
        rates = {name: [] for name in jobs}  # per round: count per second
        parent = {name: [] for name in vectors}  # per round: CPU s of this process
        total = {name: [] for name in vectors}  # and of this process and its workers
        noop = {name: [] for name in vectors if name.startswith("native")}
        names = list(jobs)
        for r in range(args.repeats):
            # A round runs every job once, each round starting one job later, so that no
            # job always follows the same one; ratios are taken within a round.
            for name in names[r % len(names):] + names[:r % len(names)]:
                clock, fn, count = jobs[name]
                if name in vectors:
                    wall, cpu, workers = wall_and_cpu(fn, worker_pids(vectors[name]))
                    parent[name].append(cpu)
                    total[name].append(cpu + workers)
                    if name in noop:
                        noop[name].append(noop_step_seconds(vectors[name]))
                else:
                    wall = (cpu_seconds if clock == "CPU" else wall_seconds)(fn)
                rates[name].append(count / wall)
    for vector in vectors.values():
        vector.close()
    two.close()
    two_small.close()
    env.close()
    report(args, unwrapped, steps, load, jobs, rates, parent, total, noop, vectors)


def spread(values: list[float]) -> str:
    """The median of per-round values, and their range: "1.73 (1.70-1.76)"."""
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def report(args, unwrapped, steps, load, jobs, rates, parent, total, noop, vectors) -> None:
    """Print the table (medians over the rounds) and the per-round ratios."""
    med = {name: statistics.median(r) for name, r in rates.items()}
    per_round = {name: [a / b for a, b in zip(r, rates["1 env"], strict=True)]
                 for name, r in rates.items()}
    print(f"straight episode of {args.seconds:g} s at dt {unwrapped.dt:g} s ({steps} env "
          f"steps, frame skip {unwrapped.frame_skip}), {args.repeats} rounds; "
          f"{os.cpu_count()} cores, load average {load:.2f} before the run")
    print(f"{'':10s} {'clock':>6s} {'steps/s':>9s} {'x real time':>12s} "
          f"{'x 1 env':>8s} {'parent ms':>10s} {'CPU x':>6s} {'noop ms':>8s}")
    for name, (clock, _, count) in jobs.items():
        if "small" in name:
            continue
        extra = ""
        if name == "2 lone" or name in vectors:
            extra = f" {statistics.median(per_round[name]):8.2f}"
        if name in vectors:
            cpu_x = statistics.median([t / count * rate for t, rate
                                       in zip(total[name], rates["env"], strict=True)])
            extra += (f" {1e3 * statistics.median(parent[name]) / steps:10.3f} "
                      f"{cpu_x:6.2f}")
            if name in noop:
                extra += f" {1e3 * statistics.median(noop[name]):8.3f}"
        print(f"{name:10s} {clock:>6s} {med[name]:9.0f} {med[name] * unwrapped.dt:12.0f}"
              f"{extra}")
    print("(medians over the rounds. generate's steps/s: env steps of the same simulated "
          "time per CPU second; x 1 env: total env steps/s, wall, over 1 env's in the same "
          "round; parent ms: the parent's CPU per vector step; CPU x: CPU of the parent and "
          "the workers per env step over env's (1 = no overhead); noop ms: wall per vector "
          "step with no env stepping)")
    print("per round, median (min-max) of the rounds:")
    print(f"  env / generate CPU per simulated second: "
          f"{spread([g / e for e, g in zip(rates['env'], rates['generate'], strict=True)])}")
    for name in ("2 lone", *vectors):
        line = f"  {name} / 1 env (total env steps/s, wall): {spread(per_round[name])}"
        if name != "2 lone":
            line += "; / 2 lone: " + spread(
                [a / b for a, b in zip(rates[name], rates["2 lone"], strict=True)])
        print(line)
    print("  control, small_loop (a few hundred bytes of data): 2 processes / 1 (total "
          "rounds/s, wall): " + spread(
              [b / a for a, b in zip(rates["1 small"], rates["2 small"], strict=True)]))
    print(f"target: env >= {TARGET:.0f} steps/s per core -> "
          f"{'met' if med['env'] >= TARGET else 'MISSED'} ({med['env']:.0f})")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
