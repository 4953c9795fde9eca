"""The one module that knows the file format (HDF5, schema v5 in docs/ARCHITECTURE.md).

Nothing else in auvsim or beamsnet opens an HDF5 file or spells a dataset path: writers
go through ``DatasetWriter`` (and ``mission_attrs``, ``copy_mission``), readers through
``open_dataset``, which checks a file before handing out typed, read-only ``Mission``
views. The schema is the core (truth, controls and mission attributes, here) plus the
fields and attributes each sensor plugin declares (``auvsim.sensors``).

Writing streams chunks into resizable, compressed datasets with a Fletcher-32 checksum
each, so memory stays flat in mission length and a flipped byte is refused when read; the
file is built under a temporary name and renamed when complete, so a failed or
interrupted run leaves nothing half-written behind.

A dataset is one file, or a folder of shards (each an ordinary dataset file holding some of
the missions, with the hash of the config that made it and a digest of its data) and an
index file whose missions are HDF5 external links into them (``write_index``): readers open
the folder, or its index, exactly as a file, and no data is copied.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from datetime import datetime, timezone
from functools import cache
from pathlib import Path

import h5py
import numpy as np

from auvsim import __version__
from auvsim.data.files import Claim, commit, interrupts_held, is_write_error, output_error, writing
from auvsim.errors import ConfigError, DatasetError
from auvsim.sensors import Attr, Field, Truth, registry

FORMAT = "auvsim-dataset"
# Version 2 = version 1 + a mission attribute ``origin``, which lets a mission imported from
# a recorded DVL stream hold only its DVL group. Version 3 = version 2 + the depth sensor's
# group and attributes, and a Fletcher-32 checksum on every dataset. Version 4 = version 3
# + the realism of issue 10: the water's current in the truth, the DVL's status codes,
# error velocity and mode, and the new realised sensor parameters (each ``Field`` and
# ``Attr`` says ``since=4``). Version 5 = version 4 + sharded datasets: shard files carry
# the root attributes ``config_sha256`` and ``data_sha256`` (``data_digest``), and an index
# file (root attribute ``layout = "index"``) links their missions. Older files are read.
FORMAT_VERSION = 5
READABLE_VERSIONS = (1, 2, 3, 4, 5)
INDEX = "index.h5"  # a sharded dataset's index, in its folder
SHARDS = "shards"  # the folder of its shards, beside the index
ORIGINS = ("simulated", "imported")
CHUNK_ROWS = 6000  # rows per HDF5 chunk: 60 s at 100 Hz, 48 kB for a float64 column
# lzf: fast, built into h5py; gzip (level 1): about 1.5x the writing cost, but every HDF5
# tool reads it without a plugin. Fletcher-32 costs a few % and catches corruption.
COMPRESSION = {"lzf": dict(compression="lzf", shuffle=True, fletcher32=True),
               "gzip": dict(compression="gzip", compression_opts=1, shuffle=True,
                            fletcher32=True)}

# The core of every simulated mission; the sensors add their own (``schema``).
CORE_FIELDS = (
    Field("truth/time", (), "f", "imu", "s", "at the IMU rate"),
    Field("truth/position_ned", (3,), "f", "imu", "m", "body origin"),
    Field("truth/velocity_ned", (3,), "f", "imu", "m/s", ""),
    Field("truth/velocity_body", (3,), "f", "imu", "m/s", "at the vehicle origin"),
    Field("truth/quaternion", (4,), "f", "imu", "-", "body -> NED, [w, x, y, z]"),
    Field("truth/angular_rate", (3,), "f", "imu", "rad/s", "body"),
    Field("truth/specific_force", (3,), "f", "imu", "m/s^2", "body, at the IMU"),
    Field("truth/altitude", (), "f", "imu", "m", "body origin above the seafloor below it"),
    Field("truth/current_ned", (3,), "f", "imu", "m/s",
          "the water's current at the body origin, NED (auvsim.physics.water)", since=4),
    Field("truth/velocity_water_body", (3,), "f", "imu", "m/s",
          "body origin's velocity through the water, body FRD", since=4),
    Field("control/propeller_rpm", (), "f", "imu", "rpm", "shaft speed reached"),
    Field("control/thrust", (), "f", "imu", "N", "propeller thrust"),
    Field("control/rudder", (), "f", "imu", "rad", "rudder angle reached"),
    Field("control/stern_planes", (), "f", "imu", "rad", "stern-plane angle reached"),
)
CORE_ATTRS = (
    Attr("origin", None, "simulated or imported", imported=True),
    Attr("scenario", None, "the manoeuvre's name", imported=True),
    Attr("seed", (), "the mission's seed", imported=True, low=0, whole=True),
    Attr("duration_s", (), "s", imported=True, low=0, strict=True),
    Attr("vehicle", None, "vehicle name or model path"),
    Attr("water_surface_speed", (), "REALISED surface speed of the mission's current, m/s "
         "(before its variation in time and space; auvsim.physics.water)", low=0, since=4),
    Attr("water_direction_deg", (), "REALISED direction the surface current flows toward, "
         "deg from north", since=4),
)
IMPORT_ATTRS = (Attr("source_file", None, "the recording"),
                Attr("source_sha256", None, "its SHA-256"))


def core_block(truth: Truth, *, propeller_rpm: np.ndarray, thrust: np.ndarray,
               rudder: np.ndarray, stern_planes: np.ndarray,
               altitude: np.ndarray) -> dict[str, np.ndarray]:
    """The core fields of one block, by path: the truth (``auvsim.sensors.Truth``), the
    altitude and the controls, (N,) each at the truth's samples (rpm, N, rad, rad, m)."""
    return {
        "truth/time": truth.time,
        "truth/position_ned": truth.position_ned,
        "truth/velocity_ned": truth.velocity_ned,
        "truth/velocity_body": truth.velocity_body,
        "truth/quaternion": truth.quaternion,
        "truth/angular_rate": truth.angular_rate,
        "truth/specific_force": truth.specific_force,
        "truth/altitude": altitude,
        "truth/current_ned": truth.current_ned,
        "truth/velocity_water_body": truth.velocity_water_body,
        "control/propeller_rpm": propeller_rpm,
        "control/thrust": thrust,
        "control/rudder": rudder,
        "control/stern_planes": stern_planes,
    }


