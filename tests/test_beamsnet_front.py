"""beamsnet's front door: where reports go by default, inputs checked before any data is
generated, refusals in one line, warnings that say what a table hides, writers that leave
nothing behind when they fail, and --help for users."""

from __future__ import annotations

import dataclasses
import errno
import json
import os
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import flat, mission

import beamsnet.evaluate
import beamsnet.experiments.reproduce
import beamsnet.experiments.stress
import beamsnet.training.train
from auvsim.config import DvlConfig
from auvsim.data.files import staged_dir
from auvsim.errors import ConfigError
from beamsnet.cli import REPORTS, main, report_dir
from beamsnet.evaluate import estimate, evaluate
from beamsnet.experiments.wording import count
from beamsnet.training.config import TrainConfig
from beamsnet.training.train import train


def _config(angle: float = 20.0):
    return flat(mission("a", 1, speed=2.0, duration=60.0),
                mission("b", 2, speed=1.0, duration=60.0),
                dvl=DvlConfig(beam_angle_deg=angle, scale_factor=0.02))


@pytest.fixture(scope="module")
def data(dataset_of):
    return dataset_of(_config(), "front")


@pytest.fixture(scope="module")
def wide(dataset_of):
    """The same missions seen by a DVL with 30 deg beams."""
    return dataset_of(_config(30.0), "front_wide")


@pytest.fixture(scope="module")
def run_on_a(data, tmp_path_factory):
    """A V2 trained on mission a of ``data`` only."""
    out = tmp_path_factory.mktemp("runs") / "v2_a"
    train(data, TrainConfig(model="v2", epochs=1, missions=("a",)), out, progress=False)
    return out


def _damaged(path: Path, tmp_path: Path, field: str, rows=slice(None)) -> Path:
    """A copy of ``path`` with ``missions/b/dvl/<field>[rows]`` set to NaN."""
    bad = tmp_path / f"bad_{field}.h5"
    shutil.copyfile(path, bad)
    with h5py.File(bad, "r+") as f:
        f[f"missions/b/dvl/{field}"][rows] = np.nan
    return bad


