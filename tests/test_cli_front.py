"""The front door of both command lines as a hostile user meets it: a full disk under
every writer, Ctrl-C at the worst moment, a closed pipe, a folder where a file belongs.
Each ends in one line (or none), its exit status, and nothing half-written."""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import flat, mission

from auvsim import cli
from auvsim.data import files, shards, writer
from auvsim.data.reader import open_dataset
from beamsnet import cli as bcli

FULL = OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
SHORT = ["--duration", "10", "--workers", "1", "--quiet"]


@pytest.fixture(scope="module")
def small(dataset_of):
    """Two short straight missions, enough for a plot, a training and an evaluation."""
    return dataset_of(flat(mission("a", 1, speed=2.0, duration=60.0),
                           mission("b", 2, speed=1.0, duration=60.0)), "small")


def _disk_fills_as_data_is_written(monkeypatch) -> None:
    """The disk is full at the first chunk an auvsim dataset writes (a real ENOSPC comes
    from HDF5 as an OSError with that errno)."""
    def full(self, key, rows):
        raise OSError(errno.ENOSPC, "Can't write data (file write failed: errno = 28)")

    monkeypatch.setattr(writer.MissionWriter, "_write", full)


def _one_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def test_full_disk_generate_one_file(tmp_path, capsys, monkeypatch):
    _disk_fills_as_data_is_written(monkeypatch)
    out = tmp_path / "out" / "x.h5"
    assert cli.main(["generate", *SHORT, "--out", str(out)]) == 2
    _one_line(capsys, "auvsim: error: ", str(out), "No space left on device",
              "free some space")
    assert list(tmp_path.iterdir()) == []  # the folder made for it goes too


def test_full_disk_as_the_file_is_made(tmp_path, capsys, monkeypatch):
    def full(*args, **kwargs):
        raise FULL

    monkeypatch.setattr(writer.h5py, "File", full)
    assert cli.main(["generate", *SHORT, "--out", str(tmp_path / "x.h5")]) == 2
    _one_line(capsys, "No space left on device")
    assert list(tmp_path.iterdir()) == []


def test_full_disk_generate_sharded(tmp_path, capsys, monkeypatch):
    _disk_fills_as_data_is_written(monkeypatch)
    out = tmp_path / "rm"
    assert cli.main(["generate", *SHORT, "--out", f"{out}/"]) == 2
    _one_line(capsys, "No space left on device", "part-00000.h5")
    assert list(tmp_path.iterdir()) == []  # a fresh folder goes with its run


def test_full_disk_as_the_index_is_written(tmp_path, capsys, monkeypatch):
    real = shards.write_index

    def full(path, *args, **kwargs):
        real(path, *args, **kwargs)
        raise FULL

    monkeypatch.setattr("auvsim.runs.generate.write_index", full)
    out = tmp_path / "rm"
    assert cli.main(["generate", *SHORT, "--out", f"{out}/"]) == 2
    _one_line(capsys, "index.h5", "No space left on device")
    # The shard was whole and sealed: it stays, as for any stopped sharded run, and the
    # next run takes it as it is. Nothing else is left.
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        "shards", "shards/part-00000.h5"]
    monkeypatch.undo()
    assert cli.main(["generate", *SHORT, "--out", f"{out}/"]) == 0
    said = capsys.readouterr().out
    assert "1 kept from an earlier run" in said
    assert "0 s simulated in" in said and "real time" not in said  # the kept one is not


def test_full_disk_import_velocity(tmp_path, capsys, monkeypatch):
    source = tmp_path / "log.npy"
    np.save(source, np.ones((3, 50)))
    _disk_fills_as_data_is_written(monkeypatch)
    assert cli.main(["import-velocity", str(source), "--out", str(tmp_path / "x.h5")]) == 2
    _one_line(capsys, "x.h5", "No space left on device")
    assert [p.name for p in tmp_path.iterdir()] == ["log.npy"]


def test_full_disk_plot_leaves_no_figure_and_no_folder(small, tmp_path, capsys, monkeypatch):
    real = Path.write_bytes
    written = []

    def fills_up(self, data):
        if written:  # the second figure finds the disk full, half of it written
            real(self, data[:100])
            raise FULL
        written.append(self)
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", fills_up)
    out = tmp_path / "figures" / "new"
    assert cli.main(["plot", str(small), "--out", str(out)]) == 2
    _one_line(capsys, "small_b.png", "No space left on device")
    assert written  # the first was written whole, then removed with its folder
    assert list(tmp_path.iterdir()) == []


