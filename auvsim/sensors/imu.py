"""IMU error model: true specific force and angular rate in, measured values out.

Per axis of each sensor (accelerometer and gyro), at sample k of a mission::

    measured[k] = true[k] + turn_on_bias + b[k] + n[k]
    b[k + 1]    = phi b[k] + sigma_b sqrt(1 - phi^2) w[k],   phi = exp(-dt / tau)
    n[k]        = density sqrt(rate) v[k]

``turn_on_bias`` ~ N(0, turn_on^2) is drawn once per mission (``draw_biases``); b is a
first-order Gauss-Markov process (steady-state std sigma_b = ``*_bias_instability``,
correlation time tau = ``bias_correlation_time``), discretised exactly and started from its
stationary distribution, b[0] ~ N(0, sigma_b^2); w, v ~ N(0, 1) white. Errors only add:
there is no scale factor, misalignment, quantisation or saturation.

Units (see ``auvsim``): specific force in m/s^2, angular rate in rad/s, body FRD axes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from ..config import ImuConfig
from . import Attr, Field, Sensor

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


class _Channel:
    """One sensor triad's stochastic errors and their random streams."""

    def __init__(self, bias: np.ndarray, noise_std: float, gm_std: float, phi: float,
                 drive_gain: float, noise_rng: np.random.Generator,
                 gm_rng: np.random.Generator) -> None:
        self.bias = bias
        self.noise_std = noise_std
        self.gm_std = gm_std
        self.phi = phi
        self.drive_std = gm_std * drive_gain  # sigma_b sqrt(1 - phi^2)
        self.noise_rng = noise_rng
        self.gm_rng = gm_rng
        # Started from the stationary distribution, so the process has the same statistics
        # at every sample and no transient depends on where a mission starts.
        self.gm_state = gm_std * gm_rng.standard_normal(3) if gm_std else np.zeros(3)
        self.exact = not (np.any(bias) or noise_std or gm_std)

    def corrupt(self, truth: np.ndarray) -> np.ndarray:
        out = truth.copy()  # a copy: the caller's truth stays intact
        if self.exact:
            return out
        if np.any(self.bias):
            out += self.bias
        if self.noise_std:
            noise = self.noise_rng.standard_normal(out.shape)
            noise *= self.noise_std
            out += noise
        if self.gm_std:
            drive = self.gm_rng.standard_normal(out.shape)
            _add_gauss_markov(out, drive, self.gm_state, self.phi, self.drive_std)
        return out


@numba.njit(cache=True)
def _add_gauss_markov(out, drive, state, phi, drive_std):
    """Add b[k] to out[k] and advance b[k + 1] = phi b[k] + drive_std w[k], in place.

    Args:
        out: (N, 3) array to add the process to.
        drive: (N, 3) standard normal draws w.
        state: (3,) b at the first row on entry, b after the last row on return.
    """
    for k in range(out.shape[0]):
        for j in range(3):
            out[k, j] += state[j]
            state[j] = phi * state[j] + drive_std * drive[k, j]


def _float_array(name: str, value: np.ndarray, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (None: any length), or a ValueError."""
    out = np.asarray(value, dtype=np.float64)
    if out.ndim != len(shape) or any(
            s not in (None, n) for s, n in zip(shape, out.shape, strict=True)):
        expected = str(tuple("N" if s is None else s for s in shape)).replace("'", "")
        raise ValueError(f"{name}: expected an array of shape {expected}, got shape "
                         f"{out.shape}")
    return out


class ImuErrorModel:
    """The error process of one mission, applied block by block.

    The output depends only on the config, the biases, the state of ``rng`` at
    construction and the full sequence of samples, not on how that sequence is split into
    calls of ``corrupt``: white noise and Gauss-Markov drive come from four child
    generators (accel noise, gyro noise, accel drive, gyro drive) that are only ever read
    forward, and the Gauss-Markov state is carried from one call to the next.

    Example::

        rng = np.random.default_rng(seed)
        model = ImuErrorModel(config.imu, draw_biases(config.imu, rng), rng)
        for block in blocks:
            f_meas, w_meas = model.corrupt(block["specific_force"], block["angular_rate"])
    """

    def __init__(self, config: ImuConfig, biases: ImuBiases, rng: np.random.Generator) -> None:
        """Spawn the child generators and draw the initial Gauss-Markov state.

        Args:
            config: rates, densities and Gauss-Markov parameters (``ImuConfig``).
            biases: the mission's turn-on biases, (3,) m/s^2 and (3,) rad/s.
            rng: parent generator; four children are spawned from it (``rng.spawn(4)``).
        """
        self.config = config
        self.biases = ImuBiases(_float_array("biases.accel", biases.accel, (3,)).copy(),
                                _float_array("biases.gyro", biases.gyro, (3,)).copy())
        accel_noise, gyro_noise, accel_gm, gyro_gm = rng.spawn(4)
        dt_over_tau = 1.0 / (config.rate_hz * config.bias_correlation_time)
        phi = math.exp(-dt_over_tau)
        # sqrt(1 - phi^2) via expm1: 1 - phi^2 would lose digits as dt << tau sends phi -> 1.
        drive_gain = math.sqrt(-math.expm1(-2.0 * dt_over_tau))
        root_rate = math.sqrt(config.rate_hz)
        self._accel = _Channel(self.biases.accel, config.accel_noise_density * root_rate,
                               config.accel_bias_instability, phi, drive_gain, accel_noise,
                               accel_gm)
        self._gyro = _Channel(self.biases.gyro, config.gyro_noise_density * root_rate,
                              config.gyro_bias_instability, phi, drive_gain, gyro_noise, gyro_gm)

    def corrupt(self, specific_force: np.ndarray,
                angular_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Measure the next N samples of the mission and advance the error state.

        ``measured = true + turn_on_bias + b[k] + n[k]`` per axis (module docstring).

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
        return self._accel.corrupt(specific_force), self._gyro.corrupt(angular_rate)


class Imu(Sensor):
    """The IMU at its site: the truth's specific force and angular rate through
    ``ImuErrorModel``, at every truth sample (the truth group runs at the IMU rate)."""

    name = "imu"
    section = "imu"
    streams = ("imu_biases", "imu_noise")
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
        Attr("imu_bias_correlation_time", (), "s"),
    )
    links = {"imu/time": "truth/time"}

    def __init__(self, config, platform, parameters):
        self.config = config.imu
        self.position = platform.vehicle.imu_position
        self.biases = draw_biases(config.imu, parameters)
        self.model: ImuErrorModel | None = None  # made from the noise stream on first use

    def rows(self, n_imu):
        return {"imu": n_imu}

    def attrs(self):
        c = self.config
        return dict(imu_rate_hz=c.rate_hz, imu_position_body=self.position,
                    imu_accel_turn_on_bias=self.biases.accel,
                    imu_gyro_turn_on_bias=self.biases.gyro,
                    imu_accel_noise_density=c.accel_noise_density,
                    imu_gyro_noise_density=c.gyro_noise_density,
                    imu_accel_bias_instability=c.accel_bias_instability,
                    imu_gyro_bias_instability=c.gyro_bias_instability,
                    imu_bias_correlation_time=c.bias_correlation_time)

    def measure(self, truth, rng):
        if self.model is None:  # its four child streams, spawned once from the noise stream
            self.model = ImuErrorModel(self.config, self.biases, rng)
        force, rate = self.model.corrupt(truth.specific_force, truth.angular_rate)
        return {"imu/time": truth.time, "imu/specific_force": force, "imu/angular_rate": rate}


SENSOR = Imu
