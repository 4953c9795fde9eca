"""Scripted manoeuvres do what their names say, from the same seed the same way."""

from __future__ import annotations

import math

import numpy as np
import pytest

from auvsim.cli import main
from auvsim.config import SCENARIOS, ScenarioConfig
from auvsim.data.reader import open_dataset
from auvsim.errors import ConfigError
from auvsim.physics.maneuvers import MANEUVERS, make_maneuver
from auvsim.physics.vehicle import Vehicle


@pytest.fixture(scope="module")
def vehicle():
    return Vehicle("auv")


def fly(vehicle, name, duration=400.0, speed=2.0, rng=None, **options):
    maneuver = make_maneuver(ScenarioConfig(name=name, speed=speed, depth=20.0,
                                            duration=duration, options=options), rng=rng)
    vehicle.reset(**maneuver.initial_state())
    maneuver.reset()
    t = np.arange(round(duration / vehicle.dt)) * vehicle.dt
    traj = maneuver.run(vehicle, t)
    q = traj.quaternion
    yaw = np.unwrap(np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]),
                               1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2)))
    return t, traj, np.degrees(yaw), maneuver


def test_random_waypoints_refuse_an_unseeded_stream():
    with pytest.raises(ValueError, match="seeded"):
        make_maneuver(ScenarioConfig(name="random_waypoints", duration=600.0))


def test_the_test_library_flies_every_manoeuvre_once_and_the_zigzag_twice():
    from auvsim.physics.maneuvers import missions

    flown = [kind for _, kind, _ in missions()]
    assert set(flown) == set(SCENARIOS) == set(MANEUVERS)
    assert flown.count("zigzag") == 2 and len(flown) == len(MANEUVERS) + 1


def test_turning_circle_heading_advances_monotonically(vehicle):
    t, traj, yaw, _ = fly(vehicle, "turning_circle", lead_s=20.0)
    turning = yaw[t >= 25.0]
    assert np.all(np.diff(turning) > 0)  # to starboard, never back
    assert turning[-1] - turning[0] > 720  # at least two full circles in 375 s
    assert np.max(np.abs(traj.position_ned[:, 2] - 20.0)) < 0.5  # depth held


@pytest.mark.parametrize("angle", [10.0, 20.0])
def test_zigzag_crosses_its_heading_limits(vehicle, angle):
    t, traj, yaw, _ = fly(vehicle, "zigzag", angle_deg=angle, rudder_deg=angle)
    rudder = np.degrees(traj.actuators[:, 1])
    assert abs(yaw[t < 20.0]).max() < 0.5  # straight lead-in
    above, below = yaw > angle, yaw < -angle
    # Crossings of +angle and -angle alternate: count entries into each region.
    assert np.count_nonzero(np.diff(above.astype(int)) == 1) >= 3
    assert np.count_nonzero(np.diff(below.astype(int)) == 1) >= 3
    # The rudder switches only beyond the limits and reaches the commanded angle (under
    # the A18-D's 41 deg rudder limit, both zigzags' rudders are reached).
    assert rudder.max() == pytest.approx(angle, abs=0.01)
    assert rudder.min() == pytest.approx(-angle, abs=0.01)
    switches = np.flatnonzero(np.diff(np.sign(traj.actuators[:, 1][t > 21.0])) != 0)
    assert np.all(np.abs(yaw[t > 21.0][switches]) > angle - 0.5)


def test_depth_step_reaches_the_new_depth(vehicle):
    t, traj, _, _ = fly(vehicle, "depth_steps", step_m=10.0, period_s=150.0, duration=300.0)
    depth = traj.position_ned[:, 2]
    assert np.abs(depth[(t > 120) & (t < 150)] - 20.0).max() < 0.3
    assert np.abs(depth[(t > 270) & (t < 300)] - 30.0).max() < 0.3


