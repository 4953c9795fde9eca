"""Whether ``auvsim check-log``'s standard errors for the DVL's scale and mounting hold:
found minus true, over the standard error it reports, on simulated missions whose DVL
errors are known, with its serial errors as they are (the larger of Newey-West's and a
slow error's of ``NAVIGATOR_SLOW_ERROR_TIME``) and with Newey-West's alone, side by side.

The missions: the ``navigator`` preset's sensors (beam scale factors, biases, sound speed,
misalignment, white beam noise, and the slow error of 9 mm/s over 19 s), ``--missions``
seeds each of a 300 s zigzag and a 300 s random-waypoints run. Each becomes a log as
``tests/test_checklog.py`` makes them: the truth at 1 Hz is the reference, the IMU and the
DVL's least-squares velocity are the streams, no fault injected.

What check-log estimates is the DVL's error as a scale and a small rotation; a DVL's four
beams with their own scale factors make a map that is not only that, so "true" here is
what the fit would give without noise: the scale and rotation nearest, over the mission's
own velocities, to the map the simulator drew (``H^+ diag((1 + s_k) / c) H M^T``, its
beam bias's velocity added). A standard error that holds gives a root mean square of
(found - true) / SE near 1 (near 1.13 for Student's t of 9 degrees of freedom).

    python benchmarks/checklog_errors.py [--missions 8]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

import auvsim.data.checklog as checklog
from auvsim.config import MissionConfig, ScenarioConfig
from auvsim.data.reader import open_dataset
from auvsim.physics.frames import rotation_matrices, rotation_rpy, skew
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
from auvsim.sensors.dvl import beam_matrix


def as_log(m) -> checklog.Log:
    """The simulated mission as a recorded log: the truth at 1 Hz as the reference."""
    t = np.asarray(m.truth.time)
    step = slice(0, None, int(round(1.0 / float(np.median(np.diff(t))))))
    return checklog.Log(
        t[step], np.asarray(m.truth.velocity_ned)[step], np.asarray(m.truth.quaternion)[step],
        np.asarray(m.truth.position_ned)[step], np.asarray(m.imu.time),
        np.asarray(m.imu.specific_force), np.asarray(m.imu.angular_rate),
        np.asarray(m.dvl.time), np.asarray(m.dvl.velocity_ls), gravity=m.attrs["gravity"])


def nearest_truth(m) -> np.ndarray:
    """[scale - 1, roll, pitch, yaw (deg)]: the fit's noise-free answer (module docstring)."""
    a = m.attrs
    h = beam_matrix(np.radians(a["beam_angle_deg"]))
    ratio = a["dvl_sound_speed_ratio"]
    drawn = (np.linalg.pinv(h) @ np.diag((1 + np.asarray(a["dvl_scale_factor"])) / ratio) @ h
             @ rotation_rpy(*np.radians(a["dvl_misalignment_rpy_deg"])).T - np.eye(3))
    bias = np.linalg.pinv(h) @ (np.asarray(a["dvl_bias"]) / ratio)
    u = np.einsum("nji,nj->ni", rotation_matrices(m.truth.quaternion), m.truth.velocity_ned)
    design = np.concatenate([u[:, :, None], skew(u)], axis=2).reshape(-1, 4)
    x, *_ = np.linalg.lstsq(design, (u @ drawn.T + bias).ravel(), rcond=None)
    return np.r_[x[0], np.degrees(x[1:])]


def found(m, name: str) -> tuple[np.ndarray, np.ndarray]:
    f = {x.name: x.value for x in checklog.check_arrays(as_log(m), name).findings}
    return (np.r_[f["dvl scale"]["scale"] - 1, f["dvl mounting"]["rpy_deg"]],
            np.r_[f["dvl scale"]["se"], f["dvl mounting"]["se_deg"]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--missions", type=int, default=8, help="seeds per scenario")
    args = parser.parse_args()
    missions = tuple(
        MissionConfig(name=f"{kind}_{seed}", seed=seed,
                      scenario=ScenarioConfig(name=kind, duration=300.0))
        for kind in ("zigzag", "random_waypoints") for seed in range(3, 3 + args.missions))
    newey_west = checklog.serial_least_squares

    def newey_west_alone(a, b, times=None, correlation_time=None):
        return newey_west(a, b)

    z = {"as it is": [], "Newey-West alone": []}
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "sim.h5"
        generate(dataclasses.replace(preset("navigator"), missions=missions), path,
                 progress=False)
        with open_dataset(path) as ds:
            for name in ds.missions:
                m = ds.missions[name]
                truth = nearest_truth(m)
                for label in z:
                    checklog.serial_least_squares = (newey_west if label == "as it is"
                                                     else newey_west_alone)
                    x, se = found(m, name)
                    z[label].append((x - truth) / se)
    checklog.serial_least_squares = newey_west
    print(f"{len(missions)} missions of 300 s; (found - true) / SE: root mean square, "
          "largest |.|")
    print(f"{'standard errors':18s} {'scale':>12s} {'roll':>12s} {'pitch':>12s} {'yaw':>12s}")
    for label, rows in z.items():
        rows = np.array(rows)
        rms, most = np.sqrt((rows ** 2).mean(axis=0)), np.abs(rows).max(axis=0)
        cells = [f"{r:5.2f} {m:5.1f}" for r, m in zip(rms, most, strict=True)]
        print(f"{label:18s} " + " ".join(f"{c:>12s}" for c in cells))


if __name__ == "__main__":
    main()
