"""``beamsnet estimate``: one model-based estimator over every ping of a dataset."""

from __future__ import annotations

import csv
import inspect
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import flat

from auvsim.config import DvlConfig, MissionConfig, ScenarioConfig, VehicleConfig
from beamsnet.cli import main
from beamsnet.evaluate import baselines


@pytest.fixture(scope="module")
def turning(dataset_of):
    """A noise-free turn whose beam 0 is dead for the middle 40 s."""
    dvl = DvlConfig(beam_angle_deg=20.0, beam_failures=((0, 40.0, 80.0),))
    turn = MissionConfig(name="turn", seed=0, scenario=ScenarioConfig(
        name="turning_circle", speed=1.5, duration=120.0))
    return dataset_of(flat(turn, dvl=dvl), "turning")


def test_every_estimators_name_has_a_key_of_its_own():
    """Names match on their letters and digits alone (``ins-dvl`` is INS/DVL), so no two
    estimators may share those."""
    from auvsim.checks import loose_key
    from beamsnet.estimators import specs

    keys = [loose_key(s.name) for s in specs() if s.kind != "network"]
    assert len(set(keys)) == len(keys) and loose_key("ins-dvl") == loose_key("INS/DVL")


def test_spec_matches_as_the_command_line_does_and_lists_the_names_it_knows():
    from beamsnet.estimators import spec

    assert spec("ls").name == "LS" and spec("robust-ls").name == "Robust LS"
    assert spec("BeamsNetV2 (seed_0)").name == "v2"  # a table row's
    with pytest.raises(KeyError, match="no estimator 'nope'; expected one of LS, Affine"):
        spec("nope")


