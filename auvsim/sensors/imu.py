"""IMU error model: true specific force and angular rate in, measured values out.

At sample k of a mission, for the accelerometer triad (f) and the gyro triad (w), in the
form of Groves (Principles of GNSS, Inertial, and Multisensor Integrated Navigation
Systems, 2nd ed., 2013, eqs. 4.16-4.17)::

    f_meas[k] = (I + S_a + M_a) f[k]          + turn_on_bias_a + b_a[k] + n_a[k]
    w_meas[k] = (I + S_g + M_g) w[k] + G f[k] + turn_on_bias_g + b_g[k] + n_g[k]
    b[k + 1]  = phi b[k] + sigma_b sqrt(1 - phi^2) u[k],   phi = exp(-dt / tau)
    n[k]      = density sqrt(rate) v[k]

S = diag(s_x, s_y, s_z) holds the scale-factor errors, M (zero diagonal) the six
cross-coupling terms of axis misalignment (non-orthogonality of the triad and its mounting
in the body; a small rotation is the antisymmetric part), and G the gyros' g-sensitivity,
rad/s per m/s^2 of the true specific force. S, M and G are drawn once per mission,
N(0, std^2) per element (``draw_calibration``), and so are the turn-on biases,
N(0, turn_on^2) per axis (``draw_biases``); b is a first-order Gauss-Markov process per
axis (steady-state std sigma_b = ``*_bias_instability``, correlation time tau, one per
triad: ``ImuConfig.accel_tau``, ``gyro_tau``), discretised exactly
(``auvsim.sensors.gauss_markov``) and started from its stationary distribution,
b[0] ~ N(0, sigma_b^2); u, v ~ N(0, 1) white. There is no
quantisation or saturation. With S, M and G zero (every config before them) the output is
bitwise that of the additive model: the products are skipped, not multiplied by zero.

A vehicle's vibration (``ImuConfig.accel_vibration_std`` and ``_per_rate``, likewise for
the gyros, per axis; zero by default) is added to every sample, after the bias terms::

    x[k] = (sigma_0 + s |r[k]|) (e[k] - e[k - 1]) / sqrt(2),   e ~ N(0, 1) white per axis

with r the true body-z rate the gyros sense (with a geographic origin the Earth's share
too, 7e-5 rad/s at most): a vehicle's hull and fins shake more in a turn (on the Snapir's
logs the IMU's content above 10 Hz is 6 to 10 mm/s^2 in straight flight and about 100 in
its hardest turns: ``auvsim.runs.presets.SNAPIR_VIBRATION``). At a steady rate it is the
first difference of a white sequence: std sigma_0 + s |r|, zero mean, and a spectrum that
rises as sin^2(pi f / rate) from nothing at zero frequency to the most at the Nyquist
frequency (98.7 % of its power above 10 Hz at 100 Hz). Its sum telescopes, so the
velocity (the angle) it adds to an integration is sigma dt (e[k] - e[-1]) / sqrt(2), e[-1]
the draw before the first sample: bounded, as vibration moves the sensor back and forth
and does not drift it. A std that changes with the rate leaves besides sum_k e[k]
(sigma[k] - sigma[k + 1]) dt / sqrt(2), of std dt sqrt(sum_k (sigma[k + 1] - sigma[k])^2
/ 2): small where the rate changes slowly against the sample rate (a turn that builds
over a few seconds moves sigma by a few thousandths of its range from one sample to the
next), but not bounded. The shape is a model: a real IMU's vibration has lines (the
Snapir's Phins one at 24 Hz) where this one spreads its power over the band. A config
without vibration keeps every draw and every bit of its output.

The true values are the truth's: f its ``specific_force`` and w its ``angular_rate``, the
body's rate in the local NED frame. With a geographic origin (``auvsim.config.
LocationConfig``) the gyros measure the rate in inertial space, ``w = w_nb + C^T w_ie``
(``auvsim.physics.earth.earth_rate_body``), and f is already the rotating Earth's (normal
gravity and the Coriolis term; the truth holds it so); without one the world is flat and
does not rotate, w = w_nb, and the output is what it always was.

Units (see ``auvsim``): specific force in m/s^2, angular rate in rad/s, body FRD axes.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import NamedTuple

import numba
import numpy as np

from auvsim.config import ImuConfig
from auvsim.physics.earth import earth_rate_body
from auvsim.physics.frames import rotation_matrices
from auvsim.sensors import Attr, Field, Sensor, shown
from auvsim.sensors.gauss_markov import gauss_markov_rows

G0 = 9.80665  # m/s^2, standard gravity: the g of micro-g and mg in datasheets
DEG = math.pi / 180.0  # rad per degree
HOUR = 3600.0  # s
MICRO_G = 1e-6 * G0  # m/s^2
MILLI_G = 1e-3 * G0  # m/s^2


def _deg_per_hour(x: float) -> float:
    """deg/h -> rad/s (a bias)."""
    return x * DEG / HOUR


def _deg_per_root_hour(x: float) -> float:
    """Angle random walk, deg/sqrt(h) -> rad/s/sqrt(Hz): sqrt(3600 s) = 60 sqrt(s)."""
    return x * DEG / 60.0


def _deg_per_hour_per_g(x: float) -> float:
    """g-sensitivity, deg/h/g -> rad/s per m/s^2."""
    return _deg_per_hour(x) / G0


# Where sensors.md quotes a bias without saying whether it is the in-run (Gauss-Markov)
# part or the per-mission turn-on spread, we read a range "lo to hi" as lo = in-run and
# hi = turn-on. The in-run figure is used as the Gauss-Markov sigma directly: a GM
# process's Allan deviation peaks at 0.62 sigma (at 1.89 tau), the flicker floor of a
# datasheet's bias instability B is 0.66 B, so sigma ~ B to within 10 %.
IMU_GRADES: dict[str, ImuConfig] = {
    # The truth, unchanged.
    "ideal": ImuConfig(
        rate_hz=100.0,
        accel_noise_density=0.0,
        gyro_noise_density=0.0,
        accel_turn_on_bias=0.0,
        gyro_turn_on_bias=0.0,
        accel_bias_instability=0.0,
        gyro_bias_instability=0.0,
    ),
    # iXblue Phins class, the Snapir's INS.
    "navigation": ImuConfig(
        rate_hz=100.0,
        # Our assumption: ../shared/reference/sensors.md gives no accelerometer noise figure.
        # 20 micro-g/sqrt(Hz) is the aviation-grade IMU of Groves, "Principles of GNSS,
        # Inertial, and Multisensor Integrated Navigation Systems" (2nd ed., example
        # INS_GNSS_Demo_12), whose gyro ARW (0.002 deg/sqrt(h)) matches the Phins'.
        accel_noise_density=20.0 * MICRO_G,
        # ARW 0.0025 deg/sqrt(h): ../shared/reference/sensors.md.
        gyro_noise_density=_deg_per_root_hour(0.0025),
        # 50 micro-g, the high end of "10 to 50 micro-g": ../shared/reference/sensors.md.
        accel_turn_on_bias=50.0 * MICRO_G,
        # 0.01 deg/h, the single bias figure of ../shared/reference/sensors.md, taken as
        # the turn-on spread too (our assumption: a FOG's turn-on repeatability is of the
        # order of its in-run stability).
        gyro_turn_on_bias=_deg_per_hour(0.01),
        # 10 micro-g, the low end of "10 to 50 micro-g": ../shared/reference/sensors.md.
        accel_bias_instability=10.0 * MICRO_G,
        # Bias stability 0.01 deg/h: ../shared/reference/sensors.md.
        gyro_bias_instability=_deg_per_hour(0.01),
        # Our assumption: sensors.md gives none. Navigation-grade biases wander over hours,
        # so one hour, about the length of a mission (and ImuConfig's default).
        bias_correlation_time=3600.0,
    ),
    # VectorNav VN-100 class MEMS.
    "mems": ImuConfig(
        rate_hz=100.0,
        # 0.14 mg/sqrt(Hz): ../shared/reference/sensors.md.
        accel_noise_density=0.14 * MILLI_G,
        # ARW 0.2 deg/sqrt(h): ../shared/reference/sensors.md.
        gyro_noise_density=_deg_per_root_hour(0.2),
        # Our assumption: sensors.md gives no turn-on figure, and its 0.04 mg in-run figure
        # would make the turn-on spread smaller than the navigation grade's. 1 mg is the low
        # end of the tactical class's accelerometer bias (1 to 5 mg) in El-Sheimy & Youssef,
        # Satellite Navigation 1:2 (2020), Table 1, the class the VN-100's 5 to 10 deg/h
        # gyro drift puts it in; a factory-calibrated unit sits at its good end.
        accel_turn_on_bias=1.0 * MILLI_G,
        # 10 deg/h, the high end of "5 to 10 deg/h": ../shared/reference/sensors.md.
        gyro_turn_on_bias=_deg_per_hour(10.0),
        # Bias stability 0.04 mg: ../shared/reference/sensors.md.
        accel_bias_instability=0.04 * MILLI_G,
        # 5 deg/h, the low end of "5 to 10 deg/h": ../shared/reference/sensors.md.
        gyro_bias_instability=_deg_per_hour(5.0),
        # Our assumption: sensors.md gives none. MEMS Allan curves bottom out at averaging
        # times of a few hundred seconds, and a GM's Allan peak sits at 1.89 tau; 300 s.
        bias_correlation_time=300.0,
    ),
}


# The three grades above have additive errors only; the paper's presets (paper-sim,
# paper-sim-text, maneuvers) fly "navigation", so their data stays as it was. Each "-full"
# grade is the same unit with the errors a strapdown user calibrates as well: scale
# factors, misalignment, g-sensitivity, and a bias correlation time per triad.
IMU_GRADES["navigation-full"] = dataclasses.replace(
    IMU_GRADES["navigation"],
    # Groves (2013), the aviation-grade IMU of the book's example INS_GNSS_Demo_12 (the
    # same unit the accelerometer noise above comes from; sensors.md gives no figure):
    # accelerometer scale factors 100, -120, 90 ppm, RMS 104 ppm; cross-coupling 40 to
    # 120 ppm, RMS 88 ppm; gyro scale factors 8, -6, -7 ppm, RMS 7 ppm; gyro
    # cross-coupling 60 to 120 ppm (in three of the six places, the triad there defining
    # the body axes), RMS over the three 97 ppm. We take each RMS, rounded, as the
    # per-element std, and the gyro's over all six places because our body axes are the
    # vehicle's, which a mounting error turns against every axis (our choice).
    accel_scale_factor_std=100e-6,
    accel_misalignment_std=90e-6,
    gyro_scale_factor_std=7e-6,
    gyro_misalignment_std=100e-6,
    # Zero, as in the same example: optical (fibre-optic, ring-laser) gyros such as the
    # Phins' have no proof mass, so no g-dependent bias worth a term.
    gyro_g_sensitivity_std=0.0,
    # Our choice, no source gives per-triad times: the gyros keep the grade's one hour; the
    # accelerometers half of it, so that the two triads' biases decorrelate apart.
    accel_bias_correlation_time=1800.0,
    gyro_bias_correlation_time=3600.0,
)
IMU_GRADES["mems-full"] = dataclasses.replace(
    IMU_GRADES["mems"],
    # Groves (2013), the tactical-grade IMU of the book's example Inertial_Demo_1NED, the
    # class the VN-100's 5 to 10 deg/h gyro drift puts it in (see "mems" above):
    # accelerometer scale factors 500, -600, 450 ppm, RMS 520 ppm; gyro scale factors
    # 400, -300, -350 ppm, RMS 352 ppm; the std is each RMS, rounded.
    accel_scale_factor_std=500e-6,
    gyro_scale_factor_std=350e-6,
    # VectorNav VN-100 datasheet (specifications table; not among the figures of
    # ../shared/reference/sensors.md): alignment error +/-0.05 deg for both triads, taken as
    # the std of each cross-coupling term (as the DVL's accuracy figure is taken as a
    # spread in the presets). It is above Groves' tactical cross-coupling (RMS 220 ppm,
    # 0.013 deg): the VN-100's figure is its own.
    accel_misalignment_std=0.05 * DEG,
    gyro_misalignment_std=0.05 * DEG,
    # Groves (2013), the same tactical-grade example: g-dependent gyro biases of 0.3 to
    # 1.9 deg/h/g in all nine places, RMS 1.14 deg/h/g; 1.1 deg/h/g per element.
    gyro_g_sensitivity_std=_deg_per_hour_per_g(1.1),
    # Our choice, no source gives per-triad times: the gyros keep the grade's 300 s, the
    # accelerometers half of it, as in "navigation-full".
    accel_bias_correlation_time=150.0,
    gyro_bias_correlation_time=300.0,
)


class ImuBiases(NamedTuple):
    """The constant turn-on biases of one mission."""

    accel: np.ndarray  # (3,) m/s^2, body FRD
    gyro: np.ndarray  # (3,) rad/s, body FRD


def draw_biases(config: ImuConfig, rng: np.random.Generator) -> ImuBiases:
    """Draw a mission's turn-on biases, N(0, std^2) per axis.

    Args:
        config: ``accel_turn_on_bias`` (m/s^2) and ``gyro_turn_on_bias`` (rad/s) are the
            standard deviations.
        rng: source of the six draws (accel x, y, z, then gyro x, y, z), made even when a
            std is zero so that one sensor's setting never shifts the other's draw.

    Returns:
        The biases; exactly zero (not -0.0) where the std is zero.
    """
    z = rng.standard_normal(6)
    accel = config.accel_turn_on_bias * z[:3] if config.accel_turn_on_bias else np.zeros(3)
    gyro = config.gyro_turn_on_bias * z[3:] if config.gyro_turn_on_bias else np.zeros(3)
    return ImuBiases(accel, gyro)


class ImuCalibration(NamedTuple):
    """The scale-factor, misalignment and g-sensitivity errors of one mission."""

    accel_scale_factor: np.ndarray  # (3,) -, the diagonal of S_a
    gyro_scale_factor: np.ndarray  # (3,) -, the diagonal of S_g
    accel_misalignment: np.ndarray  # (3, 3) rad, M_a, zero diagonal
    gyro_misalignment: np.ndarray  # (3, 3) rad, M_g, zero diagonal
    gyro_g_sensitivity: np.ndarray  # (3, 3) rad/s per m/s^2, G

    @property
    def accel_matrix(self) -> np.ndarray:
        """(3, 3) S_a + M_a: measured f = (I + S_a + M_a) f + ..."""
        return np.diag(self.accel_scale_factor) + self.accel_misalignment

    @property
    def gyro_matrix(self) -> np.ndarray:
        """(3, 3) S_g + M_g: measured w = (I + S_g + M_g) w + G f + ..."""
        return np.diag(self.gyro_scale_factor) + self.gyro_misalignment


NO_CALIBRATION_ERRORS = ImuCalibration(np.zeros(3), np.zeros(3), np.zeros((3, 3)),
                                       np.zeros((3, 3)), np.zeros((3, 3)))
for _zeros in NO_CALIBRATION_ERRORS:  # a shared default: nobody may change it
    _zeros.flags.writeable = False
_OFF_DIAGONAL = ~np.eye(3, dtype=bool)  # row-major: (0, 1), (0, 2), (1, 0), (1, 2), ...


def draw_calibration(config: ImuConfig, rng: np.random.Generator) -> ImuCalibration:
    """Draw a mission's scale-factor, misalignment and g-sensitivity errors, N(0, std^2)
    per element.

    Args:
        config: ``accel_scale_factor_std``, ``gyro_scale_factor_std`` (-),
            ``accel_misalignment_std``, ``gyro_misalignment_std`` (rad) and
            ``gyro_g_sensitivity_std`` (rad/s per m/s^2).
        rng: source of the 27 draws, made whatever the stds, in this order: accel scale
            factors x, y, z; gyro scale factors; accel misalignment (the six off-diagonal
            places, row-major); gyro misalignment; gyro g-sensitivity (nine, row-major).
            One setting never shifts another's draw.

    Returns:
        The errors; exactly zero (not -0.0) where the std is zero, and on the diagonals
        of the misalignments.
    """
    z = rng.standard_normal(27)

    def scaled(std: float, draws: np.ndarray) -> np.ndarray:
        return std * draws if std else np.zeros_like(draws)

    def off_diagonal(std: float, draws: np.ndarray) -> np.ndarray:
        out = np.zeros((3, 3))
        out[_OFF_DIAGONAL] = scaled(std, draws)
        return out

    return ImuCalibration(
        accel_scale_factor=scaled(config.accel_scale_factor_std, z[0:3]),
        gyro_scale_factor=scaled(config.gyro_scale_factor_std, z[3:6]),
        accel_misalignment=off_diagonal(config.accel_misalignment_std, z[6:12]),
        gyro_misalignment=off_diagonal(config.gyro_misalignment_std, z[12:18]),
        gyro_g_sensitivity=scaled(config.gyro_g_sensitivity_std, z[18:27]).reshape(3, 3))


class _Channel:
    """One sensor triad's errors and their random streams."""

    def __init__(self, bias: np.ndarray, noise_std: float, gm_std: float, tau_rate: float,
                 noise_rng: np.random.Generator, gm_rng: np.random.Generator,
                 matrix: np.ndarray, g_matrix: np.ndarray | None = None,
                 vibration: tuple[np.ndarray, np.ndarray] | None = None,
                 vibration_rng: np.random.Generator | None = None) -> None:
        """Derive the triad's constants and draw its initial Gauss-Markov state.

        Args:
            bias: (3,) turn-on bias.
            noise_std: white noise std per sample.
            gm_std: Gauss-Markov steady-state std.
            tau_rate: correlation time x sample rate (tau / dt), samples.
            noise_rng, gm_rng: the white noise's and the Gauss-Markov drive's streams.
            matrix: (3, 3) S + M, the triad's scale factors and misalignment.
            g_matrix: (3, 3) G, rad/s per m/s^2 of specific force (gyros only).
            vibration: (3,) the vibration's std per axis without rotation and (3,) its
                growth per rad/s of yaw rate (None: none), drawn from ``vibration_rng``.
        """
        self.bias = bias
        self.biased = bool(np.any(bias))  # asked once: np.any costs as much as the sum
        self.noise_std = noise_std
        self.gm_std = gm_std
        self.dt_over_tau = 1.0 / tau_rate
        self.noise_rng = noise_rng
        self.gm_rng = gm_rng
        # Transposed once, for row vectors: truth (N, 3) @ matrix.T is (matrix @ truth[k])_k.
        # None where zero, so that a model without these terms skips them and its output
        # keeps every bit of the additive model (even the sign of a zero).
        self.matrix_t = matrix.T.copy() if np.any(matrix) else None
        self.g_matrix_t = (g_matrix.T.copy() if g_matrix is not None and np.any(g_matrix)
                           else None)
        # Started from the stationary distribution, so the process has the same statistics
        # at every sample and no transient depends on where a mission starts.
        self.gm_state = gm_std * gm_rng.standard_normal(3) if gm_std else np.zeros(3)
        # The vibration's e[k - 1] for the next sample: its first sample is stationary too.
        self.shaking = vibration is not None
        self.vibration_std, self.vibration_per_rate = vibration if self.shaking else (_OFF, _OFF)
        self.vibration_rng = vibration_rng
        self.vibration_last = (vibration_rng.standard_normal(3) if self.shaking
                               else np.zeros(3))
        self.exact = not (self.biased or noise_std or gm_std or self.matrix_t is not None
                          or self.g_matrix_t is not None or self.shaking)
        # The samples' error terms that do not depend on the truth, made ahead in chunks:
        # the white noise n[k] and the Gauss-Markov bias b[k] of samples at, at + 1, ...
        # A block of a few samples (an environment step) then costs one compiled pass over
        # rows made earlier, not two draws and a loop. The streams are read forward only,
        # so the chunks' size changes no draw.
        self.at = 0
        self.noise = np.zeros((0, 3))
        self.gauss_markov = np.zeros((0, 3))
        self.vibration = np.zeros((0, 3))

    def corrupt(self, truth: np.ndarray, specific_force: np.ndarray,
                yaw_rate: np.ndarray) -> np.ndarray:
        out = truth.copy()  # a copy: the caller's truth stays intact
        if self.exact:
            return out
        if self.matrix_t is not None:
            out += truth @ self.matrix_t
        if self.g_matrix_t is not None:
            out += specific_force @ self.g_matrix_t
        n = len(out)
        if self.at + n > len(self.noise):
            self._ahead(n)
        _add_terms(out, self.bias if self.biased else _OFF, self.noise if self.noise_std
                   else _OFF_ROWS, self.gauss_markov if self.gm_std else _OFF_ROWS,
                   self.vibration if self.shaking else _OFF_ROWS, self.vibration_std,
                   self.vibration_per_rate, yaw_rate, self.at)
        self.at += n
        return out

    def _ahead(self, n: int) -> None:
        """Make the error terms of at least the next ``n`` samples (and a chunk more)."""
        rows = max(n, CHUNK)
        noise, gauss_markov = np.zeros((rows, 3)), np.zeros((rows, 3))
        if self.noise_std:
            noise = self.noise_rng.standard_normal((rows, 3))
            noise *= self.noise_std
        if self.gm_std:
            gauss_markov = gauss_markov_rows(self.gm_state, self.gm_rng.standard_normal(
                (rows, 3)), std=self.gm_std, dt_over_tau=self.dt_over_tau)
        left = slice(self.at, None)
        if self.shaking:  # unit rows, (e[k] - e[k - 1]) / sqrt(2): the std is the sample's
            e = self.vibration_rng.standard_normal((rows, 3))
            vibration = np.diff(np.concatenate([self.vibration_last[None], e]), axis=0)
            vibration /= math.sqrt(2.0)
            self.vibration_last = e[-1]
            self.vibration = np.concatenate([self.vibration[left], vibration])
        self.noise = np.concatenate([self.noise[left], noise])
        self.gauss_markov = np.concatenate([self.gauss_markov[left], gauss_markov])
        self.at = 0


