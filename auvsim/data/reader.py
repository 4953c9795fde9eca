"""Reading a dataset: ``open_dataset`` checks a file (or a sharded dataset's folder)
against the schema (``auvsim.data.schema``) before handing out typed, read-only
``Mission`` views; nothing else in auvsim or beamsnet opens an HDF5 dataset or spells a
dataset path.
"""

from __future__ import annotations

import json
import os
import reprlib
import time
from collections.abc import Iterator, Mapping
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import h5py
import numpy as np

from auvsim.data.schema import (
    FORMAT,
    FORMAT_VERSION,
    INDEX,
    ORIGINS,
    READABLE_VERSIONS,
    RECORDED_SINCE,
    SHARDS,
    Phases,
    Shard,
    data_digest,
    parse_groups,
    parse_phases,
    recorded_schema,
    schema,
)
from auvsim.errors import ConfigError, DatasetError, MissingFieldError
from auvsim.sensors.dvl import usable_beams

if TYPE_CHECKING:
    import xarray


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
# The files this process has checked whole, by what identifies their contents (``_identity``:
# the same inode, size, modification and status-change times), each with its shards'
# identities: opened again unchanged, a file skips the per-mission schema check, which
# reads every mission's clocks and indices (a tool that opens its file once per mission
# would otherwise check every mission each time). The status-change time (ctime) moves with
# any change of the file, and no one can set it back (a modification time can be). Only a
# file whose ctime is ``QUIET_S`` old at its check, and which is still the same file after
# it, is kept: the kernel stamps these times at its clock tick (a few ms), so a file
# changed in place within a tick of its check could keep them; one changed later gets a
# later ctime. Forgotten beyond ``CHECKED_FILES``. Each keeps its missions' attributes
# too (``Mission.attrs``), which such a file gives again without reading them: reading a
# mission's attributes costs h5py about 40 reads of 0.1 ms, a tool opening a file of 20
# missions once per mission pays it 400 times over.
_CHECKED: dict[tuple, Checked] = {}
CHECKED_FILES = 256
QUIET_S = 1.0
REMEMBER_CHECKED = True  # False: check every mission at every open


class Checked(NamedTuple):
    """A file ``open_dataset`` checked whole: its shards' identities and its missions'
    attributes (plain values, as ``Mission.attrs``), by mission name."""

    shards: tuple[tuple, ...]
    attrs: dict[str, dict]


def _copied(attrs: dict) -> dict:
    """Mission attributes a caller may change without changing the remembered ones."""
    return {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in attrs.items()}


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

    def __dir__(self) -> list[str]:  # its fields too, for a notebook's completion
        return sorted({*super().__dir__(), *self._mission._fields(self._name)})

    def __getattr__(self, field: str) -> np.ndarray:
        if field.startswith("_"):
            raise AttributeError(field)
        if field not in self._mission._fields(self._name):
            raise MissingFieldError(f"{self._mission._where} has no field "
                                    f"{self._name}/{field}")
        return self._mission.read(f"{self._name}/{field}")


# A mission's attributes that hold JSON, and what each holds: checked with its others
# (``_check_mission``), so that a damaged or hand-edited one is refused in one line, not
# met as a traceback by whichever reader parses it.
JSON_ATTRS = {"source_files": list, "check_log_json": dict}  # phases, groups: their parsers


def _json_of(text, kind: type, what: str):
    """``text`` parsed as JSON holding a ``kind``.

    Raises:
        DatasetError: it is not (``what`` names the file and the attribute).
    """
    try:
        value = json.loads(text)
    except (TypeError, ValueError):
        value = None
    if not isinstance(value, kind):
        raise DatasetError(f"{what} is not a JSON {kind.__name__} ({reprlib.repr(text)}): "
                           "damaged, or edited by hand; expected the file as auvsim wrote it")
    return value


