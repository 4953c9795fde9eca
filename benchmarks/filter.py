"""INS/DVL filter speed: real-time factor per core, and cost relative to generating the
same mission.

Generates one mission (navigation-grade IMU at 100 Hz, the paper's 1 Hz DVL noise, a
zigzag), then runs, side by side and alternating (these machines are noisy):

* ``generate``: ``auvsim generate`` of that mission, HDF5 writing included;
* ``filter``: ``beamsnet.estimators.ins.run_mission`` on it, HDF5 reading included (15 states);
* ``filter+beams``: the same with the 14 instrument states (29 states);
* ``filter+beams+gyro``: and the gyros' scale factors and misalignments (38 states; the
  ``navigation-full`` grade's spreads, set in the ``FilterConfig``);
* ``adaptive``, ``adaptive+beams``: ``filter`` and ``filter+beams`` with the beam noise
  estimated from the innovations (``FilterConfig(adaptive="innovation")``, the
  ``INS/DVL (adaptive)`` estimator);
* ``learned``, ``learned+beams``: likewise with the learned DVL noise
  (``FilterConfig(adaptive="learned")``, the ``INS/DVL (learned noise)`` estimator): its
  network run at every ping, with seeded random weights of the trained model's shape (the
  arithmetic does not depend on their values);
* ``kernel``: the compiled filter loop alone (15 states), no file reading.

and, where the shared real logs are (``--akit``, default ``../shared/data/snapir-akit``),
on a recorded segment (``Trajectory1``: 400 s, IMU 100 Hz, DVL velocity 1 Hz), the
filter with its defaults for a real vehicle (``run_arrays``: 29 states with the DVL's
scale factors, biases, misalignment and lever arm; the Earth's rate; the pings' timing):

* ``recorded``: ``beamsnet.estimators.ins.run_arrays`` on the arrays (the CSVs read once,
  untimed; their axes and clocks as published: the speed does not depend on them), fixed,
  adaptive and learned side by side, and the fixed filter with the gyro matrix's states
  (38).

Real-time factor per core = simulated (or recorded) seconds / CPU seconds of this
(single-threaded) process; the first call (numba compiling, or loading its on-disk
cache) is not timed.

    .venv/bin/python benchmarks/filter.py [--duration 600] [--repeats 3] [--akit DIR]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import perf_page
from generation import cpu_seconds  # the sibling scripts (their directory is on sys.path)
from sea_filter import DATA

from auvsim.config import Config, DvlConfig, MissionConfig, ScenarioConfig
from auvsim.data.reader import open_dataset
from auvsim.physics.frames import rotation_rpy
from auvsim.runs.generate import generate
from auvsim.sensors.imu import IMU_GRADES
from beamsnet.estimators import ins, noisemodel


def random_model() -> noisemodel.NoiseModel:
    """A noise model of the trained one's shape, with seeded random weights."""
    rng = np.random.default_rng(0)
    d = noisemodel.WINDOW * len(noisemodel.FEATURES)
    return noisemodel.NoiseModel(w1=0.1 * rng.standard_normal((noisemodel.HIDDEN, d)),
                               b1=rng.standard_normal(noisemodel.HIDDEN),
                               w2=rng.standard_normal(noisemodel.HIDDEN), b2=0.0,
                               mean=np.zeros(d), std=np.ones(d))


MODEL = random_model()
# The gyro matrix's states with the navigation-full grade's spreads (the benchmark's IMU,
# "navigation", states none).
FULL = IMU_GRADES["navigation-full"]
GYRO = dict(gyro_matrix_states=True, gyro_scale_factor_std=FULL.gyro_scale_factor_std,
            gyro_misalignment_std=FULL.gyro_misalignment_std)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=600.0, help="mission length, s")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--akit", type=Path, default=DATA,
                        help="the shared real segments (skipped if absent)")
    perf_page.add_write_option(parser, "filter")
    args = parser.parse_args()

    config = Config(missions=(MissionConfig(name="zz", scenario=ScenarioConfig(
                        name="zigzag", duration=args.duration)),),
                    dvl=DvlConfig(beam_angle_deg=20.0, noise_std=0.042**2),
                    imu=IMU_GRADES["navigation"])
    kernel_times: list[float] = []
    compiled = ins._filter

    def timed_kernel(*a):
        start = time.process_time()
        out = compiled(*a)
        kernel_times.append(time.process_time() - start)
        return out

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.h5"

        def full() -> None:
            generate(config, out, workers=1, progress=False)

        def run(beam_states: bool, adaptive: str = "none", gyro: bool = False):
            def go() -> None:
                with open_dataset(out) as f:
                    ins.run_mission(f.missions["zz"], ins.FilterConfig(
                        beam_states=beam_states, adaptive=adaptive, **(GYRO if gyro else {})),
                        noise_model=MODEL)
            return go

        full()  # loads (or compiles) every kernel once, so that none is timed
        run(False)()
        run(True)()
        times: dict[str, list[float]] = {
            name: [] for name in ("generate", "filter", "filter+beams", "filter+beams+gyro",
                                  "adaptive", "adaptive+beams", "learned", "learned+beams",
                                  "kernel")}
        ins._filter = timed_kernel
        try:
            for _ in range(args.repeats):
                times["generate"].append(cpu_seconds(full))
                kernel_times.clear()
                times["filter"].append(cpu_seconds(run(False)))
                times["kernel"].append(kernel_times[0])
                times["filter+beams"].append(cpu_seconds(run(True)))
                times["filter+beams+gyro"].append(cpu_seconds(run(True, gyro=True)))
                times["adaptive"].append(cpu_seconds(run(False, "innovation")))
                times["adaptive+beams"].append(cpu_seconds(run(True, "innovation")))
                times["learned"].append(cpu_seconds(run(False, "learned")))
                times["learned+beams"].append(cpu_seconds(run(True, "learned")))
        finally:
            ins._filter = compiled
        samples = round(args.duration * config.imu.rate_hz)

    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"zigzag mission of {args.duration:g} s, {samples} IMU samples at "
          f"{config.imu.rate_hz:g} Hz, median of {args.repeats} (CPU seconds)")
    print(f"{'':15s} {'CPU s':>8s} {'us/sample':>10s} {'x real time':>12s} {'x generate':>11s}")
    for name, t in med.items():
        print(f"{name:15s} {t:8.3f} {t / samples * 1e6:10.2f} {args.duration / t:12.0f} "
              f"{t / med['generate']:11.3f}")
    print(f"target: filter >= 1000x real time per core -> "
          f"{'met' if args.duration / med['filter'] >= 1000 else 'MISSED'}")
    for name in ("adaptive", "learned"):
        slowest = max(med[name], med[f"{name}+beams"])
        print(f"target: {name} filter >= 500x real time per core -> "
              f"{'met' if args.duration / slowest >= 500 else 'MISSED'}")
    if (args.akit / "Trajectory1").is_dir():
        recorded(args.akit / "Trajectory1", args.repeats)
    else:
        print(f"recorded segment: {args.akit} absent, not measured")