@cache
def schema(origin: str, version: int = FORMAT_VERSION) -> tuple[tuple[Field, ...],
                                                                 tuple[Attr, ...]]:
    """The fields and attributes every mission of this origin holds in a file of this
    format version (extra ones are allowed)."""
    sensors = [s for s in registry().values() if s.since_version <= version]
    fields = tuple(f for f in CORE_FIELDS + tuple(f for s in sensors for f in s.fields)
                   if f.since <= version)
    attrs = tuple(a for a in CORE_ATTRS + tuple(a for s in sensors for a in s.attributes)
                  if a.since <= version)
    if origin == "imported":
        return (tuple(f for f in fields if f.imported),
                tuple(a for a in attrs if a.imported) + IMPORT_ATTRS)
    return fields, attrs


def mission_attrs(*, origin: str, **attrs) -> dict[str, object]:
    """A mission's attributes, checked complete for its origin: the one builder, used by
    every writer (``auvsim.runs.mission``, ``auvsim.data.importer``, the environment's recorder)."""
    if origin not in ORIGINS:
        raise ValueError(f"origin: expected one of {', '.join(ORIGINS)}, got {origin!r}")
    out = dict(origin=origin, **attrs)
    missing = [a.name for a in schema(origin)[1] if a.name not in out]
    if missing:
        raise ValueError(f"mission attributes: {origin} missions need {', '.join(missing)}")
    return out


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
        try:
            if self.path.is_dir():
                raise ConfigError(f"{str(self.path)!r} is a directory: expected a file name "
                                  f"(or {os.path.join(str(self.path), '')!r}, with a trailing "
                                  "/, for a sharded dataset)", argument="out")
            self.path.parent.mkdir(parents=True, exist_ok=True)
            # Temporaries of killed runs in this folder go first (``files.sweep``).
            self.claim = Claim(self.path)
        except OSError as e:
            raise ConfigError(
                f"{str(self.path)!r}: cannot write there ({e.strerror or e}); "
                "expected a path in a writable directory", argument="out") from None
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


def data_digest(file: h5py.File) -> str:
    """SHA-256 of a dataset file's missions: every mission's attributes and the values of
    every field (dtype, shape and bytes, by path in name order). The same data give the
    same digest however, whenever and wherever they were written."""
    digest = hashlib.sha256()

    def add(group: h5py.Group, prefix: str) -> None:
        for key in sorted(group.attrs):
            value = np.asarray(group.attrs[key])
            digest.update(f"{prefix}@{key}:{value.dtype.str}{value.shape}".encode())
            digest.update(value.astype(str).tobytes() if value.dtype.kind == "O"
                          else value.tobytes())
        for key in sorted(group):
            item = group[key]
            if isinstance(item, h5py.Group):
                add(item, f"{prefix}/{key}")
            else:
                values = np.ascontiguousarray(item[()])
                digest.update(f"{prefix}/{key}:{values.dtype.str}{values.shape}".encode())
                digest.update(values.tobytes())

    add(file["missions"], "")
    return digest.hexdigest()