def test_full_disk_beamsnet_train_leaves_no_run_folder(small, tmp_path, capsys, monkeypatch):
    import beamsnet.training.train as train

    real = train.torch.save

    def full(obj, path, *args, **kwargs):
        real(obj, path, *args, **kwargs)  # the checkpoint whole, then the disk is full
        raise FULL

    monkeypatch.setattr(train.torch, "save", full)
    run = tmp_path / "runs" / "v2"
    assert bcli.main(["train", str(small), "--model", "v2", "--epochs", "1", "--out", str(run),
                      "--quiet"]) == 2
    _one_line(capsys, "beamsnet: error: ", "No space left on device")
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def run_dir(small, tmp_path_factory):
    from beamsnet.training.config import TrainConfig
    from beamsnet.training.train import train

    out = tmp_path_factory.mktemp("run") / "v2"
    train(small, TrainConfig(model="v2", epochs=1, seed=0), out, progress=False)
    return out


@pytest.mark.parametrize("command", ["evaluate", "estimate"])
def test_full_disk_beamsnet_reports_leave_nothing(small, run_dir, tmp_path, capsys,
                                                  monkeypatch, command):
    real = Path.write_bytes
    calls = []

    def fills_up(self, data):
        calls.append(self)
        if len(calls) > 1:  # the report's second file finds the disk full
            raise FULL
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", fills_up)
    out = tmp_path / "reports" / command
    args = (["evaluate", str(run_dir), str(small)] if command == "evaluate" else
            ["estimate", str(small), "--estimator", "LS"])
    assert bcli.main([*args, "--out", str(out)]) == 2
    _one_line(capsys, "beamsnet: error: ", "No space left on device")
    assert len(calls) > 1
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_as_the_output_is_renamed(tmp_path, capsys, monkeypatch):
    """SIGINT at the very moment of the rename: the run either completes and says what it
    wrote, or leaves nothing; never "nothing was written" beside a new file, and never a
    lock."""
    real = os.replace
    renamed = []

    def replace(src, dst, **kwargs):
        if Path(dst).name == "x.h5":
            signal.raise_signal(signal.SIGINT)  # as the rename happens
            renamed.append(dst)
        return real(src, dst, **kwargs)

    monkeypatch.setattr(files.os, "replace", replace)
    out = tmp_path / "x.h5"
    assert cli.main(["generate", *SHORT, "--out", str(out)]) == 130
    assert renamed
    err = _one_line(capsys, "auvsim: interrupted")
    assert os.listdir(tmp_path) == ["x.h5"]  # no temporary, no lock
    assert f"{out} had been written whole" in err
    with open_dataset(out, verify=True) as f:  # and it is whole
        assert list(f.missions) == ["mission_000"]


def test_ctrl_c_before_the_rename_leaves_nothing(tmp_path, capsys, monkeypatch):
    real = h5py.File.close

    def close(self):
        real(self)
        raise KeyboardInterrupt  # as the file is closed, before the rename

    monkeypatch.setattr(writer.h5py.File, "close", close)
    assert cli.main(["generate", *SHORT, "--out", str(tmp_path / "x.h5")]) == 130
    # Into folders it made for the file: they go too, as the file did.
    assert cli.main(["generate", *SHORT, "--out", str(tmp_path / "new" / "sub" / "x.h5")]) \
        == 130
    monkeypatch.undo()
    assert capsys.readouterr().err == "auvsim: interrupted; nothing was written\n" * 2
    assert list(tmp_path.iterdir()) == []
    # A dataset written whole into a folder made for it stays, folder and all.
    assert cli.main(["generate", *SHORT, "--out", str(tmp_path / "kept" / "x.h5")]) == 0
    assert os.listdir(tmp_path / "kept") == ["x.h5"]


