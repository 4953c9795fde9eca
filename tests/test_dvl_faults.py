"""The DVL losing bottom lock and erring as a real one does (issue 10, items 3 and 4):
known answers for every effect, and every effect off giving the idealised data."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from conftest import flat, mission

from auvsim.config import Config, DvlConfig, SeafloorConfig
from auvsim.errors import ConfigError
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from auvsim.runs import mission as mission_module
from auvsim.runs.mission import MissionRun
from auvsim.sensors.dvl import (
    DvlErrors,
    Effects,
    Mode,
    Status,
    beam_matrix,
    beam_noise_std,
    error_velocity,
    lock_status,
    logistic,
    markov_dropouts,
    ping,
)
from auvsim.world.seafloor import Seafloor

H30 = beam_matrix(math.radians(30))


def fly(dvl: DvlConfig, duration: float = 120.0, *, water=None, seafloor=None,
        **scenario) -> tuple[MissionRun, dict]:
    """A straight mission at 20 m over a 60 m flat floor (or ``seafloor``) with this DVL
    and ideal other sensors; ``water`` (an object with ``current_ned``) stands in for the
    platform's water. Returns the run and its fields, concatenated over blocks."""
    config = flat(mission(duration=duration, depth=20.0, **scenario), dvl=dvl)
    if seafloor is not None:
        config = dataclasses.replace(config, seafloor=seafloor)
    run = MissionRun(config, config.missions[0])
    if water is not None:
        sensor = next(s for s in run.sensors if s.name == "dvl")
        sensor.platform = sensor.platform._replace(water=water)
    blocks = list(run.blocks())
    return run, {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


def burst_lengths(bad: np.ndarray) -> np.ndarray:
    """Lengths of the runs of True in a 1-D bool array."""
    edges = np.diff(np.concatenate([[0], bad.astype(int), [0]]))
    return np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)


# -- lost bottom lock -------------------------------------------------------------------


@pytest.mark.parametrize("rate,burst", [(0.2, 5.0), (0.05, 1.5), (0.4, 1.0)])
def test_dropouts_have_the_configured_rate_and_mean_burst_length(rate, burst):
    """Over 200,000 pings per beam, the share in a burst and the mean burst length match
    the config within 3 sigma. For the chain's mean, sigma^2 = r (1 - r) / N (1 + l) /
    (1 - l), l = 1 - p_enter - p_leave its second eigenvalue; a burst's length is
    geometric with variance b (b - 1). (0.4, 1.0) is the case where a ping whose two
    thresholds disagree flips the state instead of keeping it."""
    n = 200_000
    u = np.random.default_rng(7).random((n, 4))
    bad = markov_dropouts(u, np.zeros(4, dtype=bool), rate=rate, burst=burst)
    p_enter, p_leave = rate / (burst * (1 - rate)), 1 / burst
    lam = 1 - p_enter - p_leave
    sigma = math.sqrt(rate * (1 - rate) / n * (1 + lam) / (1 - lam))
    assert np.all(np.abs(bad.mean(axis=0) - rate) < 3 * sigma)
    lengths = np.concatenate([burst_lengths(bad[:, k]) for k in range(4)])
    assert abs(lengths.mean() - burst) < 3 * math.sqrt(burst * (burst - 1) / len(lengths)) + 1e-12


def test_the_dropout_chain_is_the_chain_and_carries_over_blocks():
    rng = np.random.default_rng(3)
    for rate, burst in ((0.3, 4.0), (0.45, 1.2)):
        u = rng.random((500, 4))
        state = rng.random(4) < 0.5
        p_enter, p_stay = rate / (burst * (1 - rate)), 1 - 1 / burst
        expected, s = [], state.copy()
        for row in u:  # the chain, ping by ping
            s = np.where(s, row < p_stay, row < p_enter)
            expected.append(s)
        whole = markov_dropouts(u, state, rate=rate, burst=burst)
        np.testing.assert_array_equal(whole, np.array(expected))
        first = markov_dropouts(u[:123], state, rate=rate, burst=burst)
        rest = markov_dropouts(u[123:], first[-1], rate=rate, burst=burst)
        np.testing.assert_array_equal(np.concatenate([first, rest]), whole)