CHUNK = 1024  # samples of error terms made ahead at a time (about 10 s at 100 Hz)
_OFF, _OFF_ROWS = np.zeros(0), np.zeros((0, 3))  # a term that is off, for _add_terms


@numba.njit(cache=True)
def _add_terms(out, bias, noise, gauss_markov, vibration, vibration_std, per_rate, yaw_rate,
               at):
    """``out += bias; out += noise[at:at + N]; out += gauss_markov[at:at + N]; out +=
    (vibration_std + per_rate |yaw_rate|) vibration[at:at + N]``, element by element in that
    order (the same arithmetic), in one compiled pass: on the few rows of an environment
    step, numpy's calls (a broadcast above all) cost several times the additions. A term
    given empty ((0,) or (0, 3)) is off.

    Args:
        out: (N, 3) the measurement so far, added to in place.
        bias: (3,) turn-on bias.
        noise, gauss_markov, vibration: (M, 3) rows of white noise, Gauss-Markov bias and
            unit vibration, M >= at + N.
        vibration_std, per_rate: (3,) the vibration's std without rotation and its growth
            per rad/s of yaw rate.
        yaw_rate: (N,) rad/s, the samples' true yaw rate.
        at: the row of those rows of out's first row.
    """
    for k in range(out.shape[0]):
        for j in range(3):
            if bias.shape[0]:
                out[k, j] += bias[j]
            if noise.shape[0]:
                out[k, j] += noise[at + k, j]
            if gauss_markov.shape[0]:
                out[k, j] += gauss_markov[at + k, j]
            if vibration.shape[0]:
                out[k, j] += (vibration_std[j] + per_rate[j] * abs(yaw_rate[k])) * vibration[
                    at + k, j]


