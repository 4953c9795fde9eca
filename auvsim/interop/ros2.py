"""A mission as a ROS 2 bag in MCAP, written without ROS (``auvsim export --to mcap``).

Libraries: ``mcap`` (the format's reference Python package) serialises the file's
records and ``mcap-ros2-support`` encodes the one message of variable length
(``/tf_static``). Every other topic has a fixed layout once its frame ids are set, so
``auvsim.interop.cdr`` encodes its messages all at once with numpy and
``auvsim.interop.mcapfile`` lays them out in chunks as arrays: mcap_ros2's
``write_message`` (encode and write) and the mcap writer's ``add_message`` (write), one
Python call a message, take ~27 us and ~3.2 us a message (``benchmarks/export.py``
prints both): a one-hour mission's 760k messages would take ~11 times its generation.
``rosbags`` was the other candidate; it stays the independent reader the tests read the
bags back with. The mission is encoded and written a minute at a time (``block_s``).

The file follows the MCAP specification's ``ros2`` profile ("Profiles", ROS 2): message
encoding ``cdr``, schema encoding ``ros2msg`` with every definition the message needs
embedded (``auvsim.interop.rosmsg``), and each channel's ``offered_qos_profiles``
metadata: empty (the player's defaults) but for ``/tf_static``, which offers what a
latched topic's publisher offers (keep last 1, reliable, transient local), so that
``ros2 bag play`` publishes it transient-local and late subscribers get it. The profile
is written as rosbag2 writes it (rosbag2_storage, ``qos.cpp``, ``convert<Rosbag2QoS>``:
a YAML list of ``history, depth, reliability, durability, deadline {sec, nsec},
lifespan, liveliness, liveliness_lease_duration, avoid_ros_namespace_conventions``), with
the policies as the rmw enums' numbers (rmw ``types.h``: KEEP_LAST 1, RELIABLE 1,
TRANSIENT_LOCAL 1, AUTOMATIC 1), the form of bag metadata versions up to 8 (Humble).
Later players read that form when the file has a ``rosbag2`` Metadata record without
``serialized_metadata`` (rosbag2_storage_mcap, ``MCAPStorage::read_metadata``), so the
bag has one, ``{"ROS_DISTRO": "humble"}`` as Humble's MCAP plugin writes it. Chunks are
zstd-compressed (level 1) by default.

Stamps are the mission clock: ``header.stamp`` (and each message's log and publish time)
is the sample's time from the start of the mission, in whole nanoseconds (rounded), so
the bag starts at 0 (1970-01-01 read as UNIX time); play it with ``--clock`` and
``use_sim_time``. Each recorded stream keeps its own clock, as in the dataset.

Frames. auvsim is NED/FRD; ROS is ENU/FLU (REP 103, "Axis Orientation"), which allows a
NED frame beside it with the suffix ``_ned`` ("Suffix Frames"). The data keep auvsim's
axes, exactly, in frames named for them, and ``/tf_static`` ties those frames to the ROS
ones: ``odom`` -> ``odom_ned`` (ENU to NED), ``base_link`` -> ``base_link_frd`` (FLU to
FRD), and the sensors' mountings from the mission's attributes: ``base_link_frd`` ->
``imu_link`` (``imu_position_body``, axes FRD) and -> ``dvl_link``
(``dvl_position_body``, ``dvl_mounting_rpy_deg``: the nominal mounting a user assumes).

Topics (``TOPICS``; ``topics=`` renames them):

- ``imu``: ``sensor_msgs/msg/Imu`` in ``imu_link`` at the IMU rate. ``angular_velocity``
  = ``imu/angular_rate``, ``linear_acceleration`` = ``imu/specific_force`` (what an
  accelerometer reads, as REP 145 asks). Covariances: diagonal, the white noise's variance
  per sample, density^2 x rate, from ``imu_gyro_noise_density`` and
  ``imu_accel_noise_density`` (biases not included). No orientation: its covariance[0]
  is -1 (Imu.msg).
- ``dvl``: ``marine_acoustic_msgs/msg/Dvl`` in ``dvl_link`` per ping. ``velocity`` =
  ``dvl/velocity_ls`` (the instrument's output, NaN with no velocity);
  ``velocity_covar`` the covariance of the velocity's error under the mission's noise
  model (``auvsim.interop.pings``: the beams' white noise, growing with speed in bottom
  track, the water-track noise in water track, through the least squares of the beams
  that measured, plus the slow error's variance; [0] = -1 with no velocity);
  ``velocity_mode`` 1 bottom track, 2 water track (``dvl/mode`` 0, 1), 0 no velocity
  (not one of the message's values); ``beam_unit_vec`` the rows of the beam matrix
  (``auvsim.data.beams``, DVL frame); ``range`` = ``dvl/beam_range`` of the beams with
  bottom lock (``pings``: measured, status OK or outlier), NaN for the others (a
  water-track beam measured the water, not the seafloor); ``beam_velocity`` =
  ``dvl/beam_velocity`` (float32 in the message); ``beam_quality`` 1 for a beam with
  bottom lock, 0 otherwise; ``beam_velocity_covar`` each measured beam's error variance
  (its white noise^2 + the slow error's), -1 where it did not measure;
  ``num_good_beams`` the beams that measured (the velocity's); ``altitude`` cos(beam
  angle) x the mean range of the beams with bottom lock (Dvl.msg's formula), NaN with
  none; ``course_gnd``, ``speed_gnd`` from the velocity;
  ``range_covar`` -1 (unknown); ``sound_speed`` NaN (auvsim models the ratio of the speed
  of sound to the assumed one, not the speed); ``dvl_type`` piston. A recorded DVL
  without beams (``dvl_beams_derived``) says ``beam_velocities_valid`` false.
- ``depth``: ``geometry_msgs/msg/PoseWithCovarianceStamped`` in ``odom_ned``, the depth
  as ``pose.position.z`` (positive down) and its variance (noise_std^2 +
  resolution^2 / 12) at covariance[14]. The sensor measures nothing else: x, y and the
  orientation (identity) have variance ``UNMEASURED`` (1e9) on the diagonal, the
  convention of a "massively inflated covariance" that makes a filter ignore a variable
  (robot_localization, "Migrating from robot_pose_ekf", section "Covariances in Source
  Messages"; PoseWithCovariance.msg defines no value for "unknown", and a 0 would say
  "known exactly"); fuse z alone (robot_localization's usual way with a depth sensor). A pose, not
  ``sensor_msgs/msg/FluidPressure``: the sensor's output in the dataset is a depth, and a
  pressure would need a water density and an atmospheric pressure the mission does not
  have, so the value would no longer be the dataset's.
- ``truth`` (simulated) or ``reference`` (recorded, a navigation solution, never called
  truth): ``nav_msgs/msg/Odometry``, ``odom_ned`` -> ``base_link_frd``, at the truth's
  (IMU's) or the reference's rate: pose = ``position_ned`` and ``quaternion`` (body ->
  NED), twist in the body frame as Odometry.msg asks: ``velocity_body`` and
  ``angular_rate``. The truth's covariances are 0; the reference's are unknown
  (covariance[0] = -1 in both), its twist is C^T ``velocity_ned`` and its angular rate
  NaN (a reference has none), both NaN without attitude.
- ``tf_static``: ``tf2_msgs/msg/TFMessage``, once, at the first stamp, offered
  transient-local (above) for late subscribers (``docs/guides/ros2.md``).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping

import numpy as np
from tqdm import tqdm

from auvsim import __version__
from auvsim.checks import did_you_mean
from auvsim.data.beams import beam_matrix
from auvsim.data.files import (
    Claim,
    check_not_source,
    check_out_file,
    commit,
    make_parent_dirs,
    writing,
)
from auvsim.errors import AuvsimError, ConfigError
from auvsim.interop import rosmsg
from auvsim.interop.cdr import FixedLayout
from auvsim.interop.mcapfile import Topic, write_mcap
from auvsim.interop.pings import ping_errors
from auvsim.physics.frames import quaternion_from_euler, rotation_matrices

TOPICS = {"imu": "/imu/data", "dvl": "/dvl/data", "depth": "/depth/pose",
          "truth": "/truth/odometry", "reference": "/reference/odometry",
          "tf_static": "/tf_static"}
TYPES = {"imu": "sensor_msgs/msg/Imu", "dvl": "marine_acoustic_msgs/msg/Dvl",
         "depth": "geometry_msgs/msg/PoseWithCovarianceStamped",
         "truth": "nav_msgs/msg/Odometry", "reference": "nav_msgs/msg/Odometry",
         "tf_static": "tf2_msgs/msg/TFMessage"}
WORLD, BODY, IMU, DVL = "odom_ned", "base_link_frd", "imu_link", "dvl_link"
# The first bytes of every MCAP file (the MCAP specification's "Magic": 0x89 M C A P 0 \r \n).
MCAP_MAGIC = b"\x89MCAP0\r\n"
COMPRESSIONS = ("zstd", "lz4", "none")
# The variance of a pose component the depth sensor does not measure (m^2, rad^2): huge,
# so that a filter that fuses the whole pose gives it no weight (module docstring).
UNMEASURED = 1e9
# /tf_static's offered QoS, as rosbag2 records a latched topic (module docstring): one
# profile, keep last 1, reliable, transient local, automatic liveliness, durations unset.
LATCHED_QOS = ("- history: 1\n  depth: 1\n  reliability: 1\n  durability: 1\n"
               "  deadline:\n    sec: 0\n    nsec: 0\n"
               "  lifespan:\n    sec: 0\n    nsec: 0\n  liveliness: 1\n"
               "  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n"
               "  avoid_ros_namespace_conventions: false\n")
# The bag's "rosbag2" Metadata record, as rosbag2's MCAP plugin writes it in Humble: its
# presence without "serialized_metadata" makes later players read the QoS's numbers.
ROSBAG2_METADATA = {"rosbag2": {"ROS_DISTRO": "humble"}}
# A ROS 2 topic name: absolute, tokens of letters, digits and underscores, not starting
# with a digit (ROS 2 design, "Topic and Service name mapping to DDS").
_TOPIC = re.compile(r"/[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")
_S = np.float64(math.sqrt(0.5))
# Quaternions (x, y, z, w) of the frames' rotations: odom -> odom_ned (ENU to NED: pi
# about (1, 1, 0)/sqrt 2) and base_link -> base_link_frd (FLU to FRD: pi about x).
_ENU_TO_NED = (float(_S), float(_S), 0.0, 0.0)
_FLU_TO_FRD = (1.0, 0.0, 0.0, 0.0)


def export_mcap(source: str | os.PathLike, out: str | os.PathLike, *,
                mission: str | None = None, topics: Mapping[str, str] | None = None,
                compression: str = "zstd", block_s: float = 60.0,
                progress: bool = False) -> dict[str, int]:
    """Write one mission of a dataset as a ROS 2 bag in MCAP (see the module docstring).

    Args:
        source: an auvsim dataset (``auvsim.data.reader.open_dataset``).
        out: the ``.mcap`` file to write (its folder made if missing); written under a
            temporary name and renamed when whole.
        mission: the mission's name; None for a dataset of one mission.
        topics: topic names by key of ``TOPICS``, replacing those defaults.
        compression: the chunks' compression, one of ``COMPRESSIONS``.
        block_s: mission time encoded and written at once, s: what bounds the memory
            (about 7 MB a minute of the ``navigator`` sensors); the file is the same
            whatever it is, but for where chunks end.
        progress: a progress bar on stderr, in mission seconds (where it is a terminal).

    Returns:
        The number of messages written, by topic name.

    Raises:
        ConfigError: an argument is wrong (an unknown topic key, a folder that does not
            exist, a mission the dataset does not have).
        DatasetError: ``source`` is not a readable auvsim dataset.
        AuvsimError: ``mcap`` or ``mcap-ros2-support`` is not installed.
    """
    names = _topics(topics)
    if compression not in COMPRESSIONS:
        raise ConfigError(f"{compression!r}: expected one of {', '.join(COMPRESSIONS)}",
                          argument="compression")
    check_not_source(out, source)  # said as such, before it is another kind's file
    out = check_out_file(out, "MCAP", ".mcap", MCAP_MAGIC)
    if not (isinstance(block_s, (int, float)) and block_s >= 1e-3 and math.isfinite(block_s)):
        raise ConfigError(f"{block_s!r}: expected at least 0.001 s", argument="block_s")
    step = round(block_s * 1e9)
    try:
        import mcap.records  # noqa: F401  (write_mcap's records)
        import mcap_ros2.writer  # noqa: F401  (encodes /tf_static: encoded_once)
    except ImportError as e:
        package = {"mcap_ros2": "mcap-ros2-support"}.get(
            (e.name or "mcap").split(".")[0], (e.name or "mcap").split(".")[0])
        raise AuvsimError(f"writing MCAP needs the packages mcap and mcap-ros2-support "
                          f"({package} is missing): pip install 'auvsim[io]'") from None
    from auvsim.data.reader import open_dataset

    with open_dataset(source) as dataset:
        chosen = dataset.mission(mission)
        attrs, streams = chosen.attrs, _streams(chosen)
    first = min((int(m.ns[0]) for m in streams.values() if len(m.ns)), default=0)
    last = max((int(m.ns[-1]) for m in streams.values() if len(m.ns)), default=0)
    tf_type = TYPES["tf_static"]
    tf = encoded_once(tf_type, _tf_static(attrs, first))
    keys = [*streams, "tf_static"]
    types = [*(m.datatype for m in streams.values()), tf_type]
    schemas = {t: ("ros2msg", rosmsg.schema_text(t).encode()) for t in types}
    topics = [Topic(names[key], datatype,
                    {"offered_qos_profiles": LATCHED_QOS if key == "tf_static" else ""})
              for key, datatype in zip(keys, types, strict=True)]

    def blocks(bar):
        yield [(len(streams), np.array([first]), np.frombuffer(tf, dtype=np.uint8)[None])]
        done = dict.fromkeys(streams, 0)
        start = first
        for end in [*range(first + step, last + 1, step), last + 1]:
            block = []
            for i, (key, m) in enumerate(streams.items()):
                hi = int(np.searchsorted(m.ns, end))
                block.append((i, m.ns[done[key]:hi], m.encode(done[key], hi)))
                done[key] = hi
            yield block
            bar.update((min(end, last) - start) / 1e9)
            start = min(end, last)

    # A claim, as a dataset's: a killed export's temporary file (a long mission's is
    # large) is swept by the next run that writes into this folder (files.sweep).
    try:
        make_parent_dirs(out.parent)  # removed on failure, if left empty
        claim = Claim(out)
    except OSError as e:
        raise ConfigError(f"{str(out)!r}: cannot write there ({e.strerror or e}); expected "
                          "a path in a writable folder", argument="out") from None
    try:
        with writing(out), open(claim.file, "wb") as f, \
                tqdm(total=round((last - first) / 1e9, 1), unit=" s", leave=False,
                     disable=None if progress else True) as bar:
            counts = write_mcap(f, profile="ros2", library=f"auvsim {__version__}",
                                schemas=schemas, topics=topics, blocks=blocks(bar),
                                compression=compression, metadata=ROSBAG2_METADATA)
        commit(claim.file, out)
    finally:
        claim.release()
    return {t.topic: n for t, n in zip(topics, counts, strict=True)}


def encoded_once(datatype: str, message: dict) -> bytes:
    """One message's CDR payload, encoded by mcap-ros2-support's public writer (for the one
    message of variable length, ``/tf_static``): written to an MCAP file in memory and read
    back with ``mcap``'s reader."""
    import io

    from mcap.reader import make_reader
    from mcap_ros2.writer import Writer

    buffer = io.BytesIO()
    writer = Writer(buffer)
    schema = writer.register_msgdef(datatype, rosmsg.schema_text(datatype))
    writer.write_message("/encode", schema, message, log_time=0)
    writer.finish()
    buffer.seek(0)
    return next(iter(make_reader(buffer).iter_messages()))[2].data


