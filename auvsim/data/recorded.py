"""``auvsim import``: a real vehicle's logs (IMU, DVL, depth, a reference navigation
solution) as datasets of recorded missions (schema v7, ``auvsim.data.schema.recorded_schema``).

A log is a folder of CSV files and a **log description**, a small TOML that says what the
files hold (``parse_description``; ``docs/guides/recorded-logs.md`` shows one whole):

* ``[log]``: ``name`` (the mission's; default the folder's), ``reference_source`` (what the
  reference is), ``origin = [lat deg, lon deg, height m]`` (default the reference's first
  point; needed when the log has no reference);
* ``[imu]``, ``[dvl]``, ``[depth]``, ``[reference]``, each optional: ``file``, ``time`` (the
  time column) and ``time_unit`` (s, ms, us, ns), ``time_offset_s`` (added to the stamps),
  ``rate_hz`` (the rate the instrument states; ``auvsim check-log`` compares the stamps
  with it to choose the time base),
  ``columns`` (field -> a column name, or a list of them for a vector), ``units`` (field ->
  unit), ``ignore`` (columns the import may skip), ``delimiter``;
* the frames: ``frame`` FRD or FLU for the body-fixed streams (``imu``, ``dvl``), with an
  ``axis_map`` (the log's axis on each body axis, ``["x", "-y", "-z"]``), and for the
  reference ``frame`` NED or ENU and ``body`` FRD or FLU (its attitude's body frame);
* where the sensors sit: ``position_body`` (m, FRD, from the reference point) for the IMU
  and the DVL, the DVL's ``mounting_rpy_deg`` and ``beam_angle_deg``; the DVL's
  ``invalid``, its no-data value as logged (NaN in the dataset: no bottom lock; ``nan``
  for a log that writes NaN there, which a log without it may not);
* the instruments' specifications, which estimators read from the file: ``[imu.noise]``
  (``accel_noise_density``, ``gyro_noise_density``, ``accel_bias_instability``,
  ``gyro_bias_instability``, ``bias_correlation_time``, SI units) and the DVL's
  ``noise_std`` (white beam noise) and ``velocity_accuracy`` (its stated velocity std),
  m/s. No default: a spec the log does not state is not invented here; a beam noise it
  does not state is measured on its error velocity where it logs one
  (``beam_noise_from_error_velocity``).

Everything is written in auvsim's conventions (``auvsim`` package docstring): body FRD,
world NED, SI units, quaternions [w, x, y, z] body -> NED. Each stream keeps its own
clock; nothing is resampled. All clocks are shifted by one constant so that the earliest
stamp is 0 (``log_time_origin_s`` keeps it). The reference's positions become local NED
from the mission origin (``auvsim.physics.earth.ned_from_geodetic``), and ``gravity`` the
WGS-84 normal gravity there.

A log the description does not fit is refused in one line, before anything is written
(``ConfigError``): missing, extra or repeated columns (or one mapped to two fields), an
empty file, a file of fewer than two rows, a row with another number of cells (a ``#``
comment too), time that runs backwards or repeats, stamps at another rate than the
stated one (``RATE_RANGE``), a cell that is NaN or not a number, units that cannot be
right (gyros beyond a turn per second where rad/s is declared, accelerometers that do not
see gravity, angles beyond their range in rad, positions that disagree with the
velocities in distance or direction, a DVL far slower or faster than the reference),
streams that do not overlap in time or span a hundred times another's (a time unit
mistaken), and a mission name that is not a
group's (``auvsim.data.writer.check_mission_name``). The dataset is never written over one
of the log's own files.

The built-in layout ``akit`` (``AKIT_DESCRIPTION``) is that of the Snapir AUV's logs
published with A-KIT (N. Cohen and I. Klein, "Adaptive Kalman-Informed Transformer",
Engineering Applications of Artificial Intelligence 146 (2025) 110221): one folder
``TrajectoryK/`` per segment, one mission ``trajectoryK`` each.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from auvsim.checks import did_you_mean
from auvsim.config import MAX_SENSOR_OFFSET
from auvsim.data.beams import beam_noise_from_error_velocity
from auvsim.data.checklog import cumulative
from auvsim.data.schema import RECORDED_GROUPS, mission_attrs
from auvsim.data.writer import DatasetWriter, check_mission_name
from auvsim.errors import ConfigError
from auvsim.physics.earth import ned_from_geodetic, normal_gravity
from auvsim.physics.frames import euler_angles, quaternion_from_euler, quaternion_product
from auvsim.sensors.imu import G0

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_SPEED = {"m/s": 1.0, "mm/s": 1e-3}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180}
# group -> field -> (number of columns, units and their factor to SI, required)
FIELDS = {
    "imu": {"specific_force": (3, {"m/s^2": 1.0, "g": G0}, True),
            "angular_rate": (3, {"rad/s": 1.0, "deg/s": math.pi / 180}, True)},
    "dvl": {"velocity": (3, _SPEED, True), "beam_velocity": (4, _SPEED, False),
            "beam_range": (4, {"m": 1.0}, False), "error_velocity": (1, _SPEED, False),
            "altitude": (1, {"m": 1.0}, False), "status": (4, {"-": 1.0}, False)},
    "depth": {"depth": (1, {"m": 1.0}, True)},
    "reference": {"latitude": (1, _ANGLE, True), "longitude": (1, _ANGLE, True),
                  "height": (1, {"m": 1.0}, True), "velocity": (3, _SPEED, True),
                  "attitude": (3, _ANGLE, False)},
}
IMU_NOISE = ("accel_noise_density", "gyro_noise_density", "accel_bias_instability",
             "gyro_bias_instability", "bias_correlation_time")
# Bounds that no recording of an underwater vehicle reaches, so a value beyond one means a
# unit other than the declared one. A full turn per second is ten times the fastest rate in
# the Snapir logs (a 33 deg/s roll oscillation). Gyros in deg/s declared rad/s are caught
# once the vehicle turns faster than 360 deg/s / 57.3 = 6.3 deg/s for 1 % of the log
# (``UNIT_SLIP_SHARE``), which a log with turns does; a log of a straight line alone may
# pass.
MAX_RATE = 2 * math.pi  # rad/s
# An IMU's median |specific force| is about g: outside these factors of it, it is in another
# unit (g, or cm/s^2).
FORCE_FACTORS = (0.5, 2.0)
# The share of gyro samples beyond ``MAX_RATE`` that says the record is in another unit; a
# spike of a sample or two is a glitch.
UNIT_SLIP_SHARE = 0.01
MAX_SPEED = 15.0  # m/s: five times an AUV's top speed (the A18-D's 3 m/s, vehicles.md)
TRACK_RATIO = 2.0  # positions and integrated velocities may disagree by at most this factor
MIN_TRACK = 20.0  # m: below this distance travelled, the ratio says nothing
# The positions' legs (over ``TRACK_LEG`` samples) against the velocities' over the same
# samples: the cosine of the angle between them, summed over the legs, at least this. A
# frame declared NED for ENU velocities (north and east swapped, a mirror) or latitude
# and longitude swapped turns the legs against each other (on a straight line by twice
# its heading's distance from 45 deg: one near it cannot tell); a real reference's
# positions and velocities agree in direction to a degree or two.
TRACK_COSINE = 0.9  # 26 deg
TRACK_LEG = 10
# The same legs up and down: below this vertical distance in both the heights and the
# integrated vertical velocity, their directions say nothing (a depth sensor's noise, a few
# cm, and a swell's heave stay far below it); above it, a consistent reference agrees in
# direction, and one whose vertical axis is flipped disagrees (a negative cosine).
MIN_CLIMB = 5.0  # m
# The yaw against the course over the ground: a torpedo AUV's sideslip is a few degrees
# (the model card's turns: under 10 deg), and a current's crab angle asin(current / speed)
# is 30 deg for a 0.5 m/s current at 1 m/s, 60 deg for one of 0.87 m/s: beyond 60 deg at
# 1 m/s or more over the ground (median), the yaw is not of the frame it is declared in.
MAX_CRAB = 60.0  # deg
CRABBING_SPEED = 1.0  # m/s
MIN_MOVING_SAMPLES = 30
SPAN_RATIO = 100.0  # a stream may span at most this many times another's (ms read as s: 1000)
SPEED_RATIO = 5.0  # the DVL's median speed within this factor of the reference's
MOVING = 0.2  # m/s: the reference's median speed above which the DVL's is compared


# The A-KIT layout. Every figure carries its source; what the publication does not state
# (the IMU's axes, the clocks' alignment, where the sensors sit) is left at "as logged",
# for ``auvsim check-log`` to find from the data.
AKIT_DESCRIPTION = """\
# The Snapir AUV's logs as published with A-KIT (N. Cohen and I. Klein, "Adaptive
# Kalman-Informed Transformer", EAAI 146 (2025) 110221; repository ansfl/A-KIT):
# TrajectoryK/{IMU,DVL,GT}_trajectoryK.csv.
[log]
name = "trajectory{k}"
reference_source = "Delph INS post-processed navigation solution (A-KIT GT file), 1 Hz"

