"""`auvsim generate`, the straight scenario, the HDF5 layout and bad input."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys

import h5py
import numpy as np
import pytest
from conftest import CountingBar
from h5compare import assert_same_contents

from auvsim.cli import main
from auvsim.config import (
    Config,
    DvlConfig,
    ImuConfig,
    MissionConfig,
    ScenarioConfig,
    SeafloorConfig,
    VehicleConfig,
)
from auvsim.data.reader import open_dataset
from auvsim.data.schema import FORMAT_VERSION
from auvsim.errors import ConfigError, DatasetError
from auvsim.runs.generate import generate
from auvsim.runs.mission import MissionRun

TRUTH_SHAPES = {"time": (), "position_ned": (3,), "velocity_ned": (3,), "velocity_body": (3,),
                "quaternion": (4,), "angular_rate": (3,), "specific_force": (3,),
                "altitude": ()}


def straight(speed=2.0, heading_deg=30.0, depth=20.0, duration=300.0, start_speed=None,
             vehicle="auv", seed=0) -> Config:
    scenario = ScenarioConfig(speed=speed, heading_deg=heading_deg, depth=depth,
                              duration=duration, start_speed=start_speed)
    return Config(vehicle=VehicleConfig(model=vehicle),
                  missions=(MissionConfig(scenario=scenario, seed=seed),))


def truth(config: Config) -> dict[str, np.ndarray]:
    blocks = list(MissionRun(config, config.missions[0]).blocks())
    return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


@pytest.fixture(scope="module")
def demo_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("gen") / "straight.h5"
    code = main(["generate", "--scenario", "straight", "--speed", "2", "--heading-deg", "30",
                 "--depth", "20", "--duration", "120", "--seed", "7", "--out", str(out),
                 "--quiet"])
    assert code == 0
    return out


def test_generate_writes_the_schema_truth(demo_file):
    with open_dataset(demo_file) as f:
        assert f.attrs["format"] == "auvsim-dataset"
        assert f.attrs["format_version"] == FORMAT_VERSION == 7
        assert {"auvsim_version", "created_utc", "config_json"} <= set(f.attrs)
        config = Config.from_json(f.attrs["config_json"])
        assert config.missions[0].scenario.heading_deg == 30.0
        mission = f.missions["mission_000"]
        assert mission.attrs["scenario"] == "straight"
        assert mission.attrs["seed"] == 7
        assert mission.attrs["duration_s"] == 120.0
        assert mission.attrs["vehicle"] == "auv"
        assert mission.attrs["imu_rate_hz"] == 100.0
        n = 120 * 100
        for name, shape in TRUTH_SHAPES.items():
            values = mission.read(f"truth/{name}")
            assert values.shape == (n, *shape), name
            assert values.dtype == np.float64
        np.testing.assert_allclose(mission.truth.time[:3], [0.0, 0.01, 0.02])
        quat = mission.truth.quaternion
        np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0, atol=1e-12)
        # Starts on the set heading: quaternion of a 30 deg yaw about NED z.
        np.testing.assert_allclose(quat[0], [math.cos(math.radians(15)), 0, 0,
                                             math.sin(math.radians(15))], atol=1e-12)
        altitude = mission.truth.altitude
        depth = mission.truth.position_ned[:, 2]
        # The default (navigator) floor is rough terrain about a 60 m plane.
        terrain = altitude + depth
        assert np.abs(terrain - config.seafloor.depth).max() < 6 * config.seafloor.roughness
        assert terrain.std() > 0.01
        for name in ("propeller_rpm", "thrust", "rudder", "stern_planes"):
            assert mission.read(f"control/{name}").shape == (n,)


def test_gzip_on_request(tmp_path):
    out = tmp_path / "g.h5"
    assert main(["generate", "--duration", "5", "--compression", "gzip", "--out", str(out),
                 "--quiet"]) == 0
    with h5py.File(out) as f:  # the filter as stored, which the dataset API hides
        assert f["missions/mission_000/truth/velocity_body"].compression == "gzip"
        assert f["missions/mission_000/truth/velocity_body"].fletcher32


def test_config_round_trips_through_json():
    config = Config(
        vehicle=VehicleConfig(model="remus100", net_buoyancy=1.5, current_ned=(0.1, -0.2, 0)),
        missions=(MissionConfig(name="a", scenario=ScenarioConfig(speed=1.2), seed=3),
                  MissionConfig(name="b", scenario=ScenarioConfig(duration=9, start_speed=0),
                                seed=4)),
        imu=ImuConfig(rate_hz=50.0, gyro_noise_density=1e-4),
        seafloor=SeafloorConfig(kind="procedural", roughness=2.0),
        dvl=DvlConfig(rate_hz=5.0, scale_factor=(0.1, 0.2, 0.3, 0.4), bias=0.001),
        compression="gzip",
    )
    assert Config.from_json(config.to_json()) == config


@pytest.mark.parametrize("vehicle,speed", [("auv", 0.5), ("auv", 2.0), ("auv", 3.0),
                                           ("remus100", 1.5)])
def test_straight_from_rest_settles_and_holds(vehicle, speed):
    """From rest the autopilots bring the vehicle to the set point and hold it: speed
    within 1 % and depth within 0.5 m after settling (the issue's acceptance figures)."""
    data = truth(straight(vehicle=vehicle, speed=speed, duration=400.0, start_speed=0.0,
                          heading_deg=30.0, depth=25.0))
    settled = data["truth/time"] >= 200.0
    u = data["truth/velocity_body"][settled, 0]
    depth = data["truth/position_ned"][settled, 2]
    q = data["truth/quaternion"][settled]
    yaw = np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]),
                     1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2))
    assert np.max(np.abs(u / speed - 1.0)) < 0.01
    assert np.max(np.abs(depth - 25.0)) < 0.5
    assert np.max(np.abs(np.degrees(yaw) - 30.0)) < 1.0
    # Straight means straight: the track over the settled part is a line at 30 deg.
    pos = data["truth/position_ned"][settled]
    track = np.degrees(np.arctan2(pos[-1, 1] - pos[0, 1], pos[-1, 0] - pos[0, 0]))
    assert abs(track - 30.0) < 0.5


