"""Janus four-beam DVL: beam geometry, the error model (paper eq. 7) and least squares
(paper eq. 9), and the DVL's sensor plugin. The geometry and the ping pipeline (ray-cast
ranges + geometry -> true beams -> errors -> LS -> valid flags, ``ping``) live here once;
``auvsim generate``, the environment and ``auvsim import-velocity`` all call them.

Beam k = 1..4 points along, in the DVL frame,
``b_k = [cos(psi_k) sin(alpha), sin(psi_k) sin(alpha), cos(alpha)]``,
``psi_k = (k - 1) pi/2 + pi/4``, alpha the beam angle from the DVL's z (down) axis.
A beam measures the projection of the DVL's velocity over ground (in the DVL frame) on
``b_k``; ``H = [b_1; ...; b_4]`` stacks them, so ideal beams are ``H v``. Beams 1 and 3,
and 2 and 4, point in opposite directions (the Janus pairs). Beam k is column k - 1 of
every (M, 4) array, and settings and reports name beams by that index, 0 to 3
(``DvlConfig.beam_failures``, ``beamsnet stress --faults``, ``auvsim plot``).

A simulated mission's DVL also loses bottom lock as an instrument does and errs beyond
eq. 7 (``DvlConfig``; each effect off by default, and then every array is what it was):
per beam and ping a reason code (``Status``, ``dvl/status``) says why a beam has no bottom
lock; the measured beams are, per beam k (bottom track)::

    y_k = (1 + s_k) (b_k . v) / (c_true / c_assumed) + bias_k + n_k + o_k + b_k . dv

with n_k of std ``noise_std + noise_range_coeff * r_k + noise_speed_coeff * |v|``
(``beam_noise_std``) and o_k a heavy-tailed outlier on a share ``outlier_rate`` of the
beam-pings and dv a time-correlated velocity error in the DVL frame (Gauss-Markov,
``slow_velocity_error``), common to the beams; the ray casts and v use the TRUE
mounting (nominal mounting times a realised misalignment). With ``water_track`` on, a
ping with fewer than 3 bottom-locked beams measures ``H (v - v_water)`` instead
(``dvl/mode``). ``error_velocity`` is the instrument's error velocity: white beam noise
shows in it, dv (in the beams' span) does not. The realised sound-speed ratio and
misalignment come from the ``dvl_calibration`` stream, every per-ping draw of these effects
from ``dvl_faults``, dv from ``dvl_slow_error``.
"""

from __future__ import annotations

import enum
import json
import math
from typing import NamedTuple

import numba
import numpy as np

from auvsim.config import DvlConfig
from auvsim.errors import ConfigError
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from auvsim.sensors import Attr, Field, Sensor, sample_rows, samples_in, shown
from auvsim.sensors.gauss_markov import gauss_markov_rows

# The slow velocity error of the Snapir's Teledyne RDI Navigator, measured against the
# A-KIT logs' reference (``auvsim.runs.presets.navigator`` gives the measurement): its std
# per axis, m/s, and its correlation time, s. The only DVL whose slow error auvsim has
# measured: the ``navigator`` preset's, and what a recorded log is taken to have where it
# states none (the INS/DVL filter, ``auvsim check-log``'s standard errors).
NAVIGATOR_SLOW_ERROR_STD = 0.009
NAVIGATOR_SLOW_ERROR_TIME = 19.0


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


class Status(enum.IntEnum):
    """Why a beam has no bottom lock on a ping (``dvl/status``): the first that applies in
    the order PING_DROPOUT, BEAM_FAILED, NO_HIT, TOO_NEAR, LOCK_LOST, GRAZING, ECHO_LOST,
    DROPOUT (``lock_status``: the instrument, then the geometry, then the bottom, then
    chance). In water track a beam keeps its bottom-lock code; ``dvl/valid`` says whether
    it measured the water."""

    OK = 0  # bottom lock, measured
    NO_HIT = 1  # no seafloor within max_range
    TOO_NEAR = 2  # seafloor nearer than min_range
    ECHO_LOST = 3  # echo lost near the range limit (echo_loss_range)
    GRAZING = 4  # incidence on the seafloor too oblique (grazing_loss_angle_deg)
    DROPOUT = 5  # inside a random dropout burst (dropout_rate, dropout_burst)
    PING_DROPOUT = 6  # the whole ping was lost (ping_dropout_rate)
    BEAM_FAILED = 7  # the beam is dead (beam_failures)
    LOCK_LOST = 8  # every beam lost lock, a soft bottom (lock_loss_intervals)
    OUTLIER = 9  # bottom lock, measured, but an outlier: a truth label (outlier_rate)


class Mode(enum.IntEnum):
    """What a ping's velocity is relative to (``dvl/mode``)."""

    NO_VELOCITY = -1  # fewer than 3 beams measured anything
    BOTTOM_TRACK = 0  # at least 3 beams with bottom lock: velocity over ground
    WATER_TRACK = 1  # bottom lock lost, velocity relative to a water layer (water_track)


# The codes as plain ints, for numpy: it takes an IntEnum member by a slow path (a few us
# per comparison or np.where, on the one ping of an environment step).
_OK, _DROPOUT, _OUTLIER = int(Status.OK), int(Status.DROPOUT), int(Status.OUTLIER)
_PING_DROPOUT, _BEAM_FAILED = int(Status.PING_DROPOUT), int(Status.BEAM_FAILED)
_NO_VELOCITY, _BOTTOM_TRACK = int(Mode.NO_VELOCITY), int(Mode.BOTTOM_TRACK)
_WATER_TRACK = int(Mode.WATER_TRACK)


class DvlCalibration(NamedTuple):
    """The realised calibration errors of one mission (stream ``dvl_calibration``)."""

    sound_speed_ratio: float  # c_true / c_assumed
    misalignment_rpy_deg: np.ndarray  # (3,) true DVL frame -> nominal DVL frame, ZYX, deg


