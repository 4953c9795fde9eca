"""Training, checkpoints, evaluation and the beamsnet command line, on tiny datasets."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest
import torch
from conftest import flat, mission, write
from test_kill import (
    as_from_a_terminal,
    cpu_seconds,
    deaf_to_interrupts,
    process_tree,
    processes,
    still_running,
    wait_for,
)

from auvsim.config import DvlConfig
from auvsim.errors import ConfigError
from beamsnet.cli import main
from beamsnet.data import DataError, load_windows, split
from beamsnet.evaluate import estimates, table
from beamsnet.training.checkpoints import load
from beamsnet.training.config import PROFILES, TrainConfig
from beamsnet.training.runs import train_all, train_best
from beamsnet.training.train import DivergedError, predict, train


def tiny(path, *, scale=0.05, noise=0.0, duration=400.0):
    """Two straight missions; the beams' only error is a scale factor (and optional noise)."""
    return write(flat(mission("a", 1, speed=2.0, duration=duration, start_speed=0.0),
                      mission("b", 2, speed=1.0, duration=duration, start_speed=0.0),
                      dvl=DvlConfig(beam_angle_deg=20.0, scale_factor=scale, noise_std=noise)),
                 path)


@pytest.fixture(scope="module")
def scale_only(tmp_path_factory):
    return tiny(tmp_path_factory.mktemp("bn") / "scale.h5")