[imu]
# iXblue Phins Subsea (fibre-optic gyros), 100 Hz, "in the body frame": the publication
# states no axis convention; FRD as logged (auvsim check-log tests it against the reference).
file = "IMU_trajectory{k}.csv"
time = "Time [s]"
rate_hz = 100.0
time_unit = "s"
frame = "FRD"
position_body = [0.0, 0.0, 0.0]  # not published
columns.specific_force = ["ACC X [m/s^2]", "ACC Y [m/s^2]", "ACC Z [m/s^2]"]
columns.angular_rate = ["GYRO X [rad/s]", "GYRO Y [rad/s]", "GYRO Z [rad/s]"]
units = {specific_force = "m/s^2", angular_rate = "rad/s"}

[imu.noise]
# Phins class, ../shared/reference/sensors.md: gyro ARW 0.0025 deg/sqrt(h) and bias
# stability 0.01 deg/h; accelerometer bias 10 to 50 micro-g (the low end taken as the
# in-run instability). Accelerometer noise: sensors.md gives none; 20 micro-g/sqrt(Hz),
# the aviation-grade IMU of Groves, "Principles of GNSS, Inertial, and Multisensor
# Integrated Navigation Systems" (2nd ed., 2013), example INS_GNSS_Demo_12, whose gyro ARW
# (0.002 deg/sqrt(h)) matches the Phins'. Correlation time: none published; one hour.
accel_noise_density = 1.96133e-4  # 20e-6 * 9.80665 m/s^2/sqrt(Hz)
gyro_noise_density = 7.27221e-7  # 0.0025 deg/sqrt(h) = 0.0025 * pi/180 / 60 rad/s/sqrt(Hz)
accel_bias_instability = 9.80665e-5  # 10 micro-g, m/s^2
gyro_bias_instability = 4.84814e-8  # 0.01 deg/h = 0.01 * pi/180 / 3600 rad/s
bias_correlation_time = 3600.0

[dvl]
# Teledyne RDI Workhorse Navigator, 1 Hz, 30 deg Janus beams (../shared/reference/sensors.md);
# the log holds its velocity output only, in the body frame.
file = "DVL_trajectory{k}.csv"
time = "Time [s]"
rate_hz = 1.0
time_unit = "s"
frame = "FRD"
position_body = [0.0, 0.0, 0.0]  # not published
mounting_rpy_deg = [0.0, 0.0, 0.0]
beam_angle_deg = 30.0
columns.velocity = ["DVL X [m/s]", "DVL Y [m/s]", "DVL Z [m/s]"]
units = {velocity = "m/s"}
# The velocity standard deviation the publication states.
velocity_accuracy = 0.02
# White beam noise: for RDI's Janus transformation the error velocity is
# e = (b1 + b2 - b3 - b4) / (2 sqrt(2) sin a) (Teledyne RDI, "ADCP Coordinate
# Transformation", P/N 951-6079-00, 2010, sec. 5.3), so white beam noise s gives
# std(e) = s / (sqrt(2) sin a): s = sqrt(2) sin(30 deg) std(e) = 0.707 std(e). The same
# Navigator's own error velocity has std 3.73 mm/s over the 5,631 pings of
# ../shared/data/snapir-missbeamnet/validation_data.csv (MissBeamNet, Yona and Klein 2024):
# s = 2.6 mm/s. The rest of the stated 0.02 m/s survives averaging (scale, bias, alignment).
noise_std = 0.0026

[reference]
# The Delph INS solution at 1 Hz, as the publication states.
file = "GT_trajectory{k}.csv"
time = "Time [s]"
rate_hz = 1.0
time_unit = "s"
frame = "NED"
body = "FRD"
columns.latitude = "Latitude [rad]"
columns.longitude = "Longitude [rad]"
columns.height = "Altitude [m]"  # negative below the surface: a height
columns.velocity = ["V North [m/s]", "V East [m/s]", "V Down [m/s]"]
columns.attitude = ["Roll [rad]", "Pitch [rad]", "Yaw [rad]"]
units = {latitude = "rad", longitude = "rad", velocity = "m/s", attitude = "rad"}
"""
AKIT_SEGMENT = re.compile(r"Trajectory(\d+)")


@dataclass(frozen=True)
class Stream:
    """One stream of a log description (``[imu]``, ``[dvl]``, ``[depth]``, ``[reference]``).

    Attributes:
        group: its group in the dataset.
        file: its CSV, relative to the log's folder.
        time: the time column; ``scale`` its unit in s; ``offset`` s added to it.
        columns: field -> its column names (one per component).
        units: field -> factor to SI.
        axes: (3, 3) log axes -> body FRD (the axis map, then FLU -> FRD), or for the
            reference NED <- its frame.
        body_flip: the reference's attitude is of an FLU body.
        position_body: m, FRD, from the reference point (IMU and DVL).
        mounting_rpy_deg: deg, ZYX, DVL frame -> body (DVL).
        specs: the instrument's specifications by key (IMU: ``IMU_NOISE``; DVL:
            ``beam_angle_deg``, ``noise_std``, ``velocity_accuracy``), SI units or deg.
        invalid: the DVL's no-data value as logged, or None.
        rate_hz: the rate the instrument states, Hz, or None.
    """

    group: str
    file: str
    time: str
    scale: float
    offset: float
    columns: dict[str, tuple[str, ...]]
    units: dict[str, float]
    axes: np.ndarray
    ignore: tuple[str, ...] = ()
    delimiter: str = ","
    body_flip: bool = False
    position_body: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mounting_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    specs: dict[str, float] = field(default_factory=dict)
    invalid: float | None = None
    rate_hz: float | None = None


@dataclass(frozen=True)
class LogDescription:
    """A parsed log description: its ``text``, the log's ``name``, ``reference_source``,
    ``origin`` (lat deg, lon deg, height m, or None: the reference's first point) and its
    streams by group."""

    text: str
    name: str | None
    reference_source: str | None
    origin: tuple[float, float, float] | None
    streams: dict[str, Stream]


def load_toml(text: str, *, where: str) -> dict:
    """A log description's TOML text as tables (``auvsim.data.pd0``'s too).

    Raises:
        ConfigError: not TOML, or nested too deeply to read, in one line.
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{where}: not valid TOML ({e})") from None
    except RecursionError:  # the parser recurses once per level of arrays or tables
        raise ConfigError(f"{where}: not valid TOML (arrays or tables nested too deeply to "
                          "read)") from None