def _listing(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _no_space(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


# ---- where reports go ------------------------------------------------------------------


def test_a_report_goes_to_a_new_folder_unless_asked_to_refresh(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    committed = tmp_path / "reports"
    committed.mkdir()
    first = report_dir(None, False, "stress", reports=committed)
    assert re.fullmatch(r"runs/stress-\d{8}-\d{6}", str(first))
    first.mkdir(parents=True)
    second = report_dir(None, False, "stress", reports=committed)
    assert second != first and not second.exists()
    assert report_dir(None, True, "stress", reports=committed) == committed
    for inside in (Path("reports"), Path("reports/stress-rm"), committed / "x"):
        with pytest.raises(ConfigError, match="--refresh-reports to replace them"):
            report_dir(inside, False, "stress", reports=committed)
        assert report_dir(inside, True, "stress", reports=committed) == inside
    assert report_dir(Path("mine"), False, "stress", reports=committed) == Path("mine")


def test_stress_and_reproduce_never_default_to_the_committed_reports(tmp_path, monkeypatch,
                                                                    capsys):
    calls = {}

    def record(name):
        def fake(*args, **kwargs):
            calls[name] = kwargs
            return Path("report.md")
        return fake

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(beamsnet.experiments.stress, "stress", record("stress"))
    monkeypatch.setattr(beamsnet.experiments.reproduce, "paper_sim", record("paper-sim"))
    assert main(["stress", "--quiet"]) == 0
    assert re.fullmatch(r"runs/stress-\d{8}-\d{6}", str(calls["stress"]["out"]))
    assert main(["stress", "--faults", "--quiet"]) == 0
    assert re.fullmatch(r"runs/faults-\d{8}-\d{6}", str(calls["stress"]["out"]))
    assert main(["reproduce", "paper-sim", "--quiet"]) == 0
    assert re.fullmatch(r"runs/paper-sim-\d{8}-\d{6}", str(calls["paper-sim"]["out"]))
    if REPORTS.is_dir():  # a source checkout, with its committed reports
        assert main(["stress", "--refresh-reports", "--quiet"]) == 0
        assert calls["stress"]["out"] == REPORTS
        calls.clear()
        capsys.readouterr()
        assert main(["stress", "--out", str(REPORTS / "stress-rm"), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("beamsnet: error: --out ")
        assert "--refresh-reports" in err and not calls


def test_evaluate_and_estimate_default_to_a_new_runs_folder(data, run_on_a, tmp_path,
                                                            monkeypatch, capsys):
    """Neither writes into reports/ unless told: a new runs/<name>-DATE-TIME each time."""
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", str(run_on_a), str(data)]) == 0
    assert main(["estimate", str(data), "--estimator", "LS"]) == 0
    made = sorted(str(p.relative_to(tmp_path)) for p in (tmp_path / "runs").iterdir())
    assert len(made) == 2, made
    assert re.fullmatch(r"runs/estimate-\d{8}-\d{6}", made[0])
    assert re.fullmatch(r"runs/evaluation-\d{8}-\d{6}", made[1])
    assert (tmp_path / made[1] / "evaluation.md").is_file()
    assert (tmp_path / made[0] / "estimates.csv").is_file()
    assert not (tmp_path / "reports").exists()


# ---- inputs checked before any generation ----------------------------------------------


@pytest.fixture
def no_generation(monkeypatch):
    """Generating a dataset fails the test."""
    def generate(*args, **kwargs):
        raise AssertionError("a dataset was generated before the inputs were checked")

    monkeypatch.setattr("auvsim.runs.generate.generate", generate)
    monkeypatch.setattr(beamsnet.experiments.stress, "ensure_dataset", generate)
    monkeypatch.setattr(beamsnet.experiments.reproduce, "ensure_dataset", generate)


@pytest.mark.parametrize("args, said", [
    (["stress", "--train", "notes.txt"], "--train notes.txt: not an HDF5 file"),
    (["stress", "--train", "missing.h5"], "--train missing.h5: no such file"),
    (["stress", "--maneuvers", "notes.txt"], "--maneuvers notes.txt: not an HDF5 file"),
    (["stress", "--train", "{data}", "--maneuvers", "notes.txt"],
     "--maneuvers notes.txt: not an HDF5 file"),
    (["stress", "--maneuver-duration", "-1"], "--maneuver-duration: expected a positive"),
    (["stress", "--train-duration", "0"], "--train-duration: expected a positive"),
    (["stress", "--train-duration", "1e12"], "--train-duration: expected at most 259200 s"),
    (["stress", "--maneuver-duration", "1e12"], "--maneuver-duration: expected at most"),
    (["stress", "--faults", "--fault-duration", "-3"], "--fault-duration"),
    (["reproduce", "paper-sim", "--data", "notes.txt"], "--data notes.txt: not an HDF5"),
    (["train", "{data}", "--model", "v1", "--protocol", "paper"],
     "--protocol: only v2 has the choice; v1 has no past beams; expected it without"),
    (["train", "{data}", "--model", "corr", "--protocol", "fixed"],
     "--protocol: only v2 has the choice; corr always takes the past beams' changes"),
    (["reproduce", "paper-sim", "--data", "{data}"],
     "has no mission speed_1, speed_2, speed_3 (it has a, b)"),
    (["reproduce", "paper-sim", "--data", "{data}", "--duration", "100"],
     "--duration is not used with --data, whose file is the data as it is"),
])
def test_bad_inputs_are_refused_before_any_data_is_generated(args, said, data, tmp_path,
                                                             monkeypatch, capsys,
                                                             no_generation):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("not a dataset\n")
    args = [a.replace("{data}", str(data)) for a in args]
    assert main([*args, "--out", "out", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert said in err
    assert _listing(tmp_path) == {"notes.txt"}


def test_manoeuvres_need_a_truth_to_score_against(data, tmp_path, monkeypatch, capsys,
                                                  no_generation):
    """An imported DVL stream has no truth: refused as manoeuvres, before any training."""
    from auvsim.data.importer import import_velocity

    velocity = np.tile([[1.5], [0.0], [0.1]], 200)  # 3 x N, the Snapir files' layout
    np.save(tmp_path / "v.npy", velocity)
    import_velocity([tmp_path / "v.npy"], tmp_path / "imported.h5", dvl=DvlConfig())
    monkeypatch.chdir(tmp_path)
    assert main(["stress", "--train", str(data), "--maneuvers", "imported.h5", "--out", "out",
                 "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert ("--maneuvers 'imported.h5': mission v has no truth group (an imported stream); "
            "expected a simulated dataset") in err
    assert not (tmp_path / "out").exists() and not (tmp_path / "runs").exists()


# ---- warnings and refusals -------------------------------------------------------------


def test_evaluate_warns_when_a_run_is_scored_on_missions_it_never_saw(run_on_a, data,
                                                                      tmp_path, capsys):
    assert main(["evaluate", str(run_on_a), str(data), "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("beamsnet: warning: ")
    assert f"run '{run_on_a}' was trained on mission a only" in err
    assert "scores it on a, b, and b is new to it" in err
    # What the warning advises: its own mission alone, which it does without a word.
    assert "evaluate --mission NAME" in err
    assert main(["evaluate", str(run_on_a), str(data), "--mission", "a",
                 "--out", str(tmp_path / "a")]) == 0
    assert capsys.readouterr().err == ""
    scored = json.loads((tmp_path / "a" / "evaluation.json").read_text())
    assert list(scored[str(data)]["rmse_per_mission"]["LS"]) == ["a"]
    assert main(["evaluate", str(run_on_a), str(data), "--mission", "c",
                 "--out", str(tmp_path / "c")]) == 2
    assert "mission 'c': not in" in capsys.readouterr().err


def test_evaluate_without_a_run_compares_the_model_based_estimators(data, run_on_a,
                                                                    tmp_path, capsys):
    """A dataset first: the model-based estimators and filters alone (a user's own
    beside LS needed a network trained first); a run alone is refused in one line."""
    assert main(["evaluate", str(data), "--out", str(tmp_path / "alone")]) == 0
    rows = json.loads((tmp_path / "alone" / "evaluation.json").read_text())[str(data)]["rows"]
    assert "LS" in rows and "INS/DVL" in rows and not any("BeamsNet" in r for r in rows)
    capsys.readouterr()
    assert main(["evaluate", str(run_on_a), "--out", str(tmp_path / "run")]) == 2
    assert capsys.readouterr().err == (f"beamsnet: error: DATASET: '{run_on_a}' is a run; "
                                       "expected the datasets to evaluate it on after it\n")
    assert not (tmp_path / "run").exists()
    missing = tmp_path / "datasets" / "paper_sim.h5"
    assert main(["evaluate", str(missing), "--out", str(tmp_path / "run")]) == 2
    assert capsys.readouterr().err == (f"beamsnet: error: DATASET: '{missing}' does not "
                                       "exist; expected a run folder and the datasets to "
                                       "evaluate it on, or datasets alone\n")


def test_a_run_trained_on_every_mission_evaluates_without_a_word(data, tmp_path, capsys):
    run = tmp_path / "all"
    train(data, TrainConfig(model="v2", epochs=1), run, progress=False)
    assert main(["evaluate", str(run), str(data), "--out", str(tmp_path / "r")]) == 0
    assert capsys.readouterr().err == ""


def test_estimate_refuses_training_data_of_other_beams_in_one_line(data, wide, tmp_path,
                                                                   capsys):
    out = tmp_path / "est"
    assert main(["estimate", str(data), "--estimator", "Affine", "--train", str(wide),
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"beamsnet: error: --train '{wide}': its DVL's beams (30 deg from "
                          f"the vertical) are not those of '{data}' (20 deg)")
    assert not out.exists()


def test_evaluate_refuses_nan_true_velocities_in_one_line(run_on_a, data, tmp_path, capsys):
    bad = _damaged(data, tmp_path, "velocity", slice(40, 50))
    out = tmp_path / "r"
    assert main(["evaluate", str(run_on_a), str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{bad}: the true DVL velocity holds NaN or inf in " in err and "mission b" in err
    assert not out.exists()
    assert main(["estimate", str(bad), "--estimator", "LS", "--out", str(out)]) == 2
    assert "the true DVL velocity holds NaN" in capsys.readouterr().err
    assert not out.exists()


def test_a_mission_without_beam_velocities_is_refused_in_one_line(run_on_a, data, tmp_path,
                                                                  capsys):
    bad = _damaged(data, tmp_path, "beam_velocity")
    for args in (["train", str(bad), "--epochs", "1", "--quiet"],
                 ["evaluate", str(run_on_a), str(bad)]):
        out = tmp_path / args[0]
        assert main([*args, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err
        assert (f"{bad}: mission b: every beam velocity is NaN (not one ping has a "
                "valid beam)") in err
        assert not out.exists()


# ---- writers that fail leave nothing ---------------------------------------------------


def test_a_full_disk_in_train_leaves_no_partial_run(data, tmp_path, monkeypatch):
    config = TrainConfig(model="v2", epochs=1, missions=("a",))
    monkeypatch.setattr(beamsnet.training.train, "write_text", _no_space)
    with pytest.raises(OSError, match="No space left"):
        train(data, config, tmp_path / "runs" / "new", progress=False)
    assert _listing(tmp_path) == set()
    # A run that exists keeps its files as they were.
    monkeypatch.undo()
    old = tmp_path / "old"
    train(data, config, old, progress=False)
    before = {p.name: p.read_bytes() for p in old.iterdir()}
    monkeypatch.setattr(beamsnet.training.train, "write_text", _no_space)
    with pytest.raises(OSError):
        train(data, dataclasses.replace(config, seed=1), old, progress=False)
    assert {p.name: p.read_bytes() for p in old.iterdir()} == before
    assert _listing(tmp_path) == {"old", *(f"old/{n}" for n in before)}


@pytest.mark.filterwarnings("ignore::beamsnet.evaluate.UnseenMissionWarning")
def test_a_full_disk_in_evaluate_or_estimate_leaves_no_folder(run_on_a, data, tmp_path,
                                                              monkeypatch):
    monkeypatch.setattr(beamsnet.evaluate, "write_text", _no_space)
    with pytest.raises(OSError, match="No space left"):
        evaluate([run_on_a], [data], tmp_path / "reports" / "evaluation")
    with pytest.raises(OSError, match="No space left"):
        estimate("LS", data, tmp_path / "estimate")
    assert _listing(tmp_path) == set()


def test_a_staged_folder_is_moved_in_whole_or_not_at_all(tmp_path):
    out = tmp_path / "a" / "b"
    with pytest.raises(OSError), staged_dir(out) as stage:
        (stage / "one.txt").write_text("1")
        _no_space()
    assert _listing(tmp_path) == set()  # nor the folders above it that it made
    with staged_dir(out) as stage:
        (stage / "one.txt").write_text("1")
        assert not out.exists()
    assert _listing(out) == {"one.txt"}
    (out / "mine.txt").write_text("kept")
    with staged_dir(out) as stage:
        (stage / "one.txt").write_text("2")
    assert (out / "one.txt").read_text() == "2" and (out / "mine.txt").read_text() == "kept"
    assert _listing(tmp_path) == {"a", "a/b", "a/b/one.txt", "a/b/mine.txt"}


def test_a_command_says_which_files_in_its_folder_it_replaced(data, tmp_path, capsys):
    """The same estimate again writes the same files: nothing to say. Another estimator
    into the same folder replaces both files, and says so in one line; a file of the
    user's is left alone and unnamed."""
    out = tmp_path / "est"
    assert main(["estimate", str(data), "--estimator", "LS", "--out", str(out)]) == 0
    (out / "mine.txt").write_text("kept")
    assert main(["estimate", str(data), "--estimator", "LS", "--out", str(out)]) == 0
    assert capsys.readouterr().err == ""
    assert main(["estimate", str(data), "--estimator", "KF", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert err == (f"beamsnet: warning: {str(out)!r} held estimates.csv and summary.json "
                   "already; this run replaced them\n")
    assert (out / "mine.txt").read_text() == "kept"


def test_a_new_output_folder_named_as_a_file_is_refused(tmp_path, monkeypatch):
    """--out plot.png for the PNGs' folder is a slip that made a folder of that name; an
    existing folder so named is the user's own and is written into."""
    from auvsim.data.files import check_out_dir

    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match="'plot.png': a .png file's name; expected a folder"):
        check_out_dir("plot.png")
    (tmp_path / "old.pt").mkdir()
    assert check_out_dir("old.pt") == Path("old.pt")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.pt"]


def test_a_staged_folder_named_dot_is_the_current_one(tmp_path, monkeypatch):
    """``--out .`` (or ``keep/..``) writes into that folder, which exists; ``/`` and a
    place that cannot be written in are refused in one line before any work."""
    from auvsim.data.files import check_out_dir

    (tmp_path / "keep").mkdir()
    monkeypatch.chdir(tmp_path / "keep")
    with staged_dir(Path(".")) as stage:
        (stage / "one.txt").write_text("1")
    with staged_dir(Path("..")) as stage:
        (stage / "two.txt").write_text("2")
    assert _listing(tmp_path) == {"keep", "keep/one.txt", "two.txt"}
    with pytest.raises(ConfigError, match="the root directory; expected a directory below"):
        check_out_dir("/")
    if Path("/proc/self").is_dir():  # a place nobody can make a file in, root or not
        with pytest.raises(ConfigError, match="cannot write in '/proc'.*expected a directory "
                                              "you can write in"):
            check_out_dir("/proc/auvsim-report")
    assert _listing(tmp_path) == {"keep", "keep/one.txt", "two.txt"}  # no probe left


# ---- words for users -------------------------------------------------------------------


def test_help_is_for_users(capsys):
    for command in ([], ["train"], ["evaluate"], ["estimate"], ["reproduce"], ["stress"]):
        with pytest.raises(SystemExit):
            main([*command, "--help"])
        text = capsys.readouterr().out
        assert "``" not in text and "{'" not in text, command
        assert "(default: False)" not in text and "(default: [])" not in text, command
        assert not re.search(r"default: \d+\.0\)", text), command
    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "default 5 for v2, 3 for v2-paper, 3 for corr in snapir" in text


def test_counts_in_report_prose_agree_in_number():
    assert count(1, "epoch") == "1 epoch"
    assert count(30, "epoch") == "30 epochs"
    assert count(0, "seed") == "0 seeds"


# ---- figures ---------------------------------------------------------------------------


def test_every_estimator_has_a_look_of_its_own_and_keeps_it():
    from beamsnet.plotstyle import KNOWN, styles

    names = [*KNOWN, "Robust LS", "BeamsNetV2 (seed_1)", "BeamsNetV2 (seed_2)"]
    look = styles(names)
    pairs = [(s.color, s.linestyle) for s in look.values()]
    assert len(set(pairs)) == len(names) > 10
    # LS and BeamsNetV2M share blue, Affine and CorrectionNet orange: not their style.
    assert look["LS"].color == look["BeamsNetV2M"].color
    assert look["LS"].linestyle != look["BeamsNetV2M"].linestyle
    assert look["Affine"].linestyle != look["CorrectionNet"].linestyle
    # The same estimator looks the same in another figure, among other estimators.
    again = styles(["CorrectionNet (corr)", "Robust LS", "LS"])
    assert again["CorrectionNet (corr)"] == look["CorrectionNet"]
    assert again["Robust LS"] == look["Robust LS"] and again["LS"] == look["LS"]


def test_legends_sit_outside_the_data_and_epochs_are_whole(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from beamsnet.plotstyle import figure_legend, panel_grid, styles

    def overlaps(a, b) -> bool:
        return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1

    look = styles([f"estimator {i}" for i in range(13)])
    constrained = plt.subplots(2, 5, figsize=(15, 5), layout="constrained")
    # A panel grid of stress's size, log panels labelled as its are: nothing of a panel
    # (its tick labels, axis labels, title) reaches another, nor the legend, and the
    # legend lies inside the figure.
    grid = panel_grid(2, 3, panel=(2.45, 1.6), legend=2.2, wspace=0.45)
    for fig, axes in (constrained, grid):
        for ax in axes.flat:
            for name, style in look.items():
                ax.plot([0, 60], [1e-4, 1e2], label=name, **style.line())
            if axes is grid[1]:
                ax.set_yscale("log")
            ax.set(title="zigzag_20_20", xlabel="time, s")
            ax.tick_params(labelsize=6)
        axes[0, 0].set_ylabel("horizontal position error, m", fontsize=7)
        figure_legend(fig, axes[0, 0], fontsize=9)
        fig.canvas.draw()
        legend = fig.legends[0].get_window_extent()
        assert not any(overlaps(legend, ax.get_window_extent()) for ax in axes.flat)
        assert fig.bbox.contains(legend.x0, legend.y0) and fig.bbox.contains(legend.x1,
                                                                             legend.y1)
        boxes = [ax.get_tightbbox() for ax in axes.flat]
        assert not any(overlaps(a, b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
        assert not any(overlaps(legend, box) for box in boxes)
        plt.close(fig)

    figures = []
    monkeypatch.setattr(beamsnet.training.train, "save_figure",
                        lambda fig, path, dpi: figures.append(fig))
    history = {"train": [1.0, 0.5, 0.3], "test": [1.1, 0.6, 0.4]}
    beamsnet.training.train._plot_losses(history, tmp_path / "losses.png", TrainConfig())
    fig = figures[0]
    fig.canvas.draw()
    ax = fig.axes[0]
    ticks = [t for t in ax.get_xticks() if ax.get_xlim()[0] <= t <= ax.get_xlim()[1]]
    assert ticks and all(float(t).is_integer() for t in ticks)
    assert not overlaps(ax.get_legend().get_window_extent(), ax.get_window_extent())
    plt.close(fig)


def test_a_full_disk_in_a_staged_folder_names_the_output_not_its_stage(tmp_path, monkeypatch):
    """A report's files are written into a hidden stage beside --out: an error writing
    one names it in the folder the user gave, not in the stage, which is then gone."""
    import errno

    from auvsim.data.files import staged_dir, write_text
    from auvsim.errors import OutputError

    def full(self, data):
        raise OSError(errno.ENOSPC, "No space left on device")

    out = tmp_path / "report"
    with pytest.raises(OutputError) as refused:
        with staged_dir(out) as stage:
            monkeypatch.setattr(Path, "write_bytes", full)
            write_text(stage / "summary.json", "{}")
    monkeypatch.undo()
    assert str(refused.value).startswith(f"'{out / 'summary.json'}': cannot be written (No "
                                         "space left on device); expected room for it")
    assert list(tmp_path.iterdir()) == []