def test_echo_loss_and_grazing_loss_follow_their_logistic_curves():
    n = 100_000
    rng = np.random.default_rng(5)
    config = DvlConfig(echo_loss_range=60.0, echo_loss_width=4.0, max_range=90.0,
                       grazing_loss_angle_deg=50.0, grazing_loss_width_deg=3.0)
    time = np.arange(n, dtype=float)
    # Each beam at its own range: 1/2 at the middle, 1/(1 + e^-1) one width beyond.
    ranges = np.tile([60.0, 64.0, 56.0, 30.0], (n, 1))
    incidence = np.full((n, 4), 30.0)
    status = lock_status(time, ranges, config=config, incidence_deg=incidence,
                         u=rng.random((n, 9)), dropout=np.zeros((n, 4), dtype=bool))
    expected = np.array([0.5, 1 / (1 + math.exp(-1)), 1 / (1 + math.exp(1)),
                         1 / (1 + math.exp(30 / 4))])
    lost = (status == Status.ECHO_LOST).mean(axis=0)
    assert np.all(np.abs(lost - expected) < 3 * np.sqrt(expected * (1 - expected) / n) + 1e-9)
    np.testing.assert_allclose(logistic(np.array([60.0, 64.0]), 60.0, 4.0), expected[:2],
                               rtol=1e-15)
    # Grazing: 1/2 at 50 deg; the echo's loss comes first only where both apply.
    incidence[:, 0] = 50.0
    ranges[:] = 10.0
    status = lock_status(time, ranges, config=config, incidence_deg=incidence,
                         u=rng.random((n, 9)), dropout=np.zeros((n, 4), dtype=bool))
    grazing = (status == Status.GRAZING).mean(axis=0)
    assert abs(grazing[0] - 0.5) < 3 * math.sqrt(0.25 / n)
    p30 = 1 / (1 + math.exp(20 / 3))  # 30 deg: 0.13 %
    assert np.all(np.abs(grazing[1:] - p30) < 3 * math.sqrt(p30 * (1 - p30) / n))


def test_reason_codes_in_their_order_and_ping_dropouts_at_their_rate():
    n = 50_000
    config = DvlConfig(min_range=1.0, max_range=90.0, ping_dropout_rate=0.1,
                       beam_failures=((2, 10.0, 20.0),), lock_loss_intervals=((15.0, 30.0),))
    time = np.arange(n) * 0.5
    ranges = np.tile([np.nan, 0.5, 40.0, 40.0], (n, 1))
    dropout = np.zeros((n, 4), dtype=bool)
    dropout[:, 3] = True
    u = np.random.default_rng(9).random((n, 9))
    status = lock_status(time, ranges, config=config, incidence_deg=None, u=u,
                         dropout=dropout)
    lost = u[:, 8] < 0.1
    assert abs(lost.mean() - 0.1) < 3 * math.sqrt(0.09 / n)
    np.testing.assert_array_equal(status[lost], Status.PING_DROPOUT)
    kept = ~lost
    failed, soft = (time >= 10) & (time < 20), (time >= 15) & (time < 30)
    np.testing.assert_array_equal(status[kept, 0], Status.NO_HIT)
    np.testing.assert_array_equal(status[kept, 1], Status.TOO_NEAR)
    np.testing.assert_array_equal(status[kept & failed, 2], Status.BEAM_FAILED)
    np.testing.assert_array_equal(status[kept & soft & ~failed, 2], Status.LOCK_LOST)
    np.testing.assert_array_equal(status[kept & ~soft & ~failed, 2], Status.OK)
    np.testing.assert_array_equal(status[kept & soft, 3], Status.LOCK_LOST)
    np.testing.assert_array_equal(status[kept & ~soft, 3], Status.DROPOUT)


