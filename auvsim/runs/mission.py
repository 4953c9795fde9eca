"""One mission, end to end: vehicle blocks -> truth -> sensors -> dataset fields.

``MissionRun`` builds a mission's seafloor, vehicle, manoeuvre and sensors from its seed
(the named streams of ``auvsim.data.streams``), flies it block by block (``blocks``) and turns
each block of physics into the mission's fields (``measure``): the truth and controls at
the IMU rate, then every sensor plugin of ``auvsim.sensors`` in name order, then the
altitude over the seafloor. ``auvsim generate`` streams ``blocks`` into a file; the
gymnasium environment calls ``measure`` on each step's block.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from auvsim.config import Config, MissionConfig
from auvsim.data.schema import core_block, mission_attrs, phases_json
from auvsim.data.streams import mission_streams
from auvsim.errors import ConfigError, SimulationError
from auvsim.physics.earth import normal_gravity, specific_force_on_earth
from auvsim.physics.frames import rotation_matrices
from auvsim.physics.maneuvers import check_scenario, make_maneuver
from auvsim.physics.vehicle import Trajectory, Vehicle
from auvsim.physics.water import Disturbance, Water
from auvsim.sensors import Platform, Truth, registry
from auvsim.world.seafloor import Seafloor

BLOCK_SECONDS = 60.0  # simulated per call into the compiled loop, and per HDF5 append


@numba.njit(cache=True)
def _clear(altitude, position_ned):
    """Whether every row is above the seafloor and below the surface (altitude > 0,
    depth >= 0; a NaN is neither): one compiled pass, as the environment asks every step."""
    for k in range(altitude.shape[0]):
        if not (altitude[k] > 0 and position_ned[k, 2] >= 0):
            return False
    return True


class Cancelled(Exception):
    """A mission stopped early because another failed or the run was interrupted."""


def check_reachable(config: Config) -> None:
    """Refuse, before anything runs, a mission whose manoeuvre asks its vehicle for a
    speed it cannot hold (``Vehicle.check_speed``)."""
    vehicle = Vehicle(config.vehicle.model, net_buoyancy=config.vehicle.net_buoyancy)
    for m in config.missions:
        for speed in check_scenario(m.scenario).speeds():
            vehicle.check_speed(speed)


class MissionRun:
    """One mission: the vehicle, its scenario and its sensors, all seeded from the
    mission's seed.

    Args:
        config: the dataset's config.
        mission: which of its missions.
    """

    def __init__(self, config: Config, mission: MissionConfig) -> None:
        self.config, self.mission = config, mission
        streams = mission_streams(mission.seed)
        self.seafloor = Seafloor(config.seafloor, rng=streams["terrain"],
                                 location=config.location)
        v = config.vehicle
        # The water is a pure function of time and place from here on (auvsim.physics.water).
        self.water = Water(config.water, streams["water"], duration=mission.scenario.duration,
                           constant_ned=v.current_ned, water_depth=config.seafloor.depth)
        self.vehicle = Vehicle(v.model, net_buoyancy=v.net_buoyancy, current_ned=v.current_ned,
                               seafloor=self.seafloor, water=self.water,
                               disturbance=Disturbance(config.water, streams["disturbance"]),
                               hold_rpm=v.speed_control == "rpm",
                               full_rudder_turns=v.heading_control == "full-rudder-turns",
                               imu_position=v.imu_position, dvl_position=v.dvl_position)
        self.ray_data = self.vehicle.ray_data()
        self.seafloor.bind(self.vehicle.model, self.ray_data)
        dt = self.vehicle.dt
        self.decimation = round(1.0 / (config.imu.rate_hz * dt))  # physics steps per sample
        if self.decimation < 1 or abs(self.decimation * config.imu.rate_hz * dt - 1.0) > 1e-9:
            raise ConfigError(f"imu.rate_hz: expected a whole divisor of the {1 / dt:g} Hz "
                              f"physics rate, got {config.imu.rate_hz!r}")
        if round(mission.scenario.duration / dt) < 1:
            raise ConfigError(f"duration: expected at least the {dt:g} s physics step, got "
                              f"{mission.scenario.duration!r}")
        platform = Platform(self.vehicle, self.seafloor, self.ray_data, self.water)
        # A sensor gets its parameter stream and any it declares after its noise stream.
        self.sensors = [sensor(config, platform, streams[sensor.streams[0]],
                               *(streams[name] for name in sensor.streams[2:]))
                        for sensor in registry().values()]
        self.noise = {s.name: streams[s.streams[1]] for s in self.sensors}
        self.scenario = make_maneuver(mission.scenario, rng=streams["maneuver"])

    @property
    def attrs(self) -> dict:
        """The mission's attributes (``auvsim.data.schema.mission_attrs``)."""
        m = self.mission
        sensed = {}
        for sensor in self.sensors:
            sensed.update(sensor.attrs())
        # The model's g (opt.gravity points down: auvsim.physics.hydro checks it).
        gravity = self.vehicle.hydro.gravity
        place = self.config.location
        if place.given:  # the Earth's, at the origin on the surface (LocationConfig)
            sensed.update(latitude_deg=place.latitude_deg, longitude_deg=place.longitude_deg)
            gravity = normal_gravity(place.latitude_deg, 0.0)
        return mission_attrs(origin="simulated", scenario=m.scenario.name, seed=m.seed,
                             duration_s=m.scenario.duration, vehicle=self.config.vehicle.model,
                             water_surface_speed=self.water.surface_speed,
                             water_direction_deg=self.water.direction_deg,
                             gravity=gravity, phases=phases_json(self.scenario.phases()),
                             **sensed)

    @property
    def samples(self) -> int:
        """IMU (truth) samples of the whole mission."""
        steps = round(self.mission.scenario.duration / self.vehicle.dt)
        return -(-steps // self.decimation)

    @property
    def rows(self) -> dict[str, int]:
        """Rows of each clock of the mission's fields (``truth``, ``control`` and each
        sensor's)."""
        n = self.samples
        rows = {"truth": n, "control": n}
        for sensor in self.sensors:
            rows.update(sensor.rows(n))
        return rows

    @property
    def links(self) -> dict[str, str]:
        """Fields that are hard links to another (the IMU's time is the truth's)."""
        return {k: v for sensor in self.sensors for k, v in sensor.links.items()}

    def blocks(self, stop: Callable[[], bool] = lambda: False
               ) -> Iterator[dict[str, np.ndarray]]:
        """Yield the mission's fields block by block, keyed by their dataset paths; end
        early, raising ``Cancelled``, once ``stop()`` says so (it is asked before each).

        The physics of block k + 1 runs in a background thread (the compiled loop releases
        the GIL) while block k's sensors are computed and written: the two stages take
        about the same time, so a mission uses two cores. Nothing they share is written by
        both: the physics owns ``vehicle.data``, the ray casts ``ray_data``.
        """
        vehicle, dt = self.vehicle, self.vehicle.dt
        vehicle.reset(**self.scenario.initial_state())
        self.scenario.reset()
        total = round(self.mission.scenario.duration / dt)
        per_block = self.decimation * math.lcm(*(s.every(self.config) for s in self.sensors))
        block = per_block * max(1, round(BLOCK_SECONDS / dt / per_block))
        starts = range(0, total, block)

        def physics(start: int):
            steps = np.arange(start, min(start + block, total))
            try:
                return steps, self.scenario.run(vehicle, steps * dt)
            except SimulationError as e:
                raise SimulationError(f"{self.mission.name}: between t = {steps[0] * dt:.1f} "
                                      f"and {steps[-1] * dt:.1f} s, {e}") from None

        with ThreadPoolExecutor(max_workers=1) as physics_thread:
            ahead = physics_thread.submit(physics, starts[0])
            for i in range(len(starts)):
                steps, traj = ahead.result()
                if stop():
                    raise Cancelled(self.mission.name)
                if i + 1 < len(starts):
                    ahead = physics_thread.submit(physics, starts[i + 1])
                yield self.measure(steps, traj)

    def measure(self, steps: np.ndarray, traj: Trajectory) -> dict[str, np.ndarray]:
        """The mission's fields for one block of physics: truth and controls at the IMU
        rate, every sensor's measurements, and the altitude.

        Args:
            steps: (K,) global indices of the block's physics steps; the block starts on
                an IMU sample (a multiple of ``decimation``).
            traj: the vehicle's ``Trajectory`` over those steps.

        Raises:
            SimulationError: the vehicle reached the seafloor, broke the surface or left
                the terrain during the block.
        """
        if self.decimation > 1:  # else every row is a sample, and views would cost more
            traj = Trajectory(*(rows[::self.decimation] for rows in traj))
            steps = steps[::self.decimation]
        truth = Truth(int(steps[0]) // self.decimation, steps * self.vehicle.dt,
                      traj.position_ned, traj.velocity_ned, traj.velocity_body,
                      traj.quaternion, traj.angular_rate, traj.specific_force,
                      traj.current_ned, traj.velocity_water_body)
        if self.config.location.given:
            truth = truth._replace(specific_force=self._on_earth(truth))
        sensed = {}
        for sensor in self.sensors:
            sensed.update(sensor.measure(truth, self.noise[sensor.name]))
        # After the DVL: its ray casts move the terrain window first, as they always have.
        altitude = self._altitude(truth)
        actuators = traj.actuators
        return {**core_block(truth, propeller_rpm=actuators[:, 0], thrust=traj.thrust,
                             rudder=actuators[:, 1], stern_planes=actuators[:, 2],
                             altitude=altitude), **sensed}

    def _on_earth(self, truth: Truth) -> np.ndarray:
        """The truth's specific force on the rotating Earth at the config's origin: what
        an ideal accelerometer at the IMU site reads there (``LocationConfig``), from the
        flat world's (``auvsim.physics.earth.specific_force_on_earth``)."""
        rot = rotation_matrices(truth.quaternion)
        imu = self.vehicle.imu_position
        v_imu = truth.velocity_ned + np.einsum("nij,nj->ni", rot,
                                               np.cross(truth.angular_rate, imu))
        return specific_force_on_earth(
            truth.specific_force, rot, v_imu, truth.position_ned[:, 2] + rot[:, 2] @ imu,
            latitude_deg=self.config.location.latitude_deg,
            flat_gravity=self.vehicle.hydro.gravity)

    def _altitude(self, truth: Truth) -> np.ndarray:
        pos, t = truth.position_ned, truth.time
        try:
            self.seafloor.follow(pos[::100, :2], reach=self.vehicle.length)
        except ValueError as e:
            raise SimulationError(
                f"{self.mission.name}: the vehicle outran the procedural terrain window "
                f"between t = {t[0]:.1f} and {t[-1]:.1f} s ({e}); expected a larger "
                "seafloor.cell_size") from None
        altitude = self.seafloor.altitude(pos)
        if _clear(altitude, pos):  # the usual case
            return altitude
        problems = (
            (altitude <= 0, "reached the seafloor", "a scenario depth that stays above the "
             "terrain"),
            (pos[:, 2] < 0, "broke the surface", "a set depth well under the surface (the "
             "model has no free surface) and a speed, buoyancy and current it can hold depth "
             "in"),
            (np.isnan(altitude), "left the terrain", "a track that stays over the heightmap "
             "(a grid's: seafloor.extent around the location)"),
        )
        for bad, what, expected in problems:
            if bad.any():
                k = np.flatnonzero(bad)[0]
                raise SimulationError(
                    f"{self.mission.name}: the vehicle {what} at t = {t[k]:.1f} s (north "
                    f"{pos[k, 0]:.0f} m, east {pos[k, 1]:.0f} m, depth {pos[k, 2]:.1f} m): "
                    f"expected {expected}")
        return altitude