@pytest.mark.parametrize("name", ["LS", "beam-calibration", "missing beam ls", "MissingBeam_LS"])
def test_estimate_writes_every_ping_beside_the_truth(turning, tmp_path, name, capsys):
    out = tmp_path / "est"
    assert main(["estimate", str(turning), "--estimator", name, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    rows = list(csv.DictReader((out / "estimates.csv").open()))
    assert summary["pings"] == len(rows) > 100 and summary["availability"] == 1.0
    assert summary["estimator"] in {b.name for b in baselines()}
    pred = np.array([[float(r[k]) for k in ("vx", "vy", "vz")] for r in rows])
    true = np.array([[float(r[k]) for k in ("true_vx", "true_vy", "true_vz")] for r in rows])
    # Noise-free beams, three of them on the dead leg: every one of these is exact.
    np.testing.assert_allclose(pred, true, atol=1e-6)
    # Exact velocities: the dead reckoning is off the truth only by holding each ping's
    # velocity over the 1 s to the next, which on a turn at w turns the track since the
    # turn began by w dt / 2, at most (w dt / 2) (2 v / w) = v dt = 1.5 m off (1.38 m
    # measured); the DVL's own velocity dead-reckoned alike ends where the estimator's
    # does, but for their 1e-6 m/s of difference over 120 s.
    turn = summary["missions"]["turn"]
    assert turn["position"]["final_m"] < 1.5 * 1.0
    assert turn["position"]["final_m"] == pytest.approx(
        turn["baselines"]["DR: DVL + true attitude"]["final_m"], abs=1e-3)
    assert "turn: 100.0 %" in capsys.readouterr().out


def test_an_unknown_estimator_gets_one_line_and_exit_2(turning, tmp_path, capsys):
    out = tmp_path / "est"
    assert main(["estimate", str(turning), "--estimator", "magic", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--estimator" in err and "'LS'" in err
    assert not out.exists()


def test_a_filter_the_file_cannot_feed_is_left_out_with_a_warning(turning, monkeypatch):
    """``evaluate.predictions``: a filter raising an ``AuvsimError`` loses its row and
    says why in one line (``FilterWarning``); a baseline's error is never hidden."""
    import beamsnet.evaluate as evaluate
    from beamsnet.data import DataError, load_windows, split

    class Unfed:
        name = "INS/DVL"

        def fit(self, windows):
            raise DataError("mission turn: no attitude to start from\nthe rest")

    monkeypatch.setattr(evaluate, "filters", lambda dataset, **_: [Unfed()])
    train_w, test_w = split(load_windows(turning))
    with pytest.warns(evaluate.FilterWarning,
                      match="^INS/DVL left out on .*: mission turn: no attitude to start from$"):
        out = evaluate.predictions([], train_w, test_w, dataset=turning)
    assert "INS/DVL" not in out and "LS" in out
    unfed_ls = Unfed()
    unfed_ls.name = "LS"
    monkeypatch.setattr(evaluate, "baselines", lambda: [unfed_ls])
    with pytest.raises(DataError, match="no attitude"):
        evaluate.predictions([], train_w, test_w, dataset=turning)


def test_every_estimator_made_carries_its_specs_name(turning):
    """The tables, the command line and ``estimate`` find what a spec makes by the spec's
    name, so it must carry that name: a model-based estimator, and each filter on a file
    that feeds them."""
    from beamsnet.estimators import specs
    from beamsnet.evaluate import filters

    assert all(s.make().name == s.name for s in specs("model-based"))
    assert sorted(f.name for f in filters(turning)) == sorted(s.name for s in specs("filter"))


class HalfLS:
    """A user's own estimator, outside beamsnet: least squares, halved (an exact known
    answer against the truth of a noise-free file: half of it)."""

    name = "Half LS"

    def fit(self, train):
        return self

    def predict(self, windows):
        from auvsim.data.beams import least_squares

        return 0.5 * least_squares(windows.beams, windows.h)


def half_ls_spec():
    from beamsnet.estimators import Needs, Spec

    return Spec(name="Half LS", title="least squares, halved", kind="model-based",
                needs=Needs(training=False), why="it halves", make=HalfLS, order=999)


def test_a_users_own_estimator_registered_runs_beside_the_others(turning, tmp_path):
    from beamsnet.estimators import Spec, register, spec, specs, unregister
    from beamsnet.evaluate import estimate

    register(half_ls_spec())
    try:
        assert spec("half-ls").name == "Half LS" and specs("model-based")[-1].name == "Half LS"
        summary = estimate("half ls", turning, tmp_path / "est")
        rows = list(csv.DictReader((tmp_path / "est" / "estimates.csv").open()))
        pred = np.array([[float(r[k]) for k in ("vx", "vy", "vz")] for r in rows])
        true = np.array([[float(r[k]) for k in ("true_vx", "true_vy", "true_vz")]
                         for r in rows])
        np.testing.assert_allclose(pred, 0.5 * true, atol=1e-6)
        assert summary["estimator"] == "Half LS"
        with pytest.raises(ValueError, match="'Half LS' is the name of the estimator 'Half LS'"):
            register(half_ls_spec())
        with pytest.raises(ValueError, match="'ls' is the name of the estimator 'LS'"):
            register(Spec(name="ls", title="", kind="model-based", needs=spec("LS").needs,
                          why="", make=HalfLS))
    finally:
        unregister("Half LS")
    assert "Half LS" not in {s.name for s in specs()}


class TwoAxes(HalfLS):
    name = "Two axes"

    def predict(self, windows):
        return super().predict(windows)[:, :2]


def test_a_users_estimator_of_the_wrong_shape_gets_one_line_naming_it(turning, tmp_path,
                                                                     capsys):
    """Its predictions were read as they came, into a traceback three calls on."""
    import dataclasses

    from beamsnet.estimators import register, unregister

    register(dataclasses.replace(half_ls_spec(), name="Two axes", make=TwoAxes))
    try:
        assert main(["estimate", str(turning), "--estimator", "two-axes",
                     "--out", str(tmp_path / "est")]) == 2
    finally:
        unregister("Two axes")
    err = capsys.readouterr().err
    assert err.startswith("beamsnet: error: estimator 'Two axes': its predict returned shape "
                          "(") and err.endswith(", 3), a velocity (m/s, DVL frame) per "
                                                "sample\n") and err.count("\n") == 1, err
    assert not (tmp_path / "est").exists()


def test_an_installed_packages_estimator_reaches_the_command_line(turning, tmp_path):
    """Declared as an entry point of the group beamsnet.estimators (here a package on
    PYTHONPATH with its dist-info), it runs as ``beamsnet estimate --estimator``; one that
    cannot be loaded is one line."""
    site = tmp_path / "site"
    (site / "halfls-0.1.dist-info").mkdir(parents=True)
    (site / "halfls-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: halfls\nVersion: 0.1\n")
    points = site / "halfls-0.1.dist-info" / "entry_points.txt"
    points.write_text("[beamsnet.estimators]\nhalf = halfls:ESTIMATORS\n")
    (site / "halfls.py").write_text(  # the code above, as a package of its own holds it
        "import numpy as np\n" + inspect.getsource(HalfLS) + inspect.getsource(half_ls_spec)
        + "ESTIMATORS = (half_ls_spec(),)\n")

    def run(*args: str) -> subprocess.CompletedProcess:
        env = dict(os.environ, PYTHONPATH=str(site))
        return subprocess.run([sys.executable, "-c", "from beamsnet.console import run; run()",
                               *args], capture_output=True, text=True, env=env, timeout=300)

    done = run("estimate", str(turning), "--estimator", "half-ls", "--out",
               str(tmp_path / "est"))
    assert done.returncode == 0, done.stderr
    assert json.loads((tmp_path / "est" / "summary.json").read_text())["estimator"] == "Half LS"
    points.write_text("[beamsnet.estimators]\nhalf = halfls:NOTHING\n")
    done = run("estimate", str(turning), "--estimator", "LS", "--out", str(tmp_path / "e2"))
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "entry point 'half' (halfls:NOTHING) could not be loaded" in done.stderr


def test_a_water_track_ping_is_no_velocity_over_ground(dataset_of, tmp_path):
    """Lock lost for 20 s over a 0.3 m/s current: the DVL measures the water, which LS
    had scored as the velocity over ground (0.15 m/s RMSE over the mission, and 6 m of
    dead reckoning off at its end). Its pings are estimated by no one, as the filter
    leaves them, and its velocity is held over them."""
    dvl = DvlConfig(lock_loss_intervals=((30.0, 50.0),), water_track=True)
    mission = MissionConfig(name="soft", seed=0, scenario=ScenarioConfig(
        name="straight", speed=1.5, duration=80.0))
    path = dataset_of(flat(mission, dvl=dvl, vehicle=VehicleConfig(current_ned=(0.0, 0.3, 0.0))),
                      "soft")
    out = tmp_path / "ls"
    assert main(["estimate", str(path), "--estimator", "LS", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "estimates.csv").open()))
    t = np.array([float(r["time"]) for r in rows])
    vx = np.array([float(r["vx"]) for r in rows])
    soft = (t >= 30.0) & (t < 50.0)
    assert soft.sum() >= 19 and np.isnan(vx[soft]).all() and np.isfinite(vx[~soft]).all()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["availability"] == pytest.approx(1 - soft.mean())
    soft_run = summary["missions"]["soft"]
    assert soft_run["rmse_vector"] < 1e-6  # noise-free bottom track
    # Held over the gap on a straight line, where the water's velocity had put it 6 m off.
    assert soft_run["position"]["final_m"] < 0.1


def test_the_filter_says_what_noise_it_used_and_when_it_is_too_small(dataset_of, tmp_path,
                                                                      capsys):
    """Its settings in the summary were None wherever the file gave the value: a user
    could not see the noise it used. Each mission's row, and a line, give it; a noise
    set five times too small makes the innovations too large, which the line says."""
    from conftest import zigzag

    path = dataset_of(zigzag(0.01, 120.0), "zz-noise")
    out = tmp_path / "ins"
    assert main(["estimate", str(path), "--estimator", "INS/DVL", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    noise = json.loads((out / "summary.json").read_text())["missions"]["zz"]["noise"]
    assert noise["measurement_std"] == [0.01] * 4
    assert "  noise it used: DVL white 10 mm/s per beam; accelerometer " in said
    assert "likely too small" not in said
    settings = tmp_path / "small.toml"
    settings.write_text("beam_noise_std = 0.002\nbias_time = 500.0\n")
    assert main(["estimate", str(path), "--estimator", "INS/DVL", "--filter-config",
                 str(settings), "--out", str(tmp_path / "small")]) == 0
    said = capsys.readouterr().out
    assert "noise it used: DVL white 2 mm/s per beam" in said
    noise = json.loads((tmp_path / "small" / "summary.json").read_text())["missions"]["zz"][
        "noise"]
    assert noise["slow_error_time"] == 500.0  # the setting's, not the instrument's
    assert "times the size it predicts: the noise it was given (the DVL's white noise " \
        "first) is likely too small for these data" in said


def test_the_fault_sweep_still_reads_water_track_beams(dataset_of):
    """Every ping, with the water-track ping's beams as measured (the fault sweep's reading,
    the default), or NaN (``estimate``'s)."""
    from beamsnet.data import load_windows

    dvl = DvlConfig(lock_loss_intervals=((30.0, 50.0),), water_track=True)
    mission = MissionConfig(name="soft", seed=0, scenario=ScenarioConfig(
        name="straight", speed=1.5, duration=80.0))
    path = dataset_of(flat(mission, dvl=dvl, vehicle=VehicleConfig(current_ned=(0.0, 0.3, 0.0))),
                      "soft")
    kept = load_windows(path, every_ping=True)
    dropped = load_windows(path, every_ping=True, water_track=False)
    soft = (kept.time >= 30.0) & (kept.time < 50.0)
    assert np.isfinite(kept.beams[soft]).all() and np.isnan(dropped.beams[soft]).all()
    np.testing.assert_array_equal(kept.beams[~soft], dropped.beams[~soft])
