"""Running an experiment's trainings: its datasets made once, its models trained once.

``beamsnet reproduce`` (paper-sim, snapir) and ``beamsnet stress`` need the same steps
before they can evaluate anything, and this module is the one place that does them:

* ``ensure_dataset``: a preset's dataset under ``datasets/``, generated if it is missing
  or was made from another config (its stored config says so, not its name). Data
  generation never runs inside training: the file exists before any model reads it.
* ``train_runs``: every model of the experiment trained from a few seeds (``seed_runs``),
  in parallel processes (``train_all``), the seed that fits its training split best kept
  (``keep_best``), and the kept models loaded. A seed run that already holds the same
  config trained on the same file (by SHA-256) is reused rather than trained again, so a
  report rerun on unchanged data only re-evaluates. A seed whose loss diverges is
  recorded and dropped, as long as another seed of the same model trains.

Both train in parallel processes here, or with ``cluster`` as tasks on a Dask cluster
(``train_all``), whose workers read the datasets from a folder they share with this one.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import torch

from auvsim.checks import is_finite
from auvsim.data.files import check_out_dir
from auvsim.data.reader import open_dataset
from auvsim.errors import AuvsimError, ConfigError
from auvsim.runs.cluster import check_address
from beamsnet.training.checkpoints import (
    CheckpointError,
    file_identity,
    load,
    read_checkpoint,
    trained,
)
from beamsnet.training.config import PROFILES, TrainConfig, check_restarts
from beamsnet.training.runs import keep_best, seed_runs, train_all

# Beside the single-file datasets ``ensure_dataset`` makes: each one's config hash
# (``config_sha256``, which covers the vehicle model file and auvsim's version, where the
# file's stored config names the model only) with the file's size and mtime when it was
# made. A sharded dataset's shards store the hash themselves.
MADE = ".auvsim-made.json"


def check_duration(value, argument: str, *, unit: str = "seconds") -> float:
    """``value``, the duration of an experiment's preset missions, checked before any data
    is generated: a positive number of ``unit`` (seconds, or seconds per manoeuvre), at
    most a mission's longest (``MAX_DURATION``).

    Raises:
        ConfigError: naming ``argument``, the experiment's option.
    """
    from auvsim.runs.presets import MAX_DURATION

    if not (is_finite(value) and value > 0):
        raise ConfigError(f": expected a positive number of {unit}, got {value!r}",
                          argument=argument)
    if value > MAX_DURATION:
        raise ConfigError(f": expected at most {MAX_DURATION:g} s (72 h, a mission's "
                          f"longest), got {value!r}", argument=argument)
    return float(value)


class StaleDatasetWarning(UserWarning):
    """An experiment's dataset was there but made from another config (or unreadable),
    and is generated again."""


def settings(profile: str, training: TrainConfig | None, restarts: int | None, *,
             out: str | os.PathLike, cluster: str | None) -> tuple[TrainConfig, int]:
    """An experiment's training config and restarts (its ``PROFILES`` entry's where not
    given), with those, ``out`` and ``cluster`` checked before minutes go into generating
    the data.

    Raises:
        ConfigError: a bad setting.
    """
    chosen = PROFILES[profile]
    training = chosen.config if training is None else training
    restarts = chosen.restarts if restarts is None else restarts
    check_restarts(restarts)
    check_out_dir(out)
    if cluster is not None:
        check_address(cluster)
    return training, restarts


def ensure_dataset(config, path: str | os.PathLike, *, progress: bool = True,
                   cluster: str | None = None) -> Path:
    """``path``, generated from ``config`` (an ``auvsim.config.Config``) unless it holds
    exactly what ``config`` makes, on the Dask cluster ``cluster`` if one is given (the
    same data either way).

    An existing file is reused only when its config hash equals the one generating
    ``config`` would write (``auvsim.runs.generate.config_sha256``: stored in a sharded
    dataset's shards, recorded in ``MADE`` beside a file this function made; else, for a
    file made elsewhere, the SHA-256 of its stored config against that of
    ``config.to_json()``): a changed preset or an added manoeuvre regenerates it, and a
    ``StaleDatasetWarning`` says why in one line; a file there that is not even HDF5 (a
    damaged cache) is replaced too, saying so. ``generate`` writes the file whole or
    not at all, so an interrupted generation leaves nothing that a later run would take
    for a finished file.
    """
    from auvsim.runs.generate import generate

    path = Path(path)
    if path.exists():
        why = stale(path, config)
        if why is None:
            return path
        warnings.warn(f"{path}: {why}; generating it again", StaleDatasetWarning,
                      stacklevel=2)
        if why.startswith(UNREADABLE) and _not_hdf5(path):
            # This experiment's own cache, damaged before its HDF5 header was whole:
            # ``generate`` keeps a file that is not HDF5 from being replaced, and this one
            # is no one's. An HDF5 file is left to ``generate``: another program's is
            # refused, and one that another process holds open (its lock reads as
            # unreadable here) is never deleted from under it.
            path.unlink()
    generate(config, path, progress=progress, cluster=cluster)
    if path.is_file():
        _record(path, config)
    return path


UNREADABLE = "it is not a readable dataset"  # what ``stale`` says of such a file


def _not_hdf5(path: Path) -> bool:
    """Whether ``path`` is a file that does not start as an HDF5 file does."""
    from auvsim.data.writer import HDF5_SIGNATURE

    if not path.is_file():
        return False
    with open(path, "rb") as f:
        return f.read(len(HDF5_SIGNATURE)) != HDF5_SIGNATURE


def stale(path: str | os.PathLike, config) -> str | None:
    """Why the dataset at ``path`` is not what ``config`` makes, in words; None when it
    is (its stored config hash equals the one ``config`` gives, see ``ensure_dataset``)."""
    from auvsim.runs.generate import config_sha256

    try:
        with open_dataset(path) as f:
            stored, stored_sha = f.config_json, f.attrs.get("config_sha256")
    except (AuvsimError, OSError) as e:
        lines = str(e).strip().splitlines() or [type(e).__name__]
        return f"{UNREADABLE} ({lines[0]})"
    wanted = config.to_json()
    made = stored_sha if stored_sha is not None else _made(Path(path))
    if made is not None:
        if made == config_sha256(config):
            return None
    elif _sha256(stored) == _sha256(wanted):  # a file made elsewhere: its config alone
        return None
    differ = _differences(stored, wanted)
    return ("it was made from another config" + (f" ({differ})" if differ else
                                                  " (another auvsim or vehicle model)"))


def _identity(path: Path) -> list[int]:
    stat = path.stat()
    return [stat.st_size, stat.st_mtime_ns]


def _made(path: Path) -> str | None:
    """The config hash ``ensure_dataset`` recorded for the file at ``path`` (``MADE``),
    or None: none recorded, or the file has changed since (another size or mtime)."""
    try:
        entry = json.loads((path.parent / MADE).read_text()).get(path.name)
        if entry["file"] == _identity(path):
            return str(entry["config_sha256"])
    except (OSError, ValueError, AttributeError, KeyError, TypeError):
        pass
    return None


def _record(path: Path, config) -> None:
    """Record ``config``'s hash for the file ``ensure_dataset`` just made at ``path``."""
    from auvsim.data.files import write_text
    from auvsim.runs.generate import config_sha256

    index = path.parent / MADE
    try:
        made = json.loads(index.read_text())
    except (OSError, ValueError):
        made = {}
    if not isinstance(made, dict):
        made = {}
    made[path.name] = {"config_sha256": config_sha256(config), "file": _identity(path)}
    write_text(index, json.dumps(made, indent=1, sort_keys=True) + "\n")


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()