def parse_description(text: str, *, where: str = "log description") -> LogDescription:
    """A log description (TOML text; see the module docstring), checked.

    Raises:
        ConfigError: not TOML, or a key missing, unknown or of the wrong kind, in one line
            naming it.
    """
    data = load_toml(text, where=where)
    unknown = sorted(set(data) - {"log", *RECORDED_GROUPS})
    if unknown:
        raise ConfigError(f"{where}: unknown table [{unknown[0]}]; expected [log], "
                          + ", ".join(f"[{g}]" for g in RECORDED_GROUPS))
    log = data.get("log", {})
    _keys(where, "log", log, {"name", "reference_source", "origin"})
    origin = log.get("origin")
    if origin is not None:
        origin = tuple(finite_numbers(where, "log.origin", origin, 3))
        if not (-90 <= origin[0] <= 90 and -180 <= origin[1] <= 360):
            raise ConfigError(f"{where}: log.origin: expected [latitude deg in -90..90, "
                              f"longitude deg in -180..360, height m], got {list(origin)}")
    streams = {g: _stream(where, g, data[g]) for g in RECORDED_GROUPS if g in data}
    if not streams:
        raise ConfigError(f"{where}: no stream; expected at least one of "
                          + ", ".join(f"[{g}]" for g in RECORDED_GROUPS))
    if "reference" in streams and not isinstance(log.get("reference_source"), str):
        raise ConfigError(f"{where}: log.reference_source: expected a text saying what the "
                          "reference is (a navigation solution, say which)")
    if "name" in log:
        check_mission_name(log["name"], f"{where}: log.name")
    return LogDescription(text, log.get("name"), log.get("reference_source"), origin, streams)


_STREAM_KEYS = {"file", "time", "time_unit", "time_offset_s", "rate_hz", "columns", "units",
                "ignore", "delimiter", "frame"}
_GROUP_KEYS = {"imu": {"axis_map", "position_body", "noise"},
               "dvl": {"axis_map", "position_body", "mounting_rpy_deg", "beam_angle_deg",
                       "noise_std", "velocity_accuracy", "invalid"},
               "depth": set(), "reference": {"body"}}


def _stream(where: str, group: str, table: object) -> Stream:
    name = f"{where}: {group}"
    if not isinstance(table, dict):
        raise ConfigError(f"{name}: expected a table")
    _keys(where, group, table, _STREAM_KEYS | _GROUP_KEYS[group])
    for key in ("file", "time"):
        if not isinstance(table.get(key), str):
            raise ConfigError(f"{name}.{key}: expected a text (the "
                              f"{'CSV file' if key == 'file' else 'time column'}), got "
                              f"{table.get(key)!r}")
    time_unit = table.get("time_unit", "s")
    if time_unit not in TIME_UNITS:
        raise ConfigError(f"{name}.time_unit: expected one of {', '.join(TIME_UNITS)}, got "
                          f"{time_unit!r}")
    offset = _number(where, f"{group}.time_offset_s", table.get("time_offset_s", 0.0))
    rate = None
    if "rate_hz" in table:
        rate = _number(where, f"{group}.rate_hz", table["rate_hz"])
        if not rate > 0:
            raise ConfigError(f"{name}.rate_hz: expected the instrument's stated rate, Hz > 0, "
                              f"got {table['rate_hz']!r}")
    specs = FIELDS[group]
    columns_in = table.get("columns")
    if not isinstance(columns_in, dict):
        raise ConfigError(f"{name}.columns: expected a table of field = column name(s); "
                          f"fields: {', '.join(specs)}")
    columns, units = {}, {}
    units_in = table.get("units", {})
    if not isinstance(units_in, dict):
        raise ConfigError(f"{name}.units: expected a table of field = unit")
    for table_name, keys in (("columns", columns_in), ("units", units_in)):
        for key in keys:
            if key not in specs:
                raise ConfigError(f"{name}.{table_name}: unknown field {key!r}"
                                  f"{did_you_mean(key, specs)}; expected one of "
                                  f"{', '.join(specs)}")
    for key, (n, choices, required) in specs.items():
        if key not in columns_in:
            if required:
                raise ConfigError(f"{name}.columns.{key}: missing; expected "
                                  f"{'a column name' if n == 1 else f'{n} column names'}")
            continue
        cols = columns_in[key]
        cols = [cols] if isinstance(cols, str) else cols
        if not (isinstance(cols, list) and len(cols) == n and all(isinstance(c, str)
                                                                 for c in cols)):
            raise ConfigError(f"{name}.columns.{key}: expected "
                              f"{'a column name' if n == 1 else f'{n} column names'}, got "
                              f"{columns_in[key]!r}")
        columns[key] = tuple(cols)
        unit = units_in.get(key, next(iter(choices)))
        if unit not in choices:
            raise ConfigError(f"{name}.units.{key}: expected one of {', '.join(choices)}, "
                              f"got {unit!r}")
        units[key] = choices[unit]
    ignore = table.get("ignore", [])
    if not (isinstance(ignore, list) and all(isinstance(c, str) for c in ignore)):
        raise ConfigError(f"{name}.ignore: expected a list of column names")
    delimiter = table.get("delimiter", ",")
    if not (isinstance(delimiter, str) and len(delimiter) == 1):
        raise ConfigError(f"{name}.delimiter: expected one character, got {delimiter!r}")
    flip = False
    if group == "reference":
        frame = table.get("frame", "NED")
        if frame not in ("NED", "ENU"):
            raise ConfigError(f"{name}.frame: expected NED or ENU, got {frame!r}")
        axes = np.eye(3) if frame == "NED" else np.array([[0.0, 1, 0], [1, 0, 0], [0, 0, -1]])
        body = table.get("body", "FRD")
        if body not in ("FRD", "FLU"):
            raise ConfigError(f"{name}.body: expected FRD or FLU, got {body!r}")
        flip = body == "FLU"
    else:
        axes = _axis_map(where, group, table.get("axis_map", ["x", "y", "z"]))
        frame = table.get("frame", "FRD")
        if frame not in ("FRD", "FLU"):
            raise ConfigError(f"{name}.frame: expected FRD or FLU, got {frame!r}")
        if frame == "FLU":
            axes = np.diag([1.0, -1.0, -1.0]) @ axes
    mapped: dict[str, str] = {table["time"]: "time"}
    for key, cols in columns.items():
        for c in cols:
            if c in mapped:
                raise ConfigError(f"{name}.columns.{key}: column {c!r} is also the stream's "
                                  f"{mapped[c]}; expected each column of the file once")
            mapped[c] = key
    return Stream(group, table["file"], table["time"], TIME_UNITS[time_unit], offset, columns,
                  units, axes, tuple(ignore), delimiter, flip, rate_hz=rate,
                  **_instrument(where, group, table))


