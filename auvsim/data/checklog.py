"""``auvsim check-log``: what a recorded log does not document, found from its data.

A log's description may leave out the IMU's axis convention, how the streams' clocks line
up, where the sensors sit and how the DVL is mounted. Each is found here against the log's
reference navigation solution (position, NED velocity and attitude of the reference point),
by a small pure function on arrays that returns a ``Finding``: the value, the evidence it
rests on and a confidence. ``check_arrays`` runs them in order on a ``Log`` (arrays), and
``check_log`` on a recorded mission (``check_file`` on each of a file's); ``apply``
writes a corrected dataset.

Models (auvsim's conventions: body FRD, world NED, C = body -> NED from the reference's
quaternion, SI units). Times: a stream's stamp ``s`` happened at reference-clock time
``t = s + offset + rate_error * s``: every clock is measured against the reference's.
The corrected file's time base is chosen by evidence (``time_base``): the IMU's own clock
when its stamps keep the IMU's stated rate and the reference's stamps do not (the A-KIT
logs: the reference's and the DVL's stamps are stretched by 400/399), else the
reference's. How the reference's stamps compare with physical seconds is also measured
from its positions against its velocities (``reference_clock``), as evidence.

* IMU axes: ``P`` among the 48 signed permutations maps the logged triads onto the body,
  ``f_body = P f_log``: the 24 proper ones (det +1) and the 24 reflections, which no
  physical triad is but a log written through a wrong transformation holds (the A-KIT
  IMU files: ``[x, -y, z]``). Between reference samples k and k+1 the gyro's mean
  rate must equal the reference's attitude change ``log(C_k^T C_k+1) / dt``
  (``frames.attitude_rates``), and the accelerometers' mean must equal
  ``C^T (dv/dt - g n_down)`` (gravity levelled with the reference's roll and pitch).
  Each candidate's residuals, normalised by the signals' RMS, give its score; the
  winner's margin is the runner-up's score over the winner's.
* Clock offsets: the IMU's by the gyro's interval means against the reference's attitude
  rate, the DVL's by its velocity against the reference's velocity in the body,
  ``C^T v_ref``; a least-squares scan over the offset (the cross-correlation's equivalent
  for vectors), refined by a parabola to a fraction of a sample, in windows along the log;
  a line through the windows' offsets gives the offset and the clock-rate error, kept when
  the slope is significant (three standard errors).
* DVL: ``v_dvl = (1 + k) M^T (C^T v_ref + w x L)``, linearised for small mounting angles
  ``m`` (``M ~ I + [m]x``): ``v_dvl - u = k u + u x m + w x L`` with ``u = C^T v_ref``,
  solved by least squares for the scale ``1 + k``, the mounting ``m`` and the lever arm
  ``L`` (from the reference point), with standard errors from the residuals.
* Depth: a pressure sensor's depth against the reference's down position, less a
  constant (the sensor's depth below the reference point and the origin's), scanned over
  the offset as the others, in the windows where the vehicle's vertical speed varies
  (its vertical speed's std at least ``MIN_HEAVE``: a steady climb only adds a constant;
  the few cm/s a vehicle heaves in level flight can be enough); a log whose depth never
  changes leaves it not observable.
* IMU lever arm: ``f_imu = f_ref + dw/dt x L + w x (w x L) + b``: the IMU's specific force
  rotated into NED with the gyro-propagated attitude and integrated over each reference
  interval, against the reference's velocity change minus gravity (and Coriolis where the
  latitude is known); least squares for ``L`` and an accelerometer bias ``b``.
* Gravity: the IMU's mean |f| over quiet intervals (no turn, no acceleration in the
  reference) against the WGS-84 normal gravity at the latitude
  (``auvsim.physics.earth.normal_gravity``).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
from dataclasses import asdict, dataclass, field

import numba
import numpy as np

from auvsim.data.reader import open_dataset, require_attitude
from auvsim.data.schema import mission_attrs
from auvsim.data.writer import DatasetWriter
from auvsim.errors import ConfigError, DatasetError
from auvsim.physics.earth import earth_rate_ned
from auvsim.physics.frames import attitude_rates, rot_into, rotation_matrices, skew
from auvsim.sensors.dvl import NAVIGATOR_SLOW_ERROR_STD, NAVIGATOR_SLOW_ERROR_TIME

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

MAX_OFFSET = 5.0  # s: the clock offsets searched, either way
AXES_STEP = 0.25  # s: the offset grid each DVL axis map is scored on (a 1 Hz DVL's pings
# between grid points cost a turn's change of velocity over 0.125 s at most)
MIN_REFERENCE = 30  # reference samples: fewer leave the windows' fits without data
MIN_DVL_PINGS = 30  # DVL pings with a velocity: fewer leave its clock and calibration open
OFFSET_WINDOW = 50.0  # s of reference per window of the offset-vs-time fit
SIGNIFICANT = 3.0  # standard errors: a parameter kept beyond this
# Student's t quantiles at the normal's 3 sigma (two-sided 99.73 %), by degrees of freedom
# 1..30 (scipy.stats.t.ppf(scipy.stats.norm.cdf(3), dof); tests/test_checklog.py checks
# them): a slope through a few windows' offsets is significant beyond these, not beyond 3.
T_3SIGMA = (236, 19.2, 9.22, 6.62, 5.51, 4.9, 4.53, 4.28, 4.09, 3.96, 3.85, 3.76, 3.69,
            3.64, 3.59, 3.54, 3.51, 3.48, 3.45, 3.42, 3.4, 3.38, 3.36, 3.34, 3.33, 3.32,
            3.3, 3.29, 3.28, 3.27)
MIN_TURN = math.radians(0.5)  # rad/s RMS: a window turning less says nothing of its clock
MIN_HEAVE = 0.005  # m/s, the vertical speed's std: a window varying less says nothing of
# the depth's clock (a pressure sensor's 1 cm of noise at 10 Hz leaves a window 0.1 s here)
QUIET_RATE = math.radians(0.5)  # rad/s: an interval turning less is "quiet" for gravity
CLOCK_PROBE = 0.01  # s: the clock error an IMU lever arm's sensitivity is shown for
QUIET_ACCEL = 0.02  # m/s^2: and accelerating less
AXES = "xyz"
# A DVL's scale error beyond this is not a calibration's: the speed of sound in sea water
# spans about 1450 to 1550 m/s, so an instrument that assumes 1500 is off by at most ~3 %.
SCALE_PLAUSIBLE = 0.05
# A stream's stamps "agree with its stated rate" within this: quartz oscillators, which
# clock loggers and sensors, are specified to tens of ppm (e.g. +-20 to +-100 ppm
# frequency tolerance), and a stretch of stamps that matters here is thousands.
STAMP_TOLERANCE = 1e-4


@dataclass(frozen=True)
class Finding:
    """One thing the log does not document, as found.

    Attributes:
        name: what was looked for ("imu axes", "imu clock", ...).
        value: the value, JSON-able (numbers, lists, strings).
        text: the value for a reader.
        evidence: what the value rests on, with its figures.
        confidence: "high", "medium", "low" or "not observable".
    """

    name: str
    value: dict
    text: str
    evidence: str
    confidence: str


@dataclass(frozen=True)
class Log:
    """A log as arrays (each stream on its own stamps, seconds). The IMU or the DVL may be
    absent (``None``); the reference is required.

    Attributes:
        reference_time: (R,) s. reference_velocity: (R, 3) m/s NED. reference_quaternion:
            (R, 4) body -> NED [w, x, y, z]. reference_position: (R, 3) m NED or None.
        imu_time: (N,) s. specific_force: (N, 3) m/s^2 and angular_rate: (N, 3) rad/s, as
            logged (axes to be found).
        dvl_time: (P,) s. dvl_velocity: (P, 3) m/s in the DVL frame (NaN where none).
        depth_time: (D,) s. depth: (D,) m, positive down.
        gravity: m/s^2, the expected gravity (WGS-84 normal gravity at the latitude).
        latitude_deg: the latitude, or None (no Earth rate then).
        stated_rates: the rate each stream's instrument states, Hz, by stream ("imu",
            "dvl", "reference"; the log description's ``rate_hz``): where given, the
            time base is chosen by them (``time_base``).
        dvl_slow_error_time: s, the correlation time of the DVL's velocity error against
            the reference, which the DVL calibration's standard errors allow for
            (``serial_least_squares``); default the Snapir's Navigator's, measured against
            its reference (``NAVIGATOR_SLOW_ERROR_TIME``); ``log_of`` reads a mission's own
            where its attributes state one (``slow_error``).
    """

    reference_time: np.ndarray
    reference_velocity: np.ndarray
    reference_quaternion: np.ndarray
    reference_position: np.ndarray | None = None
    imu_time: np.ndarray | None = None
    specific_force: np.ndarray | None = None
    angular_rate: np.ndarray | None = None
    dvl_time: np.ndarray | None = None
    dvl_velocity: np.ndarray | None = None
    depth_time: np.ndarray | None = None
    depth: np.ndarray | None = None
    gravity: float = 9.80665
    latitude_deg: float | None = None
    stated_rates: dict = field(default_factory=dict)
    dvl_slow_error_time: float = NAVIGATOR_SLOW_ERROR_TIME


@dataclass
class Report:
    """Every finding of one mission, and the corrections ``apply`` makes of them."""

    mission: str
    findings: list[Finding] = field(default_factory=list)
    corrections: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"mission": self.mission, "findings": [asdict(f) for f in self.findings],
                "corrections": self.corrections}

    def table(self) -> str:
        """The findings as a table for a reader."""
        rows = [("finding", "value", "confidence", "evidence")]
        rows += [(f.name, f.text, f.confidence, f.evidence) for f in self.findings]
        widths = [max(len(r[i]) for r in rows) for i in range(3)]
        lines = [f"mission {self.mission}"]
        for r in rows:
            lines.append("  " + "  ".join(r[i].ljust(widths[i]) for i in range(3)) + "  " + r[3])
        return "\n".join(lines)


# ---- geometry ------------------------------------------------------------------------


def axis_maps(*, proper: bool = True) -> list[np.ndarray]:
    """The 24 proper signed permutations (det +1), (3, 3) each: ``body = P @ logged``;
    all 48 with ``proper=False``."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            p = np.zeros((3, 3))
            p[range(3), perm] = signs
            if not proper or np.linalg.det(p) > 0:
                out.append(p)
    return out


