"""The IMU's high-frequency content, real against simulated: what the learned noise's
"log rms |f| - g" input sees at sea (``reports/adaptive.md``: 0.026 m/s^2 at sea against
0.0095 in auvsim, its inputs' largest shift, before the ``navigator`` preset's IMU
recorded the Snapir's vibration; 0.016 with it).

For each of the six A-KIT segments (``../shared/data/snapir-akit``, Cohen & Klein 2025:
the Snapir's iXblue Phins at 100 Hz, imported and corrected as ``beamsnet reproduce sea``
does) and for auvsim's ``realistic-maneuvers`` missions (``--sim``, default the file
``reproduce sea`` trains on, ``datasets/sea-train_300s.h5``), per axis:

* the amplitude spectral density of the specific force (ug/sqrt(Hz)) and of the angular
  rate (deg/sqrt(h)) averaged over frequency bands: Welch's method (10 s Hann segments,
  half overlapping, one-sided), on the samples from 100 s to 200 s of each mission;
* the noise one sample holds if it is white: the std of the first differences over
  sqrt(2) (mm/s^2, deg/h);
* the median over 1 s windows of the r.m.s. of |f| - g, the learned noise's input
  (g: the mission's median |f|);
* the std above ``VIBRATION_HZ`` of each axis (a 4th-order Butterworth high-pass run
  forward and back, over the whole mission), and the correlation, over the mission's
  seconds, of the z accelerometer's r.m.s. above it with the mean |yaw rate|;
* over all the missions together, the r.m.s. of that high-passed signal over each second
  against the mean |yaw rate| (gyro z) in it, fitted per axis by least squares as
  ``a + b |r|``: the vibration the ``navigator`` preset's IMU records
  (``ImuConfig.accel_vibration_std`` = a, ``accel_vibration_per_rate`` = b, likewise for
  the gyros; ``auvsim.sensors.imu``'s model of it puts 98.7 % of its power above 10 Hz,
  so its std is what this measures).

Below 1 Hz both hold the vehicle's own motion; above it a navigation-grade IMU's white
noise is what auvsim simulates (the ``navigation-full`` grade: 20 ug/sqrt(Hz), 0.0025
deg/sqrt(h), a one-sided 28 ug/sqrt(Hz) and 0.0035 deg/sqrt(h); the A-KIT log
description states the same for the Phins, from Groves 2013, as the publication gives
none).

What it printed (2026-12-05, before the ``navigator`` preset's vibration): above 10 Hz
the real accelerometers hold 33 to 450 ug/sqrt(Hz) (auvsim: 28), with a line at 24 Hz of
up to 1750 ug/sqrt(Hz) on segments 2-5, and the real gyros 0.02 to 1.0 deg/sqrt(h)
(auvsim: 0.004); one sample holds 18 to 44 mm/s^2 and 53 to 246 deg/h if white (auvsim:
2.0 to 2.5 mm/s^2, 6 to 50 deg/h, the latter its motion). The median r.m.s. of |f| - g
over 1 s is 0.017 to 0.047 m/s^2 at sea and 0.008 to 0.011 in auvsim: the learned noise's
input moved because the real IMU records what the simulated one did not. Above 10 Hz the
real segments' median std per axis is 20.0 / 29.3 / 27.6 mm/s^2 and 138 / 136 / 45 deg/h
(auvsim then: 1.7 and 1.3 to 1.8).

Whether that content is noise an INS must distrust or vibration that integrates away, the
DVL answers: the DVL's velocity change over 1 s minus the IMU's integral of it is 7.0 mm/s
r.m.s. per horizontal axis, less than the DVL's own error model predicts (7.8;
``benchmarks/dvl_error.py``); a white noise of 20 mm/s^2 per sample at 100 Hz would add 2
mm/s to it in quadrature. So the ``navigator`` preset's IMU records it as a vibration with
no power at zero frequency (``auvsim.sensors.imu``, ``auvsim.runs.presets
.SNAPIR_VIBRATION``), of the size measured here, and the filter's IMU noise stays the
datasheet's.

The real content is not steady: per second it follows the yaw rate (correlation 0.84 to
0.91 per segment on the z accelerometer), from 6 to 10 mm/s^2 in straight flight to about
100 in the hardest turns: the fit gives 8.6 / 10.1 / 6.3 mm/s^2 + 183 / 345 / 355 mm/s^2
per rad/s and 83 / 32 / 23 deg/h + 1037 / 1570 / 390 deg/h per rad/s (r^2 0.62 to 0.75),
which the ``navigator`` preset takes (``SNAPIR_VIBRATION``). A steady vibration of the
median std (tried first) left the learned noise's input further off than before, narrow
where the real one is wide: 67 % of the recorded pings outside its simulated range (32 %
without vibration); with the line, 13.5 % (``reports/adaptive.md``). The simulated
missions give the line back (8.6 / 10.1 / 6.4 mm/s^2 + 180 / 341 / 351 per rad/s, 82 / 32 /
23 deg/h + 1029 / 1549 / 387) but turn less than the segments, so over a whole mission
they hold less of it: std above 10 Hz 9 to 13 / 12 to 19 / 8 to 18 mm/s^2 against the
segments' 17 to 27 / 26 to 45 / 23 to 42.

    PYTHONPATH=.:benchmarks .venv/bin/python benchmarks/imu_spectrum.py [--akit DIR]
        [--sim FILE]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import signal
from sea_filter import DATA

from auvsim.data.reader import open_dataset

RATE = 100.0  # Hz, both IMUs
SPAN = (10_000, 20_000)  # samples: 100 s to 200 s of a mission
SEGMENT = 1000  # samples per Welch segment (10 s)
BANDS = ((0.1, 1.0), (1.0, 5.0), (5.0, 10.0), (10.0, 20.0), (20.0, 30.0), (30.0, 40.0),
         (40.0, 50.0))  # Hz
G0 = 9.80665  # m/s^2 per g
SIM = Path("datasets/sea-train_300s.h5")
VIBRATION_HZ = 10.0  # Hz: above it, the vibration's std


def band_asd(x: np.ndarray) -> list[float]:
    """The amplitude spectral density of ``x`` (sampled at ``RATE``) averaged (in power)
    over each of ``BANDS``, in x's unit per sqrt(Hz): scipy's Welch (Hann segments of
    ``SEGMENT`` samples, half overlapping, each less its mean, one-sided)."""
    f, p = signal.welch(x, fs=RATE, nperseg=SEGMENT)
    return [math.sqrt(float(np.mean(p[(f >= lo) & (f < hi)]))) for lo, hi in BANDS]


def figures(mission) -> dict:
    """One mission's figures (the module docstring); ``seconds`` holds its
    ``per_second`` arrays, for ``vibration_fit``."""
    f = np.asarray(mission.imu.specific_force, dtype=float)
    w = np.asarray(mission.imu.angular_rate, dtype=float)
    span = slice(*SPAN)
    norm = np.linalg.norm(f, axis=1)
    excess = norm - np.median(norm)
    windows = excess[:len(excess) // 100 * 100].reshape(-1, 100)
    f_high, w_high = high_passed(f), high_passed(w)
    seconds = _per_second(f_high, w_high, w)
    return dict(
        accel=np.array([band_asd(f[span, k]) for k in range(3)]) / (G0 * 1e-6),
        gyro=np.degrees(np.array([band_asd(w[span, k]) for k in range(3)])) * 60.0,
        accel_white=1e3 * np.diff(f, axis=0).std(axis=0) / math.sqrt(2),
        gyro_white=np.degrees(np.diff(w, axis=0).std(axis=0) / math.sqrt(2)) * 3600.0,
        rms=float(np.median(np.sqrt(np.mean(windows**2, axis=1)))),
        accel_above=1e3 * f_high.std(axis=0), gyro_above=np.degrees(w_high.std(axis=0)) * 3600.0,
        turning=float(np.corrcoef(seconds[0][:, 2], seconds[2])[0, 1]), seconds=seconds)


def high_passed(x: np.ndarray) -> np.ndarray:
    """``x`` (samples, sampled at ``RATE``) above ``VIBRATION_HZ``: a 4th-order Butterworth
    high-pass, forward and back (no phase shift)."""
    sos = signal.butter(4, VIBRATION_HZ, btype="high", fs=RATE, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


def per_second(mission) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per whole second of a mission's IMU: (S, 3) the r.m.s. of the specific force above
    ``VIBRATION_HZ`` (m/s^2), (S, 3) of the angular rate (rad/s), and (S,) the mean
    |yaw rate| (rad/s)."""
    f = np.asarray(mission.imu.specific_force, dtype=float)
    w = np.asarray(mission.imu.angular_rate, dtype=float)
    return _per_second(high_passed(f), high_passed(w), w)


