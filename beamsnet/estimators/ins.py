"""INS/DVL error-state Kalman filter: strapdown mechanisation at the IMU rate, corrected by
each bottom-track DVL beam as a scalar measurement (issue 11, item 1).

Conventions are auvsim's (NED world, FRD body, body -> NED rotation C, SI units). The
mechanised point is the IMU; the DVL and the body origin are reached through the lever
arms of the file's attributes.

Mechanisation (Groves 2013, "Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems", 2nd ed., sec. 5.4, first-order form, flat Earth), from IMU sample
i - 1 to i, dt = 1 / rate::

    v_i = v_{i-1} + dt (C_{i-1} f_{i-1} + g - 2 Omega_ie x v_{i-1})
    p_i = p_{i-1} + dt v_i
    C_i = C_{i-1} Exp(dt (w_i - C_{i-1}^T Omega_ie))

with f and w the bias-corrected samples, g = (0, 0, g0) and Omega_ie the Earth rate at a
configured latitude (off by default: auvsim's world is flat and does not rotate). This is
the discrete form auvsim's truth obeys: MuJoCo's semi-implicit Euler step holds the
acceleration recorded at step i - 1 over the step and rotates by the angular velocity
recorded at step i, and the simulated accelerometer reads C^T (a - g) with the model's
g0. So noise-free data integrate back exactly at the body origin; at the IMU point (and
the DVL) the one discretisation error is the lever arm's (derived, and tested to 1e-9,
in ``tests/test_ins.py::lever_arm_error``). A real
IMU's increments would need Savage's coning and sculling terms instead.

Error state (x = x_hat + dx; Groves ch. 14.2, Sola 2017 "Quaternion kinematics for the
error-state Kalman filter" sec. 7 for the global attitude error): dp, dv (NED, m, m/s),
attitude error theta with C = Exp(theta) C_hat (NED, rad), accelerometer and gyro bias
errors (body, m/s^2, rad/s), and with ``beam_states`` each beam's scale factor s_k and
bias c_k (8 more). Continuous error dynamics (Groves eq. 14.64 without the curvature and
Earth-rate terms unless ``earth_rate``)::

    dp' = dv,   dv' = -[C f x] theta - C db_a - C n_a,   theta' = -C db_g - C n_g,
    db_a' = w_ba,  db_g' = w_bg  (random walks; s and c constant)

propagated at every IMU sample with Phi = I + F dt and Q = diag(...) dt (Groves eq.
14.72-14.82, first order), applied to the sparse blocks only. Beam k measures (auvsim's
DVL, ``auvsim.sensors.dvl``)::

    y_k = (1 + s_k) b_k . M^T (C^T v + w x L) + c_k + n_k,   n_k ~ N(0, sigma^2)

with M the nominal mounting (DVL frame -> body) and L = r_dvl - r_imu, so each usable
beam (``valid`` and bottom track) is one scalar update (Groves sec. 3.2.5: sequential
processing of uncorrelated measurements) and one to four beams all help. Each innovation
is gated by chi-square with 1 dof at ``gate_probability``. A beam is used where it has
bottom lock (``dvl/valid``) on a ping not in water track (``dvl/mode`` != 1): with fewer
than 3 such beams the ping has no LS velocity (mode -1), but its locked beams still
measure the velocity over ground. A ping without one leaves the prior, so the track has
a velocity at every ping.

Not modelled (they make the filter optimistic where the data have them): the IMU's scale
factors, misalignments and g-sensitivity (the ``-full`` grades), the DVL's mounting
misalignment, sound-speed ratio, range- and speed-dependent noise and heavy-tailed
outliers (those the gate handles), and the bias's Gauss-Markov decay (a random walk with
the same drive: the missions are much shorter than tau).

Speed (``benchmarks/filter.py``, 600 s at 100 Hz, one core): the compiled loop runs at
3400x to 4400x real time, ``run_mission`` with its HDF5 reads at 2200x to 2800x (15
states) and 1800x to 2100x (23), on a shared machine. The first call compiles the loop
(about 30 s) into numba's on-disk cache; later processes load it in under a second.
"""

