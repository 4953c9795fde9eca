"""The sensor plugins, the named random streams and the depth sensor."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import flat, mission

from auvsim.config import Config, DepthConfig
from auvsim.data.schema import schema
from auvsim.data.streams import STREAMS, imported_streams, mission_streams, stream_names
from auvsim.errors import ConfigError
from auvsim.runs.mission import MissionRun
from auvsim.sensors import (
    Attr,
    Field,
    Sensor,
    Truth,
    register,
    registry,
    sample_rows,
    samples_in,
    unregister,
)


def test_the_registry_finds_every_plugin_with_its_part_of_the_schema():
    sensors = registry()
    assert list(sensors) == ["depth", "dvl", "imu"]
    for name, sensor in sensors.items():
        assert issubclass(sensor, Sensor) and sensor.name == name
        assert sensor.section in {f.name for f in Config.__dataclass_fields__.values()}
        assert set(sensor.streams) <= set(stream_names())
        assert all(f.path.split("/")[0] in (name, "imu") for f in sensor.fields)
    # The file's schema is the core plus every plugin's fields and attributes.
    fields, attrs = schema("simulated")
    paths = {f.path for f in fields}
    assert {"depth/depth", "dvl/beam_velocity", "imu/specific_force", "truth/time"} <= paths
    assert {"depth_bias", "dvl_scale_factor", "imu_gyro_turn_on_bias"} <= {a.name for a in attrs}
    # Version-2 files have no depth group and still read.
    assert "depth/depth" not in {f.path for f in schema("simulated", 2)[0]}


def test_streams_keep_their_positions_as_the_layout_grows():
    """Streams are spawned by position: the first six are those of every dataset made
    before the depth sensor's were appended."""
    streams = mission_streams(42)
    before = np.random.default_rng(42).spawn(6)
    for name, old in zip(STREAMS[:6], before, strict=True):
        np.testing.assert_array_equal(streams[name].standard_normal(5), old.standard_normal(5))
    assert len(set(STREAMS)) == len(STREAMS)
    imported = imported_streams(3)
    assert imported["dvl_parameters"] is imported["dvl_noise"]


def test_samples_fall_on_global_multiples_wherever_a_block_starts():
    rows = [np.arange(start, start + n)[sample_rows(start, n, 7)]
            for start, n in ((0, 20), (20, 5), (25, 30))]
    np.testing.assert_array_equal(np.concatenate(rows), np.arange(0, 55, 7))