def draw_calibration(config: DvlConfig, rng: np.random.Generator) -> DvlCalibration:
    """A mission's sound-speed ratio ``1 + sound_speed_std N(0, 1)`` and mounting
    misalignment ``misalignment_std_deg N(0, 1)`` per axis (always drawn, so each is the
    same whatever the other's setting).

    A beam's echo is shifted by ``2 f0 (b . v) / c_true``; the instrument converts the
    shift back with the sound speed it assumes, so it reads ``(b . v) c_assumed /
    c_true``: the measured beams are the true ones divided by the ratio, which is why
    Teledyne RDI corrects them by multiplying with it ("ADCP Coordinate Transformation",
    P/N 951-6079-00, 2010, sec. 4.1; for the Janus piston transducers of the Workhorse,
    whose beam angle does not depend on the sound speed).
    """
    z = rng.standard_normal(4)
    return DvlCalibration(1.0 + config.sound_speed_std * float(z[0]),
                          config.misalignment_std_deg * z[1:])


def beam_noise_std(ranges: np.ndarray, speed: np.ndarray, config: DvlConfig) -> np.ndarray:
    """(M, 4) std of each beam's noise, m/s:
    ``noise_std + noise_range_coeff * r_k + noise_speed_coeff * |v|``.

    The form of a Doppler log's specification, a constant plus terms that grow with range
    (the echo's signal-to-noise ratio falls with spreading and absorption) and with speed
    (the beam's width spreads the Doppler spectrum in proportion to the speed).

    Args:
        ranges: (M, 4) slant ranges, m (NaN counts as 0: such a beam measures nothing).
        speed: (M,) |v| of the velocity the beams measure, m/s.
        config: the coefficients.
    """
    return (config.noise_std + config.noise_range_coeff * _nan_to_zero(ranges)
            + config.noise_speed_coeff * speed[:, None])


def _nan_to_zero(x: np.ndarray) -> np.ndarray:
    """``np.nan_to_num(x)`` (NaN -> 0, +-inf -> +-the largest float), compiled for the
    float64 arrays of ranges, where numpy's overhead on a few values dominates."""
    if not (isinstance(x, np.ndarray) and x.dtype == np.float64):
        return np.nan_to_num(x)
    return _nan_to_zero_loop(x.reshape(-1)).reshape(x.shape)


@numba.njit(cache=True)
def _nan_to_zero_loop(x: np.ndarray) -> np.ndarray:
    """``np.nan_to_num`` of a (K,) float64 array."""
    out = np.empty(len(x))
    big = np.finfo(np.float64).max
    for i in range(len(x)):
        v = x[i]
        if math.isnan(v):
            v = 0.0
        elif math.isinf(v):
            v = big if v > 0 else -big
        out[i] = v
    return out


def logistic(x: np.ndarray, middle: float, width: float) -> np.ndarray:
    """``1 / (1 + exp(-(x - middle) / width))``: the loss probability curves, 1/2 at
    ``middle``; NaN in gives NaN (compared False)."""
    return 0.5 * (1.0 + np.tanh(0.5 * (x - middle) / width))  # no overflow far out


def markov_dropouts(u: np.ndarray, state: np.ndarray, *, rate: float,
                    burst: float) -> np.ndarray:
    """Dropout bursts: each beam a two-state Markov chain over pings.

    A beam in lock enters a burst with probability ``p = rate / (burst (1 - rate))`` per
    ping and a beam in a burst leaves it with probability ``1 / burst``, so bursts last
    ``burst`` pings on average (geometric) and the stationary share of pings in a burst is
    ``p / (p + 1 / burst) = rate``.

    With one uniform u per beam and ping, the next state is ``u < p`` from lock and
    ``u < 1 - 1/burst`` from a burst: a compiled loop over the pings (the chain's states
    are booleans, so any way of computing them gives the same ones).

    Args:
        u: (M, 4) uniforms in [0, 1), one per ping and beam.
        state: (4,) bool, in a burst before the first ping.
        rate, burst: ``DvlConfig.dropout_rate`` and ``dropout_burst``.

    Returns:
        (M, 4) bool, in a burst at each ping.
    """
    if rate == 0:
        return np.zeros(u.shape, dtype=bool)
    return _dropout_chain(u, np.asarray(state, dtype=bool), rate / (burst * (1.0 - rate)),
                          1.0 - 1.0 / burst)


@numba.njit(cache=True)
def _dropout_chain(u: np.ndarray, state: np.ndarray, p_enter: float,
                   p_stay: float) -> np.ndarray:
    """(M, 4) bool: ``markov_dropouts``'s chain, ping by ping, from (4,) ``state``."""
    out = np.empty(u.shape, dtype=np.bool_)
    s = state.copy()
    for m in range(u.shape[0]):
        for k in range(u.shape[1]):
            s[k] = u[m, k] < p_stay if s[k] else u[m, k] < p_enter
            out[m, k] = s[k]
    return out


def in_intervals(time: np.ndarray, intervals) -> np.ndarray:
    """(M,) bool: ``time`` (M,) s inside any ``(start, end)`` (start <= t < end)."""
    inside = np.zeros(len(time), dtype=bool)
    for start, end in intervals:
        inside |= (time >= start) & (time < end)
    return inside


