"""Frames and rotations, in one place (the conventions are in the package docstring).

* NED world / FRD body, and MuJoCo's north-west-up world / forward-left-up body: the two
  differ by a rotation of pi about x, so converting flips the y and z components of
  vectors and of a quaternion's vector part (``FLIP``, ``ned_from_mujoco``).
* Quaternions ``[w, x, y, z]`` rotate body vectors into NED; Euler angles are roll, pitch,
  yaw (ZYX).

``quat_to_rot`` is the one scalar copy, compiled with numba for the physics loop;
``rotation_matrices`` is its twin for arrays of quaternions, compiled too (numpy's cost per
call dominated on the one ping of an environment step), and a test checks that they
agree.
"""

from __future__ import annotations

import math

import numba
import numpy as np

FLIP = np.array([1.0, -1.0, -1.0])  # FLU <-> FRD, NWU <-> NED, either way
_QUATERNION_FLIP = np.array([1.0, 1.0, -1.0, -1.0])  # the same, on [w, x, y, z]


@numba.njit(cache=True)
def quat_to_rot(q):
    """(3, 3) body -> NED rotation of one unit quaternion [w, x, y, z] (compiled)."""
    return rot_into(q, np.empty((3, 3)))


@numba.njit(cache=True)
def rot_into(q, out):
    """``quat_to_rot`` written into ``out`` (3, 3) and returned: the physics loop's, so
    that a step allocates nothing."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0, 0] = 1 - 2 * (y * y + z * z)
    out[0, 1] = 2 * (x * y - w * z)
    out[0, 2] = 2 * (x * z + w * y)
    out[1, 0] = 2 * (x * y + w * z)
    out[1, 1] = 1 - 2 * (x * x + z * z)
    out[1, 2] = 2 * (y * z - w * x)
    out[2, 0] = 2 * (x * z - w * y)
    out[2, 1] = 2 * (y * z + w * x)
    out[2, 2] = 1 - 2 * (x * x + y * y)
    return out


def rotation_matrices(quaternion: np.ndarray) -> np.ndarray:
    """(M, 3, 3) body -> NED rotations of (M, 4) unit quaternions [w, x, y, z]."""
    return _rotation_rows(np.asarray(quaternion, dtype=float))


@numba.njit(cache=True)
def _rotation_rows(q: np.ndarray) -> np.ndarray:
    """``rotation_matrices``, row by row: ``quat_to_rot``'s formula (``rot_into``)."""
    out = np.empty((len(q), 3, 3))
    for m in range(len(q)):
        rot_into(q[m], out[m])
    return out


def attitude_rates(t: np.ndarray, quaternion: np.ndarray) -> np.ndarray:
    """(R-1, 3) body angular rates, rad/s, over each interval of attitude samples: the
    rotation vector of ``q_k^-1 q_k+1`` (the short way round) over ``t_k+1 - t_k``, from
    body -> NED unit quaternions [w, x, y, z] (R, 4) at times ``t`` (R,) s."""
    q = np.asarray(quaternion, dtype=float)
    a, b = q[:-1], q[1:]
    # q_k^-1 q_k+1 = conj(a) b (Hamilton product), on the short way round.
    w = np.sum(a * b, axis=1)
    v = a[:, :1] * b[:, 1:] - b[:, :1] * a[:, 1:] - np.cross(a[:, 1:], b[:, 1:])
    v *= np.sign(w + (w == 0))[:, None]
    norm = np.linalg.norm(v, axis=1)
    angle = 2.0 * np.arctan2(norm, np.abs(w))
    axis = np.divide(v, norm[:, None], out=np.zeros_like(v), where=norm[:, None] > 0)
    return axis * (angle / np.diff(np.asarray(t, dtype=float)))[:, None]


def skew(v: np.ndarray) -> np.ndarray:
    """(..., 3, 3) matrices [v]x with [v]x a = v x a, of (..., 3) vectors."""
    v = np.asarray(v, dtype=float)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([np.stack([z, -w, y], -1), np.stack([w, z, -x], -1),
                     np.stack([-y, x, z], -1)], -2)


