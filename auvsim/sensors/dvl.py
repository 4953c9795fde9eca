"""Janus four-beam DVL: beam geometry, the error model (paper eq. 7) and least squares
(paper eq. 9). The geometry lives here once; everything else calls it.

Beam k = 1..4 points along, in the DVL frame,
``b_k = [cos(psi_k) sin(alpha), sin(psi_k) sin(alpha), cos(alpha)]``,
``psi_k = (k - 1) pi/2 + pi/4``, alpha the beam angle from the DVL's z (down) axis.
A beam measures the projection of the DVL's velocity over ground (in the DVL frame) on
``b_k``; ``H = [b_1; ...; b_4]`` stacks them, so ideal beams are ``H v``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..config import DvlConfig
from ..frames import rotation_rpy


def beam_matrix(beam_angle: float) -> np.ndarray:
    """(4, 3) matrix H whose rows are the unit beam directions in the DVL frame.

    Args:
        beam_angle: angle of every beam from the DVL's z axis, rad.
    """
    psi = np.arange(4) * np.pi / 2 + np.pi / 4
    s, c = math.sin(beam_angle), math.cos(beam_angle)
    return np.column_stack([np.cos(psi) * s, np.sin(psi) * s, np.full(4, c)])


class DvlErrors(NamedTuple):
    """The realised error parameters of one mission."""

    scale_factor: np.ndarray  # (4,) s_k, dimensionless
    bias: np.ndarray  # (4,) m/s


def draw_errors(config: DvlConfig, rng: np.random.Generator) -> DvlErrors:
    """Draw a mission's per-beam scale factors and biases (mean + std * N(0, 1))."""
    scale = np.broadcast_to(np.asarray(config.scale_factor, dtype=float), 4)
    bias = np.broadcast_to(np.asarray(config.bias, dtype=float), 4)
    return DvlErrors(scale + config.scale_factor_std * rng.standard_normal(4),
                     bias + config.bias_std * rng.standard_normal(4))


def measure(beam_velocity: np.ndarray, valid: np.ndarray, *, errors: DvlErrors,
            noise_std: float, rng: np.random.Generator) -> np.ndarray:
    """Measured beam velocities, paper eq. 7: ``y = (1 + s) (H v) + bias + n``.

    Args:
        beam_velocity: (M, 4) true beam velocities H v, m/s.
        valid: (M, 4) bool, beams with bottom lock; the others read NaN.
        errors: the mission's scale factors and biases.
        noise_std: std of the white noise n, m/s.
        rng: noise source; one draw per beam and ping, valid or not, so the noise of a ping
            does not depend on which beams are valid.

    Returns:
        (M, 4) measured beam velocities, m/s, NaN where not valid.
    """
    noise = noise_std * rng.standard_normal(beam_velocity.shape)
    y = (1.0 + errors.scale_factor) * beam_velocity + errors.bias + noise
    return np.where(valid, y, np.nan)


def least_squares(beams: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Velocity from beam measurements, paper eq. 9: ``v = (H^T H)^-1 H^T y`` over the
    valid (finite) beams of each ping: four beams in least squares, three solved exactly,
    fewer give NaN.

    Args:
        beams: (M, 4) beam velocities, m/s, NaN where a beam has no bottom lock.
        h: (4, 3) beam matrix.

    Returns:
        (M, 3) velocity in the DVL frame, m/s.
    """
    valid = np.isfinite(beams)
    out = np.full((len(beams), 3), np.nan)
    pattern = valid @ (1 << np.arange(4))  # which beams are valid, as a 4-bit number
    for code in np.unique(pattern):
        use = np.array([(code >> k) & 1 for k in range(4)], dtype=bool)
        if use.sum() < 3:
            continue
        rows = pattern == code
        out[rows] = beams[rows][:, use] @ np.linalg.pinv(h[use]).T
    return out


class DvlGeometry(NamedTuple):
    """Where the DVL sits and how it looks, in body (FRD) axes."""

    h: np.ndarray  # (4, 3) beam matrix, DVL frame
    mounting: np.ndarray  # (3, 3) DVL frame -> body
    lever_arm: np.ndarray  # (3,) m, DVL position relative to the body origin

    @classmethod
    def from_config(cls, config: DvlConfig, lever_arm: np.ndarray) -> DvlGeometry:
        return cls(beam_matrix(math.radians(config.beam_angle_deg)),
                   rotation_rpy(*np.radians(config.mounting_rpy_deg)), np.asarray(lever_arm))

    def velocity(self, velocity_body: np.ndarray, angular_rate: np.ndarray) -> np.ndarray:
        """(M, 3) velocity over ground of the DVL point in the DVL frame, m/s, from body
        velocities (M, 3) m/s and angular rates (M, 3) rad/s (lever arm included)."""
        v_point = velocity_body + np.cross(angular_rate, self.lever_arm)
        return v_point @ self.mounting  # rows of mounting^T v

    def rays(self, position_ned: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Beam origins (M, 3) and unit directions (M, 4, 3) in NED, from vehicle positions
        (M, 3) m and body->NED rotations (M, 3, 3)."""
        origins = position_ned + rotation @ self.lever_arm
        beams_body = self.h @ self.mounting.T  # (4, 3)
        directions = np.einsum("mij,kj->mki", rotation, beams_body)
        return origins, directions
