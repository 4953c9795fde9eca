"""The simulated IMU on the rotating WGS-84 Earth (``auvsim.config.LocationConfig``): at
rest and along a flown trajectory, the gyros read the Earth's rate and the accelerometers
the normal gravity (and the Coriolis term); without a geographic origin nothing changes."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import flat, mission, write

from auvsim.config import Config, LocationConfig
from auvsim.data.reader import open_dataset
from auvsim.errors import ConfigError
from auvsim.physics import earth
from auvsim.physics.frames import quaternion_from_euler, rotation_rpy
from auvsim.physics.vehicle import Trajectory
from auvsim.runs.mission import MissionRun
from auvsim.runs.presets import SNAPIR_WATERS, preset

FIELDS = ("truth/position_ned", "truth/velocity_ned", "truth/quaternion", "truth/angular_rate",
          "truth/specific_force", "truth/altitude", "imu/specific_force", "imu/angular_rate",
          "dvl/beam_velocity", "depth/depth")
OMEGA = 7.292115e-5  # rad/s, the Earth's rate (NIMA TR8350.2, table 3.1)


def _earth_rate_body(rpy: tuple[float, float, float], latitude_deg: float) -> np.ndarray:
    """C^T w_ie, written out here: w_ie = Omega (cos lat, 0, -sin lat) in NED."""
    lat = math.radians(latitude_deg)
    w_ie = OMEGA * np.array([math.cos(lat), 0.0, -math.sin(lat)])
    return rotation_rpy(*rpy).T @ w_ie


def _at_rest(latitude_deg: float, depth: float, rpy: tuple[float, float, float],
             seconds: float = 2.0) -> dict[str, np.ndarray]:
    """The fields ``MissionRun.measure`` makes of a vehicle held still at ``depth`` with
    attitude ``rpy`` (rad), with ideal sensors, at ``latitude_deg``: the flat world's
    accelerometer reads -g_model up, as MuJoCo's loop records it."""
    config = flat(location=LocationConfig(latitude_deg=latitude_deg, longitude_deg=34.0))
    run = MissionRun(config, config.missions[0])
    n = round(seconds / run.vehicle.dt)
    rot = rotation_rpy(*rpy)
    g_model = -float(run.vehicle.model.opt.gravity[2])
    rows = lambda v: np.tile(np.asarray(v, float), (n, 1))  # noqa: E731
    traj = Trajectory(rows([0.0, 0.0, depth]), rows([0.0, 0.0, 0.0]), rows([0.0, 0.0, 0.0]),
                      rows(quaternion_from_euler(*rpy)), rows([0.0, 0.0, 0.0]),
                      rows(rot.T @ [0.0, 0.0, -g_model]), rows([0.0, 0.0, 0.0]),
                      np.zeros(n), rows([0.0, 0.0, 0.0]), rows([0.0, 0.0, 0.0]))
    out = run.measure(np.arange(n), traj)
    out["imu_depth"] = depth + (rot @ run.vehicle.imu_position)[2]
    return out


@pytest.mark.parametrize("latitude_deg", [SNAPIR_WATERS.latitude_deg, -60.0, 0.0, 89.0])
def test_a_gyro_at_rest_reads_the_earths_rate_in_body_axes(latitude_deg):
    rpy = (math.radians(10.0), math.radians(-5.0), math.radians(120.0))
    f = _at_rest(latitude_deg, 20.0, rpy)
    gyro = f["imu/angular_rate"]
    np.testing.assert_allclose(gyro.mean(axis=0), _earth_rate_body(rpy, latitude_deg),
                               rtol=0, atol=1e-9)
    assert (gyro == gyro[0]).all()  # the same at every sample: the vehicle does not move
    # 15.04 deg/h whatever the attitude; the truth keeps the rate in the local frame, 0.
    np.testing.assert_allclose(np.degrees(np.linalg.norm(gyro, axis=1)) * 3600.0, 15.041,
                               atol=5e-4)
    assert not f["truth/angular_rate"].any()