from __future__ import annotations

import json
import math
import statistics
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from auvsim.data.beams import beam_matrix
from auvsim.data.reader import open_dataset
from auvsim.errors import DatasetError
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from beamsnet.data import DataError, Windows
from beamsnet.estimators.baselines import BeamCalibration
from beamsnet.estimators.registry import Needs, Spec

EARTH_RATE = 7.292115e-5  # rad/s, WGS84 (Groves eq. 2.133)
N_CORE = 15  # p, v, theta, b_a, b_g
N_BEAM = 23  # + 4 beam scale factors, 4 beam biases
BEAM_NOISE_FLOOR = 1e-4  # m/s: a noise-free file's beams still get a finite weight


class NoImuError(DataError):
    """A mission without an ``imu`` group (an imported DVL stream)."""


@dataclass(frozen=True)
class FilterConfig:
    """Settings of the INS/DVL filter. Stds are 1 sigma; None: from the dataset. The
    default initial stds are our choice, of the order of a navigation-grade INS aligned
    at the start of a mission.

    Attributes:
        position_std: initial position error, m per NED axis.
        velocity_std: initial velocity error, m/s per NED axis.
        attitude_std_deg: initial attitude error (level axes, heading), deg; one number
            sets both.
        accel_bias_std: initial accelerometer bias std, m/s^2 per axis; None:
            sqrt(turn-on spread^2 + bias instability^2) of the dataset's IMU config.
        gyro_bias_std: initial gyro bias std, rad/s per axis; None: as above.
        initial_error_seed: None starts exactly at the truth (biases at zero) with the
            covariance above; a seed draws the initial position, velocity and attitude
            errors from it with those stds.
        earth_rate: compensate the Earth's rotation at ``latitude_deg`` (the simulator's
            world does not rotate: keep it off for auvsim data).
        latitude_deg: deg, used only with ``earth_rate``.
        gravity: m/s^2 (down); None: the mission's, as its dataset stores it (``gravity``).
        beam_states: estimate each beam's scale factor and bias (8 more states).
        beam_scale_std: initial std of each beam's scale factor, - (``beam_states``).
        beam_bias_std: initial std of each beam's bias, m/s (``beam_states``).
        gate_probability: chi-square (1 dof) gate on each beam's normalised innovation;
            0.999 rejects 0.1 % of good beams (3.29 sigma) and a 10 sigma outlier always.
        beam_noise_std: m/s per beam; None: the dataset's ``dvl_noise_std``, at least
            ``BEAM_NOISE_FLOOR``.
        dvl_updates: False: no beam is used, pure inertial navigation from the start
            (the mechanisation alone, as in a DVL outage).
        accel_noise_density: m/s^2/sqrt(Hz); None: the dataset's.
        gyro_noise_density: rad/s/sqrt(Hz); None: the dataset's.
        accel_bias_psd: accelerometer bias random-walk PSD, (m/s^2)^2/s; None:
            2 sigma^2 / tau of the dataset's Gauss-Markov bias (its drive, to first order
            in t / tau).
        gyro_bias_psd: gyro bias random-walk PSD, (rad/s)^2/s; None: likewise.
    """

    position_std: float = 0.1
    velocity_std: float = 0.01
    attitude_std_deg: tuple[float, float] | float = (0.01, 0.05)
    accel_bias_std: float | None = None
    gyro_bias_std: float | None = None
    initial_error_seed: int | None = None
    earth_rate: bool = False
    latitude_deg: float = 0.0
    gravity: float | None = None
    beam_states: bool = False
    beam_scale_std: float = 0.01
    beam_bias_std: float = 0.01
    gate_probability: float = 0.999
    beam_noise_std: float | None = None
    dvl_updates: bool = True
    accel_noise_density: float | None = None
    gyro_noise_density: float | None = None
    accel_bias_psd: float | None = None
    gyro_bias_psd: float | None = None

    def __post_init__(self) -> None:
        for name in ("position_std", "velocity_std", "beam_scale_std", "beam_bias_std"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"FilterConfig.{name}: expected a positive std, got {value!r}")
        if isinstance(self.attitude_std_deg, (int, float)):  # one std for all three axes
            object.__setattr__(self, "attitude_std_deg", (float(self.attitude_std_deg),) * 2)
        if len(self.attitude_std_deg) != 2 or min(self.attitude_std_deg) <= 0:
            raise ValueError("FilterConfig.attitude_std_deg: expected two positive stds "
                             f"(level, heading) in deg, got {self.attitude_std_deg!r}")
        if not 0 < self.gate_probability < 1:
            raise ValueError("FilterConfig.gate_probability: expected a probability in "
                             f"(0, 1), got {self.gate_probability!r}")