def test_seafloor_normals_are_the_slope_and_the_surface_gradient():
    flat_floor = Seafloor(SeafloorConfig(kind="flat", depth=50.0))
    np.testing.assert_array_equal(flat_floor.normal_at(np.zeros(3), np.ones(3)),
                                  np.tile([0.0, 0.0, -1.0], (3, 1)))
    slope, heading = math.radians(20), math.radians(60)
    plane = Seafloor(SeafloorConfig(kind="procedural", depth=60.0, roughness=0.0,
                                    slope_deg=20.0, slope_heading_deg=60.0),
                     rng=np.random.default_rng(0))
    north, east = np.random.default_rng(1).uniform(-200, 200, (2, 50))
    expected = np.array([math.sin(slope) * math.cos(heading),
                         math.sin(slope) * math.sin(heading), -math.cos(slope)])
    # The heights are float32 (7 digits) over about 400 m of relief: about 3e-5 m per
    # vertex, over 2 m cells.
    np.testing.assert_allclose(plane.normal_at(north, east), np.tile(expected, (50, 1)),
                               atol=1e-5)
    rough = Seafloor(SeafloorConfig(kind="procedural", depth=60.0, roughness=2.0,
                                    correlation_length=10.0), rng=np.random.default_rng(2))
    # Inside a triangle the depth is linear: its gradient from small steps is the normal's.
    n0, e0, step = north + 0.1, east + 0.1, 1e-3
    d = rough.depth_at(n0, e0)
    gradient = np.stack([(rough.depth_at(n0 + step, e0) - d) / step,
                         (rough.depth_at(n0, e0 + step) - d) / step, -np.ones(50)], axis=1)
    normal = rough.normal_at(n0, e0)
    same = np.abs(np.cross(normal, gradient)).max(axis=1) < 1e-6 * np.linalg.norm(gradient, axis=1)
    assert same.mean() > 0.9  # the few steps that cross a triangle's edge excepted
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1.0, atol=1e-14)


def test_a_mission_loses_lock_as_configured():
    """A beam fails, every beam loses lock in an interval (no water track: no velocity),
    and over a rough floor at a low grazing threshold beams are lost to grazing."""
    dvl = DvlConfig(rate_hz=5.0, beam_failures=((1, 20.0, 40.0),),
                    lock_loss_intervals=((50.0, 60.0),), dropout_rate=0.1, dropout_burst=3.0,
                    ping_dropout_rate=0.05)
    _, data = fly(dvl, 80.0)
    t, status, valid, mode = (data["dvl/time"], data["dvl/status"], data["dvl/valid"],
                              data["dvl/mode"])
    lost = (status == Status.PING_DROPOUT).any(axis=1)
    np.testing.assert_array_equal(status[lost], Status.PING_DROPOUT)  # whole pings
    assert abs(lost.mean() - 0.05) < 3 * math.sqrt(0.05 * 0.95 / len(t))
    failed = (t >= 20) & (t < 40) & ~lost
    soft = (t >= 50) & (t < 60) & ~lost
    np.testing.assert_array_equal(status[failed, 1], Status.BEAM_FAILED)
    np.testing.assert_array_equal(status[soft], Status.LOCK_LOST)
    np.testing.assert_array_equal(mode[soft | lost], Mode.NO_VELOCITY)
    assert np.isnan(data["dvl/velocity_ls"][soft | lost]).all()
    np.testing.assert_array_equal(valid, (status == Status.OK) | (status == Status.OUTLIER))
    np.testing.assert_array_equal(mode, np.where(valid.sum(axis=1) >= 3, 0, -1))
    # With three beams the ideal DVL still solves the velocity exactly.
    three = failed & (valid.sum(axis=1) == 3)
    assert three.any()
    np.testing.assert_allclose(data["dvl/velocity_ls"][three], data["dvl/velocity"][three],
                               atol=1e-12)
    assert np.isnan(data["dvl/error_velocity"][three]).all()
    dropped = (status[~failed & ~soft & ~lost & ((t < 20) | (t >= 40))]
               == Status.DROPOUT).mean()
    assert 0.04 < dropped < 0.16  # 10 % of 1200 beam-pings in bursts of 3: sigma 0.02

