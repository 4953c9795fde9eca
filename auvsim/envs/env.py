"""``auvsim/AUV-v0``: the torpedo AUV as a gymnasium environment, with its DVL and IMU.

## Description

The environment is thin: the physics is ``auvsim.physics.vehicle`` and the sensors are those of
``auvsim generate`` (``auvsim.runs.mission.MissionRun.measure``), stepped ``frame_skip``
physics steps at a time with the actuator commands the action gives. ``EpisodeRecorder``
writes the episodes a policy flies to a dataset (the same fields as ``auvsim generate``'s,
the depth sensor's included), and ``ManeuverPolicy`` flies any scripted manoeuvre of
``auvsim.physics.maneuvers`` through the autopilots, so a scripted or a learned policy yields
training data for BeamsNet.

## Action Space

``Box(-1, 1, (3,), float32)``, mapped to the actuators' limits (the model file's control
ranges); a non-finite or wrongly shaped action is refused (``ValueError``):

    index  actuator                     -1 .. 1 maps to
    0      propeller shaft speed        -rpm_max .. rpm_max (900 rpm on the A18-D)
    1      rudder angle (+ = starboard)  -rudder_max .. rudder_max (41 deg on the A18-D)
    2      stern-plane angle             -planes_max .. planes_max (15 deg; + = trailing edge down,
                                                           pitches the nose down)

## Observation Space

``Box(low, high, (15,), float32)`` with finite bounds; each reading saturates at its
bound, as the instrument's does:

    index   what                                    unit     bounds
    0-2     specific force, latest IMU sample, FRD   m/s^2    +-16 g (1)
            (measured, with IMU errors; 0 before
            the first step and at a terminal one)
    3-5     angular rate, latest IMU sample, FRD     rad/s    +-2000 deg/s (1)
    6-9     beam velocities of the latest DVL ping   m/s      +-10 (2)
            (measured; 0 where not valid)
    10-13   bottom lock of each beam at that ping     1 / 0    0 .. 1
    14      depth of the body origin (true)          m        0 .. 11,000 (3)

(1) The measurement ranges of a VN-100-class MEMS IMU (VectorNav VN-100 datasheet); a
navigation-grade unit's are of the same order. (2) Our assumption of a bottom-track
DVL's velocity range: no source at hand gives the Navigator's; it is over twice the
A18-D's top speed plus the strongest ocean currents (about 2.5 m/s). (3) No finite bound
comes from the vehicle (the model file carries no depth rating): the deepest ocean
(Challenger Deep, about 10,935 m) bounds it; 0 at the surface, where the episode ends.
The depth sensor's measured readings are recorded (``depth/``) but not observed.

## Rewards

0. The environment is a data and test harness with no task of its own; give it one with
a wrapper (``gymnasium.wrappers.TransformReward``) or a subclass.

## Starting State

The first mission of ``config`` sets the start: the vehicle at its scenario's depth and
heading, at (0, 0) north/east, level, moving at the scenario's speed (``start_speed``, or
``speed``) with the shaft at the rpm that holds it. Each ``reset`` draws a mission seed
from ``self.np_random``: the seafloor (if procedural), the DVL's and IMU's error draws
and their noise follow from it, so ``reset(seed=s)`` gives the same episode for the same
actions.

## Episode End

``terminated`` when the vehicle reaches the seafloor or breaks the surface; truncated
after ``max_episode_seconds``. ``info`` holds the truth at the end of the step: ``time``
(s), ``position_ned`` (m), ``velocity_ned``, ``velocity_body`` (m/s), ``quaternion``
([w, x, y, z], body -> NED), ``angular_rate`` (rad/s), ``euler`` (roll, pitch, yaw,
rad), ``altitude`` (m), and, at the latest ping, ``dvl_velocity`` (true, DVL frame, m/s)
and ``ping_time`` (s).

## Arguments

``gymnasium.make("auvsim/AUV-v0", config=None, frame_skip=10, max_episode_seconds=600.0)``:

    config               vehicle, seafloor and sensors (default: the paper-sim preset's:
                         flat floor 60 m deep, 20 deg beams at 1 Hz, navigation-grade IMU
                         at 100 Hz); its first mission's scenario sets the start
    frame_skip           physics steps per environment step, a multiple of the physics
                         steps per IMU sample (10: dt = 0.1 s)
    max_episode_seconds  truncation time, s

## Performance

A step costs one call of the compiled physics loop (``frame_skip`` MuJoCo steps; called
past numba's dispatcher, ``Vehicle.advance``) and one ``MissionRun.measure`` of its
block: the sensors' work on a few rows, compiled where numpy's cost per call was most of
it (the IMU's error terms are made ahead, 1,024 samples at a time), with the DVL's ping,
every tenth step at the defaults, the largest part. ``benchmarks/env.py`` measures it
against ``generate`` (figures in the README). ``gymnasium.make_vec("auvsim/AUV-v0",
num_envs=N)`` gives ``auvsim.envs.vector.AuvVectorEnv``, which steps slices of the envs in
worker processes and in this one over shared memory; gymnasium's ``"sync"`` and
``"async"`` modes work too.

## Version History

* v0: the first version (auvsim 0.1): finite observation bounds, and every draw of the
  policy's manoeuvre through ``np_random``, since schema v3.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np

from auvsim.checks import did_you_mean, is_finite
from auvsim.config import MAX_DURATION, Config, MissionConfig, ScenarioConfig, load_config
from auvsim.data.reader import Block
from auvsim.data.schema import phases_json
from auvsim.data.writer import DatasetWriter, check_mission_name, check_output_path
from auvsim.errors import ConfigError, SimulationError
from auvsim.physics.control import autopilot
from auvsim.physics.frames import EULER, STATE
from auvsim.physics.maneuvers import Maneuver, check_scenario, make_maneuver
from auvsim.runs.mission import MissionRun, check_reachable
from auvsim.runs.presets import PRESETS, preset

G0 = 9.80665  # m/s^2
# Observation bounds (module docstring): specific force, angular rate, beams, lock, depth.
OBSERVATION_LOW = np.array([-16 * G0] * 3 + [-np.radians(2000.0)] * 3 + [-10.0] * 4
                           + [0.0] * 4 + [0.0], dtype=np.float32)
OBSERVATION_HIGH = np.array([16 * G0] * 3 + [np.radians(2000.0)] * 3 + [10.0] * 4
                            + [1.0] * 4 + [11000.0], dtype=np.float32)
OPEN_LOOP = np.zeros(3, dtype=np.bool_)  # the action commands every actuator directly
DEPTH = STATE["position_ned"].start + 2  # the depth's place in a state row


def _layout(fields) -> tuple[dict[str, int | slice], int]:
    """The place of each (name, length) field in one row, a number at an index (length
    None) or a vector at a slice, and the row's length."""
    places, at = {}, 0
    for name, length in fields:
        places[name] = at if length is None else slice(at, at + length)
        at += 1 if length is None else length
    return places, at