@dataclass(frozen=True)
class Shard:
    """One shard of a sharded dataset, as its index records it.

    Attributes:
        file: its file name in the ``SHARDS`` folder.
        missions: the names of its missions, in dataset order.
        config_sha256: SHA-256 of the config its missions were simulated from.
        data_sha256: the digest of its data (``data_digest``).
    """

    file: str
    missions: tuple[str, ...]
    config_sha256: str
    data_sha256: str


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
            attrs, file = f.attrs, f._file
            if attrs.get("config_sha256") != config_sha256 or "data_sha256" not in attrs:
                return None
            if data_digest(file) != attrs["data_sha256"]:
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


# Reading ---------------------------------------------------------------------------------

class Block:
    """A block of a mission's fields keyed by path (``MissionRun.measure``'s), read as a
    mission is: ``Block(arrays).dvl.beam_velocity``."""

    def __init__(self, arrays: Mapping[str, np.ndarray]) -> None:
        self._arrays = arrays

    def __getattr__(self, group: str) -> _BlockGroup:
        if group.startswith("_"):
            raise AttributeError(group)
        return _BlockGroup(self._arrays, group)


class _BlockGroup:
    def __init__(self, arrays: Mapping[str, np.ndarray], group: str) -> None:
        self._arrays, self._group = arrays, group

    def __getattr__(self, field: str) -> np.ndarray:
        if field.startswith("_"):
            raise AttributeError(field)
        return self._arrays[f"{self._group}/{field}"]


_KINDS = {"f": "float", "b": "bool", "i": "integer"}


class Group:
    """One group of a mission (``truth``, ``imu``, ``dvl``, ``control``, a sensor's),
    read-only: ``group.velocity`` reads that field whole (a numpy array)."""

    def __init__(self, mission: Mission, name: str) -> None:
        self._mission = mission
        self._name = name

    def __contains__(self, field: str) -> bool:
        return field in self._mission._fields(self._name)

    def __iter__(self) -> Iterator[str]:
        return iter(self._mission._fields(self._name))

    @property
    def rows(self) -> int:
        """Rows of the group's fields (of its first field)."""
        first = next(iter(self._mission._fields(self._name)))
        return self._mission._dataset(f"{self._name}/{first}").shape[0]

    def __getattr__(self, field: str) -> np.ndarray:
        if field.startswith("_"):
            raise AttributeError(field)
        return self._mission.read(f"{self._name}/{field}")


class Mission:
    """A mission of an open dataset: its ``name``, ``origin``, ``attrs`` (plain Python
    values and numpy arrays, the realised error parameters among them) and groups as
    attributes (``mission.truth.position_ned``, ``mission.dvl.beam_velocity``)."""

    def __init__(self, dataset: Dataset, name: str, group: h5py.Group, origin: str) -> None:
        self.dataset = dataset
        self.name = name
        self.origin = origin
        self._group = group
        self._where = _where(Path(group.file.filename), name, origin)  # a shard's, if one
        self.attrs = _plain(group.attrs)
        self.attrs.setdefault("origin", origin)

    @property
    def groups(self) -> list[str]:
        """The groups it holds (``truth``, ``imu``, ``dvl``, ...), in name order."""
        return sorted(k for k, v in self._group.items() if isinstance(v, h5py.Group))

    def has(self, group: str) -> bool:
        """Whether the mission holds this group (an imported one has only ``dvl``)."""
        return isinstance(self._group.get(group), h5py.Group)

    def __getattr__(self, group: str) -> Group:
        if group.startswith("_") or not self.has(group):
            raise AttributeError(f"mission {self.name} has no group {group!r}")
        return Group(self, group)

    def read(self, path: str) -> np.ndarray:
        """One field, whole; a field that fails its checksum or cannot be decoded is
        refused with ``DatasetError`` naming the file, the mission and the field."""
        return _read(self._where, path, self._dataset(path))

    def _dataset(self, path: str) -> h5py.Dataset:
        item = self._group.get(path)
        if not isinstance(item, h5py.Dataset):
            raise DatasetError(f"{self._where} has no field {path}")
        return item

    def _fields(self, group: str) -> list[str]:
        g = self._group.get(group)
        return [k for k, v in g.items() if isinstance(v, h5py.Dataset)] \
            if isinstance(g, h5py.Group) else []