class FilterTrack(NamedTuple):
    """The filter's output at every DVL ping of one mission (posterior, after the ping's
    beams). Shapes (P, .)."""

    ping_time: np.ndarray  # (P,) s
    velocity_dvl: np.ndarray  # (P, 3) m/s, DVL frame (nominal mounting)
    velocity_std: np.ndarray  # (P, 3) m/s
    velocity_cov: np.ndarray  # (P, 3, 3) (m/s)^2
    position_ned: np.ndarray  # (P, 3) m, body origin
    position_std: np.ndarray  # (P, 3) m
    accel_bias: np.ndarray  # (P, 3) m/s^2, body
    accel_bias_std: np.ndarray  # (P, 3)
    gyro_bias: np.ndarray  # (P, 3) rad/s, body
    gyro_bias_std: np.ndarray  # (P, 3)
    beam_scale: np.ndarray  # (P, 4) -, each beam's scale factor s_k (NaN: no beam states)
    beam_scale_std: np.ndarray  # (P, 4)
    beam_bias: np.ndarray  # (P, 4) m/s, each beam's bias c_k (NaN: no beam states)
    beam_bias_std: np.ndarray  # (P, 4)
    beams_used: np.ndarray  # (P,) int
    beams_rejected: np.ndarray  # (P,) int, gated out
    nees_velocity: np.ndarray  # (P,) e^T cov^-1 e of velocity_dvl against dvl/velocity


@numba.njit(cache=True)
def _exp_into(phi, out):
    """out <- the rotation matrix of rotation vector phi (Rodrigues; Groves eq. 2.39)."""
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    if t2 < 1e-12:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    for i in range(3):
        for j in range(3):
            out[i, j] = b * phi[i] * phi[j]  # (1 - cos) / t^2 (phi phi^T - t^2 I) + I
        out[i, i] += 1.0 - b * t2
    out[0, 1] -= a * phi[2]
    out[1, 0] += a * phi[2]
    out[0, 2] += a * phi[1]
    out[2, 0] -= a * phi[1]
    out[1, 2] -= a * phi[0]
    out[2, 1] += a * phi[0]


@numba.njit(cache=True)
def _exp(phi):
    out = np.empty((3, 3))
    _exp_into(phi, out)
    return out