def test_speed_step_reaches_the_new_speed(vehicle):
    t, traj, _, _ = fly(vehicle, "speed_steps", low=1.0, period_s=150.0, duration=300.0)
    u = traj.velocity_body[:, 0]
    assert np.abs(u[(t > 100) & (t < 150)] - 2.0).max() < 0.02
    # Down, the hull coasts: with Prestero's drag the surge time constant m / (2 X_uu u) is
    # 23 s at 1.5 m/s, and the speed loop undershoots to 0.73 m/s before it settles.
    assert np.abs(u[(t > 270) & (t < 300)] - 1.0).max() < 0.02


def test_yoyo_descends_and_climbs_between_its_depths(vehicle):
    t, traj, _, m = fly(vehicle, "yoyo", amplitude_m=10.0, period_s=200.0, duration=420.0)
    depth = traj.position_ned[:, 2]
    assert depth.max() == pytest.approx(30.0, abs=1.0)
    assert depth[(t > 210) & (t < 230)].min() == pytest.approx(20.0, abs=1.0)
    assert [p.label for p in m.phases()][:3] == ["level", "descent", "ascent"]


def test_lawnmower_flies_legs_both_ways(vehicle):
    t, _, yaw, m = fly(vehicle, "lawnmower", leg_m=200.0, spacing_m=40.0, duration=400.0)
    legs = [p for p in m.phases() if p.label == "survey leg"]
    end_of_second = legs[1].end - 5.0  # settled on the reverse heading
    assert abs(yaw[np.searchsorted(t, end_of_second)] - 180.0) < 3.0
    assert abs(yaw[np.searchsorted(t, legs[0].end - 1.0)]) < 1.0


def test_a_straight_line_on_survey_lines_has_its_legs_as_phases(vehicle):
    """``straight`` with ``leg_m`` turns at each leg's end: its phases are the legs and
    the cross legs (the turns between them), not one straight phase; without legs, one."""
    t, _, yaw, m = fly(vehicle, "straight", leg_m=200.0, spacing_m=40.0, duration=400.0)
    phases = m.phases()
    assert [p.label for p in phases][:3] == ["survey leg", "cross leg", "survey leg"]
    assert phases[0].start == 0.0 and phases[-1].end == 400.0
    assert all(a.end == b.start for a, b in zip(phases, phases[1:], strict=False))
    legs = [p for p in phases if p.label == "survey leg"]
    assert abs(yaw[np.searchsorted(t, legs[1].end - 5.0)] - 180.0) < 3.0  # it turned
    plain = make_maneuver(ScenarioConfig(name="straight", duration=60.0))
    assert [(p.start, p.end, p.label) for p in plain.phases()] == [(0.0, 60.0, "straight")]


def test_lawnmower_refuses_legs_shorter_than_a_metre_zero_included():
    """0 holds one heading for the manoeuvres flown on survey lines as an option; a
    lawnmower has legs, so it refuses 0 (and a spacing of 0) as it does any leg below 1 m,
    and flies a leg of exactly 1 m."""
    for options, name in (({"leg_m": 0.0}, "leg_m"), ({"leg_m": 0.5}, "leg_m"),
                          ({"leg_m": 0.0, "spacing_m": 0.0}, "leg_m"),
                          ({"spacing_m": 0.0}, "spacing_m")):
        with pytest.raises(ConfigError, match=f"scenario.options.{name}: expected at least 1 m"
                           ) as caught:
            make_maneuver(ScenarioConfig(name="lawnmower", duration=60.0, options=options))
        assert "\n" not in str(caught.value)
    m = make_maneuver(ScenarioConfig(name="lawnmower", duration=60.0,
                                     options={"leg_m": 1.0, "spacing_m": 1.0}))
    assert [p.label for p in m.phases()][:2] == ["survey leg", "cross leg"]


