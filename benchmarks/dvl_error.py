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
settings), one mission's along-track velocity error (velocity_ls - velocity), and how fast
the real DVL's velocity error decorrelates: the along-track difference between the DVL
and the reference's velocity in the body frame (``../shared/data/snapir-akit``, Cohen &
Klein 2025; the reference's NED velocity turned by its roll, pitch and yaw), its std and
autocorrelation, on each 400 s segment. That difference holds the reference's own errors
and the lever arm's and clocks' effects too (none removed here): an upper bound on the
DVL's, and an estimate of its correlation time.

    .venv/bin/python benchmarks/dvl_error.py [--duration 600] [--seed 0] [--data DIR]
        [--akit DIR]
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
from turning import body_velocity

from auvsim.config import Config
from auvsim.data.reader import open_dataset
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
from auvsim.sensors.dvl import Mode, clean_error_pings

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


def read_csv(path: Path) -> np.ndarray:
    """A numeric CSV with one header line, as an (n, columns) array."""
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def along_track_difference(folder: Path, k: int) -> np.ndarray:
    """(n,) DVL x minus the reference's body-frame x velocity, m/s, of segment k."""
    dvl = read_csv(folder / f"Trajectory{k}" / f"DVL_trajectory{k}.csv")
    ref = read_csv(folder / f"Trajectory{k}" / f"GT_trajectory{k}.csv")
    return dvl[:, 1] - body_velocity(ref)[:, 0]


def autocorrelation(x: np.ndarray, lag: int) -> float:
    x = x - x.mean()
    return float(np.mean(x[lag:] * x[:len(x) - lag]) / x.var())


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
        print("\nReal DVL minus reference, along track (m/s), by segment: std, "
              "autocorrelation at lags 1, 2, 5 s, and tau = -1 s / ln(r(1)):\n")
        print("| segment | std (mm/s) | r(1) | r(2) | r(5) | tau (s) |\n|---|---|---|---|---|---|")
        for k in range(1, 7):
            d = along_track_difference(args.akit, k)
            r = [autocorrelation(d, lag) for lag in (1, 2, 5)]
            print(f"| {k} | {1e3 * d.std():.1f} | {r[0]:.2f} | {r[1]:.2f} | {r[2]:.2f} | "
                  f"{-1.0 / math.log(r[0]):.1f} |")

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
