"""Bad run folders, checkpoints and outputs are refused on one line with exit code 2, and
nothing is left at ``--out``: what a hostile-user probe of ``beamsnet evaluate`` found."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile

import pytest
import torch
from conftest import flat, mission, write

from auvsim.config import DvlConfig
from beamsnet.cli import main
from beamsnet.training.checkpoints import CHECKPOINT_FORMAT, CheckpointError, load, trained
from beamsnet.training.config import TrainConfig
from beamsnet.training.train import train


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """One straight 90 s mission at 2 m/s, 20 deg beams with a 5 % scale factor."""
    return write(flat(mission("a", 1, speed=2.0, duration=90.0, start_speed=0.0),
                      dvl=DvlConfig(beam_angle_deg=20.0, scale_factor=0.05)),
                 tmp_path_factory.mktemp("data") / "line.h5")


@pytest.fixture(scope="module")
def run(dataset, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "v2"
    train(dataset, TrainConfig(model="v2", epochs=1), out, progress=False)
    return out


def _copy(run, tmp_path):
    bad = tmp_path / "bad_run"
    shutil.copytree(run, bad)
    return bad


def _rewrite(change):
    """A maker of a copy of the run whose checkpoint dict went through ``change``."""
    def make(run, dataset, tmp_path):
        bad = _copy(run, tmp_path)
        checkpoint = torch.load(bad / "model.pt", weights_only=True)
        change(checkpoint)
        torch.save(checkpoint, bad / "model.pt")
        return bad
    return make


def _write(content: bytes | None = None, *, cut: float | None = None):
    """A maker of a copy of the run whose model.pt holds ``content``, or its first ``cut``
    fraction."""
    def make(run, dataset, tmp_path):
        bad = _copy(run, tmp_path)
        data = (bad / "model.pt").read_bytes()
        (bad / "model.pt").write_bytes(content if cut is None else data[:int(cut * len(data))])
        return bad
    return make


def _save(value):
    """A maker of a copy of the run whose model.pt is ``torch.save(value)``."""
    def make(run, dataset, tmp_path):
        bad = _copy(run, tmp_path)
        torch.save(value, bad / "model.pt")
        return bad
    return make


def _damaged_inside(run, dataset, tmp_path):
    """A zip archive whose directory is intact and one stored tensor's header is not."""
    bad = _copy(run, tmp_path)
    with zipfile.ZipFile(bad / "model.pt") as archive:
        tensor = next(i for i in archive.infolist() if i.filename.endswith("/data/0"))
    data = bytearray((bad / "model.pt").read_bytes())
    data[tensor.header_offset:tensor.header_offset + 4] = b"\xff" * 4
    (bad / "model.pt").write_bytes(bytes(data))
    return bad