def lock_status(time: np.ndarray, ranges: np.ndarray, *, config: DvlConfig,
                incidence_deg: np.ndarray | None, u: np.ndarray,
                dropout: np.ndarray) -> np.ndarray:
    """(M, 4) int bottom-lock reason codes (``Status``, without ``OUTLIER``): the first
    reason that applies, in the order of ``Status``'s docstring.

    Args:
        time: (M,) ping times, s.
        ranges: (M, 4) slant ranges, m (NaN: no hit within max_range).
        config: the DVL's settings.
        incidence_deg: (M, 4) angle between each beam and the seafloor normal at its hit,
            deg (None when the grazing loss is off).
        u: (M, 9) uniforms: echo loss (4), grazing loss (4), ping dropout (1).
        dropout: (M, 4) bool, inside a dropout burst (``markov_dropouts``).
    """
    c = config
    status = np.where(dropout, _DROPOUT, _OK).astype(np.int64)
    if c.echo_loss_range is not None:
        lost = u[:, 0:4] < logistic(ranges, c.echo_loss_range, c.echo_loss_width)
        status[lost] = Status.ECHO_LOST
    if c.grazing_loss_angle_deg is not None:
        lost = u[:, 4:8] < logistic(incidence_deg, c.grazing_loss_angle_deg,
                                    c.grazing_loss_width_deg)
        status[lost] = Status.GRAZING
    if c.lock_loss_intervals:  # (none: nothing to mark, and the mask costs a few us)
        status[in_intervals(time, c.lock_loss_intervals)] = Status.LOCK_LOST
    status[ranges < c.min_range] = Status.TOO_NEAR
    status[~np.isfinite(ranges)] = Status.NO_HIT
    for beam, start, end in c.beam_failures:
        status[(time >= start) & (time < end), beam] = Status.BEAM_FAILED
    if c.ping_dropout_rate > 0:  # else no uniform in [0, 1) is below it
        status[u[:, 8] < c.ping_dropout_rate] = Status.PING_DROPOUT
    return status


def slow_velocity_error(state: np.ndarray, pings: int, *, std: float, time: float,
                        dt: float, rng: np.random.Generator) -> np.ndarray:
    """A time-correlated DVL velocity error, first-order Gauss-Markov per axis:
    ``dv[k + 1] = phi dv[k] + std sqrt(1 - phi^2) w[k]``, ``phi = exp(-dt / time)``,
    ``w ~ N(0, 1)``; stationary std ``std``, autocorrelation ``exp(-lag / time)``
    (``auvsim.sensors.gauss_markov``, the IMU's bias process too).

    Added to the beams as ``H dv``, it is a velocity error the four beams agree on (a
    sound-speed or scale error that drifts, a bias of the bottom's echo): averaging pings
    does not remove it within ``time``, and the error velocity, whose combination of the
    beams is orthogonal to H's columns, does not see it.

    Args:
        state: (3,) dv at the first ping, DVL frame, m/s; updated in place to dv after the
            last ping, so that blocks of any length give the same path.
        pings: M, the number of pings.
        std, time, dt: stationary std, m/s; correlation time, s; ping interval, s.
        rng: the ``dvl_slow_error`` stream (three normals per ping, in ping order).

    Returns:
        (M, 3) dv at each ping, DVL frame, m/s.
    """
    return gauss_markov_rows(state, rng.standard_normal((pings, 3)), std=std,
                             dt_over_tau=dt / time)


def beam_noise_from_error_velocity(error_velocity: np.ndarray, beam_angle_deg: float) -> float:
    """The white beam noise, m/s, of a 4-beam Janus DVL from its error velocity (P,) m/s
    (NaN where a ping has none): e cancels any common velocity and keeps the beams' noise,
    with std sigma / (sqrt(2) sin a) (``error_velocity``), so sigma = sqrt(2) sin(a)
    std(e). The std is robust (1.4826 MAD about the median), so a DVL's outliers do not
    inflate it.

    Raises:
        ValueError: fewer than 2 finite values.
    """
    e = np.asarray(error_velocity, dtype=float)
    e = e[np.isfinite(e)]
    if len(e) < 2:
        raise ValueError(f"error_velocity: expected at least 2 finite values, got {len(e)}")
    std = 1.4826 * float(np.median(np.abs(e - np.median(e))))
    return math.sqrt(2.0) * math.sin(math.radians(beam_angle_deg)) * std