def axis_map_names(p: np.ndarray) -> list[str]:
    """The log's axis on each body axis, as a log description's ``axis_map`` writes it
    (``["x", "-y", "-z"]``)."""
    return [("-" if p[i, j] < 0 else "") + AXES[j] for i in range(3)
            for j in range(3) if p[i, j] != 0]


# ---- the reference, interval by interval ------------------------------------------------


@dataclass(frozen=True)
class Intervals:
    """The reference between consecutive samples: (K,) starts and ends (reference clock,
    s), body rates (K, 3) rad/s from the attitude change, the specific force the reference
    implies in the body (K, 3) m/s^2, and the NED velocity change (K, 3) m/s."""

    start: np.ndarray
    end: np.ndarray
    rate: np.ndarray
    force: np.ndarray
    dv: np.ndarray

    @property
    def dt(self) -> np.ndarray:
        return self.end - self.start


def intervals(log: Log) -> Intervals:
    t = np.asarray(log.reference_time, float)
    c = rotation_matrices(log.reference_quaternion)
    dt = np.diff(t)
    rate = attitude_rates(t, log.reference_quaternion)
    dv = np.diff(np.asarray(log.reference_velocity, float), axis=0)
    accel = dv / dt[:, None] - np.array([0.0, 0.0, log.gravity])
    mid = (c[:-1] + c[1:]) / 2  # the attitude halfway, to first order
    force = np.einsum("kji,kj->ki", mid, accel)
    return Intervals(t[:-1], t[1:], rate, force, dv)


def cumulative(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N, D) trapezoidal running integral of (N, D) samples ``x`` at times ``t``."""
    steps = (x[1:] + x[:-1]) / 2 * np.diff(t)[:, None]
    return np.vstack([np.zeros((1, x.shape[1])), np.cumsum(steps, axis=0)])


def window_means(t: np.ndarray, integral: np.ndarray, a: np.ndarray,
                 b: np.ndarray) -> np.ndarray:
    """(K, D) means over [a, b] (stamps) of the signal whose running integral is
    ``integral`` (N, D) at ``t``."""
    ia = np.stack([np.interp(a, t, integral[:, d]) for d in range(integral.shape[1])], -1)
    ib = np.stack([np.interp(b, t, integral[:, d]) for d in range(integral.shape[1])], -1)
    return (ib - ia) / (b - a)[:, None]


# ---- IMU axes ---------------------------------------------------------------------------


def margin_confidence(margin: float) -> str:
    """An axis map's confidence by its margin (the runner-up's score over the winner's)."""
    return "high" if margin > 3 else "medium" if margin > 1.5 else "low"


