"""The ROS 2 message definitions a bag of auvsim embeds, and their text as MCAP stores it.

Each definition is the field list (and constants) of the upstream ``.msg`` file, comments
left out, with the types as that file names them:

- ``builtin_interfaces/msg/Time.msg``: ros2/rcl_interfaces, ``builtin_interfaces/msg``.
- ``std_msgs/msg/Header.msg``, ``geometry_msgs/msg/{Vector3,Point,Quaternion,Pose,
  PoseWithCovariance,PoseWithCovarianceStamped,Twist,TwistWithCovariance,Transform,
  TransformStamped}.msg``, ``sensor_msgs/msg/Imu.msg``, ``nav_msgs/msg/Odometry.msg``:
  ros2/common_interfaces (Humble), each package's ``msg`` folder.
- ``tf2_msgs/msg/TFMessage.msg``: ros2/geometry2 (Humble), ``tf2_msgs/msg``.
- ``marine_acoustic_msgs/msg/Dvl.msg``: apl-ocean-engineering/marine_msgs,
  ``marine_acoustic_msgs/msg/Dvl.msg`` (from WHOI's ds_sensor_msgs/Dvl.msg).

A schema of encoding ``ros2msg`` holds the message's own definition, then each type it
depends on, once, after a line of 80 ``=`` and a line ``MSG: pkg/Type`` (MCAP
specification, "Well-known schema encodings", ``ros2msg``; what rosbag2's MCAP storage
writes), so a reader needs no ROS installation to decode the bag.
"""

from __future__ import annotations

import re

PRIMITIVES = {"bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32",
              "int64", "uint64", "float32", "float64", "string", "wstring"}

# Upstream names without "msg/" (as the .msg files write a field's type) -> field lines.
DEFINITIONS = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance",
    "geometry_msgs/PoseWithCovarianceStamped": "std_msgs/Header header\n"
                                               "PoseWithCovariance pose",
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\n"
                                      "Transform transform",
    "sensor_msgs/Imu": "std_msgs/Header header\n"
                       "geometry_msgs/Quaternion orientation\n"
                       "float64[9] orientation_covariance\n"
                       "geometry_msgs/Vector3 angular_velocity\n"
                       "float64[9] angular_velocity_covariance\n"
                       "geometry_msgs/Vector3 linear_acceleration\n"
                       "float64[9] linear_acceleration_covariance",
    "nav_msgs/Odometry": "std_msgs/Header header\nstring child_frame_id\n"
                         "geometry_msgs/PoseWithCovariance pose\n"
                         "geometry_msgs/TwistWithCovariance twist",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "marine_acoustic_msgs/Dvl": "uint8 DVL_MODE_BOTTOM=1\nuint8 DVL_MODE_WATER=2\n"
                                "uint8 DVL_TYPE_PISTON=0\nuint8 DVL_TYPE_PHASED_ARRAY=1\n"
                                "std_msgs/Header header\n"
                                "uint8 velocity_mode\n"
                                "uint8 dvl_type\n"
                                "geometry_msgs/Vector3 velocity\n"
                                "float64[9] velocity_covar\n"
                                "float64 altitude\n"
                                "float64 course_gnd\n"
                                "float64 speed_gnd\n"
                                "uint8 num_good_beams\n"
                                "float32 sound_speed\n"
                                "bool beam_ranges_valid\n"
                                "bool beam_velocities_valid\n"
                                "geometry_msgs/Vector3[4] beam_unit_vec\n"
                                "float64[4] range\n"
                                "float32[4] range_covar\n"
                                "float32[4] beam_quality\n"
                                "float32[4] beam_velocity\n"
                                "float32[4] beam_velocity_covar",
}
_FIELD = re.compile(r"(?P<type>[\w/]+)(?P<array>\[\d*\])?\s+(?P<name>\w+)(?:\s+(?P<default>\S+))?$")


def short(datatype: str) -> str:
    """``pkg/Type`` of ``pkg/msg/Type`` (either given)."""
    return datatype.replace("/msg/", "/")


def full(datatype: str) -> str:
    """``pkg/msg/Type``, the name a bag's schema and a topic's type carry."""
    package, _, name = short(datatype).partition("/")
    return f"{package}/msg/{name}"


def fields(datatype: str) -> list[tuple[str, str, str]]:
    """The fields of a message (its constants left out): (type as ``pkg/Type`` or a
    primitive, array suffix (``""``, ``"[4]"`` or ``"[]"``), name), in order."""
    package = short(datatype).split("/")[0]
    out = []
    for line in DEFINITIONS[short(datatype)].splitlines():
        if "=" in line:
            continue  # a constant
        m = _FIELD.match(line)
        kind = m["type"]
        if kind not in PRIMITIVES and "/" not in kind:
            kind = f"{package}/{kind}"  # a type of the same package
        if kind == "Header":
            kind = "std_msgs/Header"
        out.append((kind, m["array"] or "", m["name"]))
    return out


def dependencies(datatype: str) -> list[str]:
    """Every message type ``datatype`` uses, each once, depth first, in field order."""
    seen: list[str] = []

    def walk(name: str) -> None:
        for kind, _, _ in fields(name):
            if kind not in PRIMITIVES and kind not in seen:
                seen.append(kind)
                walk(kind)

    walk(datatype)
    return seen


def schema_text(datatype: str) -> str:
    """The ``ros2msg`` schema of ``datatype``: its definition and its dependencies'."""
    parts = [DEFINITIONS[short(datatype)]]
    for dep in dependencies(datatype):
        parts.append(f"{'=' * 80}\nMSG: {dep}\n{DEFINITIONS[dep]}")
    return "\n".join(parts) + "\n"
