"""The only module that knows the HDF5 layout (schema v1 in docs/ARCHITECTURE.md).

Writing streams chunks into resizable, compressed datasets, so memory stays flat in mission
length; the file is built under a temporary name and renamed when complete, so a failed or
interrupted run leaves nothing half-written behind.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np

from . import __version__
from .errors import ConfigError, DatasetError

FORMAT = "auvsim-dataset"
FORMAT_VERSION = 1
CHUNK_ROWS = 6000  # rows per HDF5 chunk: 60 s at 100 Hz, 48 kB for a float64 column
# lzf: fast, built into h5py; gzip (level 1): about 1.5x the writing cost, but every HDF5
# tool reads it without a plugin.
COMPRESSION = {"lzf": dict(compression="lzf", shuffle=True),
               "gzip": dict(compression="gzip", compression_opts=1, shuffle=True)}

TRUTH_FIELDS = ("time", "position_ned", "velocity_ned", "velocity_body", "quaternion",
                "angular_rate", "specific_force", "altitude")
CONTROL_FIELDS = ("propeller_rpm", "thrust", "rudder", "stern_planes")


class DatasetWriter:
    """Writes a dataset file; use as a context manager.

    Args:
        path: the final file name; the work happens in a temporary file beside it.
        config_json: the resolved configuration, stored in the root attributes.
        compression: a key of ``COMPRESSION``.
    """

    def __init__(self, path: str | os.PathLike, *, config_json: str,
                 compression: str = "lzf") -> None:
        self.path = Path(path)
        self.filters = COMPRESSION[compression]
        self.tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            open(self.tmp, "wb").close()  # plain open: its OSError says what is wrong
        except OSError as e:
            raise ConfigError(
                f"--out {str(self.path)!r}: cannot write there ({e.strerror or e}); "
                "expected a path in a writable directory"
            ) from None
        self.file = h5py.File(self.tmp, "w")
        self.file.attrs.update(
            format=FORMAT,
            format_version=FORMAT_VERSION,
            auvsim_version=__version__,
            created_utc=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            config_json=config_json,
        )
        self.file.create_group("missions")

    def mission(self, name: str, attrs: Mapping[str, object]) -> MissionWriter:
        group = self.file["missions"].create_group(name)
        group.attrs.update(attrs)
        return MissionWriter(group, self.filters)

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.file.close()
        if exc_type is None:
            os.replace(self.tmp, self.path)
        else:
            self.tmp.unlink(missing_ok=True)


class MissionWriter:
    """Appends time-major arrays to ``/missions/<name>/<group>/<field>``.

    Rows are buffered and written a whole HDF5 chunk at a time: a chunk written in two
    parts would be compressed twice and decompressed once in between.
    """

    def __init__(self, group: h5py.Group, filters: Mapping[str, object]) -> None:
        self.group = group
        self.filters = filters
        self.pending: dict[str, list[np.ndarray]] = {}

    def append(self, fields: Mapping[str, np.ndarray]) -> None:
        """Append rows; keys are paths such as ``truth/time``."""
        for key, values in fields.items():
            parts = self.pending.setdefault(key, [])
            parts.append(np.asarray(values))
            if sum(len(p) for p in parts) >= CHUNK_ROWS:
                rows = np.concatenate(parts)
                whole = len(rows) - len(rows) % CHUNK_ROWS
                self._write(key, rows[:whole])
                self.pending[key] = [rows[whole:]]

    def flush(self) -> None:
        """Write what is buffered (the mission's last, partial chunk)."""
        for key, parts in self.pending.items():
            self._write(key, np.concatenate(parts))
        self.pending.clear()

    def _write(self, key: str, rows: np.ndarray) -> None:
        if key not in self.group:
            self.group.create_dataset(
                key, data=rows, maxshape=(None, *rows.shape[1:]),
                chunks=(CHUNK_ROWS, *rows.shape[1:]), **self.filters,
            )
            return
        ds = self.group[key]
        n = ds.shape[0]
        ds.resize(n + len(rows), axis=0)
        ds[n:] = rows


def open_dataset(path: str | os.PathLike) -> h5py.File:
    """Open an auvsim dataset for reading, after checking that it is one.

    Raises:
        DatasetError: the file is missing, not HDF5, not an auvsim dataset, or of another
            format version.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise DatasetError(f"{path}: not an HDF5 file, or corrupt") from None
    fmt = f.attrs.get("format")
    version = f.attrs.get("format_version")
    if fmt != FORMAT:
        f.close()
        raise DatasetError(f"{path}: not an auvsim dataset (format attribute is {fmt!r}, "
                           f"expected {FORMAT!r})")
    if version != FORMAT_VERSION:
        f.close()
        raise DatasetError(f"{path}: auvsim dataset format_version {version}; this auvsim "
                           f"reads version {FORMAT_VERSION}")
    return f
