"""The vehicle: a MuJoCo model plus the hydrodynamic force model, stepped in compiled code.

``Vehicle.run`` advances the simulation by N physics steps. Each step (in ``_run``, compiled
with numba) reads the state from MuJoCo, runs the autopilot and servos, looks up the current
at the vehicle and the motion disturbances now (``auvsim.physics.water``), computes the water
forces (``auvsim.physics.hydro.water_wrench``), records the true state, and calls MuJoCo's own
``mj_step`` through its C symbol, so no Python runs inside the loop.
"""

from __future__ import annotations

import collections
import math
from pathlib import Path
from typing import NamedTuple

import llvmlite.binding as llvm
import mujoco
import numba
import numpy as np
from numba import types

from auvsim.config import VehicleConfig
from auvsim.errors import ConfigError, SimulationError
from auvsim.physics.control import Gains, autopilot_into, feedforward_rpm, max_speed, servo
from auvsim.physics.frames import (
    FLIP,
    mujoco_from_ned,
    ned_from_mujoco,
    quat_to_rot,
    quaternion_from_euler,
    rot_into,
    state_row,
    yaw_of,
)
from auvsim.physics.hydro import (
    ACTUATORS,
    Hydro,
    add,
    cross,
    load_hydro,
    mat3_vec,
    mat3t_vec,
    sub,
    water_wrench_into,
)
from auvsim.physics.water import (
    CHANNELS,
    Disturbance,
    Water,
    current_at,
    disturbance_at,
    still_water,
)

MODEL_DIR = Path(__file__).resolve().parents[2] / "models"
VEHICLES = ("auv", "remus100")

# mj_step is linked by symbol name, which keeps the compiled kernel cacheable on disk.
_LIB = next(p for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll")
            for p in Path(mujoco.__file__).parent.glob(pattern))
llvm.load_library_permanently(str(_LIB))
_mj_step = types.ExternalFunction("mj_step", types.void(types.voidptr, types.voidptr))

MIN_SPEED = 0.5  # m/s: above the stern planes' reversal speed (models/README.md)
SPEED_MARGIN = 0.95  # set points up to this fraction of top speed: margin for the autopilot

# MuJoCo reports an unstable simulation (a NaN or huge acceleration) as a warning, writes
# it to MUJOCO_LOG.TXT in the working directory and resets the state. Here the warning is
# kept instead, and ``Vehicle.run`` stops the mission with it (see ``_check_stable``).
_warnings: collections.deque[str] = collections.deque(maxlen=8)
mujoco.set_mju_user_warning(_warnings.append)


# MuJoCo integrates the rigid body under its weight and the wrench auvsim applies, nothing
# else (auvsim.physics.hydro). The model's actuators only carry the control ranges (gain 0): the
# vehicle reads them and compiles its model without them (``_without_actuators``), and
# the free body has no springs or dampers, so MuJoCo's passes for those are switched off.
# They added only zeros (the data stay the same bit for bit); the passes cost a sixth of
# a physics step, the actuators' transmissions (site Jacobians) a tenth.
_UNUSED = (mujoco.mjtDisableBit.mjDSBL_ACTUATION | mujoco.mjtDisableBit.mjDSBL_SPRING
           | mujoco.mjtDisableBit.mjDSBL_DAMPER | mujoco.mjtDisableBit.mjDSBL_EULERDAMP)

_NO_ROWS = np.zeros((2, CHANNELS))  # the disturbance table when there is none
# MuJoCo's warnings of an unstable simulation (BADQPOS, BADQVEL, BADQACC: neighbours in
# mjtWarning), as a slice of ``MjData.warning``.
_UNSTABLE = slice(int(mujoco.mjtWarning.mjWARN_BADQPOS),
                  int(mujoco.mjtWarning.mjWARN_BADQACC) + 1)


def _without_actuators(spec: mujoco.MjSpec) -> dict[str, np.ndarray]:
    """Take every actuator out of ``spec``, and return the vehicle's actuators' control
    ranges (2,), by name (``auvsim.physics.hydro.ACTUATORS``), to check and use in their stead.

    Raises:
        ValueError: one of the vehicle's actuators is missing.
    """
    found = {a.name: np.array(a.ctrlrange, dtype=float) for a in spec.actuators}
    missing = [name for name in ACTUATORS if name not in found]
    if missing:
        raise ValueError(f"no actuator named {missing[0]!r}; expected {', '.join(ACTUATORS)}")
    for actuator in list(spec.actuators):
        spec.delete(actuator)
    return {name: found[name] for name in ACTUATORS}