def _differences(stored: str, wanted: str) -> str:
    """The config sections (and missions, by name) in which two config JSON texts
    differ: ``dvl; missions zigzag_20_20, added spiral``."""
    try:
        old, new = json.loads(stored), json.loads(wanted)
    except ValueError:
        return "no config stored" if not stored else ""
    if not isinstance(old, dict):
        return ""
    said = [k for k in sorted(set(old) | set(new))
            if k != "missions" and old.get(k) != new.get(k)]
    before = {m.get("name"): m for m in old.get("missions", []) if isinstance(m, dict)}
    after = {m.get("name"): m for m in new.get("missions", []) if isinstance(m, dict)}
    changed = [str(n) for n in after if n in before and before[n] != after[n]]
    changed += [f"added {n}" for n in after if n not in before]
    changed += [f"without {n}" for n in before if n not in after]
    if not changed and list(before) != list(after):
        changed.append("their order")
    if changed:
        said.append("missions " + ", ".join(changed))
    return "; ".join(said)


class ReplacedRunWarning(UserWarning):
    """Runs that held a model trained with other settings, or on another file, are
    trained again in their place (an experiment's runs are a cache of its last settings:
    another report that used them no longer has its models)."""


def warn_replaced(jobs: list[tuple], sha256: str) -> None:
    """One ``ReplacedRunWarning`` for the (data, config, run) jobs whose run holds a
    readable model of other settings (``train_config`` fields, or the data's SHA-256),
    naming what differs, before they are trained again in its place."""
    replaced, what = [], {}
    for _, config, run in jobs:
        path = Path(run) / "model.pt"
        try:
            old = read_checkpoint(path) if path.is_file() else None
        except CheckpointError:
            old = None
        if old is None:  # none, or not readable: nothing of value is replaced
            continue
        stored, wanted = old.get("train_config", {}), dataclasses.asdict(config)
        for key in sorted(set(stored) | set(wanted)):
            if key != "seed" and stored.get(key) != wanted.get(key):
                what.setdefault(key, f"{key} {stored.get(key)} -> {wanted.get(key)}")
        if old.get("dataset", {}).get("sha256") != sha256:
            what.setdefault("data", "another dataset")
        replaced.append(str(run))
    if replaced:
        warnings.warn(f"{len(replaced)} run(s) trained with other settings "
                      f"({'; '.join(what.values()) or 'an unfinished training'}) are trained "
                      f"again in their place, from {replaced[0]}", ReplacedRunWarning,
                      stacklevel=3)


