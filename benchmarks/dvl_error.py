"""The DVL's error velocity, simulated and real: the ``navigator`` preset before and after
its DVL noise was split (issue 24, item 8), against the Snapir's Teledyne RDI Navigator.

* ``real``: the instrument's own ``error`` column of the MissBeamNet logs (Yona & Klein,
  Neural Computing and Applications 36, 2024; ``../shared/data/snapir-missbeamnet``, test
  and validation files). Dropped: the invalid pings (32.768) and the values above 0.1 m/s,
  which are not error velocities: the test file's last 1,200 rows (9784-10983) hold 0.21 to
  2.69 m/s in that column beside a "z speed" of 1.5 m/s, a block whose columns hold other
  quantities; the largest value elsewhere is 0.027 m/s, so any cut between the two gives
  the same rows.
* ``before``: the preset with main's DVL noise (white beam noise 0.02 m/s + 2 mm/s per m/s
  of speed + 0.1 mm/s per m of range, no slow error: ``BEFORE``);
* ``after``: the preset as it is.

The simulated figure that compares with the real one is over bottom-track pings whose
four beams are not outliers: the real logs hold no outlier among their valid pings (the
largest |e| is 27 mm/s in 15,393), and their ``error`` is the bottom track's. The figure
over every finite ping is printed beside it.

It also prints the velocity error budget per axis at 2 m/s (analytic, from the preset's
settings), one mission's along-track velocity error (velocity_ls - velocity), and the real
DVL's slow error, measured two ways on the six A-KIT segments (``../shared/data/snapir-akit``,
Cohen & Klein 2025), imported and corrected as ``beamsnet reproduce sea`` does them
(``auvsim import --format akit``, ``auvsim check-log --apply``):

* against the reference: the DVL's velocity minus the reference's moved to the DVL
  (``beamsnet.data.reference_velocity``), each segment's mean removed, its autocovariance
  c(k) pooled over the segments and the two horizontal axes. Lag 0 holds the white noise
  of both; from lag 1 on only correlated errors remain, and ``SLOW_FIT_LAGS`` (1 to 20 s)
  are fitted by c(k) = sigma^2 exp(-k / tau) (least squares on ln c). That difference
  also holds the reference's own slow errors: an upper bound on the DVL's.
* against the IMU, which no DVL error enters: for every pair of pings k s apart, the
  change of the DVL's NED velocity (the DVL's velocity moved to the IMU, turned by the
  attitude) minus the IMU's integral of C f + g - 2 Omega x v over the same time (the
  attitude: the gyros integrated from the reference's at the segment's start, as the
  filter's mechanisation does; g the WGS-84 normal gravity). Its mean over the segment
  removed (a constant tilt or bias), its mean square per horizontal axis, pooled, is the
  structure function D(k) = 2 sigma_w^2 + 2 sigma^2 (1 - exp(-k / tau)) of white noise
  sigma_w and a Gauss-Markov error (sigma, tau), plus the IMU's own drift (which only
  adds): printed beside what each model predicts.

    PYTHONPATH=.:benchmarks .venv/bin/python benchmarks/dvl_error.py [--duration 600]
        [--seed 0] [--data DIR] [--akit DIR]
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
from sea_filter import gyro_step

from auvsim.config import Config
from auvsim.data.reader import open_dataset, require_attitude
from auvsim.physics.earth import earth_rate_ned, normal_gravity
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
from auvsim.sensors.dvl import Mode, clean_error_pings
from beamsnet.data import quaternions_at, recorded_body_rate, reference_velocity

REPO = Path(__file__).resolve().parent.parent
# ../shared/data beside the repository (a worktree sits one level deeper).
DATA = next((p / "shared" / "data" / "snapir-missbeamnet" for p in REPO.parents[:2]
             if (p / "shared" / "data" / "snapir-missbeamnet").is_dir()),
            REPO.parent / "shared" / "data" / "snapir-missbeamnet")
AKIT = DATA.parent / "snapir-akit"
FILES = ("test_data.csv", "validation_data.csv")
INVALID = 32.768  # the logs' mark of an invalid ping, m/s
NOT_AN_ERROR_VELOCITY = 0.1  # m/s (see the module docstring)
# main's navigator DVL noise before this change (commit b4de4a2).
BEFORE = dict(noise_std=0.02, noise_speed_coeff=0.002, noise_range_coeff=1e-4,
              slow_error_std=0.0)
SPEED_BINS = ((0.0, 0.5), (0.5, 1.2), (1.2, 1.8), (1.8, 2.2), (2.2, 4.0))  # m/s
ALTITUDE_BINS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0), (30.0, 45.0), (45.0, 60.0),
                 (60.0, 100.0))  # m
SLANT_RANGE = 46.0  # m, the navigator mission's mean (20 m depth over 60 m: 40 m / cos 30 deg)
STATED_ACCURACY = 0.02  # m/s, the Snapir DVL's published velocity std (A-KIT, sensors.md)
SLOW_FIT_LAGS = np.arange(1, 21)  # s (pings at 1 Hz), the lags the slow error is fitted on
STRUCTURE_LAGS = (1, 2, 3, 5, 8)  # s, the lags of the structure function against the IMU
# main's navigator slow error before it was measured against the IMU (commit 30481f7).
SLOW_BEFORE = dict(slow_error_std=0.018, slow_error_time=3.0)


def robust_std(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation: the std of a normal sample, untouched by a
    few outliers."""
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def read_real(folder: Path) -> dict[str, np.ndarray]:
    """The real error velocity (n,) m/s with the horizontal speed (n,) m/s and altitude
    (n,) m of each kept ping, over ``FILES``; and the counts dropped."""
    error, speed, altitude, invalid, other = [], [], [], 0, 0
    for name in FILES:
        with open(folder / name, newline="") as f:
            for row in csv.DictReader(f):
                e = float(row["error"])
                if math.isclose(abs(e), INVALID):
                    invalid += 1
                    continue
                if abs(e) > NOT_AN_ERROR_VELOCITY:
                    other += 1
                    continue
                error.append(e)
                speed.append(math.hypot(float(row["x speed"]), float(row["y speed"])))
                altitude.append(float(row["altitude"]))
    return dict(error=np.array(error), speed=np.array(speed), altitude=np.array(altitude),
                invalid=invalid, other=other)