def _array_kind(a: np.ndarray) -> tuple:
    """What numba's type of an array argument is made of: dtype, dimensions, layout
    (C, F or any), read-only or not, aligned or not."""
    flags = a.flags
    return (a.dtype, a.ndim, flags.c_contiguous, flags.f_contiguous, flags.writeable,
            flags.aligned)


class Trajectory(NamedTuple):
    """True state at every physics step, NED/FRD (see the package docstring). Shapes (N, .)."""

    position_ned: np.ndarray  # (N, 3) m, body origin
    velocity_ned: np.ndarray  # (N, 3) m/s
    velocity_body: np.ndarray  # (N, 3) m/s
    quaternion: np.ndarray  # (N, 4) body -> NED, [w, x, y, z]
    angular_rate: np.ndarray  # (N, 3) rad/s, body
    specific_force: np.ndarray  # (N, 3) m/s^2, body, at the IMU site
    actuators: np.ndarray  # (N, 3) shaft rpm, rudder and stern-plane angles (rad)
    thrust: np.ndarray  # (N,) N, propeller thrust
    current_ned: np.ndarray  # (N, 3) m/s, NED, the current at the body origin
    velocity_water_body: np.ndarray  # (N, 3) m/s, body, velocity through the water there

    @classmethod
    def empty(cls, n: int) -> Trajectory:
        return cls(np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 4)),
                   np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty(n),
                   np.empty((n, 3)), np.empty((n, 3)))


def model_path(vehicle: str) -> Path:
    """Path of a vehicle model: a name from ``VEHICLES`` or a path to an MJCF file."""
    if vehicle in VEHICLES:
        return MODEL_DIR / f"{vehicle}.xml"
    path = Path(vehicle)
    if path.suffix == ".xml" and path.is_file():
        return path
    raise ConfigError(
        f"unknown vehicle {vehicle!r}: expected one of {', '.join(VEHICLES)} "
        "or a path to an .xml model"
    )


# nogil: the sensors of one block are computed while the physics of the next one runs in
# another thread (auvsim.runs.mission.MissionRun.blocks).
@numba.njit(cache=True, nogil=True)
def _run(mptr, dptr, qpos, qvel, qfrc, h, g, references, closed_loop, actuators, integrals,
         current_ned, water, disturbed, rows, base, step0, imu_position, dt, out):
    flip = np.array([1.0, -1.0, -1.0])
    nu = np.zeros(6)
    quat = np.zeros(4)
    reached = np.zeros(3)  # the actuators as the water meets them: with their jitter
    jolt = np.zeros(CHANNELS)  # the disturbance now: wrench (6), then actuator jitter (3)
    # Each step's arrays, made once: a step allocates nothing.
    rot, cmd = np.empty((3, 3)), np.empty(3)
    tau, nu_dot, applied = np.empty(6), np.empty(6), np.empty(6)
    imu = (imu_position[0], imu_position[1], imu_position[2])
    for k in range(references.shape[0]):
        # MuJoCo (NWU world, FLU body) -> NED / FRD.
        quat[0] = qpos[3]
        for i in range(3):
            quat[1 + i] = qpos[4 + i] * flip[i]
        rot_into(quat, rot)
        v_ned = (qvel[0], -qvel[1], -qvel[2])
        v_body = mat3t_vec(rot, v_ned)
        for i in range(3):
            nu[i] = v_body[i]
            nu[3 + i] = qvel[3 + i] * flip[i]
        w = (nu[3], nu[4], nu[5])

        # The water at the vehicle now (auvsim.physics.water): without a moving water exactly
        # the constant current, as before it existed.
        t = (step0 + k) * dt
        if water.active:
            c = current_at(water, t, qpos[0], -qpos[1], -qpos[2])
            cur = (current_ned[0] + c[0], current_ned[1] + c[1], current_ned[2] + c[2])
        else:
            cur = (current_ned[0], current_ned[1], current_ned[2])
        if disturbed:
            disturbance_at(rows, base, t, jolt)
            # Jitter about the angle reached, within the fins' and shaft's limits.
            reached[0] = min(max(actuators[0] + jolt[6], -h.rpm_max), h.rpm_max)
            for i in (1, 2):
                limit = h.rudder_max if i == 1 else h.planes_max
                reached[i] = min(max(actuators[i] + jolt[6 + i], -limit), limit)
            thrust = water_wrench_into(h, nu, rot, reached, cur, jolt[:6], tau, nu_dot,
                                       applied)
        else:
            for i in range(3):
                reached[i] = actuators[i]
            thrust = water_wrench_into(h, nu, rot, actuators, cur, None, tau, nu_dot,
                                       applied)
        v_water = sub(v_body, mat3t_vec(rot, cur))

        # Record the state at the start of the step, with its acceleration.
        alpha = (nu_dot[3], nu_dot[4], nu_dot[5])
        lever = add(cross(alpha, imu), cross(w, cross(w, imu)))
        a_imu = add(add((nu_dot[0], nu_dot[1], nu_dot[2]), cross(w, v_body)), lever)
        for i in range(3):
            out.position_ned[k, i] = qpos[i] * flip[i]
            out.velocity_ned[k, i] = v_ned[i]
            out.velocity_body[k, i] = nu[i]
            out.angular_rate[k, i] = w[i]
            out.specific_force[k, i] = a_imu[i] - h.gravity * rot[2, i]
            out.actuators[k, i] = reached[i]
            out.current_ned[k, i] = cur[i]
            out.velocity_water_body[k, i] = v_water[i]
        for i in range(4):
            out.quaternion[k, i] = quat[i]
        out.thrust[k] = thrust

        # Autopilot and servos act on the next step. The speed loop holds the surge speed
        # through the water, as a propeller's speed control does: the stern planes and the
        # rudder need that flow, and in a following current as strong as the set speed a
        # hold over ground would stall them (in still water the two are the same numbers).
        yaw = math.atan2(rot[1, 0], rot[0, 0])
        pitch = -math.asin(min(max(rot[2, 0], -1.0), 1.0))
        for i in range(3):
            cmd[i] = references[k, i]
        autopilot_into(h, g, references[k], closed_loop, integrals, v_water[0], -qpos[2],
                       v_ned[2], pitch, yaw, w[1], w[2], dt, cmd)

        # The wrench goes to MuJoCo in its own coordinates: world force, body torque.
        f_ned = mat3_vec(rot, (applied[0], applied[1], applied[2]))
        for i in range(3):
            qfrc[i] = f_ned[i] * flip[i]
            qfrc[3 + i] = applied[3 + i] * flip[i]
        _mj_step(mptr, dptr)
        servo(h, actuators, cmd, dt)