def test_ctrl_c_names_the_models_its_workers_finished(small, tmp_path, capsys):
    """A model a training job finished stays for the next run (its folder existed), and
    an interrupted command names it among what it leaves, not "nothing else"."""
    from auvsim.cli_support import run_command
    from beamsnet.training.config import TrainConfig
    from beamsnet.training.runs import train_all

    (tmp_path / "runs").mkdir()
    for workers in (1, 2):  # in this process, and in a pool's
        outs = [tmp_path / "runs" / f"w{workers}_{k}" for k in range(workers)]

        def command(outs=outs, workers=workers):
            train_all([(small, TrainConfig(model="v2", epochs=1), o) for o in outs],
                      workers=workers, progress=False)
            raise KeyboardInterrupt

        assert run_command("beamsnet", command, {}) == 130
        err = capsys.readouterr().err
        assert err.startswith("beamsnet: interrupted; ") and err.count("\n") == 1, err
        assert err.endswith(" had been written whole before it, nothing else was\n"), err
        for o in outs:
            assert str(o) in err and (o / "model.pt").is_file()


def test_ctrl_c_in_beamsnet_is_one_line(small, tmp_path, capsys, monkeypatch):
    import beamsnet.training.train as train

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(train, "_plot_losses", interrupted)  # after model.pt was written
    run = tmp_path / "v2"
    assert bcli.main(["train", str(small), "--model", "v2", "--epochs", "1", "--out", str(run),
                      "--quiet"]) == 130
    assert capsys.readouterr().err == "beamsnet: interrupted; nothing was written\n"
    assert list(tmp_path.iterdir()) == []


def test_sharded_index_that_is_a_folder_is_refused_first(tmp_path, capsys, monkeypatch):
    out = tmp_path / "rm"
    (out / "index.h5").mkdir(parents=True)
    monkeypatch.setattr("auvsim.runs.generate._run_jobs", pytest.fail)  # before any work
    assert cli.main(["generate", *SHORT, "--out", f"{out}/"]) == 2
    _one_line(capsys, "index.h5' is a folder", "expected the index file")
    assert [p.name for p in out.iterdir()] == ["index.h5"]


def test_a_closed_pipe_ends_quietly(small):
    """``auvsim inspect X.h5 | head -1``, with the reader gone before the first line."""
    read, write = os.pipe()
    os.close(read)
    try:
        done = subprocess.run([sys.executable, "-m", "auvsim", "inspect", str(small)],
                              stdout=write, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write)
    assert done.stderr == ""
    assert done.returncode == 141  # as a shell reports a process that SIGPIPE ended


def test_an_error_on_a_pipe_that_is_not_stdout_is_an_error(tmp_path, capsys, monkeypatch):
    def broken(args):
        raise BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE))

    monkeypatch.setattr(cli, "_presets", broken)
    assert cli.main(["presets"]) == 2
    _one_line(capsys, "auvsim: error: Broken pipe")


def test_compiling_is_said_once_with_its_time(tmp_path, capsys, monkeypatch):
    """The first run (numba's cache empty) says it compiled and for how long; a run that
    compiles nothing says nothing of it."""
    from numba.core import event

    import auvsim.runs.generate as gen

    real = gen.check_reachable

    def compiling(config):  # as numba does when its cache does not have the physics
        with event.trigger_event("numba:compile"):
            real(config)

    loud = [a for a in SHORT if a != "--quiet"]
    assert cli.main(["generate", *loud, "--out", str(tmp_path / "a.h5")]) == 0
    assert "compiling the physics" not in capsys.readouterr().out
    monkeypatch.setattr(gen, "check_reachable", compiling)
    assert cli.main(["generate", *loud, "--out", str(tmp_path / "b.h5")]) == 0
    first, wrote = capsys.readouterr().out.splitlines()
    assert first.startswith("compiling the physics: ")
    assert first.endswith(" s, kept in numba's cache for later runs") and \
        wrote.startswith("wrote ")
    # Under a second, it is said to a tenth ("0 s" had been a first run's figure).
    took = first.split(": ")[1].split(" s,")[0]
    assert took != "0" and f"the {took} s of compiling aside)" in wrote, (first, wrote)
    monkeypatch.setattr(gen, "check_reachable", real)
    assert cli.main(["generate", *SHORT, "--out", str(tmp_path / "c.h5")]) == 0
    assert capsys.readouterr().out.startswith("wrote ")  # --quiet: the one line only


@pytest.mark.parametrize("command", ["", "generate", "presets", "inspect",
                                     "import-velocity", "import", "check-log", "export",
                                     "plot", "serve"])
