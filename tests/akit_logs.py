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


def axis_maps() -> list[np.ndarray]:
    """The 48 signed permutation matrices: every relabelling of three axes, the mirrored
    (determinant -1) ones included, since a log's own transformation may have mirrored
    one axis."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            a = np.zeros((3, 3))
            a[range(3), perm] = signs
            out.append(a)
    return out


def find_axes(imu_time, angular_rate, specific_force, ref_time, ref_rotation,
              ref_velocity, *, gravity: float) -> tuple[np.ndarray, dict]:
    """The axis map A (body = A imu) among the 48 signed permutations that best explains
    the reference: the IMU's samples averaged over each reference interval against the
    reference's own specific force C^T (dv/dt - g) (gravity through the roll and pitch,
    the turns' and the speed changes' accelerations) and angular rate (from its
    attitude's change). The score sums, over the six axes, the RMS residual over the
    reference's own RMS variation on that axis. Returns A and every map's score."""
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
    scale_f = np.sqrt(np.mean((f_ref - f_ref.mean(axis=0)) ** 2, axis=0))
    scale_w = np.sqrt(np.mean(w_ref**2, axis=0))
    scores = {}
    for a in axis_maps():
        ef = np.sqrt(np.mean((f_mean @ a.T - f_ref) ** 2, axis=0)) / scale_f
        ew = np.sqrt(np.mean((w_mean @ a.T - w_ref) ** 2, axis=0)) / scale_w
        scores[tuple(a.ravel())] = float(ef.sum() + ew.sum())
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


def _skew(w: np.ndarray) -> np.ndarray:
    """(N, 3, 3) cross-product matrices [w x] of (N, 3) vectors."""
    out = np.zeros((len(w), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    return out


def find_imu(imu_time, specific_force, angular_rate, ref_time_imu, ref_rotation,
             ref_velocity, *, gravity: float) -> tuple[np.ndarray, float]:
    """The IMU's position relative to the reference point, m FRD: the IMU's specific
    force (averaged over each reference interval) minus the reference point's own,
    C^T (dv/dt - g), is alpha x r + w x (w x r) (+ a constant: the accelerometer biases),
    solved for r by least squares (the roll oscillations and turns make it observable).
    Returns (r, residual RMS m/s^2)."""
    rows = np.searchsorted(imu_time, ref_time_imu)
    ok = (rows > 0) & (rows < len(imu_time))
    edges = rows[ok]
    csum = np.concatenate([np.zeros((1, 6)),
                           np.cumsum(np.hstack([specific_force, angular_rate]), axis=0)])
    mean = (csum[edges[1:]] - csum[edges[:-1]]) / np.diff(edges)[:, None]
    t, c, v = ref_time_imu[ok], ref_rotation[ok], ref_velocity[ok]
    dt = np.diff(t)[:, None]
    accel = np.diff(v, axis=0) / dt - np.array([0.0, 0.0, gravity])
    f_ref = 0.5 * (np.einsum("nji,nj->ni", c[:-1], accel) + np.einsum("nji,nj->ni", c[1:],
                                                                        accel))
    w = mean[:, 3:]
    alpha = np.gradient(w, axis=0) / dt
    a = _skew(alpha) + np.einsum("nij,njk->nik", _skew(w), _skew(w))
    a = np.concatenate([a, np.broadcast_to(np.eye(3), a.shape)], axis=2).reshape(-1, 6)
    d = (mean[:, :3] - f_ref).ravel()
    x, *_ = np.linalg.lstsq(a, d, rcond=None)
    return x[:3], float(np.sqrt(np.mean((a @ x - d) ** 2)))


def corrected(k: int, root: Path = AKIT) -> dict:
    """Segment ``k`` with what ``auvsim check-log --apply`` is to correct, found here from
    the data: the IMU's axes (``find_axes``: its y axis is mirrored, diag(1, -1, 1), on
    all six), the reference's and the DVL's stamps on the IMU's clock (``find_clock``,
    ``find_dvl``) and the IMU's and the DVL's positions from the reference point
    (``find_imu``, ``find_dvl``). The clock is found on the raw gyro z, which the map
    leaves as it is."""
    from auvsim.physics.earth import normal_gravity

    s = read_segment(k, root)
    offset, rate = find_clock(s["imu_time"], s["angular_rate"][:, 2], s["ref_time"],
                              s["ref_rpy"][:, 2])
    ref_time = offset + rate * s["ref_time"]
    gravity = normal_gravity(s["latitude_deg"], s["height_m"])
    axes, scores = find_axes(s["imu_time"], s["angular_rate"], s["specific_force"], ref_time,
                             s["ref_rotation"], s["ref_velocity"], gravity=gravity)
    s["specific_force"] = s["specific_force"] @ axes.T
    s["angular_rate"] = s["angular_rate"] @ axes.T
    ranked = sorted(scores.values())
    lag, lever, rms = find_dvl(s["imu_time"], s["angular_rate"], ref_time, s["ref_rotation"],
                               s["ref_velocity"], s["dvl_time"], s["velocity"],
                               clock_rate=rate, clock_offset=offset)
    r_imu, imu_rms = find_imu(s["imu_time"], s["specific_force"], s["angular_rate"],
                              ref_time, s["ref_rotation"], s["ref_velocity"], gravity=gravity)
    s.update(ref_time=ref_time, dvl_time=offset + rate * (s["dvl_time"] + lag),
             dvl_position_body=lever, imu_position_body=r_imu, imu_rms=imu_rms,
             clock=(offset, rate), dvl_lag=lag, dvl_rms=rms, gravity=gravity, axes=axes,
             axes_margin=ranked[1] / ranked[0])
    return s


def phins_instrument(s: dict):
    """The filter's instrument for these logs, from specifications: the Phins-class IMU
    grade (``auvsim.sensors.imu.IMU_GRADES["navigation"]``) with the log's rounding
    (``quantisation_density``) added; the DVL as ``auvsim import --format akit`` describes
    it (``auvsim.data.recorded.AKIT_DESCRIPTION``: white beam noise 2.6 mm/s from a real
    Navigator's error velocity, the publication's 0.02 m/s velocity accuracy), split as
    ``run_mission`` splits a recorded log's: the white noise through the Janus geometry,
    the rest of the accuracy a Gauss-Markov error over the ``navigator`` preset's
    measured correlation time."""
    import math

    import tomllib

    from auvsim.data.recorded import AKIT_DESCRIPTION
    from auvsim.runs.presets import navigator
    from auvsim.sensors.imu import IMU_GRADES
    from beamsnet.estimators import ins

    dvl = tomllib.loads(AKIT_DESCRIPTION.replace("{k}", "1"))["dvl"]
    white = ins.janus_velocity_std(dvl["noise_std"], dvl["beam_angle_deg"])
    grade = IMU_GRADES["navigation"]
    rate = 1.0 / float(np.median(np.diff(s["imu_time"])))
    return ins.Instrument(
        accel_noise_density=math.hypot(grade.accel_noise_density,
                                       ins.quantisation_density(s["specific_force"], rate)),
        gyro_noise_density=math.hypot(grade.gyro_noise_density,
                                      ins.quantisation_density(s["angular_rate"], rate)),
        accel_bias_std=math.hypot(grade.accel_turn_on_bias, grade.accel_bias_instability),
        gyro_bias_std=math.hypot(grade.gyro_turn_on_bias, grade.gyro_bias_instability),
        accel_bias_psd=2 * grade.accel_bias_instability**2 / grade.bias_correlation_time,
        gyro_bias_psd=2 * grade.gyro_bias_instability**2 / grade.bias_correlation_time,
        measurement_std=white,
        slow_error_std=math.sqrt(dvl["velocity_accuracy"] ** 2 - white[0] ** 2),
        slow_error_time=navigator().dvl.slow_error_time)


def run_segment(s: dict, config=None) -> dict:
    """The filter on a corrected segment (``corrected``) from its reference's first sample,
    scored against the reference at the reference's times: horizontal error (final, RMS),
    the share of time within the reported 3 sigma (radius 3 sqrt(var N + var E)), and DVL
    dead reckoning with the reference's attitude (R_ref (v_dvl - w x L) integrated at the
    DVL's rate from the same start) beside it."""
    from beamsnet.estimators import ins

    config = ins.FilterConfig() if config is None else config
    t_ref = s["ref_time"]
    k0 = int(np.searchsorted(t_ref, s["imu_time"][0]))
    i0 = int(np.searchsorted(s["imu_time"], t_ref[k0]))
    accel = (s["ref_velocity"][k0 + 1] - s["ref_velocity"][k0]) / (t_ref[k0 + 1] - t_ref[k0])
    start = ins.start_from_reference(s["imu_time"][i0], s["ref_position"][k0],
                                     s["ref_velocity"][k0], s["ref_rotation"][k0],
                                     angular_rate=s["angular_rate"][i0], acceleration=accel,
                                     config=config)
    track = ins.run_arrays(s["imu_time"], s["specific_force"], s["angular_rate"],
                           s["dvl_time"], velocity=s["velocity"],
                           dvl_position_body=s["dvl_position_body"],
                           imu_position_body=s["imu_position_body"], start=start,
                           instrument=phins_instrument(s), latitude_deg=s["latitude_deg"],
                           height_m=s["height_m"], config=config)
    ok = np.isfinite(track.position_ned[:, 0])
    rows = (t_ref >= track.ping_time[ok][0]) & (t_ref <= track.ping_time[ok][-1])
    est = np.stack([np.interp(t_ref[rows], track.ping_time[ok], track.position_ned[ok, j])
                    for j in range(2)], axis=1)
    sigma = np.interp(t_ref[rows], track.ping_time[ok], track.horizontal_std[ok])
    error = np.linalg.norm(est - s["ref_position"][rows, :2], axis=1)
    dr = dead_reckoning(s, k0)
    dr_error = np.linalg.norm(np.stack([np.interp(t_ref[rows], s["dvl_time"], dr[:, j])
                                        for j in range(2)], 1)
                              - s["ref_position"][rows, :2], axis=1)
    return dict(final=float(error[-1]), rmse=float(np.sqrt(np.mean(error**2))),
                coverage=float(np.mean(error <= 3 * sigma)), dr_final=float(dr_error[-1]),
                dr_rmse=float(np.sqrt(np.mean(dr_error**2))), sigma_final=float(sigma[-1]),
                availability=track.availability, events=len(track.events), track=track)


