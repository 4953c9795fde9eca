"""Sensors as plugins: the true signal of a mission in, measurements out.

A sensor is a class with a small interface (``Sensor``): its name, the config section it
reads, its rate, the dataset fields and mission attributes it writes (its part of the
schema), the random streams it draws from, and ``measure``, a function of one block of
truth and the sensor's noise stream. Every module of this package that defines ``SENSOR``
is a plugin; ``registry`` finds them (``register`` adds one defined elsewhere), so a new
sensor is one new file here plus its config section (a dataclass and a field of
``auvsim.config.Config``) and its tests. A plugin owns, beside its measurements:

* its checks against the rest of the config (``Sensor.check``: by default, that its rate
  is a whole divisor of the IMU's), which ``Config`` runs for every plugin;
* what ``auvsim inspect`` says of it (``Sensor.describe``, lines from a mission's file).

``auvsim.runs.mission`` builds each plugin per mission and measures every block with it;
``auvsim.data.reader`` reads the plugins' fields to check a file.

Block alignment: a sensor sampling every ``every`` IMU samples measures at the global IMU
sample indices ``0, every, 2 every, ...``, wherever a block starts (``sample_rows``), so
blocks of any length give the same samples.
"""

from __future__ import annotations

import importlib
import pkgutil
import threading
from dataclasses import dataclass
from typing import Any, ClassVar, NamedTuple

import numpy as np

import auvsim
from auvsim.errors import ConfigError

# ``auvsim.config`` runs every plugin's checks, so this module names its ``Config`` in
# annotations only (``auvsim.config.Config``, never evaluated at import): no import circle.


@dataclass(frozen=True)
class Field:
    """One dataset of the schema, per mission.

    Attributes:
        path: ``group/name`` inside the mission.
        shape: the shape of one row (``()`` for a column, ``(3,)`` for a vector).
        kind: numpy dtype kind: ``f`` float64, ``b`` bool, ``i`` int64.
        clock: whose rows it has: ``imu`` (the truth rate), or a sensor's name.
        unit: SI unit, or ``-``.
        doc: what it holds.
        imported: also written for a mission imported from a recorded stream.
        index_of: the values are row indices into this clock's fields.
        since: the first schema version that holds it (``auvsim.data.schema.FORMAT_VERSION``).
    """

    path: str
    shape: tuple[int, ...]
    kind: str
    clock: str
    unit: str
    doc: str
    imported: bool = False
    index_of: str | None = None
    since: int = 1


class Attr(NamedTuple):
    """One mission attribute of the schema: ``shape`` ``()`` for a number, ``(n,)`` for a
    vector of n numbers, ``None`` for a string; ``low`` the least value it may take (and
    ``strict`` whether it must exceed it), ``whole`` for a whole number; ``since`` the
    first schema version that holds it; ``optional`` for one only some missions hold
    (checked where present)."""

    name: str
    shape: tuple[int, ...] | None
    doc: str
    imported: bool = False
    low: float | None = None
    strict: bool = False
    whole: bool = False
    since: int = 1
    optional: bool = False


class Platform(NamedTuple):
    """What a sensor may know of its mission at the start (beside the config): the vehicle
    (sensor sites, model), the seafloor, a ``MjData`` for ray casts and the water.

    ``water.current_ned(time (M,) s, position_ned (M, 3) m) -> (M, 3) m/s`` is the current
    (NED) anywhere at any time of the mission, exactly as the vehicle's physics sees it
    (``auvsim.physics.water.Water``; the constant ``vehicle.current_ned`` included), e.g. at a DVL's
    water-track layer below the vehicle. None only for a platform built without one.
    """

    vehicle: Any  # auvsim.physics.vehicle.Vehicle
    seafloor: Any  # auvsim.world.seafloor.Seafloor
    ray_data: Any  # mujoco.MjData of the same model, for ray casts only
    water: Any = None  # auvsim.physics.water.Water


class Truth(NamedTuple):
    """One block of the true state at the IMU rate, NED/FRD (package conventions).

    Attributes:
        first: global index of the block's first IMU sample in its mission.
        time: (N,) s.
        position_ned, velocity_ned, velocity_body: (N, 3) m, m/s, m/s.
        quaternion: (N, 4) body -> NED.
        angular_rate: (N, 3) rad/s, body.
        specific_force: (N, 3) m/s^2, body, at the IMU site.
        current_ned: (N, 3) m/s, NED, the current at the body origin (None: not given,
            as by a test's stub).
        velocity_water_body: (N, 3) m/s, body, the body origin's velocity through the
            water, ``velocity_body - R^T current_ned`` (None: not given).
    """

    first: int
    time: np.ndarray
    position_ned: np.ndarray
    velocity_ned: np.ndarray
    velocity_body: np.ndarray
    quaternion: np.ndarray
    angular_rate: np.ndarray
    specific_force: np.ndarray
    current_ned: np.ndarray | None = None
    velocity_water_body: np.ndarray | None = None