def test_help_is_for_users(command, capsys):
    from auvsim.runs.presets import DEFAULT_PRESET

    with pytest.raises(SystemExit) as done:
        cli.main([*command.split(), "--help"])
    assert done.value.code == 0
    text = capsys.readouterr().out
    assert "``" not in text and "library" not in text and "thin shell" not in text
    choices = ("{lzf,gzip}", "{akit,csv,pd0,velocity}", "{IMU,DVL,GT}", "{mcap,pd0}",
               "{zstd,lz4,none}", "{beam,instrument}", "{a50}",
               "{" + ",".join(cli._parser()._subparsers._group_actions[0].choices) + "}")
    for shown in choices:  # the commands' list is argparse's
        text = text.replace(shown, "")
    assert "{" not in text  # no Python values
    if command in ("generate", "import-velocity", "import", "export"):
        options = [line.split()[0] for line in text.splitlines()
                   if line.startswith("  --") and "--out" not in line
                   and "--quiet" not in line and "--help" not in line]
        described = text.split("options:")[1]
        for option in options:  # each option with a value says what it is by default
            entry = described.split(option, 1)[1].split("\n  -", 1)[0]
            assert "default" in entry or option in ("--config", "--cluster"), option
    if command == "generate":
        assert f"default: {DEFAULT_PRESET})" in " ".join(text.split())


def test_inspect_never_prints_a_negative_zero(small, capsys, monkeypatch):
    from auvsim.data import describe as ds

    real = ds.describe
    monkeypatch.setattr(ds, "describe", lambda path: real(path) + "\n  bias [-0.,  0.01] "
                        "m/s, offset -0 m, -0.000, -0.e+00, -0.0012, v1-0")
    assert cli.main(["inspect", str(small)]) == 0
    text = capsys.readouterr().out
    assert "-0." not in text.replace("-0.0012", "") and " -0 " not in text
    assert text.rstrip().endswith("bias [0.,  0.01] m/s, offset 0 m, 0.000, 0.e+00, -0.0012, "
                                  "v1-0")


def test_the_mission_plot_says_what_it_plots(dataset_of):
    """Speed over ground and through the water; the current's direction toward, 0 to
    360 deg as inspect says it; every legend beside its panel, outside the data."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from auvsim import plot
    from auvsim.config import VehicleConfig

    # A current toward the north-east (the direction is drawn where the water moves).
    flowing = dataset_of(flat(mission("a", 1, speed=2.0, duration=30.0),
                              vehicle=VehicleConfig(current_ned=(0.2, 0.2, 0.0))), "flowing")
    with open_dataset(flowing) as f:
        m = f.missions["a"]
        fig, axes = plt.subplots(4, 2, figsize=(15, 12.8), layout="constrained")
        plot._draw(m, axes)
        current = m.truth.current_ned
        inspected = np.degrees(np.arctan2(*current.mean(axis=0)[[1, 0]])) % 360
    speed = axes[1, 0]
    assert speed.get_title() == "speed over ground and through the water"
    labels = speed.get_legend_handles_labels()[1]
    assert "over ground" in labels and "through the water" in labels
    direction = fig.axes[-1]  # the current panel's twin
    assert "toward" in direction.get_ylabel() and direction.get_ylim() == (0, 360)
    toward = direction.get_lines()[0].get_ydata()
    assert toward.min() >= 0 and toward.max() < 360
    assert abs(np.mean(toward) - inspected) < 5 and abs(inspected - 45.0) < 5
    # Still water flows toward nowhere: no direction drawn (was 0 deg, north).
    still = plot.toward_deg(np.array([[0.0, 0.0, 0.0], [0.0005, 0.0, 0.0], [0.0, 0.2, 0.0]]))
    assert np.isnan(still[:2]).all() and still[2] == pytest.approx(90.0)
    fig.canvas.draw()
    for ax in axes.ravel():
        legend = ax.get_legend()
        if legend is not None:  # entirely to the right of the panel's data area
            assert legend.get_window_extent().x0 >= ax.get_window_extent().x1 - 1
    plt.close(fig)


def _training_with_two_workers(small, out: Path):
    """``beamsnet train --restarts 2`` in a session of its own, once both seeds are
    training; returns the process and its descendants."""
    import time

    import psutil

    proc = subprocess.Popen(
        [sys.executable, "-m", "beamsnet.cli", "train", str(small), "--model", "v2",
         "--epochs", "100000", "--restarts", "2", "--out", str(out), "--quiet"],
        stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    family: list[psutil.Process] = []
    def command_line(p: psutil.Process) -> str:
        try:
            return " ".join(p.cmdline())
        except psutil.Error:  # gone, or a zombie for a moment (a start-up fork's)
            return ""

    try:
        while len([p for p in family if "forkserver" in command_line(p)]) < 3:
            if proc.poll() is not None or time.monotonic() > deadline:
                pytest.fail("the training's workers never started")
            time.sleep(0.2)
            try:
                family = psutil.Process(proc.pid).children(recursive=True)
            except psutil.NoSuchProcess:
                family = []
    except BaseException:  # no training left running on, whatever went wrong here
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        raise
    time.sleep(1.0)  # the two seeds are training
    return proc, family


def test_sigterm_mid_training_ends_every_worker_at_once(small, tmp_path):
    """A scheduler's SIGTERM reaches the parent alone: it ends the pool's workers, whose
    jobs are of no use now, instead of waiting for them, and leaves no run folder."""
    import psutil

    proc, family = _training_with_two_workers(small, tmp_path / "v2")
    try:
        proc.send_signal(signal.SIGTERM)  # to the parent only, as a batch scheduler does
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130
    assert err == "beamsnet: interrupted; nothing was written\n", err
    gone, alive = psutil.wait_procs(family, timeout=10)
    assert alive == [], [p.cmdline() for p in alive]
    assert list(tmp_path.iterdir()) == []


def test_kill_9_mid_training_leaves_no_worker_training_on(small, tmp_path):
    """Killed outright, the parent can clean nothing up: its workers see it gone and end
    within seconds, not after their jobs."""
    import psutil

    proc, family = _training_with_two_workers(small, tmp_path / "v2")
    try:
        proc.kill()
        proc.communicate(timeout=30)
        gone, alive = psutil.wait_procs(family, timeout=10)
    finally:
        with contextlib.suppress(ProcessLookupError):  # none is left, as it should be
            os.killpg(proc.pid, signal.SIGKILL)
    assert alive == [], [p.cmdline() for p in alive]


def test_a_dataset_is_not_written_under_another_formats_name(tmp_path, capsys):
    """``--out x.csv`` would be HDF5 under a CSV's name: refused in one line, nothing
    written; a .h5 or any other name is a dataset's."""
    for name in ("x.csv", "x.json", "x.CSV"):
        assert cli.main(["generate", *SHORT, "--out", str(tmp_path / name)]) == 2
        _one_line(capsys, "name for an HDF5 dataset; expected a .h5 name")
    assert list(tmp_path.iterdir()) == []
    assert cli.main(["generate", *SHORT, "--out", str(tmp_path / "x.hdf5")]) == 0


