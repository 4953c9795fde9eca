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

With ``--bits TREE`` it checks instead that both trees give the same bits on the
environment's blocks: each measures the first ``BITS_SECONDS`` of a few configs' first
missions with ``MissionRun.measure`` on 10-step and on 6000-step blocks (every field of
every block, concatenated), and every array must be byte for byte the same in both.

    .venv/bin/python benchmarks/dvl_ping.py [--preset paper-sim] [--passes 5]
    .venv/bin/python benchmarks/dvl_ping.py --old /tmp/dvl-old [--rounds 5]
    .venv/bin/python benchmarks/dvl_ping.py --bits /tmp/dvl-old
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

import perf_page

REPO = Path(__file__).resolve().parent.parent
SECONDS = 60.0  # of trajectory, s
FRAME_SKIP = 10  # physics steps per environment step
BITS_SECONDS = 120.0  # of each mission --bits compares, s


def measure_here(preset_name: str, passes: int) -> dict[str, float]:
    """Timings of the importable auvsim, in us (``block_ms`` in ms)."""
    import numpy as np

    from auvsim.runs.mission import MissionRun
    from auvsim.runs.presets import preset
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
    for t in (*small[:10], whole):  # untimed: numba's compiles or cache loads, first calls
        dvl.measure(t, rng)
        run._altitude(t)
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


def bits_configs() -> dict:
    """The configs --bits compares: the environment's default, the navigator, and the
    navigator with its beam failure and soft bottom moved into the first two minutes."""
    import dataclasses

    from auvsim.runs.presets import preset

    nav = preset("navigator")
    moved = dataclasses.replace(nav.dvl, beam_failures=((1, 20.0, 35.0),),
                                lock_loss_intervals=((50.0, 70.0),))
    return {"paper-sim": preset("paper-sim"), "navigator": nav,
            "navigator-early-faults": dataclasses.replace(nav, dvl=moved)}


def dump_fields(path: Path) -> None:
    """Write the fields ``--bits`` compares, by ``config/block_steps/field``, to an .npz."""
    import numpy as np

    from auvsim.physics.vehicle import Trajectory
    from auvsim.runs.mission import MissionRun

    arrays = {}
    for name, config in bits_configs().items():
        for block_steps in (FRAME_SKIP, 6000):
            run = MissionRun(config, config.missions[0])
            vehicle, dt = run.vehicle, run.vehicle.dt
            vehicle.reset(**run.scenario.initial_state())
            run.scenario.reset()
            steps = np.arange(round(BITS_SECONDS / dt))
            traj = run.scenario.run(vehicle, steps * dt)
            parts: dict[str, list] = {}
            for start in range(0, len(steps), block_steps):
                block = slice(start, start + block_steps)
                fields = run.measure(steps[block], Trajectory(*(x[block] for x in traj)))
                for field, value in fields.items():
                    parts.setdefault(field, []).append(value)
            for field, values in parts.items():
                arrays[f"{name}/{block_steps}/{field}"] = np.concatenate(values)
    np.savez(path, **arrays)


def compare_bits(old: Path) -> bool:
    """Dump the fields under ``old`` and this tree; print and return whether they agree."""
    import tempfile

    import numpy as np

    dumps = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, tree in (("old", old.resolve()), ("new", REPO)):
            dumps[name] = Path(tmp) / f"{name}.npz"
            subprocess.run([sys.executable, __file__, "--dump", str(dumps[name])],
                           env=dict(os.environ, PYTHONPATH=str(tree)), cwd=tree, check=True)
        a, b = np.load(dumps["old"]), np.load(dumps["new"])
        same = sorted(a.files) == sorted(b.files)
        if not same:
            print("different fields:", sorted(set(a.files) ^ set(b.files)))
        for key in sorted(set(a.files) & set(b.files)):
            x, y = a[key], b[key]
            if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
                same = False
                print(f"DIFFERENT {key}: {x.dtype}{x.shape} vs {y.dtype}{y.shape}")
        print(f"{len(a.files)} arrays ({', '.join(bits_configs())}; 10- and 6000-step "
              f"blocks, {BITS_SECONDS:g} s each): " + ("SAME BITS" if same else "DIFFERENT"))
    return same


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="paper-sim")
    parser.add_argument("--passes", type=int, default=5,
                        help="passes over the 60 s of small blocks per run")
    parser.add_argument("--old", type=Path, help="a tree of the old code: compare with it")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    parser.add_argument("--bits", type=Path, help="a tree of the old code: check that it "
                        "gives the same bits")
    parser.add_argument("--dump", type=Path, help=argparse.SUPPRESS)
    perf_page.add_write_option(parser, "dvl_ping")
    args = parser.parse_args()
    if args.dump is not None:
        dump_fields(args.dump)
        return
    if args.bits is not None:
        sys.exit(0 if compare_bits(args.bits) else 1)
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
    sys.exit(perf_page.run(main))