def imu_axes(log: Log, ref: Intervals) -> tuple[np.ndarray, Finding]:
    """The axis map P (body = P logged) that best explains the reference's attitude change
    and levelled gravity. Every signed permutation is scored, the 24 proper ones (det +1)
    and the 24 reflections: a reflection is no physical triad, but a log written through
    a wrong transformation holds one, and the data should say so rather than be forced
    into the best proper map. The gyro is compared in windows of ``OFFSET_WINDOW`` s, each
    at its own best clock offset (the clocks are not known yet and may drift)."""
    t = np.asarray(log.imu_time, float)
    w_int = cumulative(t, np.asarray(log.angular_rate, float))
    f_int = cumulative(t, np.asarray(log.specific_force, float))
    inside = (ref.start - MAX_OFFSET >= t[0]) & (ref.end + MAX_OFFSET <= t[-1])
    if inside.sum() < 10:
        inside = (ref.start >= t[0]) & (ref.end <= t[-1])
    if not inside.any():
        raise DatasetError("the IMU's stamps and the reference's do not overlap by one whole "
                           "reference interval; expected streams recorded together")
    a, b = ref.start[inside], ref.end[inside]
    rate, force = ref.rate[inside], ref.force[inside]
    window = ((a - a[0]) // OFFSET_WINDOW).astype(int)
    offsets = np.arange(-MAX_OFFSET, MAX_OFFSET + 1e-9, 0.05)
    gyro = np.stack([window_means(t, w_int, a - o, b - o) for o in offsets])  # (T, K, 3)
    accel = window_means(t, f_int, a, b)
    rate_rms = float(np.sqrt(np.mean(rate ** 2)))
    force_rms = float(np.sqrt(np.mean(force ** 2)))
    scored = []
    for p in axis_maps(proper=False):
        cost = np.sum((gyro @ p.T - rate) ** 2, axis=-1)  # (T, K)
        per_window = [cost[:, window == j].sum(axis=1) for j in np.unique(window)]
        gyro_ms = sum(float(c.min()) for c in per_window) / len(a)
        force_ms = float(np.mean(np.sum((accel @ p.T - force) ** 2, axis=-1)))
        score = math.sqrt(gyro_ms / rate_rms ** 2 + force_ms / force_rms ** 2)
        scored.append((score, p, math.sqrt(gyro_ms), math.sqrt(force_ms)))
    scored.sort(key=lambda s: s[0])
    proper = [s for s in scored if np.linalg.det(s[1]) > 0]
    (s1, p, g1, f1), (s2, p2, g2, f2) = scored[0], scored[1]
    margin = s2 / max(s1, 1e-12)
    names = axis_map_names(p)
    reflection = np.linalg.det(p) < 0
    sp, pp, gp, fp = proper[0]
    evidence = (f"gyro residual {math.degrees(g1):.3g} deg/s (reference rate RMS "
                f"{math.degrees(rate_rms):.3g} deg/s), levelled gravity residual {f1:.3g} "
                f"m/s^2, over {len(a)} intervals; runner-up {axis_map_names(p2)}: "
                f"{math.degrees(g2):.3g} deg/s, {f2:.3g} m/s^2; margin {margin:.3g}x")
    if reflection:
        evidence += (f"; a REFLECTION (det -1): no physical triad is left-handed, the log's "
                     f"transformation is; best proper map {axis_map_names(pp)}: "
                     f"{math.degrees(gp):.3g} deg/s, {fp:.3g} m/s^2, {sp / s1:.3g}x worse")
    confidence = margin_confidence(margin)
    return p, Finding("imu axes", {"axis_map": names, "matrix": p.tolist(),
                                   "determinant": int(round(np.linalg.det(p))),
                                   "score": s1, "runner_up": axis_map_names(p2),
                                   "runner_up_score": s2, "margin": margin,
                                   "best_proper": axis_map_names(pp),
                                   "best_proper_score": sp},
                      f"[{', '.join(names)}]" + (" (reflection)" if reflection else ""),
                      evidence, confidence)


# ---- clocks -----------------------------------------------------------------------------


def scan(cost, centre: float = 0.0, half: float = MAX_OFFSET,
         step: float = 0.05) -> tuple[float, float]:
    """The offset minimising ``cost(offset)``: a grid over centre +- half, a finer grid
    around its best, and a parabola through the best three points. Returns the offset and
    the cost's curvature there (its second derivative)."""
    for h, s in ((half, step), (5 * step, step / 10)):
        grid = np.arange(centre - h, centre + h + s / 2, s)
        costs = np.array([cost(o) for o in grid])
        k = int(np.argmin(costs))
        centre = float(grid[k])
    if 0 < k < len(grid) - 1:
        c0, c1, c2 = costs[k - 1], costs[k], costs[k + 1]
        curvature = (c0 - 2 * c1 + c2) / s ** 2
        if curvature > 0:
            return centre + s * (c0 - c2) / (2 * (c0 - 2 * c1 + c2)), float(curvature)
    return centre, 0.0


@dataclass(frozen=True)
class Clock:
    """A stream's clock against the reference's: ``t = s + offset + rate_error * s``."""

    offset: float
    rate_error: float
    offset_se: float
    rate_se: float
    windows: list  # [stamp at the window's centre, offset]


def fit_clock(stamps: list[float], offsets: list[float], whole: float) -> Clock:
    """A line through the windows' offsets. The slope (the rate error) is kept when it is
    significant (Student's t beyond ``T_3SIGMA``) and moves the clock by more than
    ``CLOCK_PROBE`` over the windows; else the offset is ``whole``, the one found over
    the whole log."""
    s, o = np.asarray(stamps), np.asarray(offsets)
    windows = [[float(a), float(b)] for a, b in zip(s, o, strict=True)]
    if len(s) >= 3:
        x, se, _ = least_squares(np.stack([np.ones_like(s), s], axis=1), o)
        critical = T_3SIGMA[min(len(s) - 2, len(T_3SIGMA)) - 1]
        drift = abs(x[1]) * float(s.max() - s.min())
        if abs(x[1]) > critical * max(se[1], 1e-12) and drift > CLOCK_PROBE:
            return Clock(float(x[0]), float(x[1]), float(se[0]), float(se[1]), windows)
        spread = float(np.std(o, ddof=1) / math.sqrt(len(o)))
        return Clock(whole, 0.0, spread, float(se[1]), windows)
    return Clock(whole, 0.0, float("nan"), float("nan"), windows)


def imu_clock(log: Log, p: np.ndarray, ref: Intervals) -> Clock:
    """The IMU's clock: its gyro's interval means (axes ``p``) against the reference's
    attitude rate, in windows of ``OFFSET_WINDOW`` s."""
    t = np.asarray(log.imu_time, float)
    w_int = cumulative(t, np.asarray(log.angular_rate, float) @ p.T)

    def offset_of(sel: np.ndarray, centre: float, half: float) -> tuple[float, float]:
        a, b, rate = ref.start[sel], ref.end[sel], ref.rate[sel]

        def cost(o: float) -> float:
            return float(np.mean(np.sum((window_means(t, w_int, a - o, b - o) - rate) ** 2,
                                        axis=1)))
        return scan(cost, centre, half)

    usable = (ref.start - MAX_OFFSET >= t[0]) & (ref.end + MAX_OFFSET <= t[-1])
    whole, _ = offset_of(usable, 0.0, MAX_OFFSET)
    stamps, offsets = [], []
    for lo in np.arange(ref.start[0], ref.end[-1], OFFSET_WINDOW):
        sel = usable & (ref.start >= lo) & (ref.end <= lo + OFFSET_WINDOW)
        if sel.sum() < 10 or np.sqrt(np.mean(ref.rate[sel] ** 2)) < MIN_TURN:
            continue
        o, curvature = offset_of(sel, whole, 2.0)
        if curvature > 0:
            centre = float(np.mean((ref.start[sel] + ref.end[sel]) / 2))
            stamps.append(centre - o)
            offsets.append(o)
    return fit_clock(stamps, offsets, whole)


def usable_pings(log: Log) -> np.ndarray:
    """(P,) the DVL's pings a clock is fitted on: those with a velocity, stamped inside the
    reference's span less ``MAX_OFFSET`` s at each end (every trial offset finds them a
    reference)."""
    s = np.asarray(log.dvl_time, float)
    return (np.isfinite(np.asarray(log.dvl_velocity, float)).all(axis=1)
            & (s - MAX_OFFSET >= log.reference_time[0])
            & (s + MAX_OFFSET <= log.reference_time[-1]))


def dvl_axes(log: Log, ref_body: np.ndarray, rates) -> tuple[np.ndarray, Finding]:
    """The axis map P (body = P logged) that best explains the DVL's velocity against the
    reference's in the body ``ref_body`` (R, 3) with the body rates ``rates(times)``:
    each of the 48 signed permutations, with a lever arm and a bias fitted (a DVL 2 m from
    the reference point sways by half a m/s in a hard turn; no scale or mounting, which
    would take up the map's signs) at its best clock offset on a grid of ``AXES_STEP`` s
    over ``MAX_OFFSET`` either way, scored by the residual's RMS. A log description that
    declares the wrong frame (FRD for FLU) or axis map reads here as a map other than the
    identity; ``apply`` then refuses, since the fix is the description's (logged beams
    are not turned with the velocity)."""
    t_ref = np.asarray(log.reference_time, float)
    use = usable_pings(log)
    s = np.asarray(log.dvl_time, float)[use]
    v = np.asarray(log.dvl_velocity, float)[use]
    maps = axis_maps(proper=False)
    turned = np.stack([v @ p.T for p in maps], axis=-1)  # (N, 3, 48)
    best = np.full(len(maps), np.inf)
    for o in np.arange(-MAX_OFFSET, MAX_OFFSET + 1e-9, AXES_STEP):
        t = s + o
        u = np.stack([np.interp(t, t_ref, ref_body[:, d]) for d in range(3)], -1)
        # v_map - u = w x L + b: one design for every map, a right-hand side each
        a = np.concatenate([skew(rates(t)), np.broadcast_to(np.eye(3), (len(t), 3, 3))],
                           axis=2).reshape(-1, 6)
        b = (turned - u[:, :, None]).reshape(-1, len(maps))
        x, *_ = np.linalg.lstsq(a, b, rcond=None)
        best = np.minimum(best, np.mean((b - a @ x) ** 2, axis=0) * 3)
    speed_rms = float(np.sqrt(np.mean(np.sum(ref_body ** 2, axis=-1))))
    order = np.argsort(best, kind="stable")  # ties: axis_maps' order, the identity first
    (r1, p), (r2, p2) = ((math.sqrt(best[k]), maps[k]) for k in order[:2])
    margin = r2 / max(r1, 1e-12)
    names = axis_map_names(p)
    logged = bool(np.array_equal(p, np.eye(3)))
    confidence = margin_confidence(margin)
    evidence = (f"velocity against the reference's in the body over {int(use.sum())} pings, "
                f"a lever arm and a bias fitted for each map at its best offset: residual "
                f"{1000 * r1:.1f} mm/s RMS (the reference's speed RMS "
                f"{speed_rms:.2f} m/s); runner-up {axis_map_names(p2)}: {1000 * r2:.1f} mm/s; "
                f"margin {margin:.3g}x")
    if not logged:
        evidence += ("; the DVL's clock and calibration below are fitted with this map; "
                     "state it in the log description (dvl.axis_map, or dvl.frame) and "
                     "import again")
    return p, Finding("dvl axes", {"axis_map": names, "matrix": p.tolist(),
                                   "determinant": int(round(np.linalg.det(p))),
                                   "residual_m_s": r1, "runner_up": axis_map_names(p2),
                                   "runner_up_residual_m_s": r2, "margin": margin,
                                   "as_logged": logged},
                      "as logged" if logged else f"[{', '.join(names)}]", evidence,
                      confidence)


def dvl_clock(log: Log, ref_body: np.ndarray, rates) -> tuple[Clock, Finding]:
    """The DVL's clock: its velocity against the reference's velocity in the body
    ``ref_body`` (R, 3), in windows of ``OFFSET_WINDOW`` s. At each trial offset the DVL
    model (scale, mounting, lever arm with the body rates ``rates(times)`` (M, 3), and a
    constant bias) is fitted first and its residual scored: the lever arm's ``w x L``
    follows the turns as the body velocity does, and would pull a bare comparison's
    offset by a large fraction of a second."""
    t_ref = np.asarray(log.reference_time, float)
    s = np.asarray(log.dvl_time, float)
    v = np.asarray(log.dvl_velocity, float)

    def offset_of(sel: np.ndarray, centre: float, half: float) -> tuple[float, float]:
        def cost(o: float) -> float:
            inside = sel & (s + o >= t_ref[0]) & (s + o <= t_ref[-1])
            if inside.sum() < 10:
                return 1e9
            t = s[inside] + o
            u = np.stack([np.interp(t, t_ref, ref_body[:, d]) for d in range(3)], -1)
            a = np.concatenate([dvl_model(u, rates(t)),
                                np.broadcast_to(np.eye(3), (len(t), 3, 3))], axis=2)
            b = (v[inside] - u).ravel()
            x, *_ = np.linalg.lstsq(a.reshape(-1, 10), b, rcond=None)
            r = b - a.reshape(-1, 10) @ x
            return float(r @ r) / len(t)
        return scan(cost, centre, half)

    usable = usable_pings(log)
    whole, _ = offset_of(usable, 0.0, MAX_OFFSET)
    stamps, offsets = [], []
    for lo in np.arange(s[0], s[-1], OFFSET_WINDOW):
        sel = usable & (s >= lo) & (s < lo + OFFSET_WINDOW)
        if sel.sum() < 10:
            continue
        o, curvature = offset_of(sel, whole, 2.0)
        if curvature > 0:
            stamps.append(float(np.mean(s[sel])))
            offsets.append(o)
    clock = fit_clock(stamps, offsets, whole)
    return clock, clock_finding("dvl clock", clock, s, "velocity against the "
                                "reference's velocity in the body, the DVL model fitted at "
                                "each trial offset")


def depth_clock(log: Log) -> tuple[Clock | None, Finding]:
    """The depth sensor's clock: its depth against the reference's down position less a
    constant, scanned over the offset in windows of ``OFFSET_WINDOW`` s where the
    reference's vertical speed varies (its std ``MIN_HEAVE`` or more). None and a
    "not observable" finding where fewer than three windows do (a depth that never
    changes)."""
    t_ref = np.asarray(log.reference_time, float)
    down = None if log.reference_position is None else np.asarray(
        log.reference_position, float)[:, 2]
    s = np.asarray(log.depth_time, float)
    d = np.asarray(log.depth, float)
    heave = np.asarray(log.reference_velocity, float)[:, 2]

    def offset_of(sel: np.ndarray, centre: float, half: float) -> tuple[float, float]:
        def cost(o: float) -> float:
            inside = sel & (s + o >= t_ref[0]) & (s + o <= t_ref[-1])
            if inside.sum() < 10:
                return 1e9
            r = d[inside] - np.interp(s[inside] + o, t_ref, down)
            return float(np.var(r))
        return scan(cost, centre, half)

    stamps, offsets = [], []
    if down is not None:
        whole, _ = offset_of(np.ones(len(s), dtype=bool), 0.0, MAX_OFFSET)
        for lo in np.arange(s[0], s[-1], OFFSET_WINDOW):
            sel = (s >= lo) & (s < lo + OFFSET_WINDOW)
            near = (t_ref >= lo) & (t_ref < lo + OFFSET_WINDOW)
            if sel.sum() < 10 or not near.any():
                continue
            # A steady climb shifts the depth by a constant, which the fit takes out: only
            # a change in the vertical speed tells the clock.
            if float(np.std(heave[near])) < MIN_HEAVE:
                continue
            o, curvature = offset_of(sel, whole, 2.0)
            if curvature > 0:
                stamps.append(float(np.mean(s[sel])))
                offsets.append(o)
    if len(stamps) < 3:
        return None, Finding(
            "depth clock", {"windows": len(stamps)}, "not found",
            f"{len(stamps)} windows of {OFFSET_WINDOW:g} s in which the reference's "
            f"vertical speed varies by {MIN_HEAVE:g} m/s (std) or more; expected at least 3 "
            "(a depth that never changes, or a steady climb, says nothing of its clock); "
            "not applied", "not observable")
    clock = fit_clock(stamps, offsets, whole)
    return clock, clock_finding("depth clock", clock, s, "depth against the reference's "
                                "down position less a constant, in the windows where its "
                                "vertical speed varies")


def clock_finding(name: str, clock: Clock, t: np.ndarray, what: str) -> Finding:
    nominal = 1.0 / float(np.median(np.diff(t)))
    realised = nominal / (1 + clock.rate_error)
    spread = (f"window offsets {min(o for _, o in clock.windows):+.3f} to "
              f"{max(o for _, o in clock.windows):+.3f} s" if clock.windows else "no window")
    rate = (f", rate error {clock.rate_error * 1e6:+.0f} ppm +- {clock.rate_se * 1e6:.0f}"
            f" ({nominal:.6g} Hz stamped, {realised:.6g} Hz on the reference's clock)"
            if clock.rate_error else
            f", no significant rate error ({clock.rate_se * 1e6:.0f} ppm SE)"
            if math.isfinite(clock.rate_se) else "")
    text = f"{clock.offset:+.3f} s" + (f", {clock.rate_error * 1e6:+.0f} ppm"
                                       if clock.rate_error else "")
    se = clock.offset_se
    confidence = ("low" if not math.isfinite(se) or len(clock.windows) < 3 else
                  "high" if se < 0.02 else "medium" if se < 0.1 else "low")
    return Finding(name, {"offset_s": clock.offset, "offset_se_s": se,
                          "rate_error": clock.rate_error, "rate_error_se": clock.rate_se,
                          "windows": clock.windows},
                   text, f"{what}; {len(clock.windows)} "
                   f"{'window' if len(clock.windows) == 1 else 'windows'} of {OFFSET_WINDOW:g} s, "
                   f"{spread}{rate}", confidence)


def reference_clock(log: Log) -> Finding:
    """How many physical seconds a stamped second of the reference is, as far as its own
    data say: its horizontal positions against its velocities integrated over the
    stamps, fitted in windows of ``OFFSET_WINDOW`` s (one scale, an intercept per axis;
    the windows' spread gives the standard error, the residuals not being white).

    Reported, never applied: the ratio is the clock's scale times the reference's
    velocity scale, and a DVL-aided INS's velocities carry a scale error of a few
    thousandths (the DVL's own, which ``dvl_calibration`` measures at that size), the
    size of the stretch it would have to detect. Every other stream is put on the
    reference's stamps as they are."""
    if log.reference_position is None:
        return Finding("reference clock", {"scale": None}, "-", "no reference positions",
                       "not observable")
    t = np.asarray(log.reference_time, float)
    p = np.asarray(log.reference_position, float)[:, :2]
    flown = cumulative(t, np.asarray(log.reference_velocity, float)[:, :2])
    scales = []
    for lo in np.arange(t[0], t[-1], OFFSET_WINDOW):
        sel = (t >= lo) & (t < lo + OFFSET_WINDOW)
        if sel.sum() < 10:
            continue
        f = flown[sel] - flown[sel].mean(axis=0)
        d = p[sel] - p[sel].mean(axis=0)
        if (f ** 2).sum() > 0:
            scales.append(float((f * d).sum() / (f ** 2).sum()))
    if len(scales) < 2:
        return Finding("reference clock", {"scale": None}, "-", "too short for two windows",
                       "not observable")
    scale = float(np.mean(scales))
    se = float(np.std(scales, ddof=1) / math.sqrt(len(scales)))
    stamp = float(np.median(np.diff(t)))
    evidence = (f"horizontal positions moved {scale:.5f} x the velocities integrated over "
                f"the stamps ({len(scales)} windows: {min(scales):.5f} to {max(scales):.5f}, "
                f"SE {se:.1e}); stamped every {stamp:.7g} s, {stamp * scale:.7g} s if the "
                "velocities have no scale error: not applied (clock and velocity scale "
                "are one product here)")
    return Finding("reference clock", {"scale": scale, "scale_se": se, "windows": scales,
                                       "stamp_s": stamp}, f"x{scale:.5f}", evidence, "low")


def stamp_stretch(t: np.ndarray, stated: float) -> float:
    """How many stamped seconds a stream's stamps (N,) give to a second at its stated
    rate (Hz), less one: ``median interval x stated rate - 1``."""
    return float(np.median(np.diff(np.asarray(t, float)))) * stated - 1.0


def time_base(log: Log, imu_clock_found: Clock | None, reference: Finding) -> Finding:
    """Which clock the corrected file keeps: the IMU's (an INS's own clock) or the
    reference's.

    The evidence: each stream's stamps against its stated rate (``log.stated_rates``), the
    IMU's rate error against the reference (``imu_clock_found``), and the reference's
    positions against its velocities (``reference``). The IMU's clock is the time base when
    its stamps agree with its stated rate (within ``STAMP_TOLERANCE``), the reference's do
    not, and the two stretches predict the rate error found (within three standard errors
    and ``STAMP_TOLERANCE``); then the reference's stamps are the stretched ones. Else the
    reference's clock stays the time base, as the findings measure every clock against it.
    """
    rates = log.stated_rates
    stretch = {g: stamp_stretch(t, rates[g]) for g, t in
               (("imu", log.imu_time), ("dvl", log.dvl_time),
                ("reference", log.reference_time)) if t is not None and rates.get(g)}
    value = {"clock": "reference", "stamp_stretch": stretch, "stated_rates_hz": dict(rates),
             "reference_scale": reference.value.get("scale")}
    parts = [f"{g} stamps {1e6 * e:+.0f} ppm against the stated {rates[g]:g} Hz"
             for g, e in stretch.items()]
    if imu_clock_found is None or "imu" not in stretch or "reference" not in stretch:
        why = "no stated rates for the IMU and the reference" if imu_clock_found is not None \
            else "no IMU"
        return Finding("time base", value, "reference",
                       "; ".join(parts + [f"{why}: every stream on the reference's clock"]),
                       "low")
    predicted = (1 + stretch["reference"]) / (1 + stretch["imu"]) - 1
    found = imu_clock_found.rate_error
    tolerance = SIGNIFICANT * (imu_clock_found.rate_se if math.isfinite(
        imu_clock_found.rate_se) else 0.0) + STAMP_TOLERANCE
    explained = abs(found - predicted) <= tolerance
    value.update(predicted_imu_rate_error=predicted, imu_rate_error=found,
                 imu_rate_error_se=imu_clock_found.rate_se)
    se = imu_clock_found.rate_se
    parts.append(f"they predict the IMU's rate error against the reference "
                 f"{1e6 * predicted:+.0f} ppm; "
                 + (f"found {1e6 * found:+.0f} ppm" if found else
                    "the IMU clock's found none significant")
                 + (f" (SE {1e6 * se:.0f} ppm)" if math.isfinite(se) else "")
                 + f", {'within' if explained else 'beyond'} the {1e6 * tolerance:.0f} ppm "
                 "the two may differ by")
    scale = reference.value.get("scale")
    if scale is not None:
        parts.append(f"the reference's positions move x{scale:.4f} its velocities over its "
                     f"stamps (x{1 / (1 + stretch['reference']):.4f} if its stamps are "
                     "stretched so)")
    imu_true = abs(stretch["imu"]) <= STAMP_TOLERANCE
    if imu_true and abs(stretch["reference"]) > STAMP_TOLERANCE and explained:
        value["clock"] = "imu"
        return Finding("time base", value, "imu", "; ".join(parts + [
            "the IMU's stamps keep their stated rate and the reference's do not: every "
            "stream on the IMU's clock"]), "high")
    return Finding("time base", value, "reference", "; ".join(parts + [
        "every stream on the reference's clock"]), "medium")


# ---- lever arms, DVL calibration, gravity -------------------------------------------------


def rates_at(times: np.ndarray, imu_time: np.ndarray | None, rate_integral: np.ndarray | None,
             ref: Intervals, half: float = 0.1) -> np.ndarray:
    """(M, 3) body rates at ``times`` (reference clock): the gyro's mean over +- ``half``
    when there is one (``rate_integral`` (N, 3), rad: its running integral at
    ``imu_time``, ``cumulative``), else the reference's attitude rate, interpolated."""
    if imu_time is not None:
        return window_means(imu_time, rate_integral, times - half, times + half)
    mid = (ref.start + ref.end) / 2
    return np.stack([np.interp(times, mid, ref.rate[:, d]) for d in range(3)], -1)


def least_squares(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Solution, standard errors and residual RMS of ``a x = b``."""
    x, *_ = np.linalg.lstsq(a, b, rcond=None)
    resid = b - a @ x
    var = float(resid @ resid) / max(len(b) - a.shape[1], 1)
    cov = var * np.linalg.pinv(a.T @ a)
    return x, np.sqrt(np.maximum(np.diag(cov), 0.0)), math.sqrt(var)


def serial_least_squares(a: np.ndarray, b: np.ndarray, times: np.ndarray | None = None,
                         correlation_time: float | None = None
                         ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Least squares over a time series of blocks, ``a`` (T, K, n) x = ``b`` (T, K) (K
    equations per epoch), with standard errors that hold when the residuals are
    correlated from one epoch to the next. A DVL's slow error against a reference holds
    for ten pings or more, where the OLS standard error, which takes every ping as new
    information, is several times too small.

    Two estimates of the solution's covariance, and the larger standard error of the two
    for each parameter:

    - Newey & West's (Econometrica 55, 1987: the Bartlett-weighted sum of the score's
      autocovariances between the OLS sandwich's bread) with Andrews's bandwidth for it
      (Econometrica 59, 1991, eq. 6.2 and the AR(1) plug-in of sec. 6: ``1.1447 (alpha
      T)^(1/3)``, one AR(1) per score component, equally weighted), which needs no model
      of the residuals but, where they stay correlated over a good part of the log, sees
      too few independent stretches to measure it: about 8 of a 19 s error in 300 s,
      and there it is biased low.
    - With the epochs' ``times`` (T,) s and a ``correlation_time`` s: the residuals of
      each equation k modelled as white noise plus a first-order Gauss-Markov error of
      that correlation time (covariance ``w_k^2 delta_ij + s_k^2 exp(-|t_i - t_j| /
      correlation_time)``), the two variances from the residuals' variance and their
      products over the pairs up to 2 correlation times apart, and the OLS sandwich with
      that covariance. Where the residuals are correlated over a few epochs only, it comes
      out wider than it should, and the larger of the two with it (the simulated DVL's
      own error is this model's: ``tests/test_checklog.py`` measures both cases).

    Raises:
        ValueError: ``correlation_time`` not a positive number, or ``times`` not finite
            and increasing, one per epoch.

    Returns the solution, its standard errors, the residual RMS and the Newey-West
    bandwidth (epochs)."""
    t, k, n = a.shape
    flat = a.reshape(-1, n)
    x, *_ = np.linalg.lstsq(flat, b.ravel(), rcond=None)
    resid = b - a @ x
    score = np.einsum("tkn,tk->tn", a, resid)  # (T, n): each epoch's score
    lag1 = (score[1:] * score[:-1]).sum(axis=0)
    energy = (score[:-1] ** 2).sum(axis=0)
    rho = np.clip(np.divide(lag1, energy, out=np.zeros(n), where=energy > 0), -0.97, 0.97)
    var = (score ** 2).mean(axis=0) * (1 - rho ** 2)  # each AR(1)'s innovation variance
    alpha = (np.sum(4 * rho ** 2 * var ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2))
             / max(float(np.sum(var ** 2 / (1 - rho) ** 4)), 1e-300))
    lags = min(int(1.1447 * (alpha * t) ** (1 / 3)), t - 1)
    meat = score.T @ score
    for lag in range(1, lags + 1):
        cross = score[lag:].T @ score[:-lag]
        meat += (1 - lag / (lags + 1)) * (cross + cross.T)
    bread = np.linalg.pinv(flat.T @ flat)
    dof = max(resid.size - n, 1)
    small_sample = resid.size / dof  # the sandwich's small-sample factor
    variance = np.diag(bread @ meat @ bread) * small_sample
    if times is not None and correlation_time is not None and t > 1:
        times = np.asarray(times, float)
        if not (correlation_time > 0 and math.isfinite(correlation_time)):
            raise ValueError(f"correlation_time: expected a positive number of seconds, got "
                             f"{correlation_time!r}")
        if times.shape != (t,) or not (np.all(np.isfinite(times))
                                       and np.all(np.diff(times) > 0)):
            raise ValueError(f"times: expected {t} finite, increasing times, one per epoch")
        modelled = _gauss_markov_meat(times, a, resid, correlation_time)
        variance = np.maximum(variance, np.diag(bread @ modelled @ bread) * small_sample)
    rms = math.sqrt(float((resid ** 2).sum()) / dof)
    return x, np.sqrt(np.maximum(variance, 0.0)), rms, lags


def _gauss_markov_meat(times: np.ndarray, a: np.ndarray, resid: np.ndarray, tau: float
                       ) -> np.ndarray:
    """(n, n) ``sum_k A_k^T Sigma_k A_k`` for ``serial_least_squares``'s residual model:
    ``Sigma_k = w_k^2 I + s_k^2 R``, ``R_ij = exp(-|t_i - t_j| / tau)``. ``s_k^2`` is
    fitted to the residuals' products ``r_i r_j`` of the pairs up to 2 ``tau`` apart (in
    epochs at the median step; least squares on ``s^2 R_ij``, so a gap's pair counts at
    its own time apart), at most their variance: a correlation that lasts only a few
    epochs then gives a small ``s_k^2``, not one the size of its first lag's; ``w_k^2`` is
    the rest of the variance. ``A_k^T R A_k`` in O(T) by the recursion the exponential
    allows (``_exponential_sum``)."""
    lags = int(min(math.ceil(2 * tau / float(np.median(np.diff(times)))), len(times) // 2))
    decays = [np.exp(-(times[lag:] - times[:-lag]) / tau) for lag in range(1, lags + 1)]
    fits = sum(float(d @ d) for d in decays)  # the same pairs for every equation
    meat = np.zeros((a.shape[2], a.shape[2]))
    for k in range(a.shape[1]):
        r = resid[:, k]
        variance = float(r @ r) / len(r)
        products = sum(float((r[lag:] * r[:-lag]) @ d) for lag, d in enumerate(decays, 1))
        slow = min(max(products / fits, 0.0), variance) if fits > 0 else 0.0
        design = np.ascontiguousarray(a[:, k, :])
        meat += (variance - slow) * (design.T @ design)
        if slow > 0:
            meat += slow * _exponential_sum(times, design, tau)
    return meat


@numba.njit(cache=True)
def _exponential_sum(times: np.ndarray, a: np.ndarray, tau: float) -> np.ndarray:
    """``A^T R A`` for ``R_ij = exp(-|t_i - t_j| / tau)``, ``A`` (T, n), ``times``
    increasing: ``S + S^T - A^T A`` with ``S = sum_i a_i f_i^T``, ``f_i = a_i + exp(-(t_i -
    t_(i-1)) / tau) f_(i-1)`` the decayed sum of the rows up to i."""
    n = a.shape[1]
    f = np.zeros(n)
    s = np.zeros((n, n))
    gram = np.zeros((n, n))
    for i in range(a.shape[0]):
        decay = 0.0 if i == 0 else math.exp(-(times[i] - times[i - 1]) / tau)
        for p in range(n):
            f[p] = a[i, p] + decay * f[p]
        for p in range(n):
            for q in range(n):
                s[p, q] += a[i, p] * f[q]
                gram[p, q] += a[i, p] * a[i, q]
    return s + s.T - gram


def dvl_model(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(P, 3, 7) design of ``v_dvl - u = k u + u x m + w x L`` for [k, m (3), L (3)]."""
    return np.concatenate([u[:, :, None], skew(u), skew(w)], axis=2)


def dvl_calibration(u: np.ndarray, w: np.ndarray, v: np.ndarray, t: np.ndarray,
                    slow_error_time: float = NAVIGATOR_SLOW_ERROR_TIME
                    ) -> tuple[np.ndarray, list[Finding]]:
    """Scale, mounting and lever arm of the DVL (module docstring) from pings' reference
    velocity in the body ``u`` (P, 3), body rate ``w`` (P, 3) and DVL velocity ``v`` (P, 3)
    at times ``t`` (P,) s, the residuals taken to hold a slow error of correlation time
    ``slow_error_time`` s (``serial_least_squares``). Returns [k, m, L] (7,) and the
    findings."""
    ok = np.isfinite(v).all(axis=1) & np.isfinite(u).all(axis=1) & np.isfinite(w).all(axis=1)
    x, se, rms, lags = serial_least_squares(dvl_model(u[ok], w[ok]), v[ok] - u[ok],
                                            times=t[ok], correlation_time=slow_error_time)
    k, m, lever = x[0], x[1:4], x[4:]
    turn = math.degrees(float(np.sqrt(np.mean(w[ok] ** 2))))
    rpy = np.degrees(m)
    lever_se = se[4:]
    found = [
        Finding("dvl scale", {"scale": 1 + k, "se": se[0]}, f"{1 + k:.5f}",
                f"LS on v_dvl - C^T v_ref over {int(ok.sum())} pings, residual RMS "
                f"{rms * 1e3:.1f} mm/s; SE {se[0]:.1e} (the larger of Newey-West's over "
                f"{lags} pings of the residuals' correlation and that of a slow error over "
                f"{slow_error_time:g} s)", grade(se[0], 1e-3, 5e-3)),
        Finding("dvl mounting", {"rpy_deg": rpy.tolist(), "se_deg": np.degrees(se[1:4]).tolist()},
                "[" + ", ".join(f"{a:+.3f}" for a in rpy) + "] deg",
                "small-angle mounting m (DVL frame -> body, M ~ I + [m]x) from the same fit; "
                "SE [" + ", ".join(f"{a:.3f}" for a in np.degrees(se[1:4])) + "] deg",
                grade(float(np.degrees(se[1:4]).max()), 0.05, 0.3)),
        Finding("dvl lever arm", {"position_body_m": lever.tolist(), "se_m": lever_se.tolist()},
                "[" + ", ".join(f"{a:+.3f}" for a in lever) + "] m",
                f"w x L in the same fit (body rate RMS {turn:.2g} deg/s); SE ["
                + ", ".join(f"{a:.3f}" for a in lever_se) + "] m",
                grade(float(lever_se.max()), 0.03, 0.1)),
    ]
    if abs(k) > SCALE_PLAUSIBLE:
        why = (f"the DVL's velocity is x{1 + k:.5f} the reference's, beyond any DVL's "
               f"calibration (within {100 * SCALE_PLAUSIBLE:g} %): the DVL's velocity or the "
               "reference is wrong, and nothing of this fit is applied; ")
        found = [dataclasses.replace(f, evidence=why + f.evidence, confidence="not observable")
                 for f in found]
    return x, found


def grade(se: float, high: float, medium: float) -> str:
    """Confidence of a standard error: high below ``high``, medium below ``medium``, else
    not observable."""
    return "high" if se < high else "medium" if se < medium else "not observable"


@numba.njit(cache=True)
def _propagate(q0: np.ndarray, start: np.ndarray, t: np.ndarray, w: np.ndarray,
               omega_ie: np.ndarray) -> np.ndarray:
    """(N, 4) body -> NED attitude quaternions [w, x, y, z] at each IMU sample (times
    ``t`` (N,), gyro rates ``w`` (N, 3) rad/s), propagated with the gyro from the
    reference's at the latest reference time before the sample (``start`` (K,) times,
    ``q0`` (K, 4) quaternions); NaN before the first. The samples are instants, as
    ``cumulative``'s trapezoids take them: each step turns by the mean of the rate
    interpolated between the samples over it (a rate held over the step would leave the
    attitude half a sample behind, a tilt of g dt/2 times the change of rate), less the
    Earth's rate ``omega_ie`` (3,) rad/s NED (zeros: none) at the step's first attitude:
    the body's rate relative to NED."""
    out = np.full((len(t), 4), np.nan)
    c = np.zeros((3, 3))
    earth = omega_ie[0] != 0.0 or omega_ie[1] != 0.0 or omega_ie[2] != 0.0
    k = -1
    q = np.zeros(4)
    last = 0.0
    for i in range(len(t)):
        while k + 1 < len(start) and start[k + 1] <= t[i]:
            k += 1
            q[:] = q0[k]
            last = start[k]
        if k < 0:
            continue
        h = t[i] - last  # the step since the last update
        # The rate at the step's middle, on the line between samples i - 1 and i.
        back = 0.0 if i == 0 or t[i] <= t[i - 1] else (h / 2) / (t[i] - t[i - 1])
        last = t[i]
        mx = w[i, 0] + back * (w[i - 1, 0] - w[i, 0]) if back > 0 else w[i, 0]
        my = w[i, 1] + back * (w[i - 1, 1] - w[i, 1]) if back > 0 else w[i, 1]
        mz = w[i, 2] + back * (w[i - 1, 2] - w[i, 2]) if back > 0 else w[i, 2]
        if earth:  # less C^T omega_ie
            rot_into(q, c)
            mx -= c[0, 0] * omega_ie[0] + c[1, 0] * omega_ie[1] + c[2, 0] * omega_ie[2]
            my -= c[0, 1] * omega_ie[0] + c[1, 1] * omega_ie[1] + c[2, 1] * omega_ie[2]
            mz -= c[0, 2] * omega_ie[0] + c[1, 2] * omega_ie[1] + c[2, 2] * omega_ie[2]
        rx, ry, rz = mx * h, my * h, mz * h
        angle = math.sqrt(rx * rx + ry * ry + rz * rz)
        if angle > 0:
            s = math.sin(angle / 2) / angle
            dw, dx, dy, dz = math.cos(angle / 2), rx * s, ry * s, rz * s
            a0, a1, a2, a3 = q[0], q[1], q[2], q[3]
            q[0] = a0 * dw - a1 * dx - a2 * dy - a3 * dz
            q[1] = a0 * dx + a1 * dw + a2 * dz - a3 * dy
            q[2] = a0 * dy - a1 * dz + a2 * dw + a3 * dx
            q[3] = a0 * dz + a1 * dy - a2 * dx + a3 * dw
        out[i] = q
    return out


def imu_lever_arm(log: Log, t: np.ndarray, f: np.ndarray, w: np.ndarray, *,
                  delta: float = CLOCK_PROBE) -> tuple[np.ndarray, Finding]:
    """The IMU's position from the reference point (module docstring), from IMU samples
    on the reference clock ``t`` (N,), body specific force ``f`` and rate ``w`` (N, 3).
    Its uncertainty adds, to the fit's standard errors, how far the solution moves when
    the IMU's clock moves by ``delta`` s either way: the angular acceleration's term makes
    it sensitive to timing, and a clock found from 1 Hz references is good to about
    that."""
    lever, se, rms, bias, n = _lever_fit(log, t, f, w)
    moved = [_lever_fit(log, t + d, f, w)[0] for d in (-delta, delta)]
    timing = np.abs(moved[1] - moved[0]) / 2
    total = np.sqrt(se ** 2 + timing ** 2)
    return lever, Finding(
        "imu lever arm", {"position_body_m": lever.tolist(), "se_m": total.tolist(),
                          "fit_se_m": se.tolist(), "clock_sensitivity_m": timing.tolist(),
                          "accel_bias": bias.tolist()},
        "[" + ", ".join(f"{a:+.3f}" for a in lever) + "] m",
        f"LS of the IMU's specific force (strapdown over each of {n} reference "
        f"intervals) against the reference's dv/dt - g: dw/dt x L + w x (w x L) + bias; "
        f"residual RMS {rms * 1e3:.1f} mm/s^2; SE [" + ", ".join(f"{a:.3f}" for a in total)
        + f"] m, of which the clock's +-{delta * 1e3:.0f} ms moves it ["
        + ", ".join(f"{a:.3f}" for a in timing) + "] m", grade(float(total.max()), 0.03, 0.1))


def _lever_fit(log: Log, t: np.ndarray, f: np.ndarray, w: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, int]:
    t_ref = np.asarray(log.reference_time, float)
    q = np.asarray(log.reference_quaternion, float)
    v = np.asarray(log.reference_velocity, float)
    sel = (t_ref[:-1] >= t[0]) & (t_ref[1:] <= t[-1])
    k = np.flatnonzero(sel)
    a, b = t_ref[k], t_ref[k + 1]
    # The gyros measure in inertial space; the attitude and the lever arm's terms turn
    # with the body's rate relative to NED, the gyros' less the Earth's.
    omega = np.zeros(3) if log.latitude_deg is None else earth_rate_ned(log.latitude_deg)
    c = rotation_matrices(_propagate(q, t_ref, t, w, omega))  # (N, 3, 3), NaN before
    w = w - np.einsum("nji,j->ni", np.nan_to_num(c), omega)
    dwdt = np.gradient(w, t, axis=0)
    # Each term rotated into NED with the propagated attitude: C f, and C A for the lever
    # arm's design A = [dw/dt]x + [w]x^2 and the bias's A = I.
    design = skew(dwdt) + skew(w) @ skew(w)
    c_design = c @ design
    ned = [np.einsum("nij,nj->ni", c, f)] + [c_design[:, :, j] for j in range(3)] \
        + [c[:, :, j] for j in range(3)]
    means = [window_means(t, cumulative(t, np.nan_to_num(x)), a, b) for x in ned]
    gravity = np.array([0.0, 0.0, log.gravity])
    accel = (v[k + 1] - v[k]) / (b - a)[:, None] - gravity
    if log.latitude_deg is not None:  # Coriolis of the Earth's rate on the velocity
        accel = accel + np.cross(2 * earth_rate_ned(log.latitude_deg), (v[k + 1] + v[k]) / 2)
    lhs = means[0] - accel  # (K, 3): what the lever arm and the bias must explain
    x, se, rms = least_squares(np.stack(means[1:], axis=2).reshape(-1, 6), lhs.ravel())
    return x[:3], se[:3], rms, x[3:], len(k)


def gravity_check(force: np.ndarray, ref: Intervals, expected: float, where: str
                  ) -> Finding:
    """The IMU's mean |f| over quiet intervals (``force`` (K, 3): its interval means)
    against the expected gravity."""
    quiet = ((np.linalg.norm(ref.rate, axis=1) < QUIET_RATE)
             & (np.linalg.norm(ref.dv / ref.dt[:, None], axis=1) < QUIET_ACCEL)
             & np.isfinite(force).all(axis=1))
    if quiet.sum() < 3:
        return Finding("gravity", {"expected": expected}, "-", "fewer than 3 quiet intervals",
                       "not observable")
    mag = np.linalg.norm(force[quiet], axis=1)
    mean, se = float(mag.mean()), float(mag.std(ddof=1) / math.sqrt(len(mag)))
    diff = mean - expected
    return Finding("gravity", {"mean_specific_force": mean, "se": se, "expected": expected,
                               "difference": diff, "quiet_intervals": int(quiet.sum())},
                   f"{mean:.4f} m/s^2",
                   f"mean |f| over {int(quiet.sum())} quiet 1-interval means (SE {se:.1e}); "
                   f"{where} {expected:.4f}: difference {diff:+.4f} m/s^2",
                   "high" if se < 1e-3 else "medium")


# ---- the whole check ---------------------------------------------------------------------


def check_arrays(log: Log, name: str = "log", *, gravity_source: str = "expected") -> Report:
    """Every finding of one log, in order: the reference's clock, the IMU's axes and clock,
    the DVL's clock and calibration (scale, mounting, lever arm; its clock fitted again
    with them), the IMU's lever arm and gravity. ``Report.corrections`` holds what
    ``apply`` changes (axis map, each stream's time map, positions, mounting)."""
    span = float(log.reference_time[-1] - log.reference_time[0])
    if len(log.reference_time) < MIN_REFERENCE or span < 2 * MAX_OFFSET + 10:
        raise DatasetError(f"{name}: the reference has {len(log.reference_time)} samples over "
                           f"{span:.3g} s; expected at least {MIN_REFERENCE} over "
                           f"{2 * MAX_OFFSET + 10:g} s to check a log against")
    if log.imu_time is None and log.dvl_time is None:
        raise DatasetError(f"{name}: neither an IMU nor a DVL; expected a stream to check")
    report = Report(name)
    ref = intervals(log)
    turn = float(np.sqrt(np.mean(np.sum(ref.rate ** 2, axis=1))))
    if turn < MIN_TURN:
        # Axes, clocks and lever arms are all read from how the streams see the vehicle
        # turn: a log that never turns leaves every one of them unobservable.
        raise DatasetError(f"{name}: the reference turns at {math.degrees(turn):.2g} deg/s "
                           f"RMS; expected turns (at least {math.degrees(MIN_TURN):g} deg/s "
                           "RMS) to tell the IMU's axes, the clocks and the lever arms from")
    report.findings.append(reference_clock(log))
    corrections: dict = {}
    p = np.eye(3)
    imu_t = w = w_int = f = imu_clock_found = None
    if log.imu_time is not None:
        p, found = imu_axes(log, ref)
        report.findings.append(found)
        clock = imu_clock(log, p, ref)
        s = np.asarray(log.imu_time, float)
        # Once more on the corrected stamps: a window's own drift (0.25 s per 100 s at
        # 2500 ppm) blurs its offset in the first pass. The two maps compose.
        again = imu_clock(dataclasses.replace(log, imu_time=s + clock.offset
                                              + clock.rate_error * s), p, ref)
        clock = dataclasses.replace(
            clock, offset=clock.offset * (1 + again.rate_error) + again.offset,
            rate_error=(1 + clock.rate_error) * (1 + again.rate_error) - 1,
            offset_se=max(clock.offset_se, again.offset_se),
            rate_se=max(clock.rate_se, again.rate_se))
        found = clock_finding("imu clock", clock, s, "gyro interval means against "
                              "the reference's attitude rate (twice: the second on the "
                              f"first's stamps moved it {again.offset:+.3f} s, "
                              f"{again.rate_error * 1e6:+.0f} ppm)")
        report.findings.append(found)
        imu_t = s + clock.offset + clock.rate_error * s
        imu_clock_found = clock
        w = np.asarray(log.angular_rate, float) @ p.T
        w_int = cumulative(imu_t, w)  # once: every trial DVL offset reads its rates here
        f = np.asarray(log.specific_force, float) @ p.T
        corrections.update(imu_axis_map=axis_map_names(p), imu_axis_matrix=p.tolist(),
                           imu_time_offset_s=clock.offset, imu_rate_error=clock.rate_error)
    dvl_pings = 0 if log.dvl_time is None else int(usable_pings(log).sum())
    if log.dvl_time is not None and dvl_pings < MIN_DVL_PINGS:
        # Too few pings to fit a clock or a calibration on: every trial offset would cost
        # the same, and a fit on no rows would look exact. Nothing is applied.
        report.findings.append(Finding(
            "dvl clock", {"pings": dvl_pings}, "not found",
            f"{dvl_pings} pings with a velocity inside the reference's span (less "
            f"{MAX_OFFSET:g} s each end); expected at least {MIN_DVL_PINGS}",
            "not observable"))
    elif log.dvl_time is not None:
        c = rotation_matrices(log.reference_quaternion)
        u_ref = np.einsum("kji,kj->ki", c, np.asarray(log.reference_velocity, float))
        def rates(t: np.ndarray) -> np.ndarray:
            return rates_at(t, imu_t, w_int, ref)

        p_dvl, found = dvl_axes(log, u_ref, rates)
        report.findings.append(found)
        if found.confidence == "low":  # the calibration below takes the axes as logged
            p_dvl = np.eye(3)
        v = np.asarray(log.dvl_velocity, float) @ p_dvl.T
        log = dataclasses.replace(log, dvl_velocity=v)
        clock, clock_found = dvl_clock(log, u_ref, rates)
        s = np.asarray(log.dvl_time, float)
        t = s + clock.offset + clock.rate_error * s
        u = np.stack([np.interp(t, log.reference_time, u_ref[:, d]) for d in range(3)], -1)
        inside = (t >= log.reference_time[0]) & (t <= log.reference_time[-1])
        u[~inside] = np.nan
        x, calibration = dvl_calibration(u, rates(t), v, t, log.dvl_slow_error_time)
        report.findings.append(clock_found)
        report.findings.extend(calibration)
        corrections.update(dvl_time_offset_s=clock.offset, dvl_rate_error=clock.rate_error,
                           dvl_scale=1 + x[0], dvl_mounting_rpy_deg=np.degrees(x[1:4]).tolist(),
                           dvl_position_body=x[4:].tolist())
    if log.depth_time is not None:
        clock, found = depth_clock(log)
        report.findings.append(found)
        if found.confidence in ("high", "medium"):  # else reported, and left as it was
            corrections.update(depth_time_offset_s=clock.offset,
                               depth_rate_error=clock.rate_error)
    if imu_t is not None:
        lever, found = imu_lever_arm(log, imu_t, f, w)
        report.findings.append(found)
        if found.confidence != "not observable":
            corrections["imu_position_body"] = lever.tolist()
        means = window_means(imu_t, cumulative(imu_t, f), ref.start, ref.end)
        inside = (ref.start >= imu_t[0]) & (ref.end <= imu_t[-1])
        means[~inside] = np.nan
        report.findings.append(gravity_check(means, ref, log.gravity, gravity_source))
    base = time_base(log, imu_clock_found, report.findings[0])
    report.findings.append(base)
    corrections["time_base"] = base.value["clock"]
    report.corrections = corrections
    return report


def to_json(reports: list[Report]) -> str:
    return json.dumps([r.to_json() for r in reports], indent=1)


# ---- missions and files ------------------------------------------------------------------


def log_of(mission) -> Log:
    """A recorded mission (``auvsim.data.reader.Mission``) as a ``Log``.

    Raises:
        DatasetError: the mission is not a recorded one with a reference and its attitude,
            or has neither an IMU nor a DVL to check.
    """
    if mission.origin != "recorded":
        raise DatasetError(f"mission {mission.name!r} is {mission.origin}; expected a recorded "
                           "mission with a reference to check the log against")
    if not mission.has("reference"):
        raise DatasetError(f"mission {mission.name!r} has no reference; expected a recorded "
                           "mission with a reference to check the log against")
    quaternion = require_attitude(mission)
    if not (mission.has("imu") or mission.has("dvl")):
        raise DatasetError(f"mission {mission.name!r} has neither an IMU nor a DVL; "
                           "expected a stream to check")
    ref = mission.reference
    latitude = mission.attrs.get("latitude_deg")
    imu = mission.imu if mission.has("imu") else None
    dvl = mission.dvl if mission.has("dvl") else None
    depth = mission.depth if mission.has("depth") else None
    return Log(ref.time, ref.velocity_ned, quaternion, ref.position_ned,
               None if imu is None else imu.time,
               None if imu is None else imu.specific_force,
               None if imu is None else imu.angular_rate,
               None if dvl is None else dvl.time,
               None if dvl is None else dvl.velocity_ls,
               None if depth is None else depth.time,
               None if depth is None else depth.depth,
               gravity=float(mission.attrs["gravity"]),
               latitude_deg=None if latitude is None else float(latitude),
               stated_rates=stated_rates(mission.attrs.get("log_description", "")),
               dvl_slow_error_time=slow_error(mission.attrs)[1])


def slow_error(attrs) -> tuple[float, float]:
    """A mission's DVL slow error (std per axis, m/s; correlation time, s): the one its
    attributes state (``dvl_slow_error_std`` above 0, ``dvl_slow_error_time``), else the
    Navigator's, the only DVL whose slow error auvsim has measured
    (``NAVIGATOR_SLOW_ERROR_STD``, ``_TIME``). check-log's standard errors and the INS/DVL
    filter read it."""
    if float(attrs.get("dvl_slow_error_std", 0.0)) > 0 and "dvl_slow_error_time" in attrs:
        return float(attrs["dvl_slow_error_std"]), float(attrs["dvl_slow_error_time"])
    return NAVIGATOR_SLOW_ERROR_STD, NAVIGATOR_SLOW_ERROR_TIME


def stated_rates(description: str) -> dict[str, float]:
    """The stated rate of each stream, Hz, from a log description's ``rate_hz`` keys
    (``[imu] rate_hz = 100``): {stream: rate}; none where the text states none or is not
    TOML (the import has checked it)."""
    try:
        data = tomllib.loads(description or "")
    except tomllib.TOMLDecodeError:
        return {}
    return {g: float(t["rate_hz"]) for g, t in data.items()
            if isinstance(t, dict) and isinstance(t.get("rate_hz"), (int, float))
            and t["rate_hz"] > 0}


def check_log(mission) -> Report:
    """Every finding of one recorded mission (``check_arrays`` on ``log_of(mission)``)."""
    return check_arrays(log_of(mission), mission.name,
                        gravity_source="WGS-84 normal gravity at the origin")


def check_file(path: str | os.PathLike, missions: list[str] | None = None, *,
               each=None) -> list[Report]:
    """``check_log`` of each named mission of the dataset ``path`` (default: all, in
    file order): the reports ``apply`` writes a corrected dataset from. ``each(report)``,
    if given, is called as each mission's report is done (a command line's table).

    Raises:
        ConfigError: a name in ``missions`` is not a mission of the dataset.
        DatasetError: ``path`` is no dataset, or a mission cannot be checked
            (``log_of``, ``check_arrays``).
    """
    with open_dataset(path) as ds:
        names = list(ds.missions) if missions is None else list(missions)
        unknown = [n for n in names if n not in ds.missions]
        if unknown:
            raise ConfigError(f": {unknown[0]!r} is not in {str(path)!r}; expected one of "
                              f"{', '.join(ds.missions)}", argument="missions")
        reports = []
        for n in names:
            reports.append(check_log(ds.missions[n]))
            if each is not None:
                each(reports[-1])
        return reports


def fields_of(mission) -> dict[str, np.ndarray]:
    """Every field of a mission, by path (``"imu/time"``, ...)."""
    return {f"{g}/{name}": getattr(getattr(mission, g), name)
            for g in mission.groups for name in getattr(mission, g)}


def corrected(mission, report: Report) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    """The mission's fields and attributes with ``report``'s corrections made:

    * the IMU's triads through the axis map (``body = P logged``);
    * every stream's stamps on the time base the report chose (its "time base"
      finding): the reference's clock, ``s + offset + rate_error * s`` (the reference's
      own stamps unchanged), or the IMU's, that mapped by ``(t - imu offset) / (1 + imu
      rate error)`` (the IMU's own stamps unchanged); all shifted by one constant so the
      earliest is 0 (``log_time_origin_s`` moves with it);
    * each stream's ``*_time_offset_s`` grows by the offset its map adds, the
      rates are 1 / median interval again; the sensors' positions and the DVL's mounting
      are the found ones where observable (``imu_position_body``, ``dvl_position_body``,
      ``dvl_mounting_rpy_deg``);
    * ``check_log_json``: the report (findings and corrections), JSON.

    The DVL's velocity is left as the instrument gave it (its scale is in the report); a
    depth stream's clock is moved where check-log found it with high or medium
    confidence, else shifted with the others.
    """
    c = report.corrections
    found = {f.name: f for f in report.findings}
    groups = mission.groups
    fields = fields_of(mission)
    attrs = dict(mission.attrs)
    maps = {g: (c.get(f"{g}_time_offset_s", 0.0), c.get(f"{g}_rate_error", 0.0))
            for g in ("imu", "dvl", "depth")}
    # The reference's clock t = s + offset + rate * s, then onto the IMU's own when it is
    # the time base: tau = (t - imu offset) / (1 + imu rate error).
    base_offset, base_rate = maps["imu"] if c.get("time_base") == "imu" else (0.0, 0.0)
    shift = {}
    for g in groups:
        offset, rate = maps.get(g, (0.0, 0.0))
        s = fields[f"{g}/time"]
        fields[f"{g}/time"] = (s + offset + rate * s - base_offset) / (1 + base_rate)
        shift[g] = (offset - base_offset) / (1 + base_rate)
    start = min(float(fields[f"{g}/time"][0]) for g in groups)
    for g in groups:
        fields[f"{g}/time"] = fields[f"{g}/time"] - start
        attrs[f"{g}_rate_hz"] = 1.0 / float(np.median(np.diff(fields[f"{g}/time"])))
    attrs["log_time_origin_s"] = float(attrs.get("log_time_origin_s", 0.0)) + start
    attrs["duration_s"] = max(float(fields[f"{g}/time"][-1]) for g in groups)
    if "imu_axis_matrix" in c:
        p = np.asarray(c["imu_axis_matrix"])
        for name in ("specific_force", "angular_rate"):
            fields[f"imu/{name}"] = fields[f"imu/{name}"] @ p.T
        attrs["imu_time_offset_s"] = float(attrs["imu_time_offset_s"]) + shift["imu"]
        if "imu_position_body" in c:
            attrs["imu_position_body"] = np.asarray(c["imu_position_body"])
    if "dvl_time_offset_s" in c:
        attrs["dvl_time_offset_s"] = float(attrs["dvl_time_offset_s"]) + shift["dvl"]
        if found["dvl lever arm"].confidence != "not observable":
            attrs["dvl_position_body"] = np.asarray(c["dvl_position_body"])
        if found["dvl mounting"].confidence != "not observable":
            attrs["dvl_mounting_rpy_deg"] = np.asarray(c["dvl_mounting_rpy_deg"])
    for g in ("reference", "depth"):
        if f"{g}_time_offset_s" in attrs and g in shift:
            attrs[f"{g}_time_offset_s"] = float(attrs[f"{g}_time_offset_s"]) + shift[g]
    attrs["check_log_json"] = json.dumps(report.to_json())
    return fields, attrs


def _applied_findings(attrs) -> dict:
    """A corrected mission's check-log findings by name, from its ``check_log_json`` ({}:
    no report)."""
    if "check_log_json" not in attrs:
        return {}
    return {f["name"]: f for f in json.loads(attrs["check_log_json"])["findings"]}


def applied_dvl_errors(attrs) -> tuple[np.ndarray | None, np.ndarray | None]:
    """How well a corrected mission's DVL mounting and lever arm are known: the standard
    errors (deg, m; (3,) each) of the values ``corrected`` wrote into ``attrs``
    (``dvl_mounting_rpy_deg``, ``dvl_position_body``), read from its ``check_log_json``;
    None for each one it did not write (not observable, or no report)."""
    found = _applied_findings(attrs)

    def se(name: str, key: str) -> np.ndarray | None:
        f = found.get(name)
        if f is None or f["confidence"] == "not observable" or key not in f["value"]:
            return None
        return np.asarray(f["value"][key], dtype=float)

    return se("dvl mounting", "se_deg"), se("dvl lever arm", "se_m")


def applied_clock_errors(attrs) -> tuple[float | None, float | None]:
    """How well a corrected mission's clocks are put on the reference's (s), the IMU's
    and the DVL's, read from its ``check_log_json`` (each against the reference's clock):
    the standard error of the offset its windows' line gives; where no rate was kept,
    the offset ``corrected`` applied is the whole log's, found by a scan of its own, and
    the error is widened by how far that lies from the windows' mean. None for each one
    it did not find (too few windows, or no report)."""
    found = _applied_findings(attrs)

    def error(name: str) -> float | None:
        value = found.get(name, {}).get("value")
        if not isinstance(value, dict) or value.get("offset_se_s") is None:
            return None
        se = float(value["offset_se_s"])
        if not math.isfinite(se):
            return None
        windows = np.asarray(value.get("windows") or np.zeros((0, 2)), dtype=float)
        if not len(windows) or value.get("rate_error", 0.0) != 0.0:
            return se
        return math.hypot(se, float(np.mean(windows[:, 1])) - float(value["offset_s"]))

    return error("imu clock"), error("dvl clock")


# The findings ``corrected`` writes into the corrected file; the others (the reference's
# clock, the DVL's scale, gravity) are evidence only.
APPLIED = ("imu axes", "imu clock", "dvl clock", "dvl mounting", "dvl lever arm",
           "imu lever arm", "time base")


def low_confidence(reports: list[Report]) -> list[str]:
    """``"mission: finding"`` for every finding of ``reports`` that ``apply`` would write
    and whose confidence is low. A time base that keeps the reference's clock is not one:
    every clock is measured against the reference's, so keeping it moves no stamp."""
    return [f"{r.mission}: {f.name}" for r in reports for f in r.findings
            if f.name in APPLIED and f.confidence == "low"
            and not (f.name == "time base" and f.value["clock"] == "reference")]


def changes(before, after: dict, report: Report) -> list[str]:
    """What ``corrected`` changed of a mission, in words, from its attributes ``before``
    and ``after`` (and the IMU's axis map, which moves samples, not attributes)."""
    said = []
    c = report.corrections
    axes = c.get("imu_axis_map")
    if axes is not None and list(axes) != ["x", "y", "z"]:
        said.append(f"IMU axes [{', '.join(axes)}]")
    base = "IMU" if c.get("time_base") == "imu" else "reference"
    clocks = []
    for g, name in (("imu", "IMU"), ("dvl", "DVL"), ("depth", "depth"),
                    ("reference", "reference")):
        key = f"{g}_time_offset_s"
        rate = c.get(f"{g}_rate_error", 0.0) if name != base else 0.0
        # A stream is moved by its offset, by its rate, or both (a clock found stretched
        # but not shifted moves every stamp but the first).
        if key in before and (float(after[key]) != float(before[key]) or rate):
            clocks.append(f"{name} {float(after[key]) - float(before[key]):+.3f} s"
                          + (f" and {1e6 * rate:+.0f} ppm" if rate else ""))
    base_rate = c.get("imu_rate_error", 0.0) if base == "IMU" else 0.0
    if clocks or base_rate:  # an IMU time base at its own rate rescales the others
        said.append(f"onto the {base}'s clock"
                    + (f" (it runs {1e6 * base_rate:+.0f} ppm against the reference's)"
                       if base_rate else "") + (": " + ", ".join(clocks) if clocks else ""))
    for key, words, unit in (("imu_position_body", "IMU at", "m"),
                             ("dvl_position_body", "DVL at", "m"),
                             ("dvl_mounting_rpy_deg", "DVL mounted", "deg")):
        if key in after and (key not in before or not np.array_equal(after[key], before[key])):
            said.append(f"{words} [{', '.join(f'{v:+.3f}' for v in after[key])}] {unit}")
    return said


def apply(path: str | os.PathLike, out: str | os.PathLike, reports: list[Report], *,
          compression: str = "lzf", accept_low: bool = False) -> dict[str, list[str]]:
    """Write ``out``: the dataset ``path`` with each reported mission corrected
    (``corrected``) and every other mission as it was. Built under a temporary name and
    renamed when complete (``DatasetWriter``).

    Returns:
        What was corrected, in words, per corrected mission (``changes``).

    Raises:
        ConfigError: a finding it would write is of low confidence (``low_confidence``),
            unless ``accept_low``; nothing is written.
    """
    turned = [f"{r.mission}: {f.text}" for r in reports for f in r.findings
              if f.name == "dvl axes" and not f.value["as_logged"] and f.confidence != "low"]
    if turned:
        raise ConfigError(
            f"--apply: the DVL's axes are not as logged ({'; '.join(turned)}); expected "
            "them fixed where they were declared: state the map in the log description "
            "(dvl.axis_map, or dvl.frame) and import again")
    low = low_confidence(reports)
    if low and not accept_low:
        raise ConfigError(
            f"--apply: {len(low)} correction(s) rest on a finding of low confidence "
            f"({'; '.join(low)}); expected medium or high (the table says what each rests "
            "on: state it in the log description, or give --accept-low to write it anyway)")
    by_name = {r.mission: r for r in reports}
    said = {}
    with open_dataset(path) as ds:
        config = json.dumps({"check_log": {"source": str(path),
                                           "missions": sorted(by_name)},
                             "source_config": ds.config_json})
        with DatasetWriter(out, config_json=config, compression=compression,
                           argument="apply") as writer:
            for name, mission in ds.missions.items():
                if name in by_name:
                    fields, attrs = corrected(mission, by_name[name])
                    said[name] = changes(mission.attrs, attrs, by_name[name])
                else:
                    fields, attrs = fields_of(mission), dict(mission.attrs)
                groups = sorted({p.split("/")[0] for p in fields})
                sink = writer.mission(name, mission_attrs(**attrs),
                                      rows={g: len(fields[f"{g}/time"]) for g in groups
                                            if f"{g}/time" in fields})
                sink.append(fields)
                sink.flush()
    return said