# The info's fields (module docstring) and their places in one float64 row: the time,
# the state row (``Vehicle.state_row``: frames.STATE then EULER), the altitude and the
# latest ping's. The row, ``AuvEnv.info_row``, is what auvsim.envs.vector's workers share.
INFO, INFO_SIZE = _layout([("time", None),
                           *((name, part.stop - part.start)
                             for name, part in {**STATE, "euler": EULER}.items()),
                           ("altitude", None), ("dvl_velocity", 3), ("ping_time", None)])
INFO_STATE = slice(INFO["position_ned"].start, INFO["euler"].stop)


class AuvEnv(gym.Env):
    """The A18-D class AUV with a Janus DVL and an IMU (see the module docstring for the
    action and observation tables).

    Args:
        config: vehicle, seafloor and sensors: a ``Config``, a preset's name, or a TOML
            file's path (as ``auvsim generate --config`` reads it: ``auvsim.load_config``;
            default: the ``paper-sim`` preset's: flat floor 60 m deep, 20 deg beams at 1
            Hz, navigation-grade IMU at 100 Hz). Its first mission's scenario sets the
            start: speed, heading and depth.
        frame_skip: physics steps per environment step (10: dt = 0.1 s).
        max_episode_seconds: truncation time, s.
        render_mode: None, the one mode (``metadata``): it draws nothing; an episode is
            drawn by recording it (``EpisodeRecorder``) and ``auvsim plot``.
    """

    metadata = {"render_modes": []}

    def __init__(self, config: Config | None = None, *, frame_skip: int = 10,
                 max_episode_seconds: float = 600.0, render_mode: str | None = None) -> None:
        if render_mode is not None:  # gymnasium passes it; this environment draws nothing
            raise ConfigError(f"render_mode: expected None, got {render_mode!r} (AuvEnv "
                              "draws nothing: record an episode with EpisodeRecorder and "
                              "draw it with auvsim plot)")
        if isinstance(config, str) and config in PRESETS:  # a preset's name
            config = preset(config)
        elif isinstance(config, (str, os.PathLike)):  # a TOML file, as generate --config
            if not Path(config).exists():  # neither: say both what it may be
                raise ConfigError(f"config {str(config)!r}: no such file, nor a preset's name; "
                                  f"expected a TOML file's path or one of "
                                  f"{', '.join(PRESETS)}{did_you_mean(config, PRESETS)}")
            config = load_config(config)
        self.config = preset("paper-sim") if config is None else config
        if not isinstance(self.config, Config):
            raise ConfigError(f"config: expected an auvsim Config (auvsim.runs.presets.preset"
                              f"(NAME), or auvsim.load_config(FILE)), a preset's name or a TOML "
                              f"file's path, got {type(config).__name__} {config!r}")
        # numpy scalars as the Python numbers they hold (np.bool_ as a bool: refused)
        frame_skip, max_episode_seconds = (x.item() if isinstance(x, np.generic) else x
                                           for x in (frame_skip, max_episode_seconds))
        if isinstance(frame_skip, bool) or not isinstance(frame_skip, int) or frame_skip < 1:
            raise ConfigError(f"frame_skip: expected a whole number >= 1, got {frame_skip!r}")
        if not (is_finite(max_episode_seconds) and max_episode_seconds > 0):
            raise ConfigError("max_episode_seconds: expected a positive number of seconds, "
                              f"got {max_episode_seconds!r}")
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
        self.limits = np.array([h.rpm_max, h.rudder_max, h.planes_max])
        self._limits = self.limits.tolist()
        # Reused by every step: the commands held over its physics steps, and their indices
        # from the step's first.
        self._commands = np.empty((frame_skip, 3))
        self._steps = np.arange(frame_skip)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.observation_space = gym.spaces.Box(OBSERVATION_LOW, OBSERVATION_HIGH,
                                                dtype=np.float32)
        # The arrays (truth, IMU, DVL, control) of the last step, for EpisodeRecorder;
        # None before the first step and at a terminal one.
        self.last_block: dict[str, np.ndarray] | None = None
        self.step_index: int | None = None  # physics steps into the episode; None: no reset yet
        self.ended = False  # the episode ended (terminated or truncated); reset() clears it
        # The last info's values as one row (INFO), for auvsim.envs.vector; None before a reset.
        self.info_row: np.ndarray | None = None

    def _mission(self, seed: int) -> MissionRun:
        # As long as an episode may last, so the water's paths (auvsim.physics.water) cover it.
        duration = max(self.start.duration, min(self.max_episode_seconds, MAX_DURATION))
        mission = MissionConfig(name="episode", seed=seed,
                                scenario=dataclasses.replace(self.start, name="straight",
                                                             options={}, duration=duration))
        return MissionRun(self.config, mission)

    def render(self) -> None:
        """Nothing: ``render_mode`` is None (see ``metadata``)."""
        return None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if options:  # none are read: a start to change is the config's (its first mission)
            raise ConfigError(f"options: expected None, got {options!r} (the start is the "
                              "config's first mission's scenario)")
        super().reset(seed=seed)
        self.run = self._mission(seed=int(self.np_random.integers(2**63)))
        self.run.vehicle.reset(**self.run.scenario.initial_state())
        self.step_index = 0
        self.ended = False  # terminated or truncated: step() then needs a reset()
        self.last_block = None
        self.last_ping = dict(beams=np.zeros(4), valid=np.zeros(4), velocity=np.zeros(3),
                              time=math.nan)
        state = self.run.vehicle.state_row()
        return self._observation(None, state), self._info(state)

    def step(self, action):
        if self.step_index is None:
            raise gym.error.ResetNeeded("step() before reset(): expected reset() first, "
                                        "which starts an episode")
        if self.ended:
            raise gym.error.ResetNeeded("step() after the episode ended (terminated or "
                                        "truncated): expected reset() first, which starts "
                                        "the next")
        action = np.asarray(action, dtype=float)
        values = action.tolist()
        if action.shape != (3,) or not all(map(math.isfinite, values)):
            raise ValueError(f"action: expected 3 finite numbers (propeller, rudder, stern "
                             f"planes; each clipped to [-1, 1]), got {values!r}")
        # np.clip and the product by the limits in Python floats: the same IEEE arithmetic
        # on three numbers, at a fraction of numpy's cost per call.
        self._commands[:] = [min(max(a, -1.0), 1.0) * limit
                             for a, limit in zip(values, self._limits, strict=True)]
        vehicle = self.run.vehicle
        traj = vehicle.advance(self._commands, OPEN_LOOP)  # checked above
        terminated = False
        try:
            block = self.run.measure(self._steps + self.step_index, traj)
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
        self.ended = terminated or truncated
        state = vehicle.state_row()
        return self._observation(block, state), 0.0, terminated, \
            truncated and not terminated, self._info(state)

    def _observation(self, block, state: np.ndarray) -> np.ndarray:
        # Each float64 reading rounded to float32 as it is stored (as astype rounds it).
        observation = np.zeros(15, dtype=np.float32)
        if block is not None:
            observation[0:3] = block["imu/specific_force"][-1]
            observation[3:6] = block["imu/angular_rate"][-1]
        observation[6:10] = self.last_ping["beams"]
        observation[10:14] = self.last_ping["valid"]
        observation[14] = state[DEPTH]  # now, as info's position
        # Each reading saturates at its bound: np.clip's arithmetic, without its wrapper.
        np.maximum(observation, OBSERVATION_LOW, out=observation)
        return np.minimum(observation, OBSERVATION_HIGH, out=observation)

    def _info(self, state: np.ndarray) -> dict:
        """The info of ``state`` (``Vehicle.state_row``) now: views of one new row,
        ``info_row`` (``INFO``)."""
        row = self.info_row = np.empty(INFO_SIZE)
        row[INFO["time"]] = self.step_index * self.run.vehicle.dt
        row[INFO_STATE] = state
        row[INFO["altitude"]] = self.run.seafloor.altitude(state[None, STATE["position_ned"]])[0]
        row[INFO["dvl_velocity"]] = self.last_ping["velocity"]
        row[INFO["ping_time"]] = self.last_ping["time"]
        return {key: row[part] for key, part in INFO.items()}


