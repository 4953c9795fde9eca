"""Simulate the missions of a config and stream them into one dataset file.

Each mission runs on its own (in a worker process when there are several) from its own
seed, and is streamed block by block into a temporary file of its own; the dataset is
then assembled in mission order by copying those groups. So memory stays flat in mission
length, and the output is the same whatever the number of workers.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from .config import Config, MissionConfig
from .dataset import DatasetWriter
from .errors import ConfigError, SimulationError
from .frames import rotation_matrices
from .maneuvers import check_scenario, make_maneuver
from .seafloor import Seafloor
from .sensors.dvl import DvlGeometry, draw_errors, least_squares, measure
from .sensors.imu import ImuErrorModel, draw_biases
from .vehicle import Vehicle

BLOCK_SECONDS = 60.0  # simulated per call into the compiled loop, and per HDF5 append


# The DVL fields of a block without a ping (an environment step between pings).
_NO_PINGS = {"dvl/time": np.empty(0), "dvl/velocity": np.empty((0, 3)),
             "dvl/beam_velocity_true": np.empty((0, 4)), "dvl/beam_velocity": np.empty((0, 4)),
             "dvl/beam_range": np.empty((0, 4)), "dvl/valid": np.empty((0, 4), dtype=bool),
             "dvl/velocity_ls": np.empty((0, 3)), "imu/index_of_dvl": np.empty(0, dtype=np.int64)}

MIN_SPEED = 0.5  # m/s: above the stern planes' reversal speed (models/README.md)


def check_reachable(config: Config) -> None:
    """Refuse set points the vehicle cannot hold: speeds beyond 95 % of its top speed
    (margin for the autopilot) or below ``MIN_SPEED`` (no depth control)."""
    vehicle = Vehicle(config.vehicle.model)
    limit = 0.95 * vehicle.max_speed
    for m in config.missions:
        for speed in check_scenario(m.scenario).speeds():
            if speed < MIN_SPEED:
                raise ConfigError(
                    f"speed {speed:g} m/s is too slow to hold depth: expected at least "
                    f"{MIN_SPEED:g} m/s (below about 0.4 m/s the stern planes reverse)")
            if speed > limit:
                raise ConfigError(
                    f"speed {speed:g} m/s is beyond what vehicle "
                    f"{config.vehicle.model!r} can hold: expected at most {limit:.2f} m/s "
                    f"(95 % of its {vehicle.max_speed:.2f} m/s top speed)")


def mission_streams(seed: int) -> list[np.random.Generator]:
    """A mission's independent random streams, by index: terrain, DVL parameters, DVL
    noise, IMU biases, IMU noise, manoeuvre (child streams: adding one at the end leaves
    the others unchanged)."""
    return np.random.default_rng(seed).spawn(6)


class MissionRun:
    """One mission: the vehicle, its scenario and its sensors, all seeded from the
    mission's seed (independent child streams for the terrain, the DVL's parameters and
    noise, and the IMU's)."""

    def __init__(self, config: Config, mission: MissionConfig) -> None:
        self.config, self.mission = config, mission
        streams = mission_streams(mission.seed)
        self.seafloor = Seafloor(config.seafloor, rng=streams[0])
        v = config.vehicle
        self.vehicle = Vehicle(v.model, net_buoyancy=v.net_buoyancy, current_ned=v.current_ned,
                               seafloor=self.seafloor)
        self.ray_data = self.vehicle.ray_data()
        self.seafloor.bind(self.vehicle.model, self.ray_data)
        dt = self.vehicle.dt
        self.decimation = round(1.0 / (config.imu.rate_hz * dt))
        if self.decimation < 1 or abs(self.decimation * config.imu.rate_hz * dt - 1.0) > 1e-9:
            raise ConfigError(f"imu.rate_hz: expected a whole divisor of the {1 / dt:g} Hz "
                              f"physics rate, got {config.imu.rate_hz!r}")
        self.dvl_every = round(config.imu.rate_hz / config.dvl.rate_hz)  # IMU samples per ping
        if round(mission.scenario.duration / dt) < 1:
            raise ConfigError(f"duration: expected at least the {dt:g} s physics step, got "
                              f"{mission.scenario.duration!r}")
        self.dvl = DvlGeometry.from_config(config.dvl, self.vehicle.dvl_position)
        self.dvl_errors = draw_errors(config.dvl, streams[1])
        self.dvl_noise = streams[2]
        self.imu = ImuErrorModel(config.imu, draw_biases(config.imu, streams[3]), streams[4])
        self.scenario = make_maneuver(mission.scenario, rng=streams[5])

    @property
    def attrs(self) -> dict:
        c, m = self.config, self.mission
        return dict(
            origin="simulated", scenario=m.scenario.name, seed=m.seed,
            duration_s=m.scenario.duration,
            vehicle=c.vehicle.model, imu_rate_hz=c.imu.rate_hz, dvl_rate_hz=c.dvl.rate_hz,
            beam_angle_deg=c.dvl.beam_angle_deg,
            dvl_scale_factor=self.dvl_errors.scale_factor, dvl_bias=self.dvl_errors.bias,
            dvl_noise_std=c.dvl.noise_std, dvl_min_range=c.dvl.min_range,
            dvl_max_range=c.dvl.max_range, dvl_mounting_rpy_deg=c.dvl.mounting_rpy_deg,
            dvl_position_body=self.vehicle.dvl_position,
            imu_position_body=self.vehicle.imu_position,
            imu_accel_turn_on_bias=self.imu.biases.accel,
            imu_gyro_turn_on_bias=self.imu.biases.gyro,
            imu_accel_noise_density=c.imu.accel_noise_density,
            imu_gyro_noise_density=c.imu.gyro_noise_density,
            imu_accel_bias_instability=c.imu.accel_bias_instability,
            imu_gyro_bias_instability=c.imu.gyro_bias_instability,
            imu_bias_correlation_time=c.imu.bias_correlation_time,
        )

    @property
    def rows(self) -> dict[str, int]:
        """Rows each group of the mission will have."""
        n = -(-round(self.mission.scenario.duration / self.vehicle.dt) // self.decimation)
        pings = -(-n // self.dvl_every)
        return {"truth": n, "imu": n, "control": n, "dvl": pings, "imu/index_of_dvl": pings}

    def blocks(self, stop: threading.Event | None = None) -> Iterator[dict[str, np.ndarray]]:
        """Yield the mission's arrays block by block, keyed by their dataset paths; end
        early, raising ``Cancelled``, once ``stop`` is set.

        The physics of block k + 1 runs in a background thread (the compiled loop releases
        the GIL) while block k's sensors are computed and written: the two stages take
        about the same time, so a mission uses two cores. Nothing they share is written by
        both: the physics owns ``vehicle.data``, the ray casts ``ray_data``.
        """
        vehicle, dt = self.vehicle, self.vehicle.dt
        vehicle.reset(**self.scenario.initial_state())
        self.scenario.reset()
        total = round(self.mission.scenario.duration / dt)
        per_block = self.decimation * self.dvl_every
        block = per_block * max(1, round(BLOCK_SECONDS / dt / per_block))
        starts = range(0, total, block)

        def physics(start: int):
            steps = np.arange(start, min(start + block, total))
            return steps, self.scenario.run(vehicle, steps * dt)

        with ThreadPoolExecutor(max_workers=1) as physics_thread:
            ahead = physics_thread.submit(physics, starts[0])
            for i, start in enumerate(starts):
                steps, traj = ahead.result()
                if stop is not None and stop.is_set():
                    raise Cancelled(self.mission.name)
                if i + 1 < len(starts):
                    ahead = physics_thread.submit(physics, starts[i + 1])
                yield self._sensors(steps, traj, first_imu=start // self.decimation)

    def _sensors(self, steps: np.ndarray, traj, first_imu: int) -> dict[str, np.ndarray]:
        """Truth at the IMU rate, IMU and DVL measurements of one block."""
        keep = slice(None, None, self.decimation)
        arrays = {
            "truth/time": steps[keep] * self.vehicle.dt,
            "truth/position_ned": traj.position_ned[keep],
            "truth/velocity_ned": traj.velocity_ned[keep],
            "truth/velocity_body": traj.velocity_body[keep],
            "truth/quaternion": traj.quaternion[keep],
            "truth/angular_rate": traj.angular_rate[keep],
            "truth/specific_force": traj.specific_force[keep],
            "control/propeller_rpm": traj.actuators[keep, 0],
            "control/thrust": traj.thrust[keep],
            "control/rudder": traj.actuators[keep, 1],
            "control/stern_planes": traj.actuators[keep, 2],
        }
        arrays.update(self._dvl(arrays, first_imu))
        arrays["truth/altitude"] = self._altitude(arrays)
        arrays["imu/time"] = arrays["truth/time"]
        arrays["imu/specific_force"], arrays["imu/angular_rate"] = self.imu.corrupt(
            arrays["truth/specific_force"], arrays["truth/angular_rate"])
        return arrays

    def _dvl(self, truth: dict[str, np.ndarray], first_imu: int) -> dict[str, np.ndarray]:
        """The DVL pings of a block: true velocity, beams, ray-cast ranges, measurements."""
        c = self.config.dvl
        # Pings fall on IMU samples that are whole multiples of dvl_every, wherever the
        # block starts (generate's blocks start on a ping; the environment's need not).
        offset = -first_imu % self.dvl_every
        if offset >= len(truth["truth/time"]):
            return _NO_PINGS
        ping = slice(offset, None, self.dvl_every)
        rotation = rotation_matrices(truth["truth/quaternion"][ping])
        velocity = self.dvl.velocity(truth["truth/velocity_body"][ping],
                                     truth["truth/angular_rate"][ping])
        beams_true = velocity @ self.dvl.h.T
        origins, directions = self.dvl.rays(truth["truth/position_ned"][ping], rotation)
        reach = c.max_range * np.linalg.norm(directions[..., :2], axis=-1).max()
        try:
            self.seafloor.follow(origins[:, :2], reach=reach)
        except ValueError as e:
            raise ConfigError(
                f"dvl.max_range: {c.max_range:g} m beams reach beyond the procedural terrain "
                f"window ({e}); expected a shorter max_range or a larger seafloor.cell_size"
            ) from None
        ranges = self.seafloor.cast(self.vehicle.model, self.ray_data, origins, directions,
                                    max_range=c.max_range, exclude_body=self.vehicle.body_id)
        valid = ranges >= c.min_range  # NaN (no hit within max_range) compares False
        beams = measure(beams_true, valid, errors=self.dvl_errors, noise_std=c.noise_std,
                        rng=self.dvl_noise)
        n = len(velocity)
        return {
            "dvl/time": truth["truth/time"][ping],
            "dvl/velocity": velocity,
            "dvl/beam_velocity_true": beams_true,
            "dvl/beam_velocity": beams,
            "dvl/beam_range": ranges,
            "dvl/valid": valid,
            "dvl/velocity_ls": least_squares(beams, self.dvl.h),
            "imu/index_of_dvl": first_imu + offset
            + self.dvl_every * np.arange(n, dtype=np.int64),
        }

    def _altitude(self, truth: dict[str, np.ndarray]) -> np.ndarray:
        pos, t = truth["truth/position_ned"], truth["truth/time"]
        self.seafloor.follow(pos[::100, :2], reach=self.vehicle.length)
        altitude = self.seafloor.depth_at(pos[:, 0], pos[:, 1]) - pos[:, 2]
        problems = (
            (altitude <= 0, "reached the seafloor", "a scenario depth that stays above the "
             "terrain"),
            (pos[:, 2] < 0, "broke the surface", "a speed, buoyancy and current it can hold "
             "depth in"),
            (np.isnan(altitude), "left the terrain", "a track that stays over the heightmap"),
        )
        for bad, what, expected in problems:
            if bad.any():
                k = np.flatnonzero(bad)[0]
                raise SimulationError(
                    f"{self.mission.name}: the vehicle {what} at t = {t[k]:.1f} s (north "
                    f"{pos[k, 0]:.0f} m, east {pos[k, 1]:.0f} m, depth {pos[k, 2]:.1f} m): "
                    f"expected {expected}")
        return altitude


# Where a mission reports its progress (mission index, simulated seconds): the progress
# bar in this process, or a queue back to it from a worker process.
_report = None


def _report_to_queue(progress) -> None:
    global _report
    _report = lambda index, seconds: progress.put((index, seconds))  # noqa: E731


class Cancelled(Exception):
    """A mission stopped early because another failed or the run was interrupted."""


def _stream_mission(config: Config, index: int, writer: DatasetWriter,
                    stop: threading.Event | None = None) -> None:
    """Simulate mission ``index`` and stream it into ``writer``."""
    mission = config.missions[index]
    run = MissionRun(config, mission)
    sink = writer.mission(mission.name, run.attrs, rows=run.rows)
    sink.link("imu/time", "truth/time")  # the IMU samples at the truth's times
    for arrays in run.blocks(stop):
        sink.append(arrays)
        if _report is not None:
            _report(index, len(arrays["truth/time"]) / config.imu.rate_hz)
    sink.flush()


def _write_mission(config: Config, index: int, path: str) -> None:
    """Simulate mission ``index`` into a file of its own (in a worker process)."""
    with DatasetWriter(path, config_json="", compression=config.compression) as writer:
        _stream_mission(config, index, writer)


MISSIONS_IN_FLIGHT = 2  # per process: missions simulated at once on threads


def default_workers(missions: int) -> int:
    """One worker process per two cores, at most one per mission group: a process keeps two
    missions in flight, whose physics threads release the GIL, which about fills two cores
    (measured by benchmarks/datasets.py; separate processes per mission cost more in start
    up and in copying their files together than they gain)."""
    return max(1, min(-(-missions // MISSIONS_IN_FLIGHT), (os.cpu_count() or 1) // 2))


def generate(config: Config, out: str | os.PathLike, *, workers: int | None = None,
             executor: cf.Executor | None = None, progress: bool = True) -> dict:
    """Simulate every mission of ``config`` into the dataset file ``out``.

    Args:
        config: what to simulate.
        out: the HDF5 file to write (replaced only once it is complete).
        workers: worker processes (default ``default_workers``); with 1 the missions run
            in this process, ``MISSIONS_IN_FLIGHT`` at a time on threads, and stream
            straight into ``out``.
        executor: a ``concurrent.futures`` executor to use instead of the default process
            pool (it must accept this module's ``_write_mission``).
        progress: show a progress bar on a terminal.

    Returns:
        A summary: number of missions, simulated seconds, wall seconds.
    """
    check_reachable(config)
    if workers is not None and workers < 1:
        raise ConfigError(f"workers: expected at least 1, got {workers}")
    workers = min(workers or default_workers(len(config.missions)), len(config.missions))
    started = time.perf_counter()
    simulated = sum(m.scenario.duration for m in config.missions)
    out = Path(out)
    with DatasetWriter(out, config_json=config.to_json(), compression=config.compression) as ds, \
            _progress_bar(simulated, progress) as bar:
        if workers == 1 and executor is None:
            _in_threads(config, ds)
        else:
            _in_parallel(config, ds, workers, executor, bar)
    return dict(missions=len(config.missions), simulated_s=simulated,
                wall_s=time.perf_counter() - started)


def _in_threads(config: Config, ds: DatasetWriter) -> None:
    """Missions on threads in this process, straight into the output file: their physics
    runs without the GIL, their sensors and writing take turns with it (h5py serialises
    its calls), and each mission touches only its own datasets. The first error (or an
    interrupt) stops the others at their next block."""
    stop = threading.Event()
    pool = ThreadPoolExecutor(max_workers=MISSIONS_IN_FLIGHT)
    futures = [pool.submit(_stream_mission, config, i, ds, stop)
               for i in range(len(config.missions))]
    try:
        while True:
            done, pending = cf.wait(futures, timeout=0.5, return_when=cf.FIRST_EXCEPTION)
            for future in done:
                future.result()
            if not pending:
                return
    finally:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def _progress_bar(simulated: float, progress: bool):
    global _report
    with tqdm(total=round(simulated), unit=" sim s", disable=None if progress else True,
              leave=False) as bar:
        _report = lambda index, seconds: bar.update(round(seconds))  # noqa: E731
        try:
            yield bar
        finally:
            _report = None


def _in_parallel(config: Config, ds: DatasetWriter, workers: int,
                 executor: cf.Executor | None, bar) -> None:
    """Run the missions in worker processes, each into a file of its own, and copy each
    into ``ds`` in mission order as soon as it and those before it are done."""
    parts = Path(tempfile.mkdtemp(prefix=f".{ds.path.name}.", dir=ds.path.parent))
    # forkserver: workers fork from a server that has imported auvsim (numba, MuJoCo)
    # once, so they start in milliseconds, without inheriting this process's threads.
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["auvsim.generate"])
    reports = context.SimpleQueue()  # progress from the workers, handed over at their start
    own = executor is None
    if own:
        executor = cf.ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                          initializer=_report_to_queue, initargs=(reports,))
    try:
        paths = [str(parts / f"{i}.h5") for i in range(len(config.missions))]
        futures = [executor.submit(_write_mission, config, i, p) for i, p in enumerate(paths)]
        copied = 0
        while copied < len(futures):
            done, _ = cf.wait(futures[copied:], timeout=0.5, return_when=cf.FIRST_EXCEPTION)
            for future in done:
                future.result()  # a worker's error is raised here, as soon as it happens
            while not reports.empty():
                bar.update(round(reports.get()[1]))
            while copied < len(futures) and futures[copied].done():
                with h5py.File(paths[copied], "r") as part:
                    name = config.missions[copied].name
                    part.copy(part[f"missions/{name}"], ds.file["missions"])
                os.unlink(paths[copied])
                copied += 1
    finally:
        if own:
            # Stop the workers now rather than after their missions: on an error or an
            # interrupt nothing they would still write is wanted.
            for process in list(getattr(executor, "_processes", {}).values()):
                process.terminate()
            executor.shutdown(wait=True, cancel_futures=True)
        reports.close()
        shutil.rmtree(parts, ignore_errors=True)