def autocovariance(errors: list[np.ndarray], lags: np.ndarray) -> np.ndarray:
    """(len(lags),) the autocovariance of several series at ``lags`` (samples), pooled:
    each series' mean removed, the products of its pairs k apart that are both finite
    summed over every series and divided by their count."""
    total, count = np.zeros(len(lags)), np.zeros(len(lags))
    for e in errors:
        e = e - np.nanmean(e)
        for j, k in enumerate(lags):
            p = e[:len(e) - k] * e[k:]
            total[j] += np.nansum(p)
            count[j] += np.count_nonzero(np.isfinite(p))
    return total / count


def gauss_markov_fit(lags: np.ndarray, covariance: np.ndarray, period: float
                     ) -> tuple[float, float]:
    """(sigma, tau) of c(k) = sigma^2 exp(-k period / tau) through ``covariance`` at
    ``lags`` (least squares on ln c, over the lags where c > 0): sigma in the series'
    unit, tau in s."""
    ok = covariance > 0
    slope, log_a = np.polyfit(lags[ok] * period, np.log(covariance[ok]), 1)
    return math.sqrt(math.exp(log_a)), (-1.0 / slope if slope < 0 else math.inf)


def imu_velocity_changes(mission) -> tuple[np.ndarray, np.ndarray]:
    """For a recorded mission: (P, 3) the DVL's velocity in NED at its pings, moved to
    the IMU (``M v - w x L``, L the DVL's place from the IMU), m/s; and (P, 3) the IMU's
    integral of C f + g - 2 Omega x v from its first sample within the reference to each
    ping, m/s (NaN outside). C: the gyros integrated from the reference's attitude there,
    C_i = C_(i-1) Exp(dt (w_i - C_(i-1)^T Omega)) (``sea_filter.gyro_step``); g: (0, 0,
    the WGS-84 normal gravity at the latitude); v in the Coriolis term: the DVL's NED
    velocity interpolated. Both use the same attitude, so the rotation's errors are the
    IMU's alone."""
    a = mission.attrs
    ti = np.asarray(mission.imu.time, dtype=float)
    f = np.asarray(mission.imu.specific_force, dtype=float)
    w = np.asarray(mission.imu.angular_rate, dtype=float)
    tr = np.asarray(mission.reference.time, dtype=float)
    q = np.asarray(require_attitude(mission), dtype=float)
    start = int(np.searchsorted(ti, tr[0]))
    ti, f, w = ti[start:], f[start:], w[start:]
    omega = earth_rate_ned(float(a["latitude_deg"]))
    c = np.empty((len(ti), 3, 3))
    c[0] = rotation_matrices(quaternions_at(tr, q, ti[:1]))[0]
    for i in range(1, len(ti)):
        c[i] = gyro_step(c[i - 1], ti[i] - ti[i - 1], w[i], omega)
    tp = np.asarray(mission.dvl.time, dtype=float)
    mounting = rotation_rpy(*np.radians(a["dvl_mounting_rpy_deg"]))
    lever = np.asarray(a["dvl_position_body"], float) - np.asarray(a["imu_position_body"], float)
    body = (np.asarray(mission.dvl.velocity_ls, dtype=float) @ mounting.T
            - np.cross(recorded_body_rate(mission, tp), lever))
    at_pings = np.stack([np.interp(tp, ti, c[:, i, j], left=np.nan, right=np.nan)
                         for i in range(3) for j in range(3)], axis=1).reshape(-1, 3, 3)
    ned = np.einsum("pij,pj->pi", at_pings, body)
    have = np.isfinite(ned).all(axis=1)  # the Coriolis term's v: the pings with a velocity
    v = np.stack([np.interp(ti, tp[have], ned[have, i]) for i in range(3)], axis=1)
    g = np.array([0.0, 0.0, normal_gravity(float(a["latitude_deg"]))])
    accel = np.einsum("nij,nj->ni", c, f) + g - 2 * np.cross(omega, v)
    integral = np.concatenate([np.zeros((1, 3)), np.cumsum(
        0.5 * (accel[1:] + accel[:-1]) * np.diff(ti)[:, None], axis=0)])
    return ned, np.stack([np.interp(tp, ti, integral[:, i], left=np.nan, right=np.nan)
                          for i in range(3)], axis=1)


