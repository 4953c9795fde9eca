"""How the simulated A18-D turns, sways and rolls, against the real Snapir (issue 24,
items 7 and 8).

* **Real turns** in the six Snapir segments (``TrajectoryK/{IMU,DVL,GT}_trajectoryK.csv``):
  every turn whose yaw rate peaks above ``--min-peak`` deg/s. The yaw rate is the
  reference's (GT) unwrapped yaw difference over its time step, and the gyro's z axis
  averaged over the same 1 s steps (its z agrees with the reference's yaw rate in sign).
  The speed loss is the horizontal speed of the reference's NED velocity: its lowest value
  from the turn's start (the yaw rate passing ``START`` deg/s) to ``AFTER`` s past the peak,
  against its mean over the ``BEFORE`` s before the start. ``fin flow`` is the flow angle
  at the fins at the peak, atan(r |x_fin| / U) with the model's fin lever, and ``+ slip``
  the same with the sideslip (the reference's body-axis sway less its mean before the
  turn): a rudder still pushing has its angle beyond it (models/README.md).
* **The rudder limit they imply** (``--infer``): the limit at which the model's full-rudder
  step has the hard turns' median flow angle at its peak (a bisection of model runs).
* **The model's full-rudder step**: the A18-D at the shaft speed of 2 m/s, depth held,
  rudder stepped to its limit for 60 s: peak and steady yaw rate (mean of the last 10 s),
  the speed loss and the flow angle at the peak.
* **Hard turns of each ``--sim`` dataset**, with the same detector on its truth at 1 Hz;
  with ``--rpm-alone``, also of the ``realistic-maneuvers`` preset generated here with the
  heading PID throughout (``vehicle.heading_control = "pid"``: rpm held, no full-rudder
  turns; 20 missions of 600 s, about half a minute), labelled ``rpm alone``.
* **Sway, current and roll per mission**: the std of the body-frame sway (real: the DVL's
  Y; the reference's NED velocity in body axes, C^T v, over the ground; and through the
  water, less the current fitted on the straight stretches; simulated: the DVL's Y of the
  valid pings, the truth's ``velocity_body`` and ``velocity_water_body``), the current, and
  the mean roll, each summarised by its median and range over the missions, for the real
  segments and each ``--sim`` dataset (e.g. ``auvsim generate --preset
  realistic-maneuvers`` before a change and after), and for the simulated missions that
  turn at least as much as every real segment.
  Beside them, the DVL's Y of the Snapir's long logs (``--logs``: about 8 h of its
  Navigator's output, ``log_windows``) in windows of a simulated mission's length: many
  more missions of the same vehicle than the six segments, with no reference.
  Then, for each source, whether issue 24's bounds hold: the median over missions of each
  sway std within ``SWAY_BOUNDS`` and every mission's |mean roll| within ``ROLL_BOUND``.
* **The model flown through each real segment's own manoeuvres** (``--replay``, a few
  seconds): ``replay`` gives the model each turn of the reference as a survey autopilot is
  given one, in the segment's current; its sway per segment and its hard turns beside the
  segment's own, like with like (the preset's missions turn less often than the segments).
* **The roll period**: the real roll-rate spectra's peak against the model's damped period.

    .venv/bin/python benchmarks/turning.py [--data ../shared/data/snapir-akit]
        [--logs ../shared/data/snapir-missbeamnet] [--sim LABEL=FILE.h5 ...] [--rpm-alone]
        [--min-peak 8] [--infer] [--replay]
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
import tempfile
from pathlib import Path

import h5py
import numpy as np
import perf_page

from auvsim.physics.frames import euler_angles
from auvsim.physics.vehicle import MIN_SPEED, Vehicle
from auvsim.runs.generate import generate
from auvsim.runs.presets import SNAPIR_DVL_POSITION, SNAPIR_IMU_POSITION, preset

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "snapir-akit"
DEFAULT_LOGS = DEFAULT_DATA.parent / "snapir-missbeamnet"
# The long logs' files that hold distinct pings: 9,129 of the test file's rows repeat the
# training file's (its README), so it is left out.
LOG_FILES = ("train_data.csv", "validation_data.csv")
WINDOW = 600  # pings of the long logs per window: about 600 s, a simulated mission's length
UNDERWAY = 0.5  # m/s: a window counts when its median speed is at least this (MIN_SPEED)
START = 2.0  # deg/s: a turn starts where the yaw rate passes this on the way to its peak
BEFORE = 5.0  # s of speed before the turn's start: the speed the turn began from
AFTER = 15.0  # s past the peak in which the lowest speed is sought
STEP_S = 60.0  # s of the model's full-rudder step
STEADY_S = 10.0  # s at its end that make the steady yaw rate
HARD = 12.0  # deg/s: a hard turn's peak, the lower end of the 12-18 deg/s
STRAIGHT, STRAIGHT_S = 1.5, 5.0  # deg/s, s: straight flight, |r| below this so long
HOLD_S = 3.0  # s before a replayed turn whose speed through the water sets its rpm
SWAY_BOUNDS = (0.03, 0.44)  # m/s: issue 24's range of the real per-segment sway std
ROLL_BOUND = 2.3  # deg: issue 24's largest real per-segment |mean roll|


def read_segment(folder: Path) -> dict[str, np.ndarray]:
    """One segment's three streams as arrays (the CSV header skipped)."""
    k = folder.name.removeprefix("Trajectory")
    load = lambda name: np.loadtxt(folder / f"{name}_trajectory{k}.csv",  # noqa: E731
                                   delimiter=",", skiprows=1)
    return {"gt": load("GT"), "imu": load("IMU"), "dvl": load("DVL")}


