"""How the simulated A18-D turns, sways and rolls, against the real Snapir (issue 24,
items 7 and 8).

Three parts, each printed as a table:

* **Real turns** in the shared Snapir segments (``TrajectoryK/{IMU,DVL,GT}_trajectoryK.csv``):
  every turn whose yaw rate peaks above ``--min-peak`` deg/s. The yaw rate is the
  reference's (GT) unwrapped yaw difference over its time step, and the gyro's z axis
  averaged over the same 1 s steps (the gyro's own axes are the body's FRD to the sign:
  its z agrees with the reference's yaw rate). The speed loss is the horizontal speed of the
  reference's NED velocity: its lowest value from the turn's start (the yaw rate passing
  ``START`` deg/s) to ``AFTER`` s past the peak, against its mean over the ``BEFORE`` s
  before the start. ``fin flow`` is the flow angle at the fins, atan(r |x_fin| / U) at the
  peak with the model's fin lever: a fin still pushing in a turn has its angle beyond it
  (models/README.md, "stall bound"), so it is a lower bound on the rudder angle that flew
  the turn.
* **The model's full-rudder step**: the A18-D at the shaft speed of 2 m/s, depth held,
  rudder stepped to its limit for 60 s: peak and steady yaw rate (mean of the last 10 s),
  and the speed loss.
* **Sway and roll per mission**: the std of the body-frame sway velocity (real: the DVL's
  Y, and the reference's NED velocity in body axes, C^T v; simulated: the truth's
  ``velocity_body`` at the body origin and the DVL's Y of the valid pings), and the mean
  roll (real: the reference's; simulated: the truth's), each summarised by its median and
  range over the missions, for the real segments and for each ``--sim`` dataset (e.g. one
  ``auvsim generate --preset realistic-maneuvers`` file before a change and one after).

    .venv/bin/python benchmarks/turning.py [--data ../shared/data/snapir-akit]
        [--sim LABEL=FILE.h5 ...] [--min-peak 8]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import h5py
import numpy as np
import perf_page

from auvsim.physics.frames import euler_angles, rotation_matrices, rotation_rpy
from auvsim.physics.vehicle import Vehicle

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "data" / "snapir-akit"
START = 2.0  # deg/s: a turn starts where the yaw rate passes this on the way to its peak
BEFORE = 5.0  # s of speed before the turn's start: the speed the turn began from
AFTER = 15.0  # s past the peak in which the lowest speed is sought
STEP_S = 60.0  # s of the model's full-rudder step
STEADY_S = 10.0  # s at its end that make the steady yaw rate
HARD = 12.0  # deg/s: a hard turn's peak, the lower end of the issue's 12-18 deg/s


def read_segment(folder: Path) -> dict[str, np.ndarray]:
    """One segment's three streams as arrays (the CSV header skipped)."""
    k = folder.name.removeprefix("Trajectory")
    load = lambda name: np.loadtxt(folder / f"{name}_trajectory{k}.csv",  # noqa: E731
                                   delimiter=",", skiprows=1)
    return {"gt": load("GT"), "imu": load("IMU"), "dvl": load("DVL")}


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
    sway = np.array([(rotation_rpy(*row[7:10]).T @ row[4:7])[1] for row in gt])
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
            "heading_change": float(np.sum(r[start:end + 1] * np.diff(t)[start:end + 1])),
        })
        i = end + 1
    return turns


def real_sway_roll(seg: dict[str, np.ndarray]) -> dict[str, float]:
    """Per-segment std of the body sway (DVL Y; the reference's C^T v) and mean roll."""
    gt, dvl = seg["gt"], seg["dvl"]
    body = np.array([rotation_rpy(*row[7:10]).T @ row[4:7] for row in gt])
    return {"sway_dvl": dvl[:, 2].std(), "sway_ref": body[:, 1].std(),
            "roll": math.degrees(gt[:, 7].mean())}


def sim_sway_roll(path: Path) -> dict[str, dict[str, float]]:
    """The same per mission of a simulated dataset (a single HDF5 file)."""
    out = {}
    with h5py.File(path, "r") as f:
        for name, m in f["missions"].items():
            vel = m["truth/velocity_body"][:]
            roll = euler_angles(m["truth/quaternion"][:])[:, 0]
            figures = {"sway_ref": vel[:, 1].std(), "roll": math.degrees(roll.mean())}
            if "dvl/velocity" in m:
                v = m["dvl/velocity"][:]
                ok = np.all(np.isfinite(v), axis=1)
                figures["sway_dvl"] = v[ok, 1].std() if ok.any() else math.nan
            out[name] = figures
    return out


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


