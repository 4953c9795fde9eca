"""The per-mission random streams, declared once.

A simulated mission's seed spawns one child generator per stream, by position
(``stream_names``): the streams of ``STREAMS``, then those that sensor plugins added since
declare. Children of a ``SeedSequence`` depend only on their position, so a stream added at
the end leaves every earlier one, and every dataset made before it, unchanged: append,
never reorder. Each consumer draws from its own streams only, so one setting never shifts
another's numbers.

An imported mission (a recorded DVL stream, ``auvsim import-velocity``) has no terrain,
vehicle or IMU: its DVL draws its parameters and then its noise from one generator,
``default_rng(seed)`` (``imported_streams``), as every import made so far did.
"""

from __future__ import annotations

import numpy as np

from auvsim.sensors import registry

# The layout up to schema version 6, in spawn order. Closed: a sensor added later names
# its streams in its plugin (``Sensor.streams``), and they follow these.
STREAMS = (
    "terrain",  # procedural seafloor (auvsim.world.seafloor)
    "dvl_parameters",  # per-mission DVL scale factors and biases
    "dvl_noise",  # DVL beam noise, one draw per beam and ping
    "imu_biases",  # IMU turn-on biases
    "imu_noise",  # IMU white noise and Gauss-Markov drive (four children)
    "maneuver",  # what a manoeuvre draws (random waypoints)
    "depth_parameters",  # the depth sensor's per-mission offset
    "depth_noise",  # the depth sensor's white noise
    "imu_calibration",  # IMU scale factors, misalignment and g-sensitivity (schema v4)
    "dvl_calibration",  # the DVL's realised sound-speed ratio and mounting misalignment
    "dvl_faults",  # the DVL's lost bottom lock, outliers and extra noise, per beam and ping
    "water",  # the current: per-mission speed and direction, Gauss-Markov paths, modes
    "disturbance",  # turbulent wrench and actuator jitter (Gauss-Markov drives)
)


def stream_names() -> tuple[str, ...]:
    """Every stream of a simulated mission, in spawn order: ``STREAMS``, then the streams of
    each sensor plugin that are not among them, the plugins in the order of the schema
    version that added them (``Sensor.since_version``), then of their names. A new sensor
    comes with a new schema version, so its streams follow every earlier one."""
    names = list(STREAMS)
    for sensor in sorted(registry().values(), key=lambda s: (s.since_version, s.name)):
        names += [name for name in sensor.streams if name not in names]
    return tuple(names)


def mission_streams(seed: int) -> dict[str, np.random.Generator]:
    """A simulated mission's independent streams, by name (``stream_names``)."""
    names = stream_names()
    return dict(zip(names, np.random.default_rng(seed).spawn(len(names)), strict=True))


def imported_streams(seed: int) -> dict[str, np.random.Generator]:
    """An imported mission's DVL streams: one generator, parameters drawn first."""
    rng = np.random.default_rng(seed)
    return {"dvl_parameters": rng, "dvl_noise": rng}
