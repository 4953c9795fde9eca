"""Generation speed: real-time factor per core, and cost relative to bare MuJoCo stepping.

Runs, side by side and alternating (these machines are noisy), for the same model and the
same number of physics steps:

* ``bare``: a plain Python loop of ``mujoco.mj_step`` with no forces, no recording (and no
  gravity, so the body does not fall for the whole mission);
* ``simulate``: auvsim's compiled loop with hydrodynamics, autopilots and truth recording;
* ``generate``: the whole ``auvsim generate --scenario straight`` path, HDF5 writing included.

Real-time factor per core = simulated seconds / CPU seconds of this (single-threaded) process.

    .venv/bin/python benchmarks/generation.py [--duration 3600] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import perf_page

from auvsim.config import Config, MissionConfig, ScenarioConfig, VehicleConfig
from auvsim.physics.vehicle import model_path
from auvsim.runs.generate import generate
from auvsim.runs.mission import MissionRun


def cpu_seconds(fn) -> float:
    start = time.process_time()
    fn()
    return time.process_time() - start


def wall_seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3600.0, help="mission length, s")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--vehicle", default="auv")
    perf_page.add_write_option(parser, "generation")
    args = parser.parse_args()

    config = Config(vehicle=VehicleConfig(model=args.vehicle),
                    missions=(MissionConfig(scenario=ScenarioConfig(
                        speed=2.0, heading_deg=30.0, depth=20.0, duration=args.duration)),))
    model = mujoco.MjModel.from_xml_path(str(model_path(args.vehicle)))
    model.opt.gravity[:] = 0.0  # the bare body floats instead of falling for an hour
    data = mujoco.MjData(model)
    steps = round(args.duration / model.opt.timestep)

    def bare() -> None:
        mujoco.mj_resetData(model, data)
        for _ in range(steps):
            mujoco.mj_step(model, data)

    def sim_only() -> None:
        for _ in MissionRun(config, config.missions[0]).blocks():
            pass

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.h5"

        def full() -> None:
            generate(config, out, progress=False)

        full()  # loads the compiled kernel from numba's cache (or compiles it) once
        times: dict[str, list[float]] = {"bare": [], "simulate": [], "generate": []}
        for _ in range(args.repeats):
            times["bare"].append(cpu_seconds(bare))
            times["simulate"].append(cpu_seconds(sim_only))
            times["generate"].append(cpu_seconds(full))
        size_mb = out.stat().st_size / 1e6

    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"vehicle {args.vehicle}, straight mission of {args.duration:g} s, {steps} physics "
          f"steps at {1 / model.opt.timestep:g} Hz, median of {args.repeats} (CPU seconds)")
    print(f"{'':10s} {'CPU s':>8s} {'us/step':>8s} {'x real time':>12s} {'x bare':>8s}")
    for name, t in med.items():
        print(f"{name:10s} {t:8.3f} {t / steps * 1e6:8.2f} {args.duration / t:12.0f} "
              f"{t / med['bare']:8.2f}")
    print(f"dataset size: {size_mb:.1f} MB")
    print(f"targets: generate >= 1000x real time per core -> "
          f"{'met' if args.duration / med['generate'] >= 1000 else 'MISSED'}; "
          f"generate <= 3x bare mj_step loop -> "
          f"{'met' if med['generate'] / med['bare'] <= 3 else 'MISSED'}")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
