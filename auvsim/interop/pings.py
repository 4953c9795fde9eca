"""A mission's DVL pings as an instrument reports them, computed once for every output that
plays or exports them (``auvsim.interop.ros2``'s ``/dvl/data``, ``auvsim.interop.a50``'s
reports): which beams have bottom lock, the altitude, each beam's error variance and the
covariance of the ping's velocity, from the mission's noise model.

Bottom lock. A beam is *locked* when it measured (``dvl/valid`` and a finite
``dvl/beam_velocity``, ``auvsim.data.beams.usable_beams``) with bottom lock:
``dvl/status`` OK or OUTLIER (an outlier is a bottom-locked beam with a wild value). A
water-track ping's beams measured the water and keep their bottom-lock status
(``auvsim.sensors.dvl.Status``): only those with a lock count. A file without
``dvl/status`` (imported, recorded) says nothing per beam: its beams are locked on the
bottom-track pings (``dvl/mode`` 0, or every ping without ``dvl/mode``).

Altitude: ``r_k cos(alpha_k)``, the slant range's component on the DVL's z axis (the
beam matrix's z column), averaged over the locked beams with a range; NaN without one. A
recorded mission's own ``dvl/altitude`` is the instrument's and is kept.

Noise (``auvsim.sensors.dvl``, ``ping`` and ``Dvl.effects``): on a bottom-track ping beam
k's white noise has std ``sigma_k = noise_std + noise_range_coeff r_k + noise_speed_coeff
|v|`` (``beam_noise_std``, |v| the true speed of the DVL); on a water-track ping it is
``water_track_noise_std`` in its place. Every beam also carries ``b_k . dv``, dv the
Gauss-Markov velocity error of stationary std ``slow_error_std`` per DVL axis, shared by
the beams. So a beam's variance is ``sigma_k^2 + slow^2`` (b_k a unit vector) and the
least-squares velocity's covariance ``P diag(sigma_k^2) P^T + slow^2 I``, ``P`` the
pseudo-inverse of the rows of H of the beams used (the beams that measured: the velocity
is their least squares). Scale factors, biases, misalignment (systematic) and outliers
(heavy-tailed) are not in it. The coefficients are the dataset's config for a simulated
mission; an imported or recorded one has only ``dvl_noise_std`` (and
``dvl_slow_error_std`` if any), and a recorded one with ``dvl_velocity_accuracy`` (the
instrument's stated accuracy) has that, per axis, as its velocity's covariance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PingErrors:
    """What a mission's M pings say about their beams and their errors.

    Attributes:
        measured: (M, 4) bool, the beams that measured (their least squares is the velocity).
        locked: (M, 4) bool, the beams that measured with bottom lock.
        altitude: (M,) m along the DVL's z axis, NaN without a locked beam with a range.
        beam_variance: (M, 4) (m/s)^2 of each measured beam's error; NaN where not measured.
        covariance: (M, 3, 3) (m/s)^2 of the velocity's error; NaN without a velocity.
    """

    measured: np.ndarray
    locked: np.ndarray
    altitude: np.ndarray
    beam_variance: np.ndarray
    covariance: np.ndarray


def ping_errors(mission) -> PingErrors:
    """The pings of a mission (``auvsim.data.reader.Mission`` with a ``dvl`` group) as the
    module docstring defines them."""
    from auvsim.data.beams import beam_matrix, usable_beams
    from auvsim.sensors.dvl import Mode, Status, beam_noise_std

    a, dvl = mission.attrs, mission.dvl
    m = len(dvl.time)
    h = beam_matrix(math.radians(float(a["beam_angle_deg"])))
    beams = np.asarray(dvl.beam_velocity, dtype=float) if "beam_velocity" in dvl \
        else np.full((m, 4), np.nan)
    ranges = np.asarray(dvl.beam_range, dtype=float) if "beam_range" in dvl \
        else np.full((m, 4), np.nan)
    flagged = dvl.valid if "valid" in dvl else np.isfinite(beams)
    measured = usable_beams(flagged, beams)
    velocity = np.asarray(dvl.velocity_ls, dtype=float)
    # A log without beams (the instrument's velocity alone: an A-KIT log, a PD0 file in
    # instrument coordinates) has a velocity wherever it logged one.
    has_velocity = np.isfinite(velocity).all(axis=1) & (
        (measured.sum(axis=1) >= 3) if "beam_velocity" in dvl else True)
    mode = np.asarray(dvl.mode) if "mode" in dvl \
        else np.where(has_velocity, int(Mode.BOTTOM_TRACK), int(Mode.NO_VELOCITY))
    bottom = mode == int(Mode.BOTTOM_TRACK)
    if "status" in dvl:
        locked = measured & np.isin(np.asarray(dvl.status),
                                    (int(Status.OK), int(Status.OUTLIER)))
    else:
        locked = measured & bottom[:, None]

    if mission.origin == "recorded" and "altitude" in dvl:
        altitude = np.asarray(dvl.altitude, dtype=float)
    else:
        ranged = locked & np.isfinite(ranges)
        count = ranged.sum(axis=1)
        vertical = np.where(ranged, ranges * h[:, 2], 0.0).sum(axis=1)
        altitude = np.where(count > 0, vertical / np.maximum(count, 1), np.nan)

    noise = _noise(mission)
    if mission.origin == "simulated" and "velocity" in dvl:
        speed = np.linalg.norm(np.asarray(dvl.velocity, dtype=float), axis=1)
    else:
        speed = np.zeros(m)  # the coefficients of speed and range are the simulator's
    sigma = beam_noise_std(ranges, speed, noise)  # the simulator's own noise model
    water = mode == int(Mode.WATER_TRACK)
    sigma = np.where(water[:, None], noise.water_track_noise_std if noise.water_track else 0.0,
                     sigma)
    slow2 = noise.slow_error_std ** 2
    beam_variance = np.where(measured, sigma**2 + slow2, np.nan)

    covariance = np.full((m, 3, 3), np.nan)
    if mission.origin == "recorded" and "dvl_velocity_accuracy" in a:
        covariance[has_velocity] = float(a["dvl_velocity_accuracy"]) ** 2 * np.eye(3)
    else:
        pinv = {}  # one pseudo-inverse per set of beams used (at most 5 sets of 3 or 4)
        for n in np.flatnonzero(has_velocity):
            use = measured[n]
            key = use.tobytes()
            if key not in pinv:
                pinv[key] = np.linalg.pinv(h[use])
            p = pinv[key]
            c = (p * sigma[n, use] ** 2) @ p.T + slow2 * np.eye(3)
            covariance[n] = (c + c.T) / 2  # symmetric to the last bit
    return PingErrors(measured, locked, altitude, beam_variance, covariance)


def _noise(mission):
    """The noise model's coefficients as an ``auvsim.config.DvlConfig``: the dataset's for
    a simulated mission, else one holding what the mission's attributes say (the other
    coefficients at their defaults, 0)."""
    from auvsim.config import Config, DvlConfig

    a = mission.attrs
    if mission.origin == "simulated" and mission.dataset.config_json:
        return Config.from_json(mission.dataset.config_json).dvl
    return DvlConfig(noise_std=float(a.get("dvl_noise_std", 0.0)),
                     slow_error_std=float(a.get("dvl_slow_error_std", 0.0)))