def implied_limit(flow_deg: float, key: str = "fin_flow_slip") -> float:
    """The rudder limit (deg) at which the model's full-rudder step from 2 m/s has the fin
    flow angle ``flow_deg`` at its yaw-rate peak (``key``: with the sway, or from r |x_fin| / U
    alone): the limit the measured turns imply through the model's own balance of fin and
    hull at the peak. Bisection; the flow angle grows with the limit (with the sway: 25.4,
    28.0, 29.5 deg at 30, 35, 38 deg) and does not depend on the speed."""
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
    parser.add_argument("--min-peak", type=float, default=8.0,
                        help="deg/s: the smallest yaw-rate peak counted as a turn")
    parser.add_argument("--infer", action="store_true",
                        help="also find the rudder limit the hard turns imply (a bisection "
                        "of model runs, about a minute)")
    perf_page.add_write_option(parser, "turning")
    args = parser.parse_args()
    segments = sorted(args.data.glob("Trajectory*"), key=lambda p: int(p.name[10:]))
    if not segments:
        raise SystemExit(f"--data: no Trajectory*/ folders in {args.data}")
    sims = []
    for item in args.sim:
        label, sep, file = item.partition("=")
        if not sep or not Path(file).is_file():
            raise SystemExit(f"--sim: expected LABEL=FILE.h5 of an existing file, got {item!r}")
        sims.append((label, Path(file)))

    fin_lever = abs(Vehicle("auv").hydro.fin_x)
    data = {p.name: read_segment(p) for p in segments}
    print(f"Real turns (|r| peak >= {args.min_peak:g} deg/s), {args.data}; fin lever "
          f"{fin_lever:g} m")
    print(f"{'segment':13s} {'t s':>5s} {'r GT':>6s} {'gyro z':>6s} {'turned':>7s} "
          f"{'U0':>5s} {'Umin':>5s} {'loss':>6s} {'U pk':>5s} {'slip':>6s} {'fin flow':>8s} "
          f"{'+ slip':>7s}")
    turns = []
    for name, seg in data.items():
        for turn in real_turns(seg, fin_lever, args.min_peak):
            turns.append(turn)
            print(f"{name:13s} {turn['time']:5.0f} {turn['peak']:+6.1f} {turn['gyro']:+6.1f} "
                  f"{turn['heading_change']:+7.0f} {turn['u_before']:5.2f} {turn['u_min']:5.2f} "
                  f"{100 * turn['loss']:5.1f}% {turn['u_peak']:5.2f} {turn['slip']:+6.2f} "
                  f"{turn['fin_flow']:7.1f}d {turn['fin_flow_slip']:6.1f}d")
    peaks = np.abs([t["peak"] for t in turns])
    per_segment = [max(abs(t["peak"]) for t in real_turns(s, fin_lever, args.min_peak))
                   for s in data.values()]
    print(f"{len(turns)} turns: |r| peak median {np.median(peaks):.1f}, range {peaks.min():.1f} "
          f"to {peaks.max():.1f} deg/s; each segment's largest {min(per_segment):.1f} to "
          f"{max(per_segment):.1f} deg/s; speed loss median "
          f"{100 * np.median([t['loss'] for t in turns]):.0f} % "
          f"({100 * min(t['loss'] for t in turns):.0f} to "
          f"{100 * max(t['loss'] for t in turns):.0f} %); fin flow angle at the peak up to "
          f"{max(t['fin_flow'] for t in turns):.1f} deg (median "
          f"{np.median([t['fin_flow'] for t in turns]):.1f})")

    hard = [t for t in turns if abs(t["peak"]) >= HARD]
    flows = np.array([t["fin_flow_slip"] for t in hard])
    print(f"{len(hard)} hard turns (|r| peak >= {HARD:g} deg/s): peak median "
          f"{np.median(np.abs([t['peak'] for t in hard])):.1f} deg/s, speed loss median "
          f"{100 * np.median([t['loss'] for t in hard]):.0f} % ({100 * min(t['loss'] for t in hard):.0f}"
          f" to {100 * max(t['loss'] for t in hard):.0f} %); fin flow angle with the sway at the "
          f"peak median {np.median(flows):.1f} deg (quartiles {np.percentile(flows, 25):.1f} to "
          f"{np.percentile(flows, 75):.1f}); r |x_fin| / U alone {np.median([t['fin_flow'] for t in hard]):.1f} deg")
    if args.infer:
        print(f"rudder limit at which the model's full-rudder step has that flow angle at its "
              f"peak: {implied_limit(float(np.median(flows))):.1f} deg (quartiles: "
              f"{implied_limit(float(np.percentile(flows, 25))):.1f} to "
              f"{implied_limit(float(np.percentile(flows, 75))):.1f} deg); from r |x_fin| / U "
              f"alone (no sway, so no reference point): "
              f"{implied_limit(float(np.median([t['fin_flow'] for t in hard])), 'fin_flow'):.1f} deg")

    step = model_step()
    print(f"\nModel A18-D, full rudder ({step['limit']:.1f} deg) from 2 m/s, depth held, "
          f"{STEP_S:g} s: peak {step['peak']:.2f} deg/s, steady {step['steady']:.2f} deg/s, "
          f"speed loss {100 * step['loss_min']:.1f} % at the least, {100 * step['loss_steady']:.1f} "
          f"% steady; at the peak: sway {step['slip']:+.2f} m/s, fin flow angle "
          f"{step['fin_flow']:.1f} deg, {step['fin_flow_slip']:.1f} deg with the sway")

    rows = {"real": {n: real_sway_roll(s) for n, s in data.items()}}
    rows |= {label: sim_sway_roll(path) for label, path in sims}
    print("\nPer-mission sway std (m/s) and mean roll (deg): median (range)")
    print(f"{'source':24s} {'n':>3s} {'sway, DVL Y':>26s} {'sway, body velocity':>26s} "
          f"{'mean roll':>26s} {'|mean roll| max':>15s}")
    for label, per in rows.items():
        fig = lambda key: [m.get(key, math.nan) for m in per.values()]  # noqa: E731
        print(f"{label:24s} {len(per):3d} {summary(fig('sway_dvl')):>26s} "
              f"{summary(fig('sway_ref')):>26s} {summary(fig('roll')):>26s} "
              f"{max(abs(x) for x in fig('roll')):15.2f}")
    for label, per in list(rows.items())[1:]:
        print(f"\n{label} per mission: sway std (body velocity, DVL Y) m/s, mean roll deg")
        for name, m in per.items():
            print(f"  {name:24s} {m['sway_ref']:.3f} {m.get('sway_dvl', math.nan):.3f} "
                  f"{m['roll']:+.2f}")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