def _instrument(where: str, group: str, table: dict) -> dict[str, object]:
    """The ``Stream`` fields of where an instrument sits and its specifications, checked
    (none for ``depth`` and ``reference``)."""
    if group not in ("imu", "dvl"):
        return {}
    out: dict[str, object] = {"position_body": tuple(_bounded(
        where, f"{group}.position_body", table.get("position_body", [0.0, 0.0, 0.0]),
        MAX_SENSOR_OFFSET, "m from the reference point (a sensor on the vehicle)"))}
    if group == "imu":
        noise = table.get("noise")
        if not isinstance(noise, dict):
            raise ConfigError(f"{where}: imu.noise: missing; expected a table of "
                              f"{', '.join(IMU_NOISE)} (the IMU's datasheet, SI units)")
        _keys(where, "imu.noise", noise, set(IMU_NOISE))
        out["specs"] = {k: _spec(where, f"imu.noise.{k}", noise.get(k),
                                 strict=k == "bias_correlation_time") for k in IMU_NOISE}
        return out
    out["mounting_rpy_deg"] = tuple(_bounded(
        where, "dvl.mounting_rpy_deg", table.get("mounting_rpy_deg", [0.0, 0.0, 0.0]),
        360.0, "deg"))
    # Without a stated beam noise, the logged error velocity gives it (``_dvl_noise``).
    estimated = "noise_std" not in table and "error_velocity" in table.get("columns", {})
    out["specs"] = {k: _spec(where, f"dvl.{k}", table.get(k), strict=k == "beam_angle_deg")
                    for k in ("beam_angle_deg", "noise_std", "velocity_accuracy")
                    if not (k == "noise_std" and estimated)}
    for k in ("noise_std", "velocity_accuracy"):
        if out["specs"].get(k, 0.0) > MAX_DVL_NOISE:
            raise ConfigError(f"{where}: dvl.{k}: expected m/s, at most {MAX_DVL_NOISE:g} (a "
                              f"DVL's: a few mm/s to cm/s), got {table[k]!r}")
    if not out["specs"]["beam_angle_deg"] < 90:
        raise ConfigError(f"{where}: dvl.beam_angle_deg: expected the beams' angle from the "
                          f"DVL's axis, deg in (0, 90) (a Janus DVL's: 20 to 30), got "
                          f"{table['beam_angle_deg']!r}")
    marker = table.get("invalid")
    if marker == "nan" or (isinstance(marker, float) and math.isnan(marker)):
        out["invalid"] = math.nan  # a log that writes NaN where it has no data
    elif "invalid" in table:
        out["invalid"] = _number(where, "dvl.invalid", table["invalid"])
    return out


def _axis_map(where: str, group: str, value: object) -> np.ndarray:
    """(3, 3) log axes -> declared frame: row i has sign s at column j for "s<axis j>"."""
    expected = ('three of "x", "y", "z", each once, with an optional "-" (the log\'s axis '
                'on each body axis)')
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(v, str)
                                                                for v in value)):
        raise ConfigError(f"{where}: {group}.axis_map: expected {expected}, got {value!r}")
    out = np.zeros((3, 3))
    for i, v in enumerate(value):
        sign, axis = (-1.0, v[1:]) if v.startswith("-") else (1.0, v.lstrip("+"))
        if axis not in ("x", "y", "z"):
            raise ConfigError(f"{where}: {group}.axis_map: expected {expected}, got {value!r}")
        out[i, "xyz".index(axis)] = sign
    if sorted(np.abs(out).argmax(axis=1)) != [0, 1, 2]:
        raise ConfigError(f"{where}: {group}.axis_map: expected {expected}, got {value!r}")
    return out


def _keys(where: str, table: str, value: object, allowed: set[str]) -> None:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: [{table}]: expected a table")
    unknown = sorted(set(value) - allowed)
    if unknown:
        raise ConfigError(f"{where}: {table}.{unknown[0]}: unknown key; expected "
                          f"{', '.join(sorted(allowed))}")


def _number(where: str, key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
            value):
        raise ConfigError(f"{where}: {key}: expected a finite number, got {value!r}")
    return float(value)


MAX_DVL_NOISE = 1.0  # m/s: a DVL's white noise or stated accuracy beyond it is a unit slip


def _bounded(where: str, key: str, value: object, most: float, unit: str) -> list[float]:
    """Three finite numbers of at most ``most`` either way (``finite_numbers``)."""
    numbers = finite_numbers(where, key, value, 3)
    if any(abs(x) > most for x in numbers):
        raise ConfigError(f"{where}: {key}: expected each at most {most:g} {unit} either way, "
                          f"got {value!r}")
    return numbers


def finite_numbers(where: str, key: str, value: object, n: int) -> list[float]:
    """``value`` checked to be a list of ``n`` finite numbers, as floats (``key`` names it).

    Raises:
        ConfigError: it is not.
    """
    if not (isinstance(value, list) and len(value) == n):
        raise ConfigError(f"{where}: {key}: expected {n} numbers, got {value!r}")
    return [_number(where, key, v) for v in value]


def _spec(where: str, key: str, value: object, *, strict: bool = False) -> float:
    """An instrument specification: a finite number >= 0 (> 0 when ``strict``)."""
    if value is None:
        raise ConfigError(f"{where}: {key}: missing; expected the instrument's figure (from "
                          "its datasheet; auvsim does not invent one)")
    x = _number(where, key, value)
    if x < 0 or (strict and x == 0):
        bound = "above 0" if strict else "of at least 0"
        raise ConfigError(f"{where}: {key}: expected a number {bound}, got {value!r}")
    return x


# ---- reading -------------------------------------------------------------------------


