"""``auvsim/AUV-v0``: the torpedo AUV as a gymnasium environment, with its DVL and IMU.

The environment is thin: the physics is ``auvsim.vehicle`` and the sensors are those of
``auvsim generate`` (``MissionRun._sensors``), stepped ``frame_skip`` physics steps at a
time with the actuator commands the action gives. ``EpisodeRecorder`` writes the episodes
a policy flies to a schema-v2 dataset, and ``ManeuverPolicy`` flies any scripted manoeuvre
of ``auvsim.maneuvers`` through the autopilots, so a scripted or a learned policy yields
training data for BeamsNet.

Action, ``Box(-1, 1, (3,), float32)``, mapped to the actuators' limits (the model file's
control ranges):

    index  actuator                     -1 .. 1 maps to
    0      propeller shaft speed        -rpm_max .. rpm_max (900 rpm on the A18-D)
    1      rudder angle (+ = starboard)  -fin_max .. fin_max (15 deg)
    2      stern-plane angle             -fin_max .. fin_max (+ = trailing edge down,
                                                           pitches the nose up)

Observation, ``Box(-inf, inf, (15,), float32)``:

    index   what                                    unit
    0-2     specific force, latest IMU sample, FRD   m/s^2 (measured, with IMU errors;
                                                        0 before the first step and at
                                                        a terminal one)
    3-5     angular rate, latest IMU sample, FRD     rad/s (measured)
    6-9     beam velocities of the latest DVL ping   m/s (measured; 0 where not valid)
    10-13   bottom lock of each beam at that ping     1 valid, 0 not
    14      depth of the body origin                 m (true: a pressure sensor's error
                                                        is not modelled)

Reward: 0. The environment is a data and test harness with no task of its own; give it
one with a wrapper (``gymnasium.wrappers.TransformReward``) or a subclass.

``info``: the truth at the end of the step: ``time`` (s), ``position_ned`` (m),
``velocity_ned``, ``velocity_body`` (m/s), ``quaternion`` ([w, x, y, z], body -> NED),
``angular_rate`` (rad/s), ``euler`` (roll, pitch, yaw, rad), ``altitude`` (m), and, at the
latest ping, ``dvl_velocity`` (true, DVL frame, m/s) and ``ping_time`` (s).

Episodes end (``terminated``) when the vehicle reaches the seafloor or breaks the surface,
and are truncated after ``max_episode_seconds``. ``dt = timestep x frame_skip``. All
randomness (the seafloor, the DVL's and IMU's error draws, their noise) comes from
``self.np_random``: ``reset(seed=s)`` gives the same episode for the same actions.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import gymnasium as gym
import numpy as np

from .config import Config, MissionConfig, ScenarioConfig
from .control import autopilot
from .dataset import DatasetWriter
from .errors import ConfigError, SimulationError
from .frames import euler_angles
from .generate import MissionRun, check_reachable
from .maneuvers import Maneuver, make_maneuver
from .presets import preset


class AuvEnv(gym.Env):
    """The A18-D class AUV with a Janus DVL and an IMU (see the module docstring for the
    action and observation tables).

    Args:
        config: vehicle, seafloor and sensors (default: the ``paper-sim`` preset's: flat
            floor 60 m deep, 20 deg beams at 1 Hz, navigation-grade IMU at 100 Hz). Its
            first mission's scenario sets the start: speed, heading and depth.
        frame_skip: physics steps per environment step (10: dt = 0.1 s).
        max_episode_seconds: truncation time, s.
    """

    metadata = {"render_modes": []}

    def __init__(self, config: Config | None = None, *, frame_skip: int = 10,
                 max_episode_seconds: float = 600.0) -> None:
        self.config = preset("paper-sim") if config is None else config
        if not isinstance(frame_skip, int) or frame_skip < 1:
            raise ConfigError(f"frame_skip: expected a whole number >= 1, got {frame_skip!r}")
        self.start = self.config.missions[0].scenario
        check_reachable(dataclasses.replace(self.config, missions=self.config.missions[:1]))
        self.frame_skip = frame_skip
        self.max_episode_seconds = float(max_episode_seconds)
        self.run = self._mission(seed=0)
        self.dt = self.run.vehicle.dt * frame_skip
        if frame_skip % self.run.decimation:
            raise ConfigError(f"frame_skip: expected a multiple of {self.run.decimation} "
                              "physics steps per IMU sample")
        h = self.run.vehicle.hydro
        self.limits = np.array([h.rpm_max, h.fin_max, h.fin_max])
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, (15,), np.float32)
        # The arrays (truth, IMU, DVL, control) of the last step, for EpisodeRecorder;
        # None before the first step and at a terminal one.
        self.last_block: dict[str, np.ndarray] | None = None

    def _mission(self, seed: int) -> MissionRun:
        mission = MissionConfig(name="episode", seed=seed,
                                scenario=dataclasses.replace(self.start, name="straight",
                                                             options={}))
        return MissionRun(self.config, mission)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.run = self._mission(seed=int(self.np_random.integers(2**63)))
        self.run.vehicle.reset(**self.run.scenario.initial_state())
        self.step_index = 0
        self.last_block = None
        self.last_ping = dict(beams=np.zeros(4), valid=np.zeros(4), velocity=np.zeros(3),
                              time=math.nan)
        return self._observation(None), self._info()

    def step(self, action):
        command = np.clip(np.asarray(action, dtype=float), -1.0, 1.0) * self.limits
        vehicle = self.run.vehicle
        traj = vehicle.run(np.tile(command, (self.frame_skip, 1)), (False, False, False))
        steps = np.arange(self.step_index, self.step_index + self.frame_skip)
        terminated = False
        try:
            block = self.run._sensors(steps, traj, first_imu=self.step_index //
                                      self.run.decimation)
        except SimulationError:
            terminated, block = True, None  # reached the seafloor or broke the surface
        self.step_index += self.frame_skip
        self.last_block = block
        if block is not None and len(block["dvl/time"]):
            self.last_ping = dict(beams=np.nan_to_num(block["dvl/beam_velocity"][-1]),
                                  valid=block["dvl/valid"][-1].astype(float),
                                  velocity=block["dvl/velocity"][-1],
                                  time=float(block["dvl/time"][-1]))
        truncated = self.step_index * vehicle.dt >= self.max_episode_seconds - 1e-9
        return self._observation(block), 0.0, terminated, truncated and not terminated, \
            self._info()

    def _observation(self, block) -> np.ndarray:
        imu = np.zeros(6) if block is None else np.r_[block["imu/specific_force"][-1],
                                                      block["imu/angular_rate"][-1]]
        depth = self.run.vehicle.state()["position_ned"][2]  # now, as info's position
        ping = self.last_ping
        return np.r_[imu, ping["beams"], ping["valid"], depth].astype(np.float32)

    def _info(self) -> dict:
        state = self.run.vehicle.state()
        altitude = float(self.run.seafloor.depth_at(state["position_ned"][:1],
                                                    state["position_ned"][1:2])[0]
                         - state["position_ned"][2])
        return dict(time=self.step_index * self.run.vehicle.dt, **state,
                    euler=euler_angles(state["quaternion"]), altitude=altitude,
                    dvl_velocity=self.last_ping["velocity"].copy(),
                    ping_time=self.last_ping["time"])


class ManeuverPolicy:
    """A scripted manoeuvre flown through the autopilots, as a policy for ``AuvEnv``:
    ``action = policy(observation, info)``. The autopilot runs once per environment step
    (``env.dt``) instead of every physics step.

    Args:
        maneuver: a ``Maneuver``, or a ``ScenarioConfig`` to build one from.
        env: the environment it will fly (for the vehicle's limits and gains).
    """

    def __init__(self, maneuver: Maneuver | ScenarioConfig, env: AuvEnv) -> None:
        self.maneuver = maneuver if isinstance(maneuver, Maneuver) else make_maneuver(maneuver)
        self.env = env.unwrapped
        self.reset()

    def reset(self) -> None:
        self.integrals = np.zeros(3)
        self.maneuver.reset()

    def __call__(self, observation, info: dict) -> np.ndarray:
        env = self.env
        vehicle = env.run.vehicle
        roll, pitch, yaw = info["euler"]
        reference, closed = self.maneuver.command(info["time"], yaw)
        command = autopilot(vehicle.hydro, vehicle.gains, np.asarray(reference, dtype=float),
                            np.asarray(closed, dtype=np.bool_), self.integrals,
                            info["velocity_body"][0], info["position_ned"][2],
                            info["velocity_ned"][2], pitch, yaw, info["angular_rate"][1],
                            info["angular_rate"][2], env.dt)
        return np.clip(command / env.limits, -1.0, 1.0).astype(np.float32)


class EpisodeRecorder(gym.Wrapper):
    """Writes every episode the wrapped ``AuvEnv`` runs as a mission of a dataset at
    ``path`` (schema v2, the same fields as ``auvsim generate``'s), when it is closed.

    Args:
        env: an ``AuvEnv`` (or a wrapper of one).
        path: the HDF5 file to write; it appears, complete, on ``close()``.
        name: missions are named ``<name>_000``, ``<name>_001``, ...
    """

    def __init__(self, env: gym.Env, path: str | Path, *, name: str = "episode") -> None:
        super().__init__(env)
        self.path = Path(path)
        self.name = name
        self.episodes: list[tuple[dict, list[dict]]] = []
        self.blocks: list[dict[str, np.ndarray]] = []  # the current episode's steps

    def reset(self, **kwargs):
        self._keep()
        return self.env.reset(**kwargs)

    def step(self, action):
        out = self.env.step(action)
        block = self.env.unwrapped.last_block
        if block is not None:
            self.blocks.append(block)
        return out

    def _keep(self) -> None:
        """Set the finished (or interrupted) episode aside for writing."""
        if self.blocks:
            env = self.env.unwrapped
            samples = sum(len(b["truth/time"]) for b in self.blocks)
            attrs = dict(env.run.attrs, scenario="environment",
                         duration_s=samples / env.config.imu.rate_hz)
            self.episodes.append((attrs, self.blocks))
            self.blocks = []

    def close(self) -> None:
        self._keep()
        if self.episodes:
            env = self.env.unwrapped
            with DatasetWriter(self.path, config_json=env.config.to_json(),
                               compression=env.config.compression) as writer:
                for i, (attrs, blocks) in enumerate(self.episodes):
                    sink = writer.mission(f"{self.name}_{i:03d}", attrs)
                    sink.link("imu/time", "truth/time")
                    for block in blocks:
                        sink.append(block)
                    sink.flush()
            self.episodes = []
        super().close()