def depth_run(duration: float, **depth) -> tuple[MissionRun, dict]:
    config = flat(mission(duration=duration, depth=20.0), depth=DepthConfig(**depth))
    run = MissionRun(config, config.missions[0])
    blocks = list(run.blocks())
    return run, {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


def test_depth_sensor_noise_bias_and_resolution_have_their_statistics():
    run, data = depth_run(600.0, rate_hz=20.0, noise_std=0.05, bias_std=0.3)
    t, measured = data["depth/time"], data["depth/depth"]
    np.testing.assert_allclose(np.diff(t), 0.05, atol=1e-12)  # 20 Hz from t = 0
    true = data["truth/position_ned"][::5, 2]  # every 5th 100 Hz sample
    error = measured - true
    bias = run.attrs["depth_bias"]
    assert bias != 0 and abs(bias) < 4 * 0.3
    n = len(error)
    assert abs(error.mean() - bias) < 4 * 0.05 / np.sqrt(n)
    assert error.std() == pytest.approx(0.05, rel=4 / np.sqrt(2 * n))
    # Quantised output is a whole number of steps, within half a step of the unrounded.
    _, q = depth_run(60.0, rate_hz=10.0, noise_std=0.0, resolution=0.01)
    steps = q["depth/depth"] / 0.01
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert np.abs(q["depth/depth"] - q["truth/position_ned"][::10, 2]).max() <= 0.005 + 1e-12


def test_an_ideal_depth_sensor_reads_the_truth():
    _, data = depth_run(30.0)
    np.testing.assert_array_equal(data["depth/depth"], data["truth/position_ned"][::10, 2])


def test_depth_noise_drawn_ahead_is_the_noise_drawn_block_by_block():
    """The sensor draws its noise ahead, a chunk at a time: uneven blocks, across chunk
    edges, read the numbers one draw per block gives, bit for bit; a new generator starts
    afresh."""
    config = flat(mission(duration=10.0, depth=20.0),
                  depth=DepthConfig(rate_hz=10.0, noise_std=0.05, bias_std=0.3))
    sensor = registry()["depth"](config, None, np.random.default_rng(1))
    every = sensor.every_imu
    true = np.random.default_rng(2).uniform(0.0, 100.0, 30_000)
    rng, reference = np.random.default_rng(5), np.random.default_rng(5)
    edges = [0, 1, 1, 7, 9000, 9001, 21_000, 30_000]  # an empty block; 3,000 samples
    for start, stop in zip(edges[:-1], edges[1:], strict=True):
        n = stop - start
        position = np.zeros((n, 3))
        position[:, 2] = true[start:stop]
        truth = Truth(start, np.arange(start, stop) * 0.01, position, *[None] * 7)
        rows = sample_rows(start, n, every)
        expected = position[rows, 2] + sensor.bias + 0.05 * reference.standard_normal(
            len(position[rows]))
        assert sensor.measure(truth, rng)["depth/depth"].tobytes() == expected.tobytes()
    fresh = np.random.default_rng(9)
    truth = Truth(0, np.zeros(1), np.zeros((1, 3)), *[None] * 7)
    expected = sensor.bias + 0.05 * np.random.default_rng(9).standard_normal(1)
    assert sensor.measure(truth, fresh)["depth/depth"].tobytes() == (0.0 + expected).tobytes()


def test_the_depth_sensor_does_not_change_the_other_sensors():
    """Its own streams: the DVL and IMU read the same with any depth-sensor setting."""
    _, a = depth_run(30.0)
    _, b = depth_run(30.0, noise_std=1.0, bias_std=1.0, rate_hz=50.0)
    for key in ("dvl/beam_velocity", "imu/specific_force", "truth/position_ned"):
        np.testing.assert_array_equal(a[key], b[key])


# -- a new sensor is one plugin: its schema, checks and inspect lines ----------------------

class Thermometer(Sensor):
    """A toy sensor defined here, as a user's would be: the water temperature from the
    depth, a linear thermocline, at ``RATE`` Hz (a real one would read its config
    section; this toy has none, so it states its rate itself)."""

    RATE = 10.0
    name = "thermometer"
    section = "thermometer"
    streams = ("thermometer_parameters", "thermometer_noise")  # its own, new ones
    fields = (Field("thermometer/time", (), "f", "thermometer", "s", "sample times"),
              Field("thermometer/temperature", (), "f", "thermometer", "degC", "water"))
    attributes = (Attr("thermometer_rate_hz", (), "Hz", low=0, strict=True, since=6),)
    since_version = 6

    def __init__(self, config, platform, parameters):
        self.every_imu = self.every(config)

    @classmethod
    def rate_hz(cls, config):
        return cls.RATE

    @classmethod
    def describe(cls, mission):
        t = mission.thermometer.temperature
        return [f"    thermometer {mission.attrs['thermometer_rate_hz']:g} Hz ({len(t)} "
                f"samples): {t.min():.2f} to {t.max():.2f} degC"]

    def rows(self, n_imu):
        return {"thermometer": samples_in(n_imu, self.every_imu)}

    def attrs(self):
        return {"thermometer_rate_hz": self.RATE}

    def measure(self, truth, rng):
        rows = sample_rows(truth.first, len(truth.time), self.every_imu)
        return {"thermometer/time": truth.time[rows],
                "thermometer/temperature": 15.0 - 0.1 * truth.position_ned[rows, 2]}


@pytest.fixture
def thermometer():
    register(Thermometer)
    yield Thermometer
    unregister(Thermometer.name)
    Thermometer.RATE = 10.0


def test_a_new_sensors_streams_follow_every_earlier_one(thermometer):
    """Declared in its plugin alone, they are spawned after the closed layout, whose
    generators draw what they drew before."""
    # Ordered by the schema version of the plugin that declares them, then by name: the
    # DVL's slow error (a v1 plugin's stream outside the closed layout) before the toy's (v6).
    assert stream_names() == (*STREAMS, "dvl_slow_error", "thermometer_parameters",
                              "thermometer_noise")
    streams = mission_streams(7)
    before = np.random.default_rng(7).spawn(len(STREAMS))
    for name, old in zip(STREAMS, before, strict=True):
        np.testing.assert_array_equal(streams[name].standard_normal(3), old.standard_normal(3))
    assert streams["thermometer_noise"].standard_normal() != streams[
        "thermometer_parameters"].standard_normal()


def test_a_sensor_registered_from_outside_joins_the_schema_checks_and_inspect(
        thermometer, tmp_path, capsys):
    from auvsim.cli import main
    from auvsim.runs.generate import generate

    assert "thermometer" in registry()
    assert "thermometer/temperature" in {f.path for f in schema("simulated")[0]}
    assert "thermometer/temperature" not in {f.path for f in schema("simulated", 5)[0]}
    thermometer.RATE = 33.0  # not a whole divisor of the IMU's 100 Hz: its check refuses
    with pytest.raises(ConfigError, match=r"^thermometer.rate_hz: expected a whole divisor "
                       r"of the 100 Hz IMU rate, got 33.0$"):
        flat(mission(duration=5.0))
    thermometer.RATE = 10.0
    path = tmp_path / "t.h5"
    generate(flat(mission(duration=5.0, depth=20.0)), path, workers=1, progress=False)
    assert main(["inspect", str(path)]) == 0
    text = capsys.readouterr().out
    assert "    thermometer 10 Hz (50 samples): 13.00 to 13.00 degC" in text
    assert "    thermometer: temperature, time" in text
    with pytest.raises(ValueError, match="registered already"):
        register(Thermometer)


def test_every_plugin_describes_its_part_of_a_mission(tmp_path):
    from auvsim.data.describe import describe
    from auvsim.runs.generate import generate

    path = tmp_path / "d.h5"
    generate(flat(mission(duration=5.0)), path, workers=1, progress=False)
    text = describe(path)
    for first in ("    depth sensor 10 Hz (50 samples)", "    DVL 1 Hz (5 pings)",
                  "    DVL errors: scale factor [0., 0., 0., 0.]", "    IMU 100 Hz (500 samples)"):
        assert first in text
    assert "-0." not in text  # negative zeros print as zeros


def test_status_colours_come_from_the_enumeration_for_any_number_of_codes(monkeypatch):
    """An 11th status code once gave IndexError: ten colours were listed by hand."""
    import enum

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_rgb

    from auvsim import plot

    Status = enum.IntEnum("Status", {f"CODE_{k}": k for k in range(14)} | {"OK": 0})
    monkeypatch.setattr(plot, "Status", Status)
    colours = plot.status_colours(len(Status))
    assert len(colours) == 14 and colours[:10] == list(plot.STATUS_COLOURS)
    assert len({to_rgb(c) for c in colours}) == 14  # each code its own colour
    fig, ax = plt.subplots()
    status = np.arange(14 * 4).reshape(14, 4) % 14  # every code, the 11th to 14th too
    plot._draw_status(ax, status, (0, 13, 3.5, -0.5))
    assert len(ax.get_legend().get_patches()) == 14
    plt.close(fig)