@numba.njit(cache=True)
def _matmul_into(a, b, out):
    """out <- a b for 3x3 matrices (no BLAS call, no allocation)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j]


@numba.njit(cache=True)
def _phi_apply(x, dt, m_va, m_vba, m_abg, m_vv, m_aa):
    """x <- Phi x in place for one state vector (a column or row of P): Phi = I + F dt on
    the blocks p<-v, v<-theta, v<-b_a, theta<-b_g, and with the Earth rate v<-v, a<-a."""
    v0, v1, v2 = x[3], x[4], x[5]
    a0, a1, a2 = x[6], x[7], x[8]
    for r in range(3):
        x[r] += dt * x[3 + r]
        x[3 + r] += (m_va[r, 0] * a0 + m_va[r, 1] * a1 + m_va[r, 2] * a2
                     + m_vba[r, 0] * x[9] + m_vba[r, 1] * x[10] + m_vba[r, 2] * x[11]
                     + m_vv[r, 0] * v0 + m_vv[r, 1] * v1 + m_vv[r, 2] * v2)
        x[6 + r] += (m_abg[r, 0] * x[12] + m_abg[r, 1] * x[13] + m_abg[r, 2] * x[14]
                     + m_aa[r, 0] * a0 + m_aa[r, 1] * a1 + m_aa[r, 2] * a2)


@numba.njit(cache=True)
def _filter(f, w, dt, g, omega_ie, ping_row, beams, usable, h, mounting, lever, r_imu,
            p, v, c, ba, bg, P, q, r_beam, gate, n):
    """Run the filter over one mission. Arrays are updated in place where they are state
    (p, v, c, ba, bg, P); outputs per ping are returned.

    Args:
        f, w: (N, 3) measured specific force, m/s^2, and angular rate, rad/s, body.
        dt: IMU interval, s. g: gravity, m/s^2 (down). omega_ie: (3,) Earth rate, NED.
        ping_row: (P,) IMU sample of each ping. beams: (P, 4) m/s. usable: (P, 4) bool.
        h: (4, 3) beam matrix. mounting: (3, 3) DVL -> body. lever: (3,) r_dvl - r_imu.
        r_imu: (3,) IMU position in the body, m.
        p, v, c, ba, bg: initial IMU-point position, velocity, rotation, biases.
        P: (n, n) initial covariance. q: (4,) PSDs (accel, gyro white noise; accel, gyro
            bias random walk). r_beam: beam variance, (m/s)^2. gate: chi-square threshold.
        n: states, 15 or 23.
    """
    n_ping = ping_row.shape[0]
    out_v = np.empty((n_ping, 3))
    out_cov = np.empty((n_ping, 3, 3))
    out_p = np.empty((n_ping, 3))
    out_pstd = np.empty((n_ping, 3))
    out_b = np.full((n_ping, 28), np.nan)
    used = np.zeros(n_ping, dtype=np.int64)
    rejected = np.zeros(n_ping, dtype=np.int64)
    s = np.zeros(4)
    cb = np.zeros(4)
    m_vv = np.zeros((3, 3))
    m_aa = np.zeros((3, 3))
    earth = omega_ie[0] != 0.0 or omega_ie[1] != 0.0 or omega_ie[2] != 0.0
    if earth:
        m_vv = -2.0 * dt * np.array([[0.0, -omega_ie[2], omega_ie[1]],
                                     [omega_ie[2], 0.0, -omega_ie[0]],
                                     [-omega_ie[1], omega_ie[0], 0.0]])
        m_aa = 0.5 * m_vv
    gmb = mounting @ h.T  # (3, 4): M b_k, beam directions in the body
    k_ping = 0
    hrow = np.zeros(n)
    fb, wb, cf, dphi, cor = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
    c_old, rot, m_va, m_c = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    for i in range(f.shape[0]):
        if i > 0:
            for r in range(3):
                fb[r] = f[i - 1, r] - ba[r]
                wb[r] = w[i, r] - bg[r]
            for r in range(3):
                cf[r] = c[r, 0] * fb[0] + c[r, 1] * fb[1] + c[r, 2] * fb[2]
            if earth:
                cor[:] = np.cross(omega_ie, v)
                wb -= c.T @ omega_ie
                cf -= 2.0 * cor
            cf[2] += g
            for r in range(3):
                v[r] += dt * cf[r]
                p[r] += dt * v[r]
                dphi[r] = dt * wb[r]
                c_old[r, :] = c[r, :]
            cf[2] -= g  # C f (less the Coriolis term) is what the error dynamics see
            if earth:
                cf += 2.0 * cor
            _exp_into(dphi, rot)
            _matmul_into(c_old, rot, c)
            # Covariance: Phi P Phi^T (columns, then rows of the result), + Q dt.
            m_va[0, 1], m_va[0, 2], m_va[1, 2] = dt * cf[2], -dt * cf[1], dt * cf[0]
            m_va[1, 0], m_va[2, 0], m_va[2, 1] = -dt * cf[2], dt * cf[1], -dt * cf[0]
            for r in range(3):
                for j in range(3):
                    m_c[r, j] = -dt * c_old[r, j]
            for j in range(n):
                _phi_apply(P[:, j], dt, m_va, m_c, m_c, m_vv, m_aa)
            for j in range(n):
                _phi_apply(P[j, :], dt, m_va, m_c, m_c, m_vv, m_aa)
            for r in range(3):
                P[3 + r, 3 + r] += q[0] * dt
                P[6 + r, 6 + r] += q[1] * dt
                P[9 + r, 9 + r] += q[2] * dt
                P[12 + r, 12 + r] += q[3] * dt
        while k_ping < n_ping and ping_row[k_ping] == i:
            # The DVL's lever arm turns with the body relative to the Earth: w_nb.
            wb = w[i] - bg - c.T @ omega_ie
            for k in range(4):
                if not usable[k_ping, k]:
                    continue
                u = c.T @ v + np.cross(wb, lever)  # DVL point velocity, body
                gk = (1.0 + s[k]) * gmb[:, k]
                a = c @ gk
                beam_true = gmb[0, k] * u[0] + gmb[1, k] * u[1] + gmb[2, k] * u[2]
                y_hat = (1.0 + s[k]) * beam_true + cb[k]
                hrow[:] = 0.0
                hrow[3:6] = a
                hrow[6:9] = np.cross(a, v)
                hrow[12:15] = np.cross(gk, lever)
                if n > N_CORE:
                    hrow[15 + k] = beam_true
                    hrow[19 + k] = 1.0
                ph = P @ hrow
                s_inn = hrow @ ph + r_beam
                nu = beams[k_ping, k] - y_hat
                if nu * nu > gate * s_inn:
                    rejected[k_ping] += 1
                    continue
                used[k_ping] += 1
                gain = ph / s_inn
                dx = gain * nu
                P -= np.outer(gain, ph)
                P[:, :] = 0.5 * (P + P.T)
                # Inject the error estimate into the nominal state (it is reset to 0).
                p += dx[0:3]
                v += dx[3:6]
                c[:, :] = _exp(dx[6:9]) @ c
                ba += dx[9:12]
                bg += dx[12:15]
                if n > N_CORE:
                    s += dx[15:19]
                    cb += dx[19:23]
            wb = w[i] - bg - c.T @ omega_ie
            jac = np.zeros((3, 9))  # d v_dvl / d (dv, theta, db_g)
            mt = mounting.T
            jv = mt @ c.T
            jac[:, 0:3] = jv
            vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
            jac[:, 3:6] = jv @ vx
            lx = np.array([[0.0, -lever[2], lever[1]], [lever[2], 0.0, -lever[0]],
                           [-lever[1], lever[0], 0.0]])
            jac[:, 6:9] = mt @ lx
            idx = np.array([3, 4, 5, 6, 7, 8, 12, 13, 14])
            sub = np.empty((9, 9))
            for a_ in range(9):
                for b_ in range(9):
                    sub[a_, b_] = P[idx[a_], idx[b_]]
            out_cov[k_ping] = jac @ sub @ jac.T
            out_v[k_ping] = mt @ (c.T @ v + np.cross(wb, lever))
            out_p[k_ping] = p - c @ r_imu
            for r in range(3):
                # The origin's position error adds theta x (C r_imu); r_imu is short, and
                # its share is below the position std's first digit: the IMU point's std.
                out_pstd[k_ping, r] = math.sqrt(P[r, r])
                out_b[k_ping, r] = ba[r]
                out_b[k_ping, 3 + r] = math.sqrt(P[9 + r, 9 + r])
                out_b[k_ping, 6 + r] = bg[r]
                out_b[k_ping, 9 + r] = math.sqrt(P[12 + r, 12 + r])
            if n > N_CORE:
                for k in range(4):
                    out_b[k_ping, 12 + k] = s[k]
                    out_b[k_ping, 16 + k] = math.sqrt(P[15 + k, 15 + k])
                    out_b[k_ping, 20 + k] = cb[k]
                    out_b[k_ping, 24 + k] = math.sqrt(P[19 + k, 19 + k])
            k_ping += 1
    return out_v, out_cov, out_p, out_pstd, out_b, used, rejected


def _dataset_config(mission) -> dict:
    text = mission.dataset.config_json
    return json.loads(text) if text else {}


def run_mission(mission, config: FilterConfig = FilterConfig(), *,
                beam_correction: tuple[np.ndarray, np.ndarray] | None = None) -> FilterTrack:
    """Run the filter over one mission from its start.

    Args:
        mission: an ``auvsim.data.reader.Mission`` view of a simulated mission.
        config: the filter's settings.
        beam_correction: per-beam (scale factors s, biases b (m/s)), each (4,), known from
            a calibration (``beamsnet.estimators.baselines.BeamCalibration``): every beam is used as
            ``(y - b) / (1 + s)``. None: the beams as measured.

    Returns:
        The track at every DVL ping.

    Raises:
        NoImuError: the mission has no IMU record (an imported stream).
    """
    if not mission.has("imu"):
        raise NoImuError(f"mission {mission.name} has no IMU record; the INS/DVL filter "
                         "integrates the IMU, so it is skipped")
    a, cfg = mission.attrs, config
    dataset_config = _dataset_config(mission)
    imu_cfg = dataset_config.get("imu", {})
    rate = float(a["imu_rate_hz"])
    f = np.ascontiguousarray(mission.imu.specific_force, dtype=np.float64)
    w = np.ascontiguousarray(mission.imu.angular_rate, dtype=np.float64)
    truth = mission.truth
    r_imu = np.asarray(a["imu_position_body"], dtype=float)
    r_dvl = np.asarray(a["dvl_position_body"], dtype=float)
    mounting = rotation_rpy(*np.radians(a["dvl_mounting_rpy_deg"]))
    h = beam_matrix(math.radians(float(a["beam_angle_deg"])))
    gravity = cfg.gravity if cfg.gravity is not None else mission.gravity

    # Initial state: the truth at sample 0, moved to the IMU point.
    c0 = rotation_matrices(truth.quaternion[:1])[0]
    w0 = truth.angular_rate[0]
    p0 = truth.position_ned[0] + c0 @ r_imu
    v0 = truth.velocity_ned[0] + c0 @ np.cross(w0, r_imu)
    level, heading = np.radians(cfg.attitude_std_deg)
    att_std = np.array([level, level, heading])
    if cfg.initial_error_seed is not None:
        rng = np.random.default_rng(cfg.initial_error_seed)
        p0 = p0 + cfg.position_std * rng.standard_normal(3)
        v0 = v0 + cfg.velocity_std * rng.standard_normal(3)
        c0 = rotation_vector_exp(att_std * rng.standard_normal(3)) @ c0

    def bias_std(given, turn_on_key, instability_key):
        if given is not None:
            return given
        return math.hypot(float(imu_cfg.get(turn_on_key, 0.0)), float(a[instability_key]))

    def psd(given, instability_key, tau_key):
        if given is not None:
            return given
        sigma, tau = float(a[instability_key]), float(a.get(tau_key, a[
            "imu_bias_correlation_time"]))
        return 2.0 * sigma**2 / tau

    n = N_BEAM if cfg.beam_states else N_CORE
    std = np.concatenate([
        np.full(3, cfg.position_std), np.full(3, cfg.velocity_std), att_std,
        np.full(3, bias_std(cfg.accel_bias_std, "accel_turn_on_bias",
                            "imu_accel_bias_instability")),
        np.full(3, bias_std(cfg.gyro_bias_std, "gyro_turn_on_bias",
                            "imu_gyro_bias_instability")),
        np.full(4, cfg.beam_scale_std), np.full(4, cfg.beam_bias_std)])[:n]
    # Zero stds (an ideal IMU) would make P singular only where nothing is unknown.
    P = np.diag(std**2)
    q = np.array([
        (cfg.accel_noise_density if cfg.accel_noise_density is not None
         else float(a["imu_accel_noise_density"]))**2,
        (cfg.gyro_noise_density if cfg.gyro_noise_density is not None
         else float(a["imu_gyro_noise_density"]))**2,
        psd(cfg.accel_bias_psd, "imu_accel_bias_instability", "imu_accel_bias_correlation_time"),
        psd(cfg.gyro_bias_psd, "imu_gyro_bias_instability", "imu_gyro_bias_correlation_time")])
    sigma_beam = cfg.beam_noise_std if cfg.beam_noise_std is not None else max(
        float(a["dvl_noise_std"]), BEAM_NOISE_FLOOR)
    lat = math.radians(cfg.latitude_deg)
    omega_ie = (EARTH_RATE * np.array([math.cos(lat), 0.0, -math.sin(lat)])
                if cfg.earth_rate else np.zeros(3))

    dvl = mission.dvl
    beams = np.asarray(dvl.beam_velocity, dtype=float)
    if beam_correction is not None:
        scale, bias = (np.asarray(x, dtype=float) for x in beam_correction)
        beams = (beams - bias) / (1.0 + scale)
    mode = dvl.mode if "mode" in dvl else np.zeros(len(beams), dtype=np.int64)
    # A beam with bottom lock measures the velocity over ground whether or not the ping
    # has the 3 such beams an LS velocity needs (mode 0 or -1; ``valid`` is the lock
    # there); in water track (mode 1) ``valid`` means it measured the water: not used.
    usable = (np.asarray(dvl.valid, dtype=bool) & (mode != 1)[:, None] & np.isfinite(beams)
              & cfg.dvl_updates)
    ping_row = np.asarray(mission.imu.index_of_dvl, dtype=np.int64)
    out_v, cov, pos, pos_std, b, used, rejected = _filter(
        f, w, 1.0 / rate, gravity, omega_ie, ping_row, np.nan_to_num(beams), usable, h,
        mounting, r_dvl - r_imu, r_imu, p0.copy(), v0.copy(), c0.copy(), np.zeros(3),
        np.zeros(3), P, q, sigma_beam**2, _chi2_1dof(cfg.gate_probability), n)
    err = out_v - np.asarray(dvl.velocity, dtype=float)
    nees = np.einsum("pi,pi->p", err, np.linalg.solve(cov, err[..., None])[..., 0])
    return FilterTrack(ping_time=np.asarray(dvl.time, dtype=float), velocity_dvl=out_v,
                       velocity_std=np.sqrt(np.diagonal(cov, axis1=1, axis2=2)),
                       velocity_cov=cov, position_ned=pos, position_std=pos_std,
                       accel_bias=b[:, 0:3], accel_bias_std=b[:, 3:6],
                       gyro_bias=b[:, 6:9], gyro_bias_std=b[:, 9:12],
                       beam_scale=b[:, 12:16], beam_scale_std=b[:, 16:20],
                       beam_bias=b[:, 20:24], beam_bias_std=b[:, 24:28],
                       beams_used=used, beams_rejected=rejected, nees_velocity=nees)


def _chi2_1dof(probability: float) -> float:
    """Quantile of chi-square with 1 dof: the square of the normal's two-sided one."""
    return statistics.NormalDist().inv_cdf(0.5 + 0.5 * probability) ** 2