class Mission:
    """A mission of an open dataset: its ``name``, ``origin``, ``attrs`` (plain Python
    values and numpy arrays, the realised error parameters among them) and groups as
    attributes (``mission.truth.position_ned``, ``mission.dvl.beam_velocity``).

    A recorded mission (schema v7) has a ``reference`` (a navigation solution) where a
    simulated one has its ``truth``; asking it for ``truth`` is refused in one line."""

    def __init__(self, dataset: Dataset, name: str, group: h5py.Group, origin: str,
                 attrs: dict | None = None) -> None:
        self.dataset = dataset
        self.name = name
        self.origin = origin
        self._group = group
        self._field_names: dict[str, list[str]] = {}  # ``_fields``, by group
        self._items: dict[str, h5py.HLObject | None] = {}  # ``_item``, by path
        self._where = _where(Path(group.file.filename), name, origin)  # a shard's, if one
        # ``attrs``: the group's, as remembered from a check of this very file.
        self.attrs = _plain(group.attrs) if attrs is None else _copied(attrs)
        self.attrs.setdefault("origin", origin)

    @property
    def groups(self) -> list[str]:
        """The groups it holds (``truth``, ``imu``, ``dvl``, ...), in name order."""
        self._check_open()
        return sorted(k for k, v in self._group.items() if isinstance(v, h5py.Group))

    def has(self, group: str) -> bool:
        """Whether the mission holds this group (an imported one has only ``dvl``; a
        recorded one those its ``groups`` attribute lists)."""
        return isinstance(self._item(group), h5py.Group)

    @property
    def reference(self) -> Group:
        """A recorded mission's reference: the navigation solution it is scored against
        (``reference/time``, ``latitude_deg``, ``position_ned``, ``velocity_ned``, and
        ``quaternion`` when the log has attitude). A reference, never the truth.

        Raises:
            DatasetError: the mission has none (simulated and imported ones do not).
        """
        if not self.has("reference"):
            hint = ("its truth is in mission.truth" if self.has("truth")
                    else "only recorded missions have one")
            raise DatasetError(f"{self._where} has no reference group; {hint}")
        return Group(self, "reference")

    @property
    def gravity(self) -> float | None:
        """The magnitude of gravity in the vehicle model that flew it, m/s^2: the
        ``gravity`` attribute (schema v6), or for an older file the gravity of the model
        its config names (the default ``auv`` if it names none), as it was read before v6.
        None for an imported mission: a recording of a DVL alone cannot know it."""
        if "gravity" in self.attrs:
            return float(self.attrs["gravity"])
        if self.origin == "imported":
            return None
        config = json.loads(self.dataset.config_json) if self.dataset.config_json else {}
        return _model_gravity(config.get("vehicle", {}).get("model", "auv"))

    @property
    def phases(self) -> Phases:
        """Its manoeuvre's phases, (start s, end s, label) each, in time order: the
        ``phases`` attribute (schema v6), or for an older file the phases of the manoeuvre
        made again from its config and seed, as they were before v6. Empty for a mission
        without scripted phases: imported, flown by a policy (an environment's episode), or
        from an older file whose config does not name exactly its missions."""
        if "phases" in self.attrs:
            return parse_phases(self.attrs["phases"])
        if self.origin != "simulated":
            return []
        return list(self.dataset._derived_phases().get(self.name, []))

    def __dir__(self) -> list[str]:  # its groups too, for a notebook's completion
        return sorted({*super().__dir__(), *self.groups})

    def __getattr__(self, group: str) -> Group:
        if group == "truth" and self.origin == "recorded":
            raise DatasetError(f"{self._where}: recorded missions have a reference, not a "
                               "truth; use mission.reference (a navigation solution)")
        if group.startswith("_") or not self.has(group):
            raise AttributeError(f"mission {self.name} has no group {group!r}")
        return Group(self, group)

    def to_xarray(self, *, timedelta: bool = False) -> dict[str, xarray.Dataset]:
        """Its groups as xarray Datasets, group name -> Dataset, every field of the
        schema read whole (``auvsim.data.xarray_views.group_datasets``): each on its
        group's own ``time`` coordinate (s), fields with ``units`` and ``description``
        attributes and component coordinates (``axis`` x/y/z, ``ned`` N/E/D, ``component``
        w/x/y/z, ``beam`` 0-3, the columns), the mission's attributes on each Dataset. A recorded
        mission's ``reference`` says it is a reference. Needs xarray
        (``pip install 'auvsim[io]'``).

        Args:
            timedelta: ``time`` as a ``timedelta64[ns]`` index (rounded to the
                nanosecond), which ``resample`` needs; default the file's float seconds.

        Raises:
            AuvsimError: xarray is not installed.
            DatasetError: a field is corrupt (``read``).
        """
        from auvsim.data.xarray_views import group_datasets

        if self.origin == "recorded":
            fields, _ = _recorded_fields(self._where, self._group)
        else:
            fields, _ = schema(self.origin, self.dataset.version)
        attrs = {**self.attrs, "mission": self.name, "dataset": str(self.dataset.path)}
        return group_datasets(fields, self.read, attrs, timedelta=timedelta)

    def read(self, path: str) -> np.ndarray:
        """One field, whole; a field that fails its checksum or cannot be decoded is
        refused with ``DatasetError`` naming the file, the mission and the field, and so
        is any field of a shard whose data differ from its seal (``Dataset.check_seal``,
        at the first read from each shard)."""
        self._check_open()
        self.dataset.check_seal(self._group.file)
        return _read(self._where, path, self._dataset(path))

    def _check_open(self) -> None:
        if not self._group.id.valid:  # h5py's own error says "Not an id of a file object"
            raise DatasetError(f"{self._where}: its dataset is closed; expected reads inside "
                               "the `with open_dataset(...)` block (or the arrays copied out "
                               "before it ends)")

    def _dataset(self, path: str) -> h5py.Dataset:
        item = self._item(path)
        if not isinstance(item, h5py.Dataset):
            raise DatasetError(f"{self._where} has no field {path}")
        return item

    # The file is open read-only, so a group or field is looked up once (a lookup costs
    # about 80 us, and ``mission.imu.time`` takes two) and a group's fields are listed once
    # (h5py opens each item to tell a field from a group).
    def _item(self, path: str) -> h5py.HLObject | None:
        self._check_open()
        if path not in self._items:
            self._items[path] = self._group.get(path)
        return self._items[path]

    def _fields(self, group: str) -> list[str]:
        if group not in self._field_names:
            g = self._item(group)
            self._field_names[group] = [
                k for k in g if g.get(k, getclass=True) is h5py.Dataset
            ] if isinstance(g, h5py.Group) else []
        return self._field_names[group]


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
        self._phases: dict[str, Phases] | None = None
        self._sealed_ok: set[str] = set()  # files whose data match their seal

    @property
    def config_json(self) -> str:
        return str(self.attrs.get("config_json", ""))

    def mission(self, name: str | None = None) -> Mission:
        """The mission called ``name``; with None, the dataset's only mission (a command
        that reads one mission never guesses which of several is meant).

        Raises:
            ConfigError: (``argument="mission"``) ``name`` is not a mission of the
                dataset, or it is None and the dataset has several missions.
        """
        names = list(self.missions)
        listed = f"{', '.join(names[:10])}{', ...' if len(names) > 10 else ''}"
        if name is None:
            if len(names) != 1:
                raise ConfigError(f": the dataset has {len(names)} missions ({listed}); "
                                  "expected one named", argument="mission")
            name = names[0]
        if name not in self.missions:
            raise ConfigError(f"{str(name)[:80]!r}: no such mission; expected one of "
                              f"{listed}", argument="mission")
        return self.missions[name]

    def _derived_phases(self) -> dict[str, Phases]:
        """Every mission's phases rebuilt from the config (files before schema v6): its
        manoeuvre made again from the mission's seed stream, as ``auvsim.runs.mission``
        made it; none unless the config names exactly the file's missions."""
        if self._phases is None:
            self._phases = _rebuilt_phases(self.config_json, set(self.missions))
        return self._phases

    def digest(self) -> str:
        """The digest of its missions' data (``auvsim.data.schema.data_digest``), every
        field read: what a shard is sealed with."""
        return data_digest(self._file)

    def check_seal(self, file: h5py.File) -> None:
        """Refuse a shard (a file sealed with ``data_sha256``) whose data no longer match
        its seal: HDF5 recomputes a field's own checksum when a value is edited through
        it, so only the digest of the whole shard tells. Each file is checked once, at the
        first read from it (about 80 ms for a 600 s mission of the default sensors, the
        cost of reading every field once more); opening stays cheap, whatever the number
        of shards. Files without a seal (a single-file dataset) pass.

        Raises:
            DatasetError: the data differ from the seal, or a field is corrupt.
        """
        name = file.filename
        if name in self._sealed_ok:
            return
        sealed = file.attrs.get("data_sha256")
        if sealed is not None:
            where = Path(name)

            def read(key: str, ds: h5py.Dataset) -> np.ndarray:
                mission, _, field = key.lstrip("/").partition("/")
                origin = file["missions"][mission].attrs.get("origin", "simulated")
                return _read(_where(where, mission, origin), field, ds)

            if not isinstance(sealed, str) or data_digest(file, read) != sealed:
                raise DatasetError(
                    f"{where}: its data differ from the digest it was sealed with "
                    "(data_sha256): the file was changed after auvsim wrote it; expected the "
                    "data auvsim generate wrote (running it again makes the shard anew)")
        self._sealed_ok.add(name)

    def verify(self) -> None:
        """Read every dataset of every mission (extra ones too), so each checksum is
        verified, and each shard's seal (``check_seal``); the first that fails is refused
        (``DatasetError``)."""
        for mission in self.missions.values():
            for key in dataset_paths(mission._group):
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
    elif path.is_dir() and (path / "model.pt").exists():
        raise DatasetError(f"{path}: is a training run (model.pt), not a dataset; expected "
                           "an auvsim dataset file or a sharded dataset's folder")
    elif path.is_dir():
        hint = (" (auvsim generate writes its index last: run it again to finish the "
                "dataset)") if (path / SHARDS).is_dir() else ""
        raise DatasetError(f"{path}: is a directory with no {INDEX}; expected an auvsim "
                           f"dataset file or a sharded dataset's folder{hint}")
    if not path.exists():
        raise DatasetError(f"{path}: no such file")
    if not path.is_file():
        raise DatasetError(f"{path}: not a regular file; expected an auvsim dataset file")
    try:
        open(path, "rb").close()  # plain open: its OSError says what is wrong
        key = _identity(path)  # before the file is opened: what is checked is this file
    except OSError as e:
        raise DatasetError(f"{path}: cannot read it ({e.strerror or _reason(e)})") from None
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise DatasetError(f"{path}: not an HDF5 file, or corrupt ({_reason(e)}); expected "
                           "an auvsim dataset (auvsim generate or auvsim import writes one)"
                           ) from None
    try:
        dataset = _checked(path, f, key)
        if verify:
            dataset.verify()
    except DatasetError:
        f.close()
        raise
    except (KeyError, OSError, ValueError, TypeError, RuntimeError) as e:
        f.close()
        raise DatasetError(f"{path}: corrupt auvsim dataset ({_reason(e)})") from None
    return dataset


