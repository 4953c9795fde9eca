"""The checkpoint of a trained network (``model.pt``): its format, reading and checking
it, the dataset identity and sensor setup it records, and whether a run already holds a
given training.

A checkpoint carries the model's name and constructor arguments, its weights, the
training config, the dataset's identity (path, SHA-256, ``config_json``) and its sensor
setup, so evaluation rebuilds exactly what was trained and can tell which data it came
from. Only tensors and plain values are unpickled: a file that needs arbitrary Python
objects is not one of ours, and is refused with ``CheckpointError``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import pickle
import warnings
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from auvsim.errors import AuvsimError, ConfigError
from beamsnet.estimators import models, spec
from beamsnet.estimators.networks import build
from beamsnet.training.config import TrainConfig


class CheckpointError(AuvsimError):
    """A run directory or checkpoint file that is missing, unreadable, not a beamsnet
    checkpoint, or whose weights do not fit the model it names. A subclass of auvsim's
    base error, so a command line's one-line handling catches it."""


# What marks a beamsnet checkpoint, and the keys (and their types) every reader relies on.
CHECKPOINT_FORMAT = "beamsnet-checkpoint"
CHECKPOINT_VERSION = 1
_CHECKPOINT_KEYS = {"model": str, "kwargs": dict, "state_dict": dict, "train_config": dict,
                    "dataset": dict}
# The training data's sensor setup a network is tied to (the geometry and rates: it
# learned one beam matrix and one ping spacing) and the error model it learned to undo.
SENSOR_GEOMETRY = ("beam_angle_deg", "dvl_mounting_rpy_deg", "dvl_rate_hz", "imu_rate_hz")
SENSOR_ERRORS = ("dvl_scale_factor", "dvl_bias", "dvl_noise_std")


def file_identity(path: str | Path) -> dict:
    """Path, SHA-256 and generating config of a dataset: the SHA-256 of its file's bytes,
    or of a sharded dataset's shards' bytes in index order."""
    from auvsim.data.reader import open_dataset
    from auvsim.data.shards import data_files

    digest = hashlib.sha256()
    for file in data_files(path):
        with open(file, "rb") as f:
            for block in iter(lambda f=f: f.read(1 << 22), b""):
                digest.update(block)
    with open_dataset(path) as f:
        config_json = f.config_json
    return dict(path=str(path), sha256=digest.hexdigest(), config_json=config_json)


def sensor_setup(path: str | Path, missions: Sequence[str] | None = None) -> dict[str, dict]:
    """Per mission of a dataset (the named ones, default all): its sensor geometry and
    rates (``SENSOR_GEOMETRY``) and realised DVL error model (``SENSOR_ERRORS``), as
    floats and lists of floats (what a checkpoint stores). An attribute a mission does
    not have (an imported stream has no IMU rate or mounting) is left out, and so is a
    named mission the file does not hold (its reader refuses it, in its words)."""
    from auvsim.data.reader import read_attrs

    _, attrs = read_attrs(path)
    names = list(attrs) if missions is None else [n for n in missions if n in attrs]
    return {name: {key: np.asarray(attrs[name][key], dtype=float).tolist()
                   for key in SENSOR_GEOMETRY + SENSOR_ERRORS if key in attrs[name]}
            for name in names}



def trained(run: str | Path, config: TrainConfig, sha256: str) -> bool:
    """Whether ``run`` already holds this config trained on the file with this SHA-256
    (then a report re-evaluates it instead of training again). A run whose checkpoint
    cannot be read is not trained: training again replaces it."""
    path = Path(run) / "model.pt"
    if not path.is_file():
        return False
    try:
        checkpoint = read_checkpoint(path)
    except CheckpointError:
        return False
    return (checkpoint["train_config"] == dataclasses.asdict(config)
            and checkpoint["dataset"].get("sha256") == sha256
            and "final_train_loss" in checkpoint)



def load(run: str | Path) -> tuple[torch.nn.Module, dict]:
    """The trained model of a run directory (or ``model.pt`` path) and its checkpoint.

    Raises:
        CheckpointError: the run does not exist or has no ``model.pt``; it is not a
            beamsnet checkpoint (empty, truncated, corrupt, another kind of file, keys
            missing); or its weights do not fit the model it names.
    """
    path = _checkpoint_path(run)
    checkpoint = read_checkpoint(path)
    try:
        model = build(checkpoint["model"], **checkpoint["kwargs"])
    except (TypeError, ValueError, RuntimeError, MemoryError) as e:  # absurd sizes too
        raise _refused(path, f"its model arguments {checkpoint['kwargs']} do not build "
                       f"{spec(checkpoint['model']).short} ({e})") from None
    _check_weights(model, checkpoint, path)
    model.load_state_dict(checkpoint["state_dict"])
    model.eval()
    # The beam angles it learned (``predict`` refuses others); empty: not recorded.
    sensors = checkpoint.get("sensors")
    model.trained_beam_angles_deg = tuple(sorted(
        {float(s["beam_angle_deg"]) for s in sensors.values()
         if isinstance(s, dict) and "beam_angle_deg" in s})) if isinstance(sensors, dict) else ()
    return model, checkpoint