def read_table(path: Path, stream: Stream) -> dict[str, np.ndarray]:
    """The stream's columns of a CSV with a header line, by field: (N,) stamps under
    ``time`` (s, before the offset) and (N, n) values in SI units, in the log's axes.

    Raises:
        ConfigError: the file is missing or unreadable; a described column is missing or a
            column is neither described nor ignored; fewer than two rows; a row has another
            number of cells; a cell is not a number or is NaN; time runs backwards or
            repeats.
    """
    if path.is_dir():
        raise ConfigError(f"{str(path)!r}: is a folder; expected the CSV file of the log "
                          f"description's {stream.group}.file")
    if not path.is_file():
        raise ConfigError(f"{str(path)!r}: no such file (the log description's "
                          f"{stream.group}.file)")
    try:
        with open(path, encoding="utf-8-sig") as f:
            # A name in double quotes (R's write.csv, spreadsheets) is the name inside them.
            header = [_unquoted(c.strip())
                      for c in f.readline().rstrip("\r\n").split(stream.delimiter)]
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{str(path)!r}: cannot read it as text ({e})") from None
    if header == [""]:
        raise ConfigError(f"{str(path)!r}: empty; expected a header line naming the columns, "
                          "then rows of numbers")
    wanted = {"time": (stream.time,), **stream.columns}
    named = [c for cols in wanted.values() for c in cols]
    twice = sorted({c for c in named if header.count(c) > 1})
    if twice:  # which of them is the column? (ignored columns may share a name)
        raise ConfigError(f"{str(path)!r}: column {twice[0]!r} appears {header.count(twice[0])} "
                          "times in the header; expected each described column once")
    for key, cols in wanted.items():
        for c in cols:
            if c not in header:
                has = ", ".join(map(repr, header))
                said = f"{stream.group}.time" if key == "time" else f"{stream.group}.columns"
                other = next((d for d in ",;\t " if d != stream.delimiter
                              and len(header) == 1 and d in header[0]), None)
                hint = (f" (its cells are separated by {other!r}: say {stream.group}."
                        f"delimiter = {other!r})" if other else "")
                raise ConfigError(f"{str(path)!r}: no column {c!r} (the log description's "
                                  f"{said}); the file has {has}{hint}")
    extra = [c for c in header if c not in named and c not in stream.ignore]
    if "" in extra:
        raise ConfigError(f"{str(path)!r}: column {header.index('') + 1} of the header has no "
                          "name; expected a name for every column (a delimiter at the end of "
                          "each line?)")
    if extra:
        raise ConfigError(f"{str(path)!r}: column {extra[0]!r} is not in the log description; "
                          f"expected it mapped in {stream.group}.columns or listed in "
                          f"{stream.group}.ignore")
    use = sorted({header.index(c) for c in named})
    # A stream whose no-data value is NaN reads an empty cell (what pandas writes for NaN)
    # as NaN too; any other stream needs a number in every cell.
    empty_is_nan = stream.invalid is not None and math.isnan(stream.invalid)
    try:
        with warnings.catch_warnings():  # a header alone: refused below, in one line
            warnings.filterwarnings("ignore", "loadtxt: input contained no data")
            array = np.loadtxt(path, delimiter=stream.delimiter, skiprows=1, usecols=use,
                               ndmin=2, encoding="utf-8-sig", comments=None,
                               converters=_empty_as_nan if empty_is_nan else None)
    except ValueError:
        raise ConfigError(_bad_row(path, stream.delimiter, header)) from None
    if array.shape[0] < 2:
        raise ConfigError(f"{str(path)!r}: {array.shape[0]} row(s) under the header; expected "
                          "a stream of samples (at least 2)")
    # loadtxt takes a row of more cells when usecols is given: count them.
    _check_width(path, stream.delimiter, header, array.shape[0])
    bad = ~np.isfinite(array)
    if stream.invalid is not None and math.isnan(stream.invalid):  # NaN: no data, declared
        codes = [header.index(c) for c in stream.columns.get("status", ())]
        bad &= np.isinf(array) | np.isin(use, [header.index(stream.time), *codes])
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise ConfigError(f"{str(path)!r} line {row + 2}: column {header[use[col]]!r} is "
                          f"{array[row, col]}; expected a number in every cell (a row of "
                          "missing data is dropped from the log, not left NaN; a DVL that "
                          "writes nan for no bottom lock: invalid = \"nan\")")
    column = {i: array[:, k] for k, i in enumerate(use)}
    out = {key: np.stack([column[header.index(c)] for c in cols], axis=1)
           for key, cols in stream.columns.items()}
    if stream.invalid is not None and not math.isnan(stream.invalid):
        # the instrument's no-data value, as logged: NaN from here on
        for key, v in out.items():
            if key != "status":  # a code, not a measurement: kept as logged
                v[v == stream.invalid] = np.nan
    out = {key: (v[:, 0] if v.shape[1] == 1 else v) * stream.units[key]
           for key, v in out.items()}
    stamps = column[header.index(stream.time)]
    t = stamps * stream.scale
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        k = back[0]
        what = "repeats" if t[k + 1] == t[k] else "runs backwards"
        # As written (in full: an epoch's stamps differ in their last digits).
        raise ConfigError(f"{str(path)!r} line {k + 3}: time {what} ({float(stamps[k])!r}, "
                          f"then {float(stamps[k + 1])!r} in column {stream.time!r}); "
                          "expected increasing stamps")
    out["time"] = t
    return out


def _check_width(path: Path, delimiter: str, header: list[str], rows: int) -> None:
    """Every row has as many cells as the ``header`` (loadtxt does not check the cells it
    skips); cheap when they do: only a file whose delimiters do not add up is scanned."""
    with open(path, "rb") as f:
        data = f.read()
    if data.count(delimiter.encode()) == (len(header) - 1) * (rows + 1):
        return
    raise ConfigError(_bad_row(path, delimiter, header))


def _empty_as_nan(cell: str) -> float:
    return float(cell) if cell.strip() else math.nan


def _unquoted(name: str) -> str:
    return name[1:-1] if len(name) >= 2 and name[0] == name[-1] == '"' else name


def _bad_row(path: Path, delimiter: str, header: list[str]) -> str:
    """The first row that is not numbers under each of ``header``'s columns, said in one
    line."""
    width = len(header)
    with open(path, encoding="utf-8-sig") as f:
        next(f, None)
        for number, line in enumerate(f, start=2):
            if not line.strip():
                continue
            cells = line.rstrip("\r\n").split(delimiter)
            if len(cells) != width:
                return (f"{str(path)!r} line {number}: {len(cells)} cells, the header has "
                        f"{width}; expected every row to have the header's columns")
            for column, cell in zip(header, cells, strict=True):
                try:
                    float(cell)
                except ValueError:
                    empty = ("; an empty cell is missing data, which only a DVL's no-data "
                             "value may be: invalid = \"nan\" takes empty cells too"
                             if not cell.strip() else "")
                    return (f"{str(path)!r} line {number}: {cell.strip()!r} under "
                            f"{column!r} is not a number; expected numbers under the "
                            f"header{empty}")
    return f"{str(path)!r}: cannot be read as a table of numbers"


# ---- one log -------------------------------------------------------------------------


@dataclass
class Recording:
    """One log, read and checked: its mission name, its groups (``RECORDED_GROUPS``
    order), fields by path, attributes and the files it came from (one per group)."""

    name: str
    groups: list[str]
    fields: dict[str, np.ndarray]
    attrs: dict[str, object]
    files: list[Path]