def _sensor_position(model: mujoco.MjModel, site: str, position) -> np.ndarray:
    """Where a sensor sits, m, FRD: ``position`` (checked), or the model's site of that
    name when None."""
    if position is None:
        return np.array(model.site(site).pos) * FLIP
    return np.array(position, dtype=float)


class Vehicle:
    """A torpedo AUV in MuJoCo with its hydrodynamics, autopilots and servos.

    Args:
        vehicle: a name from ``VEHICLES`` or a path to an MJCF model of the same layout.
        net_buoyancy: buoyancy minus weight, N.
        current_ned: constant ocean current, m/s, NED.
        water: the mission's moving water (``auvsim.physics.water.Water``), added to
            ``current_ned``; None for none.
        disturbance: the mission's motion disturbances (``auvsim.physics.water.Disturbance``);
            None for none.
        seafloor: terrain to add to the scene (``auvsim.world.seafloor.Seafloor``), for ray casts;
            bind it to a ``MjData`` of its own (``ray_data``), not to ``self.data``, so that
            casts may run while another thread steps the physics.
        hold_rpm: the speed channel holds the shaft at the rpm of its reference speed in
            straight flight instead of holding the speed (``control.Gains.hold_rpm``).
        full_rudder_turns: large heading changes at full rudder up to the PID's braking
            point (``control.Gains.full_rudder_turns``).
        imu_position, dvl_position: where the IMU and the DVL sit, m, FRD from the body
            origin; None for the model's ``imu`` and ``dvl`` sites.
    """

    def __init__(self, vehicle: str = "auv", *, net_buoyancy: float = 0.0,
                 current_ned: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 seafloor=None, water: Water | None = None,
                 disturbance: Disturbance | None = None, hold_rpm: bool = False,
                 full_rudder_turns: bool = False, imu_position=None,
                 dvl_position=None) -> None:
        self.name = vehicle
        path = model_path(vehicle)
        try:
            spec = mujoco.MjSpec.from_file(str(path))
            if seafloor is not None:
                seafloor.attach(spec)
            ranges = _without_actuators(spec)
            self.model = spec.compile()
            self.model.opt.disableflags |= _UNUSED
            self.data = mujoco.MjData(self.model)
            self.body_id = self.model.body("vehicle").id
            self.hydro: Hydro = load_hydro(self.model, net_buoyancy=net_buoyancy,
                                           ranges=ranges)
        except (ValueError, KeyError) as e:  # MuJoCo's parse errors are ValueErrors
            reason = " ".join(str(e).split())
            raise ConfigError(f"vehicle {str(path)!r}: not a vehicle model of auvsim's layout "
                              f"({reason}); expected one like models/auv.xml") from None
        # Views into the MjData, which never moves: made once, since each attribute
        # access makes a new array (the environment reads them every step).
        d = self.data
        self._qpos, self._qvel, self._qfrc, self._xfrc = (d.qpos, d.qvel, d.qfrc_applied,
                                                          d.xfrc_applied)
        self._warnings = d.warning.number[_UNSTABLE]
        self.length = 2.0 * float(self.model.geom("hull").size[0])
        self.gains = Gains(length=self.length, hold_rpm=bool(hold_rpm),
                           full_rudder_turns=bool(full_rudder_turns))
        self.current_ned = np.array(current_ned, dtype=float)
        self.water_table = water.table if water is not None else still_water()
        self.disturbance = disturbance if disturbance is not None and disturbance.active \
            else None
        self.step = 0  # physics steps since the last reset: the clock of water and jitter
        # The config's own check of the positions (three finite numbers, within reach).
        sensors = VehicleConfig(imu_position=imu_position, dvl_position=dvl_position)
        self.imu_position = _sensor_position(self.model, "imu", sensors.imu_position)
        self.dvl_position = _sensor_position(self.model, "dvl", sensors.dvl_position)
        self.dt = float(self.model.opt.timestep)
        self.max_speed = max_speed(self.hydro)
        self.actuators = np.zeros(3)  # shaft rpm, rudder, stern planes (rad)
        self.integrals = np.zeros(3)
        # The compiled loop for this vehicle's argument types, called without numba's
        # dispatcher: it works out the types of every argument on every call, and those of
        # the two NamedTuples (Hydro, WaterTable: 42 fields) cost 15 to 20 us, as much as
        # the environment's whole step may. ``_argument_key`` says when it holds: the same
        # objects in the vehicle's attributes the loop reads (an attribute given a new
        # object may bring a new type), and caller's arrays of the same dtype and layout.
        self._compiled = None
        self._key: tuple[tuple, tuple] = ((), ())

    def check_speed(self, speed: float) -> None:
        """Refuse a surge set point the vehicle cannot hold: below ``MIN_SPEED`` (no depth
        control) or beyond ``SPEED_MARGIN`` of its top speed."""
        limit = SPEED_MARGIN * self.max_speed
        if speed < MIN_SPEED:
            raise ConfigError(
                f"speed {speed:g} m/s is too slow to hold depth: expected at least "
                f"{MIN_SPEED:g} m/s (the stern planes reverse below 0.33 to 0.36 m/s)")
        if speed > limit:
            raise ConfigError(
                f"speed {speed:g} m/s is beyond what vehicle {self.name!r} can hold: "
                f"expected at most {limit:.2f} m/s ({100 * SPEED_MARGIN:.0f} % of its "
                f"{self.max_speed:.2f} m/s top speed)")

    def ray_data(self) -> mujoco.MjData:
        """A fresh ``MjData`` with every static geom placed, for ray casts only."""
        data = mujoco.MjData(self.model)
        mujoco.mj_forward(self.model, data)
        return data

    @property
    def current_ned(self) -> np.ndarray:
        """The constant ocean current, m/s, NED: (3,) float64."""
        return self._current_ned

    @current_ned.setter
    def current_ned(self, value) -> None:
        # Held as the compiled loop's own type (float64, contiguous; the same object when
        # it is one), so that an integer or strided current is not a new compilation of
        # the loop (about 15 s).
        current = np.ascontiguousarray(value, dtype=float)
        if current.shape != (3,):
            raise ValueError(f"current_ned: expected 3 numbers (north, east, down), got "
                             f"shape {current.shape}")
        self._current_ned = current

    def reset(self, *, position_ned=(0.0, 0.0, 0.0), roll: float = 0.0, pitch: float = 0.0,
              yaw: float = 0.0, velocity_body=(0.0, 0.0, 0.0)) -> None:
        """Place the vehicle (m, rad, m/s in NED/FRD); a forward speed starts the shaft at
        the rpm that holds it."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:7], self.data.qvel[:3] = mujoco_from_ned(
            position_ned, quaternion_from_euler(roll, pitch, yaw), velocity_body)
        self.actuators[:] = 0.0
        u = float(velocity_body[0])
        self.actuators[0] = math.copysign(feedforward_rpm(self.hydro, abs(u)), u)
        self.integrals[:] = 0.0
        self.step = 0
        if self.disturbance is not None:
            self.disturbance.reset()
        mujoco.mj_forward(self.model, self.data)  # positions of every geom, for ray casts

    def state(self, *, euler: bool = False) -> dict[str, np.ndarray]:
        """The true state now (NED/FRD, SI): ``position_ned``, ``velocity_ned``,
        ``velocity_body``, ``quaternion`` and ``angular_rate``, as a Trajectory row; with
        ``euler`` also roll, pitch and yaw (``euler``, rad)."""
        return ned_from_mujoco(self._qpos, self._qvel, euler=euler)

    def state_row(self) -> np.ndarray:
        """The true state now as one new (19,) row: ``state(euler=True)``'s fields, in
        the order and at the slices of ``frames.STATE`` and ``frames.EULER``."""
        return state_row(self._qpos, self._qvel)

    def yaw(self) -> float:
        """Current heading, rad from north (NED)."""
        return yaw_of(quat_to_rot(self.state()["quaternion"]))

    def run(self, references: np.ndarray, closed_loop=(True, True, True)) -> Trajectory:
        """Advance ``len(references)`` physics steps and return the true state at each.

        Args:
            references: (N, 3) per step; for a closed-loop channel the speed (m/s), heading
                (rad) or depth (m) to hold, for an open-loop one the shaft rpm, rudder or
                stern-plane angle (rad) to command.
            closed_loop: which of the three channels the autopilot drives.

        Raises:
            ValueError: ``references`` is not a finite (N, 3) array, or ``closed_loop`` not
                three flags (the compiled loop does no bounds checks).
            SimulationError: MuJoCo found the simulation unstable during these steps.
        """
        references = np.ascontiguousarray(references, dtype=float)
        if references.ndim != 2 or references.shape[1] != 3:
            raise ValueError(f"references: expected an array of shape (N, 3), got shape "
                             f"{references.shape}")
        if not np.isfinite(references).all():
            raise ValueError("references: expected finite numbers, got NaN or infinity")
        if len(closed_loop) != 3:
            raise ValueError(f"closed_loop: expected 3 flags (speed, heading, depth), got "
                             f"{closed_loop!r}")
        return self.advance(references, np.array(closed_loop, dtype=np.bool_))

    def advance(self, references: np.ndarray, closed_loop: np.ndarray) -> Trajectory:
        """``run`` without its checks, for a caller that made its arguments so: a finite
        float64 C-contiguous (N, 3) array and a (3,) bool array (the environment, every
        step)."""
        out = Trajectory.empty(len(references))
        d = self.data
        self._xfrc[:] = 0.0
        if self.disturbance is not None:
            base, rows = self.disturbance.table(self.step * self.dt,
                                                (self.step + len(references)) * self.dt)
        else:
            base, rows = 0, _NO_ROWS
        args = (self.model._address, d._address, self._qpos, self._qvel, self._qfrc, self.hydro,
                self.gains, references, closed_loop, self.actuators, self.integrals,
                self.current_ned, self.water_table, self.disturbance is not None, rows, base,
                self.step, self.imu_position, self.dt, out)
        key = self._argument_key(references, closed_loop)
        if self._compiled is not None and self._key[0] == key[0] and all(
                [a is b for a, b in zip(key[1], self._key[1], strict=True)]):
            self._compiled(*args)
        else:
            _run(*args)  # compiles, or loads from the cache, the loop for these types
            self._compiled = _run.overloads[tuple(map(_run.typeof_pyval, args))].entry_point
            self._key = key
        self.step += len(references)
        self._check_stable()
        return out

    def _argument_key(self, references, closed_loop) -> tuple[tuple, tuple]:
        """What fixes the compiled loop's argument types: what numba's types of the
        caller's arrays are made of (``_array_kind``; numba's own ``typeof`` costs 13 us
        an array), and the objects of the vehicle's attributes the loop reads, by
        identity (held, so that no other object can take one's place). The disturbance
        rows are always a new float64 C array (``np.concatenate``), MuJoCo's views fixed."""
        return ((_array_kind(references), _array_kind(closed_loop)),
                (self.hydro, self.gains, self.water_table, self.current_ned, self.actuators,
                 self.integrals, self.imu_position))

    def _check_stable(self) -> None:
        if any(self._warnings.tolist()):  # four counts: a tenth of ndarray.any's cost
            said = _warnings[-1] if _warnings else "Nan, Inf or huge value in the state"
            raise SimulationError(f"the simulation became unstable (MuJoCo: "
                                  f"{said.split('. ')[0]}); expected a vehicle, current and "
                                  "buoyancy it can fly with")