class Sensor:
    """Base of the sensor plugins.

    A subclass sets the class attributes and implements ``__init__`` (draw the mission's
    parameters from its ``parameters`` stream), ``attrs`` and ``measure``.

    Args:
        config: the whole config; the sensor reads its ``section``.
        platform: the mission's vehicle, seafloor and rates.
        parameters: the sensor's parameter stream (per-mission draws).
        *more: the streams it declares after its noise stream, in order (per-mission
            draws added later, which leave the earlier streams' draws as they were).
    """

    name: ClassVar[str]  # its group in the file
    section: ClassVar[str]  # its config section
    # (parameters, noise, *more) stream names; more: further parameter streams, passed to
    # __init__ after ``parameters`` in order. Names that ``auvsim.data.streams.STREAMS``
    # does not hold are new streams, spawned after every earlier one (``stream_names``).
    streams: ClassVar[tuple[str, ...]]
    fields: ClassVar[tuple[Field, ...]]
    attributes: ClassVar[tuple[Attr, ...]]
    links: ClassVar[dict[str, str]] = {}  # field -> truth field it is a hard link to
    since_version: ClassVar[int] = 1  # first schema version that holds it

    def __init__(self, config: auvsim.config.Config, platform: Platform,
                 parameters: np.random.Generator,
                 *more: np.random.Generator) -> None:
        raise NotImplementedError

    @classmethod
    def rate_hz(cls, config: auvsim.config.Config) -> float:
        return float(getattr(config, cls.section).rate_hz)

    @classmethod
    def every(cls, config: auvsim.config.Config) -> int:
        """IMU samples per sample of this sensor."""
        return round(config.imu.rate_hz / cls.rate_hz(config))

    @classmethod
    def check(cls, config: auvsim.config.Config) -> None:
        """Refuse settings of this sensor that are wrong only beside the rest of the config
        (its own section checks its ranges alone): by default its rate, which must be a
        whole divisor of the IMU's, so its samples fall on IMU samples. A plugin with more
        to check extends this.

        Raises:
            ConfigError: naming the setting, what was expected and what was given.
        """
        rate = cls.rate_hz(config)
        ratio = config.imu.rate_hz / rate
        if not (abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1):
            raise ConfigError(f"{cls.section}.rate_hz: expected a whole divisor of the "
                              f"{config.imu.rate_hz:g} Hz IMU rate, got {rate!r}")

    @classmethod
    def describe(cls, mission: Any) -> list[str]:
        """What ``auvsim inspect`` prints for this sensor in a mission that holds its group
        (an ``auvsim.data.reader.Mission``): lines indented four spaces, its rate, its
        realised parameters, how much of its data is usable."""
        return [f"    {cls.name} {mission.attrs.get(f'{cls.section}_rate_hz', '?')} Hz "
                f"({getattr(mission, cls.name).rows} samples)"]

    def rows(self, n_imu: int) -> dict[str, int]:
        """Rows of each of its fields' clocks in a mission of ``n_imu`` IMU samples."""
        raise NotImplementedError

    def attrs(self) -> dict[str, object]:
        """Its mission attributes: settings and the realised parameters."""
        raise NotImplementedError

    def measure(self, truth: Truth, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Its fields (by path) for one block of truth, drawing noise from ``rng``."""
        raise NotImplementedError


def sample_rows(first: int, n: int, every: int) -> slice:
    """The rows of a block (first global IMU index ``first``, ``n`` rows) that fall on
    global indices that are whole multiples of ``every``."""
    return slice(-first % every, n, every)


def samples_in(n_imu: int, every: int) -> int:
    """Samples of a sensor sampling every ``every`` of ``n_imu`` IMU samples, from 0."""
    return -(-n_imu // every)


def shown(values: Any, precision: int = 6) -> str:
    """Numbers as ``auvsim inspect`` prints them: numpy's layout, no ``-0.`` (adding 0.0
    turns a negative zero into zero and leaves every other number as it is)."""
    return np.array2string(np.asarray(values, dtype=float) + 0.0, precision=precision,
                           separator=", ")


_found: dict[str, type[Sensor]] = {}  # the package's plugins, once imported
_finding = threading.Lock()
_added: dict[str, type[Sensor]] = {}  # plugins registered from elsewhere


def registry() -> dict[str, type[Sensor]]:
    """Every sensor plugin: each module of this package defining ``SENSOR``, and those
    given to ``register``, by name, in name order: the order ``auvsim.runs.mission``
    measures them in."""
    if not _found:
        with _finding:  # threads of a worker ask at once: none may see a partial list
            found = {}
            for info in pkgutil.iter_modules(__path__):
                module = importlib.import_module(f"{__name__}.{info.name}")
                sensor = getattr(module, "SENSOR", None)
                if sensor is not None:
                    found[sensor.name] = sensor
            _found.update(found)
    return dict(sorted({**_found, **_added}.items()))


def register(sensor: type[Sensor]) -> type[Sensor]:
    """Add a sensor plugin defined outside this package (a class decorator); its name
    must be new. Its ``section`` must be a section of ``auvsim.config.Config``, or it
    overrides ``rate_hz``."""
    if sensor.name in registry():
        raise ValueError(f"sensor {sensor.name!r}: a plugin of that name is registered "
                         "already; expected a new name")
    _added[sensor.name] = sensor
    return sensor


def unregister(name: str) -> None:
    """Remove a plugin that ``register`` added."""
    _added.pop(name, None)