def test_ctrl_c_in_a_rerun_into_a_sharded_dataset_says_its_index_went(tmp_path, capsys,
                                                                      monkeypatch):
    """Another command into a finished sharded dataset removes its index before it
    replaces shards: stopped then, it says so (the folder is no dataset until a run
    finishes), where it had said nothing else was changed."""
    import auvsim.runs.generate as gen

    out = tmp_path / "rm"
    assert cli.main(["generate", "--preset", "maneuvers", "--duration", "5", "--quiet",
                     "--workers", "1", "--out", f"{out}/"]) == 0
    assert (out / "index.h5").is_file()

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(gen, "write_index", stopped)
    capsys.readouterr()
    assert cli.main(["generate", "--preset", "maneuvers", "--duration", "6", "--quiet",
                     "--workers", "1", "--out", f"{out}/"]) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "had been written whole before it; it had removed " \
        f"{out / 'index.h5'} (run it again to finish)" in err, err
    assert not (out / "index.h5").exists()


def python_c(code: str, *args: str, timeout: float = 120, **kwargs
             ) -> subprocess.CompletedProcess:
    """``python -c code args``, its output captured as text."""
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True,
                          text=True, timeout=timeout, **kwargs)


def test_ctrl_c_while_beamsnet_loads_is_one_line():
    """The beamsnet program loads torch and every estimator (some 2 s) inside exit_with's
    catch (``beamsnet.console``): a Ctrl-C then is one line and 130, not a traceback. The
    interrupt is made to come while beamsnet.cli is being imported."""
    code = ("import sys, types\n"
            "class Loading(types.ModuleType):\n"
            "    def __getattr__(self, name):\n"
            "        raise KeyboardInterrupt\n"
            "sys.modules['beamsnet.cli'] = Loading('beamsnet.cli')\n"
            "from beamsnet.console import run\n"
            "run()\n")
    done = python_c(code)
    assert done.returncode == 130, done.stderr
    assert done.stderr == "beamsnet: interrupted; nothing was written\n"