def structure_function(missions, lags) -> np.ndarray:
    """(len(lags),) (m/s)^2, D(k): the mean square per horizontal NED axis of the DVL's
    velocity change over k pings minus the IMU's (``imu_velocity_changes``), each
    mission's mean at each lag removed, pooled over the missions."""
    total, count = np.zeros(len(lags)), np.zeros(len(lags))
    for m in missions:
        dvl, imu = imu_velocity_changes(m)
        for j, k in enumerate(lags):
            d = (dvl[k:] - dvl[:-k] - (imu[k:] - imu[:-k]))[:, :2]
            d = d[np.isfinite(d).all(axis=1)]
            d -= d.mean(axis=0)
            total[j] += np.sum(d**2)
            count[j] += d.size
    return total / count


def predicted_structure(white: float, slow: float, tau: float, lags) -> np.ndarray:
    """(len(lags),) D(k) of white noise ``white`` and a Gauss-Markov error (``slow``,
    ``tau`` s) per axis, at ``lags`` s: 2 white^2 + 2 slow^2 (1 - exp(-k / tau))."""
    k = np.asarray(lags, dtype=float)
    return 2 * white**2 + 2 * slow**2 * (1 - np.exp(-k / tau))


def real_slow_error(akit: Path, white: float) -> tuple[float, float]:
    """Print the real DVL's slow error measured against the reference and against the IMU
    on the A-KIT segments of ``akit`` (the module docstring), beside what the preset's
    model (white per axis ``white`` at 2 m/s) predicts before and after; return the fit
    (sigma m/s, tau s)."""
    from beamsnet.experiments.sea import sea_dataset

    with tempfile.TemporaryDirectory() as tmp, open_dataset(
            sea_dataset(akit, Path(tmp))[0]) as dataset:
        missions = [dataset.missions[name] for name in sorted(dataset.missions)]
        errors = [np.asarray(m.dvl.velocity_ls, dtype=float)[:, axis]
                  - reference_velocity(m, np.asarray(m.dvl.time, dtype=float))[:, axis]
                  for m in missions for axis in (0, 1)]
        lags = np.arange(0, SLOW_FIT_LAGS[-1] + 1)
        c = autocovariance(errors, lags)
        sigma, tau = gauss_markov_fit(SLOW_FIT_LAGS, c[SLOW_FIT_LAGS], 1.0)
        d = structure_function(missions, STRUCTURE_LAGS)
    print(f"\nReal DVL minus reference (both horizontal DVL axes, {len(missions)} segments "
          "pooled), autocovariance c(k), (mm/s)^2:\n")
    print("| k (s) | " + " | ".join(str(k) for k in (0, 1, 2, 3, 5, 10, 15, 20)) + " |")
    print("|---" * 9 + "|")
    print("| c(k) | " + " | ".join(f"{1e6 * c[k]:.1f}" for k in (0, 1, 2, 3, 5, 10, 15, 20))
          + " |")
    print(f"\nFit over lags {SLOW_FIT_LAGS[0]}-{SLOW_FIT_LAGS[-1]} s: slow error sigma "
          f"{1e3 * sigma:.1f} mm/s, tau {tau:.1f} s; what lag 0 adds, "
          f"sqrt(c(0) - sigma^2) = {1e3 * math.sqrt(max(c[0] - sigma**2, 0)):.1f} mm/s "
          "(white noise of the DVL and the reference).")
    models = {"measured against the IMU": d,
              f"white {1e3 * white:.1f} + slow before ({1e3 * SLOW_BEFORE['slow_error_std']:g}"
              f" mm/s, {SLOW_BEFORE['slow_error_time']:g} s)": predicted_structure(
                  white, SLOW_BEFORE["slow_error_std"], SLOW_BEFORE["slow_error_time"],
                  STRUCTURE_LAGS),
              f"white {1e3 * white:.1f} + slow fitted above ({1e3 * sigma:.1f} mm/s, "
              f"{tau:.1f} s)": predicted_structure(white, sigma, tau, STRUCTURE_LAGS)}
    print("\nDVL velocity change minus the IMU's, rms per horizontal axis sqrt(D(k)), mm/s "
          "(the IMU's own drift adds to the measured row):\n")
    print("| | " + " | ".join(f"k = {k} s" for k in STRUCTURE_LAGS) + " |")
    print("|---" * (len(STRUCTURE_LAGS) + 1) + "|")
    for label, row in models.items():
        print(f"| {label} | " + " | ".join(f"{1e3 * math.sqrt(x):.1f}" for x in row) + " |")
    return sigma, tau


