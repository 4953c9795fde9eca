"""The dataset format: its name and version, the fields and attributes of a mission, and
the records of a sharded dataset's index. The one place that says what a file holds.

A dataset is an HDF5 file whose root attributes are ``format`` (``FORMAT``),
``format_version`` (``FORMAT_VERSION``), ``auvsim_version``, ``created_utc`` and
``config_json`` (the resolved config that made it), and whose group ``missions`` holds one
group per mission: its attributes (``schema(origin)[1]``) and its fields as datasets
``<group>/<field>``, time along the first axis (``schema(origin)[0]``). The schema is the
core (truth, controls and mission attributes, here) plus the fields and attributes each
sensor plugin declares (``auvsim.sensors``).

A sharded dataset is a folder: its shards in ``SHARDS/`` (ordinary dataset files holding
some of the missions, sealed with the root attributes ``config_sha256`` and
``data_sha256``, ``data_digest``) and an index ``INDEX`` (root attribute
``layout = "index"``, ``shards`` a JSON list of ``Shard`` records) whose missions are HDF5
external links into them.

A mission of origin ``recorded`` (a real vehicle's logs, ``auvsim import``) has a schema of
its own (``recorded_schema``): the groups its attribute ``groups`` lists, each stream on its
own clock, and a ``reference`` group (a navigation solution) in place of ``truth``.

Reading lives in ``auvsim.data.reader``, writing in ``auvsim.data.writer``, the sharded
layout in ``auvsim.data.shards``, ``auvsim inspect``'s summary in ``auvsim.data.describe``
and the recorded logs' import in ``auvsim.data.recorded``.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache

import h5py
import numpy as np

from auvsim.sensors import Attr, Field, Sensor, Truth, registry

FORMAT = "auvsim-dataset"
# Version 2 = version 1 + a mission attribute ``origin``, which lets a mission imported from
# a recorded DVL stream hold only its DVL group. Version 3 = version 2 + the depth sensor's
# group and attributes, and a Fletcher-32 checksum on every dataset. Version 4 = version 3
# + the realism of issue 10: the water's current in the truth, the DVL's status codes,
# error velocity and mode, and the new realised sensor parameters (each ``Field`` and
# ``Attr`` says ``since=4``). Version 5 = version 4 + sharded datasets: shard files carry
# the root attributes ``config_sha256`` and ``data_sha256`` (``data_digest``), and an index
# file (root attribute ``layout = "index"``) links their missions. Version 6 = version 5 +
# two attributes of every simulated mission, facts a reader would otherwise re-derive from
# the simulator: ``gravity`` (m/s^2, the magnitude of the vehicle model's gravity, from
# its compiled MJCF) and ``phases`` (its manoeuvre's phases, ``phases_json``). Older files
# are read; ``auvsim.data.reader.Mission`` derives both for them as before (``gravity``
# from the model file named by the config, ``phases`` by making the manoeuvre again from
# the mission's seed). Version 7 = version 6 + a third origin, ``recorded``: a real
# vehicle's logs (IMU, DVL, depth, and a navigation solution as the ``reference``, never
# called truth), each stream on its own clock, every group optional and named by the
# mission's ``groups`` attribute (``recorded_schema``). A new origin changes what a
# reader must expect of a mission, so the version says it: a version-6 reader refuses the
# file in one line instead of misreading it. Simulated and imported missions are written
# as in version 6, array by array; older files are read as before. Also from version 7, a
# simulated mission flown at a geographic origin (``auvsim.config.LocationConfig``) holds
# the optional attributes ``latitude_deg`` and ``longitude_deg``, its ``gravity`` is the
# WGS-84 normal gravity there, and its IMU measured the rotating Earth; without an
# origin, nothing changes.
FORMAT_VERSION = 7
READABLE_VERSIONS = (1, 2, 3, 4, 5, 6, 7)
INDEX = "index.h5"  # a sharded dataset's index, in its folder
SHARDS = "shards"  # the folder of its shards, beside the index
ORIGINS = ("simulated", "imported", "recorded")
RECORDED_SINCE = 7  # the first version with recorded missions

# The core of every simulated mission; the sensors add their own (``schema``).
CORE_FIELDS = (
    Field("truth/time", (), "f", "imu", "s", "at the IMU rate"),
    Field("truth/position_ned", (3,), "f", "imu", "m", "body origin"),
    Field("truth/velocity_ned", (3,), "f", "imu", "m/s", "body origin, over the ground"),
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
    Attr("origin", None, "simulated, imported or recorded (v7)", imported=True),
    Attr("scenario", None, "the manoeuvre's name", imported=True),
    Attr("seed", (), "the mission's seed", imported=True, low=0, whole=True),
    Attr("duration_s", (), "s", imported=True, low=0, strict=True),
    Attr("vehicle", None, "vehicle name or model path"),
    Attr("water_surface_speed", (), "REALISED surface speed of the mission's current, m/s "
         "(before its variation in time and space; auvsim.physics.water)", low=0, since=4),
    Attr("water_direction_deg", (), "REALISED direction the surface current flows toward, "
         "deg from north", since=4),
    Attr("gravity", (), "m/s^2, magnitude of the vehicle model's gravity (its compiled MJCF's "
         "opt.gravity, pointing down); with a geographic origin (v7), the WGS-84 normal "
         "gravity at it on the surface", low=0, strict=True, since=6),
    Attr("phases", None, "the manoeuvre's phases, a JSON list of [start s, end s, label] "
         "(auvsim.physics.maneuvers.Maneuver.phases; [] for a mission flown by a policy, "
         "such as an environment's episode)", since=6),
    # A simulated mission flown at a geographic origin (auvsim.config.LocationConfig).
    Attr("latitude_deg", (), "geodetic latitude of the mission origin, deg (only with a "
         "geographic origin: its IMU measures the Earth's rate and normal gravity there)",
         since=7, optional=True),
    Attr("longitude_deg", (), "longitude of the mission origin, deg (with latitude_deg)",
         since=7, optional=True),
)
IMPORT_ATTRS = (Attr("source_file", None, "the recording"),
                Attr("source_sha256", None, "its SHA-256"))


# A recorded mission (schema v7): every group optional, the ``groups`` attribute says
# which are there; each group's fields are on its own clock (its ``time``, s, from the log's
# first stamp, after the stream's described time offset). Fields in ``RECORDED_OPTIONAL``
# may be absent from a group that is present.
RECORDED_GROUPS = ("imu", "dvl", "depth", "reference")
RECORDED_FIELDS = (
    Field("imu/time", (), "f", "imu", "s", "the IMU's own clock"),
    Field("imu/specific_force", (3,), "f", "imu", "m/s^2", "body FRD, after the axis map"),
    Field("imu/angular_rate", (3,), "f", "imu", "rad/s", "body FRD, after the axis map"),
    Field("dvl/time", (), "f", "dvl", "s", "the DVL's own clock"),
    Field("dvl/velocity_ls", (3,), "f", "dvl", "m/s",
          "the instrument's own velocity output, DVL frame (NaN: no bottom lock)"),
    Field("dvl/beam_velocity", (4,), "f", "dvl", "m/s", "along each beam, as logged"),
    Field("dvl/beam_range", (4,), "f", "dvl", "m", "slant range of each beam"),
    Field("dvl/error_velocity", (), "f", "dvl", "m/s", "the instrument's error velocity"),
    Field("dvl/altitude", (), "f", "dvl", "m", "above the seafloor, as the DVL reports it"),
    Field("dvl/valid", (4,), "b", "dvl", "-", "the beam measured something"),
    Field("dvl/status", (4,), "i", "dvl", "-", "the instrument's status per beam"),
    Field("dvl/mode", (), "i", "dvl", "-", "0 bottom track, -1 none"),
    Field("depth/time", (), "f", "depth", "s", "the depth sensor's own clock"),
    Field("depth/depth", (), "f", "depth", "m", "positive down"),
    Field("reference/time", (), "f", "reference", "s", "the reference's own clock"),
    Field("reference/latitude_deg", (), "f", "reference", "deg", "geodetic, WGS-84"),
    Field("reference/longitude_deg", (), "f", "reference", "deg", "WGS-84"),
    Field("reference/height_m", (), "f", "reference", "m",
          "above the ellipsoid (negative under water)"),
    Field("reference/position_ned", (3,), "f", "reference", "m",
          "local NED from the mission origin (latitude_deg, longitude_deg, height_m)"),
    Field("reference/velocity_ned", (3,), "f", "reference", "m/s", "NED"),
    Field("reference/quaternion", (4,), "f", "reference", "-", "body -> NED, [w, x, y, z]"),
    Field("reference/rpy_deg", (3,), "f", "reference", "deg", "roll, pitch, yaw (ZYX)"),
)
RECORDED_OPTIONAL = frozenset({
    "dvl/beam_velocity", "dvl/beam_range", "dvl/error_velocity", "dvl/altitude",
    "dvl/valid", "dvl/status", "dvl/mode", "reference/quaternion", "reference/rpy_deg"})
_COMMON = {a.name: a for a in CORE_ATTRS if a.imported}
RECORDED_ATTRS = {  # group -> the attributes a recorded mission holds when it has it
    "": (
        _COMMON["origin"], _COMMON["scenario"], _COMMON["seed"], _COMMON["duration_s"],
        Attr("groups", None, "the groups present, a JSON list (of imu, dvl, depth, reference)"),
        Attr("latitude_deg", (), "the mission origin's geodetic latitude, deg"),
        Attr("longitude_deg", (), "the mission origin's longitude, deg"),
        Attr("height_m", (), "the mission origin's height above the ellipsoid, m"),
        Attr("gravity", (), "m/s^2, WGS-84 normal gravity at the mission origin "
             "(auvsim.physics.earth.normal_gravity)", low=0, strict=True),
        Attr("log_description", None, "the log description (TOML) the import followed"),
        Attr("source_files", None, "the log's files, a JSON list"),
        Attr("source_sha256", None, "their SHA-256, a JSON list in the same order"),
    ),
    "imu": (
        Attr("imu_rate_hz", (), "nominal rate, 1 / median sample interval, Hz", low=0,
             strict=True),
        Attr("imu_position_body", (3,), "m, body FRD, from the reference point"),
        Attr("imu_accel_noise_density", (), "instrument spec, m/s^2/sqrt(Hz)", low=0),
        Attr("imu_gyro_noise_density", (), "instrument spec, rad/s/sqrt(Hz)", low=0),
        Attr("imu_accel_bias_instability", (), "instrument spec, m/s^2", low=0),
        Attr("imu_gyro_bias_instability", (), "instrument spec, rad/s", low=0),
        Attr("imu_bias_correlation_time", (), "instrument spec, s", low=0, strict=True),
        Attr("imu_time_offset_s", (), "s, added to the log's stamps"),
    ),
    "dvl": (
        Attr("dvl_rate_hz", (), "nominal rate, 1 / median ping interval, Hz", low=0,
             strict=True),
        Attr("beam_angle_deg", (), "beam angle from the DVL's axis, deg", low=0),
        Attr("dvl_position_body", (3,), "m, body FRD, from the reference point"),
        Attr("dvl_mounting_rpy_deg", (3,), "deg, ZYX, DVL frame -> body"),
        Attr("dvl_noise_std", (), "the instrument's white beam noise, m/s", low=0),
        Attr("dvl_velocity_accuracy", (), "the instrument's stated velocity std, m/s", low=0),
        Attr("dvl_time_offset_s", (), "s, added to the log's stamps"),
        Attr("dvl_beams_derived", (), "1: the log has no beams (a reader deriving H v from "
             "velocity_ls must say so); 0: dvl/beam_velocity is the instrument's",
             low=0, whole=True),
    ),
    "depth": (
        Attr("depth_rate_hz", (), "nominal rate, Hz", low=0, strict=True),
        Attr("depth_time_offset_s", (), "s, added to the log's stamps"),
    ),
    "reference": (
        Attr("reference_source", None, "what the reference is (a navigation solution, "
             "never the truth)"),
        Attr("reference_rate_hz", (), "nominal rate, Hz", low=0, strict=True),
        Attr("reference_time_offset_s", (), "s, added to the log's stamps"),
    ),
}


def recorded_schema(groups: Sequence[str]) -> tuple[tuple[Field, ...], tuple[Field, ...],
                                                     tuple[Attr, ...]]:
    """What a recorded mission with these groups holds: its required fields, the
    optional ones it may hold, and its attributes.

    Raises:
        ValueError: a group is not one of ``RECORDED_GROUPS``, or none is given.
    """
    unknown = [g for g in groups if g not in RECORDED_GROUPS]
    if unknown or not groups:
        raise ValueError(f"expected groups among {', '.join(RECORDED_GROUPS)}, got "
                         f"{list(groups)}")
    fields = [f for f in RECORDED_FIELDS if f.path.split("/")[0] in groups]
    attrs = RECORDED_ATTRS[""] + tuple(a for g in RECORDED_GROUPS if g in groups
                                       for a in RECORDED_ATTRS[g])
    return (tuple(f for f in fields if f.path not in RECORDED_OPTIONAL),
            tuple(f for f in fields if f.path in RECORDED_OPTIONAL), attrs)


def parse_groups(text: object) -> list[str]:
    """The groups a recorded mission's ``groups`` attribute lists.

    Raises:
        ValueError: not a JSON list of known group names, or an empty one.
    """
    try:
        groups = json.loads(text) if isinstance(text, str) else None
    except ValueError:
        groups = None
    if not (isinstance(groups, list) and all(isinstance(g, str) for g in groups)
            and len(set(groups)) == len(groups)):
        raise ValueError(f"expected a JSON list of group names, got {text!r}")
    recorded_schema(groups)  # known names, at least one
    return groups


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


Phases = list[tuple[float, float, str]]


def phases_json(phases: Sequence[tuple[float, float, str]]) -> str:
    """A mission's ``phases`` attribute: (start s, end s, label) each, as a JSON list of
    lists (floats written exactly: ``parse_phases`` gives them back bit for bit)."""
    return json.dumps([[float(start), float(end), str(label)] for start, end, label in phases])


def parse_phases(text: str) -> Phases:
    """The phases a ``phases`` attribute holds (``phases_json``).

    Raises:
        ValueError: the text is not a JSON list of [start, end, label], finite numbers
            with start <= end and a string.
    """
    items = json.loads(text)
    if not isinstance(items, list):
        raise ValueError(f"expected a list of phases, got {type(items).__name__}")
    out = []
    for item in items:
        if not (isinstance(item, list) and len(item) == 3
                and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                        and math.isfinite(v) for v in item[:2])
                and item[0] <= item[1] and isinstance(item[2], str)):
            raise ValueError(f"expected [start s, end s, label], got {item!r}")
        out.append((float(item[0]), float(item[1]), item[2]))
    return out


def schema(origin: str, version: int = FORMAT_VERSION) -> tuple[tuple[Field, ...],
                                                                 tuple[Attr, ...]]:
    """The fields and attributes every mission of this origin (simulated or imported)
    holds in a file of this format version (extra ones are allowed): the core's and the
    sensor plugins'. A recorded mission's depend on its groups: ``recorded_schema``."""
    return _schema(origin, version, tuple(registry().values()))


@cache
def _schema(origin: str, version: int, plugins: tuple[type[Sensor], ...]
            ) -> tuple[tuple[Field, ...], tuple[Attr, ...]]:
    sensors = [s for s in plugins if s.since_version <= version]
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
    needed = (recorded_schema(parse_groups(out.get("groups")))[2] if origin == "recorded"
              else schema(origin)[1])
    missing = [a.name for a in needed if a.name not in out and not a.optional]
    if missing:
        raise ValueError(f"mission attributes: {origin} missions need {', '.join(missing)}")
    return out



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


def data_digest(file: h5py.File,
                read: Callable[[str, h5py.Dataset], np.ndarray] | None = None) -> str:
    """SHA-256 of a dataset file's missions: every mission's attributes and the values of
    every field (dtype, shape and bytes, by path in name order). The same data give the
    same digest however, whenever and wherever they were written.

    Args:
        file: the open file.
        read: reads a field whole, given its path under ``missions`` (``/<mission>/<group>
            /<field>``) and its dataset (a reader's, to refuse a corrupt one in its words);
            default ``dataset[()]``.
    """
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
                values = np.ascontiguousarray(item[()] if read is None
                                              else read(f"{prefix}/{key}", item))
                digest.update(f"{prefix}/{key}:{values.dtype.str}{values.shape}".encode())
                digest.update(values.tobytes())

    add(file["missions"], "")
    return digest.hexdigest()

