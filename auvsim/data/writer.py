"""Writing a dataset file: streamed, checksummed, and complete or not there at all.

Writing streams chunks into resizable, compressed datasets with a Fletcher-32 checksum
each, so memory stays flat in mission length and a flipped byte is refused when read; the
file is built under a temporary name and renamed when complete, so a failed or
interrupted run leaves nothing half-written behind (``auvsim.data.files.Claim``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np

from auvsim import __version__
from auvsim.data.files import (
    FILE_SUFFIXES,
    Claim,
    check_writable_path,
    commit,
    interrupts_held,
    is_write_error,
    make_parent_dirs,
    output_error,
    writing,
)
from auvsim.data.schema import FORMAT, FORMAT_VERSION, data_digest
from auvsim.errors import ConfigError

CHUNK_ROWS = 6000  # rows per HDF5 chunk: 60 s at 100 Hz, 48 kB for a float64 column
# lzf: fast, built into h5py; gzip (level 1): about 1.5x the writing cost, but every HDF5
# tool reads it without a plugin. Fletcher-32 costs a few % and catches corruption.
COMPRESSION = {"lzf": dict(compression="lzf", shuffle=True, fletcher32=True),
               "gzip": dict(compression="gzip", compression_opts=1, shuffle=True,
                            fletcher32=True)}


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def check_mission_name(name: object, where: str) -> None:
    """A mission's name is a group's name in the file: a text, not empty, without "/",
    and not "." or "..".

    Raises:
        ConfigError: it is not (``where`` names what gave it).
    """
    if not (isinstance(name, str) and name.strip() and "/" not in name
            and name not in (".", "..")):
        raise ConfigError(f"{where}: expected a name without '/' (not empty, '.' or '..'), "
                          f"got {name!r}")


# Names of files in other formats, which a dataset is written under by mistake only (a
# user who asked for CSV would get HDF5 under a .csv name): refused as an output's name.
OTHER_FORMATS = FILE_SUFFIXES - {".h5", ".hdf5"}


def foreign_hdf5(path: Path) -> bool:
    """Whether ``path`` is an HDF5 file that opens and is not auvsim's (no ``format``
    attribute of ``FORMAT``): another program's file, which no command replaces. One that
    does not open (damaged) is not called foreign: it may be a dataset to replace."""
    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") != FORMAT
    except (OSError, ValueError):
        return False


def check_output_path(path: str | os.PathLike, argument: str = "out", *,
                      hint: str = "") -> Path:
    """A user's output path for a dataset file, checked before a command's work: what
    ``check_writable_path`` refuses, and an existing file that is neither HDF5 nor empty
    (a command replaces a dataset, never a user's other file) or not a regular file.
    The writer itself replaces any file (its own caches and shards, damaged or not).

    Raises:
        ConfigError: naming ``argument``.
    """
    path = Path(path)
    check_writable_path(path, argument, hint=hint)
    if path.exists() and not path.is_file():
        raise ConfigError(f"{str(path)!r}: not a regular file; expected a file path",
                          argument=argument)
    if path.is_file() and path.stat().st_size > 0:
        with open(path, "rb") as f:
            if f.read(len(HDF5_SIGNATURE)) != HDF5_SIGNATURE:
                raise ConfigError(f"{str(path)!r}: a file that is not HDF5 is there; "
                                  "expected a new path, or a dataset to replace",
                                  argument=argument)
        if foreign_hdf5(path):
            raise ConfigError(f"{str(path)!r}: an HDF5 file that is not an auvsim dataset is "
                              "there (another program's); expected a new path, or a dataset "
                              "to replace", argument=argument)
    if path.suffix.lower() in OTHER_FORMATS:
        raise ConfigError(f"{str(path)!r}: a {path.suffix} name for an HDF5 dataset; "
                          f"expected a .h5 name{hint}", argument=argument)
    return path


class DatasetWriter:
    """Writes a dataset file; use as a context manager.

    Args:
        path: the final file name; the work happens in a temporary file beside it
            (``check_output_path`` is what a command checks of a user's path first).
        config_json: the resolved configuration, stored in the root attributes.
        compression: a key of ``COMPRESSION``.
        argument: the argument that gave ``path``, which its errors name (``--out``).
        exclusive: refuse a path a live run of this host is writing (``files.Claim``).
    """

    def __init__(self, path: str | os.PathLike, *, config_json: str,
                 compression: str = "lzf", argument: str = "out",
                 exclusive: bool = True) -> None:
        self.path = Path(path)
        self.filters = COMPRESSION[compression]
        try:
            check_writable_path(self.path, argument)
            make_parent_dirs(self.path.parent)  # removed on failure, if left empty
            # Temporaries of killed runs in this folder go first (``files.sweep``).
            self.claim = Claim(self.path, exclusive=exclusive)
        except OSError as e:
            raise ConfigError(
                f"{str(self.path)!r}: cannot write there ({e.strerror or e}); "
                "expected a path in a writable directory", argument=argument) from None
        self.tmp = self.claim.file
        try:
            # No chunk cache: whole chunks are written at once, so caching them would only
            # defer their compression to the close, outside the physics/sensors overlap.
            with writing(self.path):
                self.file = h5py.File(self.tmp, "w", rdcc_nbytes=0)
        except BaseException:
            self.claim.release()
            raise
        self.file.attrs.update(
            format=FORMAT,
            format_version=FORMAT_VERSION,
            auvsim_version=__version__,
            created_utc=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            config_json=config_json,
        )
        self.file.create_group("missions")

    def mission(self, name: str, attrs: Mapping[str, object],
                rows: Mapping[str, int] | None = None,
                links: Mapping[str, str] | None = None) -> MissionWriter:
        """Start a mission.

        Args:
            name: the mission's name.
            attrs: its attributes (``mission_attrs``).
            rows: the expected rows per group (``truth``: N) or per dataset
                (``imu/index_of_dvl``: M), so datasets are made at their final size.
            links: fields to write as hard links to another (``imu/time`` ->
                ``truth/time``).
        """
        check_mission_name(name, "mission name")
        group = self.file["missions"].create_group(name)
        group.attrs.update(attrs)
        sink = MissionWriter(group, self.filters, rows)
        for key, target in (links or {}).items():
            sink.link(key, target)
        return sink

    def seal(self, config_sha256: str) -> str:
        """Make the file a shard: store the SHA-256 of the config that made its missions
        and the digest of their data (``data_digest``, of what was written); call after
        the last mission. Returns the digest."""
        digest = data_digest(self.file)
        self.file.attrs.update(config_sha256=config_sha256, data_sha256=digest)
        return digest

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        # Closing, renaming and releasing are one step for Ctrl-C: it comes after them, so
        # the output is either there whole (and ``commit`` recorded it) or not at all, and
        # no lock is left.
        with interrupts_held():
            try:
                with writing(self.path):
                    self.file.close()
                    if exc_type is None:
                        commit(self.tmp, self.path)
            finally:
                self.claim.release()  # the temporary file if still there, parts, lock
        if is_write_error(exc):  # a full disk as the data was written, say
            raise output_error(self.path, exc) from exc


class MissionWriter:
    """Appends time-major arrays to ``/missions/<name>/<group>/<field>``.

    Rows are buffered and written a whole HDF5 chunk at a time: a chunk written in two
    parts would be compressed twice and decompressed once in between. When the final
    number of rows of a group is known (``rows``), datasets are created at their final
    size (HDF5 allocates chunks only as they are written), which saves a resize per write.
    """

    def __init__(self, group: h5py.Group, filters: Mapping[str, object],
                 rows: Mapping[str, int] | None = None) -> None:
        self.group = group
        self.filters = filters
        self.rows = dict(rows or {})
        self.pending: dict[str, list[np.ndarray]] = {}
        self.datasets: dict[str, h5py.Dataset] = {}
        self.written: dict[str, int] = {}
        self.links: dict[str, str] = {}

    def link(self, key: str, target: str) -> None:
        """Make ``key`` an HDF5 hard link to dataset ``target`` (same data, written once):
        readers see an ordinary dataset. Rows appended under ``key`` are ignored."""
        self.links[key] = target

    def append(self, fields: Mapping[str, np.ndarray]) -> None:
        """Append rows; keys are paths such as ``truth/time``."""
        for key, values in fields.items():
            if key in self.links:
                continue
            parts = self.pending.setdefault(key, [])
            parts.append(np.asarray(values))
            if sum(len(p) for p in parts) >= CHUNK_ROWS:
                rows = np.concatenate(parts) if len(parts) > 1 else parts[0]
                whole = len(rows) - len(rows) % CHUNK_ROWS
                self._write(key, rows[:whole])
                self.pending[key] = [rows[whole:]] if whole < len(rows) else []

    def flush(self) -> None:
        """Write what is buffered (the mission's last, partial chunk)."""
        for key, parts in self.pending.items():
            if parts:
                self._write(key, np.concatenate(parts))
        self.pending.clear()
        for key, ds in self.datasets.items():
            if ds.shape[0] != self.written[key]:
                ds.resize(self.written[key], axis=0)  # fewer rows came than announced
        for key, target in self.links.items():
            self.group[key] = self.group[target]

    def _write(self, key: str, rows: np.ndarray) -> None:
        ds = self.datasets.get(key)
        if ds is None:
            n = max(self.rows.get(key, self.rows.get(key.split("/")[0], 0)), len(rows))
            ds = self.datasets[key] = self.group.create_dataset(
                key, shape=(n, *rows.shape[1:]), dtype=rows.dtype,
                maxshape=(None, *rows.shape[1:]), chunks=(CHUNK_ROWS, *rows.shape[1:]),
                **self.filters)
            self.written[key] = 0
        start = self.written[key]
        end = start + len(rows)
        if end > ds.shape[0]:
            ds.resize(end, axis=0)
        ds[start:end] = rows
        self.written[key] = end


def copy_mission(source: str | os.PathLike, name: str, writer: DatasetWriter) -> None:
    """Copy mission ``name`` of the dataset file ``source`` into ``writer``'s file, as it
    is stored (no recompression; hard links stay links)."""
    with h5py.File(source, "r") as part:
        part.copy(part[f"missions/{name}"], writer.file["missions"])