def _topics(topics: Mapping[str, str] | None) -> dict[str, str]:
    names = dict(TOPICS)
    for key, name in (topics or {}).items():
        if key not in TOPICS:
            raise ConfigError(f"{key!r}: no such topic key; expected keys among "
                              f"{', '.join(TOPICS)}{did_you_mean(key, TOPICS)}",
                              argument="topics")
        if not (isinstance(name, str) and _TOPIC.fullmatch(name)):
            raise ConfigError(f"{key} = {name!r}: expected an absolute ROS 2 topic name "
                              "(/a/b, letters, digits and _)", argument="topics")
        names[key] = name
    if len(set(names.values())) < len(names):
        raise ConfigError("two keys name the same topic; expected a topic each",
                          argument="topics")
    return names


def stamps_ns(time: np.ndarray) -> np.ndarray:
    """(N,) times, s, as whole nanoseconds (int64, rounded to the nearest).

    Raises:
        ConfigError: a time is negative (a bag's log time is unsigned) or not finite.
    """
    time = np.asarray(time, dtype=np.float64)
    if len(time) and not (np.all(np.isfinite(time)) and time.min() >= 0):
        raise ConfigError("a stream has times before the mission's start or not finite; "
                          "expected times >= 0 s", argument="source")
    return np.round(time * 1e9).astype(np.int64)


