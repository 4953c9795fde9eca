"""Reading the shared A-KIT segments (``../shared/data/snapir-akit``) as arrays, and
finding from the data what their publication does not document (the IMU's axes, the
streams' clocks, the DVL's position): for the filter's tests on real logs until
``auvsim import --format akit`` and ``auvsim check-log`` read them (issue 24).

Every finding is a least-squares fit against the reference, general to any log with a
reference attitude; nothing here is a number read off these files.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from auvsim.physics.earth import ned_from_geodetic
from auvsim.physics.frames import rotation_rpy

AKIT = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "snapir-akit"
for _candidate in (AKIT, Path("/work/shared/data/snapir-akit")):
    if _candidate.is_dir():
        AKIT = _candidate
        break
SEGMENTS = tuple(range(1, 7))


def read_segment(k: int, root: Path = AKIT) -> dict:
    """Segment ``k``'s three CSV files as arrays, the reference as local NED from its
    first point (``auvsim.physics.earth.ned_from_geodetic``) and as rotation matrices."""
    def load(kind: str) -> np.ndarray:
        return np.loadtxt(root / f"Trajectory{k}" / f"{kind}_trajectory{k}.csv",
                          delimiter=",", skiprows=1)

    imu, dvl, gt = load("IMU"), load("DVL"), load("GT")
    lat, lon, height = np.degrees(gt[:, 2]), np.degrees(gt[:, 1]), gt[:, 3]
    origin = (float(lat[0]), float(lon[0]), float(height[0]))
    return dict(imu_time=imu[:, 0], specific_force=imu[:, 1:4], angular_rate=imu[:, 4:7],
                dvl_time=dvl[:, 0], velocity=dvl[:, 1:4], ref_time=gt[:, 0],
                ref_position=ned_from_geodetic(lat, lon, height, origin),
                ref_velocity=gt[:, 4:7], ref_rpy=gt[:, 7:10],
                ref_rotation=np.stack([rotation_rpy(*r) for r in gt[:, 7:10]]),
                latitude_deg=origin[0], longitude_deg=origin[1], height_m=origin[2])


def proper_axis_maps() -> list[np.ndarray]:
    """The 24 signed permutation matrices with determinant +1 (every right-handed
    relabelling of three axes)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            a = np.zeros((3, 3))
            a[range(3), perm] = signs
            if np.linalg.det(a) > 0:
                out.append(a)
    return out


def find_axes(imu_time, angular_rate, specific_force, ref_time, ref_rotation,
              ref_velocity, *, gravity: float) -> tuple[np.ndarray, dict]:
    """The axis map A (body = A imu) among the 24 right-handed ones that best explains
    the reference: the IMU's samples averaged over each reference interval against the
    reference's own specific force C^T (dv/dt - g) (the turns' centripetal and the speed
    changes' accelerations tell the level axes apart, gravity the vertical) and angular
    rate (from its attitude's change). Returns A and every map's RMS residual,
    normalised by the reference's own RMS of each."""
    rows = np.searchsorted(imu_time, ref_time)
    ok = (rows > 0) & (rows < len(imu_time))
    edges = rows[ok]
    csum_f = np.concatenate([np.zeros((1, 3)), np.cumsum(specific_force, axis=0)])
    csum_w = np.concatenate([np.zeros((1, 3)), np.cumsum(angular_rate, axis=0)])
    n = np.diff(edges)[:, None]
    f_mean = (csum_f[edges[1:]] - csum_f[edges[:-1]]) / n
    w_mean = (csum_w[edges[1:]] - csum_w[edges[:-1]]) / n
    t, c, v = ref_time[ok], ref_rotation[ok], ref_velocity[ok]
    dt = np.diff(t)[:, None]
    accel = np.diff(v, axis=0) / dt - np.array([0.0, 0.0, gravity])
    c_mid = c[:-1]  # attitude at the interval's start: its change is a few degrees
    f_ref = np.einsum("nji,nj->ni", c_mid, accel)
    rel = np.einsum("nji,njk->nik", c[:-1], c[1:])  # C_k^T C_k+1
    w_ref = np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0],
                      rel[:, 1, 0] - rel[:, 0, 1]], axis=1) / (2 * dt)
    scores = {}
    for a in proper_axis_maps():
        ef = np.sqrt(np.mean((f_mean @ a.T - f_ref) ** 2)) / np.sqrt(np.mean(f_ref**2))
        ew = np.sqrt(np.mean((w_mean @ a.T - w_ref) ** 2)) / np.sqrt(np.mean(w_ref**2))
        scores[tuple(a.ravel())] = float(ef + ew)
    best = min(scores, key=scores.get)
    return np.array(best).reshape(3, 3), scores