def _float_array(name: str, value: np.ndarray, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (None: any length), or a ValueError."""
    out = np.asarray(value, dtype=np.float64)
    if out.ndim == len(shape):
        for s, n in zip(shape, out.shape, strict=True):  # a loop: every environment step
            if s is not None and s != n:
                break
        else:
            return out
    expected = str(tuple("N" if s is None else s for s in shape)).replace("'", "")
    raise ValueError(f"{name}: expected an array of shape {expected}, got shape {out.shape}")


def _vibration(std, per_rate) -> tuple[np.ndarray, np.ndarray] | None:
    """A triad's vibration, (3,) std per axis without rotation and (3,) its growth per
    rad/s of yaw rate, or None where it has none."""
    if not (any(std) or any(per_rate)):
        return None
    return np.asarray(std, dtype=float), np.asarray(per_rate, dtype=float)


class ImuErrorModel:
    """The error process of one mission, applied block by block.

    The output depends only on the config, the biases, the calibration errors, the state
    of ``rng`` at construction and the full sequence of samples, not on how that sequence
    is split into calls of ``corrupt``: white noise and Gauss-Markov drive come from four
    child generators (accel noise, gyro noise, accel drive, gyro drive; two more for a
    vibration) that are only ever read forward, the Gauss-Markov state (and the
    vibration's last draw) is carried from one call to the next, and the scale-factor,
    misalignment and g-sensitivity terms act sample by sample.

    Example::

        streams = mission_streams(seed)  # auvsim.data.streams
        model = ImuErrorModel(config.imu, draw_biases(config.imu, streams["imu_biases"]),
                              streams["imu_noise"], calibration=draw_calibration(
                                  config.imu, streams["imu_calibration"]))
        for block in blocks:
            f_meas, w_meas = model.corrupt(block["specific_force"], block["angular_rate"])
    """

    def __init__(self, config: ImuConfig, biases: ImuBiases, rng: np.random.Generator, *,
                 calibration: ImuCalibration = NO_CALIBRATION_ERRORS) -> None:
        """Spawn the child generators and draw the initial Gauss-Markov state.

        Args:
            config: rates, densities and Gauss-Markov parameters (``ImuConfig``).
            biases: the mission's turn-on biases, (3,) m/s^2 and (3,) rad/s.
            rng: parent generator; four children are spawned from it (``rng.spawn(4)``),
                and two more for a vibration.
            calibration: the mission's scale-factor, misalignment and g-sensitivity
                errors (``draw_calibration``); none by default.
        """
        self.config = config
        self.biases = ImuBiases(_float_array("biases.accel", biases.accel, (3,)).copy(),
                                _float_array("biases.gyro", biases.gyro, (3,)).copy())
        self.calibration = ImuCalibration(*(
            _float_array(f"calibration.{name}", value, shape).copy()
            for name, value, shape in zip(
                ImuCalibration._fields, calibration,
                ((3,), (3,), (3, 3), (3, 3), (3, 3)), strict=True)))
        accel_noise, gyro_noise, accel_gm, gyro_gm = rng.spawn(4)
        # The vibration's two streams are spawned after those four, and only where there
        # is one: a config without keeps every draw it had.
        accel_shake = _vibration(config.accel_vibration_std, config.accel_vibration_per_rate)
        gyro_shake = _vibration(config.gyro_vibration_std, config.gyro_vibration_per_rate)
        shaking = accel_shake is not None or gyro_shake is not None
        accel_vib, gyro_vib = rng.spawn(2) if shaking else (None, None)
        root_rate = math.sqrt(config.rate_hz)
        c = self.calibration
        self._accel = _Channel(self.biases.accel, config.accel_noise_density * root_rate,
                               config.accel_bias_instability, config.rate_hz * config.accel_tau,
                               accel_noise, accel_gm, c.accel_matrix,
                               vibration=accel_shake, vibration_rng=accel_vib)
        self._gyro = _Channel(self.biases.gyro, config.gyro_noise_density * root_rate,
                              config.gyro_bias_instability, config.rate_hz * config.gyro_tau,
                              gyro_noise, gyro_gm, c.gyro_matrix, c.gyro_g_sensitivity,
                              vibration=gyro_shake, vibration_rng=gyro_vib)

    def corrupt(self, specific_force: np.ndarray,
                angular_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measure the next N samples of the mission and advance the error state.

        ``f_meas = (I + S_a + M_a) f + b_a + n_a (+ x_a)`` and
        ``w_meas = (I + S_g + M_g) w + G f + b_g + n_g (+ x_g)`` per sample (module
        docstring; x: the vibration, where there is one, at the sample's yaw rate: that of
        ``angular_rate``).

        Args:
            specific_force: (N, 3) true specific force f = a - g at the IMU, m/s^2, body
                FRD, sampled at ``config.rate_hz``.
            angular_rate: (N, 3) true angular rate, rad/s, body FRD, same samples.

        Returns:
            (N, 3) measured specific force (m/s^2) and (N, 3) measured angular rate
            (rad/s), new float64 arrays; bitwise equal to the inputs when every error of
            the config is zero.
        """
        specific_force = _float_array("specific_force", specific_force, (None, 3))
        angular_rate = _float_array("angular_rate", angular_rate, (len(specific_force), 3))
        # The yaw rate a vibration's std grows with, copied only where one is on (one
        # compiled layout); ``_OFF`` otherwise, which ``_add_terms`` never reads.
        yaw_rate = (np.ascontiguousarray(angular_rate[:, 2])
                    if self._accel.shaking or self._gyro.shaking else _OFF)
        return (self._accel.corrupt(specific_force, specific_force, yaw_rate),
                self._gyro.corrupt(angular_rate, specific_force, yaw_rate))


class Imu(Sensor):
    """The IMU at its site: the truth's specific force and angular rate (with a
    geographic origin, plus the Earth's rate in body axes) through ``ImuErrorModel``, at
    every truth sample (the truth group runs at the IMU rate).

    Streams: turn-on biases from ``imu_biases``, noise from ``imu_noise``, and the
    scale-factor, misalignment and g-sensitivity errors from ``imu_calibration`` (the
    third, added in schema v4, so that every earlier draw is what it was)."""

    name = "imu"
    section = "imu"
    streams = ("imu_biases", "imu_noise", "imu_calibration")
    fields = (
        Field("imu/time", (), "f", "imu", "s", "sample times (a hard link to truth/time)"),
        Field("imu/specific_force", (3,), "f", "imu", "m/s^2", "measured, body"),
        Field("imu/angular_rate", (3,), "f", "imu", "rad/s", "measured, body"),
    )
    attributes = (
        Attr("imu_rate_hz", (), "Hz", low=0, strict=True),
        Attr("imu_position_body", (3,), "m, FRD"),
        Attr("imu_accel_turn_on_bias", (3,), "REALISED, m/s^2"),
        Attr("imu_gyro_turn_on_bias", (3,), "REALISED, rad/s"),
        Attr("imu_accel_noise_density", (), "m/s^2/sqrt(Hz)"),
        Attr("imu_gyro_noise_density", (), "rad/s/sqrt(Hz)"),
        Attr("imu_accel_bias_instability", (), "m/s^2"),
        Attr("imu_gyro_bias_instability", (), "rad/s"),
        Attr("imu_bias_correlation_time", (), "s; from v4 the config's shared value, which "
             "the two below override"),
        Attr("imu_accel_bias_correlation_time", (), "s, the accelerometers' Gauss-Markov "
             "correlation time", low=0, strict=True, since=4),
        Attr("imu_gyro_bias_correlation_time", (), "s, the gyros' Gauss-Markov correlation "
             "time", low=0, strict=True, since=4),
        Attr("imu_accel_scale_factor", (3,), "REALISED, -: the diagonal of S_a", since=4),
        Attr("imu_gyro_scale_factor", (3,), "REALISED, -: the diagonal of S_g", since=4),
        Attr("imu_accel_misalignment", (9,), "REALISED, rad: M_a (3, 3) row-major, zero "
             "diagonal", since=4),
        Attr("imu_gyro_misalignment", (9,), "REALISED, rad: M_g (3, 3) row-major, zero "
             "diagonal", since=4),
        Attr("imu_gyro_g_sensitivity", (9,), "REALISED, rad/s per m/s^2: G (3, 3) "
             "row-major", since=4),
    )
    links = {"imu/time": "truth/time"}

    def __init__(self, config, platform, parameters, calibration):
        self.config = config.imu
        self.latitude_deg = config.location.latitude_deg  # None: the flat world
        self.position = platform.vehicle.imu_position
        self.biases = draw_biases(config.imu, parameters)
        self.calibration = draw_calibration(config.imu, calibration)
        self.model: ImuErrorModel | None = None  # made from the noise stream on first use

    def rows(self, n_imu):
        return {"imu": n_imu}

    @classmethod
    def describe(cls, mission):
        return describe_mission(mission)

    def attrs(self):
        c, cal = self.config, self.calibration
        return dict(imu_rate_hz=c.rate_hz, imu_position_body=self.position,
                    imu_accel_turn_on_bias=self.biases.accel,
                    imu_gyro_turn_on_bias=self.biases.gyro,
                    imu_accel_noise_density=c.accel_noise_density,
                    imu_gyro_noise_density=c.gyro_noise_density,
                    imu_accel_bias_instability=c.accel_bias_instability,
                    imu_gyro_bias_instability=c.gyro_bias_instability,
                    imu_bias_correlation_time=c.bias_correlation_time,
                    imu_accel_bias_correlation_time=c.accel_tau,
                    imu_gyro_bias_correlation_time=c.gyro_tau,
                    imu_accel_scale_factor=cal.accel_scale_factor,
                    imu_gyro_scale_factor=cal.gyro_scale_factor,
                    imu_accel_misalignment=cal.accel_misalignment.ravel(),
                    imu_gyro_misalignment=cal.gyro_misalignment.ravel(),
                    imu_gyro_g_sensitivity=cal.gyro_g_sensitivity.ravel())

    def measure(self, truth, rng):
        if self.model is None:  # its child streams, spawned once from the noise stream
            self.model = ImuErrorModel(self.config, self.biases, rng,
                                       calibration=self.calibration)
        rate = truth.angular_rate
        if self.latitude_deg is not None:  # in inertial space: the Earth's rate too
            rate = rate + earth_rate_body(rotation_matrices(truth.quaternion),
                                          self.latitude_deg)
        force, rate = self.model.corrupt(truth.specific_force, rate)
        return {"imu/time": truth.time, "imu/specific_force": force, "imu/angular_rate": rate}


def describe_mission(mission) -> list[str]:
    """What ``auvsim inspect`` prints of a mission's IMU (``Imu.describe``)."""
    a = mission.attrs
    lines = [f"    IMU {a['imu_rate_hz']:g} Hz ({mission.imu.rows} samples)"]
    if "imu_accel_turn_on_bias" in a:
        lines.append(
            f"    IMU errors: accel turn-on bias {shown(a['imu_accel_turn_on_bias'])} "
            f"m/s^2, gyro {shown(a['imu_gyro_turn_on_bias'])} rad/s; noise densities "
            f"{a['imu_accel_noise_density']:.3g} m/s^2/rtHz, "
            f"{a['imu_gyro_noise_density']:.3g} rad/s/rtHz")
    if "imu_accel_scale_factor" in a:  # v4
        largest = {k: f"{np.max(np.abs(a[f'imu_{k}'])):.3g}" for k in (
            "accel_misalignment", "gyro_misalignment", "gyro_g_sensitivity")}
        lines.append(
            f"    IMU calibration: scale factors accel {shown(a['imu_accel_scale_factor'])}, "
            f"gyro {shown(a['imu_gyro_scale_factor'])}; largest misalignment accel "
            f"{largest['accel_misalignment']}, gyro {largest['gyro_misalignment']} rad; "
            f"largest g-sensitivity {largest['gyro_g_sensitivity']} rad/s per m/s^2; bias "
            f"correlation times accel {a['imu_accel_bias_correlation_time']:g} s, gyro "
            f"{a['imu_gyro_bias_correlation_time']:g} s")
    imu = json.loads(mission.dataset.config_json or "{}").get("imu", {})
    shake = {f"{k}_{v}": imu.get(f"{k}_vibration_{v}", (0.0, 0.0, 0.0))
             for k in ("accel", "gyro") for v in ("std", "per_rate")}
    if any(any(x) for x in shake.values()):  # the config's (no attribute holds it)
        lines.append(
            f"    IMU vibration (config): accel {shown(shake['accel_std'], 4)} m/s^2 + "
            f"{shown(shake['accel_per_rate'], 4)} per rad/s of yaw rate, gyro "
            f"{shown(shake['gyro_std'], 6)} rad/s + {shown(shake['gyro_per_rate'], 6)} per "
            "rad/s")
    return lines


SENSOR = Imu
