"""The configuration: a few frozen dataclasses, validated on construction.

The resolved config is written into every dataset (``config_json``) and reads back to an
equal object (``Config.from_json(config.to_json()) == config``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, field

from .errors import ConfigError

SCENARIOS = ("straight",)


def _check(ok: bool, name: str, expected: str, got: object) -> None:
    if not ok:
        raise ConfigError(f"{name}: expected {expected}, got {got!r}")


def _finite(name: str, value: float) -> None:
    _check(isinstance(value, (int, float)) and math.isfinite(value), name, "a finite number",
           value)


@dataclass(frozen=True)
class VehicleConfig:
    """Which vehicle, and the water around it.

    Attributes:
        model: ``auv`` (A18-D class), ``remus100`` or a path to an MJCF model.
        net_buoyancy: buoyancy minus weight, N (positive floats up).
        current_ned: constant ocean current, m/s, NED.
    """

    model: str = "auv"
    net_buoyancy: float = 0.0
    current_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        _check(isinstance(self.model, str) and self.model != "", "vehicle.model",
               "a vehicle name or model path", self.model)
        _finite("vehicle.net_buoyancy", self.net_buoyancy)
        object.__setattr__(self, "current_ned", tuple(float(c) for c in self.current_ned))
        _check(len(self.current_ned) == 3, "vehicle.current_ned", "3 numbers (m/s, NED)",
               self.current_ned)
        for c in self.current_ned:
            _finite("vehicle.current_ned", c)


@dataclass(frozen=True)
class ScenarioConfig:
    """What the vehicle is asked to do.

    Attributes:
        name: one of ``SCENARIOS``.
        speed: surge speed to hold, m/s.
        heading_deg: heading to hold, degrees from north.
        depth: depth to hold, m.
        duration: mission length, s.
        start_speed: initial surge speed, m/s; ``None`` starts at ``speed`` (on the set
            point, so the data is steady from the first sample).
    """

    name: str = "straight"
    speed: float = 2.0
    heading_deg: float = 0.0
    depth: float = 20.0
    duration: float = 600.0
    start_speed: float | None = None

    def __post_init__(self) -> None:
        _check(self.name in SCENARIOS, "scenario", f"one of {', '.join(SCENARIOS)}", self.name)
        for name in ("speed", "heading_deg", "depth", "duration"):
            _finite(f"scenario.{name}", getattr(self, name))
        _check(self.duration > 0, "duration", "a positive number of seconds", self.duration)
        _check(self.speed > 0, "speed", "a positive speed in m/s", self.speed)
        _check(self.depth > 0, "depth", "a positive depth in m", self.depth)
        if self.start_speed is not None:
            _finite("scenario.start_speed", self.start_speed)
            _check(self.start_speed >= 0, "start_speed", "a speed >= 0 m/s", self.start_speed)


@dataclass(frozen=True)
class MissionConfig:
    """One mission of a dataset: a scenario and the seed of its random streams."""

    name: str = "mission_000"
    scenario: ScenarioConfig = field(default_factory=ScenarioConfig)
    seed: int = 0

    def __post_init__(self) -> None:
        _check(isinstance(self.name, str) and self.name.isidentifier(), "mission.name",
               "a name of letters, digits and underscores", self.name)
        _check(isinstance(self.seed, int) and self.seed >= 0, "seed", "an integer >= 0",
               self.seed)


@dataclass(frozen=True)
class Config:
    """Everything that determines a dataset.

    Attributes:
        vehicle: the vehicle and the water.
        missions: the missions, each simulated independently.
        imu_rate_hz: rate of the truth and IMU samples; the physics rate must be a whole
            multiple of it.
        seafloor_depth: depth of the (flat) seafloor, m.
        compression: HDF5 compression, ``lzf`` (fast) or ``gzip`` (read by every HDF5 tool).
    """

    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    missions: tuple[MissionConfig, ...] = (MissionConfig(),)
    imu_rate_hz: float = 100.0
    seafloor_depth: float = 100.0
    compression: str = "lzf"

    def __post_init__(self) -> None:
        object.__setattr__(self, "missions", tuple(self.missions))
        _check(len(self.missions) > 0, "missions", "at least one mission", self.missions)
        names = [m.name for m in self.missions]
        _check(len(set(names)) == len(names), "missions", "distinct mission names", names)
        _finite("imu_rate_hz", self.imu_rate_hz)
        _check(self.imu_rate_hz > 0, "imu_rate_hz", "a positive rate in Hz", self.imu_rate_hz)
        _finite("seafloor_depth", self.seafloor_depth)
        _check(self.compression in ("lzf", "gzip"), "compression", "lzf or gzip",
               self.compression)
        for m in self.missions:
            _check(m.scenario.depth < self.seafloor_depth, "depth",
                   f"a depth above the seafloor at {self.seafloor_depth:g} m", m.scenario.depth)

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict) -> Config:
        try:
            missions = tuple(
                MissionConfig(**{**m, "scenario": ScenarioConfig(**m["scenario"])})
                for m in d.get("missions", ())
            )
            rest = {k: v for k, v in d.items() if k not in ("vehicle", "missions")}
            return cls(vehicle=VehicleConfig(**d.get("vehicle", {})), missions=missions, **rest)
        except TypeError as e:  # unknown or missing keys
            raise ConfigError(f"config: {e}") from None

    @classmethod
    def from_json(cls, text: str) -> Config:
        return cls.from_dict(json.loads(text))
