"""Shared test setup: small configs on a flat floor, and datasets generated from them."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from auvsim.config import (
    Config,
    DvlConfig,
    ImuConfig,
    MissionConfig,
    ScenarioConfig,
    SeafloorConfig,
)
from auvsim.runs.generate import generate


def mission(name: str = "mission_000", seed: int = 0, **scenario) -> MissionConfig:
    """A mission flying ``ScenarioConfig(**scenario)`` (straight by default)."""
    return MissionConfig(name=name, seed=seed, scenario=ScenarioConfig(**scenario))


def flat(*missions: MissionConfig, dvl: DvlConfig | None = None, imu: ImuConfig | None = None,
         floor: float = 60.0, **changes) -> Config:
    """A config over a flat floor ``floor`` m deep, with ideal sensors unless given."""
    return Config(missions=missions or (mission(),),
                  seafloor=SeafloorConfig(kind="flat", depth=floor),
                  dvl=DvlConfig() if dvl is None else dvl,
                  imu=ImuConfig() if imu is None else imu, **changes)


def zigzag(noise_std: float, duration: float) -> Config:
    """A zigzag of ``duration`` s (mission ``zz``, seed 3) over the flat floor with a
    navigation-grade IMU and beams of white noise ``noise_std`` at 1 Hz: the INS/DVL
    filters' test mission."""
    from auvsim.sensors.imu import IMU_GRADES

    return flat(MissionConfig(name="zz", seed=3, scenario=ScenarioConfig(
                    name="zigzag", duration=duration)),
                imu=IMU_GRADES["navigation"], dvl=DvlConfig(noise_std=noise_std))


def write(config: Config, path: Path) -> Path:
    """``config`` generated into ``path`` in this process, quietly."""
    generate(config, path, workers=1, progress=False)
    return path


@pytest.fixture(scope="module")
def dataset_of(tmp_path_factory):
    """A factory: ``dataset_of(config, name)`` generates ``config`` once per module into a
    file named ``name.h5`` and returns its path."""
    made: dict[str, Path] = {}

    def make(config: Config, name: str) -> Path:
        if name not in made:
            made[name] = write(config, tmp_path_factory.mktemp(name) / f"{name}.h5")
        return made[name]

    return make


# Mission a reaches the seafloor within seconds; mission b alone would take minutes: a run
# that reports a's error quickly has stopped b early.
FAILING_TOML = """
[[missions]]
name = "a"
[missions.scenario]
depth = 59.8
duration = 600
[[missions]]
name = "b"
[missions.scenario]
duration = 200000
[seafloor]
kind = "procedural"
depth = 60
roughness = 3
"""


class Fields(SimpleNamespace):
    """A stand-in for a mission or one of its groups (``auvsim.data.reader.Group``): its
    fields as attributes, and ``"field" in group``."""

    def __contains__(self, field: str) -> bool:
        return field in vars(self)


class CountingBar:
    """Stands in for tqdm (``monkeypatch.setattr("auvsim.runs.generate.tqdm", CountingBar)``):
    ``CountingBar.updates`` collects what the run's progress added up to."""

    updates: list[int] = []

    def __init__(self, *args, **kwargs):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def update(self, n):
        CountingBar.updates.append(n)


def pytest_collection_modifyitems(config, items) -> None:
    """The slow end-to-end tests first, so that the two workers of ``make test`` finish
    together (the longest jobs first) rather than one alone on a long test at the end."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@pytest.fixture(autouse=True)
def _default_interrupts():
    """Every test starts with Python's own SIGINT and SIGTERM handling, as a command
    started from a terminal has. A test run started in the background of a shell without
    job control inherits SIGINT ignored (a POSIX shell ignores it for asynchronous
    commands), Python then leaves it ignored, and so do the processes a test starts: the
    Ctrl-C tests would test nothing."""
    import signal

    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    yield