class Dataset:
    """An open, checked dataset file (``open_dataset``); use as a context manager.

    Attributes:
        path: the file (a sharded dataset's index).
        version: its format version.
        attrs: the root attributes (``config_json``, ``created_utc``, ...).
        missions: name -> ``Mission``, in the file's order.
        shards: a sharded dataset's shard files, in index order; empty for one file.
    """

    def __init__(self, path: Path, file: h5py.File) -> None:
        self.path = path
        self._file = file
        self.attrs = _plain(file.attrs)
        self.version = int(self.attrs["format_version"])
        self.missions: dict[str, Mission] = {}
        self.shards: list[Path] = []
        self._shard_files: dict[Path, h5py.File] = {}

    @property
    def config_json(self) -> str:
        return str(self.attrs.get("config_json", ""))

    def verify(self) -> None:
        """Read every dataset of every mission (extra ones too), so each checksum is
        verified; the first that fails is refused (``DatasetError``)."""
        for mission in self.missions.values():
            for key in _dataset_paths(mission._group):
                mission.read(key)

    def close(self) -> None:
        for shard in self._shard_files.values():
            shard.close()
        self._file.close()

    def __enter__(self) -> Dataset:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open_dataset(path: str | os.PathLike, *, verify: bool = False) -> Dataset:
    """Open an auvsim dataset for reading, after checking that it is one and that every
    mission has every field and attribute of its origin with the right shape and type,
    fields of one clock of equal length (at least one row), sample times finite and
    increasing, and indices in range.

    Args:
        path: the file, or a sharded dataset's folder or its index (``INDEX``): its
            shards must be there, each the one the index lists.
        verify: also read every field now, checking its checksum (``Dataset.verify``);
            otherwise a corrupt field is refused when it is read.

    Raises:
        DatasetError: the file is missing, not HDF5, not an auvsim dataset, of another
            format version, inconsistent or corrupt, or a shard is missing or another
            run's; the message is one line naming the file (the shard) and, where there
            is one, the mission and the field.
    """
    path = Path(path)
    if path.is_dir() and (path / INDEX).exists():
        path = path / INDEX
    elif path.is_dir():
        raise DatasetError(f"{path}: is a directory with no {INDEX}; expected an auvsim "
                           "dataset file or a sharded dataset's folder (auvsim generate "
                           "writes its index last: run it again to finish the dataset)")
    if not path.exists():
        raise DatasetError(f"{path}: no such file")
    if not path.is_file():
        raise DatasetError(f"{path}: not a regular file; expected an auvsim dataset file")
    try:
        open(path, "rb").close()  # plain open: its OSError says what is wrong
    except OSError as e:
        raise DatasetError(f"{path}: cannot read it ({e.strerror or _reason(e)})") from None
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise DatasetError(f"{path}: not an HDF5 file, or corrupt ({_reason(e)})") from None
    try:
        dataset = _checked(path, f)
        if verify:
            dataset.verify()
    except DatasetError:
        f.close()
        raise
    except (KeyError, OSError, ValueError, TypeError, RuntimeError) as e:
        f.close()
        raise DatasetError(f"{path}: corrupt auvsim dataset ({_reason(e)})") from None
    return dataset


def _checked(path: Path, f: h5py.File) -> Dataset:
    if "format" not in f.attrs:
        raise DatasetError(f"{path}: not an auvsim dataset (no format attribute; expected "
                           f"{FORMAT!r})")
    fmt = f.attrs["format"]
    if not (isinstance(fmt, str) and fmt == FORMAT):
        raise DatasetError(f"{path}: not an auvsim dataset (format attribute is "
                           f"{_show(fmt)}; expected {FORMAT!r})")
    readable = ", ".join(map(str, READABLE_VERSIONS))
    if "format_version" not in f.attrs:
        raise DatasetError(f"{path}: auvsim dataset with no format_version attribute; this "
                           f"auvsim reads versions {readable}")
    version = f.attrs["format_version"]
    if not isinstance(version, (int, np.integer)) or version not in READABLE_VERSIONS:
        newer = (isinstance(version, (int, np.integer)) and version > FORMAT_VERSION)
        raise DatasetError(f"{path}: auvsim dataset format_version {_show(version)}; this "
                           f"auvsim reads versions {readable}"
                           + (" (the file is from a newer auvsim)" if newer else ""))
    version = int(version)
    if not isinstance(f.get("missions"), h5py.Group):
        raise DatasetError(f"{path}: corrupt auvsim dataset (no missions group)")
    dataset = Dataset(path, f)
    layout = f.attrs.get("layout", "file")
    if layout not in ("file", "index"):
        raise DatasetError(f"{path}: auvsim dataset with layout {_show(layout)}; expected "
                           "'file' or 'index'")
    records = _index_records(path, f) if layout == "index" else None
    try:
        _check_missions(path, f, dataset, records, version)
    except BaseException:
        for shard in dataset._shard_files.values():
            shard.close()
        raise
    return dataset