def test_beams_facing_down_a_slope_are_lost_to_grazing():
    """Flying north, level, over a plane that deepens northward at 20 deg: the seafloor's
    upward normal is (sin 20, 0, -cos 20), so the forward beams (azimuth 45 and 315 deg,
    30 deg off vertical) meet it at acos(cos 30 cos 20 - sin 30 cos 45 sin 20) = 46.1 deg
    and the aft ones at acos(cos 30 cos 20 + sin 30 cos 45 sin 20) = 20.8 deg. With the
    loss at 1/2 at 40 deg over 0.5 deg, the forward beams are lost and the aft ones kept
    (both to within about 1e-5)."""
    slope = SeafloorConfig(kind="procedural", depth=60.0, roughness=0.0, slope_deg=20.0,
                           slope_heading_deg=0.0)
    _, data = fly(DvlConfig(grazing_loss_angle_deg=40.0, grazing_loss_width_deg=0.5), 30.0,
                  seafloor=slope)
    s30, c30, s20, c20 = (math.sin(math.radians(30)), math.cos(math.radians(30)),
                          math.sin(math.radians(20)), math.cos(math.radians(20)))
    forward = math.degrees(math.acos(c30 * c20 - s30 * math.sqrt(0.5) * s20))
    aft = math.degrees(math.acos(c30 * c20 + s30 * math.sqrt(0.5) * s20))
    assert forward == pytest.approx(46.1, abs=0.05) and aft == pytest.approx(20.8, abs=0.05)
    status = data["dvl/status"]
    np.testing.assert_array_equal(status[:, [0, 3]], Status.GRAZING)
    np.testing.assert_array_equal(status[:, [1, 2]], Status.OK)
    np.testing.assert_array_equal(data["dvl/mode"], Mode.NO_VELOCITY)


# -- measurement errors -----------------------------------------------------------------


def effects(m: int, **changes) -> Effects:
    """No effect beyond eq. 7, for m pings, with ``changes``."""
    base = dict(status=np.zeros((m, 4), dtype=np.int64), sound_speed_ratio=1.0,
                extra_noise=None, outlier=np.zeros((m, 4), dtype=bool),
                outlier_error=np.zeros((m, 4)), water_velocity=None,
                water_lock=np.zeros((m, 4), dtype=bool), water_noise=np.zeros((m, 4)))
    return Effects(**{**base, **changes})


def test_every_effect_off_gives_the_eq7_pipeline_bit_for_bit():
    rng = np.random.default_rng(4)
    v = rng.normal(size=(300, 3))
    lock = rng.random((300, 4)) < 0.8
    errors = DvlErrors(np.array([0.01, -0.02, 0.0, 0.003]), np.array([1e-3, 0, 2e-3, 0]))
    plain = ping(v, lock, h=H30, errors=errors, noise_std=0.02, rng=np.random.default_rng(1))
    full = ping(v, lock, h=H30, errors=errors, noise_std=0.02, rng=np.random.default_rng(1),
                effects=effects(300, status=np.where(lock, 0, 1)))
    for name, values in plain.items():
        np.testing.assert_array_equal(full[name], values, err_msg=name)
    np.testing.assert_array_equal(full["status"], np.where(lock, Status.OK, Status.NO_HIT))
    np.testing.assert_array_equal(full["mode"], np.where(lock.sum(axis=1) >= 3, 0, -1))


def test_every_effect_off_in_a_mission_is_the_idealised_dvl(monkeypatch):
    """Defaults and explicitly-off settings give the same mission; the ideal DVL reads
    H v on every beam, LS gives the truth, the error velocity is 0 up to rounding, and
    blocks of any length give the same pings."""
    off = DvlConfig(noise_std=0.01, echo_loss_range=None, grazing_loss_angle_deg=None,
                    dropout_rate=0.0, ping_dropout_rate=0.0, beam_failures=(),
                    lock_loss_intervals=(), noise_range_coeff=0.0, noise_speed_coeff=0.0,
                    outlier_rate=0.0, sound_speed_std=0.0, misalignment_std_deg=0.0,
                    water_track=False)
    run, data = fly(off, 60.0)
    _, default = fly(DvlConfig(noise_std=0.01), 60.0)
    for name in data:
        np.testing.assert_array_equal(data[name], default[name], err_msg=name)
    np.testing.assert_array_equal(data["dvl/status"], Status.OK)
    np.testing.assert_array_equal(data["dvl/mode"], Mode.BOTTOM_TRACK)
    assert run.attrs["dvl_sound_speed_ratio"] == 1.0
    _, ideal = fly(DvlConfig(), 60.0)
    np.testing.assert_array_equal(ideal["dvl/beam_velocity"], ideal["dvl/beam_velocity_true"])
    speed = np.linalg.norm(ideal["dvl/velocity"], axis=1)
    assert np.all(np.abs(ideal["dvl/error_velocity"]) <= 4e-16 * speed)
    # Blocks of 5 s instead of 60 s: the same draws, the same dropout chain.
    everything = DvlConfig(rate_hz=5.0, noise_std=0.01, dropout_rate=0.2, dropout_burst=4.0,
                           ping_dropout_rate=0.05, outlier_rate=0.05, outlier_std=0.3,
                           noise_speed_coeff=0.01, echo_loss_range=45.0)
    _, long_blocks = fly(everything, 30.0)
    monkeypatch.setattr(mission_module, "BLOCK_SECONDS", 5.0)
    _, short_blocks = fly(everything, 30.0)
    for name in long_blocks:
        if name.startswith("dvl/") and name != "dvl/velocity_ls":
            np.testing.assert_array_equal(short_blocks[name], long_blocks[name], err_msg=name)
    # LS on a group of pings is a matrix product, whose rounding BLAS may vary with the
    # number of rows (it did before these effects, for three-beam pings).
    np.testing.assert_allclose(short_blocks["dvl/velocity_ls"], long_blocks["dvl/velocity_ls"],
                               rtol=0, atol=1e-15)


