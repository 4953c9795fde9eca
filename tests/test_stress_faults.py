"""``beamsnet stress --faults``: estimators on pings with missing beams, the held dead
reckoning, every-ping windows, and the sweep end to end at a tiny size."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from auvsim.cli import main as auvsim_main
from auvsim.sensors.dvl import beam_matrix
from beamsnet.cli import main
from beamsnet.data import Windows, load_windows
from beamsnet.estimators import specs
from beamsnet.estimators.baselines import KalmanFilter
from beamsnet.estimators.networks import BeamsNetV2
from beamsnet.evaluate import baselines
from beamsnet.experiments.faults import SWEEPS, _estimates, sweeps
from beamsnet.navigation import held

# A filter that trains on the missions of the file it runs on: the test data here are
# another file than the training data, so it is left out (with a warning saying why).
FILTERS = {s.name for s in specs("filter")} - {"INS/DVL (learned noise)"}

TINY = ["stress", "--faults", "--train-duration", "60", "--fault-duration", "30",
        "--fault-mission", "straight", "--epochs", "1", "--average-epochs", "1",
        "--out", "reports", "--quiet"]


def _windows(n: int = 40, seed: int = 0, noise: float = 0.0) -> Windows:
    """Windows of one mission: beams = H v + noise (m/s), a slowly varying v."""
    rng = np.random.default_rng(seed)
    h = beam_matrix(math.radians(20.0))
    v = np.array([2.0, 0.0, 0.1]) + np.cumsum(rng.normal(0, 0.01, (n + 3, 3)), axis=0)
    beams = v @ h.T + rng.normal(0, noise, (n + 3, 4))
    return Windows(beams=beams[3:], past_beams=np.stack([beams[k:k + 3] for k in range(n)]),
                   accel=None, gyro=None, target=v[3:], velocity_ls=v[3:],
                   mission=np.zeros(n, dtype=np.int64), time=np.arange(3.0, n + 3),
                   names=("m",), h=h)


def _dropped(w: Windows, pings: list[int], beam: int = 0) -> Windows:
    """``w`` with ``beam`` lost (NaN) on ``pings``, in the current and the past beams."""
    beams = w.beams.copy()
    beams[pings, beam] = np.nan
    past = w.past_beams.copy()
    for k in pings:  # ping k is the past of pings k+1 .. k+3
        for lag in range(1, 4):
            if k + lag < len(w.target):
                past[k + lag, 3 - lag, beam] = np.nan
    return w._replace(beams=beams, past_beams=past)


def test_held_fills_a_gap_with_the_last_estimate_and_the_start_before_the_first():
    """Before its first estimate the navigator holds the velocity it started with, the
    target's at the mission's first sample (each mission its own), as the INS/DVL filter
    starts from the truth's state."""
    w = _windows(6)._replace(mission=np.array([0, 0, 0, 0, 1, 1]))
    w = w._replace(target=np.arange(18.0).reshape(6, 3) + 10.0)
    pred = np.array([[np.nan] * 3, [1.0, 0, 0], [np.nan] * 3, [3.0, 0, 0],
                     [np.nan] * 3, [5.0, 0, 0]])
    filled = held(w, pred)
    np.testing.assert_array_equal(filled[:, 0], [10, 1, 1, 3, 22, 5])
    np.testing.assert_array_equal(filled[0], w.target[0])
    np.testing.assert_array_equal(filled[4], w.target[4])


def test_each_estimator_on_pings_with_a_lost_beam():
    """LS solves the three beams left exactly; the affine map gives none; the Kalman filter
    holds its estimate; BeamsNetV2 gives none while the beam is missing from its past."""
    from beamsnet.estimators.baselines import AffineCalibration, LeastSquares

    train = _windows(200, seed=1, noise=0.002)
    w = _dropped(_windows(40), [10, 11, 25])
    baselines = [b.fit(train) for b in (LeastSquares(), AffineCalibration(), KalmanFilter())]
    checkpoint = {"model": "v2", "train_config": {"n_past": 3}}
    from pathlib import Path

    out = _estimates(baselines, [(Path("v2"), BeamsNetV2(), checkpoint)], w)
    lost = np.zeros(40, dtype=bool)
    lost[[10, 11, 25]] = True
    np.testing.assert_allclose(out["LS"], w.target, atol=1e-12)  # noise-free: exact
    assert np.isnan(out["Affine"][lost]).all() and np.isfinite(out["Affine"][~lost]).all()
    kf = out["KF"]
    assert np.isfinite(kf).all()
    np.testing.assert_array_equal(kf[10], kf[9])  # a prediction step holds the estimate
    np.testing.assert_array_equal(kf[11], kf[9])
    v2 = out["BeamsNetV2 (v2)"]
    gone = np.zeros(40, dtype=bool)
    for k in (10, 11, 25):
        gone[k:k + 4] = True
    assert np.isnan(v2[gone]).all() and np.isfinite(v2[~gone]).all()