def _check_missions(path: Path, f: h5py.File, dataset: Dataset,
                    records: dict[str, Shard] | None, version: int) -> None:
    for name in f["missions"]:
        group = (f["missions"][name] if records is None
                 else _shard_group(path, f, name, records, dataset))
        if not isinstance(group, h5py.Group):
            raise DatasetError(f"{path}: missions/{name} is not a mission group")
        expected = f"expected one of {', '.join(ORIGINS)} (schema v{version})"
        if "origin" not in group.attrs and version >= 2:
            raise DatasetError(f"{path}: mission {name} has no origin attribute; {expected}")
        origin = group.attrs.get("origin", "simulated")
        if not (isinstance(origin, str) and origin in ORIGINS):
            raise DatasetError(f"{path}: mission {name} has origin {_show(origin)}; "
                               f"{expected}")
        _check_mission(path, name, group, origin, version)
        dataset.missions[name] = Mission(dataset, name, group, origin)


def _index_records(path: Path, f: h5py.File) -> dict[str, Shard]:
    """An index's shard records by mission name."""
    records = []
    try:
        for r in json.loads(f.attrs["shards"]):
            missions = r["missions"]
            if not (isinstance(missions, list) and all(isinstance(m, str) for m in missions)
                    and all(isinstance(r[k], str) for k in ("file", "config_sha256",
                                                            "data_sha256"))):
                raise ValueError("expected a file name, a list of mission names and two "
                                 "hashes per shard")
            records.append(Shard(r["file"], tuple(missions), r["config_sha256"],
                                 r["data_sha256"]))
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"{path}: corrupt auvsim index (its shards attribute: "
                           f"{_reason(e)})") from None
    return {name: r for r in records for name in r.missions}


def _shard_group(path: Path, f: h5py.File, name: str, records: dict[str, Shard],
                 dataset: Dataset) -> h5py.Group:
    """Mission ``name`` of an index, in its shard, after checking that the shard is there
    and is the one the index lists (sealed with the same config hash)."""
    link = f["missions"].get(name, getlink=True)
    if (not isinstance(link, h5py.ExternalLink) or name not in records
            or link.filename != f"{SHARDS}/{records[name].file}"
            or link.path != f"/missions/{name}"):
        raise DatasetError(f"{path}: missions/{name} is not a link to the shard the index "
                           "lists; expected an index written by auvsim generate")
    shard = path.parent / link.filename
    if not shard.is_file():
        raise DatasetError(f"{path}: mission {name}'s shard {link.filename} is missing; "
                           f"expected every shard the index lists in {path.parent / SHARDS} "
                           "(running the same auvsim generate again makes it)")
    file = dataset._shard_files.get(shard)
    try:
        if file is None:  # each shard opened once, whatever its number of missions
            file = h5py.File(shard, "r")
        group = file["missions"][name]
    except (KeyError, OSError) as e:
        if file is not None and shard not in dataset._shard_files:
            file.close()
        raise DatasetError(f"{shard}: cannot be read as the shard of mission {name} "
                           f"({_reason(e)}); the shard is corrupt or not an auvsim "
                           "dataset") from None
    if shard not in dataset._shard_files:
        dataset.shards.append(shard)
        dataset._shard_files[shard] = file  # closed with the dataset
    if file.attrs.get("format") != FORMAT or file.attrs.get("config_sha256") != \
            records[name].config_sha256:
        raise DatasetError(f"{shard}: not the shard the index {path} lists (another config "
                           "or run wrote it since); expected the shards of one auvsim "
                           "generate run (running it again makes them agree)")
    return group