def _identity(path: Path) -> tuple:
    """What tells the file at ``path`` from any other, and from itself changed: its path,
    device, inode, size, modification and status-change (``CTIME``) times."""
    s = path.stat()
    return (str(path.resolve()), s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns, s.st_ctime_ns)


CTIME = 5  # the status-change time's place in an ``_identity``


def _unchanged(key: tuple) -> Checked | None:
    """What was remembered of ``key``'s file, checked whole, if it and its shards are as
    they were; else None."""
    checked = _CHECKED.get(key)
    if checked is None:
        return None
    try:
        same = all(_identity(Path(shard[0])) == shard for shard in checked.shards)
    except OSError:
        return None
    return checked if same else None


def _remember(path: Path, key: tuple, dataset: Dataset) -> None:
    """Record ``path`` (``key``, taken before it was opened) as checked whole, with its
    missions' attributes, if it is still that file, and it and its shards were quiet for
    ``QUIET_S``."""
    try:
        if _identity(path) != key:
            return
        known = tuple(_identity(shard) for shard in dataset.shards)
    except OSError:
        return
    quiet = time.time_ns() - int(QUIET_S * 1e9)
    if all(k[CTIME] < quiet for k in (key, *known)):
        if len(_CHECKED) >= CHECKED_FILES:
            _CHECKED.clear()
        _CHECKED[key] = Checked(known, {name: _copied(m.attrs)
                                        for name, m in dataset.missions.items()})