def test_kalman_filter_has_no_estimate_before_the_first_measurement():
    w = _windows(30)
    kf = KalmanFilter(calibrate=False).fit(_windows(200, seed=1, noise=0.002))
    beams = w.beams.copy()
    beams[:4] = np.nan
    pred = kf.predict(w._replace(beams=beams))
    assert np.isnan(pred[:4]).all() and np.isfinite(pred[4:]).all()
    # The first measurement starts the filter, as the first ping does without a gap.
    np.testing.assert_allclose(pred[4], w.target[4], atol=1e-12)


def test_every_ping_windows_keep_lost_beams_as_nan_and_water_track_out_of_training(
        tmp_path):
    """A dead beam is NaN in the every-ping windows and keeps its pings out of the
    samples; water-track pings keep their beams there and are never samples."""
    import dataclasses

    from auvsim.runs.generate import generate
    from auvsim.runs.presets import preset

    base = preset("paper-sim").with_duration(40)
    config = dataclasses.replace(
        base, missions=base.missions[1:2], dvl=dataclasses.replace(
            base.dvl, water_track=True, lock_loss_intervals=((10.0, 20.0),),
            beam_failures=((1, 25.0, 30.0),)))
    path = tmp_path / "faulty.h5"
    generate(config, path, progress=False)
    every = load_windows(path, every_ping=True)
    samples = load_windows(path)
    t = every.time
    water = (t >= 10) & (t < 20)
    dead = (t >= 25) & (t < 30)
    assert np.isfinite(every.beams[water]).all()  # water track: measured, relative to water
    assert np.isnan(every.beams[dead, 1]).all() and np.isfinite(every.beams[~dead]).all()
    # A sample needs its ping and its 3 past pings in bottom track with every beam.
    touched = [(s >= 10 and s < 23) or (s >= 25 and s < 33) for s in t]
    np.testing.assert_array_equal(samples.time, t[~np.array(touched)])


