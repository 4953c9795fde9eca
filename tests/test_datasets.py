"""Full datasets: sensors in the generated files, presets, TOML configs, workers,
`auvsim inspect`, and bad input."""

from __future__ import annotations

import dataclasses
import math
import os
import time

import h5py
import numpy as np
import pytest
from conftest import FAILING_TOML, flat, mission, write
from h5compare import assert_same_contents

from auvsim.cli import main
from auvsim.config import (
    Config,
    DvlConfig,
    MissionConfig,
    ScenarioConfig,
    SeafloorConfig,
)
from auvsim.data.reader import open_dataset
from auvsim.data.schema import FORMAT_VERSION, schema
from auvsim.errors import DatasetError
from auvsim.runs.generate import generate
from auvsim.runs.presets import PRESETS, preset
from auvsim.sensors.dvl import beam_matrix

IDEAL = flat(mission(seed=5, speed=2.0, heading_deg=30.0, depth=20.0, duration=60.0),
             dvl=DvlConfig(beam_angle_deg=30.0, max_range=90.0))


def rotation(q: np.ndarray) -> np.ndarray:
    """(M, 3, 3) body -> NED rotations of [w, x, y, z] quaternions (written out here)."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1),
    ], axis=1)


def test_level_on_a_flat_floor_slant_range_is_altitude_over_cos_alpha():
    from auvsim.physics.vehicle import Vehicle
    from auvsim.world.seafloor import Seafloor

    floor = Seafloor(SeafloorConfig(kind="flat", depth=60.0))
    vehicle = Vehicle("auv", seafloor=floor)
    rays = vehicle.ray_data()
    floor.bind(vehicle.model, rays)
    vehicle.reset(position_ned=(10.0, -4.0, 20.0))
    dvl = np.array([10.0, -4.0, 20.0]) + vehicle.dvl_position
    h = beam_matrix(math.radians(30))
    ranges = floor.cast(vehicle.model, rays, dvl[None], h[None], max_range=90.0,
                        exclude_body=vehicle.body_id)
    altitude = 60.0 - dvl[2]
    np.testing.assert_allclose(ranges, altitude / math.cos(math.radians(30)), rtol=1e-12)


@pytest.fixture(scope="module")
def ideal_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("ideal") / "ideal.h5"
    write(IDEAL, out)
    return out


def test_every_schema_field_is_written(ideal_file):
    with open_dataset(ideal_file) as f:
        m = f.missions["mission_000"]
        n, pings = 6000, 60
        fields, attrs = schema("simulated")
        rows = {"imu": n, "dvl": pings, "depth": n // 10}
        for field in fields:
            assert m.read(field.path).shape == (rows[field.clock], *field.shape), field.path
        assert m.imu.index_of_dvl.dtype == np.int64
        assert m.dvl.valid.dtype == bool
        np.testing.assert_array_equal(m.imu.index_of_dvl, np.arange(pings) * 100)
        np.testing.assert_array_equal(m.dvl.time,
                                      m.truth.time[m.imu.index_of_dvl])
        for attr in attrs:  # an optional one (the geographic origin's) only where given
            assert attr.name in m.attrs or attr.optional, attr.name
        assert "latitude_deg" not in m.attrs  # IDEAL has no geographic origin
        assert m.attrs["dvl_scale_factor"].shape == (4,)


def test_ideal_sensors_read_the_truth(ideal_file):
    """No errors configured: beams equal H v, LS equals the true DVL velocity, the IMU equals
    the truth (bitwise), and on a flat floor with the vehicle level the slant ranges are the
    DVL's altitude over cos(beam angle)."""
    with open_dataset(ideal_file) as f:
        m = f.missions["mission_000"]
        np.testing.assert_array_equal(m.dvl.beam_velocity, m.dvl.beam_velocity_true)
        np.testing.assert_allclose(m.dvl.velocity_ls, m.dvl.velocity, atol=1e-12)
        np.testing.assert_array_equal(m.imu.specific_force, m.truth.specific_force)
        np.testing.assert_array_equal(m.imu.angular_rate, m.truth.angular_rate)
        # Flat floor: each beam's range is the DVL's height over the floor divided by the
        # beam direction's down component (the vehicle rolls a few degrees under the
        # propeller's torque, so the beams are not at exactly 30 deg from vertical).
        idx = m.imu.index_of_dvl
        rot = rotation(m.truth.quaternion[idx])
        dvl = m.truth.position_ned[idx] + rot @ m.attrs["dvl_position_body"]
        h = beam_matrix(math.radians(30))
        down = np.einsum("mj,kj->mk", rot[:, 2, :], h)  # NED z of each beam
        expected = (60.0 - dvl[:, 2])[:, None] / down
        np.testing.assert_allclose(m.dvl.beam_range, expected, rtol=1e-9)
        np.testing.assert_allclose(m.truth.altitude, 60.0 - m.truth.position_ned[:, 2])
        # Forward at 2 m/s: the DVL's velocity is 2 m/s along its x, as the truth says.
        np.testing.assert_allclose(m.dvl.velocity[:, 0], 2.0, rtol=1e-3)