def _checked(path: Path, f: h5py.File, key: tuple) -> Dataset:
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
    if f.attrs.get("config_json"):
        _json_of(f.attrs["config_json"], dict, f"{str(path)!r}: its config_json")
    dataset = Dataset(path, f)
    layout = f.attrs.get("layout", "file")
    if layout not in ("file", "index"):
        raise DatasetError(f"{path}: auvsim dataset with layout {_show(layout)}; expected "
                           "'file' or 'index'")
    records = _index_records(path, f) if layout == "index" else None
    try:
        known = _unchanged(key) if REMEMBER_CHECKED else None
        _check_missions(path, f, dataset, records, version, known=known)
        if known is None:
            _remember(path, key, dataset)
    except BaseException:
        for shard in dataset._shard_files.values():
            shard.close()
        raise
    return dataset


def _check_missions(path: Path, f: h5py.File, dataset: Dataset,
                    records: dict[str, Shard] | None, version: int, *,
                    known: Checked | None = None) -> None:
    """Check each mission's group and origin, and unless the file is ``known`` its fields
    and attributes (``_check_mission``), and add it to ``dataset`` (a known file's
    missions with the attributes remembered)."""
    for name in f["missions"]:
        group = (f["missions"][name] if records is None
                 else _shard_group(path, f, name, records, dataset))
        if not isinstance(group, h5py.Group):
            raise DatasetError(f"{path}: missions/{name} is not a mission group")
        expected = f"expected one of {', '.join(ORIGINS)} (schema v{version})"
        if "origin" not in group.attrs and version >= 2:
            raise DatasetError(f"{path}: mission {name} has no origin attribute; {expected}")
        origin = group.attrs.get("origin", "simulated")
        if not (isinstance(origin, str) and origin in ORIGINS) or (
                origin == "recorded" and version < RECORDED_SINCE):
            raise DatasetError(f"{path}: mission {name} has origin {_show(origin)}; "
                               f"{expected}")
        if known is None:
            _check_mission(path, name, group, origin, version)
        dataset.missions[name] = Mission(dataset, name, group, origin,
                                         None if known is None else known.attrs[name])


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
    if (file.attrs.get("format") != FORMAT
            or file.attrs.get("config_sha256") != records[name].config_sha256
            or file.attrs.get("data_sha256") != records[name].data_sha256):
        raise DatasetError(f"{shard}: not the shard the index {path} lists (another config "
                           "or run wrote it since); expected the shards of one auvsim "
                           "generate run (running it again makes them agree)")
    return group