def dead_reckoning(s: dict, k0: int) -> np.ndarray:
    """(P, 3) DVL dead reckoning with the reference's attitude: the reference point's
    velocity R_ref (v_dvl - w x L) (the attitude and rate interpolated at each ping)
    integrated from the reference's position at sample ``k0`` (rectangles, each ping's
    velocity held to the next)."""
    from auvsim.physics.frames import rotation_rpy as rpy

    t, tp = s["ref_time"], s["dvl_time"]
    rpy_ref = s["ref_rpy"].copy()
    rpy_ref[:, 2] = np.unwrap(rpy_ref[:, 2])
    angles = np.stack([np.interp(tp, t, rpy_ref[:, j]) for j in range(3)], axis=1)
    csum = np.concatenate([np.zeros((1, 3)), np.cumsum(s["angular_rate"], axis=0)])
    i0, i1 = np.searchsorted(s["imu_time"], [tp - 0.5, tp + 0.5])
    w = (csum[i1] - csum[i0]) / np.maximum(i1 - i0, 1)[:, None]
    v_body = s["velocity"] - np.cross(w, s["dvl_position_body"])
    v_ned = np.einsum("pij,pj->pi", np.stack([rpy(*a) for a in angles]), v_body)
    out = np.full((len(tp), 3), np.nan)
    start = int(np.searchsorted(tp, t[k0]))
    pos = np.array([np.interp(tp[start], t, s["ref_position"][:, j]) for j in range(3)])
    out[start] = pos
    for k in range(start + 1, len(tp)):
        pos = pos + (tp[k] - tp[k - 1]) * v_ned[k - 1]
        out[k] = pos
    return out