def _check_mission(path: Path, name: str, group: h5py.Group, origin: str,
                   version: int) -> None:
    fields, attrs = schema(origin, version)
    where = _where(Path(group.file.filename), name, origin)
    missing = [fl.path for fl in fields if not isinstance(group.get(fl.path), h5py.Dataset)]
    missing += [f"attribute {a.name}" for a in attrs
                if a.name not in group.attrs and not (a.name == "origin" and version == 1)]
    if missing:
        raise DatasetError(f"{where} lacks {', '.join(missing)} (schema v{version})")
    for a in attrs:  # attributes first: they are small, and say what the fields mean
        if a.name not in group.attrs:
            continue
        value = group.attrs[a.name]
        if a.shape is None:
            ok = isinstance(value, str)
            expected = "a string"
        else:
            array = np.asarray(value)
            ok = (array.dtype.kind in "iuf" and array.shape == a.shape
                  and bool(np.isfinite(array).all()))
            expected = ("a finite number" if a.shape == () else
                        f"{a.shape[0]} finite numbers")
            if ok and a.whole:
                ok, expected = array.dtype.kind in "iu", "a whole number"
            if ok and a.low is not None:
                ok = bool((array > a.low).all() if a.strict else (array >= a.low).all())
                expected = f"{'a number above' if a.strict else 'a number of at least'} {a.low:g}"
        if not ok:
            raise DatasetError(f"{where}: attribute {a.name} is {_show(value)}; expected "
                               f"{expected}")
    rows: dict[str, tuple[int, str]] = {}
    for fl in fields:
        ds = group[fl.path]
        expected = ("N", *fl.shape)
        if ds.ndim != 1 + len(fl.shape) or ds.shape[1:] != fl.shape:
            raise DatasetError(f"{where}: field {fl.path} has shape {_shape(ds.shape)}; "
                               f"expected {_shape(expected)}")
        if ds.dtype.kind != fl.kind and not (fl.kind == "i" and ds.dtype.kind == "u"):
            raise DatasetError(f"{where}: field {fl.path} holds {_dtype(ds.dtype)}; "
                               f"expected {_KINDS[fl.kind]} values")
        n = ds.shape[0]
        if fl.clock in rows and rows[fl.clock][0] != n:
            other, first = rows[fl.clock][0], rows[fl.clock][1]
            raise DatasetError(f"{where}: field {fl.path} has {n} rows but {first} has "
                               f"{other}; expected fields of one clock to have equal rows")
        rows.setdefault(fl.clock, (n, fl.path))
    for n, first in rows.values():
        if n == 0:
            raise DatasetError(f"{where}: field {first} has no rows; expected at least one "
                               "sample")
    times: dict[str, tuple[np.ndarray, str]] = {}  # clock -> its sample times, their field
    for fl in fields:
        if fl.path.rsplit("/", 1)[-1] == "time" and fl.clock not in times:
            t = _read(where, fl.path, group[fl.path])
            _check_times(where, fl.path, t)
            times[fl.clock] = t, fl.path
    for fl in fields:
        if fl.index_of is None or fl.index_of not in rows:
            continue
        index = _read(where, fl.path, group[fl.path])
        limit, target = rows[fl.index_of]
        if index.min() < 0 or index.max() >= limit:
            raise DatasetError(f"{where}: field {fl.path} holds indices from {index.min()} "
                               f"to {index.max()}; expected indices in [0, {limit}) (the "
                               f"rows of {target})")
        if fl.clock in times and fl.index_of in times:
            # Each index is the sample of the other clock at this row's time (a ping's
            # IMU sample): an index in range but off by some rows would cut the wrong data.
            (own, own_path), (other, other_path) = times[fl.clock], times[fl.index_of]
            step = float(np.diff(other).min()) if len(other) > 1 else np.inf
            bad = np.flatnonzero(np.abs(other[index] - own) > step / 2)
            if len(bad):
                k = bad[0]
                raise DatasetError(
                    f"{where}: field {fl.path} row {k} is {index[k]}, the sample of "
                    f"{other_path} at {other[index[k]]:.9g} s, but {own_path} is "
                    f"{own[k]:.9g} s there; expected the index of the sample at that time")


def _check_times(where: str, path: str, t: np.ndarray) -> None:
    """Sample times must be finite and strictly increasing (every reader indexes by them,
    and a plot's axes cannot hold NaN)."""
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise DatasetError(f"{where}: field {path} holds {t[bad[0]]} at row {bad[0]}; "
                           "expected finite sample times")
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        k = back[0]
        raise DatasetError(f"{where}: field {path} goes from {t[k]:.9g} s to {t[k + 1]:.9g} "
                           f"s at row {k + 1}; expected increasing sample times")