def _check_mission(path: Path, name: str, group: h5py.Group, origin: str,
                   version: int) -> None:
    where = _where(Path(group.file.filename), name, origin)
    if origin == "recorded":
        fields, attrs = _recorded_fields(where, group)
    else:
        fields, attrs = schema(origin, version)
    missing = [fl.path for fl in fields if not isinstance(group.get(fl.path), h5py.Dataset)]
    missing += [f"attribute {a.name}" for a in attrs if a.name not in group.attrs
                and not a.optional and not (a.name == "origin" and version == 1)]
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
    if "phases" in group.attrs and isinstance(group.attrs["phases"], str):
        try:
            parse_phases(group.attrs["phases"])
        except ValueError as e:
            raise DatasetError(f"{where}: attribute phases is {_show(group.attrs['phases'])}; "
                               f"expected a JSON list of [start s, end s, label] ({_reason(e)})"
                               ) from None
    for key, kind in JSON_ATTRS.items():
        if key in group.attrs:
            _json_of(group.attrs[key], kind, f"{where}: its {key} attribute")
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


def _recorded_fields(where: str, group: h5py.Group) -> tuple[list, tuple]:
    """A recorded mission's fields to check (the required ones of the groups its
    ``groups`` attribute lists, and the optional ones it holds) and its attributes."""
    text = group.attrs.get("groups")
    try:
        groups = parse_groups(text)
    except ValueError:
        raise DatasetError(f"{where}: attribute groups is {_show(text)}; expected a JSON "
                           "list of the groups it holds (imu, dvl, depth, reference)") from None
    unlisted = [k for k, v in group.items() if isinstance(v, h5py.Group) and k not in groups]
    if unlisted:
        raise DatasetError(f"{where} holds group {unlisted[0]}, which its groups attribute "
                           f"{_show(text)} does not list; expected the groups it holds")
    required, optional, attrs = recorded_schema(groups)
    return [*required, *(f for f in optional if isinstance(group.get(f.path), h5py.Dataset))
            ], attrs


