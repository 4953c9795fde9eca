"""The only module that knows the HDF5 layout (schema v2 in docs/ARCHITECTURE.md).

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
# Version 2 = version 1 + a mission attribute ``origin``, which lets a mission imported from
# a recorded DVL stream hold only its DVL group. Version 1 files are read as all simulated.
FORMAT_VERSION = 2
READABLE_VERSIONS = (1, 2)
CHUNK_ROWS = 6000  # rows per HDF5 chunk: 60 s at 100 Hz, 48 kB for a float64 column
# lzf: fast, built into h5py; gzip (level 1): about 1.5x the writing cost, but every HDF5
# tool reads it without a plugin.
COMPRESSION = {"lzf": dict(compression="lzf", shuffle=True),
               "gzip": dict(compression="gzip", compression_opts=1, shuffle=True)}

# What every mission holds, by origin (extra fields are allowed).
DVL_FIELDS = ("dvl/time", "dvl/velocity", "dvl/beam_velocity_true", "dvl/beam_velocity",
              "dvl/valid", "dvl/velocity_ls")
DVL_ATTRS = ("origin", "scenario", "seed", "duration_s", "dvl_rate_hz", "beam_angle_deg",
             "dvl_scale_factor", "dvl_bias", "dvl_noise_std")
REQUIRED_FIELDS = (
    "truth/time", "truth/position_ned", "truth/velocity_ned", "truth/velocity_body",
    "truth/quaternion", "truth/angular_rate", "truth/specific_force", "truth/altitude",
    "imu/time", "imu/specific_force", "imu/angular_rate", "imu/index_of_dvl",
    *DVL_FIELDS, "dvl/beam_range",
    "control/propeller_rpm", "control/thrust", "control/rudder", "control/stern_planes",
)
REQUIRED_ATTRS = (
    *DVL_ATTRS, "vehicle", "imu_rate_hz", "dvl_min_range", "dvl_max_range",
    "dvl_mounting_rpy_deg", "dvl_position_body", "imu_position_body",
    "imu_accel_turn_on_bias", "imu_gyro_turn_on_bias", "imu_accel_noise_density",
    "imu_gyro_noise_density", "imu_accel_bias_instability", "imu_gyro_bias_instability",
    "imu_bias_correlation_time",
)
IMPORTED_FIELDS = DVL_FIELDS
IMPORTED_ATTRS = (*DVL_ATTRS, "source_file", "source_sha256")
ORIGINS = {"simulated": (REQUIRED_FIELDS, REQUIRED_ATTRS),
           "imported": (IMPORTED_FIELDS, IMPORTED_ATTRS)}


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
        if self.path.is_dir():
            raise ConfigError(f"{str(self.path)!r} is a directory: expected a file name",
                              argument="out")
        self.tmp = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            open(self.tmp, "wb").close()  # plain open: its OSError says what is wrong
        except OSError as e:
            raise ConfigError(
                f"{str(self.path)!r}: cannot write there ({e.strerror or e}); "
                "expected a path in a writable directory", argument="out") from None
        # No chunk cache: whole chunks are written at once, so caching them would only
        # defer their compression to the close, outside the physics/sensors overlap.
        self.file = h5py.File(self.tmp, "w", rdcc_nbytes=0)
        self.file.attrs.update(
            format=FORMAT,
            format_version=FORMAT_VERSION,
            auvsim_version=__version__,
            created_utc=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            config_json=config_json,
        )
        self.file.create_group("missions")

    def mission(self, name: str, attrs: Mapping[str, object],
                rows: Mapping[str, int] | None = None) -> MissionWriter:
        """Start a mission; ``rows`` gives the expected rows per group (``truth``: N) or
        per dataset (``imu/index_of_dvl``: M)."""
        group = self.file["missions"].create_group(name)
        group.attrs.update(attrs)
        return MissionWriter(group, self.filters, rows)

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            self.file.close()
            if exc_type is None:
                os.replace(self.tmp, self.path)
        finally:
            self.tmp.unlink(missing_ok=True)


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


def open_dataset(path: str | os.PathLike) -> h5py.File:
    """Open an auvsim dataset for reading, after checking that it is one.

    Raises:
        DatasetError: the file is missing, not HDF5, not an auvsim dataset, of another
            format version, or a mission lacks a field of the schema.
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
    if version not in READABLE_VERSIONS:
        f.close()
        raise DatasetError(f"{path}: auvsim dataset format_version {version}; this auvsim "
                           f"reads versions {', '.join(map(str, READABLE_VERSIONS))}")
    try:
        if not isinstance(f.get("missions"), h5py.Group):
            raise DatasetError(f"{path}: corrupt auvsim dataset (no missions group)")
        for name, mission in f["missions"].items():
            origin = mission.attrs.get("origin", "simulated" if version == 1 else None)
            if origin not in ORIGINS:
                raise DatasetError(f"{path}: mission {name} has origin {origin!r}; expected "
                                   f"one of {', '.join(ORIGINS)} (schema v{version})")
            fields, attrs = ORIGINS[origin]
            missing = [k for k in fields if k not in mission]
            missing += [f"attribute {k}" for k in attrs
                        if k not in mission.attrs and not (k == "origin" and version == 1)]
            if missing:
                raise DatasetError(f"{path}: mission {name} ({origin}) lacks "
                                   f"{', '.join(missing)} (schema v{version})")
    except (KeyError, OSError) as e:
        f.close()
        raise DatasetError(f"{path}: corrupt auvsim dataset ({e})") from None
    except DatasetError:
        f.close()
        raise
    return f