def test_error_velocity_has_the_analytic_std_with_white_noise():
    """std(e) = sigma / (sqrt(2) sin(alpha)): d^2 (4 sigma^2) with d = 1 / (2 sqrt(2) sin a);
    the sample std of N normals is within sigma / sqrt(2 N) per sigma of it."""
    n, sigma = 200_000, 0.02
    for alpha in (20.0, 30.0):
        h = beam_matrix(math.radians(alpha))
        v = np.random.default_rng(2).normal(size=(n, 3))
        y = v @ h.T + sigma * np.random.default_rng(3).standard_normal((n, 4))
        e = error_velocity(y, h)
        expected = sigma / (math.sqrt(2) * math.sin(math.radians(alpha)))
        assert abs(e.std() - expected) < 3 * expected / math.sqrt(2 * n)
        assert abs(e.mean()) < 3 * expected / math.sqrt(n)
        # Beam 1 and 3 (and 2 and 4) are the opposite pairs: their sums are 2 cos(a) w.
        np.testing.assert_allclose(h[0] + h[2], [0, 0, 2 * math.cos(math.radians(alpha))],
                                   atol=1e-16)
    one_missing = np.array([[0.1, 0.2, np.nan, 0.3]])
    assert np.isnan(error_velocity(one_missing, H30)).all()


def test_sound_speed_ratio_scales_the_beams_exactly():
    run, data = fly(DvlConfig(sound_speed_std=0.01), 30.0, speed=1.5)
    ratio = run.attrs["dvl_sound_speed_ratio"]
    assert ratio != 1.0 and abs(ratio - 1) < 0.05
    np.testing.assert_array_equal(data["dvl/beam_velocity"],
                                  data["dvl/beam_velocity_true"] / ratio)
    # The beams of a piston-transducer DVL, and so its LS velocity, scale by the ratio.
    np.testing.assert_allclose(data["dvl/velocity_ls"] * ratio, data["dvl/velocity"],
                               rtol=1e-12, atol=1e-13)


def test_noise_grows_with_speed_and_range_as_configured():
    ranges = np.array([[10.0, 20.0, np.nan, 0.0]])
    config = DvlConfig(noise_std=0.01, noise_range_coeff=1e-4, noise_speed_coeff=0.002)
    np.testing.assert_allclose(beam_noise_std(ranges, np.array([2.0]), config),
                               [[0.01 + 1e-3 + 4e-3, 0.01 + 2e-3 + 4e-3, 0.014, 0.014]],
                               rtol=1e-14)
    # A mission: the beams' residual std is 0.005 + 1e-4 r + 0.01 |v| within 3 sigma.
    dvl = DvlConfig(rate_hz=10.0, noise_std=0.005, noise_range_coeff=1e-4,
                    noise_speed_coeff=0.01)
    _, data = fly(dvl, 150.0, speed=2.0)
    late = data["dvl/time"] > 30  # at speed
    residual = (data["dvl/beam_velocity"] - data["dvl/beam_velocity_true"])[late]
    std = beam_noise_std(data["dvl/beam_range"][late],
                         np.linalg.norm(data["dvl/velocity"][late], axis=1), dvl)
    z = residual / std
    n = z.size
    assert abs(z.std() - 1) < 3 / math.sqrt(2 * n)
    assert abs(z.mean()) < 3 / math.sqrt(n)
    assert 0.005 + 0.004 + 0.019 < std.mean() < 0.005 + 0.006 + 0.021  # 46 m, 2 m/s