def read_log(folder: str | os.PathLike, description: LogDescription, *,
             name: str | None = None) -> Recording:
    """Read and check one log: the files ``description`` names, in ``folder``.

    Raises:
        ConfigError: a file does not fit the description, a unit cannot be right, or the
            streams do not overlap in time (one line each).
    """
    folder = Path(folder)
    name = name or description.name or folder_name(folder)
    check_mission_name(name, f"{str(folder)!r}: the mission's name (log.name, or the folder's)")
    tables = {g: read_table(folder / s.file, s) for g, s in description.streams.items()}
    streams = description.streams
    where = {g: repr(str(folder / s.file)) for g, s in streams.items()}
    _check_rates(tables, streams, where)
    _check_units(tables, where)
    starts = {g: t["time"][0] + streams[g].offset for g, t in tables.items()}
    ends = {g: t["time"][-1] + streams[g].offset for g, t in tables.items()}
    if len(tables) > 1 and max(starts.values()) >= min(ends.values()):
        a = max(starts, key=starts.get)
        b = min(ends, key=ends.get)
        raise ConfigError(f"{where[a]}: the {a} stream spans {starts[a]:.9g} to {ends[a]:.9g} s"
                          f" and the {b} stream {starts[b]:.9g} to {ends[b]:.9g} s: they do not "
                          "overlap; expected streams of one mission (check the files and each "
                          "stream's time_offset_s)")
    spans = {g: ends[g] - starts[g] for g in tables}
    long, short = max(spans, key=spans.get), min(spans, key=spans.get)
    if spans[long] > SPAN_RATIO * max(spans[short], 1e-9):
        raise ConfigError(f"{where[long]}: the {long} stream spans {spans[long]:.6g} s and the "
                          f"{short} stream {spans[short]:.6g} s; expected streams of one "
                          f"mission (is {long}.time_unit or {short}.time_unit right: s, ms, "
                          "us or ns?)")
    t0 = min(starts.values())
    fields: dict[str, np.ndarray] = {}
    attrs: dict[str, object] = {}
    for g, table in tables.items():
        s = streams[g]
        t = table["time"] + (s.offset - t0)
        fields[f"{g}/time"] = t
        if g == "reference":
            fields.update(_reference(table, s))
            attrs.update(reference_source=description.reference_source,
                         reference_time_offset_s=s.offset)
        elif g == "imu":
            fields["imu/specific_force"] = table["specific_force"] @ s.axes.T
            fields["imu/angular_rate"] = table["angular_rate"] @ s.axes.T
            attrs.update({f"imu_{k}": v for k, v in s.specs.items()},
                         imu_position_body=np.array(s.position_body), imu_time_offset_s=s.offset)
        elif g == "dvl":
            fields.update(_dvl(table, s))
            attrs.update(beam_angle_deg=s.specs["beam_angle_deg"],
                         dvl_position_body=np.array(s.position_body),
                         dvl_mounting_rpy_deg=np.array(s.mounting_rpy_deg),
                         dvl_noise_std=_dvl_noise(table, s, where[g]),
                         dvl_velocity_accuracy=s.specs["velocity_accuracy"],
                         dvl_time_offset_s=s.offset,
                         dvl_beams_derived=int("beam_velocity" not in table))
        else:
            fields["depth/depth"] = table["depth"]
            attrs["depth_time_offset_s"] = s.offset
        attrs[f"{g}_rate_hz"] = 1.0 / float(np.median(np.diff(t)))
    if description.origin is not None:
        origin = description.origin
    elif "reference" in tables:
        origin = (float(fields["reference/latitude_deg"][0]),
                  float(fields["reference/longitude_deg"][0]),
                  float(fields["reference/height_m"][0]))
    else:
        raise ConfigError("log description: log.origin: missing; expected [latitude deg, "
                          "longitude deg, height m] when the log has no reference")
    if "reference" in tables:
        fields["reference/position_ned"] = ned_from_geodetic(
            fields["reference/latitude_deg"], fields["reference/longitude_deg"],
            fields["reference/height_m"], origin)
        _check_track(fields, where["reference"])
        _check_heading(fields, where["reference"])
        _check_speeds(tables, where)  # the reference agrees with itself: now the DVL
    groups = [g for g in RECORDED_GROUPS if g in tables]
    duration = max(float(fields[f"{g}/time"][-1]) for g in groups)
    attrs.update(groups=json.dumps(groups), latitude_deg=origin[0], longitude_deg=origin[1],
                 height_m=origin[2], gravity=normal_gravity(origin[0], origin[2]),
                 log_time_origin_s=t0, duration_s=duration)
    files = [folder / streams[g].file for g in groups]
    return Recording(name, groups, fields, attrs, files)


RATE_RANGE = (0.5, 2.0)  # the stamps' median rate over the stated one that a log may have
# Where a stream states no rate, the rates its stamps may come at, Hz: wider than any
# instrument of its kind that we know logs (IMUs from a few Hz to a few kHz; DVLs ping
# from every few seconds, deep, to tens of Hz; depth sensors and navigation solutions
# alike), narrower than a time column in another unit makes them (ms read as s: a 100 Hz
# IMU at 0.1 Hz, a 1 Hz DVL at 0.001 Hz).
PLAUSIBLE_RATES = {"imu": ("an IMU's", 1.0, 10_000.0), "dvl": ("a DVL's", 0.02, 100.0),
                   "depth": ("a depth sensor's", 0.02, 1000.0),
                   "reference": ("a navigation solution's", 0.02, 1000.0)}


def _check_rates(tables: dict[str, dict[str, np.ndarray]], streams: dict[str, Stream],
                 where: dict[str, str]) -> None:
    """Each stream's stamps at its stated rate (``rate_hz``), within ``RATE_RANGE``: wider
    than any clock's error or a log's dropped samples, narrower than a time column in
    another unit (ms read as s: a thousandth of the rate)."""
    for g, s in streams.items():
        rate = 1.0 / float(np.median(np.diff(tables[g]["time"])))
        if s.rate_hz is None:
            kind, low, high = PLAUSIBLE_RATES[g]
            if not low <= rate <= high:
                raise ConfigError(f"{where[g]}: its stamps come at {rate:.4g} Hz; expected "
                                  f"{kind} rate, {low:g} to {high:g} Hz (is "
                                  f"{g}.time_unit right: s, ms, us or ns? a log at another "
                                  f"rate: state it in {g}.rate_hz)")
            continue
        if not RATE_RANGE[0] <= rate / s.rate_hz <= RATE_RANGE[1]:
            raise ConfigError(f"{where[g]}: its stamps come at {rate:.4g} Hz, the log "
                              f"description's {g}.rate_hz says {s.rate_hz:g} Hz; expected "
                              f"the time column in {g}.time_unit (s, ms, us or ns) and the "
                              "instrument's stated rate")


def _dvl(table: dict[str, np.ndarray], s: Stream) -> dict[str, np.ndarray]:
    out = {key: values for key, values in table.items() if key != "time"}
    velocity = out.pop("velocity") @ s.axes.T
    fields = {"dvl/velocity_ls": velocity,
              "dvl/mode": np.where(np.isfinite(velocity).all(axis=1), 0, -1)}
    codes = out.pop("status", None)
    for key, values in out.items():
        fields[f"dvl/{key}"] = values
    if codes is not None:  # the instrument's codes per beam, whole numbers as logged
        if not np.array_equal(codes, np.round(codes)):
            raise ConfigError(f"{s.file!r}: dvl.columns.status: expected whole-number codes, "
                              f"got {codes[codes != np.round(codes)][0]:g}")
        fields["dvl/status"] = codes.astype(np.int64)
    if "beam_velocity" in out:
        fields["dvl/valid"] = np.isfinite(out["beam_velocity"])
    return fields


def _dvl_noise(table: dict[str, np.ndarray], s: Stream, where: str) -> float:
    """The DVL's white beam noise, m/s: its ``noise_std`` as the log description states
    it, else what its logged error velocity shows (``beam_noise_from_error_velocity``),
    which the description (the file's ``log_description``) then lacks.

    Raises:
        ConfigError: the error velocity has fewer than 2 values to estimate it from.
    """
    if "noise_std" in s.specs:
        return s.specs["noise_std"]
    try:
        return beam_noise_from_error_velocity(table["error_velocity"], s.specs["beam_angle_deg"])
    except ValueError:
        raise ConfigError(f"{where}: dvl.noise_std is not stated and the error velocity has "
                          "fewer than 2 values to estimate it from; expected the "
                          "instrument's beam noise (dvl.noise_std)") from None


def _reference(table: dict[str, np.ndarray], s: Stream) -> dict[str, np.ndarray]:
    out = {"reference/latitude_deg": np.degrees(table["latitude"]),
           "reference/longitude_deg": np.degrees(table["longitude"]),
           "reference/height_m": table["height"],
           "reference/velocity_ned": table["velocity"] @ s.axes.T}
    if "attitude" in table:
        q = quaternion_from_euler(*table["attitude"].T)
        if s.axes[0, 0] == 0:  # ENU: the frame's rotation first (ENU -> NED, 180 deg about NE)
            q = quaternion_product(np.array([0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0]), q)
        if s.body_flip:  # FLU body: FRD -> FLU, 180 deg about x, then the attitude
            q = quaternion_product(q, np.array([0.0, 1.0, 0.0, 0.0]))
        q *= np.where(q[:, :1] < 0, -1.0, 1.0)  # w >= 0: one of the two signs, always
        out["reference/quaternion"] = q
        out["reference/rpy_deg"] = np.degrees(euler_angles(q))
    return out