def body_velocity(gt: np.ndarray) -> np.ndarray:
    """(N, 3) the reference's velocity in its body axes, C^T v, m/s: each row's NED
    velocity (columns 4-6) turned by its roll, pitch and yaw (columns 7-9, rad; C body ->
    NED, ZYX, as ``auvsim.physics.frames.rotation_rpy``)."""
    v = gt[:, 4:7]
    cr, sr = np.cos(gt[:, 7]), np.sin(gt[:, 7])
    cp, sp = np.cos(gt[:, 8]), np.sin(gt[:, 8])
    cy, sy = np.cos(gt[:, 9]), np.sin(gt[:, 9])
    # The columns of C: the body's x, y and z axes in NED.
    axes = np.stack([np.column_stack([cy * cp, sy * cp, -sp]),
                     np.column_stack([cy * sp * sr - sy * cr, sy * sp * sr + cy * cr, cp * sr]),
                     np.column_stack([cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr])],
                    axis=1)
    return np.einsum("nij,nj->ni", axes, v)


def real_turns(seg: dict[str, np.ndarray], fin_lever: float, min_peak: float) -> list[dict]:
    """The turns of one segment whose |yaw rate| peaks above ``min_peak`` deg/s."""
    gt, imu = seg["gt"], seg["imu"]
    t = gt[:, 0]
    r = np.degrees(np.diff(np.unwrap(gt[:, 9])) / np.diff(t))  # between GT samples
    t_mid = 0.5 * (t[1:] + t[:-1])
    # The gyro averaged over each GT step (the IMU clock taken as the GT's: its offset,
    # a fraction of a second, moves a 1 s mean little).
    gyro = np.array([imu[(imu[:, 0] >= a) & (imu[:, 0] < b), 6].mean()
                     for a, b in zip(t[:-1], t[1:], strict=True)])
    speed = np.hypot(gt[:, 4], gt[:, 5])
    # The reference's velocity in body axes: its sway, less its mean before the turn (the
    # current's share, which turns with the heading only slowly), is the hull's sideslip.
    sway = body_velocity(gt)[:, 1]
    turns = []
    i = 0
    while i < len(r):
        if abs(r[i]) < min_peak:
            i += 1
            continue
        sign = math.copysign(1.0, r[i])
        end = i
        while end + 1 < len(r) and sign * r[end + 1] > START:
            end += 1
        start = i
        while start > 0 and sign * r[start - 1] > START:
            start -= 1
        peak = start + int(np.argmax(sign * r[start:end + 1]))
        before = (t >= t[start] - BEFORE) & (t <= t[start])
        window = (t >= t[start]) & (t <= t_mid[peak] + AFTER)
        u_before = speed[before].mean()
        u_peak = 0.5 * (speed[peak] + speed[peak + 1])
        # Flow at the fins, positive against the turn: r |x_fin| plus the sideslip
        # (v < 0 in a starboard turn), the reference point taken as the hull's centre.
        slip = 0.5 * (sway[peak] + sway[peak + 1]) - sway[before].mean()
        fin_flow_slip = math.atan((math.radians(abs(r[peak])) * fin_lever - sign * slip)
                                  / u_peak)
        turns.append({
            "time": t_mid[peak], "peak": r[peak], "gyro": math.degrees(gyro[peak]),
            "u_before": u_before, "u_min": speed[window].min(),
            "loss": 1.0 - speed[window].min() / u_before, "u_peak": u_peak,
            "fin_flow": math.degrees(math.atan(math.radians(abs(r[peak])) * fin_lever
                                               / u_peak)),
            "fin_flow_slip": math.degrees(fin_flow_slip), "slip": slip,
            # Roll toward the turn's inside (starboard in a starboard turn) at the peak, and
            # its largest either way from the start to AFTER s past the peak.
            "roll_peak": sign * math.degrees(0.5 * (gt[peak, 7] + gt[peak + 1, 7])),
            "roll_in": float(np.degrees(sign * gt[window, 7]).max()),
            "roll_out": float(np.degrees(-sign * gt[window, 7]).max()),
            "heading_change": float(np.sum(r[start:end + 1] * np.diff(t)[start:end + 1])),
        })
        i = end + 1
    return turns


