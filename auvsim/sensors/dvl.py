"""Janus four-beam DVL: beam geometry, the error model (paper eq. 7) and least squares
(paper eq. 9), and the DVL's sensor plugin. The geometry and the ping pipeline (ray-cast
ranges + geometry -> true beams -> errors -> LS -> valid flags, ``ping``) live here once;
``auvsim generate``, the environment and ``auvsim import-velocity`` all call them.

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
from ..errors import ConfigError
from ..frames import rotation_matrices, rotation_rpy
from . import Attr, Field, Sensor, sample_rows, samples_in


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


def true_beams(velocity: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(M, 4) ideal beam velocities ``H v`` of (M, 3) DVL-frame velocities, m/s; NaN on a
    ping whose velocity is not finite (a dropout in a recorded stream)."""
    finite = np.isfinite(velocity).all(axis=1)
    return np.where(finite[:, None], np.nan_to_num(velocity) @ h.T, np.nan)


def ping(velocity: np.ndarray, lock: np.ndarray, *, h: np.ndarray, errors: DvlErrors,
         noise_std: float, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """The DVL's pings, the one pipeline: true beams -> eq. 7 errors -> eq. 9 LS.

    Args:
        velocity: (M, 3) true velocity over ground of the DVL in its frame, m/s (NaN rows:
            no measurement).
        lock: (M, 4) bool, beams with bottom lock (from the ray casts' ranges).
        h: (4, 3) beam matrix.
        errors: the mission's scale factors and biases.
        noise_std: beam noise, m/s.
        rng: the DVL's noise stream (one draw per beam and ping).

    Returns:
        ``velocity``, ``beam_velocity_true`` (M, 4), ``beam_velocity`` (M, 4, NaN where not
        valid), ``valid`` (M, 4; bottom lock on a finite ping) and ``velocity_ls`` (M, 3).
    """
    valid = lock & np.isfinite(velocity).all(axis=1)[:, None]
    beams_true = true_beams(velocity, h)
    beams = measure(beams_true, valid, errors=errors, noise_std=noise_std, rng=rng)
    return dict(velocity=velocity, beam_velocity_true=beams_true, beam_velocity=beams,
                valid=valid, velocity_ls=least_squares(beams, h))


def config_attrs(config: DvlConfig, errors: DvlErrors) -> dict[str, object]:
    """The DVL attributes every mission carries, simulated or imported."""
    return dict(dvl_rate_hz=config.rate_hz, beam_angle_deg=config.beam_angle_deg,
                dvl_scale_factor=errors.scale_factor, dvl_bias=errors.bias,
                dvl_noise_std=config.noise_std)


def synthesise(velocity: np.ndarray, config: DvlConfig,
               streams: dict[str, np.random.Generator]) -> tuple[dict[str, np.ndarray], dict]:
    """The DVL fields and attributes of a recorded DVL-frame velocity stream (N, 3) taken
    as the truth, with the error model of ``config`` (the beam-synthesis half of the
    pipeline: every finite ping has bottom lock).

    Args:
        velocity: (N, 3) m/s, one row per ping.
        config: beam angle, rate and error model (ranges and mounting are not used).
        streams: the ``dvl_parameters`` and ``dvl_noise`` streams (``auvsim.streams``).

    Returns:
        The ``dvl`` fields by path (pings at ``config.rate_hz`` from t = 0), and the
        attributes.
    """
    h = beam_matrix(math.radians(config.beam_angle_deg))
    errors = draw_errors(config, streams["dvl_parameters"])
    lock = np.ones((len(velocity), 4), dtype=bool)
    fields = ping(velocity, lock, h=h, errors=errors, noise_std=config.noise_std,
                  rng=streams["dvl_noise"])
    out = {"dvl/time": np.arange(len(velocity)) / config.rate_hz}
    out.update((f"dvl/{k}", v) for k, v in fields.items())
    return out, config_attrs(config, errors)


class Dvl(Sensor):
    """The Janus DVL: beams ray-cast on the seafloor from the DVL site, with the lever
    arm and mounting, then ``ping``. Pings fall on IMU samples that are whole multiples
    of the ping interval (``sample_rows``); ``imu/index_of_dvl`` records them."""

    name = "dvl"
    section = "dvl"
    streams = ("dvl_parameters", "dvl_noise")
    fields = (
        Field("dvl/time", (), "f", "dvl", "s", "ping times", imported=True),
        Field("dvl/velocity", (3,), "f", "dvl", "m/s", "TRUE DVL velocity in the DVL frame: "
              "the regression target", imported=True),
        Field("dvl/beam_velocity_true", (4,), "f", "dvl", "m/s", "H v", imported=True),
        Field("dvl/beam_velocity", (4,), "f", "dvl", "m/s", "measured (NaN where the beam "
              "has no bottom lock)", imported=True),
        Field("dvl/beam_range", (4,), "f", "dvl", "m", "slant range to the seafloor (NaN: "
              "no hit within max_range; a hit nearer than min_range is kept but not valid)"),
        Field("dvl/valid", (4,), "b", "dvl", "-", "bottom lock", imported=True),
        Field("dvl/velocity_ls", (3,), "f", "dvl", "m/s", "LS estimate from the measured "
              "beams (NaN if < 3 valid)", imported=True),
        Field("imu/index_of_dvl", (), "i", "dvl", "-", "IMU sample index of each ping",
              index_of="imu"),
    )
    attributes = (
        Attr("dvl_rate_hz", (), "ping rate, Hz", imported=True, low=0, strict=True),
        Attr("beam_angle_deg", (), "beam angle from the DVL's z axis, deg", imported=True,
             low=0, strict=True),
        Attr("dvl_scale_factor", (4,), "REALISED scale factor s_k", imported=True),
        Attr("dvl_bias", (4,), "REALISED bias, m/s", imported=True),
        Attr("dvl_noise_std", (), "beam noise std, m/s", imported=True, low=0),
        Attr("dvl_min_range", (), "m", low=0),
        Attr("dvl_max_range", (), "m", low=0, strict=True),
        Attr("dvl_mounting_rpy_deg", (3,), "DVL frame -> body, ZYX, deg"),
        Attr("dvl_position_body", (3,), "m, FRD"),
    )

    def __init__(self, config, platform, parameters):
        self.config = config.dvl
        self.platform = platform
        self.geometry = DvlGeometry.from_config(config.dvl, platform.vehicle.dvl_position)
        self.errors = draw_errors(config.dvl, parameters)
        self.every_imu = self.every(config)

    def rows(self, n_imu):
        return {"dvl": samples_in(n_imu, self.every_imu)}

    def attrs(self):
        c = self.config
        return dict(config_attrs(c, self.errors), dvl_min_range=c.min_range,
                    dvl_max_range=c.max_range, dvl_mounting_rpy_deg=c.mounting_rpy_deg,
                    dvl_position_body=self.platform.vehicle.dvl_position)

    def measure(self, truth, rng):
        c, vehicle, seafloor = self.config, self.platform.vehicle, self.platform.seafloor
        rows = sample_rows(truth.first, len(truth.time), self.every_imu)
        if rows.start >= len(truth.time):
            return _no_pings()
        velocity = self.geometry.velocity(truth.velocity_body[rows], truth.angular_rate[rows])
        origins, directions = self.geometry.rays(truth.position_ned[rows],
                                                 rotation_matrices(truth.quaternion[rows]))
        reach = c.max_range * np.linalg.norm(directions[..., :2], axis=-1).max()
        try:
            seafloor.follow(origins[:, :2], reach=reach)
        except ValueError as e:
            raise ConfigError(
                f"dvl.max_range: {c.max_range:g} m beams reach beyond the procedural terrain "
                f"window ({e}); expected a shorter max_range or a larger seafloor.cell_size"
            ) from None
        ranges = seafloor.cast(vehicle.model, self.platform.ray_data, origins, directions,
                               max_range=c.max_range, exclude_body=vehicle.body_id)
        fields = ping(velocity, ranges >= c.min_range,  # NaN (no hit) compares False
                      h=self.geometry.h, errors=self.errors, noise_std=c.noise_std, rng=rng)
        out = {"dvl/time": truth.time[rows]}
        out.update((f"dvl/{k}", v) for k, v in fields.items())
        out["dvl/beam_range"] = ranges
        out["imu/index_of_dvl"] = (truth.first + rows.start
                                   + self.every_imu * np.arange(len(velocity), dtype=np.int64))
        return out


def _no_pings() -> dict[str, np.ndarray]:
    """The DVL fields of a block without a ping (an environment step between pings)."""
    return {f.path: np.empty((0, *f.shape), dtype={"f": float, "b": bool, "i": np.int64}[f.kind])
            for f in Dvl.fields}


SENSOR = Dvl