def _rebuilt_phases(config_json: str, names: set[str]) -> dict[str, Phases]:
    # Imported here: only files before schema v6 need the simulator's config and
    # manoeuvres, and reading a file should not load them.
    from auvsim.config import Config
    from auvsim.data.streams import mission_streams
    from auvsim.errors import AuvsimError
    from auvsim.physics.maneuvers import make_maneuver

    try:
        config = Config.from_json(config_json)
    except (AuvsimError, ValueError, TypeError):
        return {}
    if {m.name for m in config.missions} != names:
        return {}
    return {m.name: [tuple(p) for p in make_maneuver(
        m.scenario, rng=mission_streams(m.seed)["maneuver"]).phases()]
        for m in config.missions}


@lru_cache(maxsize=8)
def _model_gravity(model: str) -> float:
    """Gravity of a vehicle model (its MJCF ``option gravity``), m/s^2, for files before
    schema v6. MuJoCo is imported here: only those files need it."""
    import mujoco

    from auvsim.physics.vehicle import model_path

    return -float(mujoco.MjModel.from_xml_path(str(model_path(model))).opt.gravity[2])


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


def dataset_paths(group: h5py.Group) -> list[str]:
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


def require_usable_beams(mission: Mission) -> np.ndarray:
    """(M, 4) bool: the mission's usable beams (flagged valid, with a finite velocity;
    ``auvsim.sensors.dvl.usable_beams``), for a consumer that needs some to work on (a
    plot, training, an evaluation).

    Raises:
        DatasetError: not one beam of the mission is usable, in one line naming it.
    """
    usable = usable_beams(mission.dvl.valid, mission.dvl.beam_velocity)
    if not usable.any():
        raise DatasetError(f"{mission._where}: no usable beam in its {len(usable)} pings "
                           "(every beam is flagged invalid or its velocity is NaN); expected "
                           "at least one valid, finite beam velocity")
    return usable


def require_attitude(mission: Mission) -> np.ndarray:
    """(R, 4) the mission's attitude, body -> NED [w, x, y, z], at its reference's (or a
    simulated mission's truth's) samples, for a consumer that needs one (the INS/DVL
    filter's start and scores).

    Raises:
        DatasetError: the mission has no attitude (a recorded reference without one, or
            an imported DVL stream), in one line naming it.
    """
    if mission.has("truth"):
        return mission.truth.quaternion
    if mission.has("reference") and "quaternion" in mission.reference:
        return mission.reference.quaternion
    what = ("its reference has no attitude (reference/quaternion)" if mission.has("reference")
            else "it has neither a reference nor a truth")
    raise DatasetError(f"{mission._where}: {what}; expected a reference with roll, pitch "
                       "and yaw (map them in the log description) or a start attitude given "
                       "another way")


def read_attrs(path: str | os.PathLike) -> tuple[dict, dict[str, dict]]:
    """The root attributes of a dataset and each mission's attributes, as plain Python
    values (numpy arrays for vectors), after ``open_dataset``'s checks."""
    with open_dataset(path) as f:
        return f.attrs, {name: m.attrs for name, m in f.missions.items()}
