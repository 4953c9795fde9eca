"""beamsnet's training jobs on a Dask cluster (``--cluster local:N``): the same weights,
summaries and reports as the local runs, byte for byte; a bad address refused before any
work; no worker process left behind."""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import psutil
import pytest
import torch
from conftest import flat, mission, write

import beamsnet.training.runs
from auvsim.config import DvlConfig
from auvsim.errors import SimulationError
from auvsim.runs.presets import preset
from beamsnet.cli import main
from beamsnet.training.checkpoints import load
from beamsnet.training.config import TrainConfig
from beamsnet.training.runs import train_all

# The parts of a summary that say where and how fast, not what was trained.
WHERE = ("checkpoint", "plot", "seconds", "samples_per_second")


# multiprocessing's helpers, which live as long as this process (the pool's workers are
# the forkserver's children, and are counted).
HELPERS = ("multiprocessing.forkserver", "multiprocessing.resource_tracker")


@pytest.fixture(autouse=True)
def no_process_left():
    """Every process a test starts has ended when it returns."""
    def ours() -> set[psutil.Process]:
        found = set()
        for child in psutil.Process().children(recursive=True):
            try:
                helper = child.ppid() == os.getpid() and any(
                    h in " ".join(child.cmdline()) for h in HELPERS)
            except psutil.NoSuchProcess:
                continue
            if not helper:
                found.add(child)
        return found

    before = ours()
    yield
    deadline = time.monotonic() + 5.0
    while (left := {p for p in ours() - before if p.is_running()}) and \
            time.monotonic() < deadline:
        time.sleep(0.2)
    assert not left, [" ".join(p.cmdline())[:120] for p in left]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return write(flat(mission("a", 1, speed=2.0, duration=90.0, start_speed=0.0),
                      mission("b", 2, speed=1.0, duration=90.0, start_speed=0.0),
                      dvl=DvlConfig(beam_angle_deg=20.0, scale_factor=0.05, noise_std=0.01)),
                 tmp_path_factory.mktemp("cluster") / "two.h5")


def _same_runs(here, there, summaries_here, summaries_there, names) -> None:
    for a, b in zip(summaries_here, summaries_there, strict=True):
        assert {k: v for k, v in a.items() if k not in WHERE} == \
            {k: v for k, v in b.items() if k not in WHERE}
    for name in names:
        mine, theirs = load(here / name)[1], load(there / name)[1]
        assert mine["state_dict"].keys() == theirs["state_dict"].keys()
        for key, value in mine["state_dict"].items():
            assert torch.equal(value, theirs["state_dict"][key]), (name, key)
        assert mine["history"] == theirs["history"]


@pytest.fixture
def two_threads():
    """This process runs torch with two threads, as it does on two or more cores where
    nothing limits it (``make test`` runs its workers with one), so that a training that
    took the process's threads in place of its own one would be seen."""
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    yield
    torch.set_num_threads(previous)


@pytest.mark.slow
def test_train_all_on_a_cluster_gives_the_local_weights(data, tmp_path, two_threads):
    """Two jobs trained one after the other in this process (two torch threads), and the
    same two jobs on a one-worker cluster (Dask's nannies set OMP_NUM_THREADS=1): the same
    weights and summaries, exactly, because every training runs with
    ``TRAINING_THREADS`` whatever the process's own number (V1's and V2's weights differ
    in their last bits between one thread and two). Two local processes against the
    cluster: the paper-sim report below."""
    def jobs(root):
        return [(data, TrainConfig(model="v1", epochs=2, average_epochs=1), root / "v1"),
                (data, TrainConfig(model="v2", epochs=2, seed=1), root / "v2")]

    here, there = tmp_path / "here", tmp_path / "there"
    local = train_all(jobs(here), workers=1, progress=False)
    cluster = train_all(jobs(there), workers=1, progress=False, cluster="local:1")
    _same_runs(here, there, local, cluster, ("v1", "v2"))


ADDRESSES = []  # where ``_thread_pool`` was asked to run


@contextmanager
def _thread_pool(address, *, threads):
    """A thread pool standing in for a cluster's executor, one job at a time."""
    ADDRESSES.append((address, threads))
    with ThreadPoolExecutor(max_workers=1) as pool:
        yield pool