@pytest.fixture(scope="module")
def v2_run(scale_only, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "v2"
    summary = train(scale_only, TrainConfig(model="v2", epochs=6, lr=0.003, seed=3), out,
                    progress=False)
    return out, summary


def test_training_reduces_the_loss_and_beats_ls_on_a_scale_factor(scale_only, v2_run):
    """With a 5 % scale factor on every beam, LS is 5 % off; the network learns the
    correction (the test split includes the acceleration from rest of neither mission,
    so it is steady motion at 1 and 2 m/s)."""
    out, summary = v2_run
    losses = summary["history"]["train"]
    assert losses[-1] < 0.1 * losses[0]
    windows, predictions = estimates([out], scale_only)
    rows = table(windows, predictions)
    v2 = next(r for name, r in rows.items() if name.startswith("BeamsNetV2"))
    assert v2["rmse"] < 0.5 * rows["LS"]["rmse"]
    assert v2["improvement"] > 50


def test_checkpoint_reloads_with_identical_predictions(scale_only, v2_run):
    out, _ = v2_run
    model, checkpoint = load(out)
    again, _ = load(out / "model.pt")
    _, test = split(load_windows(scale_only, n_past=3))
    np.testing.assert_array_equal(predict(model, test), predict(again, test))
    assert checkpoint["model"] == "v2"
    assert checkpoint["kwargs"] == {"n_past": 3, "past_input": "changes"}
    assert len(checkpoint["dataset"]["sha256"]) == 64
    assert checkpoint["train_config"]["epochs"] == 6
    assert (out / "losses.png").stat().st_size > 1000


def test_training_is_deterministic(scale_only, tmp_path):
    config = TrainConfig(model="v2", epochs=2, seed=7)
    train(scale_only, config, tmp_path / "a", progress=False)
    train(scale_only, config, tmp_path / "b", progress=False)
    a = torch.load(tmp_path / "a" / "model.pt", weights_only=False)["state_dict"]
    b = torch.load(tmp_path / "b" / "model.pt", weights_only=False)["state_dict"]
    for key in a:
        assert torch.equal(a[key], b[key]), key


def test_restarts_keep_the_seed_that_fits_the_training_split_best(scale_only, tmp_path):
    summary = train_best(scale_only, TrainConfig(model="v2", epochs=2, seed=5), tmp_path,
                         restarts=3, workers=2, progress=False)
    record = json.loads((tmp_path / "restarts.json").read_text())
    losses = record["losses"]
    assert sorted(losses) == [str(tmp_path / f"seed_{s}") for s in (5, 6, 7)]
    assert len(set(losses.values())) == 3  # different seeds, different fits
    best = min(losses, key=losses.get)
    assert record["kept"] == summary["kept"] == best
    kept, checkpoint = load(tmp_path)
    assert checkpoint["train_config"]["seed"] == int(best.rsplit("_", 1)[1])
    assert checkpoint["final_train_loss"] == losses[best]
    _, test = split(load_windows(scale_only))
    np.testing.assert_array_equal(predict(kept, test),
                                  predict(load(best)[0], test))


def test_polyak_averaging_keeps_the_mean_of_the_last_epochs_weights(scale_only, tmp_path):
    """With averaging over the last epoch the saved weights are the mean over that epoch's
    steps, not the last step's: the same training, other saved weights, and the loss
    recorded for them is theirs."""
    last = train(scale_only, TrainConfig(model="v2", epochs=3, seed=1), tmp_path / "last",
                 progress=False)
    mean = train(scale_only, TrainConfig(model="v2", epochs=3, seed=1, average_epochs=1),
                 tmp_path / "mean", progress=False)
    assert last["history"] == mean["history"]  # the same trajectory of the weights
    a = torch.load(tmp_path / "last" / "model.pt", weights_only=False)["state_dict"]
    b = torch.load(tmp_path / "mean" / "model.pt", weights_only=False)["state_dict"]
    assert set(a) == set(b) and any(not torch.equal(a[k], b[k]) for k in a)
    model, checkpoint = load(tmp_path / "mean")
    train_w, _ = split(load_windows(scale_only))
    mse = np.mean((predict(model, train_w) - train_w.target) ** 2)
    assert checkpoint["final_train_loss"] == pytest.approx(mse, rel=1e-4)
    assert checkpoint["final_train_loss"] != last["final_train_loss"]
    with pytest.raises(ConfigError, match="average_epochs") as refused:
        TrainConfig(epochs=3, average_epochs=4)
    assert refused.value.argument == "average_epochs"
    with pytest.raises(ConfigError, match=r"expected it off \(False\) for v2 \(only corr "
                       r"takes the IMU as an option; the others always or never\), got True"):
        TrainConfig(model="v2", imu=True)


def test_parallel_training_gives_what_one_process_gives(scale_only, tmp_path, monkeypatch):
    """To the bit, whatever the threads of the process it trains in. And its progress bar
    counts the workers' epochs as they end, not only whole models (it sat at 0 of 3 for
    minutes)."""
    import beamsnet.training.runs as runs

    counted = []

    class Bar:
        def __init__(self, *, total, unit, **kwargs):
            counted.append((total, unit))

        def update(self, n=1):
            counted.append(n)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(runs, "tqdm", Bar)
    jobs = [(scale_only, TrainConfig(model="v2", epochs=2 + s, seed=s), tmp_path / f"p{s}")
            for s in (1, 2)]
    parallel = train_all(jobs, workers=2, progress=True)
    assert counted[0] == (7, " epochs") and counted[1:] == [1] * 7
    # The same job in this process, with its torch threads at three (no pool worker's
    # own number here): the same bits (a seed trained alone took the process's threads,
    # in a pool one, and its weights differed), trained on one thread throughout.
    previous, during = torch.get_num_threads(), []
    torch.set_num_threads(3)
    try:
        serial = train(scale_only, jobs[1][1], tmp_path / "serial", progress=False,
                       on_epoch=lambda: during.append(torch.get_num_threads()))
        assert torch.get_num_threads() == 3  # given back
    finally:
        torch.set_num_threads(previous)
    assert during == [1] * jobs[1][1].epochs
    assert parallel[1]["final_train_loss"] == serial["final_train_loss"]
    a = torch.load(tmp_path / "p2" / "model.pt", weights_only=False)["state_dict"]
    b = torch.load(tmp_path / "serial" / "model.pt", weights_only=False)["state_dict"]
    for key in a:
        assert torch.equal(a[key], b[key]), key


@pytest.mark.parametrize("sig, to_group", [(signal.SIGINT, True), (signal.SIGTERM, False)],
                         ids=["ctrl-c", "sigterm"])
def test_an_interrupt_of_parallel_training_is_one_line_and_leaves_nothing(scale_only, tmp_path,
                                                                         sig, to_group):
    """Ctrl-C (SIGINT to the process group), or SIGTERM to the command alone (a scheduler's,
    whose workers the command then ends), once two pool workers train: exit 130, the one
    line on stderr, no output and no process left. Before, a worker's tqdm lock (its
    default, a multiprocessing lock, is a named semaphore in a forkserver child) was left
    to the resource tracker, which warned of "leaked semaphore objects" after the line.
    A pool worker is forked from the pool's server (a child of the command), which has
    imported the trainer: its CPU clock starts at the fork, and after 1 s it trains. The
    server and its workers ignore both signals (the command stops them), as every pool's
    and cluster's do: a pool that starts in the same process later forks from it."""
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "beamsnet.cli", "train", str(scale_only), "--out", str(out),
         "--epochs", "500", "--restarts", "2", "--quiet"],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, preexec_fn=as_from_a_terminal)
    try:
        def training() -> bool:  # both workers into their epochs
            assert proc.poll() is None, proc.communicate()
            table = processes()
            servers = {p for p, (parent, _, _) in table.items() if parent == proc.pid}
            workers = [p for p, (parent, _, _) in table.items()
                       if parent in servers and cpu_seconds(p) > 1.0]
            if len(workers) >= 2:
                assert all(map(deaf_to_interrupts, servers | set(workers)))
            return len(workers) >= 2

        wait_for(training, "two workers training", timeout=120)
        tree = process_tree(proc.pid)
        (os.killpg if to_group else os.kill)(proc.pid, sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130
    assert err.splitlines() == ["beamsnet: interrupted; nothing was written"]
    assert list(tmp_path.iterdir()) == []
    wait_for(lambda: not still_running(tree), "the run's processes to end", timeout=10)


def test_v1_trains_on_imu_windows(scale_only, tmp_path):
    summary = train(scale_only, TrainConfig(model="v1", epochs=2, lr=0.001), tmp_path / "v1",
                    progress=False)
    assert np.isfinite(summary["history"]["train"]).all()
    _, checkpoint = load(tmp_path / "v1")
    assert checkpoint["kwargs"]["imu_window"] == 100


def test_cli_train_and_evaluate(scale_only, tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["train", str(scale_only), "--model", "v2", "--epochs", "2", "--out", str(run),
                 "--quiet"]) == 0
    assert main(["evaluate", str(run), str(scale_only), "--out", str(tmp_path / "rep")]) == 0
    text = capsys.readouterr().out
    assert "| LS |" in text and "BeamsNetV2" in text and "| Affine |" in text
    result = json.loads((tmp_path / "rep" / "evaluation.json").read_text())
    rows = next(iter(result.values()))["rows"]
    assert rows["LS"]["improvement"] == 0.0
    assert (tmp_path / "rep" / "scale_errors.png").exists()


def test_train_gives_least_squares_loss_beside_the_networks(scale_only, tmp_path):
    from beamsnet.data import load_windows, split
    from beamsnet.training.train import train

    config = TrainConfig(model="v2", epochs=1)
    summary = train(scale_only, config, tmp_path / "run", progress=False)
    test = split(load_windows(scale_only, n_past=config.n_past), config.train_fraction)[1]
    h = test.h  # (4, 3): LS is pinv(H) y, worked out here by the normal equations
    ls = np.linalg.solve(h.T @ h, h.T @ test.beams.T).T
    assert summary["ls_test_loss"] == pytest.approx(np.mean((ls - test.target) ** 2), rel=1e-9)


@pytest.mark.parametrize("loss,warned", [(2.0, True), (0.5, False)])
def test_the_command_warns_of_a_network_worse_than_least_squares(monkeypatch, capsys, loss,
                                                                  warned):
    import beamsnet.training.train

    monkeypatch.setattr(beamsnet.training.train, "train", lambda *a, **k: {
        "final_train_loss": loss, "final_test_loss": loss, "ls_test_loss": 1.0,
        "samples_per_second": 1.0, "checkpoint": "c", "plot": "p"})
    assert main(["train", "data.h5", "--model", "v1", "--out", "run", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert "(test split; least squares 1)" in out
    said = ("beamsnet: warning: BeamsNetV1 does worse on the test split than least squares "
            "on the same beams (2 times its loss)")
    assert (said in err) == warned and err.count("\n") == warned


@pytest.mark.parametrize("args,message", [
    (["train", "missing.h5", "--out", "x"], "no such file"),
    (["train", "{data}", "--out", "{tmp}/r", "--mission", "nope"], "nope"),
    (["train", "{data}", "--out", "{tmp}/r", "--epochs", "0"], "epochs"),
    (["train", "{data}", "--model", "v3", "--out", "x"], "invalid choice"),
    (["train", "{data}", "--out", "{tmp}/r", "--restarts", "0"], "restarts"),
    # Checked before any data is generated:
    (["stress", "--restarts", "0", "--out", "{tmp}/s"], "restarts"),
    (["reproduce", "paper-sim", "--epochs", "2", "--average-epochs", "3"],
     "--average-epochs: expected a whole number from 0 to epochs (2), got 3"),
])
def test_bad_input_gives_one_line_and_exit_2(scale_only, tmp_path, capsys, args, message):
    args = [a.format(data=scale_only, tmp=tmp_path) for a in args]
    with pytest.raises(SystemExit) as stop:
        raise SystemExit(main(args))
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_too_short_for_a_window(tmp_path, capsys):
    short = tiny(tmp_path / "short.h5", duration=3.0)  # 3 pings, V2 needs 4
    assert main(["train", str(short), "--out", str(tmp_path / "r"), "--quiet"]) == 2
    assert "ping" in capsys.readouterr().err


@pytest.mark.slow
def test_reproduce_paper_sim_end_to_end_small(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["reproduce", "paper-sim", "--duration", "120", "--epochs", "2",
                 "--restarts", "2", "--average-epochs", "1", "--out", "reports",
                 "--quiet"]) == 0
    report = (tmp_path / "reports" / "paper-sim.md").read_text()
    assert "| 1 m/s |" in report and "| 3 m/s |" in report and "75.45" in report
    assert "| 2 m/s | V1 |" in report and "seed_1" in report  # every seed's result
    assert (tmp_path / "runs" / "paper-sim" / "speed_2" / "v1" / "restarts.json").exists()
    assert (tmp_path / "reports" / "paper-sim.png").exists()


@pytest.mark.parametrize("field,value", [
    ("model", "v3"), ("epochs", 0), ("epochs", True), ("lr", -0.1), ("lr", float("nan")),
    ("lr_gamma", 0.0), ("batch_size", 2.5), ("train_fraction", 1.0), ("dropout", 1.0),
    ("shared_imu_conv", 1), ("seed", -1), ("missions", "a"), ("missions", ()), ("missions", 5),
])
def test_train_config_errors_name_the_field(field, value):
    with pytest.raises(ConfigError) as refused:
        TrainConfig(**{field: value})
    assert refused.value.argument == field
    assert str(refused.value).startswith(f"{field}: expected ")
    assert "--" not in str(refused.value)  # a library message names no flag


def test_train_config_keeps_one_spelling_of_the_missions():
    assert TrainConfig(missions=["a", "b"]).missions == ("a", "b")
    assert TrainConfig(missions=["a"]) == TrainConfig(missions=("a",))


def test_profiles_resolve_given_values_over_their_own():
    """A profile gives its settings; given values win, and fewer epochs than the profile
    averages over are all averaged unless the averaging is given too."""
    paper_sim = PROFILES["paper-sim"]
    assert paper_sim.resolve() == (paper_sim.config, paper_sim.restarts)
    config, restarts = paper_sim.resolve(epochs=2, lr=0.5, restarts=4)
    assert (config.epochs, config.lr, config.average_epochs, restarts) == (2, 0.5, 2, 4)
    assert paper_sim.resolve(epochs=2, average_epochs=0)[0].average_epochs == 0
    # Everything else is TrainConfig's: the profiles only name what they change.
    assert dataclasses.replace(PROFILES["snapir"].config, lr=TrainConfig.lr,
                               epochs=TrainConfig.epochs,
                               average_epochs=TrainConfig.average_epochs) == TrainConfig()
    with pytest.raises(ConfigError, match="restarts"):
        paper_sim.resolve(restarts=0)


def test_cli_defaults_are_train_configs(monkeypatch, capsys):
    """Every training default of the command line, used or shown, comes from TrainConfig
    and its profiles."""
    import beamsnet.experiments.reproduce
    import beamsnet.experiments.stress
    import beamsnet.training.train

    calls = {}

    def record(name):
        def fake(*args, **kwargs):
            calls[name] = (args, kwargs)
            return {"final_train_loss": 0.0, "final_test_loss": 0.0, "ls_test_loss": 0.0,
                    "samples_per_second": 1.0, "checkpoint": "c", "plot": "p"}
        return fake

    monkeypatch.setattr(beamsnet.training.train, "train", record("train"))
    monkeypatch.setattr(beamsnet.experiments.reproduce, "paper_sim", record("paper-sim"))
    monkeypatch.setattr(beamsnet.experiments.reproduce, "snapir", record("snapir"))
    monkeypatch.setattr(beamsnet.experiments.reproduce, "sim2real", record("sim2real"))
    monkeypatch.setattr(beamsnet.experiments.stress, "stress", record("stress"))
    assert main(["train", "data.h5", "--out", "run", "--quiet"]) == 0
    assert calls["train"][0][1] == TrainConfig()
    for command in (["reproduce", "paper-sim"], ["stress"]):
        assert main([*command, "--quiet"]) == 0
        profile = PROFILES[command[-1]]
        kwargs = calls[command[-1]][1]
        assert (kwargs["training"], kwargs["restarts"]) == (profile.config, profile.restarts)
    # The sea-data experiments score every seed; sim2real trains with the sea profile.
    for command in (["reproduce", "snapir"], ["reproduce", "sim2real"]):
        assert main([*command, "--quiet"]) == 0
        kwargs = calls[command[-1]][1]
        assert kwargs["training"] == PROFILES["snapir"].config and kwargs["seeds"] is None
    capsys.readouterr()

    def help_of(command):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        return " ".join(capsys.readouterr().out.split())

    train_help = help_of("train")
    shown = {flag: getattr(TrainConfig(), flag[2:].replace("-", "_"))
             for flag in ("--model", "--epochs", "--lr", "--batch-size", "--seed",
                          "--average-epochs")}
    shown["--restarts"] = PROFILES["train"].restarts
    options = {o.split()[0]: o for o in train_help.split("options:")[1].split(" --")}
    for flag, value in shown.items():
        assert options[flag[2:]].endswith(f"(default: {value})"), flag
    reproduce_help = help_of("reproduce")
    assert (f"default: {PROFILES['paper-sim'].config.epochs:g} for paper-sim, "
            f"{PROFILES['snapir'].config.epochs:g} for snapir") in reproduce_help
    assert f"default {PROFILES['paper-sim'].restarts:g} for paper-sim" in reproduce_help
    assert "(default: None)" not in reproduce_help
    stress_help = help_of("stress")
    assert f"(default: {PROFILES['stress'].config.epochs})" in stress_help
    assert f"default {PROFILES['stress'].config.average_epochs}, at most" in stress_help


def test_training_refuses_non_finite_data_before_writing(scale_only, tmp_path, capsys):
    """A dataset whose targets (or a network's inputs) hold NaN is refused with one line
    naming the file and the field, before anything is written."""
    bad = tmp_path / "nan.h5"
    shutil.copyfile(scale_only, bad)
    with h5py.File(bad, "r+") as f:
        f["missions/a/dvl/velocity"][...] = np.nan
        f["missions/b/imu/specific_force"][5000:] = np.inf
    out = tmp_path / "run"
    assert main(["train", str(bad), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{bad}: the true DVL velocity holds NaN or inf in " in err and "mission a" in err
    assert not out.exists()
    with pytest.raises(DataError, match="the measured specific force holds NaN or inf") as refused:
        train(bad, TrainConfig(model="v1", missions=("b",)), out, progress=False)
    assert "mission b at 51 s" in str(refused.value)
    assert not out.exists()


def test_a_diverging_loss_stops_training_and_writes_nothing(scale_only, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", str(scale_only), "--model", "v1", "--lr", "1e20", "--epochs", "1",
                 "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("beamsnet: error: --lr 1e+20: BeamsNetV1 (seed 0) diverged, its "
                          "training loss became ")
    assert not out.exists()
    # Under restarts (in worker processes) a diverged seed is dropped; when every seed
    # diverges, that is the error, and still nothing is written.
    assert main(["train", str(scale_only), "--model", "v1", "--lr", "1e20", "--epochs", "1",
                 "--restarts", "2", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("beamsnet: error: --lr: every run diverged")
    assert str(out / "seed_0") in err and str(out / "seed_1") in err
    assert not out.exists()


def test_restarts_drop_a_diverged_seed_and_record_why(scale_only, tmp_path, monkeypatch):
    import beamsnet.training.runs

    real = beamsnet.training.runs.train

    def seed_1_diverges(dataset, config, out, *, progress=True):
        if config.seed == 1:
            raise DivergedError("0.01: seed 1 diverged", argument="lr")
        return real(dataset, config, out, progress=progress)

    monkeypatch.setattr(beamsnet.training.runs, "train", seed_1_diverges)
    out = tmp_path / "best"
    summary = train_best(scale_only, TrainConfig(epochs=1), out, restarts=3, workers=1,
                         progress=False)
    record = json.loads((out / "restarts.json").read_text())
    assert record["diverged"] == {str(out / "seed_1"): "lr 0.01: seed 1 diverged"}
    assert np.isnan(record["losses"][str(out / "seed_1")])
    finite = {r: v for r, v in record["losses"].items() if np.isfinite(v)}
    assert sorted(finite) == [str(out / "seed_0"), str(out / "seed_2")]
    assert summary["kept"] == min(finite, key=finite.get) != str(out / "seed_1")
    assert not (out / "seed_1").exists()
    assert load(out)[1]["final_train_loss"] == finite[summary["kept"]]