@pytest.mark.parametrize("name, option", [("depth_steps", "step_m"), ("yoyo", "amplitude_m")])
def test_a_depth_change_above_the_surface_is_refused(name, option):
    """From 20 m, a change of -30 m would command -10 m: refused when the manoeuvre is made,
    not at the surface 157 s in with advice about buoyancy; -19 m still flies."""
    with pytest.raises(ConfigError, match=f"scenario.options.{option}: expected a change "
                                          "that keeps the depth below the surface"):
        make_maneuver(ScenarioConfig(name=name, depth=20.0, duration=60.0,
                                     options={option: -30.0}))
    make_maneuver(ScenarioConfig(name=name, depth=20.0, duration=60.0, options={option: -19.0}))


def test_spiral_dive_turns_and_descends(vehicle):
    t, traj, yaw, _ = fly(vehicle, "spiral_dive", dive_m=20.0, descent_rate=0.1)
    assert np.all(np.diff(yaw[t > 30.0]) > 0)
    assert traj.position_ned[-1, 2] == pytest.approx(40.0, abs=1.0)


def test_random_waypoints_are_seeded(vehicle):
    a = make_maneuver(ScenarioConfig(name="random_waypoints", duration=600.0),
                      rng=np.random.default_rng(4))
    b = make_maneuver(ScenarioConfig(name="random_waypoints", duration=600.0),
                      rng=np.random.default_rng(4))
    c = make_maneuver(ScenarioConfig(name="random_waypoints", duration=600.0),
                      rng=np.random.default_rng(5))
    np.testing.assert_array_equal(a.legs, b.legs)
    assert not np.array_equal(a.legs, c.legs)
    # The first leg heads for the first waypoint.
    wx, wy, _ = a.waypoints[0]
    assert a.legs[0, 1] == pytest.approx(math.atan2(wy, wx))


def test_unknown_option_is_refused():
    with pytest.raises(ConfigError, match="unknown option.*angle_deg"):
        ScenarioConfig(name="turning_circle", options={"angle_deg": 10.0})
    with pytest.raises(ConfigError, match="finite number"):
        ScenarioConfig(name="zigzag", options={"angle_deg": "ten"})


def test_generate_a_manoeuvre_and_the_same_seed_twice(tmp_path):
    args = ["generate", "--scenario", "zigzag", "--speed", "2", "--duration", "120",
            "--seed", "3", "--quiet"]
    assert main([*args, "--out", str(tmp_path / "a.h5")]) == 0
    assert main([*args, "--out", str(tmp_path / "b.h5")]) == 0
    with open_dataset(tmp_path / "a.h5") as a, open_dataset(tmp_path / "b.h5") as b:
        m = a.missions[next(iter(a.missions))]
        assert m.attrs["scenario"] == "zigzag"
        assert np.degrees(np.abs(m.control.rudder).max()) > 14.0
        other = b.missions[next(iter(b.missions))]
        np.testing.assert_array_equal(m.dvl.beam_velocity,
                                      other.dvl.beam_velocity)


def test_vehicle_state_is_what_reset_set(vehicle):
    vehicle.reset(position_ned=(1.0, 2.0, 30.0), yaw=0.5, velocity_body=(1.5, 0.0, 0.0))
    state = vehicle.state()
    np.testing.assert_allclose(state["position_ned"], [1.0, 2.0, 30.0], atol=1e-12)
    np.testing.assert_allclose(state["velocity_body"], [1.5, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(state["velocity_ned"][:2], 1.5 * np.array([np.cos(0.5),
                                                                           np.sin(0.5)]))
    assert vehicle.yaw() == pytest.approx(0.5)


def test_euler_angles_are_those_the_vehicle_was_placed_at(vehicle):
    from auvsim.physics.frames import euler_angles

    vehicle.reset(position_ned=(0.0, 0.0, 20.0), roll=0.1, pitch=-0.2, yaw=2.5)
    q = vehicle.state()["quaternion"]
    np.testing.assert_allclose(euler_angles(q), [0.1, -0.2, 2.5], atol=1e-12)
    np.testing.assert_allclose(euler_angles(np.tile(q, (3, 1))), np.tile([0.1, -0.2, 2.5],
                                                                          (3, 1)), atol=1e-12)