@pytest.mark.parametrize("latitude_deg", [SNAPIR_WATERS.latitude_deg, -60.0, 0.0, 89.0])
def test_an_accelerometer_at_rest_reads_the_normal_gravity_at_its_depth(latitude_deg):
    rpy = (math.radians(-20.0), math.radians(8.0), math.radians(-45.0))
    f = _at_rest(latitude_deg, 30.0, rpy)
    g = earth.normal_gravity(latitude_deg, -f["imu_depth"])
    force = f["imu/specific_force"]
    np.testing.assert_allclose(np.linalg.norm(force, axis=1), g, rtol=0, atol=1e-12)
    # Straight up in the body's axes, and what the truth holds (an ideal accelerometer).
    np.testing.assert_allclose(force, np.tile(rotation_rpy(*rpy).T @ [0.0, 0.0, -g],
                                              (len(force), 1)), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(force, f["truth/specific_force"])
    # The International Gravity Formula 1980's series (Moritz 1980), an independent form
    # of the surface value, and the textbook free-air gradient of 3.086e-6 m/s^2 per m.
    s = math.sin(math.radians(latitude_deg))
    surface = 9.780327 * (1 + 0.0053024 * s**2
                          - 0.0000058 * math.sin(math.radians(2 * latitude_deg))**2)
    assert g == pytest.approx(surface + 3.086e-6 * f["imu_depth"], rel=1e-6)


def test_the_snapir_waters_give_the_gravity_the_real_logs_hold():
    # The issue measured a mean |f| of 9.7955 m/s^2 on quiet stretches of the real logs.
    f = _at_rest(SNAPIR_WATERS.latitude_deg, 15.0, (0.0, 0.0, 0.0))
    assert np.linalg.norm(f["imu/specific_force"], axis=1).mean() == pytest.approx(
        9.7955, abs=1e-4)


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """One 30 s turning circle at 2 m/s with ideal sensors, flown in the flat world and in
    the Snapir's waters: (fields by path, attributes) of each."""
    base = flat(mission(name="turning", seed=4, duration=30.0))
    scenario = dataclasses.replace(base.missions[0].scenario, name="turning_circle")
    base = dataclasses.replace(base, missions=(dataclasses.replace(base.missions[0],
                                                                   scenario=scenario),))
    out = {}
    for key, location in (("flat", LocationConfig()), ("earth", SNAPIR_WATERS)):
        path = write(dataclasses.replace(base, location=location),
                     tmp_path_factory.mktemp(key) / f"{key}.h5")
        with open_dataset(path) as d:
            m = d.missions["turning"]
            out[key] = ({k: m.read(k) for k in FIELDS}, dict(m.attrs))
    return out


def test_the_origin_changes_what_the_imu_measures_and_nothing_else(flown):
    (flat_f, flat_a), (earth_f, earth_a) = flown["flat"], flown["earth"]
    for path in FIELDS:  # MuJoCo's motion, the DVL and the depth sensor as before
        if path not in ("truth/specific_force", "imu/specific_force", "imu/angular_rate"):
            np.testing.assert_array_equal(earth_f[path], flat_f[path], err_msg=path)
    assert "latitude_deg" not in flat_a and "longitude_deg" not in flat_a
    assert flat_a["gravity"] == 9.81  # the model's (models/auv.xml)
    assert (earth_a["latitude_deg"], earth_a["longitude_deg"]) == (32.8498, 34.8922)
    assert earth_a["gravity"] == earth.normal_gravity(32.8498, 0.0)
    # An ideal IMU reads the truth, which holds the ideal accelerometer's reading.
    np.testing.assert_array_equal(earth_f["imu/specific_force"], earth_f["truth/specific_force"])


def test_along_a_turn_the_imu_reads_earth_rate_gravity_and_coriolis(flown):
    (flat_f, _), (earth_f, _) = flown["flat"], flown["earth"]
    lat = math.radians(SNAPIR_WATERS.latitude_deg)
    w_ie = OMEGA * np.array([math.cos(lat), 0.0, -math.sin(lat)])
    q = earth_f["truth/quaternion"]
    rot = np.stack([_rotation(row) for row in q[::50]])
    every = slice(None, None, 50)
    gyro = earth_f["imu/angular_rate"][every] - flat_f["imu/angular_rate"][every]
    np.testing.assert_allclose(gyro, np.einsum("nji,j->ni", rot, w_ie), rtol=0, atol=1e-15)
    # f = f_flat + C^T ((g_model - g_n(depth)) e_down + 2 w_ie x v_imu), v_imu = v + C (w x r).
    imu = np.array([0.5, 0.0, 0.0])  # the imu site of models/auv.xml, FRD
    w = earth_f["truth/angular_rate"][every]
    v_imu = earth_f["truth/velocity_ned"][every] + np.einsum("nij,nj->ni", rot, np.cross(w, imu))
    depth = earth_f["truth/position_ned"][every, 2] + (rot @ imu)[:, 2]
    term = 2.0 * np.cross(w_ie, v_imu)
    term[:, 2] += 9.81 - np.array([earth.normal_gravity(SNAPIR_WATERS.latitude_deg, -d)
                                   for d in depth])
    np.testing.assert_allclose(earth_f["truth/specific_force"][every]
                               - flat_f["truth/specific_force"][every],
                               np.einsum("nji,nj->ni", rot, term), rtol=0, atol=1e-12)
    # The Coriolis term is there, -2 Omega sin(lat) v east at the start, where the vehicle
    # runs north (heading 0, level) at 2 m/s: 1.6e-4 m/s^2 (16 micro-g), pointing west, the
    # force that holds a northbound vehicle on its line against the deflection to the
    # right of the northern hemisphere.
    v0 = earth_f["truth/velocity_ned"][0]
    assert abs(v0[0] - 2.0) < 0.05 and abs(v0[1]) < 0.05 and abs(v0[2]) < 0.05
    extra = earth_f["truth/specific_force"][0] - flat_f["truth/specific_force"][0]
    assert extra[1] == pytest.approx(-2.0 * OMEGA * math.sin(lat) * v0[0], rel=0.03)


def _rotation(q: np.ndarray) -> np.ndarray:
    """Body -> NED rotation of a unit quaternion [w, x, y, z], written out here."""
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def test_without_an_origin_the_world_is_flat_and_the_config_says_so():
    config = Config()
    assert not config.location.given
    assert Config.from_json(config.to_json()) == config
    for name in ("paper-sim", "paper-sim-text", "maneuvers"):
        assert not preset(name).location.given, name
    for name in ("navigator", "realistic-maneuvers", "sim2real"):
        assert preset(name).location == SNAPIR_WATERS, name
        assert Config.from_json(preset(name).to_json()) == preset(name)


@pytest.mark.parametrize("settings, message", [
    (dict(latitude_deg=91.0, longitude_deg=0.0), "location.latitude_deg: expected deg in"),
    (dict(latitude_deg=float("nan"), longitude_deg=0.0), "location.latitude_deg"),
    (dict(latitude_deg=30.0, longitude_deg=-181.0), "location.longitude_deg"),
    (dict(latitude_deg=30.0), "location: expected both latitude_deg and longitude_deg"),
    (dict(longitude_deg=30.0), "location: expected both"),
    (dict(latitude_deg="north", longitude_deg=0.0), "location.latitude_deg"),
])
def test_a_bad_origin_is_refused_naming_the_setting(settings, message):
    with pytest.raises(ConfigError, match=message):
        Config.from_dict({"location": settings})


def test_inspect_says_where_a_mission_was_flown(tmp_path):
    from auvsim.data.describe import describe

    config = flat(mission(duration=2.0), location=LocationConfig(latitude_deg=-33.9,
                                                                 longitude_deg=-18.4))
    text = describe(write(config, tmp_path / "cape.h5"))
    assert "gravity 9.79" in text and "at 33.9 deg S, 18.4 deg W (the rotating Earth)" in text


def test_the_earths_terms_do_not_depend_on_how_a_mission_is_split_into_blocks():
    """The environment's 10-step blocks and generate's long ones give the same bits, and
    a second run the same again (the terms are per sample and draw nothing)."""
    config = preset("navigator").with_duration(5.0)

    def fields(block_steps: int) -> dict[str, np.ndarray]:
        run = MissionRun(config, config.missions[0])
        vehicle, dt = run.vehicle, run.vehicle.dt
        vehicle.reset(**run.scenario.initial_state())
        run.scenario.reset()
        steps = np.arange(round(5.0 / dt))
        traj = run.scenario.run(vehicle, steps * dt)
        parts = [run.measure(steps[k:k + block_steps],
                             Trajectory(*(x[k:k + block_steps] for x in traj)))
                 for k in range(0, len(steps), block_steps)]
        return {p: np.concatenate([b[p] for b in parts]) for p in (
            "truth/specific_force", "imu/specific_force", "imu/angular_rate")}

    small, large, again = fields(10), fields(10**6), fields(10)  # 10**6: one block
    for path in small:
        np.testing.assert_array_equal(small[path], large[path], err_msg=path)
        np.testing.assert_array_equal(small[path], again[path], err_msg=path)
