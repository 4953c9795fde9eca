"""The experiment runner: datasets made once, models trained once from a few seeds and
the best kept, a diverged seed dropped."""

from __future__ import annotations

import dataclasses
import json
import math
import os

import h5py
import pytest
from conftest import flat, mission

import beamsnet.training.runs
from auvsim.config import DvlConfig
from auvsim.data.reader import read_attrs
from auvsim.errors import ConfigError
from auvsim.runs.generate import config_sha256
from beamsnet.experiments import runner
from beamsnet.experiments.runner import (
    ReplacedRunWarning,
    StaleDatasetWarning,
    ensure_dataset,
    train_runs,
)
from beamsnet.training.checkpoints import load
from beamsnet.training.config import TrainConfig
from beamsnet.training.train import DivergedError

TWO_LINES = flat(mission("a", 1, speed=2.0, duration=90.0, start_speed=0.0),
                 mission("b", 2, speed=1.0, duration=90.0, start_speed=0.0),
                 dvl=DvlConfig(beam_angle_deg=20.0, scale_factor=0.05))


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return ensure_dataset(TWO_LINES, tmp_path_factory.mktemp("exp") / "datasets" / "two.h5",
                          progress=False)


def _diverging(seeds):
    """``train``, except that the seeds in ``seeds`` diverge."""
    real = beamsnet.training.runs.train

    def train(dataset, config, out, *, progress=True):
        if config.seed in seeds:
            raise DivergedError(f"0.01: seed {config.seed} diverged", argument="lr")
        return real(dataset, config, out, progress=progress)
    return train


def test_ensure_dataset_generates_only_a_missing_file(data):
    root, missions = read_attrs(data)
    assert sorted(missions) == ["a", "b"] and root["config_json"] == TWO_LINES.to_json()
    stamp = data.stat().st_mtime_ns
    assert ensure_dataset(TWO_LINES, data, progress=False) == data
    assert data.stat().st_mtime_ns == stamp


def test_ensure_dataset_regenerates_a_file_made_from_another_config(tmp_path):
    path = tmp_path / "one.h5"
    before = flat(mission("a", 1, speed=1.0, duration=20.0, start_speed=0.0))
    ensure_dataset(before, path, progress=False)
    # The preset changed: another speed, and one more mission.
    after = flat(mission("a", 1, speed=1.5, duration=20.0, start_speed=0.0),
                 mission("b", 2, speed=1.0, duration=20.0, start_speed=0.0))
    with pytest.warns(StaleDatasetWarning) as said:
        assert ensure_dataset(after, path, progress=False) == path
    assert [str(w.message) for w in said] == [
        f"{path}: it was made from another config (missions a, added b); generating it "
        "again"]
    root, missions = read_attrs(path)
    assert root["config_json"] == after.to_json() and sorted(missions) == ["a", "b"]
    # Another DVL: the section is named.
    dvl = dataclasses.replace(after, dvl=DvlConfig(scale_factor=0.01))
    with pytest.warns(StaleDatasetWarning, match=r"another config \(dvl\); generating"):
        ensure_dataset(dvl, path, progress=False)
    # A file that is not a dataset is replaced too, saying so.
    path.write_text("not HDF5")
    with pytest.warns(StaleDatasetWarning, match="it is not a readable dataset"):
        ensure_dataset(dvl, path, progress=False)
    assert read_attrs(path)[0]["config_json"] == dvl.to_json()
    # Another program's HDF5 file is not deleted: generate refuses it, as it refuses a
    # user's other file.
    foreign = tmp_path / "theirs.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = [1.0]
    with pytest.warns(StaleDatasetWarning), pytest.raises(ConfigError, match="another "
                                                          "program's"):
        ensure_dataset(dvl, foreign, progress=False)
    with h5py.File(foreign, "r") as f:
        assert list(f["x"][:]) == [1.0]


def test_ensure_dataset_regenerates_a_file_made_with_another_vehicle_model(tmp_path):
    """A single file stores its config, which names the model file only: the hash of the
    config with the model's contents is recorded beside it (``runner.MADE``), so an edited
    model makes it again; a file changed since it was made falls back to its config."""
    from auvsim.physics.vehicle import model_path

    model = tmp_path / "my-auv.xml"
    model.write_text(model_path("auv").read_text())
    one = flat(mission("a", 1, speed=1.0, duration=20.0, start_speed=0.0))
    one = dataclasses.replace(one, vehicle=dataclasses.replace(one.vehicle, model=str(model)))
    path = tmp_path / "datasets" / "one.h5"
    ensure_dataset(one, path, progress=False)
    assert runner.stale(path, one) is None
    model.write_text(model.read_text().replace('ctrlrange="-900 900"', 'ctrlrange="-800 800"'))
    with pytest.warns(StaleDatasetWarning, match=r"another config \(another auvsim or "
                                                 r"vehicle model\); generating it again"):
        ensure_dataset(one, path, progress=False)
    assert runner.stale(path, one) is None
    made = json.loads((path.parent / runner.MADE).read_text())
    assert made["one.h5"]["config_sha256"] == config_sha256(one)
    # Changed since it was made: the record no longer speaks for it, its config does (the
    # model's name only, so another edit of the model goes unseen, as for any file made
    # elsewhere).
    os.utime(path, ns=(0, 0))
    model.write_text(model.read_text().replace('ctrlrange="-800 800"', 'ctrlrange="-700 700"'))
    assert runner.stale(path, one) is None