def _read(where: str, path: str, ds: h5py.Dataset) -> np.ndarray:
    """A dataset whole; one that fails its checksum or cannot be decoded is refused with a
    ``DatasetError`` naming the field, not read as data."""
    try:
        return ds[()]
    except OSError as e:
        text = str(e).lower()
        # HDF5 says only "filter returned failure": with Fletcher-32 on, that filter runs
        # first when reading, so a changed byte fails it before decompression is tried.
        checksum = (ds.fletcher32 and "filter" in text) or "checksum" in text
        what = "fails its checksum" if checksum else "cannot be read"
        raise DatasetError(f"{where}: field {path} {what} (HDF5: {_reason(e)}); the file "
                           "is corrupt") from None


def _dataset_paths(group: h5py.Group) -> list[str]:
    """The paths of every dataset under ``group``, at any depth, in the file's order."""
    paths: list[str] = []

    def visit(key: str, item: object) -> None:
        if isinstance(item, h5py.Dataset):
            paths.append(key)

    group.visititems(visit)
    return paths


def _where(path: Path, name: str, origin: str) -> str:
    return f"{path}: mission {name} ({origin})"


def _shape(shape: tuple) -> str:
    return "(" + ", ".join(map(str, shape)) + ("," if len(shape) == 1 else "") + ")"


def _dtype(dtype: np.dtype) -> str:
    if dtype.kind in "SUO":
        return f"strings ({dtype})"
    return str(dtype) if dtype.names is None else "a compound type"


def _show(value: object, limit: int = 80) -> str:
    """A value from a file as one short line: strings quoted, numbers and arrays as numpy
    prints them (numpy scalars without their type), long ones cut."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        text = np.array2string(value, threshold=8, edgeitems=3, max_line_width=10**6)
        if value.ndim > 1 or value.size > 8:
            text += f" (shape {_shape(value.shape)})"
    else:
        text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _reason(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__


def _plain(attrs) -> dict:
    return {k: v.item() if isinstance(v, np.generic) else v for k, v in attrs.items()}


def read_attrs(path: str | os.PathLike) -> tuple[dict, dict[str, dict]]:
    """The root attributes of a dataset and each mission's attributes, as plain Python
    values (numpy arrays for vectors), after ``open_dataset``'s checks."""
    with open_dataset(path) as f:
        return f.attrs, {name: m.attrs for name, m in f.missions.items()}


def _describe_v4(m: Mission, a: dict, fmt) -> list[str]:
    """The lines of what schema v4 added, where the mission has it: the DVL's realised
    calibration, its beams' status codes, modes and error velocity, and the current."""
    from auvsim.sensors.dvl import Mode, Status

    lines = []
    if "dvl_sound_speed_ratio" in a:
        lines.append(f"    DVL calibration: sound-speed ratio {a['dvl_sound_speed_ratio']:.6f}, "
                     f"misalignment {fmt(a['dvl_misalignment_rpy_deg'])} deg (roll, pitch, "
                     "yaw)")
    dvl = m.dvl
    if "status" in dvl:
        status = dvl.status
        counts = np.bincount(status.ravel().clip(0, len(Status) - 1), minlength=len(Status))
        shares = ", ".join(f"{Status(code).name.lower()} {100 * n / status.size:.1f} %"
                           for code, n in enumerate(counts) if n)
        lines.append(f"    DVL beam status: {shares}")
    if "mode" in dvl:
        mode = dvl.mode
        shares = ", ".join(f"{x.name.lower().replace('_', ' ')} "
                           f"{100 * np.mean(mode == x):.1f} %" for x in Mode)
        error = dvl.error_velocity
        finite = error[np.isfinite(error)]
        rms = f"{np.sqrt(np.mean(finite**2)):.3g} m/s" if finite.size else "none"
        lines.append(f"    DVL modes: {shares}; error velocity rms {rms} over "
                     f"{finite.size} four-beam pings")
    if "water_surface_speed" in a:
        lines.append(f"    water: surface current {a['water_surface_speed']:.3f} m/s toward "
                     f"{a['water_direction_deg'] % 360:.0f} deg (drawn for the mission)")
    if m.has("truth") and "current_ned" in m.truth:
        current = m.truth.current_ned
        speed = np.hypot(current[:, 0], current[:, 1])
        mean = current.mean(axis=0)
        toward = np.degrees(np.arctan2(mean[1], mean[0])) % 360
        lines.append(f"    current at the vehicle: {speed.min():.3f} to {speed.max():.3f} m/s "
                     f"(mean {np.hypot(mean[0], mean[1]):.3f} m/s toward {toward:.0f} deg)")
    return lines


