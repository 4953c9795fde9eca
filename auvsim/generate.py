"""Simulate the missions of a config and stream them into a dataset file."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator

import numpy as np
from tqdm import tqdm

from .config import Config, MissionConfig
from .dataset import DatasetWriter
from .errors import ConfigError
from .scenarios import make_scenario
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


def simulate(config: Config, mission: MissionConfig) -> Iterator[dict[str, np.ndarray]]:
    """Yield the mission's arrays block by block, keyed by their dataset paths.

    Truth is kept at ``config.imu.rate_hz``: every k-th physics step.
    """
    v = config.vehicle
    vehicle = Vehicle(v.model, net_buoyancy=v.net_buoyancy, current_ned=v.current_ned)
    decimation = round(1.0 / (config.imu.rate_hz * vehicle.dt))
    if decimation < 1 or abs(decimation * config.imu.rate_hz * vehicle.dt - 1.0) > 1e-9:
        raise ConfigError(
            f"imu_rate_hz: expected a whole divisor of the {1 / vehicle.dt:g} Hz physics rate, "
            f"got {config.imu.rate_hz!r}"
        )
    scenario = make_scenario(mission.scenario)
    vehicle.reset(**scenario.initial_state())
    total = round(mission.scenario.duration / vehicle.dt)
    block = decimation * max(1, round(BLOCK_SECONDS / vehicle.dt / decimation))
    for start in range(0, total, block):
        steps = np.arange(start, min(start + block, total))
        traj = vehicle.run(scenario.references(steps * vehicle.dt), scenario.closed_loop)
        keep = slice(None, None, decimation)
        yield {
            "truth/time": steps[keep] * vehicle.dt,
            "truth/position_ned": traj.position_ned[keep],
            "truth/velocity_ned": traj.velocity_ned[keep],
            "truth/velocity_body": traj.velocity_body[keep],
            "truth/quaternion": traj.quaternion[keep],
            "truth/angular_rate": traj.angular_rate[keep],
            "truth/specific_force": traj.specific_force[keep],
            "truth/altitude": config.seafloor.depth - traj.position_ned[keep, 2],
            "control/propeller_rpm": traj.actuators[keep, 0],
            "control/thrust": traj.thrust[keep],
            "control/rudder": traj.actuators[keep, 1],
            "control/stern_planes": traj.actuators[keep, 2],
        }


def generate(config: Config, out: str | os.PathLike, *, progress: bool = True) -> dict:
    """Simulate every mission of ``config`` into the dataset file ``out``.

    Returns a summary: missions, simulated seconds, wall seconds.
    """
    check_reachable(config)
    started = time.perf_counter()
    simulated = sum(m.scenario.duration for m in config.missions)
    with DatasetWriter(out, config_json=config.to_json(),
                       compression=config.compression) as writer, tqdm(
        total=round(simulated), unit=" sim s", disable=None if progress else True, leave=False
    ) as bar:
        for mission in config.missions:
            bar.set_description(mission.name)
            attrs = dict(scenario=mission.scenario.name, seed=mission.seed,
                         duration_s=mission.scenario.duration, vehicle=config.vehicle.model,
                         imu_rate_hz=config.imu.rate_hz)
            sink = writer.mission(mission.name, attrs)
            for arrays in simulate(config, mission):
                sink.append(arrays)
                bar.update(round(len(arrays["truth/time"]) / config.imu.rate_hz))
            sink.flush()
    return dict(missions=len(config.missions), simulated_s=simulated,
                wall_s=time.perf_counter() - started)