def rate_slip(angular_rate: np.ndarray) -> int | None:
    """The first sample of a gyro record (N, 3) beyond ``MAX_RATE``, where more than
    ``UNIT_SLIP_SHARE`` of them are (the record is in another unit); None otherwise."""
    beyond = np.linalg.norm(angular_rate, axis=1) > MAX_RATE
    return int(np.argmax(beyond)) if np.mean(beyond) > UNIT_SLIP_SHARE else None


def force_slip(specific_force: np.ndarray, g: float) -> float | None:
    """The median |specific force| of an accelerometer record (N, 3) where it lies outside
    ``FORCE_FACTORS`` of ``g`` (the record is in another unit); None otherwise."""
    force = float(np.median(np.linalg.norm(specific_force, axis=1)))
    return None if FORCE_FACTORS[0] * g < force < FORCE_FACTORS[1] * g else force


def _check_units(tables: dict[str, dict[str, np.ndarray]], where: dict[str, str]) -> None:
    """Refuse values no vehicle's log holds in the declared unit (see the bounds above)."""
    if "imu" in tables:
        k = rate_slip(tables["imu"]["angular_rate"])
        if k is not None:
            rate = float(np.linalg.norm(tables["imu"]["angular_rate"][k]))
            raise ConfigError(
                f"{where['imu']} line {k + 2}: the angular rate reaches {rate:.4g} rad/s, "
                "beyond a full turn per second; expected rad/s as declared (are the gyros in "
                "deg/s? say imu.units.angular_rate = \"deg/s\")")
        force = force_slip(tables["imu"]["specific_force"], G0)
        if force is not None:
            raise ConfigError(
                f"{where['imu']}: the specific force's median magnitude is {force:.4g} m/s^2 "
                "in the declared unit; expected about gravity, 9.8 m/s^2 (is "
                "imu.units.specific_force right: m/s^2 or g?)")
    if "dvl" in tables:
        v = np.linalg.norm(tables["dvl"]["velocity"], axis=1)
        speed = float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any() else 0.0
        if speed > MAX_SPEED:
            raise ConfigError(
                f"{where['dvl']}: the DVL's median speed is {speed:.4g} m/s in the declared "
                f"unit, beyond {MAX_SPEED:g} m/s; expected m/s (is dvl.units.velocity mm/s?)")
        # One ping beyond the bound, the rest alike: the instrument's no-data value (an
        # RDI DVL's -32768 mm/s) that the description does not name.
        for key in ("velocity", "beam_velocity"):
            if key not in tables["dvl"]:
                continue
            values = np.nan_to_num(tables["dvl"][key], nan=0.0)
            row = np.flatnonzero(np.abs(values).max(axis=1) > MAX_SPEED)
            if len(row):
                k = int(row[0])
                worst = values[k, np.abs(values[k]).argmax()]
                raise ConfigError(
                    f"{where['dvl']} line {k + 2}: the DVL's {key.replace('_', ' ')} reads "
                    f"{worst:.6g} m/s, beyond {MAX_SPEED:g} m/s; expected a "
                    "vehicle's velocity (is it the instrument's no-data value? name it in "
                    "dvl.invalid, in the log's own unit)")
    if "reference" in tables:
        ref = tables["reference"]
        for key, limit, what in (("latitude", math.pi / 2, "90 deg"),
                                 ("longitude", 2 * math.pi, "360 deg")):
            worst = float(np.abs(ref[key]).max())
            if worst > limit * (1 + 1e-9):
                raise ConfigError(
                    f"{where['reference']}: the {key} reaches {math.degrees(worst):.6g} deg "
                    f"in the declared unit, beyond {what}; expected its unit as declared "
                    f"(reference.units.{key}: deg or rad?)")
        if "attitude" in ref:
            worst = float(np.abs(ref["attitude"]).max())
            if worst > 2 * math.pi * (1 + 1e-9):
                raise ConfigError(
                    f"{where['reference']}: an attitude angle reaches {worst:.6g} rad, "
                    "beyond a full turn; expected radians as declared (reference.units."
                    "attitude = \"deg\"?)")


def _check_speeds(tables: dict[str, dict[str, np.ndarray]], where: dict[str, str]) -> None:
    """The DVL's median speed within ``SPEED_RATIO`` of the reference's, where the
    reference moves (``MOVING``): a velocity in mm/s declared as m/s (or the reverse)
    makes them differ a thousandfold."""
    if "dvl" not in tables:
        return
    v = np.linalg.norm(tables["dvl"]["velocity"], axis=1)
    dvl = float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any() else 0.0
    ref = float(np.median(np.linalg.norm(tables["reference"]["velocity"], axis=1)))
    if ref > MOVING and not 1 / SPEED_RATIO < dvl / ref < SPEED_RATIO:
        raise ConfigError(f"{where['dvl']}: the DVL's median speed is {dvl:.4g} m/s and the "
                          f"reference's {ref:.4g} m/s; expected them alike (is "
                          "dvl.units.velocity right: m/s or mm/s?)")


def _check_track(fields: dict[str, np.ndarray], where: str) -> None:
    """The distance travelled by the reference's positions and by its integrated
    velocities agree to within ``TRACK_RATIO`` (lat/lon in degrees declared as radians, or
    the reverse, makes them differ by 57x), and so do their directions, to
    ``TRACK_COSINE`` over legs of ``TRACK_LEG`` samples (a frame declared NED for ENU
    velocities mirrors one against the other)."""
    t = fields["reference/time"]
    step = np.linalg.norm(np.diff(fields["reference/position_ned"][:, :2], axis=0), axis=1)
    v = np.linalg.norm(fields["reference/velocity_ned"][:, :2], axis=1)
    flown = float(np.sum((v[1:] + v[:-1]) / 2 * np.diff(t)))
    track = float(step.sum())
    if max(flown, track) > MIN_TRACK and not (
            1 / TRACK_RATIO < track / max(flown, 1e-12) < TRACK_RATIO):
        ratio = max(track, flown) / max(min(track, flown), 1e-12)
        time_unit = any(abs(math.log10(ratio) - k) < 0.05 for k in (3, 6, 9))
        raise ConfigError(
            f"{where}: the positions travel {track:.4g} m but the velocities "
            f"{flown:.4g} m; expected them to agree ("
            + ("a thousandfold or more: is reference.time_unit right, s, ms, us or ns?)"
               if time_unit else "are reference.units.latitude and longitude, or the "
               "velocity's, right?)"))
    if max(flown, track) > MIN_TRACK:
        a, b = _legs(fields, slice(0, 2))
        dot = float(np.sum(a * b))
        cosine = dot / max(math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b))), 1e-12)
        if cosine < TRACK_COSINE:
            angle = math.degrees(math.atan2(float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])),
                                            dot))
            raise ConfigError(
                f"{where}: the positions move in another direction than the velocities "
                f"(their legs of {TRACK_LEG} samples agree to a cosine of {cosine:.2f}, a "
                f"mean turn of {angle:+.0f} deg); expected them to agree (is reference.frame "
                "right, NED or ENU? are the latitude and longitude columns swapped?)")
    _check_vertical(fields, where)