def test_depth_and_heading_changes_settle():
    """Set points away from the start: 10 m deeper and 60 deg to starboard."""
    config = straight(speed=2.0, heading_deg=60.0, depth=30.0, duration=300.0)
    scenario = config.missions[0].scenario
    from auvsim.physics.maneuvers import make_maneuver
    from auvsim.physics.vehicle import Vehicle

    vehicle = Vehicle("auv")
    vehicle.reset(position_ned=(0, 0, 20.0), velocity_body=(2.0, 0, 0))
    traj = make_maneuver(scenario).run(vehicle, np.arange(30000) * vehicle.dt)
    late = slice(15000, None)  # after 150 s
    q = traj.quaternion[late]
    yaw = np.degrees(np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]),
                                1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2)))
    assert np.max(np.abs(traj.position_ned[late, 2] - 30.0)) < 0.5
    assert np.max(np.abs(yaw - 60.0)) < 1.0
    assert np.max(np.abs(traj.velocity_body[late, 0] / 2.0 - 1.0)) < 0.01


def test_same_seed_gives_identical_files(tmp_path, demo_file):
    again = tmp_path / "again.h5"
    assert main(["generate", "--speed", "2", "--heading-deg", "30", "--depth", "20",
                 "--duration", "120", "--seed", "7", "--out", str(again), "--quiet"]) == 0
    assert_same_contents(demo_file, again)