class Messages:
    """One topic's messages as columns, encoded a block of rows at a time.

    Args:
        datatype: the message type (``TYPES``).
        strings: its string fields' values (``cdr.FixedLayout``).
        ns: (N,) int64 stamps, ns.
        columns: field path -> (N, ...) array, a value per message.
        constants: field path -> the value of every message (a number or an array of
            the field's shape).
    """

    def __init__(self, datatype: str, strings: Mapping[str, str], ns: np.ndarray,
                 columns: Mapping[str, np.ndarray], constants: Mapping[str, object]) -> None:
        self.datatype, self.ns = datatype, ns
        self.columns, self.constants = dict(columns), dict(constants)
        for path, values in self.columns.items():
            if len(values) != len(ns):
                raise ValueError(f"{datatype}.{path}: expected {len(ns)} rows, got "
                                 f"{len(values)}")
        self.layout = FixedLayout(datatype, strings)

    def encode(self, lo: int, hi: int) -> np.ndarray:
        """(hi - lo, size) uint8: messages lo..hi-1 serialised."""
        m = self.layout.empty(hi - lo)
        ns = self.ns[lo:hi]
        m["header.stamp.sec"] = ns // 1_000_000_000
        m["header.stamp.nanosec"] = ns % 1_000_000_000
        for path, values in self.columns.items():
            m[path] = values[lo:hi]
        for path, value in self.constants.items():
            m[path] = value
        return self.layout.encode(m)