def test_train_runs_keeps_each_models_best_seed_and_reuses_what_is_trained(data, tmp_path):
    configs = {f"{m}/v2": TrainConfig(epochs=1, missions=(m,)) for m in ("a", "b")}
    kept = train_runs(data, configs, tmp_path, 2, workers=1, progress=False)
    assert list(kept) == ["a/v2", "b/v2"]
    for name, k in kept.items():
        assert k.run == tmp_path / name and k.loaded()[0] == k.run
        assert k.seeds == (tmp_path / name / "seed_0", tmp_path / name / "seed_1")
        assert k.trained_seeds == k.seeds and k.diverged == {}
        losses = {r: load(r)[1]["final_train_loss"] for r in k.seeds}
        assert losses[k.seeds[0]] != losses[k.seeds[1]]
        assert k.kept == min(losses, key=losses.get)
        assert k.checkpoint["final_train_loss"] == losses[k.kept]
        assert k.checkpoint["train_config"]["missions"] == (name[0],)
        record = json.loads((k.run / "restarts.json").read_text())
        assert record["kept"] == str(k.kept)

    # Run again on the same file: nothing is trained or copied again.
    stamps = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*") if p.is_file()
              and p.name != "restarts.json"}
    again = train_runs(data, configs, tmp_path, 2, workers=1, progress=False)
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    assert {n: k.kept for n, k in again.items()} == {n: k.kept for n, k in kept.items()}

    # Another config of one model trains that model's seeds again, and only those, and
    # says so: the runs are a cache another report may have used.
    with pytest.warns(ReplacedRunWarning, match=r"2 run\(s\) trained with other settings "
                      r"\(lr 0.01 -> 0.005\) are trained again in their place, from "):
        changed = train_runs(data, {"a/v2": dataclasses.replace(configs["a/v2"], lr=0.005)},
                             tmp_path, 2, workers=1, progress=False)
    assert changed["a/v2"].checkpoint["train_config"]["lr"] == 0.005
    moved = {p for p, stamp in stamps.items() if p.stat().st_mtime_ns != stamp}
    assert {tmp_path / "a" / "v2" / f"seed_{s}" / "model.pt" for s in (0, 1)} <= moved
    assert not any(p.is_relative_to(tmp_path / "b") for p in moved)


def test_a_diverged_seed_is_dropped_and_recorded(data, tmp_path, monkeypatch):
    monkeypatch.setattr(beamsnet.training.runs, "train", _diverging({0}))
    k = train_runs(data, {"v2": TrainConfig(epochs=1)}, tmp_path, 2, workers=1,
                   progress=False)["v2"]
    seed_0, seed_1 = tmp_path / "v2" / "seed_0", tmp_path / "v2" / "seed_1"
    assert k.diverged == {seed_0: "lr 0.01: seed 0 diverged"}
    assert k.kept == seed_1 and k.trained_seeds == (seed_1,) and not seed_0.exists()
    record = json.loads((tmp_path / "v2" / "restarts.json").read_text())
    assert record["diverged"] == {str(seed_0): "lr 0.01: seed 0 diverged"}


def test_every_seed_diverging_is_an_error_and_writes_nothing(data, tmp_path, monkeypatch):
    monkeypatch.setattr(beamsnet.training.runs, "train", _diverging({0, 1}))
    with pytest.raises(DivergedError, match="every run diverged") as refused:
        train_runs(data, {"v2": TrainConfig(epochs=1)}, tmp_path / "runs", 2, workers=1,
                   progress=False)
    assert refused.value.argument == "lr"
    assert not (tmp_path / "runs").exists()


def test_the_paper_sim_report_lists_a_diverged_seed(tmp_path, monkeypatch):
    from beamsnet.experiments.reproduce import paper_sim

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(beamsnet.training.runs, "train", _diverging({1}))
    report = paper_sim("paper-sim", data=None, duration=60.0, out=tmp_path / "reports",
                       training=TrainConfig(epochs=1), restarts=2, workers=1,
                       progress=False).read_text()
    assert (tmp_path / "datasets" / "paper-sim_60s.h5").exists()
    for speed in (1, 2, 3):
        for model in ("V1", "V2"):
            assert f"| {speed} m/s | {model} |" in report
    assert report.count("seed_1 diverged") == 6 and report.count("seed_0 ") == 6
    assert "each model trained from 2 seeds" in report
    assert "paper-sim_60s.h5`, 60 s per speed" in report
    # Given a file, the report says the file's own length, not the --duration default's.
    again = paper_sim("paper-sim", data=tmp_path / "datasets" / "paper-sim_60s.h5",
                      duration=7200.0, out=tmp_path / "again", training=TrainConfig(epochs=1),
                      restarts=2, workers=1, progress=False).read_text()
    assert "paper-sim_60s.h5`, 60 s per speed" in again and "7200" not in again
    # What differs from the paper's protocol says the paper's; what does not, nothing.
    assert "1 epoch (the paper: 30);" in report and "batch 4, lr 0.01 decaying" in report
    verdicts = [line.split(" | ")[5] for line in report.splitlines()
                if line.startswith("| ") and " m/s | " in line and line.count(" | ") == 7]
    assert len(verdicts) == 3 and set(verdicts) <= {"both", "V1 only", "V2 only", "neither"}


def test_the_improvement_figure_shows_an_estimator_worse_than_least_squares():
    from beamsnet.experiments.reproduce import FIGURE_FLOOR, figure_floor

    assert figure_floor([75.2, 80.0, math.nan]) == 0.0
    assert figure_floor([75.2, -12.0]) == -17.0
    assert figure_floor([75.2, -10457.3]) == FIGURE_FLOOR