if __name__ == "__main__":  # the table: python tests/akit_logs.py
    for k in SEGMENTS:
        s = corrected(k)
        r = run_segment(s)
        print(f"segment {k}: axes {s['axes'].astype(int).tolist()} (next best "
              f"{s['axes_margin']:.1f}x worse), clock {s['clock'][0]:+.3f} s + "
              f"{s['clock'][1]:.6f} t, DVL lag "
              f"{s['dvl_lag']:+.2f} s, DVL at {np.round(s['dvl_position_body'], 2)} m, IMU at "
              f"{np.round(s['imu_position_body'], 2)} m | "
              f"filter final {r['final']:.2f} m, RMSE {r['rmse']:.2f} m, 3-sigma coverage "
              f"{100 * r['coverage']:.0f} %, sigma_h final {r['sigma_final']:.2f} m, "
              f"availability {100 * r['availability']:.1f} %, events {r['events']} | DR "
              f"final {r['dr_final']:.2f} m, RMSE {r['dr_rmse']:.2f} m")


class _View:
    """Fields as attributes, ``in`` for their names (a group view of plain arrays)."""

    def __init__(self, **fields) -> None:
        self.__dict__.update(fields)

    def __contains__(self, name: str) -> bool:
        return name in self.__dict__


def corrected_mission(mission, s: dict):
    """A recorded mission (``auvsim import --format akit``) as ``check-log --apply`` is to
    write it, from the corrections ``corrected`` found for its segment ``s``: the IMU's
    samples through the axis map, the reference's and the DVL's times on the IMU's clock,
    the sensors' positions from the reference point in the attributes."""
    attrs = dict(mission.attrs, imu_position_body=s["imu_position_body"],
                 dvl_position_body=s["dvl_position_body"])
    imu, dvl, ref = mission.imu, mission.dvl, mission.reference
    offset, rate = s["clock"]
    return _View(
        name=mission.name, origin="recorded", attrs=attrs, gravity=mission.gravity,
        dataset=mission.dataset, has=mission.has,
        imu=_View(time=imu.time, specific_force=imu.specific_force @ s["axes"].T,
                  angular_rate=imu.angular_rate @ s["axes"].T),
        dvl=_View(time=offset + rate * (dvl.time + s["dvl_lag"]), velocity_ls=dvl.velocity_ls,
                  mode=dvl.mode),
        reference=_View(time=offset + rate * ref.time, position_ned=ref.position_ned,
                        velocity_ned=ref.velocity_ned, quaternion=ref.quaternion))