def test_outliers_come_at_their_rate_with_their_size_and_are_labelled():
    dvl = DvlConfig(rate_hz=10.0, outlier_rate=0.05, outlier_std=0.5)
    _, data = fly(dvl, 150.0)
    status = data["dvl/status"]
    outlier = status == Status.OUTLIER
    n = status.size
    assert abs(outlier.mean() - 0.05) < 3 * math.sqrt(0.05 * 0.95 / n)
    error = data["dvl/beam_velocity"] - data["dvl/beam_velocity_true"]
    np.testing.assert_array_equal(error[~outlier], 0.0)  # an otherwise ideal DVL
    # Student t, 3 degrees of freedom, scaled to std 0.5: its median |error| is
    # 0.5 / sqrt(3) * 0.7649 (t3's upper quartile); heavy tails: kurtosis above a normal's.
    size = np.abs(error[outlier])
    assert abs(np.median(size) / (0.5 / math.sqrt(3) * 0.7649) - 1) < 0.15
    assert np.mean(size**4) / np.mean(size**2) ** 2 > 3.5
    assert data["dvl/valid"][outlier].all()


def test_misalignment_turns_the_true_dvl_frame_and_keeps_the_nominal_attribute():
    dvl = DvlConfig(misalignment_std_deg=2.0, mounting_rpy_deg=(0.0, 0.0, 45.0))
    run, data = fly(dvl, 20.0)
    attrs = run.attrs
    np.testing.assert_array_equal(attrs["dvl_mounting_rpy_deg"], [0.0, 0.0, 45.0])
    misalignment = attrs["dvl_misalignment_rpy_deg"]
    assert np.all(misalignment != 0) and np.all(np.abs(misalignment) < 8.0)
    true_mounting = rotation_rpy(*np.radians([0, 0, 45])) @ rotation_rpy(*np.radians(misalignment))
    at = data["imu/index_of_dvl"]
    lever = np.asarray(attrs["dvl_position_body"])
    v_point = data["truth/velocity_body"][at] + np.cross(data["truth/angular_rate"][at], lever)
    np.testing.assert_allclose(data["dvl/velocity"], v_point @ true_mounting, atol=1e-12)
    # The ranges are cast along the true beams: level flight over a flat floor, each beam
    # at altitude / (its true direction's down component).
    rotation = rotation_matrices(data["truth/quaternion"][at])
    down = np.einsum("mij,kj->mki", rotation, H30 @ true_mounting.T)[..., 2]
    altitude = 60.0 - (data["truth/position_ned"][at, 2] + (rotation @ lever)[:, 2])
    np.testing.assert_allclose(data["dvl/beam_range"], altitude[:, None] / down, rtol=1e-9)


class UniformCurrent:
    """A stand-in for the platform's water: one current everywhere, always."""

    def __init__(self, current_ned):
        self.current = np.asarray(current_ned, dtype=float)
        self.asked = []

    def current_ned(self, time, position_ned):
        assert time.ndim == 1 and position_ned.shape == (len(time), 3)
        self.asked.append(position_ned)
        return np.tile(self.current, (len(time), 1))