def rotation_vector_exp(phi: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of a rotation vector (3,), rad (Rodrigues)."""
    return _exp(np.asarray(phi, dtype=float))


def run(path, mission_name: str, config: FilterConfig = FilterConfig()) -> FilterTrack:
    """``run_mission`` on mission ``mission_name`` of the dataset at ``path``."""
    try:
        f = open_dataset(path)
    except DatasetError as e:  # the dataset module's own one-line message
        raise DataError(str(e)) from None
    with f:
        if mission_name not in f.missions:
            raise DataError(f"mission_name: {mission_name!r} not in {path}; it has "
                            f"{', '.join(f.missions)}")
        return run_mission(f.missions[mission_name], config)


class InsDvlFilter:
    """The filter as a beamsnet estimator: ``fit`` learns the DVL's per-beam scale factors
    and biases on the training split (``BeamCalibration``: the systematic beam errors of
    eq. 7, which the IMU cannot tell from the velocity on a steady leg, as every other
    calibrated estimator of the tables learns them), ``predict`` runs each mission of the
    windows from its start (causal) on the corrected beams and returns the posterior
    DVL-frame velocity at each sample's ping, ``positions`` its position. Tracks are cached
    per mission until the next ``fit``. A mission without an IMU raises ``NoImuError``
    (from ``tracks`` and ``predict``)."""

    name = "INS/DVL"

    def __init__(self, dataset, config: FilterConfig | None = None, *,
                 calibrate: bool = True) -> None:
        """Args: dataset: path of the file the windows come from; config: settings;
        calibrate: correct the beams by the calibration ``fit`` learns (False: the beams
        as measured, ``fit`` learns nothing)."""
        self.dataset = dataset
        self.config = config if config is not None else FilterConfig()
        self.calibrate = calibrate
        if not calibrate:
            self.name = "INS/DVL (raw beams)"
        self.correction: tuple[np.ndarray, np.ndarray] | None = None
        self._tracks: dict[str, FilterTrack] = {}

    def fit(self, train: Windows) -> InsDvlFilter:
        if self.calibrate:
            calibration = BeamCalibration().fit(train)
            self.correction = (calibration.scale, calibration.bias)
        self._tracks = {}
        return self

    def tracks(self, windows: Windows) -> dict[str, FilterTrack]:
        """The track of every mission the windows use, by name (run once, cached)."""
        wanted = [windows.names[i] for i in np.unique(windows.mission)]
        missing = [name for name in wanted if name not in self._tracks]
        if missing:
            with open_dataset(self.dataset) as f:
                for name in missing:
                    self._tracks[name] = run_mission(f.missions[name], self.config,
                                                     beam_correction=self.correction)
        return {name: self._tracks[name] for name in wanted}

    def predict(self, windows: Windows) -> np.ndarray:
        """(S, 3) DVL-frame velocity, m/s, at each sample's ping: the track of mission
        ``windows.names[windows.mission]`` at the ping whose time is ``windows.time``
        (NaN if no ping has that time)."""
        return self._at_pings(windows, "velocity_dvl")

    def positions(self, windows: Windows) -> np.ndarray:
        """(S, 3) estimated NED position of the body origin, m, at each sample's ping."""
        return self._at_pings(windows, "position_ned")

    def _at_pings(self, windows: Windows, field: str) -> np.ndarray:
        tracks = self.tracks(windows)
        out = np.full((len(windows.time), 3), np.nan)
        for i in np.unique(windows.mission):
            track = tracks[windows.names[i]]
            rows = np.flatnonzero(windows.mission == i)
            k = np.searchsorted(track.ping_time, windows.time[rows])
            k = np.minimum(k, len(track.ping_time) - 1)
            hit = np.abs(track.ping_time[k] - windows.time[rows]) <= 1e-9 * np.maximum(
                1.0, np.abs(windows.time[rows]))
            out[rows[hit]] = getattr(track, field)[k[hit]]
        return out


ESTIMATORS = (
    Spec("INS/DVL", "INS/DVL filter: the IMU integrated, updated by each locked beam",
         "filter", make=InsDvlFilter, order=10,
         needs=Needs(beams=0, imu=True, text="needs the IMU record"),
         why="its noise model is the file's, and it gates beams it finds inconsistent"),
)