def error_velocity(beams: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(M,) the instrument's error velocity, m/s, from (M, 4) measured beams (NaN where a
    beam is missing, and then NaN).

    Teledyne RD Instruments, "ADCP Coordinate Transformation: Formulas and Calculations"
    (P/N 951-6079-00, 2010), sec. 5.3, beam-to-instrument transformation:
    ``e = d (b1 + b2 - b3 - b4)``, ``d = a / sqrt(2)``,
    ``a = 1 / (2 sin(alpha))``, its beam pairs being (1, 2) and (3, 4). Here the opposite
    pairs are (1, 3) and (2, 4), so ``e = d (y1 + y3 - y2 - y4)``: the difference of the
    two pairs' estimates of the vertical velocity, scaled so that with white beam noise
    sigma its std, ``sigma / (sqrt(2) sin(alpha))``, is that of a horizontal component.
    Ideal beams give 0 up to rounding (about 1e-16 |v|: the computed cosines and sines of
    the four azimuths are not exact negatives of each other).

    Args:
        beams: (M, 4) measured beam velocities, m/s.
        h: (4, 3) beam matrix (its beam angle).
    """
    key = h.tobytes()
    if key not in _ERROR_SCALE:  # numpy's scalar arithmetic costs more than the rest
        sin_alpha = float(np.hypot(h[0, 0], h[0, 1]))
        _ERROR_SCALE[key] = 1.0 / (2.0 * math.sqrt(2.0) * sin_alpha)
    d = _ERROR_SCALE[key]
    return d * ((beams[:, 0] + beams[:, 2]) - (beams[:, 1] + beams[:, 3]))


_ERROR_SCALE: dict[bytes, float] = {}  # a few entries: beam matrix -> error_velocity's d


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
    if valid.all():  # every ping on four beams (most do): the same product, in one go
        return beams @ _pinv(h, _BEAMS_USED[15]).T
    out = np.full((len(beams), 3), np.nan)
    pattern = valid @ _BEAM_BITS  # which beams are valid, as a 4-bit number
    for code in np.unique(pattern):
        use = _BEAMS_USED[code]
        if use.sum() < 3:
            continue
        rows = pattern == code
        out[rows] = beams[rows][:, use] @ _pinv(h, use).T
    return out


_BEAM_BITS = 1 << np.arange(4)
# The beams each 4-bit pattern uses, (4,) bool by pattern.
_BEAMS_USED = tuple(np.array([(code >> k) & 1 for k in range(4)], dtype=bool)
                    for code in range(16))


_PINV: dict[tuple, np.ndarray] = {}  # a few entries: (beam matrix, beams used) -> pinv


def _pinv(h: np.ndarray, use: np.ndarray) -> np.ndarray:
    """``np.linalg.pinv(h[use])``, computed once per beam matrix and (4,) bool choice of
    beams: the environment solves one ping per call, and the SVD would dominate it."""
    key = (h.shape, h.dtype.str, h.tobytes(), use.tobytes())
    if key not in _PINV:
        _PINV[key] = np.linalg.pinv(h[use])
        _PINV[key].flags.writeable = False
    return _PINV[key]


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
        v_point = _add_cross(velocity_body, angular_rate, self.lever_arm)
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
    if finite.all():  # a simulated mission's: the same product without the NaN handling
        return np.ascontiguousarray(velocity) @ h.T  # C-ordered, as nan_to_num's copy was
    return np.where(finite[:, None], np.nan_to_num(velocity) @ h.T, np.nan)


# Compiled elementwise loops for the few-row blocks of the environment, where numpy's
# per-call overhead dominates: the same operations in the same order as the numpy
# expressions they replace (no fastmath), so the same bits. Products of matrices stay in
# numpy, whose rounding may depend on the shapes.

@numba.njit(cache=True)
def _add_cross(v: np.ndarray, w: np.ndarray, r: np.ndarray) -> np.ndarray:
    """(M, 3) ``v + w x r`` of (M, 3) v and w and a (3,) r, as np.cross computes w x r."""
    out = np.empty((len(v), 3))
    for m in range(len(v)):
        out[m, 0] = v[m, 0] + (w[m, 1] * r[2] - w[m, 2] * r[1])
        out[m, 1] = v[m, 1] + (w[m, 2] * r[0] - w[m, 0] * r[2])
        out[m, 2] = v[m, 2] + (w[m, 0] * r[1] - w[m, 1] * r[0])
    return out


@numba.njit(cache=True)
def _three_or_more(valid: np.ndarray) -> np.ndarray:
    """(M,) bool: at least 3 of a row's (M, 4) bool beams (``valid.sum(axis=1) >= 3``)."""
    out = np.empty(valid.shape[0], dtype=np.bool_)
    for m in range(valid.shape[0]):
        count = 0
        for k in range(valid.shape[1]):
            count += valid[m, k]
        out[m] = count >= 3
    return out


@numba.njit(cache=True)
def _measured_beams(signal: np.ndarray, scale: np.ndarray, bias: np.ndarray, ratio: float,
                    noise: np.ndarray) -> np.ndarray:
    """(M, 4) ``(1 + scale) (signal / ratio) + bias + noise`` of (M, 4) signal and noise,
    (4,) scale factors and biases, and the sound-speed ratio, m/s."""
    out = np.empty(signal.shape)
    for m in range(signal.shape[0]):
        for k in range(signal.shape[1]):
            out[m, k] = (1.0 + scale[k]) * (signal[m, k] / ratio) + bias[k] + noise[m, k]
    return out


@numba.njit(cache=True)
def _longest_horizontal(d: np.ndarray) -> float:
    """The largest horizontal length ``sqrt(n^2 + e^2)`` of (M, B, 3) vectors, as
    ``np.linalg.norm(d[..., :2], axis=-1).max()`` computes it (M B > 0)."""
    longest = -np.inf
    for m in range(d.shape[0]):
        for k in range(d.shape[1]):
            length = math.sqrt(d[m, k, 0] * d[m, k, 0] + d[m, k, 1] * d[m, k, 1])
            if math.isnan(length):
                return length  # as max propagates NaN
            longest = max(longest, length)
    return longest


class Effects(NamedTuple):
    """What a simulated mission's DVL adds to one block of M pings beyond eq. 7 (``ping``).

    Attributes:
        status: (M, 4) int bottom-lock reason codes (``lock_status``).
        sound_speed_ratio: c_true / c_assumed: every measured beam is divided by it.
        extra_noise: (M, 4) m/s, added to the bottom-track beams (the noise beyond
            ``noise_std`` that grows with range and speed), or None.
        outlier: (M, 4) bool, beam-pings whose bottom-track measurement is an outlier, or
            None: none is (``outlier_rate`` 0).
        outlier_error: (M, 4) m/s, the outliers' errors.
        water_velocity: (M, 3) m/s, in the DVL frame, the velocity over ground of the water
            layer the DVL tracks, or None: no water track.
        water_lock: (M, 4) bool, beams that can track it.
        water_noise: (M, 4) m/s, the water-track beams' noise.
        slow_error: (M, 3) m/s, DVL frame, the time-correlated velocity error dv
            (``slow_velocity_error``) added to every measured beam as ``H dv``, or None.
    """

    status: np.ndarray
    sound_speed_ratio: float
    extra_noise: np.ndarray | None
    outlier: np.ndarray | None
    outlier_error: np.ndarray
    water_velocity: np.ndarray | None
    water_lock: np.ndarray
    water_noise: np.ndarray
    slow_error: np.ndarray | None = None