@dataclass(frozen=True)
class KeptRun:
    """One model of an experiment: trained from several seeds, the best one kept.

    Attributes:
        run: the directory the kept seed was copied into (``runs_dir / name``).
        model: the kept network, in evaluation mode.
        checkpoint: its checkpoint (``beamsnet.training.checkpoints.load``).
        kept: the seed run that was kept (one of ``seeds``).
        seeds: every seed run, in seed order.
        diverged: the seed runs whose training loss became non-finite (they have no
            checkpoint), with the reason.
    """

    run: Path
    model: torch.nn.Module
    checkpoint: dict
    kept: Path
    seeds: tuple[Path, ...]
    diverged: Mapping[Path, str]

    @property
    def trained_seeds(self) -> tuple[Path, ...]:
        """The seed runs that trained (have a checkpoint), in seed order."""
        return tuple(r for r in self.seeds if r not in self.diverged)

    def loaded(self) -> tuple[Path, torch.nn.Module, dict]:
        """(run, model, checkpoint): what ``beamsnet.evaluate.predictions`` takes."""
        return self.run, self.model, self.checkpoint


def train_runs(data: str | os.PathLike, configs: Mapping[str, TrainConfig],
               runs_dir: str | os.PathLike, restarts: int, *, workers: int | None = None,
               progress: bool = True, cluster: str | None = None) -> dict[str, KeptRun]:
    """Train every config of ``configs`` on ``data`` from ``restarts`` seeds, keep each
    one's best, and load the kept models.

    Args:
        data: the dataset every model trains on (each config's ``missions`` of it).
        configs: name -> config. A name is a directory under ``runs_dir`` and may have
            several parts (``speed_1/v1``); its seeds go to ``runs_dir/name/seed_<s>``,
            the kept copy to ``runs_dir/name``.
        runs_dir: where the runs go.
        restarts: seeds per config (``seed_runs``), >= 1.
        workers: training processes (default: one per core, at most one per job).
        progress: progress bars.
        cluster: train on this Dask cluster (``train_all``) instead.

    Returns:
        name -> ``KeptRun``, in the order of ``configs``.

    Raises:
        ConfigError: ``restarts`` < 1; ``DivergedError`` when every seed of a config
            diverged; and what ``beamsnet.training.train.train`` raises for bad data.
    """
    check_restarts(restarts)
    runs_dir = Path(runs_dir)
    sha256 = file_identity(data)["sha256"]
    seeds, jobs = {}, []  # name -> its seed runs; (data, config, run) left to train
    for name, config in configs.items():
        pairs = seed_runs(config, runs_dir / name, restarts)
        seeds[name] = [run for _, run in pairs]
        jobs += [(data, c, run) for c, run in pairs if not trained(run, c, sha256)]
    warn_replaced(jobs, sha256)
    summaries = train_all(jobs, workers=workers, progress=progress, diverged="record",
                          cluster=cluster)
    diverged = {Path(run): s["diverged"]
                for (_, _, run), s in zip(jobs, summaries, strict=True) if "diverged" in s}

    kept = {}
    for name in configs:
        dropped = {r: diverged[r] for r in seeds[name] if r in diverged}
        record = keep_best(seeds[name], runs_dir / name, diverged=dropped)
        kept[name] = KeptRun(runs_dir / name, *load(runs_dir / name), kept=Path(record["kept"]),
                             seeds=tuple(seeds[name]), diverged=dropped)
    return kept