def describe(path: str | os.PathLike) -> str:
    """A human-readable summary of a dataset: missions, durations, rates, DVL validity,
    the realised error parameters and the fields. Every field is read, so a corrupt one
    is refused here (``DatasetError``)."""
    def fmt(values) -> str:
        return np.array2string(np.asarray(values), precision=6, separator=", ")

    with open_dataset(path, verify=True) as f:
        sharded = f" in {len(f.shards)} shard(s) of {f.path.parent / SHARDS}" if f.shards \
            else ""
        lines = [f"{path}: auvsim dataset v{f.version} "
                 f"(auvsim {f.attrs.get('auvsim_version', '?')}, created "
                 f"{f.attrs.get('created_utc', '?')}), {len(f.missions)} mission(s)"
                 + sharded]
        for name, m in f.missions.items():
            a = m.attrs
            valid = m.dvl.valid
            solvable = (f"{100 * valid.mean():.1f} % of beams valid, "
                        f"{100 * (valid.sum(axis=1) >= 3).mean():.1f} % of pings solvable")
            if m.origin == "imported":
                lines += [
                    f"  {name}: imported from {a['source_file']} (sha256 "
                    f"{a['source_sha256'][:12]}...), seed {a['seed']}, {a['duration_s']:g} s",
                    f"    DVL {a['dvl_rate_hz']:g} Hz ({len(valid)} pings), beams at "
                    f"{a['beam_angle_deg']:g} deg, {solvable}; no truth, IMU or controls",
                ]
            else:
                lines += [
                    f"  {name}: {a['scenario']}, seed {a['seed']}, {a['duration_s']:g} s, "
                    f"vehicle {a['vehicle']}",
                    f"    IMU {a['imu_rate_hz']:g} Hz ({m.imu.rows} samples); DVL "
                    f"{a['dvl_rate_hz']:g} Hz ({len(valid)} pings), beams at "
                    f"{a['beam_angle_deg']:g} deg, {solvable}",
                ]
            lines.append(f"    DVL errors: scale factor {fmt(a['dvl_scale_factor'])}, bias "
                         f"{fmt(a['dvl_bias'])} m/s, noise std {a['dvl_noise_std']:g} m/s")
            lines += _describe_v4(m, a, fmt)
            if "imu_accel_turn_on_bias" in a:
                lines.append(
                    f"    IMU errors: accel turn-on bias {fmt(a['imu_accel_turn_on_bias'])} "
                    f"m/s^2, gyro {fmt(a['imu_gyro_turn_on_bias'])} rad/s; noise densities "
                    f"{a['imu_accel_noise_density']:.3g} m/s^2/rtHz, "
                    f"{a['imu_gyro_noise_density']:.3g} rad/s/rtHz")
            if "imu_accel_scale_factor" in a:  # v4
                largest = {k: f"{np.max(np.abs(a[f'imu_{k}'])):.3g}" for k in (
                    "accel_misalignment", "gyro_misalignment", "gyro_g_sensitivity")}
                lines.append(
                    f"    IMU calibration: scale factors accel "
                    f"{fmt(a['imu_accel_scale_factor'])}, gyro {fmt(a['imu_gyro_scale_factor'])};"
                    f" largest misalignment accel {largest['accel_misalignment']}, gyro "
                    f"{largest['gyro_misalignment']} rad; largest g-sensitivity "
                    f"{largest['gyro_g_sensitivity']} rad/s per m/s^2; bias correlation "
                    f"times accel {a['imu_accel_bias_correlation_time']:g} s, gyro "
                    f"{a['imu_gyro_bias_correlation_time']:g} s")
            if "depth_rate_hz" in a:
                lines.append(
                    f"    depth sensor {a['depth_rate_hz']:g} Hz ({m.depth.rows} samples): "
                    f"offset {a['depth_bias']:.4g} m, noise std {a['depth_noise_std']:g} m, "
                    f"resolution {a['depth_resolution']:g} m")
        first = next(iter(f.missions.values()), None)
        if first is not None:
            lines.append("  fields of each mission:")
            for group in first.groups:
                lines.append(f"    {group}: " + ", ".join(sorted(Group(first, group))))
        return "\n".join(lines)