BAD_INPUTS = [
    (["--duration", "0"], "duration"),
    (["--duration", "-5"], "duration"),
    (["--scenario", "zigzag-nope"], "scenario"),
    (["--vehicle", "submarine"], "vehicle"),
    (["--speed", "9"], "speed 9 m/s is beyond"),
    (["--speed", "0"], "speed"),
    (["--depth", "150"], "depth"),
    (["--speed", "fast"], "--speed"),
    (["--duration", "nan"], "duration"),
    (["--duration", "1e9"], "duration: expected at most 259200 s"),
    (["--duration", "1e300"], "duration: expected at most"),
    (["--duration", "9223372036854775808"], "duration: expected at most"),
    (["--heading-deg", "1e300"], "heading_deg"),
    (["--depth", "1e300"], "depth: expected at most 11000 m"),
    (["--speed", "1e300"], "speed: expected at most 10 m/s"),
    (["--seed", "9223372036854775808"], "seed"),
    (["--workers", "0"], "--workers: expected a whole number >= 1"),
    (["--option", "rudder_deg"], "--option: expected NAME=X"),
    (["--option", "rudder_deg=inf"], "--option: expected NAME=X"),
    (["--scenario", "zigzag", "--option", "rudder=30"],
     "unknown option(s) rudder for zigzag; expected some of angle_deg"),
    (["--preset", "paper_sim"], "unknown preset 'paper_sim' (did you mean 'paper-sim'?)"),
    (["--scenario", "zig-zag"], "got 'zig-zag' (did you mean 'zigzag'?)"),
    (["--preset", "maneuvers", "--option", "rudder_deg=10"],
     "--option rudder_deg: the missions of preset 'maneuvers' fly different manoeuvres, and "
     "straight, lawnmower, depth_steps, yoyo, speed_steps, random_waypoints take no such "
     "option (only turning_circle, zigzag, spiral_dive)"),
]


@pytest.mark.parametrize("args,message", BAD_INPUTS)
def test_bad_input_gives_one_line_and_exit_2(tmp_path, capsys, args, message):
    out = tmp_path / "bad.h5"
    with pytest.raises(SystemExit) as stop:
        sys.exit(main(["generate", *args, "--out", str(out)]))
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


# The probe of issue #9 (fuzzed configs): each crashed with a traceback, ran on for ever or
# wrote meaningless data. TOML text, files beside it, and what the one line must name.
SHORT = "[[missions]]\n[missions.scenario]\nduration = 5\n"
BAD_FILES = [
    ("x = " + "[" * 2000 + "]" * 2000 + "\n", {}, "nested too deeply"),
    ("x = " + "{a = " * 2000 + "1" + "}" * 2000 + "\n", {}, "nested too deeply"),
    ("[[missions]]\n[missions.scenario]\nduration = 1e300\n", {}, "duration"),
    ("[[missions]]\n[missions.scenario]\nduration = 9223372036854775808\n", {}, "duration"),
    ("[vehicle]\ncurrent_ned = [1e6, 0, 0]\n" + SHORT, {}, "vehicle.current_ned"),
    ("[vehicle]\nnet_buoyancy = -9223372036854775808\n" + SHORT, {}, "vehicle.net_buoyancy"),
    ("[vehicle]\ndvl_position = [-1.85, 0]\n" + SHORT, {}, "vehicle.dvl_position"),
    ("[vehicle]\nimu_position = [1e3, 0, 0]\n" + SHORT, {}, "vehicle.imu_position"),
    ("[seafloor]\nkind = \"heightmap\"\nheightmap = \"map.npy\"\n" + SHORT,
     {"map.npy": b""}, "map.npy"),
    ("[seafloor]\nkind = \"heightmap\"\nheightmap = \"map.npy\"\n" + SHORT,
     {"map.npy": b"\x93NUMPY garbage"}, "map.npy"),
    (SHORT + "name = \"random_waypoints\"\noptions = {depth_span_m = -1}\n", {},
     "scenario.options.depth_span_m"),
    (SHORT + "name = \"random_waypoints\"\noptions = {count = 1e15}\n", {},
     "scenario.options.count"),
    ("[vehicle]\nmodel = \"sphere.xml\"\n" + SHORT, {"sphere.xml": "hull 0.25"},
     "geom 'hull' size"),
    ("[vehicle]\nmodel = \"wide.xml\"\n" + SHORT, {"wide.xml": "hull 0.2"},
     "geom 'hull' size"),
    # 0.2 m cells make a 204 m terrain window, which a 60 s block at 3.4 m/s outran.
    ("[seafloor]\nkind = \"procedural\"\ncell_size = 0.2\n[dvl]\nmax_range = 1\n"
     "min_range = 0.1\n" + SHORT + "speed = 3.4\n", {}, "seafloor.cell_size"),
]


