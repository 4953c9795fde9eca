"""``auvsim import-velocity``: a recorded DVL velocity stream as a dataset.

A real vehicle cannot give the true velocity beside the measured one. The BeamsNet paper's
sea experiment (sec. 4.2) therefore took the velocity its DVL recorded as the truth and
synthesised the beams a DVL under test would have measured, with the same error model as
its simulation (paper eq. 7). This module does that with the DVL's own ping pipeline
(``auvsim.sensors.dvl.synthesise``: ``H v`` with the configured beam angle, then scale
factor, bias and noise, then least squares), drawing from the imported mission's streams
(``auvsim.data.streams.imported_streams``).

Each input file becomes one mission of origin ``imported`` (schema v2): the DVL group only,
since there is no truth trajectory, IMU or control record. A row that is not finite (a
dropout in the recording) is a ping without bottom lock.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from auvsim.config import DvlConfig
from auvsim.data.schema import mission_attrs
from auvsim.data.streams import imported_streams
from auvsim.data.writer import DatasetWriter
from auvsim.errors import ConfigError
from auvsim.sensors.dvl import synthesise


def read_velocity(path: str | os.PathLike) -> np.ndarray:
    """(N, 3) velocities, m/s, from a ``.npy`` array of shape (3, N) (the layout of the
    paper's published data) or a ``.csv`` with three columns (vx, vy, vz), one row per ping,
    with or without a header line.

    Raises:
        ConfigError: the file is missing, unreadable or of another shape.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{str(path)!r}: no such file; expected a .npy (3 x N) or .csv "
                          "(N rows of vx, vy, vz) velocity stream")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        try:
            array = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as e:
            raise ConfigError(f"{str(path)!r}: not a readable .npy array ({e})") from None
        if array.ndim != 2 or array.shape[0] != 3 or not np.issubdtype(array.dtype, np.number):
            raise ConfigError(f"{str(path)!r}: expected a numeric array of shape (3, N) "
                              f"(vx, vy, vz by ping), got {array.dtype} {array.shape}")
        return np.asarray(array.T, dtype=float)
    if suffix == ".csv":
        return _read_csv(path)
    raise ConfigError(f"{str(path)!r}: expected a .npy (3 x N) or .csv (N x 3) file, got "
                      f"{suffix or 'no extension'}")


def _read_csv(path: Path) -> np.ndarray:
    try:
        lines = [line for line in path.read_text().splitlines() if line.strip()]
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{str(path)!r}: cannot read it as text ({e})") from None
    rows = []
    for number, line in enumerate(lines, start=1):
        cells = [c.strip() for c in line.split(",")]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if number == 1:
                continue  # a header line
            raise ConfigError(f"{str(path)!r} line {number}: expected three numbers "
                              f"(vx, vy, vz), got {line.strip()!r}") from None
        if len(values) != 3:
            raise ConfigError(f"{str(path)!r} line {number}: expected three columns "
                              f"(vx, vy, vz), got {len(values)}")
        rows.append(values)
    return np.array(rows, dtype=float).reshape(-1, 3)


def import_velocity(sources: Sequence[str | os.PathLike], out: str | os.PathLike, *,
                    dvl: DvlConfig, seed: int = 0, names: Sequence[str] | None = None,
                    compression: str = "lzf") -> dict:
    """Write a dataset with one imported mission per velocity file.

    Args:
        sources: velocity files (see ``read_velocity``); sampled at ``dvl.rate_hz``.
        out: the HDF5 file to write (built under a temporary name, renamed when complete).
        dvl: beam angle, rate and error model (ranges and mounting are not used).
        seed: mission i draws its errors and noise from ``seed + i``.
        names: mission names; default the files' stems.

    Returns:
        A summary: mission names and their number of pings.
    """
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f": expected a whole number >= 0, got {seed!r}", argument="seed")
    sources = [Path(s) for s in sources]
    names = [s.stem for s in sources] if names is None else list(names)
    if len(set(names)) != len(names):
        raise ConfigError(f"mission names must differ, got {names} (from the file stems; "
                          "rename a file)")
    velocities = [read_velocity(s) for s in sources]  # all read and checked before writing
    for source, v in zip(sources, velocities, strict=True):
        if not np.isfinite(v).all(axis=1).any():
            raise ConfigError(f"{str(source)!r}: no finite velocity row; nothing to import")
    settings = dict(dvl=dataclasses.asdict(dvl), seed=seed,
                    sources=[str(s) for s in sources])
    summary = {}
    with DatasetWriter(out, config_json=json.dumps({"import": settings}),
                       compression=compression) as writer:
        for i, (source, name, velocity) in enumerate(zip(sources, names, velocities, strict=True)):
            fields, dvl_attrs = synthesise(velocity, dvl, imported_streams(seed + i))
            n = len(velocity)
            attrs = mission_attrs(origin="imported", scenario="imported", seed=seed + i,
                                  duration_s=n / dvl.rate_hz, **dvl_attrs,
                                  source_file=str(source),
                                  source_sha256=hashlib.sha256(source.read_bytes()).hexdigest())
            sink = writer.mission(name, attrs, rows={"dvl": n})
            sink.append(fields)
            sink.flush()
            summary[name] = n
    return summary