def _one_env(env: object, who: str) -> AuvEnv:
    """The ``AuvEnv`` under ``env`` (its wrappers taken off).

    Raises:
        ConfigError: ``env`` is no single ``AuvEnv`` (a vector environment, say: its envs
            are in other processes).
    """
    unwrapped = getattr(env, "unwrapped", None)
    if not isinstance(unwrapped, AuvEnv):
        raise ConfigError(f"env: {who} takes one auvsim environment, gym.make("
                          f"'auvsim/AUV-v0') or a wrapper of it; expected an AuvEnv, got "
                          f"{type(env).__name__}")
    return unwrapped


class ManeuverPolicy:
    """A scripted manoeuvre flown through the autopilots, as a policy for ``AuvEnv``:
    ``action = policy(observation, info)``. The autopilot runs once per environment step
    (``env.dt``) instead of every physics step.

    Args:
        maneuver: a ``ScenarioConfig`` to build the manoeuvre from at each ``reset``,
            drawing what it draws (random waypoints) from the environment's
            ``np_random``; or a ready ``Maneuver``, flown as it is.
        env: the environment it will fly (for the vehicle's limits and gains).

    Call ``reset()`` after each ``env.reset()``.

    Raises:
        ConfigError: a ``ScenarioConfig`` whose speeds the vehicle cannot hold
            (``Vehicle.check_speed``) or that ``Config`` refuses in the environment's config
            (a depth below its seafloor), as ``auvsim generate`` refuses it; a
            ``maneuver`` that is neither; an ``env`` that is no single ``AuvEnv``.
    """

    def __init__(self, maneuver: Maneuver | ScenarioConfig, env: AuvEnv) -> None:
        if not isinstance(maneuver, (Maneuver, ScenarioConfig)):
            raise ConfigError(f"maneuver: expected a ScenarioConfig (ScenarioConfig(name="
                              f"'zigzag')) or a Maneuver, got {type(maneuver).__name__} "
                              f"{maneuver!r}")
        self.env = _one_env(env, "ManeuverPolicy")
        self.scenario = None if isinstance(maneuver, Maneuver) else maneuver
        self.maneuver = maneuver if isinstance(maneuver, Maneuver) else None
        self.integrals = np.zeros(3)
        if self.scenario is not None:  # refused as auvsim generate refuses it
            for speed in check_scenario(self.scenario).speeds():
                self.env.run.vehicle.check_speed(speed)
            # The config's own checks of a mission (its depth above the seafloor).
            dataclasses.replace(self.env.config,
                                missions=(MissionConfig(scenario=self.scenario),))

    def reset(self) -> None:
        if self.scenario is not None:
            rng = np.random.default_rng(self.env.np_random.integers(2**63))
            self.maneuver = make_maneuver(self.scenario, rng=rng)
        self.integrals = np.zeros(3)
        self.maneuver.reset()

    def __call__(self, observation, info: dict) -> np.ndarray:
        if self.maneuver is None:
            raise RuntimeError("ManeuverPolicy: call reset() after env.reset() first")
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
    ``path`` (the same format and fields as ``auvsim generate``'s), when it is closed
    (``close()``, or the end of a ``with`` block). The episodes are held until then; a
    recorder dropped unclosed warns that they were not written.

    Args:
        env: an ``AuvEnv`` (or a wrapper of one).
        path: the HDF5 file to write; it appears, complete, on ``close()``.
        name: missions are named ``<name>_000``, ``<name>_001``, ...

    Raises:
        ConfigError: ``path`` or ``name`` cannot be written (``check_output_path``,
            ``check_mission_name``): said now, not after the episodes have run; an
            ``env`` that is no single ``AuvEnv``.
    """

    def __init__(self, env: gym.Env, path: str | Path, *, name: str = "episode") -> None:
        _one_env(env, "EpisodeRecorder")
        check_output_path(path, "path")
        check_mission_name(f"{name}_000", "name")
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
            samples = sum(len(Block(b).truth.time) for b in self.blocks)
            # A policy flew it, not the scenario's script: no manoeuvre phases to state.
            attrs = dict(env.run.attrs, scenario="environment",
                         duration_s=samples / env.config.imu.rate_hz, phases=phases_json([]))
            self.episodes.append((attrs, self.blocks))
            self.blocks = []

    def close(self) -> None:
        self._keep()
        if self.episodes:
            env = self.env.unwrapped
            with DatasetWriter(self.path, config_json=env.config.to_json(),
                               compression=env.config.compression) as writer:
                for i, (attrs, blocks) in enumerate(self.episodes):
                    sink = writer.mission(f"{self.name}_{i:03d}", attrs, links=env.run.links)
                    for block in blocks:
                        sink.append(block)
                    sink.flush()
            self.episodes = []
        super().close()

    def __del__(self) -> None:
        held = len(getattr(self, "episodes", ())) + bool(getattr(self, "blocks", ()))
        try:
            if held:
                warnings.warn(f"EpisodeRecorder: {held} episode(s) were not written to "
                              f"{str(self.path)!r}: close() writes them (or a with block)",
                              RuntimeWarning, stacklevel=1)
        except Exception:  # noqa: BLE001  (at interpreter exit, the warning's machinery may be gone)
            pass