def summary(e: np.ndarray) -> str:
    p = np.percentile(e, [1, 5, 50, 95, 99]) * 1e3
    return (f"{1e3 * e.std():.1f} | {1e3 * robust_std(e):.1f} | {1e3 * e.mean():+.1f} | "
            + " / ".join(f"{v:+.0f}" for v in p) + f" | {len(e)}")


def binned(e: np.ndarray, x: np.ndarray, bins, unit: str) -> list[tuple[float, float, int]]:
    """Print the std and robust std of ``e`` per bin of ``x``; return (mean x, std, n)."""
    out = []
    for lo, hi in bins:
        inside = (x >= lo) & (x < hi)
        if inside.sum() < 30:
            continue
        out.append((float(x[inside].mean()), float(e[inside].std()), int(inside.sum())))
        print(f"| {lo:g}-{hi:g} {unit} | {1e3 * e[inside].std():.1f} | "
              f"{1e3 * robust_std(e[inside]):.1f} | {inside.sum()} |")
    return out


def simulate(config: Config, folder: Path, name: str) -> dict[str, np.ndarray]:
    """One run of ``config``: the error velocity of its bottom-track pings without an
    outlier beam, of every finite ping, and the along-track velocity error."""
    path = folder / f"{name}.h5"
    generate(config, path, workers=1, progress=False)
    with open_dataset(path) as dataset:
        mission = next(iter(dataset.missions.values()))
        e = mission.read("dvl/error_velocity")
        mode = mission.read("dvl/mode")
        clean = clean_error_pings(e, mode, mission.read("dvl/status"))
        error = mission.read("dvl/velocity_ls") - mission.read("dvl/velocity")
    finite = np.isfinite(e)
    along = error[np.isfinite(error[:, 0]) & (mode == Mode.BOTTOM_TRACK), 0]
    return dict(clean=e[clean], all=e[finite], along=along)


