"""The moving water and the motion disturbances (auvsim/water.py), with known answers."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from conftest import flat, mission

from auvsim.cli import main
from auvsim.config import Config, WaterConfig
from auvsim.data.streams import STREAMS
from auvsim.errors import ConfigError
from auvsim.physics.frames import rotation_matrices
from auvsim.physics.vehicle import Vehicle
from auvsim.physics.water import (
    CHANNELS,
    DISTURBANCE_STEP,
    SEGMENT,
    Disturbance,
    Water,
    gauss_markov,
)
from auvsim.runs.mission import MissionRun
from auvsim.runs.presets import NAVIGATOR_WATER, preset

OPEN = (False, False, False)


def uniform(speed: float, direction_deg: float, **changes) -> WaterConfig:
    """A current of one speed and direction everywhere, for ever (unless changed)."""
    return WaterConfig(speed_min=speed, speed_max=speed, direction_deg=direction_deg,
                       profile="piecewise", **changes)


def water(config: WaterConfig, *, seed: int = 0, duration: float = 600.0, **kw) -> Water:
    return Water(config, np.random.default_rng(seed), duration=duration, **kw)


# ---------------------------------------------------------------------------------------
# The current's profile over depth, and the purity of the current
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("depth", [0.0, 20.0, 45.0, 59.0])
def test_power_law_profile_has_its_analytic_value(depth):
    w = water(WaterConfig(speed_min=0.8, speed_max=0.8, direction_deg=30.0,
                          water_depth=60.0))
    c = w.current_ned(np.array([0.0, 100.0]), np.array([[0.0, 0.0, depth]] * 2))
    speed = 0.8 * ((60.0 - depth) / 60.0) ** (1.0 / 7.0)
    expected = speed * np.array([math.cos(math.radians(30)), math.sin(math.radians(30)), 0])
    np.testing.assert_allclose(c, [expected, expected], rtol=1e-14, atol=1e-15)


def test_power_law_is_zero_at_and_below_the_bed_and_the_surface_value_above_the_surface():
    w = water(WaterConfig(speed_min=0.5, speed_max=0.5, water_depth=40.0))
    c = w.current_ned(np.zeros(3), np.array([[0.0, 0.0, 40.0], [0.0, 0.0, 80.0],
                                             [0.0, 0.0, -2.0]]))
    np.testing.assert_array_equal(c[:2], 0.0)
    np.testing.assert_allclose(c[2], [0.5, 0.0, 0.0], rtol=1e-15)


def test_power_law_takes_the_seafloor_depth_unless_given():
    run = MissionRun(flat(mission(duration=10.0), floor=50.0,
                          water=WaterConfig(speed_min=0.3, speed_max=0.3)), mission())
    c = run.water.current_ned(np.zeros(1), np.array([[0.0, 0.0, 25.0]]))
    assert c[0, 0] == pytest.approx(0.3 * 0.5 ** (1 / 7), rel=1e-14)


def test_piecewise_profile_is_linear_between_its_points_and_constant_beyond():
    w = water(uniform(1.0, 90.0, profile_depths=(10.0, 50.0), profile_factors=(1.0, 0.2)))
    z = np.array([0.0, 10.0, 20.0, 50.0, 70.0])
    c = w.current_ned(np.zeros(5), np.c_[np.zeros((5, 2)), z])
    np.testing.assert_allclose(c[:, 1], [1.0, 1.0, 0.8, 0.2, 0.2], rtol=1e-14)
    np.testing.assert_allclose(c[:, [0, 2]], 0.0, atol=1e-16)


def test_constant_current_is_added_and_alone_without_moving_water():
    still = water(WaterConfig(), constant_ned=(0.1, -0.2, 0.0))
    c = still.current_ned(np.arange(3.0), np.zeros((3, 3)))
    np.testing.assert_array_equal(c, [[0.1, -0.2, 0.0]] * 3)
    moving = water(uniform(0.5, 0.0), constant_ned=(0.1, -0.2, 0.0))
    np.testing.assert_allclose(moving.current_ned(np.zeros(1), np.zeros((1, 3))),
                               [[0.6, -0.2, 0.0]], rtol=1e-15)


def test_spatial_modes_have_the_configured_std_over_space():
    # Over many seeds and places, each component's std is spatial_std (8 modes per seed,
    # so the field of one seed is not Gaussian; the ensemble is). The sample std rests on
    # n = 200 seeds x 8 independent amplitudes per component, so its own std is about
    # std / sqrt(2 n); the 50 places per seed (wavelengths apart) add little to it.
    values = []
    for seed in range(200):
        w = water(WaterConfig(spatial_std=0.1, spatial_wavelength=1000.0), seed=seed)
        p = np.random.default_rng(1000 + seed).uniform(-1e5, 1e5, (50, 3))
        p[:, 2] = 0.0
        values.append(w.current_ned(np.zeros(50), p)[:, :2])
    v = np.concatenate(values)
    n = 200 * 8
    for k in range(2):
        assert abs(v[:, k].std() - 0.1) < 3 * 0.1 / math.sqrt(2 * n)


def test_direction_is_drawn_uniformly_in_its_spread():
    directions = [water(WaterConfig(speed_min=0.2, speed_max=0.4, direction_deg=90.0,
                                    direction_spread_deg=45.0), seed=s) for s in range(500)]
    d = np.array([w.direction_deg for w in directions])
    u = np.array([w.surface_speed for w in directions])
    assert 45.0 <= d.min() and d.max() <= 135.0 and 0.2 <= u.min() and u.max() <= 0.4
    # uniform: mean at the centre within 3 sigma (std of a uniform on 90 deg: 90/sqrt(12))
    assert abs(d.mean() - 90.0) < 3 * 90.0 / math.sqrt(12 * len(d))


def test_truth_current_is_what_platform_water_gives_at_the_same_time_and_place():
    # The DVL's water track asks Platform.water; the physics looked up the same function.
    config = flat(mission(duration=30.0), water=NAVIGATOR_WATER)
    run = MissionRun(config, config.missions[0])
    block = next(run.blocks())
    t, p = block["truth/time"], block["truth/position_ned"]
    np.testing.assert_array_equal(run.water.current_ned(t, p), block["truth/current_ned"])
    assert np.abs(block["truth/current_ned"]).max() > 0.01


def test_current_changes_slowly_enough_to_neglect_its_time_derivative():
    # The force of an accelerating flow (Froude-Krylov plus added mass, (m + m_A) dc/dt)
    # is neglected: along the navigator's tracks the water at the vehicle accelerates by
    # about 1e-3 m/s^2 rms, a few N on the A18-D, below the turbulent forces it is
    # given (18 N std in sway) even at its worst.
    config = flat(mission(duration=600.0, name="turning_circle"), water=NAVIGATOR_WATER)
    rates = []
    for seed in range(3):
        m = dataclasses.replace(config.missions[0], seed=seed)
        run = MissionRun(config, m)
        c = np.concatenate([b["truth/current_ned"] for b in run.blocks()])
        rates.append(np.linalg.norm(c[100:] - c[:-100], axis=1) / 1.0)  # over 1 s
    rate = np.concatenate(rates)
    h = run.vehicle.hydro
    force = (h.mass + h.added_mass[1]) * rate
    assert np.sqrt(np.mean(rate**2)) < 2e-3
    assert force.max() < NAVIGATOR_WATER.turbulence_force_std[1]


# ---------------------------------------------------------------------------------------
# The current moves the vehicle
# ---------------------------------------------------------------------------------------


def test_uniform_water_moves_the_vehicle_exactly_as_the_constant_current_does():
    # The same uniform current given the old way (vehicle.current_ned) and the new way
    # (a Water of one speed and direction at every depth): 0.0 + c is c, so the two runs
    # are the same arithmetic, bit for bit.
    c = 0.5 * np.array([math.cos(math.radians(40)), math.sin(math.radians(40)), 0.0])
    runs = []
    for vehicle in (Vehicle("auv", current_ned=tuple(c)),
                    Vehicle("auv", water=water(uniform(0.5, 40.0)))):
        vehicle.reset(position_ned=(0.0, 0.0, 20.0), velocity_body=(1.5, 0.0, 0.0), yaw=0.3)
        vehicle.actuators[:] = (400.0, 0.1, 0.0)
        runs.append(vehicle.run(np.tile((400.0, 0.1, 0.0), (2000, 1)), OPEN))
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(runs[1].current_ned, np.tile(c, (2000, 1)), rtol=1e-15)


def test_the_speed_autopilot_holds_the_speed_through_the_water():
    # A following current of 0.5 m/s: holding 1.5 m/s through the water, the vehicle makes
    # 2.0 m/s over ground (a hold over ground would ask the propeller for 1.0 m/s of flow).
    reference = np.tile((1.5, 0.0, 20.0), (20000, 1))  # speed, heading north, depth
    vehicle = Vehicle("auv", water=water(uniform(0.5, 0.0), duration=200.0))
    vehicle.reset(position_ned=(0.0, 0.0, 20.0), velocity_body=(2.0, 0.0, 0.0))
    run = vehicle.run(reference)
    end = slice(-1000, None)
    assert np.abs(run.velocity_water_body[end, 0] - 1.5).max() < 0.005
    assert np.abs(run.velocity_body[end, 0] - 2.0).max() < 0.005


def test_in_a_steady_current_velocity_over_ground_is_through_water_plus_current():
    # Same rpm, heading and depth held in still water and in a uniform 0.6 m/s current
    # from the side: once settled, the velocity through the water is the still-water
    # one, and the velocity over ground is it plus the current (the crab shows in the
    # body-frame velocity over ground).
    c_dir = 100.0
    current = 0.6 * np.array([math.cos(math.radians(c_dir)), math.sin(math.radians(c_dir)), 0])
    reference = np.tile((450.0, 0.0, 20.0), (30000, 1))  # rpm open loop, heading, depth
    runs = []
    for w in (None, water(uniform(0.6, c_dir), duration=300.0)):
        vehicle = Vehicle("auv", water=w)
        vehicle.reset(position_ned=(0.0, 0.0, 20.0), velocity_body=(1.8, 0.0, 0.0))
        runs.append(vehicle.run(reference, (False, True, True)))
    still, drifting = runs
    end = slice(-1000, None)  # the last 10 s of 300
    rot = rotation_matrices(drifting.quaternion[end])
    ground = drifting.velocity_ned[end]
    through = np.einsum("nij,nj->ni", rot, drifting.velocity_water_body[end])
    np.testing.assert_allclose(ground, through + drifting.current_ned[end], atol=1e-12)
    np.testing.assert_allclose(drifting.velocity_water_body[end], still.velocity_body[end],
                               atol=2e-4)
    np.testing.assert_allclose(ground, still.velocity_ned[end] + current, atol=2e-4)
    crab = math.degrees(math.atan2(drifting.velocity_body[-1, 1], drifting.velocity_body[-1, 0]))
    assert crab > 10.0  # the current pushes it to starboard, seen in the body frame


def test_a_seeds_water_does_not_depend_on_the_missions_duration():
    # A longer mission extends the Gauss-Markov paths of a shorter one: over the first
    # 600 s the water of seed 1 is the same for a 600 s and a 1200 s mission.
    t = np.linspace(0.0, 600.0, 61)
    points = np.column_stack([2.0 * t, -t, np.full_like(t, 20.0)])
    short, long = (water(NAVIGATOR_WATER, seed=1, duration=d).current_ned(t, points)
                   for d in (600.0, 1200.0))
    np.testing.assert_array_equal(short, long)
    assert np.abs(np.diff(short[:, 0])).max() > 0  # the water does vary


def test_the_vehicle_sees_the_current_at_its_own_depth():
    config = flat(mission(duration=20.0, depth=30.0), floor=60.0,
                  water=WaterConfig(speed_min=0.4, speed_max=0.4, direction_deg=-90.0))
    run = MissionRun(config, config.missions[0])
    block = next(run.blocks())
    z = block["truth/position_ned"][:, 2]
    expected = 0.4 * ((60.0 - z) / 60.0) ** (1 / 7)
    np.testing.assert_allclose(block["truth/current_ned"][:, 1], -expected, rtol=1e-12)
    np.testing.assert_allclose(block["truth/current_ned"][:, 0], 0.0, atol=1e-12)


# ---------------------------------------------------------------------------------------
# Gauss-Markov statistics
# ---------------------------------------------------------------------------------------


def _gm_checks(x: np.ndarray, std: float, tau: float, step: float) -> None:
    """Mean, std and lag-1 correlation of an AR(1) sample within 3 sigma of their
    theoretical values (Box & Jenkins: var of the mean sigma^2 (1 + phi) / ((1 - phi) n),
    of the sample variance 2 sigma^4 (1 + phi^2) / ((1 - phi^2) n), of the lag-1
    correlation (1 - phi^2) / n)."""
    n, phi = len(x), math.exp(-step / tau)
    assert abs(x.mean()) < 3 * std * math.sqrt((1 + phi) / ((1 - phi) * n))
    var_sd = std**2 * math.sqrt(2 * (1 + phi**2) / ((1 - phi**2) * n))
    assert abs(x.var() - std**2) < 3 * var_sd
    xc = x - x.mean()
    phi_hat = float(xc[1:] @ xc[:-1] / (xc @ xc))
    assert abs(phi_hat - phi) < 3 * math.sqrt((1 - phi**2) / n)
    tau_hat = -step / math.log(phi_hat)
    assert tau_hat == pytest.approx(tau, rel=0.1)


def test_gauss_markov_path_has_its_std_and_correlation_time():
    x = gauss_markov(np.random.default_rng(7), 400_000, 0.1, 3600.0, 10.0)
    _gm_checks(x, 0.1, 3600.0, 10.0)


def test_current_speed_and_direction_paths_have_their_statistics():
    config = WaterConfig(speed_min=0.5, speed_max=0.5, speed_std=0.1, speed_time=600.0,
                         direction_std_deg=10.0, direction_time=1200.0)
    w = water(config, seed=3, duration=4e6)
    speed = np.hypot(*w.table.surface.T)
    direction = np.degrees(np.arctan2(w.table.surface[:, 1], w.table.surface[:, 0]))
    _gm_checks(speed - 0.5, 0.1, 600.0, 10.0)
    _gm_checks(direction - w.direction_deg, 10.0, 1200.0, 10.0)


def test_disturbance_paths_have_their_statistics_across_segments():
    config = dataclasses.replace(NAVIGATOR_WATER, turbulence_time=2.0, jitter_time=0.8)
    d = Disturbance(config, np.random.default_rng(11))
    base, rows = d.table(0.0, 300 * SEGMENT * DISTURBANCE_STEP)
    assert base == 0 and rows.shape[1] == CHANNELS and len(rows) > 300 * SEGMENT
    stds = [*config.turbulence_force_std, *config.turbulence_moment_std,
            config.rpm_jitter_std, math.radians(config.fin_jitter_std_deg),
            math.radians(config.fin_jitter_std_deg)]
    taus = [config.turbulence_time] * 6 + [config.jitter_time] * 3
    for k in range(CHANNELS):
        _gm_checks(rows[:, k], stds[k], taus[k], DISTURBANCE_STEP)


# ---------------------------------------------------------------------------------------
# Determinism
# ---------------------------------------------------------------------------------------


def test_water_and_disturbance_are_determined_by_the_seed():
    a, b, c = (water(NAVIGATOR_WATER, seed=s) for s in (5, 5, 6))
    np.testing.assert_array_equal(a.table.surface, b.table.surface)
    assert not np.array_equal(a.table.surface, c.table.surface)
    d1, d2 = (Disturbance(NAVIGATOR_WATER, np.random.default_rng(5)) for _ in range(2))
    np.testing.assert_array_equal(d1.table(0, 100)[1], d2.table(0, 100)[1])


def test_disturbed_physics_does_not_depend_on_how_the_mission_is_cut():
    # The disturbances are drawn by segment as time goes on: runs cut into pieces of
    # other lengths (the Kempf zigzag's 0.1 s chunks, the environment's steps) meet the
    # same values, and a reset draws the same paths again.
    def fly(pieces):
        v = Vehicle("auv", water=water(NAVIGATOR_WATER, seed=2),
                    disturbance=Disturbance(NAVIGATOR_WATER, np.random.default_rng(2)))
        out = []
        for _ in range(2):  # twice, with a reset between
            v.reset(position_ned=(0.0, 0.0, 20.0), velocity_body=(2.0, 0.0, 0.0))
            for n in pieces:
                out.append(v.run(np.tile((2.0, 0.0, 20.0), (n, 1)), (True, True, True)))
        return out

    whole, cut = fly([7000]), fly([10, 2990, 4000])
    for k in range(2):
        joined = np.concatenate([t.angular_rate for t in cut[3 * k:3 * k + 3]])
        np.testing.assert_array_equal(whole[k].angular_rate, joined)
    np.testing.assert_array_equal(whole[0].position_ned, whole[1].position_ned)


def test_missions_with_the_same_seed_are_the_same_and_new_streams_are_appended():
    assert STREAMS[-2:] == ("water", "disturbance")
    config = flat(mission(duration=20.0), water=NAVIGATOR_WATER)
    blocks = [next(MissionRun(config, config.missions[0]).blocks()) for _ in range(2)]
    for key in blocks[0]:
        np.testing.assert_array_equal(blocks[0][key], blocks[1][key])


def test_disturbances_make_a_straight_line_not_straight():
    # Without them the yaw rate is 1e-11 rad/s after the first minute (issue 10).
    rates = []
    for w in (WaterConfig(), dataclasses.replace(
            WaterConfig(), turbulence_force_std=NAVIGATOR_WATER.turbulence_force_std,
            turbulence_moment_std=NAVIGATOR_WATER.turbulence_moment_std,
            rpm_jitter_std=2.0, fin_jitter_std_deg=0.2)):
        config = flat(mission(duration=120.0), water=w)
        run = MissionRun(config, config.missions[0])
        block = list(run.blocks())[-1]
        rates.append(np.abs(block["truth/angular_rate"][-3000:, 2]).max())
        speed = block["truth/velocity_body"][-3000:, 0]
    assert rates[0] < 1e-8 and rates[1] > 1e-3
    assert 1e-4 < speed.std() < 0.05  # the speed wanders by mm/s to cm/s


# ---------------------------------------------------------------------------------------
# Config: defaults, backward compatibility, bad values
# ---------------------------------------------------------------------------------------


def test_defaults_are_still_water_and_old_configs_load():
    old = json.loads(preset("paper-sim").to_json())
    del old["water"]  # a config written before the section existed
    config = Config.from_json(json.dumps(old))
    assert config.water == WaterConfig()
    d = Disturbance(config.water, np.random.default_rng(0))
    assert not d.active and not water(config.water).table.active
    navigator = preset("navigator")
    assert Config.from_json(navigator.to_json()) == navigator


BAD_WATER = [
    ("speed_min", -0.1), ("speed_min", 0.6), ("speed_max", 3.5), ("speed_max", math.nan),
    ("direction_deg", 400.0), ("direction_spread_deg", 190.0), ("speed_std", -1.0),
    ("speed_time", 10.0), ("direction_std_deg", -5.0), ("direction_time", 0.0),
    ("spatial_std", 5.0), ("spatial_wavelength", 10.0), ("profile", "log"),
    ("power_exponent", 2.0), ("water_depth", 0.0), ("water_depth", "deep"),
    ("profile_depths", (10.0, 5.0)), ("profile_depths", ()), ("profile_factors", (1.0, 0.5)),
    ("profile_factors", (3.0,)), ("turbulence_force_std", (1.0, 2.0)),
    ("turbulence_force_std", (-1.0, 0.0, 0.0)), ("turbulence_moment_std", (0, 0, 1e4)),
    ("turbulence_time", 0.01), ("rpm_jitter_std", -2.0), ("rpm_jitter_std", 1e3),
    ("fin_jitter_std_deg", 10.0), ("jitter_time", math.inf),
]


def test_every_water_setting_has_a_bad_value_case():
    assert {name for name, _ in BAD_WATER} == {f.name for f in dataclasses.fields(WaterConfig)}


@pytest.mark.parametrize("name,value", BAD_WATER)
def test_bad_water_values_are_refused_naming_the_field(name, value):
    base = dict(speed_max=0.5) if name == "speed_min" else {}
    with pytest.raises(ConfigError) as e:
        WaterConfig(**{**base, name: value})
    message = str(e.value)
    assert message.startswith(f"water.{name}:") and "\n" not in message
    assert "expected" in message and "got" in message


def test_a_bad_water_config_file_gives_one_line_and_exit_2(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text("[water]\nspeed_max = 9.0\n[[missions]]\n"
                                       "[missions.scenario]\nduration = 5\n")
    assert main(["generate", "--config", "bad.toml", "--out", "x.h5", "--quiet"]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "water.speed_max" in err and "Traceback" not in err


def test_the_water_and_the_seafloor_or_the_constant_current_together():
    # Over a heightmap the power law needs its water depth, and the constant current and
    # the water's own together stay within MAX_CURRENT: one line each, naming the field.
    from auvsim.config import SeafloorConfig, VehicleConfig

    moving = WaterConfig(speed_min=0.5, speed_max=0.5)
    heightmap = SeafloorConfig(kind="heightmap", heightmap="map.npy")
    with pytest.raises(ConfigError, match=r"^water.water_depth: expected the water depth H"):
        Config(water=moving, seafloor=heightmap)
    Config(water=dataclasses.replace(moving, water_depth=80.0), seafloor=heightmap)
    with pytest.raises(ConfigError, match=r"^water.speed_max: expected a current of at most "
                                          r"3 m/s with vehicle.current_ned added"):
        Config(water=WaterConfig(speed_min=1.0, speed_max=1.5),
               vehicle=VehicleConfig(current_ned=(2.0, 0.0, 0.0)))