def ping(velocity: np.ndarray, lock: np.ndarray, *, h: np.ndarray, errors: DvlErrors,
         noise_std: float, rng: np.random.Generator,
         effects: Effects | None = None) -> dict[str, np.ndarray]:
    """The DVL's pings, the one pipeline: true beams -> eq. 7 errors -> eq. 9 LS.

    With ``effects`` (a simulated mission), per beam k:
    ``y_k = (1 + s_k) (b_k . v') / ratio + bias_k + n_k + o_k``, where v' is v in bottom
    track and ``v - v_water`` in water track (a ping with fewer than 3 bottom-locked beams
    and at least 3 beams that can see the water layer, when water track is on), n_k the
    eq. 7 noise plus ``extra_noise`` in bottom track and ``water_noise`` in water track,
    and o_k the outlier error on bottom-locked outlier beams; ``slow_error`` dv adds
    ``b_k . dv`` to every beam, in either track (the instrument's own error).

    Args:
        velocity: (M, 3) true velocity over ground of the DVL in its frame, m/s (NaN rows:
            no measurement).
        lock: (M, 4) bool, beams with bottom lock (from the ray casts' ranges).
        h: (4, 3) beam matrix.
        errors: the mission's scale factors and biases.
        noise_std: beam noise, m/s.
        rng: the DVL's noise stream (one draw per beam and ping).
        effects: a simulated mission's effects beyond eq. 7 (``lock`` must then be
            ``effects.status == Status.OK``); None: eq. 7 alone.

    Returns:
        ``velocity``, ``beam_velocity_true`` (M, 4), ``beam_velocity`` (M, 4, NaN where not
        valid), ``valid`` (M, 4; the beam measured something on a finite ping) and
        ``velocity_ls`` (M, 3); with ``effects`` also ``status`` (M, 4), ``mode`` (M,) and
        ``error_velocity`` (M,).
    """
    finite = np.isfinite(velocity).all(axis=1)
    valid = lock & finite[:, None]
    beams_true = true_beams(velocity, h)
    if effects is None:
        beams = measure(beams_true, valid, errors=errors, noise_std=noise_std, rng=rng)
        return dict(velocity=velocity, beam_velocity_true=beams_true, beam_velocity=beams,
                    valid=valid, velocity_ls=least_squares(beams, h))
    e = effects
    noise = noise_std * rng.standard_normal(beams_true.shape)  # as eq. 7 draws it
    if e.extra_noise is not None:
        noise = noise + e.extra_noise
    mode = np.where(_three_or_more(valid), _BOTTOM_TRACK, _NO_VELOCITY)
    signal = beams_true
    if e.water_velocity is not None:
        water = (mode != _BOTTOM_TRACK) & _three_or_more(e.water_lock & finite[:, None])
        mode = np.where(water, _WATER_TRACK, mode)
        valid = np.where(water[:, None], e.water_lock & finite[:, None], valid)
        signal = np.where(water[:, None], true_beams(velocity - e.water_velocity, h), signal)
        noise = np.where(water[:, None], e.water_noise, noise)
    if e.slow_error is not None:
        noise = noise + e.slow_error @ h.T
    y = _measured_beams(signal, errors.scale_factor, errors.bias, e.sound_speed_ratio, noise)
    if e.outlier is None:
        status = e.status.astype(np.int64)
    else:
        outlier = e.outlier & lock & (mode != _WATER_TRACK)[:, None]
        y = np.where(outlier, y + e.outlier_error, y)
        status = np.where(outlier, _OUTLIER, e.status).astype(np.int64)
    beams = np.where(valid, y, np.nan)
    return dict(velocity=velocity, beam_velocity_true=beams_true, beam_velocity=beams,
                valid=valid, velocity_ls=least_squares(beams, h), status=status,
                mode=mode.astype(np.int64), error_velocity=error_velocity(beams, h))


def config_attrs(config: DvlConfig, errors: DvlErrors) -> dict[str, object]:
    """The DVL attributes every mission carries, simulated or imported."""
    return dict(dvl_rate_hz=config.rate_hz, beam_angle_deg=config.beam_angle_deg,
                dvl_scale_factor=errors.scale_factor, dvl_bias=errors.bias,
                dvl_noise_std=config.noise_std)