def test_beamsnet_without_torch_runs_the_model_based_estimators(tmp_path):
    """A plain install leaves out the learn extra (PyTorch). The model-based estimators
    and the filters then run, and evaluate scores them; a network, the learned-noise
    filter and training say in one line what to install and exit 2. Before, every
    beamsnet command said so, even --help."""
    data = tmp_path / "d.h5"
    assert cli.main(["generate", "--duration", "30", "--out", str(data), "--quiet"]) == 0
    code = ("import sys\n"
            "sys.modules['torch'] = None  # as if it were not installed\n"
            "from beamsnet.console import run\n"
            "run()\n")

    def beamsnet(*args: str) -> subprocess.CompletedProcess:
        return python_c(code, *args, timeout=300, cwd=tmp_path)

    assert beamsnet("--help").returncode == 0
    listed = beamsnet("estimate", "--help").stdout
    assert "INS/DVL (adaptive)" in listed and "learned noise" not in listed, listed
    done = beamsnet("estimate", str(data), "--estimator", "INS/DVL", "--out", "ins")
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "ins" / "estimates.csv").is_file()
    done = beamsnet("evaluate", str(data), "--out", "evaluation")
    assert done.returncode == 0, done.stderr
    table = (tmp_path / "evaluation" / "evaluation.md").read_text()
    assert "| LS |" in table and "| INS/DVL |" in table
    for args in (("estimate", str(data), "--estimator", "INS/DVL (learned noise)"),
                 ("train", str(data), "--out", "run"),
                 ("train", str(data), "--out", "run", "--model", "v2")):
        done = beamsnet(*args)
        assert done.returncode == 2, done.stderr
        assert done.stderr.count("\n") == 1, done.stderr
        assert "PyTorch, which is not installed" in done.stderr or \
            "PyTorch is not installed" in done.stderr, done.stderr
        assert "pip install 'auvsim[learn]'" in done.stderr, done.stderr
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("experiment, default", [("sea", "DEFAULT_SEA"),
                                                 ("snapir", "DEFAULT_SNAPIR")])
def test_reproduce_without_its_default_data_asks_for_data(experiment, default, tmp_path,
                                                          monkeypatch, capsys):
    """The default data folders are beside a checkout of this project; elsewhere (an
    installed package, another clone) the one line names --data with the default it
    tried, where for sea it had named only the path."""
    monkeypatch.setattr(bcli, default, tmp_path / "absent")
    assert bcli.main(["reproduce", experiment, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and \
        err.startswith(f"beamsnet: error: --data '{tmp_path / 'absent'}'"), err
    assert not (tmp_path / "out").exists()


def test_python_api_without_torch_says_what_to_install():
    """``from beamsnet import train`` (or ``load``, ``predict``) without PyTorch: an
    ImportError naming the extra to install, where it had been a bare "No module named
    'torch'"; what needs no PyTorch still loads."""
    code = ("import sys\n"
            "sys.modules['torch'] = None  # as if it were not installed\n"
            "import beamsnet\n"
            "assert callable(beamsnet.load_windows)\n"
            "for name in ('train', 'load', 'predict', 'TrainConfig'):\n"
            "    try:\n"
            "        getattr(beamsnet, name)\n"
            "    except ModuleNotFoundError as e:\n"
            "        assert e.name == 'torch', e\n"
            "        print(name, e)\n")
    done = python_c(code)
    assert done.returncode == 0, done.stderr
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    assert {"train", "load", "predict"} <= set(lines), done.stdout
    for message in lines.values():
        assert message.startswith("beamsnet.") and "pip install 'auvsim[learn]'" in message


def test_python_m_runs_both_programs_as_their_console_scripts(tmp_path):
    """``python -m beamsnet`` had failed (no ``__main__``); both now run their programs,
    a bad argument one line and exit 2 as from the console scripts."""
    for prog in ("auvsim", "beamsnet"):
        done = subprocess.run([sys.executable, "-m", prog, "--help"], capture_output=True,
                              text=True, timeout=120)
        assert done.returncode == 0 and done.stdout.startswith(f"usage: {prog} "), done.stderr
        command = ["estimate", "--estimator", "LS"] if prog == "beamsnet" else ["inspect"]
        done = subprocess.run([sys.executable, "-m", prog, *command, str(tmp_path / "none.h5")],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
        assert done.stderr.startswith(f"{prog}: error: "), done.stderr
