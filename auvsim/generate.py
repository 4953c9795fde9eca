"""Simulate the missions of a config and stream them into one dataset file.

Each mission runs on its own (in a worker process when there are several) from its own
seed, and is streamed block by block into a temporary file of its own; the dataset is
then assembled in mission order by copying those groups. So memory stays flat in mission
length, and the output is the same whatever the number of workers.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import queue
import shutil
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from .config import Config, MissionConfig
from .dataset import DatasetWriter
from .errors import ConfigError, SimulationError
from .scenarios import make_scenario
from .seafloor import Seafloor
from .sensors.dvl import DvlGeometry, draw_errors, least_squares, measure, rotation_matrices
from .sensors.imu import ImuErrorModel, draw_biases
from .vehicle import Vehicle

BLOCK_SECONDS = 60.0  # simulated per call into the compiled loop, and per HDF5 append


def check_reachable(config: Config) -> None:
    """Refuse set points the vehicle cannot hold (speeds beyond 95 % of its top speed,
    leaving margin for the autopilot)."""
    vehicle = Vehicle(config.vehicle.model)
    limit = 0.95 * vehicle.max_speed
    for m in config.missions:
        if m.scenario.speed > limit:
            raise ConfigError(
                f"speed {m.scenario.speed:g} m/s is beyond what vehicle "
                f"{config.vehicle.model!r} can hold: expected at most {limit:.2f} m/s "
                f"(95 % of its {vehicle.max_speed:.2f} m/s top speed)"
            )


class MissionRun:
    """One mission: the vehicle, its scenario and its sensors, all seeded from the
    mission's seed (independent child streams for the terrain, the DVL's parameters and
    noise, and the IMU's)."""

    def __init__(self, config: Config, mission: MissionConfig) -> None:
        self.config, self.mission = config, mission
        streams = np.random.default_rng(mission.seed).spawn(5)
        self.seafloor = Seafloor(config.seafloor, rng=streams[0])
        v = config.vehicle
        self.vehicle = Vehicle(v.model, net_buoyancy=v.net_buoyancy, current_ned=v.current_ned,
                               seafloor=self.seafloor)
        dt = self.vehicle.dt
        self.decimation = round(1.0 / (config.imu.rate_hz * dt))
        if self.decimation < 1 or abs(self.decimation * config.imu.rate_hz * dt - 1.0) > 1e-9:
            raise ConfigError(f"imu.rate_hz: expected a whole divisor of the {1 / dt:g} Hz "
                              f"physics rate, got {config.imu.rate_hz!r}")
        self.dvl_every = round(config.imu.rate_hz / config.dvl.rate_hz)  # IMU samples per ping
        self.dvl = DvlGeometry.from_config(config.dvl, self.vehicle.dvl_position)
        self.dvl_errors = draw_errors(config.dvl, streams[1])
        self.dvl_noise = streams[2]
        self.imu = ImuErrorModel(config.imu, draw_biases(config.imu, streams[3]), streams[4])
        self.scenario = make_scenario(mission.scenario)

    @property
    def attrs(self) -> dict:
        c, m = self.config, self.mission
        return dict(
            scenario=m.scenario.name, seed=m.seed, duration_s=m.scenario.duration,
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

    def blocks(self) -> Iterator[dict[str, np.ndarray]]:
        """Yield the mission's arrays block by block, keyed by their dataset paths."""
        vehicle, dt = self.vehicle, self.vehicle.dt
        vehicle.reset(**self.scenario.initial_state())
        total = round(self.mission.scenario.duration / dt)
        per_block = self.decimation * self.dvl_every
        block = per_block * max(1, round(BLOCK_SECONDS / dt / per_block))
        for start in range(0, total, block):
            steps = np.arange(start, min(start + block, total))
            traj = vehicle.run(self.scenario.references(steps * dt), self.scenario.closed_loop)
            keep = slice(None, None, self.decimation)
            arrays = {
                "truth/time": steps[keep] * dt,
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
            arrays.update(self._dvl(arrays, first_imu=start // self.decimation))
            arrays["truth/altitude"] = self._altitude(arrays)
            arrays["imu/time"] = arrays["truth/time"]
            arrays["imu/specific_force"], arrays["imu/angular_rate"] = self.imu.corrupt(
                arrays["truth/specific_force"], arrays["truth/angular_rate"])
            yield arrays

    def _dvl(self, truth: dict[str, np.ndarray], first_imu: int) -> dict[str, np.ndarray]:
        """The DVL pings of a block: true velocity, beams, ray-cast ranges, measurements."""
        c = self.config.dvl
        ping = slice(None, None, self.dvl_every)
        rotation = rotation_matrices(truth["truth/quaternion"][ping])
        velocity = self.dvl.velocity(truth["truth/velocity_body"][ping],
                                     truth["truth/angular_rate"][ping])
        beams_true = velocity @ self.dvl.h.T
        origins, directions = self.dvl.rays(truth["truth/position_ned"][ping], rotation)
        reach = c.max_range * np.linalg.norm(directions[..., :2], axis=-1).max()
        self.seafloor.follow(origins[:, :2], reach=reach)
        ranges = self.seafloor.cast(self.vehicle.model, self.vehicle.data, origins, directions,
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
            "imu/index_of_dvl": first_imu + self.dvl_every * np.arange(n, dtype=np.int64),
        }

    def _altitude(self, truth: dict[str, np.ndarray]) -> np.ndarray:
        pos = truth["truth/position_ned"]
        altitude = self.seafloor.depth_at(pos[:, 0], pos[:, 1]) - pos[:, 2]
        hit = np.flatnonzero(altitude <= 0)
        if hit.size:
            k = hit[0]
            raise SimulationError(
                f"{self.mission.name}: the vehicle reached the seafloor at t = "
                f"{truth['truth/time'][k]:.1f} s (depth {pos[k, 2]:.1f} m): expected a "
                "scenario depth that stays above the terrain")
        return altitude


# Where a mission reports its progress (mission index, simulated seconds): the progress
# bar in this process, or a queue back to it from a worker process.
_report = None


def _report_to_queue(progress: queue.Queue) -> None:
    global _report
    _report = lambda index, seconds: progress.put((index, seconds))  # noqa: E731


def _write_mission(config: Config, index: int, path: str) -> None:
    """Simulate mission ``index`` into its own file (runs in a worker process)."""
    mission = config.missions[index]
    run = MissionRun(config, mission)
    with DatasetWriter(path, config_json="", compression=config.compression) as writer:
        sink = writer.mission(mission.name, run.attrs)
        for arrays in run.blocks():
            sink.append(arrays)
            if _report is not None:
                _report(index, len(arrays["truth/time"]) / config.imu.rate_hz)
        sink.flush()


def generate(config: Config, out: str | os.PathLike, *, workers: int | None = None,
             executor: cf.Executor | None = None, progress: bool = True) -> dict:
    """Simulate every mission of ``config`` into the dataset file ``out``.

    Args:
        config: what to simulate.
        out: the HDF5 file to write (replaced only once it is complete).
        workers: worker processes (default: one per core, at most one per mission); 1 runs
            in this process.
        executor: a ``concurrent.futures`` executor to use instead of the default process
            pool (it must accept this module's ``_write_mission``).
        progress: show a progress bar on a terminal.

    Returns:
        A summary: number of missions, simulated seconds, wall seconds.
    """
    check_reachable(config)
    if workers is not None and workers < 1:
        raise ConfigError(f"workers: expected at least 1, got {workers}")
    workers = min(workers or os.cpu_count() or 1, len(config.missions))
    started = time.perf_counter()
    simulated = sum(m.scenario.duration for m in config.missions)
    out = Path(out)
    with DatasetWriter(out, config_json=config.to_json(), compression=config.compression) as ds:
        parts = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
        try:
            paths = [str(parts / f"{i}.h5") for i in range(len(config.missions))]
            _run_all(config, paths, workers, executor, progress, simulated)
            for path, mission in zip(paths, config.missions, strict=True):
                with h5py.File(path, "r") as part:
                    part.copy(part[f"missions/{mission.name}"], ds.file["missions"])
        finally:
            shutil.rmtree(parts, ignore_errors=True)
    return dict(missions=len(config.missions), simulated_s=simulated,
                wall_s=time.perf_counter() - started)


def _run_all(config, paths, workers, executor, progress, simulated) -> None:
    global _report
    bar = tqdm(total=round(simulated), unit=" sim s", disable=None if progress else True,
               leave=False)
    with bar:
        if workers == 1 and executor is None:
            _report = lambda index, seconds: bar.update(round(seconds))  # noqa: E731
            try:
                for i, path in enumerate(paths):
                    bar.set_description(config.missions[i].name)
                    _write_mission(config, i, path)
            finally:
                _report = None
            return
        manager = multiprocessing.Manager()
        reports = manager.Queue()
        own = executor is None
        if own:
            executor = cf.ProcessPoolExecutor(
                max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                initializer=_report_to_queue, initargs=(reports,))
        try:
            pending = {executor.submit(_write_mission, config, i, p) for i, p in enumerate(paths)}
            while pending:
                done, pending = cf.wait(pending, timeout=0.2)
                while not reports.empty():
                    bar.update(round(reports.get()[1]))
                for future in done:
                    future.result()  # a worker's error is raised here
        finally:
            if own:
                executor.shutdown(cancel_futures=True)
            manager.shutdown()