def _bit_flipped(run, dataset, tmp_path):
    """One bit of a stored tensor's bytes flipped: torch.load would read it."""
    bad = _copy(run, tmp_path)
    with zipfile.ZipFile(bad / "model.pt") as archive:
        tensor = next(i for i in archive.infolist() if i.filename.endswith("/data/0"))
    data = bytearray((bad / "model.pt").read_bytes())
    start = tensor.header_offset + 30 + len(tensor.filename.encode()) + len(tensor.extra)
    data[start + tensor.compress_size // 2] ^= 0x01
    (bad / "model.pt").write_bytes(bytes(data))
    return bad


def _model_pt_is_a_directory(run, dataset, tmp_path):
    bad = _copy(run, tmp_path)
    (bad / "model.pt").unlink()
    (bad / "model.pt").mkdir()
    return bad


def _no_model_pt(run, dataset, tmp_path):
    (tmp_path / "empty_run").mkdir()
    return tmp_path / "empty_run"


class Payload:
    """A Python object in a pickle: never unpickled from a checkpoint."""


def _bigger_output_layer(checkpoint):
    checkpoint["state_dict"]["out.weight"] = torch.zeros(3, 7)


def _nan_weight(checkpoint):
    checkpoint["state_dict"]["out.bias"] = torch.full((3,), float("nan"))


# name -> (a maker of the bad run from a good one, what the message must say)
BAD_RUNS = {
    "corrupt": (_write(bytes(range(256)) * 40), "not a zip archive"),
    "empty": (_write(b""), "is empty"),
    "truncated": (_write(cut=0.5), "truncated, corrupt"),
    "text": (_write(b"a model, honest\n"), "not a PyTorch checkpoint"),
    "damaged inside": (_damaged_inside, "is a corrupt PyTorch checkpoint"),
    "bit flipped": (_bit_flipped, "fails its CRC-32 check (changed or damaged since"),
    "missing key": (_rewrite(lambda c: c.pop("state_dict")), "lacks state_dict"),
    "shape mismatch": (_rewrite(_bigger_output_layer),
                       "out.weight has shape (3, 7), the model's is (3, 6)"),
    "nan weights": (_rewrite(_nan_weight), "out.bias holds NaN"),
    "bad kwargs": (_rewrite(lambda c: c["kwargs"].update(n_past="3")),
                   "do not build BeamsNetV2"),
    "absurd kwargs": (_rewrite(lambda c: c["kwargs"].update(n_past=10**9)),
                      "n_past must be an int in [1, 10000]"),
    "bad train_config": (_rewrite(lambda c: c["train_config"].update(epochs=0)),
                         "train_config is not a training config"),
    "other format": (_rewrite(lambda c: c.update(format="other")),
                     f"has format 'other' version 1; this beamsnet reads {CHECKPOINT_FORMAT!r}"),
    "not a dict": (_save([1, 2, 3]), "holds a list"),
    "python objects": (_save({"model": "v2", "payload": Payload()}),
                       "other than tensors and plain values"),
    "model.pt a directory": (_model_pt_is_a_directory,
                             "model.pt': is a directory, not the checkpoint file"),
    "no model.pt": (_no_model_pt, "has no model.pt"),
    "dataset as run": (lambda run, dataset, tmp_path: dataset,
                       "is an HDF5 file (a dataset?), not a run"),
    "missing run": (lambda run, dataset, tmp_path: tmp_path / "nowhere", "does not exist"),
}


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("beamsnet: error: "), err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("case", list(BAD_RUNS))
def test_evaluate_refuses_a_bad_run_on_one_line_and_leaves_no_output(
        case, run, dataset, tmp_path, capsys):
    make, what = BAD_RUNS[case]
    bad = make(run, dataset, tmp_path)
    out = tmp_path / "report"
    assert main(["evaluate", str(bad), str(dataset), "--out", str(out)]) == 2
    err = _one_line_error(capsys)
    if case == "dataset as run":  # a dataset first is no run: the same dataset twice
        assert f"DATASET: '{bad}' is given twice; expected each dataset once" in err
    else:
        assert f"run '{bad}" in err  # the run path (or its model.pt), named as the run
        assert what in err and "expected a run directory with the model.pt" in err
    assert not out.exists()
    # The same run given with --also is refused the same way.
    assert main(["evaluate", str(run), str(dataset), "--also", str(bad), "--out",
                 str(out)]) == 2
    assert what in _one_line_error(capsys) and not out.exists()


def test_load_raises_checkpoint_errors_and_a_broken_run_is_trained_again(
        run, dataset, tmp_path):
    bad = _write(cut=0.5)(run, dataset, tmp_path)
    with pytest.raises(CheckpointError) as refused:
        load(bad)
    assert refused.value.argument == "run"
    checkpoint = torch.load(run / "model.pt", weights_only=True)
    config, sha256 = TrainConfig(**checkpoint["train_config"]), checkpoint["dataset"]["sha256"]
    assert trained(run, config, sha256) and not trained(bad, config, sha256)


def test_the_checkpoint_carries_a_format_marker_and_older_ones_still_load(
        run, dataset, tmp_path):
    _, checkpoint = load(run)
    assert (checkpoint["format"], checkpoint["format_version"]) == (CHECKPOINT_FORMAT, 1)
    # Runs trained before the marker have the same keys: they are read alike.
    old = _rewrite(lambda c: [c.pop("format"), c.pop("format_version")])(run, dataset,
                                                                          tmp_path)
    model, _ = load(old)
    assert model.n_past == 3


def test_evaluate_refuses_a_file_as_out_and_leaves_it(run, dataset, tmp_path, capsys):
    out = tmp_path / "report.md"
    out.write_text("mine\n")
    assert main(["evaluate", str(run), str(dataset), "--out", str(out)]) == 2
    err = _one_line_error(capsys)
    assert f"--out '{out}': exists and is not a directory" in err
    assert out.read_text() == "mine\n" and sorted(tmp_path.iterdir()) == [out]
    # Nor a directory inside a file.
    assert main(["evaluate", str(run), str(dataset), "--out", str(out / "sub")]) == 2
    assert f"is inside '{out}', which exists and is not a directory" in _one_line_error(capsys)


def test_evaluate_refuses_a_file_that_is_not_a_dataset(run, tmp_path, capsys):
    fake = tmp_path / "fake.h5"
    fake.write_text("not HDF5\n")
    out = tmp_path / "report"
    assert main(["evaluate", str(run), str(fake), "--out", str(out)]) == 2
    assert f"{fake}: not an HDF5 file, or corrupt" in _one_line_error(capsys)
    assert not out.exists()


def test_train_refuses_a_file_as_out_before_training(dataset, tmp_path, capsys,
                                                     monkeypatch):
    import beamsnet.training.train

    monkeypatch.setattr(beamsnet.training.train, "load_windows", None)  # never reached
    out = tmp_path / "run"
    out.write_text("mine\n")
    assert main(["train", str(dataset), "--out", str(out), "--quiet"]) == 2
    assert f"--out '{out}': exists and is not a directory" in _one_line_error(capsys)
    assert main(["train", str(dataset), "--out", str(out), "--restarts", "2", "--quiet"]) == 2
    assert "exists and is not a directory" in _one_line_error(capsys)
    assert out.read_text() == "mine\n"


def test_a_checkpoint_that_cannot_be_saved_is_one_line_and_no_run(dataset, tmp_path,
                                                                    capsys, monkeypatch):
    """torch.save on a full disk raises a RuntimeError without an errno: named as the run's
    output that cannot be written, in one line, and no run folder is left."""
    def full(*args, **kwargs):
        raise RuntimeError("[enforce fail at inline_container.cc:603] . unexpected pos "
                           "1600 vs 1496\nPytorchStreamWriter failed writing file")

    monkeypatch.setattr(torch, "save", full)
    out = tmp_path / "run"
    assert main(["train", str(dataset), "--epochs", "1", "--out", str(out), "--quiet"]) == 2
    err = _one_line_error(capsys)
    assert f"'{out / 'model.pt'}': cannot be written ([enforce fail" in err
    assert "expected room for it there" in err and not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_the_command_prints_no_traceback(run, dataset, tmp_path):
    """The same through the command line's entry point, in a fresh interpreter."""
    bad = _write(cut=0.3)(run, dataset, tmp_path)
    out = tmp_path / "report"
    done = subprocess.run([sys.executable, "-m", "beamsnet.cli", "evaluate", str(bad),
                           str(dataset), "--out", str(out)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert done.stderr.startswith(f"beamsnet: error: run '{bad / 'model.pt'}': ")
    assert not out.exists()


def test_predict_refuses_windows_of_another_beam_angle(run, dataset, tmp_path):
    """A loaded network knows the beam angle it learned: predict on 30 deg beams with a
    model of 20 deg ones is refused (it was 0.69 m/s off where LS is 0.013), unless the
    caller allows it, as evaluate's allow_mismatch does."""
    from auvsim.errors import ConfigError
    from beamsnet.data import load_windows
    from beamsnet.training.train import predict

    model, _ = load(run)
    assert model.trained_beam_angles_deg == (20.0,)
    assert predict(model, load_windows(dataset)).shape[1] == 3  # its own geometry
    other = write(flat(mission("b", 2, speed=2.0, duration=30.0, start_speed=0.0),
                       dvl=DvlConfig(beam_angle_deg=30.0)), tmp_path / "thirty.h5")
    windows = load_windows(other)
    with pytest.raises(ConfigError, match="windows' beams are at 30 deg and the model was "
                                          "trained on beams at 20 deg"):
        predict(model, windows)
    assert predict(model, windows, allow_mismatch=True).shape == (len(windows.target), 3)