@pytest.mark.parametrize("text,files,message", BAD_FILES)
def test_bad_config_file_gives_one_line_and_exit_2(tmp_path, capfd, monkeypatch, text, files,
                                                    message):
    from auvsim.physics.vehicle import model_path

    monkeypatch.chdir(tmp_path)  # where MuJoCo would write a MUJOCO_LOG.TXT
    for name, content in files.items():
        if isinstance(content, bytes):
            (tmp_path / name).write_bytes(content)
        else:  # a hull of another length: the shipped model with its a semi-axis changed
            a = content.split()[1]
            model = model_path("auv").read_text().replace('size="2.75 0.25 0.25"',
                                                          f'size="{a} 0.25 0.25"')
            (tmp_path / name).write_text(model)
    (tmp_path / "bad.toml").write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["generate", "--config", "bad.toml", "--out", "x.h5", "--quiet"]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("auvsim: error: ") and message in err
    assert out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_unwritable_output_is_refused(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    assert main(["generate", "--duration", "10", "--out", str(blocker / "x.h5")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a_file' is a file, not a folder" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]


def test_an_output_that_is_a_folder_or_another_file_is_refused(tmp_path, capsys):
    """A folder is refused with the hint of a sharded dataset (a trailing /); a user's
    file that is not HDF5 is never replaced; an empty one (mktemp's) is."""
    assert main(["generate", "--duration", "10", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"(or '{tmp_path}/', with a trailing /, for a sharded" in err
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    assert main(["generate", "--duration", "10", "--out", str(notes)]) == 2
    assert "a file that is not HDF5 is there" in capsys.readouterr().err
    assert notes.read_text() == "mine"
    empty = tmp_path / "empty.h5"
    empty.write_bytes(b"")
    assert main(["generate", "--duration", "10", "--out", str(empty), "--quiet"]) == 0
    assert empty.stat().st_size > 0


def test_the_library_refuses_a_users_other_file_as_the_command_line_does(tmp_path):
    """``generate()`` from Python had replaced any file at ``out`` (a user's script, say)
    with the dataset; it now refuses it as ``auvsim generate --out`` does."""
    from auvsim.runs.presets import preset

    script = tmp_path / "analysis.py"
    script.write_text("print(1)\n")
    with pytest.raises(ConfigError, match="a file that is not HDF5 is there"):
        generate(preset("navigator").with_duration(10), script, progress=False)
    assert script.read_text() == "print(1)\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["analysis.py"]


def test_console_script_error_has_no_traceback(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "auvsim", "generate", "--duration", "-1", "--out",
         str(tmp_path / "x.h5")], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "auvsim: error: duration: expected a positive number of seconds, got -1.0"]


def test_a_script_that_generates_at_its_top_level_is_told_to_guard_it(tmp_path):
    """Each worker of the pool imports the main script again as it starts: there an
    unguarded ``generate`` now says what to do, where it had failed on the output its
    parent holds, and the parent only said that a worker ended abruptly."""
    script = tmp_path / "unguarded.py"
    script.write_text("import auvsim\n"
                      "config = auvsim.preset('paper-sim')\n"
                      "auvsim.generate(config, 'out.h5', workers=2, progress=False)\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert done.returncode == 1
    assert ("RuntimeError: generate() was called in a worker process importing the main "
            "script as it started: a script that does so at its top level must do it under "
            "if __name__ == \"__main__\":") in done.stderr, done.stderr[-2000:]
    assert "its error is printed above" in done.stderr.splitlines()[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["unguarded.py"]


def test_failure_midway_leaves_nothing(tmp_path, monkeypatch):
    import auvsim.runs.generate as gen

    def failing(config, mission):
        yield from []
        raise RuntimeError("simulated crash")

    monkeypatch.setattr(gen.MissionRun, "blocks", lambda self, stop=None: failing(None, None))
    with pytest.raises(RuntimeError):
        generate(straight(duration=10), tmp_path / "x.h5", progress=False)
    assert list(tmp_path.iterdir()) == []


def test_reader_refuses_foreign_corrupt_and_other_versions(tmp_path, demo_file):
    with pytest.raises(DatasetError, match="no such file"):
        open_dataset(tmp_path / "missing.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(200))
    with pytest.raises(DatasetError, match="not an HDF5 file"):
        open_dataset(junk)
    foreign = tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = [1, 2, 3]
    with pytest.raises(DatasetError, match="not an auvsim dataset"):
        open_dataset(foreign)
    newer = tmp_path / "newer.h5"
    newer.write_bytes(demo_file.read_bytes())
    with h5py.File(newer, "r+") as f:
        f.attrs["format_version"] = 8
    with pytest.raises(DatasetError,
                       match="format_version 8; this auvsim reads versions 1, 2, 3, 4, 5, 6, 7 "
                       r"\(the file is from a newer auvsim\)"):
        open_dataset(newer)


def test_version_1_files_still_read_as_simulated(demo_file, tmp_path):
    """Schema v2 only added the mission attribute ``origin``; a v1 file has none."""
    old = tmp_path / "v1.h5"
    old.write_bytes(demo_file.read_bytes())
    with h5py.File(old, "r+") as f:
        f.attrs["format_version"] = 1
        for m in f["missions"].values():
            del m.attrs["origin"]
    with open_dataset(old) as f:
        assert len(f.missions) == 1
    with h5py.File(old, "r+") as f:  # the same file claiming v2 lacks the attribute
        f.attrs["format_version"] = 2
    with pytest.raises(DatasetError, match="has no origin attribute"):
        open_dataset(old)


@pytest.mark.parametrize("kwargs", [dict(speed=float("nan")), dict(duration=float("inf")),
                                    dict(name="nope"), dict(depth=-3.0)])
def test_scenario_validation_names_the_field(kwargs):
    with pytest.raises(ConfigError) as err:
        ScenarioConfig(**kwargs)
    field = next(iter(kwargs))
    assert ("scenario" if field == "name" else field) in str(err.value)


def test_an_unstable_mission_stops_the_run_naming_mission_and_time(tmp_path, monkeypatch):
    from auvsim.errors import SimulationError
    from auvsim.physics.vehicle import Vehicle

    calls = {"n": 0}

    def unstable_on_the_second_block(self):
        calls["n"] += 1
        if calls["n"] == 2:
            raise SimulationError("the simulation became unstable (MuJoCo: test)")

    monkeypatch.setattr(Vehicle, "_check_stable", unstable_on_the_second_block)
    with pytest.raises(SimulationError, match=r"mission_000: between t = 60\.0 and 120\.0 s, "
                                              r"the simulation became unstable"):
        generate(straight(duration=180), tmp_path / "x.h5", progress=False)
    assert list(tmp_path.iterdir()) == []


def test_progress_comes_back_from_any_executor(tmp_path, monkeypatch):
    """A thread pool stands in for a cluster's executor: jobs report through the part
    folder, and the file is the one the built-in paths write."""
    from concurrent.futures import ThreadPoolExecutor

    config = straight(duration=130)
    config = dataclasses.replace(config, missions=(
        config.missions[0], dataclasses.replace(config.missions[0], name="other", seed=4)))
    monkeypatch.setattr(CountingBar, "updates", [])
    monkeypatch.setattr("auvsim.runs.generate.tqdm", CountingBar)
    with ThreadPoolExecutor(max_workers=2) as pool:
        generate(config, tmp_path / "pool.h5", executor=pool, progress=False)
    updates = CountingBar.updates
    monkeypatch.undo()
    generate(config, tmp_path / "threads.h5", workers=1, progress=False)
    assert sum(updates) == 260
    assert_same_contents(tmp_path / "pool.h5", tmp_path / "threads.h5")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pool.h5", "threads.h5"]


def test_another_vehicle_on_a_preset_takes_its_own_sensors_and_turbulence(tmp_path):
    """--vehicle remus100 on the navigator preset (the default): the preset's sensor sites
    (the Snapir's, 1.8 m aft, behind a REMUS 100's tail) go back to the model's own, and
    its turbulent wrench, sized through the A18-D's force model, is scaled by the two
    models' coefficients (read here from the model files' hydrodynamics). With the A18-D's
    wrench the 31 kg vehicle rolled over; with its own it holds its attitude and depth."""
    from auvsim.physics.vehicle import Vehicle
    from auvsim.runs.presets import preset, with_vehicle

    navigator = preset("navigator")
    assert with_vehicle(navigator, "auv") is navigator
    remus = with_vehicle(navigator, "remus100")
    assert remus.vehicle.model == "remus100"
    assert remus.vehicle.imu_position is remus.vehicle.dvl_position is None
    assert remus.vehicle.speed_control == navigator.vehicle.speed_control
    a, r = Vehicle("auv").hydro, Vehicle("remus100").hydro
    lift = (r.hull_lift + r.fin_lift) / (a.hull_lift + a.fin_lift)
    moment = ((r.hull_lift * -r.hull_lift_x + r.fin_lift * -r.fin_x)
              / (a.hull_lift * -a.hull_lift_x + a.fin_lift * -a.fin_x))
    old, new = navigator.water, remus.water
    assert np.allclose(new.turbulence_force_std,
                       np.multiply(old.turbulence_force_std,
                                   (r.axial_drag / a.axial_drag, lift, lift)))
    assert np.allclose(new.turbulence_moment_std,
                       np.multiply(old.turbulence_moment_std, moment))

    out = tmp_path / "remus.h5"
    assert main(["generate", "--vehicle", "remus100", "--scenario", "zigzag", "--speed", "1.5",
                 "--duration", "120", "--out", str(out), "--quiet"]) == 0
    with h5py.File(out) as f:
        truth = f["missions/mission_000/truth"]
        q, depth = truth["quaternion"][:], truth["position_ned"][:, 2]
    roll = np.degrees(np.arctan2(2 * (q[:, 0] * q[:, 1] + q[:, 2] * q[:, 3]),
                                 1 - 2 * (q[:, 1] ** 2 + q[:, 2] ** 2)))
    assert np.abs(roll).max() < 10.0 and np.abs(depth - 20.0).max() < 1.0


@pytest.mark.parametrize("flags,field", [
    (["--preset", "maneuvers", "--scenario", "zigzag"], "--scenario"),
    (["--preset", "paper-sim", "--speed", "2"], "--speed"),
    (["--preset", "realistic-maneuvers", "--speed", "1"], "--speed")])
def test_an_override_of_what_names_a_presets_missions_is_refused(flags, field, tmp_path,
                                                                 capsys):
    """One manoeuvre or speed over missions named for theirs would leave maneuvers'
    turning_circle flying a zigzag and paper-sim's speed_1 at 2 m/s: refused in one line,
    nothing written; an override the missions share (--duration) is not."""
    out = tmp_path / "x.h5"
    assert main(["generate", *flags, "--duration", "5", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{field}: the missions of preset" in err, err
    assert "differ in it" in err and not out.exists()
    assert main(["generate", flags[0], flags[1], "--duration", "5", "--out", str(out),
                 "--quiet"]) == 0


def test_configs_built_in_python_take_numpy_seeds_and_name_what_is_wrong(tmp_path):
    """A numpy integer seed is the number it holds; a ScenarioConfig where a MissionConfig
    belongs, or a preset's name where a Config belongs, is named in one line instead of
    failing deep inside (an AttributeError)."""
    import auvsim

    assert auvsim.MissionConfig(seed=np.int64(7)).seed == 7
    assert type(auvsim.MissionConfig(seed=np.int64(7)).seed) is int
    with pytest.raises(ConfigError, match="missions: expected MissionConfigs .* got "
                                          "'ScenarioConfig'"):
        Config(missions=[ScenarioConfig()])
    with pytest.raises(ConfigError, match="mission.scenario: expected a ScenarioConfig"):
        MissionConfig(scenario="zigzag")
    with pytest.raises(ConfigError, match="config: expected an auvsim Config .* got str "
                                          "'navigator'"):
        generate("navigator", tmp_path / "x.h5")
    assert not (tmp_path / "x.h5").exists()


def test_a_bare_config_has_bottom_lock():
    """The defaults fly 20 m deep over a floor the default DVL reaches (a 100 m floor left
    its 30 deg beams 92 m away, beyond its 90 m range: a dataset with no lock at all)."""
    config = Config()
    altitude = config.seafloor.depth - config.missions[0].scenario.depth
    slant = altitude / math.cos(math.radians(config.dvl.beam_angle_deg))
    assert config.dvl.min_range < slant < config.dvl.max_range
    short = MissionConfig(scenario=ScenarioConfig(duration=20.0))
    data = truth(dataclasses.replace(config, missions=(short,)))
    assert np.isfinite(data["dvl/beam_velocity"]).mean() > 0.9


def test_another_programs_hdf5_file_is_never_replaced(tmp_path, capsys):
    """An HDF5 file that is not an auvsim dataset (another program's) at --out, as a
    sharded folder's index, or among its shards is the user's: refused, or left, never
    replaced or deleted; a dataset at --out is replaced as before."""
    def foreign(path):
        with h5py.File(path, "w") as f:
            f["temperature"] = np.zeros(3)

    theirs = tmp_path / "theirs.h5"
    foreign(theirs)
    assert main(["generate", "--duration", "5", "--out", str(theirs), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "an HDF5 file that is not an auvsim dataset is there" in err, err
    with h5py.File(theirs) as f:
        assert list(f) == ["temperature"]
    ours = tmp_path / "ours.h5"
    for _ in range(2):
        assert main(["generate", "--duration", "5", "--out", str(ours), "--quiet"]) == 0

    folder = tmp_path / "rm"
    folder.mkdir()
    foreign(folder / "index.h5")
    assert main(["generate", "--preset", "maneuvers", "--duration", "5", "--workers", "1",
                 "--out", f"{folder}/", "--quiet"]) == 2
    assert "not an auvsim index is there" in capsys.readouterr().err
    (folder / "index.h5").unlink()
    (folder / "shards").mkdir()
    foreign(folder / "shards" / "part-00099.h5")
    assert main(["generate", "--preset", "maneuvers", "--duration", "5", "--workers", "1",
                 "--out", f"{folder}/", "--quiet"]) == 0
    assert (folder / "shards" / "part-00099.h5").is_file()  # not taken for a stale shard


def test_option_sets_a_scenario_option_of_every_mission():
    """``--option NAME=X``, any number of times, over the scenario's own options (those of a
    preset's missions too), into the config the file records."""
    from auvsim.cli import _parser, build_config

    def options(*flags: str) -> list[dict]:
        args = _parser().parse_args(["generate", *flags, "--out", "x.h5"])
        return [m.scenario.options for m in build_config(args).missions]

    assert options("--scenario", "zigzag", "--option", "rudder_deg=30",
                   "--option", "angle_deg=10") == [{"rudder_deg": 30.0, "angle_deg": 10.0}]
    assert options("--preset", "paper-sim", "--option", "leg_m=300") == [{"leg_m": 300.0}] * 3


def test_an_empty_out_is_refused_as_empty(tmp_path, capsys, monkeypatch):
    """``--out ""`` was read as '.', "a directory; expected a file name (or '', ...)"."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main(["generate", "--duration", "5", "--out", ""])
    assert stop.value.code == 2
    assert capsys.readouterr().err.endswith("argument --out: '': empty; expected a path\n")
    assert list(tmp_path.iterdir()) == []