def test_water_track_beams_are_h_times_velocity_relative_to_the_water():
    # ping: exactly H (v - v_water) on the water-track pings, with eq. 7's noise replaced.
    rng = np.random.default_rng(6)
    v, water = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    lock = np.zeros((50, 4), dtype=bool)
    lock[:25] = True
    zero = DvlErrors(np.zeros(4), np.zeros(4))
    out = ping(v, lock, h=H30, errors=zero, noise_std=0.0, rng=rng,
               effects=effects(50, status=np.where(lock, 0, 8), water_velocity=water,
                               water_lock=np.ones((50, 4), dtype=bool)))
    np.testing.assert_array_equal(out["mode"], np.repeat([0, 1], 25))
    np.testing.assert_array_equal(out["beam_velocity"][25:], (v - water)[25:] @ H30.T)
    np.testing.assert_array_equal(out["beam_velocity"][:25], v[:25] @ H30.T)
    assert out["valid"].all()
    # A mission: lock lost for 10 s over a 0.3 m/s current to the east.
    current = UniformCurrent([0.0, 0.3, 0.0])
    dvl = DvlConfig(rate_hz=2.0, lock_loss_intervals=((10.0, 20.0),), water_track=True,
                    water_track_range=8.0)
    run, data = fly(dvl, 30.0, water=current)
    t, mode = data["dvl/time"], data["dvl/mode"]
    soft = (t >= 10) & (t < 20)
    np.testing.assert_array_equal(mode, np.where(soft, Mode.WATER_TRACK, Mode.BOTTOM_TRACK))
    np.testing.assert_array_equal(data["dvl/status"][soft], Status.LOCK_LOST)
    assert data["dvl/valid"].all()
    at = data["imu/index_of_dvl"]
    rotation = rotation_matrices(data["truth/quaternion"][at])
    v_water = np.einsum("mji,j->mi", rotation, current.current)  # body = DVL frame here
    relative = data["dvl/velocity"] - v_water
    np.testing.assert_allclose(data["dvl/beam_velocity"][soft], relative[soft] @ H30.T,
                               atol=1e-14)
    np.testing.assert_allclose(data["dvl/velocity_ls"][soft], relative[soft], atol=1e-13)
    # The layer asked for lies water_track_range below the DVL, at every ping.
    origin = data["truth/position_ned"][at] + rotation @ run.attrs["dvl_position_body"]
    np.testing.assert_allclose(np.concatenate(current.asked), origin + [0.0, 0.0, 8.0],
                               atol=1e-12)