def synthesise(velocity: np.ndarray, config: DvlConfig,
               streams: dict[str, np.random.Generator]) -> tuple[dict[str, np.ndarray], dict]:
    """The DVL fields and attributes of a recorded DVL-frame velocity stream (N, 3) taken
    as the truth, with the error model of ``config`` (the beam-synthesis half of the
    pipeline: every finite ping has bottom lock). Eq. 7 alone: the effects beyond it
    (lost lock, outliers, sound speed, water track) need a simulated mission's geometry
    and are not applied, so an import writes what it always wrote.

    Args:
        velocity: (N, 3) m/s, one row per ping.
        config: beam angle, rate and error model (ranges and mounting are not used).
        streams: the ``dvl_parameters`` and ``dvl_noise`` streams (``auvsim.data.streams``).

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


# The columns of a block's draws from ``dvl_faults``' children (``Dvl.effects``), each
# block drawn whole in ping order. A new drawn effect takes a child of its own, spawned
# after these three, never a column more: one more column moves every later draw of
# every realistic dataset (``tests/test_pinned_data.py``).
_UNIFORMS = 17  # per ping:
_U_LOSS = slice(0, 8)  # echo loss 4, grazing loss 4
_U_DROPOUT = slice(8, 12)  # the dropout chain 4
_U_PING = slice(12, 13)  # ping dropout 1
_U_OUTLIER = slice(13, 17)  # outliers 4
_NORMALS = 8  # per ping:
_N_EXTRA = slice(0, 4)  # the noise beyond noise_std 4
_N_WATER = slice(4, 8)  # water-track noise 4


class Dvl(Sensor):
    """The Janus DVL: beams ray-cast on the seafloor from the DVL site, with the lever
    arm and the true mounting, then ``ping`` with the effects of ``DvlConfig``. Pings
    fall on IMU samples that are whole multiples of the ping interval (``sample_rows``);
    ``imu/index_of_dvl`` records them.

    Streams: ``dvl_parameters`` (scale factors, biases), ``dvl_noise`` (eq. 7's noise),
    ``dvl_calibration`` (sound-speed ratio, misalignment), ``dvl_slow_error`` (the
    Gauss-Markov velocity error, drawn only when ``slow_error_std`` > 0: its start, then
    three normals per ping) and ``dvl_faults``, split into
    three children each drawn once per block in ping order, so that blocks of any length
    give the same pings: uniforms (M, 17: echo loss 4, grazing loss 4, dropout chain 4,
    ping dropout 1, outliers 4; the chain's first state 4 at the start), normals (M, 8:
    the noise beyond ``noise_std`` 4, water-track noise 4) and Student t (M, 4: outliers).
    """

    name = "dvl"
    section = "dvl"
    # dvl_slow_error is not in STREAMS: spawned after every earlier stream (stream_names).
    streams = ("dvl_parameters", "dvl_noise", "dvl_calibration", "dvl_faults",
               "dvl_slow_error")
    fields = (
        Field("dvl/time", (), "f", "dvl", "s", "ping times", imported=True),
        Field("dvl/velocity", (3,), "f", "dvl", "m/s", "TRUE DVL velocity in the (true) DVL "
              "frame: the regression target", imported=True),
        Field("dvl/beam_velocity_true", (4,), "f", "dvl", "m/s", "H v, over ground (in "
              "water track too)", imported=True),
        Field("dvl/beam_velocity", (4,), "f", "dvl", "m/s", "measured (NaN where the beam "
              "measured nothing)", imported=True),
        Field("dvl/beam_range", (4,), "f", "dvl", "m", "slant range to the seafloor (NaN: "
              "no hit within max_range; a hit nearer than min_range is kept but not valid)"),
        Field("dvl/valid", (4,), "b", "dvl", "-", "the beam measured (bottom lock, or the "
              "water in water track)", imported=True),
        Field("dvl/velocity_ls", (3,), "f", "dvl", "m/s", "LS estimate from the measured "
              "beams (NaN if < 3 valid)", imported=True),
        Field("dvl/status", (4,), "i", "dvl", "-", "bottom-lock reason code per beam "
              "(auvsim.sensors.dvl.Status: 0 ok, 1 no hit within max_range, 2 nearer than "
              "min_range, 3 echo lost, 4 grazing angle, 5 dropout, 6 ping dropout, "
              "7 beam failed, 8 lock lost, 9 outlier)", since=4),
        Field("dvl/error_velocity", (), "f", "dvl", "m/s", "the instrument's error velocity "
              "d (y1 + y3 - y2 - y4), NaN unless all 4 beams measured", since=4),
        Field("dvl/mode", (), "i", "dvl", "-", "0 bottom track, 1 water track, -1 no "
              "velocity (auvsim.sensors.dvl.Mode)", since=4),
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
        Attr("dvl_mounting_rpy_deg", (3,), "NOMINAL DVL frame -> body, ZYX, deg (what the "
             "user assumes)"),
        Attr("dvl_position_body", (3,), "m, FRD"),
        Attr("dvl_sound_speed_ratio", (), "REALISED c_true / c_assumed: the measured beams "
             "are divided by it", low=0, strict=True, since=4),
        Attr("dvl_misalignment_rpy_deg", (3,), "REALISED misalignment, true DVL frame -> "
             "nominal DVL frame, ZYX, deg", since=4),
        Attr("dvl_slow_error_std", (), "std of the Gauss-Markov velocity error dv per DVL "
             "axis, m/s (0: none)", low=0, since=7),
        Attr("dvl_slow_error_time", (), "its correlation time, s", low=0, strict=True,
             since=7),
        Attr("dvl_slow_error_start", (3,), "REALISED dv at t = 0, DVL frame, m/s", since=7),
    )

    def __init__(self, config, platform, parameters, calibration, faults, slow):
        c = self.config = config.dvl
        self.platform = platform
        self.errors = draw_errors(c, parameters)
        self.calibration = draw_calibration(c, calibration)
        self.geometry = DvlGeometry.from_config(c, platform.vehicle.dvl_position)
        if c.misalignment_std_deg > 0:  # else the nominal matrices, bit for bit
            misalignment = rotation_rpy(*np.radians(self.calibration.misalignment_rpy_deg))
            self.geometry = self.geometry._replace(
                mounting=self.geometry.mounting @ misalignment)
        self.every_imu = self.every(config)
        self.uniform, self.normal, self.heavy = faults.spawn(3)
        self.in_burst = self.uniform.random(4) < c.dropout_rate  # a stationary start
        self.slow_rng = slow
        # Started stationary, as the IMU's Gauss-Markov biases are; no draw when off.
        self.slow_state = (c.slow_error_std * slow.standard_normal(3) if c.slow_error_std > 0
                           else np.zeros(3))
        self.slow_start = self.slow_state.copy()

    def rows(self, n_imu):
        return {"dvl": samples_in(n_imu, self.every_imu)}

    @classmethod
    def describe(cls, mission):
        return describe_mission(mission)

    def attrs(self):
        c = self.config
        return dict(config_attrs(c, self.errors), dvl_min_range=c.min_range,
                    dvl_max_range=c.max_range, dvl_mounting_rpy_deg=c.mounting_rpy_deg,
                    dvl_position_body=self.platform.vehicle.dvl_position,
                    dvl_sound_speed_ratio=self.calibration.sound_speed_ratio,
                    dvl_misalignment_rpy_deg=self.calibration.misalignment_rpy_deg,
                    dvl_slow_error_std=c.slow_error_std,
                    dvl_slow_error_time=c.slow_error_time,
                    dvl_slow_error_start=self.slow_start)

    def measure(self, truth, rng):
        c, vehicle, seafloor = self.config, self.platform.vehicle, self.platform.seafloor
        rows = sample_rows(truth.first, len(truth.time), self.every_imu)
        if rows.start >= len(truth.time):
            return _no_pings()
        time = truth.time[rows]
        velocity = self.geometry.velocity(truth.velocity_body[rows], truth.angular_rate[rows])
        rotation = rotation_matrices(truth.quaternion[rows])
        origins, directions = self.geometry.rays(truth.position_ned[rows], rotation)
        reach = c.max_range * _longest_horizontal(directions)
        try:
            seafloor.follow(origins[:, :2], reach=reach)
        except ValueError as e:
            raise ConfigError(
                f"dvl.max_range: {c.max_range:g} m beams reach beyond the procedural terrain "
                f"window ({e}); expected a shorter max_range or a larger seafloor.cell_size"
            ) from None
        ranges = seafloor.cast(vehicle.model, self.platform.ray_data, origins, directions,
                               max_range=c.max_range, exclude_body=vehicle.body_id)
        effects = self.effects(time, velocity, ranges, origins, directions, rotation)
        fields = ping(velocity, effects.status == _OK, h=self.geometry.h,
                      errors=self.errors, noise_std=c.noise_std, rng=rng, effects=effects)
        out = {"dvl/time": time}
        out.update((f"dvl/{k}", v) for k, v in fields.items())
        out["dvl/beam_range"] = ranges
        first = truth.first + rows.start
        out["imu/index_of_dvl"] = np.arange(first, first + self.every_imu * len(velocity),
                                            self.every_imu, dtype=np.int64)
        return out

    def effects(self, time: np.ndarray, velocity: np.ndarray, ranges: np.ndarray,
                origins: np.ndarray, directions: np.ndarray, rotation: np.ndarray) -> Effects:
        """A block's effects beyond eq. 7, from its pings' times (M,) s, DVL velocities
        (M, 3) m/s, slant ranges (M, 4) m, beam origins (M, 3) m and directions
        (M, 4, 3) in NED, and body -> NED rotations (M, 3, 3)."""
        c, m = self.config, len(time)
        u = self.uniform.random((m, _UNIFORMS))
        n = self.normal.standard_normal((m, _NORMALS))
        t = self.heavy.standard_t(3, (m, 4))
        incidence = None
        if c.grazing_loss_angle_deg is not None:
            hits = origins[:, None, :] + _nan_to_zero(ranges)[..., None] * directions
            normal = self.platform.seafloor.normal_at(hits[..., 0], hits[..., 1])
            cos_incidence = np.clip(-np.einsum("mki,mki->mk", directions, normal), -1, 1)
            incidence = np.where(np.isfinite(ranges), np.degrees(np.arccos(cos_incidence)),
                                 np.nan)
        dropout = markov_dropouts(u[:, _U_DROPOUT], self.in_burst, rate=c.dropout_rate,
                                  burst=c.dropout_burst)
        if m:
            self.in_burst = dropout[-1]
        status = lock_status(time, ranges, config=c, incidence_deg=incidence,
                             u=np.concatenate([u[:, _U_LOSS], u[:, _U_PING]], axis=1),
                             dropout=dropout)
        extra = None
        if c.noise_range_coeff > 0 or c.noise_speed_coeff > 0:
            std = beam_noise_std(ranges, np.linalg.norm(velocity, axis=1), c)
            extra = np.sqrt(np.maximum(std**2 - c.noise_std**2, 0.0)) * n[:, _N_EXTRA]
        water, water_lock = None, np.zeros((m, 4), dtype=bool)
        if c.water_track:
            water = self.water_velocity(time, origins, rotation)
            # The layer must lie above the seafloor along the beam; a lost or dead ping
            # or beam measures nothing either way.
            layer = c.water_track_range / np.where(directions[..., 2] > 0,
                                                   directions[..., 2], np.nan)
            water_lock = ((~np.isfinite(ranges) | (ranges > layer)) & np.isfinite(layer)
                          & (status != _PING_DROPOUT) & (status != _BEAM_FAILED))
        slow = None
        if c.slow_error_std > 0:
            slow = slow_velocity_error(self.slow_state, m, std=c.slow_error_std,
                                       time=c.slow_error_time, dt=1.0 / c.rate_hz,
                                       rng=self.slow_rng)
        return Effects(status=status, sound_speed_ratio=self.calibration.sound_speed_ratio,
                       extra_noise=extra,
                       outlier=(u[:, _U_OUTLIER] < c.outlier_rate if c.outlier_rate > 0
                                else None),
                       outlier_error=c.outlier_std / math.sqrt(3.0) * t,
                       water_velocity=water, water_lock=water_lock,
                       water_noise=c.water_track_noise_std * n[:, _N_WATER], slow_error=slow)

    def water_velocity(self, time: np.ndarray, origins: np.ndarray,
                       rotation: np.ndarray) -> np.ndarray:
        """(M, 3) velocity over ground of the water ``water_track_range`` below the DVL,
        in the DVL frame, m/s: the platform's current there (still water without one)."""
        water = getattr(self.platform, "water", None)
        if water is None:
            return np.zeros((len(time), 3))
        layer = origins + np.array([0.0, 0.0, self.config.water_track_range])
        current_ned = np.asarray(water.current_ned(time, layer), dtype=float)
        current_body = np.einsum("mji,mj->mi", rotation, current_ned)  # R^T c
        return current_body @ self.geometry.mounting  # rows of mounting^T c


def _empty(field: Field) -> np.ndarray:
    empty = np.empty((0, *field.shape), dtype={"f": float, "b": bool, "i": np.int64}[field.kind])
    empty.flags.writeable = False
    return empty


# Made once: most environment steps fall between pings.
_NO_PINGS = {f.path: _empty(f) for f in Dvl.fields}


def usable_beams(valid: np.ndarray, beam_velocity: np.ndarray) -> np.ndarray:
    """(M, 4) bool: the beams that measured, flagged ``valid`` (M, 4) with a finite
    ``beam_velocity`` (M, 4, m/s). A file may flag NaN beams valid (an edited one, or a
    recording): they are not velocities."""
    return np.asarray(valid, dtype=bool) & np.isfinite(beam_velocity)


def clean_error_pings(error: np.ndarray, mode: np.ndarray, status: np.ndarray) -> np.ndarray:
    """(M,) bool: the pings whose error velocity (M,) an instrument's own is compared with
    (a real log's is the bottom track's, and holds no outlier): bottom-track pings
    (``mode`` (M,)) with a finite error velocity and no outlier beam (``status`` (M, 4))."""
    return (np.isfinite(error) & (mode == Mode.BOTTOM_TRACK)
            & ~(status == Status.OUTLIER).any(axis=1))


def describe_mission(mission) -> list[str]:
    """What ``auvsim inspect`` prints of a mission's DVL (``Dvl.describe``)."""
    a, dvl = mission.attrs, mission.dvl
    usable = usable_beams(dvl.valid, dvl.beam_velocity)
    share = 100 * usable.mean() if usable.size else 0.0
    solvable = 100 * (usable.sum(axis=1) >= 3).mean() if len(usable) else 0.0
    lines = [f"    DVL {a['dvl_rate_hz']:g} Hz ({len(usable)} pings), beams at "
             f"{a['beam_angle_deg']:g} deg, {share:.1f} % of beams valid, {solvable:.1f} % of "
             "pings solvable",
             f"    DVL errors: scale factor {shown(a['dvl_scale_factor'])}, bias "
             f"{shown(a['dvl_bias'])} m/s, noise std {a['dvl_noise_std']:g} m/s"]
    if a.get("dvl_slow_error_std", 0) > 0:
        lines[-1] += (f", slow error std {a['dvl_slow_error_std']:g} m/s over "
                      f"{a['dvl_slow_error_time']:g} s (Gauss-Markov)")
    effects = (config_effects(json.loads(mission.dataset.config_json or "{}").get("dvl", {}))
               if mission.origin == "simulated" else [])
    if effects:  # the config's (no attribute holds them)
        lines.append(f"    DVL effects (config): {'; '.join(effects)}")
    if "dvl_sound_speed_ratio" in a:
        lines.append(f"    DVL calibration: sound-speed ratio {a['dvl_sound_speed_ratio']:.6f}, "
                     f"misalignment {shown(a['dvl_misalignment_rpy_deg'])} deg (roll, pitch, "
                     "yaw)")
    if "status" in dvl:
        status = dvl.status
        counts = np.bincount(status.ravel().clip(0, len(Status) - 1), minlength=len(Status))
        shares = ", ".join(f"{Status(code).name.lower()} {100 * n / status.size:.1f} %"
                           for code, n in enumerate(counts) if n)
        lines.append(f"    DVL beam status: {shares}")
    if "mode" in dvl:
        mode = dvl.mode
        shares = ", ".join(f"{x.name.lower().replace('_', ' ')} "
                           f"{100 * np.mean(mode == x):.1f} %" for x in Mode)
        error = dvl.error_velocity
        finite = error[np.isfinite(error)]
        rms = f"{np.sqrt(np.mean(finite**2)):.3g} m/s" if finite.size else "none"
        lines.append(f"    DVL modes: {shares}; error velocity rms {rms} over "
                     f"{finite.size} four-beam pings")
        if "status" in dvl:  # one outlier sets the rms above
            clean = clean_error_pings(error, mode, status)
            if clean.any():
                lines[-1] += (f" ({np.sqrt(np.mean(error[clean] ** 2)):.3g} m/s over the "
                              f"{int(clean.sum())} bottom-track pings without an outlier)")
    return lines


def config_effects(dvl: dict) -> list[str]:
    """In words, the effects a DVL config (``config_json``'s ``dvl`` table) turns on
    beyond eq. 7 that no attribute records: the noise's growth, the losses, dropouts,
    failures, outliers and water track; none for a config without them (or none)."""
    def interval(start, end) -> str:
        return f"{start:g}-{end:g} s"

    try:
        c = DvlConfig(**dvl)
    except (TypeError, ValueError):  # none, or another version's: nothing to say of it
        return []
    growth = [f"{coeff:g} {unit}" for coeff, unit in ((c.noise_speed_coeff, "m/s per m/s of "
                                                       "speed"),
                                                      (c.noise_range_coeff, "m/s per m of "
                                                       "range")) if coeff > 0]
    out = ["beam noise + " + " + ".join(growth)] if growth else []
    if c.echo_loss_range is not None:
        out.append(f"echoes fade at {c.echo_loss_range:g} m of range "
                   f"(width {c.echo_loss_width:g} m)")
    if c.grazing_loss_angle_deg is not None:
        out.append(f"grazing loss from {c.grazing_loss_angle_deg:g} deg of incidence")
    if c.dropout_rate > 0:
        out.append(f"dropouts {100 * c.dropout_rate:g} % of beams in bursts of "
                   f"{c.dropout_burst:g} pings")
    if c.ping_dropout_rate > 0:
        out.append(f"{100 * c.ping_dropout_rate:g} % of pings lost")
    out += [f"beam {beam} dead {interval(start, end)}" for beam, start, end in c.beam_failures]
    out += [f"lock lost {interval(start, end)}" for start, end in c.lock_loss_intervals]
    if c.outlier_rate > 0:
        out.append(f"outliers {100 * c.outlier_rate:g} % of beams, std {c.outlier_std:g} m/s")
    if c.water_track:
        out.append(f"water track {c.water_track_range:g} m below, noise "
                   f"{c.water_track_noise_std:g} m/s")
    return out


def _no_pings() -> dict[str, np.ndarray]:
    """The DVL fields of a block without a ping (an environment step between pings): empty
    and read-only."""
    return dict(_NO_PINGS)


SENSOR = Dvl