def _streams(mission) -> dict[str, Messages]:
    """Every topic's messages, by key of ``TOPICS``, for the groups the mission has."""
    attrs = mission.attrs
    out: dict[str, Messages] = {}
    if mission.has("imu") and "imu_rate_hz" in attrs:
        out["imu"] = _imu(mission, attrs)
    if mission.has("dvl"):
        out["dvl"] = _dvl(mission, attrs)
    if mission.has("depth"):
        out["depth"] = _depth(mission, attrs)
    if mission.origin == "recorded":
        if mission.has("reference"):
            out["reference"] = _odometry(mission.reference, reference=True)
    elif mission.has("truth"):
        out["truth"] = _odometry(mission.truth, reference=False)
    return out


def _xyz(name: str, values: np.ndarray, axes: str = "xyz") -> dict[str, np.ndarray]:
    return {f"{name}.{axis}": values[:, k] for k, axis in enumerate(axes)}


def _diagonal(variance: float, size: int = 3) -> np.ndarray:
    """A (size * size,) row-major diagonal covariance."""
    return np.diag(np.full(size, variance)).ravel()


def _imu(mission, attrs) -> Messages:
    imu = mission.imu
    rate = float(attrs["imu_rate_hz"])
    unknown = np.zeros(9)
    unknown[0] = -1.0  # no orientation (Imu.msg)
    return Messages(TYPES["imu"], {"header.frame_id": IMU}, stamps_ns(imu.time), {
        **_xyz("angular_velocity", imu.angular_rate),
        **_xyz("linear_acceleration", imu.specific_force)}, {
        "orientation_covariance": unknown,
        "angular_velocity_covariance":
            _diagonal(float(attrs["imu_gyro_noise_density"]) ** 2 * rate),
        "linear_acceleration_covariance":
            _diagonal(float(attrs["imu_accel_noise_density"]) ** 2 * rate)})