def rotation_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """(3, 3) rotation of ZYX Euler angles (rad): vectors in the rotated frame -> parent."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def quaternion_from_euler(roll, pitch, yaw) -> np.ndarray:
    """Unit quaternions [w, x, y, z] of ZYX Euler angles (rad), shape (..., 4): (4,) of
    three numbers, (N, 4) of three (N,) arrays (broadcast together)."""
    half = [np.asarray(a, dtype=float) / 2 for a in (roll, pitch, yaw)]
    cr, cp, cy = (np.cos(h) for h in half)
    sr, sp, sy = (np.sin(h) for h in half)
    return np.stack([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy], axis=-1)


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a b of quaternions [w, x, y, z], shape (..., 4), broadcast
    together: b's rotation, then a's."""
    shape = np.broadcast_shapes(np.shape(a), np.shape(b))
    aw, ax, ay, az = np.moveaxis(np.broadcast_to(a, shape), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.broadcast_to(b, shape), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw],
                    axis=-1)


def euler_angles(quaternion: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad, ZYX), shape (..., 3), of body -> NED unit quaternions
    [w, x, y, z], shape (..., 4)."""
    w, x, y, z = np.moveaxis(np.asarray(quaternion, dtype=float), -1, 0)
    sin_pitch = np.clip(2 * (w * y - z * x), -1.0, 1.0)
    return np.stack([np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
                     np.arcsin(sin_pitch),
                     np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))], axis=-1)


# The fields of ``ned_from_mujoco``'s state, and their slices of ``state_row``'s row.
STATE = {"position_ned": slice(0, 3), "velocity_ned": slice(3, 6),
         "velocity_body": slice(6, 9), "quaternion": slice(9, 13),
         "angular_rate": slice(13, 16)}
EULER = slice(16, 19)


def ned_from_mujoco(qpos: np.ndarray, qvel: np.ndarray, *,
                    euler: bool = False) -> dict[str, np.ndarray]:
    """The NED/FRD state of a free body from MuJoCo's NWU/FLU ``qpos`` (7,) and ``qvel``
    (6,): ``position_ned``, ``velocity_ned``, ``velocity_body``, ``quaternion`` and
    ``angular_rate`` (SI), and with ``euler`` its roll, pitch and yaw (``euler``, rad):
    views of one row computed in one compiled call (the environment's, every step)."""
    row = state_row(qpos, qvel)
    state = {name: row[part] for name, part in STATE.items()}
    if euler:
        state["euler"] = row[EULER]
    return state


@numba.njit(cache=True)
def state_row(qpos, qvel):
    """(19,) position, NED velocity, body velocity ``R^T v``, quaternion, angular rate and
    ZYX Euler angles (``euler_angles``' formula) from MuJoCo's ``qpos`` and ``qvel``."""
    out = np.empty(19)
    out[9] = qpos[3]
    for i in range(3):
        out[i] = qpos[i] * FLIP[i]
        out[3 + i] = qvel[i] * FLIP[i]
        out[10 + i] = qpos[4 + i] * _QUATERNION_FLIP[1 + i]
        out[13 + i] = qvel[3 + i] * FLIP[i]
    r = quat_to_rot(out[9:13])
    for i in range(3):
        out[6 + i] = r[0, i] * out[3] + r[1, i] * out[4] + r[2, i] * out[5]
    w, x, y, z = out[9], out[10], out[11], out[12]
    out[16] = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    out[17] = math.asin(min(max(2 * (w * y - z * x), -1.0), 1.0))
    out[18] = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return out


def mujoco_from_ned(position_ned, quaternion: np.ndarray,
                    velocity_body) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's ``qpos`` (7,) and the linear part of ``qvel`` (3,) of a free body placed at
    ``position_ned`` (m) with attitude ``quaternion`` (body -> NED) and moving at
    ``velocity_body`` (m/s, FRD)."""
    qpos = np.empty(7)
    qpos[:3] = np.asarray(position_ned, dtype=float) * FLIP
    qpos[3] = quaternion[0]
    qpos[4:7] = quaternion[1:] * FLIP
    v_world = quat_to_rot(quaternion) @ np.asarray(velocity_body, dtype=float) * FLIP
    return qpos, v_world


def yaw_of(rotation: np.ndarray) -> float | np.ndarray:
    """Heading (rad from north) of a (3, 3) body -> NED rotation (a float), or of each of
    a stack (..., 3, 3) (an array)."""
    rotation = np.asarray(rotation)
    if rotation.ndim == 2:
        return math.atan2(rotation[1, 0], rotation[0, 0])
    return np.arctan2(rotation[..., 1, 0], rotation[..., 0, 0])