def test_beams_beyond_max_range_are_invalid(tmp_path):
    deep = dataclasses.replace(IDEAL, seafloor=SeafloorConfig(kind="flat", depth=200.0))
    out = tmp_path / "deep.h5"
    write(deep, out)
    with open_dataset(out) as f:
        m = f.missions["mission_000"]
        assert not m.dvl.valid.any()
        assert np.isnan(m.dvl.beam_velocity).all()
        assert np.isnan(m.dvl.beam_range).all()
        assert np.isnan(m.dvl.velocity_ls).all()


def test_same_data_for_any_number_of_workers(tmp_path):
    two = dataclasses.replace(
        preset("navigator"),
        missions=tuple(MissionConfig(name=f"m{i}", seed=i, scenario=ScenarioConfig(
            speed=1.0 + i, duration=30.0)) for i in range(3)))
    one_worker, two_workers = tmp_path / "w1.h5", tmp_path / "w2.h5"
    generate(two, one_worker, workers=1, progress=False)
    generate(two, two_workers, workers=2, progress=False)
    assert_same_contents(one_worker, two_workers)
    with h5py.File(one_worker) as f:
        assert list(f["missions"]) == ["m0", "m1", "m2"]
        # Independent missions: different seeds give different noise.
        assert not np.array_equal(f["missions/m0/dvl/beam_velocity"][:5],
                                  f["missions/m1/dvl/beam_velocity"][:5])