def states_of(track: ins.FilterTrack) -> int:
    """How many states the filter that made ``track`` carried (its columns of states that
    were off are NaN): on a recorded DVL velocity no slow-error states (its per-axis biases
    are that error)."""
    def on(column) -> bool:
        return column is not None and bool(np.isfinite(column).any())

    return (ins.N_CORE + (ins.N_BEAM - ins.N_CORE) * on(track.beam_scale)
            + ins.N_SLOW * on(track.slow_error) + ins.N_GYRO_MATRIX * on(track.gyro_matrix))


def recorded(folder: Path, repeats: int) -> None:
    """The filter's speed on a recorded segment (the A-KIT layout's Trajectory1), started
    at its reference's first sample (position, velocity, roll, pitch and yaw)."""
    def load(kind: str) -> np.ndarray:
        return np.loadtxt(folder / f"{kind}_trajectory1.csv", delimiter=",", skiprows=1)

    imu, dvl, gt = load("IMU"), load("DVL"), load("GT")
    grade = IMU_GRADES["navigation"]
    start = ins.start_from_reference(
        imu[0, 0], np.zeros(3), gt[0, 4:7], rotation_rpy(*gt[0, 7:10]),
        angular_rate=imu[0, 4:7])
    inputs = dict(imu_time=imu[:, 0], specific_force=imu[:, 1:4], angular_rate=imu[:, 4:7],
                  dvl_time=dvl[:, 0], velocity=dvl[:, 1:4], start=start,
                  instrument=ins.Instrument(grade.accel_noise_density,
                                            grade.gyro_noise_density, 5e-4, 5e-8, 0.0, 0.0,
                                            np.full(3, 0.02)),
                  latitude_deg=float(np.degrees(gt[0, 2])))
    ins.run_arrays(**inputs)  # compiled or loaded once, untimed
    seconds = float(imu[-1, 0] - imu[0, 0])
    adaptive = ins.FilterConfig(adaptive="innovation")
    learned = ins.FilterConfig(adaptive="learned")
    gyro = ins.FilterConfig(**GYRO)
    states = {"fixed": states_of(ins.run_arrays(**inputs)),
              "fixed+gyro": states_of(ins.run_arrays(**inputs, config=gyro))}
    times: dict[str, list[float]] = {"fixed": [], "adaptive": [], "learned": [],
                                     "fixed+gyro": []}
    for _ in range(repeats):  # alternating, as above
        times["fixed"].append(cpu_seconds(lambda: ins.run_arrays(**inputs)))
        times["adaptive"].append(cpu_seconds(lambda: ins.run_arrays(**inputs,
                                                                     config=adaptive)))
        times["learned"].append(cpu_seconds(lambda: ins.run_arrays(
            **inputs, config=learned, noise_model=MODEL)))
        times["fixed+gyro"].append(cpu_seconds(lambda: ins.run_arrays(**inputs, config=gyro)))
    for name, target in (("fixed", 1000), ("adaptive", 500), ("learned", 500),
                         ("fixed+gyro", 1000)):
        t = statistics.median(times[name])
        print(f"recorded segment {folder.name} ({name}): {seconds:g} s, {len(imu)} IMU "
              f"samples, {len(dvl)} DVL pings, {states.get(name, states['fixed'])} states, "
              f"median of {repeats}: "
              f"{t:.3f} CPU s, {seconds / t:.0f}x real time per core")
        print(f"target: {name} filter >= {target}x real time per core on a recorded "
              f"segment -> {'met' if seconds / t >= target else 'MISSED'}")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
