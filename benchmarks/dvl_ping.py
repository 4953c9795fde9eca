"""Time the DVL and the altitude on the environment's small blocks, and on one 60 s block.

The environment (``auvsim/AUV-v0``) calls ``MissionRun.measure`` on blocks of 10 physics
steps; at the default 1 Hz pings and 100 Hz IMU one block in ten holds a ping. This script
flies one 60 s stretch of a preset's first mission once, then times, on that same
trajectory:

* ``Dvl.measure`` per 10-row block, split into blocks with a ping (M = 1) and without
  (M = 0), median per call, us;
* ``MissionRun._altitude`` per 10-row block, median, us;
* ``Dvl.measure`` on the whole 6000-row block (60 pings, what ``auvsim generate`` does),
  median per call, ms.

It measures whatever ``auvsim`` is importable. With ``--old TREE`` it instead runs itself
in subprocesses, alternately with ``PYTHONPATH=TREE`` and with this script's tree, for
``--rounds`` rounds, and prints each round's pair and the medians over rounds: on a shared
machine only timings taken side by side mean anything.

    .venv/bin/python benchmarks/dvl_ping.py [--preset paper-sim] [--passes 5]
    .venv/bin/python benchmarks/dvl_ping.py --old /tmp/dvl-old [--rounds 5]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SECONDS = 60.0  # of trajectory, s
FRAME_SKIP = 10  # physics steps per environment step


def measure_here(preset_name: str, passes: int) -> dict[str, float]:
    """Timings of the importable auvsim, in us (``block_ms`` in ms)."""
    import numpy as np

    from auvsim.mission import MissionRun
    from auvsim.presets import preset
    from auvsim.sensors import Truth

    config = preset(preset_name)
    run = MissionRun(config, config.missions[0])
    dvl = next(s for s in run.sensors if s.name == "dvl")
    rng = run.noise["dvl"]
    vehicle, dt = run.vehicle, run.vehicle.dt
    vehicle.reset(**run.scenario.initial_state())
    run.scenario.reset()
    steps = np.arange(round(SECONDS / dt))
    traj = run.scenario.run(vehicle, steps * dt)

    def truth(start: int, stop: int) -> Truth:
        keep = slice(start, stop, run.decimation)
        return Truth(start // run.decimation, steps[keep] * dt, traj.position_ned[keep],
                     traj.velocity_ned[keep], traj.velocity_body[keep], traj.quaternion[keep],
                     traj.angular_rate[keep], traj.specific_force[keep],
                     traj.current_ned[keep], traj.velocity_water_body[keep])

    small = [truth(k, k + FRAME_SKIP) for k in range(0, len(steps), FRAME_SKIP)]
    whole = truth(0, len(steps))
    ping, no_ping, altitude, block = [], [], [], []
    clock = time.perf_counter_ns
    for _ in range(passes):
        for t in small:
            start = clock()
            out = dvl.measure(t, rng)
            end = clock()
            (ping if len(out["dvl/time"]) else no_ping).append((end - start) / 1e3)
            start = clock()
            run._altitude(t)
            altitude.append((clock() - start) / 1e3)
        start = clock()
        dvl.measure(whole, rng)
        block.append((clock() - start) / 1e6)
    return dict(ping_us=statistics.median(ping), no_ping_us=statistics.median(no_ping),
                altitude_us=statistics.median(altitude), block_ms=statistics.median(block),
                pings=len(ping) // passes, blocks=len(small))


def compare(old: Path, preset_name: str, passes: int, rounds: int) -> None:
    """Run ``measure_here`` alternately under ``old`` and this tree; print the pairs."""
    trees = {"old": old.resolve(), "new": REPO}
    results: dict[str, list[dict]] = {"old": [], "new": []}
    keys = ("ping_us", "no_ping_us", "altitude_us", "block_ms")
    print(f"preset {preset_name}, {passes} passes per run; old = {trees['old']}, "
          f"new = {trees['new']}")
    print(f"{'round':>5} {'tree':>4} " + " ".join(f"{k:>12}" for k in keys))
    for r in range(rounds):
        order = ("old", "new") if r % 2 == 0 else ("new", "old")
        for name in order:
            env = dict(os.environ, PYTHONPATH=str(trees[name]))
            done = subprocess.run(
                [sys.executable, __file__, "--preset", preset_name, "--passes", str(passes),
                 "--json"], env=env, cwd=trees[name], check=True, capture_output=True,
                text=True)
            result = json.loads(done.stdout.strip().splitlines()[-1])
            results[name].append(result)
            print(f"{r:>5} {name:>4} " + " ".join(f"{result[k]:>12.1f}" for k in keys))
    print(f"{'median':>10} " + " ".join(f"{k:>12}" for k in keys))
    for name in ("old", "new"):
        print(f"{name:>10} " + " ".join(
            f"{statistics.median(x[k] for x in results[name]):>12.1f}" for k in keys))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="paper-sim")
    parser.add_argument("--passes", type=int, default=5,
                        help="passes over the 60 s of small blocks per run")
    parser.add_argument("--old", type=Path, help="a tree of the old code: compare with it")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    args = parser.parse_args()
    if args.old is not None:
        compare(args.old, args.preset, args.passes, args.rounds)
        return
    result = measure_here(args.preset, args.passes)
    if args.json:
        print(json.dumps(result))
    else:
        for key, value in result.items():
            print(f"{key:>12} {value:.1f}")


if __name__ == "__main__":
    main()