@pytest.mark.parametrize("restarts", [1, 2])
def test_cli_train_runs_its_jobs_on_the_cluster(data, tmp_path, monkeypatch, capsys,
                                                restarts):
    """``beamsnet train --cluster``: with one seed too, the job goes to the cluster."""
    monkeypatch.setattr(beamsnet.training.runs, "executor", _thread_pool)
    ADDRESSES.clear()
    run = tmp_path / "run"
    assert main(["train", str(data), "--out", str(run), "--epochs", "1", "--restarts",
                 str(restarts), "--cluster", "tcp://10.0.0.5:8786", "--quiet"]) == 0
    assert ADDRESSES == [("tcp://10.0.0.5:8786", 1)]
    out = capsys.readouterr().out
    assert "trained BeamsNetV2: final loss" in out and str(run / "model.pt") in out
    assert out.startswith("kept ") == (restarts == 2)  # the seed kept of the restarts
    assert load(run)[1]["train_config"]["epochs"] == 1


def test_a_lost_worker_is_one_line_and_stops_the_other_jobs(monkeypatch):
    from distributed import KilledWorker

    ran = []

    def job(dataset, config, out, *, progress, record):
        ran.append(out)
        raise KilledWorker("train-0", None, 3)

    monkeypatch.setattr(beamsnet.training.runs, "executor", _thread_pool)
    monkeypatch.setattr(beamsnet.training.runs, "_job", job)
    with pytest.raises(SimulationError, match="ended abruptly on every try") as lost:
        train_all([("d.h5", TrainConfig(), f"run_{i}") for i in range(4)], progress=False,
                  cluster="local:2")
    assert lost.value.__cause__ is None and lost.value.__suppress_context__
    assert ran == ["run_0"]  # the jobs not started were cancelled


@pytest.fixture(scope="module")
def paper_sim_60s(tmp_path_factory):
    return write(preset("paper-sim").with_duration(60.0),
                 tmp_path_factory.mktemp("datasets") / "paper-sim_60s.h5")


@pytest.mark.slow
def test_reproduce_paper_sim_on_a_cluster_writes_the_local_report(paper_sim_60s, tmp_path,
                                                                   monkeypatch):
    """``beamsnet reproduce paper-sim`` here (its 6 jobs on a pool of one process per
    core) and with ``--cluster local:2``, each in a folder of its own that holds the same
    dataset: the same report, figure, restart records and checkpoints, byte for byte (the
    report holds no wall time)."""
    args = ["reproduce", "paper-sim", "--duration", "60", "--epochs", "1", "--restarts", "1",
            "--average-epochs", "1", "--out", "reports", "--quiet"]
    for folder, extra in (("here", []), ("there", ["--cluster", "local:2"])):
        (tmp_path / folder / "datasets").mkdir(parents=True)
        os.link(paper_sim_60s, tmp_path / folder / "datasets" / paper_sim_60s.name)
        monkeypatch.chdir(tmp_path / folder)
        assert main(args + extra) == 0
    here, there = tmp_path / "here", tmp_path / "there"
    written = sorted(p.relative_to(here) for p in here.rglob("*")
                     if p.is_file() and "datasets" not in p.parts)
    assert written == sorted(p.relative_to(there) for p in there.rglob("*")
                             if p.is_file() and "datasets" not in p.parts)
    assert {"reports/paper-sim.md", "runs/paper-sim/speed_2/v1/restarts.json"} <= set(
        map(str, written))
    for path in written:
        assert (here / path).read_bytes() == (there / path).read_bytes(), path


@pytest.mark.parametrize("command", [
    ["train", "data.h5", "--out", "run"],
    ["train", "data.h5", "--out", "run", "--restarts", "3"],
    ["reproduce", "paper-sim"],
    ["reproduce", "snapir", "--data", "snapir"],
    ["stress", "--train-duration", "60", "--maneuver-duration", "60"],
])
@pytest.mark.parametrize("address", ["nonsense", "local:0"])
def test_a_bad_cluster_address_is_one_line_before_any_work(command, address, tmp_path,
                                                           monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([*command, "--cluster", address, "--quiet"]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err
    assert captured.err.startswith(f"beamsnet: error: --cluster {address!r}: ")
    assert list(tmp_path.iterdir()) == []