def _dvl(mission, attrs) -> Messages:
    dvl = mission.dvl
    ns = stamps_ns(dvl.time)
    n = len(ns)
    velocity = np.asarray(dvl.velocity_ls, dtype=np.float64)
    has = dvl.__contains__
    beams = dvl.beam_velocity if has("beam_velocity") else np.full((n, 4), np.nan)
    ranges = dvl.beam_range if has("beam_range") else np.full((n, 4), np.nan)
    mode = dvl.mode if has("mode") else np.where(np.isfinite(velocity[:, 0]), 0, -1)
    h = beam_matrix(math.radians(float(attrs["beam_angle_deg"])))
    errors = ping_errors(mission)
    covariance = errors.covariance.reshape(n, 9)
    covariance[~np.isfinite(covariance[:, 0])] = -np.eye(1, 9).ravel()  # unknown (Dvl.msg)
    return Messages(TYPES["dvl"], {"header.frame_id": DVL}, ns, {
        "velocity_mode": np.select([mode == 0, mode == 1], [1, 2], 0),
        **_xyz("velocity", velocity),
        "velocity_covar": covariance,
        "altitude": errors.altitude,
        "course_gnd": np.arctan2(velocity[:, 1], velocity[:, 0]),
        "speed_gnd": np.hypot(velocity[:, 0], velocity[:, 1]),
        "num_good_beams": errors.measured.sum(axis=1),
        "range": np.where(errors.locked, ranges, np.nan),
        "beam_quality": errors.locked.astype(np.float32),
        "beam_velocity": beams,
        "beam_velocity_covar": np.where(errors.measured, errors.beam_variance, -1.0)}, {
        "dvl_type": 0,  # DVL_TYPE_PISTON: a Janus array of four transducers
        "sound_speed": np.nan,
        "beam_ranges_valid": has("beam_range"),
        "beam_velocities_valid": has("beam_velocity")
                                 and not int(attrs.get("dvl_beams_derived", 0)),
        **{f"beam_unit_vec.{i}.{axis}": h[i, k] for i in range(4)
           for k, axis in enumerate("xyz")},
        "range_covar": -1.0})