def _check_heading(fields: dict[str, np.ndarray], where: str) -> None:
    """The reference's yaw and its course over the ground agree to ``MAX_CRAB`` (median,
    where it moves faster than ``CRABBING_SPEED``): a compass heading in an ENU frame's
    yaw column (``90 - h`` is the ENU yaw) passed the import, and every finding of
    check-log was then nonsense."""
    if "reference/rpy_deg" not in fields:
        return
    v = fields["reference/velocity_ned"]
    moving = np.hypot(v[:, 0], v[:, 1]) > CRABBING_SPEED
    if moving.sum() < MIN_MOVING_SAMPLES:
        return
    course = np.degrees(np.arctan2(v[moving, 1], v[moving, 0]))
    off = (course - fields["reference/rpy_deg"][moving, 2] + 180.0) % 360.0 - 180.0
    median = float(np.median(np.abs(off)))
    if median > MAX_CRAB:
        raise ConfigError(
            f"{where}: the yaw differs from the course over the ground by {median:.0f} deg "
            f"(median, where it moves faster than {CRABBING_SPEED:g} m/s); expected them "
            f"within {MAX_CRAB:g} deg, a vehicle's sideslip and a current's crab angle (is "
            "the yaw column in reference.frame? a compass heading h is an ENU yaw of 90 - h)")


def _legs(fields: dict[str, np.ndarray], axes: slice) -> tuple[np.ndarray, np.ndarray]:
    """The reference's moves over legs of ``TRACK_LEG`` samples (and the last, shorter
    one), in the NED ``axes``: (K, n) by its positions and (K, n) by its velocities'
    integral."""
    t = fields["reference/time"]
    moved = cumulative(t, fields["reference/velocity_ned"][:, axes])
    legs = np.unique(np.append(np.arange(0, len(t), TRACK_LEG), len(t) - 1))
    return (np.diff(fields["reference/position_ned"][legs, axes], axis=0),
            np.diff(moved[legs], axis=0))


def _check_vertical(fields: dict[str, np.ndarray], where: str) -> None:
    """The reference's heights against its integrated vertical velocity, where both
    travel ``MIN_CLIMB`` up and down: a frame declared NED for ENU velocities turns up into
    down (on a heading of 45 deg the horizontal legs cannot tell), and so does a depth
    column, positive down, given as the height."""
    a, b = (x[:, 0] for x in _legs(fields, slice(2, 3)))
    if min(np.abs(a).sum(), np.abs(b).sum()) < MIN_CLIMB:
        return
    cosine = float(a @ b) / max(float(np.linalg.norm(a) * np.linalg.norm(b)), 1e-12)
    if cosine < 0:
        raise ConfigError(
            f"{where}: the heights go down where the vertical velocity goes up (their legs "
            f"of {TRACK_LEG} samples agree to a cosine of {cosine:.2f}); expected them to "
            "agree (is reference.frame right, NED or ENU? is the height column a depth, "
            "positive down?)")


# ---- the import ----------------------------------------------------------------------


def folder_name(path: str | os.PathLike) -> str:
    """A folder's own name as its user gave it (``.`` and ``..`` made absolute, a
    symbolic link's name kept, not its target's)."""
    return Path(os.path.abspath(path)).name


def akit_segments(source: Path) -> list[tuple[Path, int]]:
    """The A-KIT segments under ``source``: itself if it is a ``TrajectoryK`` folder, else
    its ``TrajectoryK`` subfolders, in K order."""
    if not source.is_dir():
        raise ConfigError(f"{str(source)!r}: not a folder; expected an A-KIT folder "
                          "(TrajectoryK/ subfolders) or one TrajectoryK folder")
    match = AKIT_SEGMENT.fullmatch(folder_name(source))
    if match:
        return [(source, int(match[1]))]
    found = sorted(((p, int(m[1])) for p in source.iterdir()
                    if p.is_dir() and (m := AKIT_SEGMENT.fullmatch(p.name))),
                   key=lambda pk: pk[1])
    if not found:
        raise ConfigError(f"{str(source)!r}: no TrajectoryK folder in it; expected the A-KIT "
                          "layout, TrajectoryK/{IMU,DVL,GT}_trajectoryK.csv")
    return found


def read_description(path: str | os.PathLike, *, argument: str = "description") -> str:
    """The text of a log description file (or any small TOML file a command names: the
    error names ``argument``, the library argument that gave it).

    Raises:
        ConfigError: the file is missing or cannot be read as text.
    """
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise ConfigError(f"{str(path)!r}: no such file", argument=argument) from None
    except IsADirectoryError:
        raise ConfigError(f"{str(path)!r}: is a folder; expected a TOML file",
                          argument=argument) from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{str(path)!r}: cannot read it ({e})", argument=argument) from None


def import_logs(sources: Sequence[str | os.PathLike], out: str | os.PathLike, *,
                format: str, description: str | os.PathLike | None = None,
                compression: str = "lzf") -> dict[str, dict]:
    """Write a dataset with one recorded mission per log (every log read and checked
    before anything is written; the file is built under a temporary name and renamed
    when complete).

    Args:
        sources: ``akit``: A-KIT folders (or ``TrajectoryK`` folders), a mission per
            segment; ``csv``: log folders, a mission each (named by the folder, or by
            ``log.name`` for a single one).
        out: the HDF5 file to write.
        format: ``akit`` or ``csv`` (``velocity`` is ``auvsim.data.importer``'s).
        description: the log description file (``csv``; ``akit`` has its own).

    Returns:
        Each mission's groups, by name: ``{group: (rows, rate Hz)}``.
    """
    if format not in ("akit", "csv"):
        raise ConfigError(f": expected akit or csv, got {format!r}", argument="format")
    if not sources:
        raise ConfigError(": expected at least one log", argument="sources")
    logs: list[tuple[Path, LogDescription, str | None]] = []
    if format == "akit":
        if description is not None:
            raise ConfigError(": the akit layout has its own description; give one only "
                              "with --format csv", argument="description")
        for source in sources:
            for folder, k in akit_segments(Path(source)):
                text = AKIT_DESCRIPTION.replace("{k}", str(k))
                logs.append((folder, parse_description(text, where=f"akit layout ({folder})"),
                             None))
    else:
        if description is None:
            raise ConfigError(": missing; --format csv needs a log description (TOML)",
                              argument="description")
        parsed = parse_description(read_description(description), where=str(description))
        for source in sources:
            if not Path(source).is_dir():
                raise ConfigError(f"{str(source)!r}: not a folder; expected the folder of a "
                                  "log's CSV files")
            logs.append((Path(source), parsed,
                         None if len(sources) == 1 else folder_name(source)))
    recordings = [read_log(folder, d, name=name) for folder, d, name in logs]
    names = [r.name for r in recordings]
    if len(set(names)) != len(names):
        raise ConfigError(f"mission names must differ, got {names}; rename a folder")
    read = [p for r in recordings for p in r.files] + ([] if description is None
                                                       else [Path(description)])
    if Path(out).exists() and any(Path(out).samefile(p) for p in read):
        raise ConfigError(f"{str(out)!r}: is one of the log's own files; expected a new path "
                          "for the dataset (the log stays as recorded)", argument="out")
    settings = dict(format=format, sources=[str(s) for s in sources],
                    description=None if description is None else str(description))
    summary: dict[str, dict] = {}
    with DatasetWriter(out, config_json=json.dumps({"import": settings}),
                       compression=compression) as writer:
        for recording, (_, d, _) in zip(recordings, logs, strict=True):
            attrs = mission_attrs(
                origin="recorded", scenario="recorded", seed=0,
                log_description=d.text,
                source_files=json.dumps([str(p) for p in recording.files]),
                source_sha256=json.dumps([hashlib.sha256(p.read_bytes()).hexdigest()
                                          for p in recording.files]),
                **recording.attrs)
            rows = {g: len(recording.fields[f"{g}/time"]) for g in recording.groups}
            sink = writer.mission(recording.name, attrs, rows=rows)
            sink.append(recording.fields)
            sink.flush()
            summary[recording.name] = {g: (rows[g], attrs[f"{g}_rate_hz"])
                                       for g in recording.groups}
    return summary