def test_a_bad_fault_setting_exits_2_with_one_line(tmp_path, capsys):
    from auvsim.cli import main

    config = tmp_path / "bad.toml"
    config.write_text("[dvl]\ndropout_rate = 0.7\n")
    assert main(["generate", "--config", str(config), "--out", str(tmp_path / "x.h5"),
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "dvl.dropout_rate: expected" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "x.h5").exists()


def test_inspect_shows_the_calibration_the_lost_lock_and_the_modes(tmp_path, capsys):
    from conftest import write

    from auvsim.cli import main

    dvl = DvlConfig(sound_speed_std=0.01, lock_loss_intervals=((5.0, 10.0),))
    path = write(flat(mission(duration=20.0), dvl=dvl), tmp_path / "f.h5")
    assert main(["inspect", str(path)]) == 0
    text = capsys.readouterr().out
    assert "DVL calibration: sound-speed ratio " in text
    assert "DVL beam status: ok 75.0 %, lock_lost 25.0 %" in text
    assert "DVL modes: no velocity 25.0 %, bottom track 75.0 %, water track 0.0 %" in text
    # What the config turns on and no attribute records: said, and only that.
    assert "    DVL effects (config): lock lost 5-10 s\n" in text


def test_config_effects_name_every_effect_the_config_turns_on():
    from auvsim.sensors.dvl import config_effects

    c = DvlConfig(noise_speed_coeff=0.002, noise_range_coeff=1e-4, echo_loss_range=80.0,
                  grazing_loss_angle_deg=60.0, dropout_rate=0.02, dropout_burst=3.0,
                  ping_dropout_rate=0.005, beam_failures=((2, 300.0, 360.0),),
                  lock_loss_intervals=((450.0, 480.0),), outlier_rate=0.002, outlier_std=0.3,
                  water_track=True, water_track_noise_std=0.05)
    assert config_effects(json.loads(Config(dvl=c).to_json())["dvl"]) == [
        "beam noise + 0.002 m/s per m/s of speed + 0.0001 m/s per m of range",
        "echoes fade at 80 m of range (width 5 m)", "grazing loss from 60 deg of incidence",
        "dropouts 2 % of beams in bursts of 3 pings", "0.5 % of pings lost",
        "beam 2 dead 300-360 s", "lock lost 450-480 s",
        "outliers 0.2 % of beams, std 0.3 m/s", "water track 10 m below, noise 0.05 m/s"]
    assert config_effects(json.loads(Config().to_json())["dvl"]) == []
    assert config_effects({"no_such_setting": 1}) == []


def test_inspect_gives_the_error_velocity_of_the_pings_without_an_outlier(tmp_path, capsys):
    """Beside the rms over every four-beam ping, which one outlier sets, inspect gives the
    rms over the bottom-track pings whose beams hold no outlier: what an instrument's own
    error velocity is compared with. Computed here from the file's own columns."""
    from conftest import write

    from auvsim.cli import main
    from auvsim.data.reader import open_dataset

    dvl = DvlConfig(noise_std=0.002, outlier_rate=0.05, outlier_std=0.5)
    path = write(flat(mission(duration=60.0), dvl=dvl), tmp_path / "f.h5")
    assert main(["inspect", str(path)]) == 0
    text = capsys.readouterr().out
    with open_dataset(path) as f:
        d = f.missions[next(iter(f.missions))].dvl
        e, mode, status = d.error_velocity, d.mode, d.status
    clean = (np.isfinite(e) & (mode == Mode.BOTTOM_TRACK)
             & ~(status == Status.OUTLIER).any(axis=1))
    assert 0 < clean.sum() < np.isfinite(e).sum()  # outliers there, and pings without
    every = np.sqrt(np.mean(e[np.isfinite(e)] ** 2))
    rms = np.sqrt(np.mean(e[clean] ** 2))
    assert rms < every / 3  # the outliers set the first figure, not the second
    assert (f"error velocity rms {every:.3g} m/s over {np.isfinite(e).sum()} four-beam pings "
            f"({rms:.3g} m/s over the {clean.sum()} bottom-track pings without an outlier)"
            ) in text


# -- bad settings -----------------------------------------------------------------------


@pytest.mark.parametrize("kwargs,field", [
    (dict(echo_loss_range=-5.0), "dvl.echo_loss_range"),
    (dict(echo_loss_range=float("nan")), "dvl.echo_loss_range"),
    (dict(echo_loss_width=0.0), "dvl.echo_loss_width"),
    (dict(grazing_loss_angle_deg=90.0), "dvl.grazing_loss_angle_deg"),
    (dict(grazing_loss_width_deg=-1.0), "dvl.grazing_loss_width_deg"),
    (dict(dropout_rate=1.0), "dvl.dropout_rate"),
    (dict(dropout_rate=0.6, dropout_burst=1.0), "dvl.dropout_rate"),
    (dict(dropout_burst=0.5), "dvl.dropout_burst"),
    (dict(ping_dropout_rate=-0.1), "dvl.ping_dropout_rate"),
    (dict(beam_failures=((4, 0.0, 10.0),)), "dvl.beam_failures"),
    (dict(beam_failures=((1, 10.0, 5.0),)), "dvl.beam_failures"),
    (dict(beam_failures=(1, 0.0, 5.0)), "dvl.beam_failures"),
    (dict(lock_loss_intervals=((5.0,),)), "dvl.lock_loss_intervals"),
    (dict(lock_loss_intervals=(("a", 3.0),)), "dvl.lock_loss_intervals"),
    (dict(noise_range_coeff=-1e-4), "dvl.noise_range_coeff"),
    (dict(noise_speed_coeff=float("inf")), "dvl.noise_speed_coeff"),
    (dict(outlier_rate=1.5), "dvl.outlier_rate"),
    (dict(outlier_std=-0.1), "dvl.outlier_std"),
    (dict(sound_speed_std=0.2), "dvl.sound_speed_std"),
    (dict(misalignment_std_deg=45.0), "dvl.misalignment_std_deg"),
    (dict(water_track="yes"), "dvl.water_track"),
    (dict(water_track_range=0.0), "dvl.water_track_range"),
    (dict(water_track=True, water_track_range=200.0), "dvl.water_track_range"),
    (dict(water_track_noise_std=-0.01), "dvl.water_track_noise_std"),
])
def test_bad_fault_settings_are_refused_in_one_line_naming_the_field(kwargs, field):
    with pytest.raises(ConfigError) as caught:
        DvlConfig(**kwargs)
    message = str(caught.value)
    assert message.startswith(f"{field}: expected ") and "\n" not in message


def test_fault_settings_round_trip_through_json():
    from auvsim.config import Config

    config = flat(dvl=DvlConfig(beam_failures=[[2, 5, 9.5]], lock_loss_intervals=[[1, 2]],
                                echo_loss_range=70.0, water_track=True))
    assert Config.from_json(config.to_json()) == config
    assert config.dvl.beam_failures == ((2, 5.0, 9.5),)
