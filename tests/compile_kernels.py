"""Compile the numba kernels into their cache before the tests start (``make test`` runs
this beside the documentation build).

numba compiles a kernel at its first call and caches it beside the source (``cache=True``).
On a fresh clone every process that calls a kernel before some process has written its
cache compiles it too: the simulator's kernels take about 17 s, the INS/DVL filter's
about 38 s, and the two test workers, the commands the tests start and their worker
processes would each pay it at the start of the run. Here they are compiled once, each in
its own process, so the two take as long as the longer: the simulator's through a short
``navigator`` mission (every sensor effect on), the filter's through ``run_arrays`` on a
vehicle at rest, on beams and on a velocity. The filter's loop takes every input as an
array of fixed type, so these calls compile the one signature every caller uses (a run of
the tests leaves a single ``_filter`` entry in the cache).
"""

from __future__ import annotations

import multiprocessing
import tempfile
from pathlib import Path

import numpy as np


def simulator() -> None:
    from auvsim.runs.generate import generate
    from auvsim.runs.presets import preset

    with tempfile.TemporaryDirectory() as tmp:
        generate(preset("navigator").with_duration(20.0), Path(tmp) / "kernels.h5",
                 workers=1, progress=False)


def ins_filter() -> None:
    from beamsnet.estimators.ins import Instrument, Start, run_arrays

    imu_time = np.arange(2001) / 100.0
    at_rest = np.tile([0.0, 0.0, -9.81], (len(imu_time), 1))
    dvl_time = np.arange(1.0, 20.0)
    start = Start(0.0, np.zeros(3), np.zeros(3), np.eye(3), np.full(3, 0.1),
                  np.full(3, 0.01), np.full(3, 1e-3))
    for k, measured in ((4, "beams"), (3, "velocity")):
        instrument = Instrument(1e-4, 1e-6, 1e-3, 1e-5, 1e-10, 1e-14, np.full(k, 0.002))
        run_arrays(imu_time, at_rest, np.zeros_like(at_rest), dvl_time,
                   **{measured: np.zeros((len(dvl_time), k))}, beam_angle_deg=30.0,
                   latitude_deg=32.85, start=start, instrument=instrument)


def main() -> None:
    spawn = multiprocessing.get_context("spawn")
    workers = [spawn.Process(target=job) for job in (simulator, ins_filter)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    if any(w.exitcode for w in workers):
        raise SystemExit(f"compiling the kernels failed (exit codes "
                         f"{[w.exitcode for w in workers]})")


if __name__ == "__main__":
    main()
