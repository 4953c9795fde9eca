"""Sharded datasets: a folder of shard files and an index that reads as one dataset.

Each shard is an ordinary dataset file holding some of the missions, sealed with the hash
of the config that made it and a digest of its data (``auvsim.data.writer.DatasetWriter.seal``);
the index's missions are HDF5 external links into them (``write_index``): readers open
the folder, or its index, exactly as a file, and no data is copied.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import asdict
from datetime import datetime, timezone
from pathlib import Path

import h5py

from auvsim import __version__
from auvsim.data.reader import open_dataset
from auvsim.data.schema import FORMAT, FORMAT_VERSION, SHARDS, Shard
from auvsim.errors import DatasetError


def shard_state(path: str | os.PathLike, config_sha256: str) -> Shard | None:
    """The shard at ``path`` if it is complete and holds what ``config_sha256`` makes:
    a readable dataset file sealed with that config hash whose data still match its
    digest (every field read again). None if it is missing, foreign, another config's,
    or its data differ (then it is to be made again)."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with open_dataset(path) as f:
            attrs = f.attrs
            # An older auvsim's shard lacks what this version's index promises its readers.
            if (attrs.get("config_sha256") != config_sha256 or "data_sha256" not in attrs
                    or f.version != FORMAT_VERSION):
                return None
            if f.digest() != attrs["data_sha256"]:
                return None
            return Shard(path.name, tuple(f.missions), config_sha256, attrs["data_sha256"])
    except (DatasetError, OSError, KeyError, ValueError, TypeError, RuntimeError):
        return None


def write_index(path: str | os.PathLike, shards: Sequence[Shard], *,
                config_json: str) -> None:
    """Write the index of a sharded dataset at ``path`` (a temporary name in the dataset's
    folder, which the caller renames to ``INDEX``): the root attributes of a dataset file,
    ``layout = "index"``, the shards' records, and each mission as an external link to
    its group in ``SHARDS/<shard file>``, so readers see one dataset and no data moves."""
    with h5py.File(path, "w") as f:
        f.attrs.update(format=FORMAT, format_version=FORMAT_VERSION,
                       auvsim_version=__version__,
                       created_utc=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                       config_json=config_json, layout="index",
                       shards=json.dumps([asdict(s) for s in shards]))
        missions = f.create_group("missions")
        for shard in shards:
            for name in shard.missions:
                missions[name] = h5py.ExternalLink(f"{SHARDS}/{shard.file}", f"/missions/{name}")


def data_files(path: str | os.PathLike) -> list[Path]:
    """The files that hold a dataset's data: the file itself, or a sharded dataset's
    shards in index order (not its index, which a rewrite changes without the data)."""
    with open_dataset(path) as f:
        return list(f.shards) if f.shards else [f.path]