def straight(seg: dict[str, np.ndarray]) -> np.ndarray:
    """(N,) bool: the reference's samples with |yaw rate| < ``STRAIGHT`` deg/s for
    ``STRAIGHT_S`` s either side."""
    gt = seg["gt"]
    r = np.abs(np.degrees(np.gradient(np.unwrap(gt[:, 9]), gt[:, 0])))
    half = round(STRAIGHT_S / np.median(np.diff(gt[:, 0])))
    return np.array([r[max(0, i - half):i + half + 1].max() < STRAIGHT for i in range(len(r))])


def real_sway_roll(seg: dict[str, np.ndarray]) -> dict[str, float]:
    """Per-segment std of the body sway (DVL Y; the reference's C^T v over the ground, and
    through the water) and mean roll, and the current.

    The current is fitted on the straight stretches, where a hull flies without sideslip and
    its sway over the ground is the current's cross component: sway = -sin(psi) c_N +
    cos(psi) c_E + U sin(e), with e a yaw misalignment of the reference (least squares over
    the segment's headings; the turns between the legs make it well posed)."""
    gt, dvl = seg["gt"], seg["dvl"]
    body = body_velocity(gt)
    a, ok, fit = _current_fit(seg)
    c_n, c_e, _ = fit
    through_water = body[:, 1] - a[:, :2] @ [c_n, c_e]
    return {"sway_dvl": dvl[:, 2].std(), "sway_ref": body[:, 1].std(),
            "sway_water": through_water.std(), "current": math.hypot(c_n, c_e),
            "sway_straight": (body[ok, 1] - a[ok] @ fit).std(),
            "roll": math.degrees(gt[:, 7].mean())}