def read_checkpoint(path: str | Path) -> dict:
    """The checkpoint in the file ``path``, checked to be a beamsnet checkpoint.

    Only tensors and plain values are unpickled (``weights_only``): a checkpoint is data,
    and a file that needs arbitrary Python objects to load is not one of ours.

    Raises:
        CheckpointError: as ``load``.
    """
    path = Path(path)
    # torch.save has written zip archives since PyTorch 1.6: anything else (an empty,
    # truncated or text file, a bare pickle) is refused before torch parses it.
    if not zipfile.is_zipfile(path):
        size = path.stat().st_size
        raise _refused(path, "is empty" if size == 0 else
                       f"is not a PyTorch checkpoint ({size} bytes, not a zip archive: "
                       "truncated, corrupt or another kind of file)")
    # torch.load reads the archive without checking its members' CRC-32s: a flipped bit
    # in the weights would load, and score otherwise. The zip's own check finds it.
    try:
        with zipfile.ZipFile(path) as archive:
            damaged = archive.testzip()
    except (zipfile.BadZipFile, OSError, EOFError) as e:
        raise _refused(path, f"is a corrupt PyTorch checkpoint ({_first_line(e)})") from None
    if damaged is not None:
        raise _refused(path, f"is a corrupt PyTorch checkpoint: its member {damaged!r} "
                       "fails its CRC-32 check (changed or damaged since it was written)")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # torch's notes on pickle protocols
            checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:
        raise _refused(path, "holds something other than tensors and plain values: a "
                       "corrupt pickle, or Python objects, which a checkpoint never needs "
                       "and which are not unpickled") from None
    except _TORCH_LOAD_ERRORS as e:
        raise _refused(path, f"is a corrupt PyTorch checkpoint ({type(e).__name__}: "
                       f"{_first_line(e)})") from None
    if not isinstance(checkpoint, dict):
        raise _refused(path, f"holds a {type(checkpoint).__name__}, not a beamsnet "
                       "checkpoint (a dict)")
    # Checkpoints from before the format marker have the same keys and are read alike.
    marker = checkpoint.get("format", CHECKPOINT_FORMAT), checkpoint.get("format_version", 1)
    if marker != (CHECKPOINT_FORMAT, CHECKPOINT_VERSION):
        raise _refused(path, f"has format {marker[0]!r} version {marker[1]!r}; this beamsnet "
                       f"reads {CHECKPOINT_FORMAT!r} version {CHECKPOINT_VERSION}")
    missing = [k for k in _CHECKPOINT_KEYS if k not in checkpoint]
    if missing:
        raise _refused(path, f"lacks {', '.join(missing)}: not a beamsnet checkpoint")
    wrong = [f"{k} is a {type(checkpoint[k]).__name__}" for k, kind in _CHECKPOINT_KEYS.items()
             if not isinstance(checkpoint[k], kind)]
    if checkpoint["model"] not in models() and not wrong:
        wrong.append(f"model is {checkpoint['model']!r}, not {' or '.join(models())}")
    if not wrong:
        try:
            TrainConfig(**checkpoint["train_config"])
        except (ConfigError, TypeError) as e:
            wrong.append(f"train_config is not a training config ({e})")
    if wrong:
        raise _refused(path, f"is not a beamsnet checkpoint: {'; '.join(wrong)}")
    return checkpoint


# What torch.load raises on a damaged zip archive or pickle inside it.
_TORCH_LOAD_ERRORS = (RuntimeError, OSError, EOFError, zipfile.BadZipFile, KeyError,
                      ValueError, TypeError, IndexError, AttributeError, UnicodeDecodeError)
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _checkpoint_path(run: str | Path) -> Path:
    """The ``model.pt`` of a run directory (or the path itself, if it is a file)."""
    path = Path(run)
    if not path.exists():
        raise _refused(path, "does not exist")
    if path.is_dir():
        path = path / "model.pt"
        if not path.exists():
            raise _refused(path.parent, "has no model.pt (is it a run directory, and did "
                           "its training finish?)")
        if not path.is_file():
            raise _refused(path, "is a directory, not the checkpoint file" if path.is_dir()
                           else "is not a regular file")
    else:
        with open(path, "rb") as f:
            if f.read(len(_HDF5_SIGNATURE)) == _HDF5_SIGNATURE:
                raise _refused(path, "is an HDF5 file (a dataset?), not a run")
    return path


def _check_weights(model: torch.nn.Module, checkpoint: dict, path: Path) -> None:
    """Refuse a state_dict whose keys, shapes or values do not fit ``model``."""
    state, expected = checkpoint["state_dict"], model.state_dict()
    problems = [f"no {k}" for k in expected if k not in state]
    problems += [f"unexpected {k}" for k in state if k not in expected]
    for k, v in expected.items():
        if k not in state:
            continue
        if not isinstance(state[k], torch.Tensor):
            problems.append(f"{k} is a {type(state[k]).__name__}, not a tensor")
        elif state[k].shape != v.shape:
            problems.append(f"{k} has shape {tuple(state[k].shape)}, the model's is "
                            f"{tuple(v.shape)}")
        elif state[k].is_floating_point() and not torch.isfinite(state[k]).all():
            problems.append(f"{k} holds NaN or inf")
    if problems:
        more = f" and {len(problems) - 3} more" if len(problems) > 3 else ""
        raise _refused(path, f"has weights that do not fit "
                       f"{spec(checkpoint['model']).short}({_kwargs(checkpoint['kwargs'])}): "
                       f"{'; '.join(problems[:3])}{more}")


def _refused(path: Path, what: str) -> CheckpointError:
    return CheckpointError(f"{str(path)!r}: {what}; expected a run directory with the "
                           "model.pt that beamsnet training writes", argument="run")


def _kwargs(kwargs: dict) -> str:
    return ", ".join(f"{k}={v!r}" for k, v in kwargs.items())


def _first_line(error: BaseException) -> str:
    """The start of an exception's message, for a one-line error."""
    text = (str(error).strip().splitlines() or [""])[0]
    return text if len(text) <= 100 else text[:97] + "..."