def read_attrs(path: str | os.PathLike) -> tuple[dict, dict[str, dict]]:
    """The root attributes of a dataset and each mission's attributes, as plain Python
    values (numpy arrays for vectors), after ``open_dataset``'s checks."""
    def plain(attrs) -> dict:
        return {k: v.item() if isinstance(v, np.generic) else v for k, v in attrs.items()}

    with open_dataset(path) as f:
        return plain(f.attrs), {name: plain(m.attrs) for name, m in f["missions"].items()}


def describe(path: str | os.PathLike) -> str:
    """A human-readable summary of a dataset: missions, durations, rates, DVL validity,
    the realised error parameters and the fields."""
    def fmt(values) -> str:
        return np.array2string(np.asarray(values), precision=6, separator=", ")

    with open_dataset(path) as f:
        lines = [f"{path}: auvsim dataset v{f.attrs['format_version']} "
                 f"(auvsim {f.attrs.get('auvsim_version', '?')}, created "
                 f"{f.attrs.get('created_utc', '?')}), {len(f['missions'])} mission(s)"]
        for name, m in f["missions"].items():
            a = m.attrs
            valid = m["dvl/valid"][()]
            solvable = (f"{100 * valid.mean():.1f} % of beams valid, "
                        f"{100 * (valid.sum(axis=1) >= 3).mean():.1f} % of pings solvable")
            if a.get("origin") == "imported":
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
                    f"    IMU {a['imu_rate_hz']:g} Hz ({len(m['imu/time'])} samples); DVL "
                    f"{a['dvl_rate_hz']:g} Hz ({len(valid)} pings), beams at "
                    f"{a['beam_angle_deg']:g} deg, {solvable}",
                ]
            lines.append(f"    DVL errors: scale factor {fmt(a['dvl_scale_factor'])}, bias "
                         f"{fmt(a['dvl_bias'])} m/s, noise std {a['dvl_noise_std']:g} m/s")
            if "imu_accel_turn_on_bias" in a:
                lines.append(
                    f"    IMU errors: accel turn-on bias {fmt(a['imu_accel_turn_on_bias'])} "
                    f"m/s^2, gyro {fmt(a['imu_gyro_turn_on_bias'])} rad/s; noise densities "
                    f"{a['imu_accel_noise_density']:.3g} m/s^2/rtHz, "
                    f"{a['imu_gyro_noise_density']:.3g} rad/s/rtHz")
        first = next(iter(f["missions"].values()), None)
        if first is not None:
            lines.append("  fields of each mission:")
            for group in sorted(first):
                lines.append(f"    {group}: " + ", ".join(sorted(first[group])))
        return "\n".join(lines)