def train_seeds(data: str | os.PathLike, configs: Mapping[str, TrainConfig],
                runs_dir: str | os.PathLike, seeds: int | Mapping[str, int], *,
                workers: int | None = None, progress: bool = True,
                cluster: str | None = None
                ) -> dict[str, list[tuple[Path, torch.nn.Module, dict]]]:
    """Train every config of ``configs`` on ``data`` from seeds 0 .. ``seeds`` - 1 and load
    every seed's model: for reports that score each seed (no seed kept over another).

    A seed run already holding the same config trained on the same file is reused. A
    seed whose training diverges stops the report (``DivergedError``): every seed is a
    row of it, and none is dropped silently.

    Args:
        data: the dataset (each config's ``missions`` of it).
        configs: name -> config (its seed is replaced); a name is a directory under
            ``runs_dir``, its seeds go to ``runs_dir/name/seed_<s>``.
        runs_dir: where the runs go.
        seeds: how many seeds, >= 1; or name -> how many, for each config.
        workers, progress: training processes; progress bars.
        cluster: train on this Dask cluster (``train_all``) instead.

    Returns:
        name -> [(run, model, checkpoint)] in seed order, what
        ``beamsnet.evaluate.predictions`` takes.
    """
    counts = seeds if isinstance(seeds, Mapping) else dict.fromkeys(configs, seeds)
    for count in counts.values():
        check_restarts(count)
    runs_dir = Path(runs_dir)
    sha256 = file_identity(data)["sha256"]
    runs, jobs = {}, []
    for name, config in configs.items():
        pairs = seed_runs(dataclasses.replace(config, seed=0), runs_dir / name, counts[name])
        runs[name] = [run for _, run in pairs]
        jobs += [(data, c, run) for c, run in pairs if not trained(run, c, sha256)]
    warn_replaced(jobs, sha256)
    train_all(jobs, workers=workers, progress=progress, cluster=cluster)
    return {name: [(run, *load(run)) for run in seed_list] for name, seed_list in runs.items()}