def _per_second(f_high: np.ndarray, w_high: np.ndarray, w: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``per_second`` from the high-passed specific force and rate and the rate."""
    second = int(RATE)
    n = second * (len(w) // second)

    def rms(x):
        return np.sqrt(np.mean(x[:n].reshape(-1, second, 3) ** 2, axis=1))

    return rms(f_high), rms(w_high), np.abs(w[:n, 2]).reshape(-1, second).mean(axis=1)


def vibration_fit(seconds) -> dict[str, np.ndarray]:
    """Over every second of several missions together (``seconds``: each one's
    ``per_second``), per axis, least squares of the r.m.s. above ``VIBRATION_HZ`` on the
    mean |yaw rate|, ``a + b |r|``: the accelerometers' a (m/s^2) and b (m/s^2 per rad/s),
    the gyros' a (rad/s) and b (rad/s per rad/s), and the fits' r^2."""
    parts = list(seconds)
    rate = np.concatenate([p[2] for p in parts])
    design = np.stack([np.ones_like(rate), rate], axis=1)
    out = {}
    for k, name in enumerate(("accel", "gyro")):
        y = np.concatenate([p[k] for p in parts])
        coef = np.linalg.lstsq(design, y, rcond=None)[0]
        out[f"{name}_std"], out[f"{name}_per_rate"] = coef
        out[f"{name}_r2"] = 1.0 - (y - design @ coef).var(axis=0) / y.var(axis=0)
    return out


def fit_line(label: str, fit: dict) -> str:
    """``vibration_fit``'s line, printed in mm/s^2 and deg/h."""
    deg_h = np.degrees(1.0) * 3600.0
    return (f"{label}: above {VIBRATION_HZ:g} Hz, r.m.s. per second = a + b |yaw rate|: accel "
            f"a {fmt(1e3 * fit['accel_std'])} mm/s^2, b {fmt(1e3 * fit['accel_per_rate'])} "
            f"mm/s^2 per rad/s (r^2 {fmt(fit['accel_r2'], 2)}); gyro a "
            f"{fmt(deg_h * fit['gyro_std'])} deg/h, b {fmt(deg_h * fit['gyro_per_rate'])} "
            f"deg/h per rad/s (r^2 {fmt(fit['gyro_r2'], 2)})")


def table(name: str, found: dict) -> list[str]:
    bands = " ".join(f"{lo:g}-{hi:g}" for lo, hi in BANDS)
    out = [f"{name}: ASD per band (Hz: {bands}); white per sample; median rms |f| - g "
           f"{found['rms']:.4f} m/s^2"]
    for k, axis in enumerate("xyz"):
        out.append(f"  accel {axis} ug/sqrt(Hz): "
                   + " ".join(f"{v:7.0f}" for v in found["accel"][k])
                   + f"   | {found['accel_white'][k]:6.2f} mm/s^2 per sample")
    for k, axis in enumerate("xyz"):
        out.append(f"  gyro {axis} deg/sqrt(h):  "
                   + " ".join(f"{v:7.3f}" for v in found["gyro"][k])
                   + f"   | {found['gyro_white'][k]:6.1f} deg/h per sample")
    out.append(f"  above {VIBRATION_HZ:g} Hz: accel {fmt(found['accel_above'])} mm/s^2, "
               f"gyro {fmt(found['gyro_above'])} deg/h; per second, accel z's r.m.s. "
               f"against |yaw rate|: correlation {found['turning']:.2f}")
    return out


def fmt(v, digits: int = 1) -> str:
    """Numbers joined by " / " with ``digits`` decimals."""
    return " / ".join(f"{x:.{digits}f}" for x in v)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--akit", type=Path, default=DATA, help="the A-KIT folder")
    parser.add_argument("--sim", type=Path, default=SIM,
                        help="a realistic-maneuvers file (default: %(default)s)")
    args = parser.parse_args(argv)
    lines = []
    if (args.akit / "Trajectory1").is_dir():
        from beamsnet.experiments.sea import sea_dataset

        with tempfile.TemporaryDirectory() as tmp, open_dataset(
                sea_dataset(args.akit, Path(tmp))[0]) as real:
            found = [figures(real.missions[name]) for name in sorted(real.missions)]
            for name, f in zip(sorted(real.missions), found, strict=True):
                lines += table(f"real {name}", f)
            lines.append(f"real, median over the segments, above {VIBRATION_HZ:g} Hz: accel "
                         f"{fmt(np.median([f['accel_above'] for f in found], axis=0))} "
                         f"mm/s^2, gyro "
                         f"{fmt(np.median([f['gyro_above'] for f in found], axis=0))} deg/h")
            lines.append(fit_line("real, the segments together",
                                  vibration_fit(f["seconds"] for f in found)))
    else:
        lines.append(f"(no A-KIT segments in {args.akit}: the real rows are left out)")
    if args.sim.is_file():
        with open_dataset(args.sim) as sim:
            found = {name: figures(sim.missions[name]) for name in sorted(sim.missions)}
            for name in list(found)[:6]:
                lines += table(f"auvsim {name}", found[name])
            lines.append(fit_line("auvsim, every mission together",
                                  vibration_fit(f["seconds"] for f in found.values())))
    else:
        lines.append(f"(no {args.sim}: run beamsnet reproduce sea to make it)")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
