"""Dataset generation with all sensors: speed per core and on all cores, cost relative to
bare MuJoCo stepping, and peak memory against mission length.

Side by side in one run (these machines are noisy):

* ``paper-sim`` (3 missions x 7,200 s, DVL 1 Hz, IMU 100 Hz, every schema field) pinned
  to one core, and with the default workers on all cores. Real-time factor per core =
  simulated seconds / CPU seconds (all threads); speed-up = one-core wall time / all-core
  wall time. Pinned to one core the threads also pay for switching, so that run's CPU
  time is higher: both are printed, the targets use the all-core run's;
* a bare Python ``mj_step`` loop on the same model for the same number of steps;
* peak resident memory of ``auvsim generate`` for a 1 h and a 24 h mission (separate
  processes, ``ru_maxrss``).

    .venv/bin/python benchmarks/datasets.py [--duration 7200] [--skip-memory]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import perf_page

from auvsim.physics.vehicle import model_path
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset


def timed(fn) -> tuple[float, float]:
    """(wall seconds, CPU seconds of this process) of ``fn()``."""
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def peak_memory_mb(duration: float, out: Path) -> float:
    """Peak RSS (MB) of a separate ``auvsim generate`` process for one mission."""
    code = (
        "import resource, sys; from auvsim.cli import main; "
        f"main(['generate', '--preset', 'paper-sim', '--duration', '{duration}', "
        f"'--workers', '1', '--quiet', '--out', '{out}']); "
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True)
    return int(result.stdout.split()[-1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=7200.0,
                        help="length of each paper-sim mission, s")
    parser.add_argument("--repeats", type=int, default=3, help="alternating runs; medians")
    parser.add_argument("--skip-memory", action="store_true")
    perf_page.add_write_option(parser, "datasets")
    args = parser.parse_args()

    config = preset("paper-sim").with_duration(args.duration)
    simulated = sum(m.scenario.duration for m in config.missions)
    cores = os.cpu_count() or 1

    model = mujoco.MjModel.from_xml_path(str(model_path(config.vehicle.model)))
    model.opt.gravity[:] = 0.0  # the bare body floats instead of falling for hours
    data = mujoco.MjData(model)
    steps = round(simulated / model.opt.timestep)

    def bare() -> None:
        for _ in range(steps):
            mujoco.mj_step(model, data)

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "paper_sim.h5"
        generate(config, out, workers=1, progress=False)  # warm numba's cache
        every_cpu = os.sched_getaffinity(0)
        runs: dict[str, list[tuple[float, float]]] = {"one": [], "all": [], "bare": []}
        for _ in range(args.repeats):
            os.sched_setaffinity(0, {min(every_cpu)})
            try:
                runs["one"].append(timed(lambda: generate(config, out, workers=1,
                                                          progress=False)))
            finally:
                os.sched_setaffinity(0, every_cpu)
            runs["all"].append(timed(lambda: generate(config, out, progress=False)))
            runs["bare"].append(timed(bare))
        (one_wall, one_cpu), (all_wall, all_cpu), (_, bare_cpu) = (
            tuple(statistics.median(x) for x in zip(*runs[k], strict=True))
            for k in ("one", "all", "bare"))
        size = out.stat().st_size / 1e6
        memory = None
        if not args.skip_memory:
            memory = (peak_memory_mb(3600, Path(tmp) / "1h.h5"),
                      peak_memory_mb(86400, Path(tmp) / "24h.h5"))

    per_core = simulated / all_cpu
    print(f"paper-sim: 3 missions x {args.duration:g} s = {simulated:g} s simulated, "
          f"{steps} physics steps, {size:.0f} MB written, {cores} cores, "
          f"medians of {args.repeats} alternating runs")
    print(f"  one core:     {one_wall:6.2f} s wall, {one_cpu:6.2f} s CPU -> "
          f"{simulated / one_wall:6.0f}x real time")
    print(f"  {cores} cores:      {all_wall:6.2f} s wall, {all_cpu:6.2f} s CPU -> "
          f"{simulated / all_wall:6.0f}x real time, {per_core:.0f}x per core, speed-up "
          f"{one_wall / all_wall:.2f}x")
    print(f"  bare mj_step: {bare_cpu:6.2f} s CPU -> generate costs "
          f"{all_cpu / bare_cpu:.2f}x bare stepping ({one_cpu / bare_cpu:.2f}x pinned)")
    if memory:
        print(f"  peak memory:  1 h mission {memory[0]:.0f} MB, 24 h mission {memory[1]:.0f} MB"
              f" -> ratio {memory[1] / memory[0]:.2f}")
    checks = [("per core >= 1000x real time", per_core >= 1000),
              (f"speed-up on {cores} cores >= 1.7x", one_wall / all_wall >= 1.7),
              ("<= 3x bare stepping", all_cpu / bare_cpu <= 3)]
    if memory:
        checks.append(("24 h memory <= 1.2x 1 h", memory[1] / memory[0] <= 1.2))
    print("targets: " + "; ".join(f"{name}: {'met' if ok else 'MISSED'}" for name, ok in checks))


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