def _depth(mission, attrs) -> Messages:
    depth = mission.depth
    covariance = np.diag(np.full(6, UNMEASURED)).ravel()
    covariance[14] = (float(attrs.get("depth_noise_std", 0.0)) ** 2
                      + float(attrs.get("depth_resolution", 0.0)) ** 2 / 12)
    return Messages(TYPES["depth"], {"header.frame_id": WORLD}, stamps_ns(depth.time), {
        "pose.pose.position.z": depth.depth}, {
        "pose.pose.orientation.w": 1.0, "pose.covariance": covariance})


def _odometry(group, *, reference: bool) -> Messages:
    ns = stamps_ns(group.time)
    n = len(ns)
    unknown = np.zeros(36)
    if reference:
        quaternion = group.quaternion if "quaternion" in group else np.full((n, 4), np.nan)
        linear = body_velocity(quaternion, group.velocity_ned)
        angular = np.full((n, 3), np.nan)
        unknown[0] = -1.0
    else:
        quaternion, linear, angular = (group.quaternion, group.velocity_body,
                                       group.angular_rate)
    return Messages(TYPES["truth"], {"header.frame_id": WORLD, "child_frame_id": BODY}, ns, {
        **_xyz("pose.pose.position", group.position_ned),
        **_xyz("pose.pose.orientation", quaternion, "wxyz"),
        **_xyz("twist.twist.linear", linear),
        **_xyz("twist.twist.angular", angular)}, {
        "pose.covariance": unknown, "twist.covariance": unknown})


def body_velocity(quaternion: np.ndarray, velocity_ned: np.ndarray) -> np.ndarray:
    """(N, 3) body-frame velocity C^T v of (N, 4) quaternions [w, x, y, z] (body -> NED)
    and (N, 3) NED velocities, m/s (NaN where the quaternion is)."""
    return np.einsum("nji,nj->ni", rotation_matrices(quaternion), velocity_ned)


def _transform(parent: str, child: str, ns: int, translation, rotation_xyzw) -> dict:
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return {"header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": parent},
            "child_frame_id": child,
            "transform": {"translation": dict(zip("xyz", map(float, translation), strict=True)),
                          "rotation": dict(zip("xyzw", map(float, rotation_xyzw),
                                                strict=True))}}


def _tf_static(attrs: Mapping, ns: int) -> dict:
    """The static transforms: the ROS frames to auvsim's and the sensors' mountings."""
    transforms = [_transform("odom", WORLD, ns, (0, 0, 0), _ENU_TO_NED),
                  _transform("base_link", BODY, ns, (0, 0, 0), _FLU_TO_FRD)]
    if "imu_position_body" in attrs:
        transforms.append(_transform(BODY, IMU, ns, attrs["imu_position_body"], (0, 0, 0, 1)))
    if "dvl_position_body" in attrs:
        rpy = np.radians(np.asarray(attrs.get("dvl_mounting_rpy_deg", (0, 0, 0)), float))
        w, x, y, z = quaternion_from_euler(*rpy)
        transforms.append(_transform(BODY, DVL, ns, attrs["dvl_position_body"], (x, y, z, w)))
    return {"transforms": transforms}