def test_paper_sim_preset_is_the_papers_setup(tmp_path, capsys):
    out = tmp_path / "paper.h5"
    assert main(["generate", "--preset", "paper-sim", "--duration", "20", "--workers", "1",
                 "--out", str(out), "--quiet"]) == 0
    with open_dataset(out) as f:
        assert list(f.missions) == ["speed_1", "speed_2", "speed_3"]
        for speed, name in zip((1, 2, 3), ("speed_1", "speed_2", "speed_3"), strict=True):
            a = f.missions[name].attrs
            assert a["beam_angle_deg"] == 20.0 and a["dvl_rate_hz"] == 1.0
            assert a["imu_rate_hz"] == 100.0
            np.testing.assert_array_equal(a["dvl_scale_factor"], [0.007] * 4)
            np.testing.assert_array_equal(a["dvl_bias"], [0.0001] * 4)
            assert a["dvl_noise_std"] == pytest.approx(0.042**2)
            v = f.missions[name].truth.velocity_body[:, 0]
            # 1.3 % at 1 m/s, 12 s in: the speed feedforward balances the quadratic drag
            # only, and with Prestero's drag the faded linear surge damping is 17 % of the
            # drag at 1 m/s (models/README.md); the integrator takes it up within a minute.
            assert np.abs(v / speed - 1).max() < 0.015
        config = Config.from_json(f.attrs["config_json"])
        assert config.missions[0].scenario.duration == 20.0
    capsys.readouterr()
    assert main(["presets"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in listed] == list(PRESETS)


def test_paper_sim_text_differs_only_in_noise():
    code, text = preset("paper-sim"), preset("paper-sim-text")
    assert text.dvl.noise_std == 0.042
    assert dataclasses.replace(text, dvl=code.dvl) == code


def test_long_run_beam_noise_has_the_configured_std(tmp_path):
    """Through the whole pipeline: y - H v (1 + s) - b has the configured std (3 %) and
    zero mean, with the realised s and b read back from the file's attributes."""
    config = dataclasses.replace(
        preset("paper-sim-text"),
        missions=(MissionConfig(scenario=ScenarioConfig(speed=2.0, duration=1500.0), seed=9),))
    out = tmp_path / "noise.h5"
    write(config, out)
    with open_dataset(out) as f:
        m = f.missions["mission_000"]
        s, b = m.attrs["dvl_scale_factor"], m.attrs["dvl_bias"]
        residual = m.dvl.beam_velocity - m.dvl.beam_velocity_true * (1 + s) - b
    assert abs(residual.std() / 0.042 - 1) < 0.03
    assert abs(residual.mean()) < 4 * 0.042 / math.sqrt(residual.size)


def test_toml_config_round_trips_into_the_file(tmp_path):
    toml = tmp_path / "mission.toml"
    toml.write_text("""
compression = "gzip"

[vehicle]
model = "remus100"

[[missions]]
name = "survey"
seed = 4
[missions.scenario]
speed = 1.5
depth = 15.0
duration = 30.0

[seafloor]
kind = "procedural"
depth = 40.0
roughness = 0.5

[dvl]
beam_angle_deg = 25.0
noise_std = 0.01
scale_factor = [0.001, 0.002, 0.003, 0.004]

[imu]
gyro_noise_density = 1e-5
""")
    out = tmp_path / "toml.h5"
    assert main(["generate", "--config", str(toml), "--out", str(out), "--workers", "1",
                 "--quiet"]) == 0
    with open_dataset(out) as f:
        config = Config.from_json(f.attrs["config_json"])
        assert config.vehicle.model == "remus100"
        assert config.dvl.scale_factor == (0.001, 0.002, 0.003, 0.004)
        assert f.missions["survey"].attrs["beam_angle_deg"] == 25.0
    with h5py.File(out) as f:  # the filter as stored, which the dataset API hides
        assert f["missions/survey/truth/time"].compression == "gzip"
    assert Config.from_json(config.to_json()) == config


def test_inspect_describes_the_file(ideal_file, capsys):
    assert main(["inspect", str(ideal_file)]) == 0
    text = capsys.readouterr().out
    assert ("mission_000: straight at 2 m/s, heading 30 deg, 20 m deep, seed 5, 60 s, "
            "vehicle auv") in text  # what it was commanded, from the stored config
    assert "DVL 1 Hz (60 pings)" in text and "100.0 % of beams valid" in text
    assert "    dvl: beam_range, beam_velocity, beam_velocity_true, error_velocity, mode, " \
        "status, time, valid, velocity, velocity_ls" in text


def test_reader_refuses_a_mission_missing_a_field(tmp_path, ideal_file):
    broken = tmp_path / "broken.h5"
    broken.write_bytes(ideal_file.read_bytes())
    with h5py.File(broken, "r+") as f:
        del f["missions/mission_000/dvl/velocity"]
    with pytest.raises(DatasetError, match="lacks dvl/velocity"):
        open_dataset(broken)
    assert main(["inspect", str(broken)]) == 2


def test_a_field_a_group_does_not_have_is_an_attribute_error_and_a_dataset_error(ideal_file):
    """``hasattr(mission.dvl, "fields")`` is False, as Python's protocol asks, and reading
    it names the file, the mission and the field in one line, as a ``DatasetError``."""
    with open_dataset(ideal_file) as f:
        dvl = f.missions["mission_000"].dvl
        assert hasattr(dvl, "velocity") and not hasattr(dvl, "fields")
        assert getattr(dvl, "fields", None) is None
        with pytest.raises(DatasetError, match="mission_000.* has no field dvl/fields$"):
            dvl.fields  # noqa: B018


def test_dir_lists_a_missions_groups_and_a_groups_fields(ideal_file):
    """What a notebook completes after ``mission.`` and ``mission.dvl.`` (it offered only
    ``rows``; iterating listed the fields)."""
    with open_dataset(ideal_file) as f:
        m = f.missions["mission_000"]
        assert set(m.groups) <= set(dir(m)) and "read" in dir(m)
        assert set(m.dvl) <= set(dir(m.dvl)) and "rows" in dir(m.dvl)
        assert "velocity" in dir(m.dvl) and "position_ned" in dir(m.truth)


def test_a_file_opened_again_unchanged_is_not_checked_again(tmp_path, ideal_file, monkeypatch):
    """The per-mission check runs once per file as long as the file stays as it was (and
    was quiet when checked); changed in place, it is checked again and refused."""
    from auvsim.data import reader

    checks = []
    real = reader._check_mission
    monkeypatch.setattr(reader, "_check_mission", lambda *a: checks.append(a[1]) or real(*a))
    copy = tmp_path / "copy.h5"
    copy.write_bytes(ideal_file.read_bytes())
    for _ in range(2):  # just written (within QUIET_S): checked both times
        with open_dataset(copy) as f:
            assert list(f.missions) == ["mission_000"]
    assert checks == ["mission_000"] * 2
    with h5py.File(copy, "r") as f:
        stored = dict(f["missions/mission_000"].attrs)
    monkeypatch.setattr(reader, "QUIET_S", 0.05)
    time.sleep(0.1)
    for _ in range(3):  # quiet: checked once, then known, its attributes remembered
        with open_dataset(copy) as f:
            attrs = f.missions["mission_000"].attrs
            assert attrs["origin"] == "simulated"
            assert attrs.keys() == stored.keys()
            for k, v in stored.items():
                np.testing.assert_array_equal(attrs[k], v, err_msg=k)
            # A caller's change to its copy is not the next open's.
            attrs["dvl_scale_factor"] += 1.0
            attrs["beam_angle_deg"] = -1.0
    assert len(checks) == 3
    with h5py.File(copy, "r+") as f:
        del f["missions/mission_000/dvl/velocity"]
    old = copy.stat().st_mtime - 60.0
    os.utime(copy, (old, old))  # its modification time set back: its ctime still tells
    with pytest.raises(DatasetError, match="lacks dvl/velocity"):
        open_dataset(copy)
    assert len(checks) == 4


BAD = [
    ("[dvl]\nrate_hz = 0\n", "dvl.rate_hz"),
    ("[dvl]\nrate_hz = 3\n", "dvl.rate_hz"),  # not a divisor of 100 Hz
    ("[imu]\nrate_hz = -100\n", "imu.rate_hz"),
    ("[dvl]\nbeam_angle_deg = 95\n", "dvl.beam_angle_deg"),
    ("[dvl]\nnoise_std = -0.1\n", "dvl.noise_std"),
    ("[dvl]\nbias = nan\n", "dvl.bias"),
    ("[imu]\ngyro_noise_density = nan\n", "imu.gyro_noise_density"),
    ("[dvl]\nbeam_angel_deg = 30\n", "unknown setting(s) beam_angel_deg (did you mean "
                                          "'beam_angle_deg'?)"),
    ("[seafloor]\nkind = \"moon\"\n", "seafloor.kind"),
    ("this is not toml", "not valid TOML"),
    ("[seafloor]\nkind = \"heightmap\"\nheightmap = 5\n", "seafloor.heightmap"),
    ("[[missions]]\nseed = true\n", "seed"),
    ("[dvl]\nscale_factor = \"1234\"\n", "dvl.scale_factor"),
    ("[seafloor]\nkind = \"procedural\"\n[dvl]\nmax_range = 2000\n", "dvl.max_range"),
    ("[[missions]]\n[missions.scenario]\ndepth = 59.5\nduration = 5\n"
     "[seafloor]\nkind = \"procedural\"\ndepth = 60\nroughness = 3\n", "reached the seafloor"),
]


@pytest.mark.parametrize("text,message", BAD)
def test_bad_config_gives_one_line_and_exit_2(tmp_path, capsys, text, message):
    toml = tmp_path / "bad.toml"
    toml.write_text(text)
    out = tmp_path / "never.h5"
    assert main(["generate", "--config", str(toml), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


@pytest.mark.parametrize("args,message", [
    (["--preset", "paper-simulation"], "unknown preset 'paper-simulation'"),
    (["--config", "/nonexistent/x.toml"], "no such file"),
    (["--workers", "0"], "workers"),
])
def test_bad_options_give_one_line_and_exit_2(tmp_path, capsys, args, message):
    assert main(["generate", *args, "--duration", "5", "--out", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []


def test_inspect_missing_file(capsys, tmp_path):
    assert main(["inspect", str(tmp_path / "none.h5")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_heightmap_named_in_a_toml_file_is_found_next_to_it(tmp_path, monkeypatch):
    """A user's terrain: a plane 50 m deep sloping 1 m per 10 m to the east; altitude and
    ranges come from it (the vehicle holds 20 m depth heading north along x = 0)."""
    east = (np.arange(201) - 100) * 2.0  # 2 m cells, centred on the start
    depths = np.tile(50.0 + 0.1 * east, (201, 1))
    np.save(tmp_path / "floor.npy", depths)
    (tmp_path / "map.toml").write_text("""
[[missions]]
[missions.scenario]
speed = 1.0
duration = 20.0
[seafloor]
kind = "heightmap"
heightmap = "floor.npy"
cell_size = 2.0
""")
    monkeypatch.chdir("/")  # the path must resolve against the TOML file, not the cwd
    out = tmp_path / "map.h5"
    assert main(["generate", "--config", str(tmp_path / "map.toml"), "--out", str(out),
                 "--workers", "1", "--quiet"]) == 0
    with open_dataset(out) as f:
        m = f.missions["mission_000"]
        pos = m.truth.position_ned
        np.testing.assert_allclose(m.truth.altitude, 50.0 + 0.1 * pos[:, 1] - pos[:, 2],
                                   atol=1e-4)
        assert m.dvl.valid.all()


def test_one_missions_failure_stops_the_others_early(tmp_path, capsys):
    """Mission a reaches the seafloor within seconds; the long mission b must not be
    simulated to its end before the error is reported."""
    import time

    toml = tmp_path / "fail.toml"
    toml.write_text(FAILING_TOML)
    started = time.perf_counter()
    assert main(["generate", "--config", str(toml), "--out", str(tmp_path / "x.h5"),
                 "--workers", "1", "--quiet"]) == 2
    assert time.perf_counter() - started < 30  # b alone would take about two minutes
    assert "a: the vehicle reached the seafloor" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fail.toml"]


def test_sigterm_stops_cleanly(tmp_path):
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen(
        [sys.executable, "-m", "auvsim", "generate", "--preset", "paper-sim", "--workers", "2",
         "--duration", "200000", "--quiet", "--out", str(tmp_path / "x.h5")],
        stderr=subprocess.PIPE, text=True)  # about five minutes of work: it cannot finish
    time.sleep(6)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args,message", [
    (["--speed", "0.2"], "too slow"),
    (["--seed", "99999999999999999999999"], "seed"),
])
def test_more_bad_options(tmp_path, capsys, args, message):
    assert main(["generate", *args, "--duration", "5", "--out", str(tmp_path / "x.h5")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert list(tmp_path.iterdir()) == []


def test_out_may_not_be_a_directory(tmp_path, capsys):
    assert main(["generate", "--duration", "5", "--out", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


# -- schema v6: facts of the simulator stored in the file -------------------------------

FACTS = flat(MissionConfig("zigzag", ScenarioConfig("zigzag", duration=60.0), 3),
             MissionConfig("waypoints", ScenarioConfig("random_waypoints", duration=60.0,
                                                          options={"radius_m": 60.0}), 4),
             mission("straight", seed=5, duration=30.0))


def _rebuilt(config: Config) -> tuple[dict[str, list], float]:
    """The phases and gravity as beamsnet derived them before v6: the manoeuvre made
    again from each mission's seed stream, the model's MJCF loaded."""
    import mujoco

    from auvsim.data.streams import mission_streams
    from auvsim.physics.maneuvers import make_maneuver
    from auvsim.physics.vehicle import model_path

    phases = {m.name: make_maneuver(m.scenario, rng=mission_streams(m.seed)["maneuver"]).phases()
              for m in config.missions}
    gravity = -float(mujoco.MjModel.from_xml_path(str(model_path("auv"))).opt.gravity[2])
    return phases, gravity


@pytest.fixture(scope="module")
def facts_file(dataset_of):
    return dataset_of(FACTS, "facts")


def test_missions_store_their_gravity_and_phases(facts_file):
    phases, gravity = _rebuilt(FACTS)
    with open_dataset(facts_file) as f:
        assert f.version == FORMAT_VERSION >= 6
        for name, m in f.missions.items():
            assert m.gravity == gravity == 9.81
            assert m.phases == phases[name] and m.phases
            assert all(type(p) is tuple and len(p) == 3 for p in m.phases)
        assert [p[2] for p in f.missions["zigzag"].phases] == ["straight", "zigzag"]
        assert f.missions["straight"].phases == [(0.0, 30.0, "straight")]


def test_a_version_5_file_derives_the_same_gravity_and_phases(facts_file, tmp_path):
    old = tmp_path / "v5.h5"
    old.write_bytes(facts_file.read_bytes())
    with h5py.File(old, "r+") as f:
        f.attrs["format_version"] = 5
        for name in f["missions"]:
            del f[f"missions/{name}"].attrs["gravity"], f[f"missions/{name}"].attrs["phases"]
    with open_dataset(facts_file) as new, open_dataset(old) as f:
        assert f.version == 5
        for name, m in f.missions.items():
            assert "phases" not in m.attrs
            assert (m.gravity, m.phases) == (new.missions[name].gravity,
                                              new.missions[name].phases)


def test_a_version_5_file_whose_config_does_not_name_its_missions_has_no_phases(
        facts_file, tmp_path):
    old = tmp_path / "v5.h5"
    old.write_bytes(facts_file.read_bytes())
    with h5py.File(old, "r+") as f:
        f.attrs["format_version"] = 5
        f.attrs["config_json"] = ""
        del f["missions/zigzag"].attrs["phases"], f["missions/zigzag"].attrs["gravity"]
    with open_dataset(old) as f:
        m = f.missions["zigzag"]
        assert m.phases == [] and m.gravity == 9.81  # the default model's


def test_a_version_6_file_without_gravity_is_refused(facts_file, tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(facts_file.read_bytes())
    with h5py.File(bad, "r+") as f:
        del f["missions/zigzag"].attrs["gravity"]
    with pytest.raises(DatasetError, match="zigzag .*lacks attribute gravity"):
        open_dataset(bad)


def test_a_mission_read_after_its_dataset_closed_says_so(ideal_file):
    """In a notebook a mission outlives its ``with`` block easily: reading it then is one
    DatasetError saying the dataset is closed, not h5py's "Not an id of a file object"."""
    with open_dataset(ideal_file) as f:
        mission = next(iter(f.missions.values()))
        velocity = mission.dvl.velocity  # read inside: kept
    assert velocity.shape[1] == 3
    for read in (lambda: mission.dvl.velocity, lambda: mission.groups,
                 lambda: mission.has("truth")):
        with pytest.raises(DatasetError, match="its dataset is closed; expected reads inside "
                                               "the `with open_dataset"):
            read()


def test_the_writer_keeps_every_row_of_appends_that_are_not_whole_chunks(tmp_path):
    """Appends of 1.2 and 1.1 chunks: every row lands, in order (an import appends a
    whole stream at once)."""
    from auvsim.data.writer import CHUNK_ROWS, MissionWriter

    whole = np.arange(2 * CHUNK_ROWS + 500, dtype=float)
    with h5py.File(tmp_path / "x.h5", "w") as f:
        group = f.create_group("m")
        sink = MissionWriter(group, {}, {"dvl": len(whole)})
        sink.append({"dvl/time": whole[:CHUNK_ROWS + 1000]})
        sink.append({"dvl/time": whole[CHUNK_ROWS + 1000:]})
        sink.flush()
        np.testing.assert_array_equal(group["dvl/time"][()], whole)