def _current_fit(seg: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``real_sway_roll``'s fit: its design matrix (N, 3), the straight samples it is
    fitted on, and (c_N, c_E, e)."""
    gt = seg["gt"]
    psi, speed = gt[:, 9], np.hypot(gt[:, 4], gt[:, 5])
    a = np.column_stack([-np.sin(psi), np.cos(psi), speed])
    ok = straight(seg)
    fit, *_ = np.linalg.lstsq(a[ok], body_velocity(gt)[ok, 1], rcond=None)
    return a, ok, fit


def replay(seg: dict[str, np.ndarray], name: str = "auv") -> dict[str, np.ndarray]:
    """The model flown through a real segment's own manoeuvres, laid out as
    ``sim_missions`` lays out a simulated mission (its DVL: the truth at the Snapir's DVL
    position, v + w x r, at 1 Hz, without the instrument's errors).

    It flies as ``presets.REAL_VEHICLE`` does (rpm held, full-rudder turns), in the
    segment's current (``_current_fit``, constant), at the reference's depth. Each turn of
    the reference (the samples whose |yaw rate| exceeds ``START`` deg/s) becomes what a
    survey autopilot is given: from the turn's start, the heading the turn ends on, and the
    shaft held at the rpm of the speed through the water of the ``HOLD_S`` s before it;
    between turns, the reference's heading and speed through the water. How fast it turns,
    how far it slips and how much speed it loses are then the model's own."""
    gt = seg["gt"]
    t = gt[:, 0] - gt[0, 0]
    yaw = np.unwrap(gt[:, 9])
    _, _, (c_n, c_e, _) = _current_fit(seg)
    through = np.hypot(gt[:, 4] - c_n, gt[:, 5] - c_e)
    heading, speed = yaw.copy(), through.copy()
    turning = np.abs(np.degrees(np.gradient(yaw, t))) > START
    edges = np.flatnonzero(np.diff(np.concatenate([[0], turning.astype(int), [0]])))
    for start, end in zip(edges[::2], edges[1::2], strict=True):
        heading[start:end] = yaw[min(end, len(yaw) - 1)]  # the first sample past the turn
        before = through[(t >= t[start] - HOLD_S) & (t < t[start])]
        speed[start:end] = before.mean() if len(before) else through[end - 1]
    vehicle = Vehicle(name, current_ned=(c_n, c_e, 0.0), hold_rpm=True,
                      full_rudder_turns=True, imu_position=SNAPIR_IMU_POSITION,
                      dvl_position=SNAPIR_DVL_POSITION)
    vehicle.reset(position_ned=(0.0, 0.0, -gt[0, 3]), yaw=yaw[0],
                  velocity_body=(through[0], 0.0, 0.0))
    ts = vehicle.dt * np.arange(round(t[-1] / vehicle.dt))
    refs = np.column_stack([np.maximum(np.interp(ts, t, speed), MIN_SPEED),
                            np.interp(ts, t, heading), np.interp(ts, t, -gt[:, 3])])
    return segment_of(vehicle.run(refs), vehicle.dt, vehicle.dvl_position)


def segment_of(traj, dt: float, dvl_position) -> dict[str, np.ndarray]:
    """A simulated run (a ``Trajectory`` at the physics step ``dt``) laid out as a real
    segment (``read_segment``) and as ``sim_missions`` lays out a simulated mission: the
    reference at 1 Hz (time, two unused columns, altitude, NED velocity, roll, pitch,
    yaw), the gyro at the physics rate, the DVL as the truth at ``dvl_position`` (v + w x
    r, without the instrument's errors) at 1 Hz, and the truth's body velocities, roll and
    current."""
    every = round(1.0 / dt)
    t = dt * np.arange(len(traj.angular_rate))
    euler = euler_angles(traj.quaternion)
    at_dvl = traj.velocity_body + np.cross(traj.angular_rate, dvl_position)
    return {"gt": np.column_stack([t, np.zeros((len(t), 2)), -traj.position_ned[:, 2],
                                   traj.velocity_ned, euler])[::every],
            "imu": np.column_stack([t, np.zeros((len(t), 3)), traj.angular_rate]),
            "dvl": np.column_stack([t, at_dvl])[::every],
            "velocity_body": traj.velocity_body, "roll": euler[:, 0],
            "velocity_water_body": traj.velocity_water_body, "current": traj.current_ned}


def roll_period(seg: dict[str, np.ndarray]) -> float:
    """Period (s) of the largest peak of the roll-rate spectrum between 0.05 and 3 Hz
    (the gyro's x, Hann window, smoothed over 41 bins)."""
    imu = seg["imu"]
    p = imu[:, 4] - imu[:, 4].mean()
    f = np.fft.rfftfreq(len(p), np.median(np.diff(imu[:, 0])))
    power = np.convolve(np.abs(np.fft.rfft(p * np.hanning(len(p)))) ** 2,
                        np.ones(41) / 41, mode="same")
    band = (f > 0.05) & (f < 3.0)
    return 1.0 / f[band][np.argmax(power[band])]


def model_roll_period(name: str = "auv") -> float:
    """The model's damped roll period (s): omega_n^2 = W BG / (I_x + A_44) with the inertia
    about the CO, and the damping ratio of its linear roll damping."""
    h = Vehicle(name).hydro
    m44 = np.linalg.inv(h.mass_matrix_inv)[3, 3]
    omega = math.sqrt(h.weight * h.r_g[2] / m44)
    zeta = h.linear_damping[3] / (2.0 * omega * m44)
    return 2.0 * math.pi / (omega * math.sqrt(1.0 - zeta * zeta))


def heading_change(seg: dict[str, np.ndarray]) -> float:
    """Total heading change of a segment in its turns, deg (both ways counted; the steps
    whose yaw rate exceeds ``START`` deg/s, so that the wobble of straight flight does not
    count)."""
    gt = seg["gt"]
    step = np.diff(np.unwrap(gt[:, 9]))
    turning = np.abs(np.degrees(step / np.diff(gt[:, 0]))) > START
    return math.degrees(np.abs(step[turning]).sum())


def log_windows(folder: Path) -> tuple[list[dict[str, float]], int]:
    """The per-window sway of the Snapir's long DVL logs (MissBeamNet's ``LOG_FILES``, about
    8 h of the Navigator's own velocity output, ``x/y/z speed`` in the body axes, at about
    1 Hz):
    each file cut into consecutive windows of ``WINDOW`` valid pings (every velocity
    component finite and below 10 m/s: 32.768 marks an invalid ping), kept where the
    vehicle is underway (median horizontal speed at least ``UNDERWAY``). Per window: the
    std of the DVL's Y (``sway_dvl``) and its median speed (``speed``). Returns the
    windows and the number of valid pings in the files."""
    out, pings = [], 0
    for name in LOG_FILES:
        with open(folder / name, newline="") as f:
            v = np.array([[float(row[f"{axis} speed"]) for axis in "xyz"]
                          for row in csv.DictReader(f)])
        v = v[np.all(np.isfinite(v) & (np.abs(v) < 10.0), axis=1)]
        pings += len(v)
        for start in range(0, len(v) - WINDOW + 1, WINDOW):
            w = v[start:start + WINDOW]
            speed = float(np.median(np.hypot(w[:, 0], w[:, 1])))
            if speed >= UNDERWAY:
                out.append({"sway_dvl": float(w[:, 1].std()), "speed": speed})
    return out, pings


def sim_missions(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """Each mission of a simulated dataset (one HDF5 file) laid out as a real segment: its
    truth sampled at 1 Hz as the reference (time, three unused columns, NED velocity,
    roll, pitch, yaw), its truth's angular rate as the gyro, its DVL velocity (valid
    pings) as the DVL, and its truth's body velocity."""
    out = {}
    with h5py.File(path, "r") as f:
        for name, m in f["missions"].items():
            t = m["truth/time"][:]
            every = max(1, round(1.0 / (t[1] - t[0])))
            euler = euler_angles(m["truth/quaternion"][:])
            gt = np.column_stack([t, np.zeros((len(t), 3)), m["truth/velocity_ned"][:],
                                  euler])[::every]
            imu = np.column_stack([t, np.zeros((len(t), 3)), m["truth/angular_rate"][:]])
            v = m["dvl/velocity"][:] if "dvl/velocity" in m else np.full((1, 3), np.nan)
            dvl = np.column_stack([np.zeros(len(v)), v])
            out[name] = {"gt": gt, "imu": imu, "dvl": dvl[np.all(np.isfinite(v), axis=1)],
                         "velocity_body": m["truth/velocity_body"][:], "roll": euler[:, 0],
                         "velocity_water_body": m["truth/velocity_water_body"][:],
                         "current": m["truth/current_ned"][:]}
    return out


def sim_sway_roll(seg: dict[str, np.ndarray]) -> dict[str, float]:
    """``real_sway_roll`` of a simulated mission (``sim_missions``), from its truth at the
    simulation's rate."""
    dvl = seg["dvl"]
    ok = np.repeat(straight(seg), round(len(seg["roll"]) / len(seg["gt"])))[:len(seg["roll"])]
    return {"sway_ref": seg["velocity_body"][:, 1].std(),
            "sway_dvl": dvl[:, 2].std() if len(dvl) else math.nan,
            "sway_water": seg["velocity_water_body"][:, 1].std(),
            "sway_straight": seg["velocity_water_body"][ok, 1].std() if ok.any() else math.nan,
            "current": float(np.linalg.norm(seg["current"][:, :2], axis=1).mean()),
            "roll": math.degrees(seg["roll"].mean())}


def turn_summary(turns: list[dict]) -> str:
    """One line on the hard turns among ``turns``."""
    hard = [t for t in turns if abs(t["peak"]) >= HARD]
    if not hard:
        return f"no turn with a |r| peak >= {HARD:g} deg/s"
    med = lambda key: float(np.median([t[key] for t in hard]))  # noqa: E731
    return (f"{len(hard):3d} hard turns: |r| peak median "
            f"{np.median(np.abs([t['peak'] for t in hard])):4.1f} deg/s, speed loss median "
            f"{100 * med('loss'):3.0f} %, sway at the peak median "
            f"{np.median([abs(t['slip']) for t in hard]):.2f} m/s, fin flow angle median "
            f"{med('fin_flow_slip'):4.1f} deg; roll toward the inside at the peak median "
            f"{med('roll_peak'):+.1f} deg, largest inward {med('roll_in'):+.1f}, outward "
            f"{med('roll_out'):+.1f} deg (medians)")


def model_step(name: str = "auv", speed: float = 2.0, rudder_max: float | None = None
               ) -> dict[str, float]:
    """The model's full-rudder step from ``speed``, depth held; ``rudder_max`` (rad) in
    place of the model's rudder limit if given."""
    vehicle = Vehicle(name)
    if rudder_max is not None:
        vehicle.hydro = vehicle.hydro._replace(rudder_max=rudder_max)
    vehicle.reset(position_ned=(0.0, 0.0, 50.0), velocity_body=(speed, 0.0, 0.0))
    steps = round(STEP_S / vehicle.dt)
    command = np.tile([vehicle.actuators[0], vehicle.hydro.rudder_max, 50.0], (steps, 1))
    traj = vehicle.run(command, closed_loop=(False, False, True))
    r = np.degrees(traj.angular_rate[:, 2])
    u = np.linalg.norm(traj.velocity_body, axis=1)
    last = slice(-round(STEADY_S / vehicle.dt), None)
    peak = int(np.argmax(r))
    lever = abs(vehicle.hydro.fin_x)
    flow = lambda slip: math.degrees(math.atan(  # noqa: E731
        (math.radians(r[peak]) * lever - slip) / u[peak]))
    return {"limit": math.degrees(vehicle.hydro.rudder_max), "peak": r[peak],
            "steady": r[last].mean(), "loss_steady": 1.0 - u[last].mean() / speed,
            "loss_min": 1.0 - u.min() / speed, "slip": traj.velocity_body[peak, 1],
            "fin_flow": flow(0.0), "fin_flow_slip": flow(traj.velocity_body[peak, 1])}


def rpm_alone_missions() -> dict[str, dict[str, np.ndarray]]:
    """``sim_missions`` of the ``realistic-maneuvers`` preset with the heading PID
    throughout (rpm still held): what its full-rudder line turns add."""
    config = preset("realistic-maneuvers")
    config = dataclasses.replace(config, vehicle=dataclasses.replace(config.vehicle,
                                                                     heading_control="pid"))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rpm-alone.h5"
        generate(config, path, workers=1, progress=False)
        return sim_missions(path)


def implied_limit(flow_deg: float, key: str = "fin_flow_slip") -> float:
    """The rudder limit (deg) at which the model's full-rudder step from 2 m/s has the fin
    flow angle ``flow_deg`` at its yaw-rate peak (``key``: with the sway, or from r |x_fin| / U
    alone): the limit the measured turns imply through the model's own balance of fin and
    hull at the peak. Bisection; the flow angle grows with the limit (with the sway: 25.0,
    27.3, 28.6, 29.7 deg at 30, 35, 38, 41 deg) and does not depend on the speed."""
    lo, hi = 15.0, 60.0
    for _ in range(12):
        mid = 0.5 * (lo + hi)
        if model_step(rudder_max=math.radians(mid))[key] < flow_deg:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def summary(values) -> str:
    v = np.asarray([x for x in values if math.isfinite(x)])
    if v.size == 0:
        return f"{'-':>20s}"
    return f"{np.median(v):6.3f} ({v.min():.3f} to {v.max():.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA,
                        help="folder of TrajectoryK/ segments")
    parser.add_argument("--sim", action="append", default=[], metavar="LABEL=FILE.h5",
                        help="a simulated dataset to measure beside the real segments")
    parser.add_argument("--rpm-alone", action="store_true",
                        help="also generate and measure realistic-maneuvers with the heading "
                        "PID in place of its full-rudder turns (about half a minute)")
    parser.add_argument("--min-peak", type=float, default=8.0,
                        help="deg/s: the smallest yaw-rate peak counted as a turn")
    parser.add_argument("--infer", action="store_true",
                        help="also find the rudder limit the hard turns imply (a bisection "
                        "of model runs, about a minute)")
    parser.add_argument("--replay", action="store_true",
                        help="also fly the model through each real segment's own "
                        "manoeuvres and compare its sway and turns (a few seconds)")
    parser.add_argument("--logs", type=Path, default=None,
                        help="folder of the Snapir's long DVL logs (MissBeamNet's "
                        "train_data.csv, validation_data.csv), measured beside the segments "
                        f"(default: {DEFAULT_LOGS}, skipped when absent)")
    perf_page.add_write_option(parser, "turning")
    args = parser.parse_args()
    segments = sorted(args.data.glob("Trajectory*"), key=lambda p: int(p.name[10:]))
    if not segments:
        parser.error(f"--data: expected a folder of Trajectory*/ segments, got {args.data}")
    sims = []
    for item in args.sim:
        label, sep, file = item.partition("=")
        if not sep or not Path(file).is_file():
            parser.error(f"--sim: expected LABEL=FILE.h5 of an existing file, got {item!r}")
        sims.append((label, Path(file)))

    fin_lever = abs(Vehicle("auv").hydro.fin_x)
    data = {p.name: read_segment(p) for p in segments}
    turns = print_real_turns(data, fin_lever, args.min_peak, args.data)
    hard = [t for t in turns if abs(t["peak"]) >= HARD]
    flows = np.array([t["fin_flow_slip"] for t in hard])
    alone = float(np.median([t["fin_flow"] for t in hard]))
    print(f"{len(hard)} hard turns (|r| peak >= {HARD:g} deg/s): fin flow angle with the "
          f"sway at the peak median {np.median(flows):.1f} deg (quartiles "
          f"{np.percentile(flows, 25):.1f} to {np.percentile(flows, 75):.1f}), from "
          f"r |x_fin| / U alone median {alone:.1f} deg")
    if args.infer:
        limits = [implied_limit(float(np.percentile(flows, q))) for q in (50, 25, 75)]
        print(f"rudder limit at which the model's full-rudder step has that flow angle at "
              f"its peak: {limits[0]:.1f} deg (quartiles {limits[1]:.1f} to {limits[2]:.1f}); "
              f"from r |x_fin| / U alone (no sway, so no reference point): "
              f"{implied_limit(alone, 'fin_flow'):.1f} deg")

    if args.replay:
        print_replay(data, fin_lever, args.min_peak)

    step = model_step()
    print(f"\nModel A18-D, full rudder ({step['limit']:.1f} deg) from 2 m/s, depth held, "
          f"{STEP_S:g} s: peak {step['peak']:.2f} deg/s, steady {step['steady']:.2f} deg/s, "
          f"speed loss {100 * step['loss_min']:.1f} % at the least, "
          f"{100 * step['loss_steady']:.1f} % steady; at the peak: sway {step['slip']:+.2f} "
          f"m/s, fin flow angle {step['fin_flow']:.1f} deg, {step['fin_flow_slip']:.1f} deg "
          "with the sway")

    missions = {label: sim_missions(path) for label, path in sims}
    if args.rpm_alone:
        missions["rpm alone"] = rpm_alone_missions()
    print("\nHard turns, real and simulated (the same detector on the truth at 1 Hz):")
    print(f"{'real':24s} {turn_summary(turns)}")
    for label, per in missions.items():
        sim_turns = [t for seg in per.values()
                     for t in real_turns(seg, fin_lever, args.min_peak)]
        print(f"{label:24s} {turn_summary(sim_turns)}")
    logs = args.logs or DEFAULT_LOGS
    present = all((logs / name).is_file() for name in LOG_FILES)
    if args.logs is not None and not present:
        parser.error(f"--logs: expected a folder holding {' and '.join(LOG_FILES)}, got "
                     f"{args.logs}")
    print_sway_roll(data, missions, *(log_windows(logs) if present else ([], 0)))

    periods = [roll_period(s) for s in data.values()]
    print(f"\nRoll period: real (roll-rate spectrum peak) median {np.median(periods):.2f} s "
          f"({min(periods):.2f} to {max(periods):.2f}); the model's damped period "
          f"{model_roll_period():.2f} s")


def print_real_turns(data: dict, fin_lever: float, min_peak: float, folder: Path
                     ) -> list[dict]:
    """Print the real segments' turns, one line each, and return them."""
    print(f"Real turns (|r| peak >= {min_peak:g} deg/s), {folder}; fin lever {fin_lever:g} m")
    print(f"{'segment':13s} {'t s':>5s} {'r GT':>6s} {'gyro z':>6s} {'turned':>7s} "
          f"{'U0':>5s} {'Umin':>5s} {'loss':>6s} {'U pk':>5s} {'slip':>6s} {'fin flow':>8s} "
          f"{'+ slip':>7s}")
    turns = []
    for name, seg in data.items():
        for t in real_turns(seg, fin_lever, min_peak):
            turns.append(t)
            print(f"{name:13s} {t['time']:5.0f} {t['peak']:+6.1f} {t['gyro']:+6.1f} "
                  f"{t['heading_change']:+7.0f} {t['u_before']:5.2f} {t['u_min']:5.2f} "
                  f"{100 * t['loss']:5.1f}% {t['u_peak']:5.2f} {t['slip']:+6.2f} "
                  f"{t['fin_flow']:7.1f}d {t['fin_flow_slip']:6.1f}d")
    peaks = np.abs([t["peak"] for t in turns])
    largest = [max(abs(t["peak"]) for t in real_turns(s, fin_lever, min_peak))
               for s in data.values()]
    losses = 100 * np.array([t["loss"] for t in turns])
    print(f"{len(turns)} turns: |r| peak median {np.median(peaks):.1f}, range {peaks.min():.1f} "
          f"to {peaks.max():.1f} deg/s; each segment's largest {min(largest):.1f} to "
          f"{max(largest):.1f} deg/s; speed loss median {np.median(losses):.0f} % "
          f"({losses.min():.0f} to {losses.max():.0f} %)")
    return turns


def print_replay(data: dict, fin_lever: float, min_peak: float) -> None:
    """Each real segment beside the model flown through its own manoeuvres (``replay``):
    the sway std per segment and its hard turns, like with like."""
    print(f"\nThe model flown through each real segment's own manoeuvres (replay): real / "
          f"model; hard turns: |r| peak >= {HARD:g} deg/s")
    print(f"{'segment':13s} {'sway, DVL Y':>13s} {'over ground':>13s} {'through water':>13s} "
          f"{'hard turns':>10s} {'largest |r| peak':>16s} {'hard speed loss':>15s}")
    figures = {key: ([], []) for key in ("sway_dvl", "sway_ref", "sway_water")}
    for name, seg in data.items():
        real, model = real_sway_roll(seg), sim_sway_roll(flown := replay(seg))
        for key, (reals, models) in figures.items():
            reals.append(real[key])
            models.append(model[key])
        turns = [[t for t in real_turns(s, fin_lever, min_peak) if abs(t["peak"]) >= HARD]
                 for s in (seg, flown)]
        peak = [max((abs(t["peak"]) for t in ts), default=math.nan) for ts in turns]
        loss = [100 * np.median([t["loss"] for t in ts]) if ts else math.nan for ts in turns]
        print(f"{name:13s} " + " ".join(f"{real[k]:6.3f}/{model[k]:.3f}" for k in figures)
              + f" {len(turns[0]):>6d}/{len(turns[1]):<3d} {peak[0]:9.1f}/{peak[1]:<6.1f} "
              f"{loss[0]:8.0f}/{loss[1]:.0f} %")
    reals, models = figures["sway_dvl"]
    ratio = np.array(models) / np.array(reals)
    print(f"{'median':13s} " + " ".join(f"{np.median(r):6.3f}/{np.median(m):.3f}"
                                        for r, m in figures.values())
          + f"; sway, DVL Y, model / real per segment {ratio.min():.2f} to {ratio.max():.2f}")


def _verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def _sway_inside(per: dict, key: str) -> bool:
    """Whether the median over missions of ``key`` lies within ``SWAY_BOUNDS``."""
    median = float(np.median([m[key] for m in per.values()]))
    return SWAY_BOUNDS[0] <= median <= SWAY_BOUNDS[1]


def print_sway_roll(data: dict, missions: dict, windows: list[dict], pings: int) -> None:
    """The per-mission sway and roll table: real segments, each simulated dataset, and its
    missions that turn at least as much as every real segment (like with like: a mission's
    sway std grows with its heading changes, as the current's cross component turns with
    the heading and every turn slips); then the DVL's Y of the long logs' ``windows``
    (``log_windows``, of ``pings`` valid pings), and which simulated medians lie within
    their 10-90 % range."""
    least = min(heading_change(s) for s in data.values())
    rows = {"real": {n: real_sway_roll(s) | {"turned": heading_change(s)}
                     for n, s in data.items()}}
    for label, per in missions.items():
        rows[label] = {n: sim_sway_roll(s) | {"turned": heading_change(s)}
                       for n, s in per.items()}
        rows[f"{label}, turning"] = {n: m for n, m in rows[label].items()
                                     if m["turned"] >= least}
    columns = (("sway_dvl", "sway, DVL Y"), ("sway_ref", "sway over the ground"),
               ("sway_water", "sway through the water"), ("sway_straight", "straight, water"),
               ("current", "current m/s"), ("roll", "mean roll deg"))
    print(f"\nPer-mission sway std (m/s), current and mean roll (deg): median (range); "
          f"'turning': the missions that turn at least as much as every real segment "
          f"({least:.0f} deg)")
    print(f"{'source':24s} {'n':>3s} " + " ".join(f"{title:>26s}" for _, title in columns)
          + f" {'|mean roll| max':>15s}")
    for label, per in rows.items():
        if not per:
            continue
        figures = {key: [m[key] for m in per.values()] for key, _ in columns}
        print(f"{label:24s} {len(per):3d} "
              + " ".join(f"{summary(figures[key]):>26s}" for key, _ in columns)
              + f" {max(abs(x) for x in figures['roll']):15.2f}")
    if windows:
        sway = np.array([w["sway_dvl"] for w in windows])
        low, high = np.percentile(sway, [10, 90])
        print(f"{'real, long logs':24s} {len(sway):3d} {summary(sway):>26s} (the DVL's Y of "
              f"{WINDOW}-ping windows underway; 10-90 %: {low:.3f} to {high:.3f}; median "
              f"speed {np.median([w['speed'] for w in windows]):.2f} m/s; of {pings} valid "
              f"pings, {pings / 3600:.1f} h at 1 Hz)")
        for label in missions:
            median = float(np.median([m["sway_dvl"] for m in rows[label].values()]))
            print(f"  {label}: sway, DVL Y median {median:.3f} m/s, within the long logs' "
                  f"10-90 % range: {_verdict(low <= median <= high)}")
    print(f"\nIssue 24's bounds (from the real segments): per-mission sway std median in "
          f"{SWAY_BOUNDS[0]:g}-{SWAY_BOUNDS[1]:g} m/s, every |mean roll| <= {ROLL_BOUND:g} deg")
    for label in rows:
        if label.endswith(", turning") or not rows[label]:
            continue
        verdicts = [f"{title} {_verdict(_sway_inside(rows[label], key))}"
                    for key, title in columns[:3]]
        roll_ok = max(abs(m["roll"]) for m in rows[label].values()) <= ROLL_BOUND
        print(f"  {label:22s} " + ", ".join(verdicts) + f"; roll {_verdict(roll_ok)}")
    for label in ("real", *missions):
        print(f"\n{label} per mission: " + ", ".join(title for _, title in columns)
              + ", heading change in turns (deg)")
        for name, m in rows[label].items():
            print(f"  {name:24s} " + " ".join(f"{m[key]:+7.3f}" for key, _ in columns)
                  + f" {m['turned']:7.0f}")

if __name__ == "__main__":
    sys.exit(perf_page.run(main))