def test_every_ping_windows_equal_the_samples_on_a_clean_file(tmp_path):
    path = tmp_path / "line.h5"
    assert auvsim_main(["generate", "--preset", "paper-sim", "--duration", "30",
                        "--out", str(path), "--quiet"]) == 0
    a, b = load_windows(path), load_windows(path, every_ping=True)
    for field in ("beams", "past_beams", "target", "accel", "time", "mission"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_every_sweep_has_its_settings_in_the_config():
    plan = sweeps(300.0)
    assert list(plan) == list(SWEEPS)
    assert [f.level for f in plan["dropout"]] == [0.0, 0.1, 0.2, 0.3, 0.5]
    from auvsim.runs.presets import maneuvers

    base = maneuvers(300.0)
    dead = plan["dead beam"][-1].config(base)
    assert dead.dvl.beam_failures == ((0, 0.0, 300.0),)
    water = plan["water track"][1].config(base)
    assert water.dvl.water_track and water.dvl.lock_loss_intervals == ((112.5, 187.5),)
    assert water.vehicle.current_ned == (0.0, 0.3, 0.0)
    assert plan["dropout"][0].config(base) == base  # the clean setting changes nothing


@pytest.mark.parametrize("flags, named", [
    (["--fault-duration", "5"], "--fault-duration"),
    (["--fault-duration", "nan"], "--fault-duration"),
    (["--fault-mission", "nope"], "--fault-mission"),
    (["--fault-mission", "straight", "--fault-mission", "straight"], "--fault-mission"),
    (["--maneuvers", "x.h5"], "--maneuvers"),
    (["--no-faults", "--fault-duration", "60"], "--fault-duration"),
    (["--no-faults", "--fault-mission", "straight"], "--fault-mission"),
])
def test_bad_fault_options_get_one_line_and_exit_2(tmp_path, monkeypatch, capsys, flags,
                                                   named):
    monkeypatch.chdir(tmp_path)
    faults = [] if flags[0] == "--no-faults" else ["--faults"]
    assert main(["stress", *faults, "--quiet", *[f for f in flags if f != "--no-faults"]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []  # nothing generated, trained or written


@pytest.mark.slow
def test_fault_sweep_writes_its_table_for_every_setting(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(TINY) == 0
    # The learned noise is left out once for the run, not once per file (17 of them).
    left = [line for line in capsys.readouterr().err.splitlines()
            if "INS/DVL (learned noise) left out" in line]
    assert len(left) == 1 and left[0].endswith("(and on 16 more of its files)"), left
    assert "the training windows are of another (their mission 'speed_1' is not in it)" \
        in left[0]
    out = tmp_path / "reports"
    summary = json.loads((out / "faults.json").read_text())
    assert list(summary["sweeps"]) == list(SWEEPS)
    assert summary["missions"] == ["straight"]
    assert "paper-sim_60s" in summary["train_data"]
    report = (out / "faults.md").read_text()
    names = {b.name for b in baselines()} | FILTERS | {
            "BeamsNetV1 (v1)", "BeamsNetV2 (v2)", "BeamsNetV2M (v2m)", "CorrectionNet (corr)"}
    for sweep, rows in summary["sweeps"].items():
        assert len(rows) == len(sweeps(30.0)[sweep])
        for row in rows:
            assert set(row["estimators"]) == names
            assert f"| {row['label']} |" in report
            for c in row["estimators"].values():
                assert 0 <= c["availability"] <= 1
                assert c["availability"] == 0 or np.isfinite(c["rmse_vector"])
    assert (out / "faults.png").stat().st_size > 20_000
    # The faults reach the table: LS solves the three beams a dead beam leaves, the
    # affine map cannot and says so; dropouts cost every estimator availability.
    dead = summary["sweeps"]["dead beam"][-1]["estimators"]
    assert dead["LS"]["availability"] == 1 and dead["Affine"]["availability"] == 0
    assert "n/a: needs 4 beams |" in report and "n/a: needs 4 beams on 4 pings" in report
    worst = summary["sweeps"]["dropout"][-1]["estimators"]
    bridging = {"KF", "KF (beam calibration)", "Missing-beam LS"} | FILTERS  # no gaps
    assert all(c["availability"] < 1 for n, c in worst.items() if n not in bridging)
    assert all(worst[n]["availability"] > worst["LS"]["availability"] for n in bridging)
    assert worst["BeamsNetV2 (v2)"]["availability"] <= worst["LS"]["availability"]
    assert not (out / "stress.md").exists()  # the manoeuvre report is another run's
    # One file per distinct setting (20 % dropout in bursts of 5 is in two sweeps).
    files = sorted((tmp_path / "datasets" / "faults").glob("*.h5"))
    assert len(files) == len({r["dataset"] for rows in summary["sweeps"].values()
                              for r in rows}) == 17
    # The combined setting's dead reckoning, per mission, for every estimator.
    combined = summary["sweeps"]["dropout + dead beam"][-1]
    assert "### Dead reckoning per mission: " + combined["label"] in report
    for c in combined["estimators"].values():
        assert c["availability"] == 0 or set(c["dr_missions"]) == {"straight"}


def test_the_rows_worse_than_ls_are_counted_over_the_distinct_settings():
    """The clean setting starts several sweeps and one dropout setting is in two: each is
    one setting, named by its first row, for the list of rows worse than LS as for the
    findings' counts (the report had counted 20 rows of its 17 settings)."""
    from beamsnet.experiments.faults import _distinct

    clean, shared, other = {"LS": 1}, {"LS": 2}, {"LS": 3}
    sweeps = {"dropout": [dict(dataset="clean.h5", label="none", estimators=clean),
                          dict(dataset="d20.h5", label="20 %", estimators=shared)],
              "burst": [dict(dataset="d20.h5", label="20 %, bursts of 5", estimators=shared),
                        dict(dataset="b20.h5", label="bursts of 20", estimators=other)],
              "outliers": [dict(dataset="clean.h5", label="none", estimators=clean)]}
    assert _distinct(sweeps) == {"none (dropout)": clean, "20 % (dropout)": shared,
                                 "bursts of 20 (burst)": other}