def find_clock(imu_time, yaw_rate_body, ref_time, ref_yaw, *, window: float = 100.0,
               search: float = 3.0) -> tuple[float, float]:
    """The reference clock against the IMU's: t_imu = offset + rate * t_ref, by matching
    the integrated gyro yaw (a heading's increments do not depend on where it starts)
    to the reference yaw over windows, then a straight line through the windows' offsets.
    Returns (offset s, rate)."""
    psi = np.concatenate([[0.0], np.cumsum(0.5 * (yaw_rate_body[1:] + yaw_rate_body[:-1])
                                           * np.diff(imu_time))])
    yaw = np.unwrap(ref_yaw)
    centres, offsets = [], []
    lags = np.arange(-search, search, 0.005)
    for t0 in np.arange(ref_time[0], ref_time[-1] - window + 1e-9, window / 2):
        rows = (ref_time >= t0) & (ref_time <= t0 + window)
        ts, ys = ref_time[rows], yaw[rows] - yaw[rows].mean()
        cost = [np.sum((ys - (p := np.interp(ts + lag, imu_time, psi)) + p.mean()) ** 2)
                for lag in lags]
        centres.append(ts.mean())
        offsets.append(lags[int(np.argmin(cost))])
    slope, intercept = np.polyfit(centres, offsets, 1)
    return float(intercept), float(1.0 + slope)


def find_dvl(imu_time, angular_rate, ref_time_imu, ref_rotation, ref_velocity, dvl_time,
             velocity, *, clock_rate: float, clock_offset: float,
             search: float = 3.0) -> tuple[float, np.ndarray, float]:
    """The DVL's clock and its position relative to the reference point: for each trial
    lag, the DVL's sample j is taken at IMU time offset + rate (t_j + lag) and
    v_dvl - C_ref^T v_ref = w x L + b is solved for the lever arm L and a constant b by
    least squares (the turns' rates make L observable); the lag of least residual wins.
    Returns (lag s in the DVL's stamps, L (3,) m body FRD, residual RMS m/s)."""
    body = np.einsum("nji,nj->ni", ref_rotation, ref_velocity)
    csum = np.concatenate([np.zeros((1, 3)), np.cumsum(angular_rate, axis=0)])
    best = None
    for lag in np.arange(-search, search + 1e-9, 0.05):
        t = clock_offset + clock_rate * (dvl_time + lag)
        ok = (t > max(ref_time_imu[0], imu_time[0]) + 0.5) & (
            t < min(ref_time_imu[-1], imu_time[-1]) - 0.5)
        vb = np.stack([np.interp(t[ok], ref_time_imu, body[:, j]) for j in range(3)], 1)
        i0, i1 = np.searchsorted(imu_time, [t[ok] - 0.5, t[ok] + 0.5])
        w = (csum[i1] - csum[i0]) / (i1 - i0)[:, None]  # the ping's second, averaged
        d = velocity[ok] - vb
        # w x L = -[L x] w ... as rows: (w x L)_i = sum_j (skew(w))_ij L_j
        skew = np.zeros((len(w), 3, 3))
        skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
        skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
        a = np.concatenate([skew, np.broadcast_to(np.eye(3), skew.shape)], axis=2)
        x, *_ = np.linalg.lstsq(a.reshape(-1, 6), d.ravel(), rcond=None)
        rms = float(np.sqrt(np.mean((a.reshape(-1, 6) @ x - d.ravel()) ** 2)))
        if best is None or rms < best[2]:
            best = (float(lag), x[:3], rms)
    return best