def budget(config: Config, speed: float, slant_range: float) -> list[tuple[str, float]]:
    """The per-axis velocity error std at ``speed`` (m/s) and ``slant_range`` (m) along
    the DVL's x, m/s, term by term
    (LS over four beams at angle alpha, azimuths 45 deg + k 90 deg): white beam noise
    sigma/(sqrt(2) sin alpha); per-beam scale factors s_std speed/2 (each beam's weight
    cos^2(psi)/(2 ...) sums to a quarter of sum s_k); the sound speed ratio's spread times
    the speed; per-beam biases b_std/(sqrt(2) sin alpha); the slow error's std."""
    c = config.dvl
    sin_a = math.sin(math.radians(c.beam_angle_deg))
    sigma = c.noise_std + c.noise_speed_coeff * speed + c.noise_range_coeff * slant_range
    return [("white beam noise", sigma / (math.sqrt(2) * sin_a)),
            ("scale factors", c.scale_factor_std * speed / 2),
            ("sound speed", c.sound_speed_std * speed),
            ("biases", c.bias_std / (math.sqrt(2) * sin_a)),
            ("slow error (Gauss-Markov)", c.slow_error_std)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=600.0, help="mission length, s")
    parser.add_argument("--seed", type=int, default=0, help="the mission's seed")
    parser.add_argument("--data", type=Path, default=DATA,
                        help="the MissBeamNet logs (default: %(default)s)")
    parser.add_argument("--akit", type=Path, default=AKIT,
                        help="the A-KIT segments (default: %(default)s)")
    args = parser.parse_args()

    after = preset("navigator")
    mission = dataclasses.replace(after.missions[0], seed=args.seed, scenario=dataclasses.replace(
        after.missions[0].scenario, duration=args.duration))
    after = dataclasses.replace(after, missions=(mission,))
    before = dataclasses.replace(after, dvl=dataclasses.replace(after.dvl, **BEFORE))

    print("Error velocity, mm/s: std | robust std (MAD) | mean | percentiles 1/5/50/95/99 | "
          "pings\n")
    print("| | std | robust std | mean | percentiles | pings |\n|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        sims = {name: simulate(config, Path(tmp), name)
                for name, config in (("before", before), ("after", after))}
    for name, sim in sims.items():
        print(f"| sim {name}, bottom track, no outlier | {summary(sim['clean'])} |")
        print(f"| sim {name}, every finite ping | {summary(sim['all'])} |")
    if not (args.data / FILES[0]).exists():
        print(f"\n(no real logs in {args.data}: the real rows are left out)")
        real = None
    else:
        real = read_real(args.data)
        print(f"| real Navigator (Snapir) | {summary(real['error'])} |")
        print(f"\nReal pings dropped: {real['invalid']} invalid (32.768), {real['other']} "
              f"with |error| > {NOT_AN_ERROR_VELOCITY} m/s (not error velocities).")
        e = real["error"] - real["error"].mean()
        lag1 = float(np.mean(e[1:] * e[:-1]) / e.var())
        print(f"Real lag-1 autocorrelation (consecutive kept rows): {lag1:.2f}\n")
        print("| real, by horizontal speed | std | robust std | pings |\n|---|---|---|---|")
        rows = binned(real["error"], real["speed"], SPEED_BINS, "m/s")
        print("\n| real, by altitude | std | robust std | pings |\n|---|---|---|---|")
        binned(real["error"], real["altitude"], ALTITUDE_BINS, "m")
        x, y, n = (np.array(v) for v in zip(*rows, strict=True))
        slope, intercept = np.polyfit(x, y, 1, w=np.sqrt(n))
        sin_a = math.sin(math.radians(after.dvl.beam_angle_deg))
        print(f"\nLine through the speed bins (weights sqrt(pings)): std(e) = "
              f"{1e3 * intercept:.2f} mm/s + {1e3 * slope:.2f} mm/s per m/s; beam noise "
              f"sigma = sqrt(2) sin(alpha) std(e) = {1e3 * math.sqrt(2) * sin_a * intercept:.2f}"
              f" mm/s + {1e3 * math.sqrt(2) * sin_a * slope:.2f} mm/s per m/s "
              f"(preset: {1e3 * after.dvl.noise_std:g} + {1e3 * after.dvl.noise_speed_coeff:g})")

    if (args.akit / "Trajectory1").is_dir():
        white = budget(after, 2.0, SLANT_RANGE)[0][1]
        sigma, tau = real_slow_error(args.akit, white)
        print(f"\nPreset: slow error {1e3 * after.dvl.slow_error_std:g} mm/s over "
              f"{after.dvl.slow_error_time:g} s (fitted: {1e3 * sigma:.1f} mm/s, {tau:.1f} s).")
    else:
        print(f"\n(no A-KIT segments in {args.akit}: the real slow error is left out)")

    print(f"\nVelocity error per axis along track at 2 m/s and {SLANT_RANGE:g} m of slant "
          "range (analytic), mm/s:\n")
    print("| term | before | after |\n|---|---|---|")
    terms = {name: budget(config, 2.0, SLANT_RANGE)
             for name, config in (("before", before), ("after", after))}
    for (label, b), (_, a) in zip(terms["before"], terms["after"], strict=True):
        print(f"| {label} | {1e3 * b:.1f} | {1e3 * a:.1f} |")
    total = {k: math.sqrt(sum(v**2 for _, v in t)) for k, t in terms.items()}
    print(f"| combined | {1e3 * total['before']:.1f} | {1e3 * total['after']:.1f} |")
    print(f"\n(stated: {1e3 * STATED_ACCURACY:g} mm/s.) One simulated mission's along-track "
          f"velocity error RMS, bottom track: before "
          f"{1e3 * np.sqrt(np.mean(sims['before']['along']**2)):.1f} mm/s, after "
          f"{1e3 * np.sqrt(np.mean(sims['after']['along']**2)):.1f} mm/s (one mission: its "
          "per-mission draws make this one sample, see "
          "tests/test_dvl_noise.py for the average).")
    if real is not None:
        lo, hi = min(r[1] for r in rows), max(r[1] for r in rows)
        std = sims["after"]["clean"].std()
        speed = after.missions[0].scenario.speed
        near = np.abs(real["speed"] - speed) < 0.2
        print(f"\nSim after {1e3 * std:.1f} mm/s at {speed:g} m/s; real "
              f"{1e3 * real['error'][near].std():.1f} mm/s within 0.2 m/s of that speed, "
              f"{1e3 * real['error'].std():.1f} over all, {1e3 * lo:.1f}-{1e3 * hi:.1f} over "
              f"the speed bins: {'inside' if lo <= std <= hi else 'OUTSIDE'} the real range.")


if __name__ == "__main__":
    sys.exit(main())
