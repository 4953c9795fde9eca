"""The DVL: beam geometry, error model (eq. 7), least squares (eq. 9), lever arm, mounting."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from auvsim.config import Config, DvlConfig
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from auvsim.physics.vehicle import Trajectory
from auvsim.runs.mission import MissionRun
from auvsim.runs.presets import preset
from auvsim.sensors.dvl import (
    DvlErrors,
    DvlGeometry,
    Mode,
    Status,
    beam_matrix,
    draw_errors,
    least_squares,
    measure,
)

RNG = np.random.default_rng(12)


def test_beam_matrix_is_the_janus_x():
    alpha = math.radians(20)
    h = beam_matrix(alpha)
    np.testing.assert_allclose(np.linalg.norm(h, axis=1), 1.0)
    np.testing.assert_allclose(h[:, 2], math.cos(alpha))  # every beam 20 deg off the z axis
    azimuth = np.degrees(np.arctan2(h[:, 1], h[:, 0])) % 360
    np.testing.assert_allclose(azimuth, [45, 135, 225, 315])
    # Forward motion: the two forward beams see +u sin(a)/sqrt(2), the aft two minus that.
    np.testing.assert_allclose(h @ [1.0, 0, 0], np.array([1, -1, -1, 1]) * math.sin(alpha)
                               / math.sqrt(2))


def test_least_squares_is_exact_without_noise_with_four_and_three_beams():
    h = beam_matrix(math.radians(30))
    v = RNG.normal(size=(500, 3))
    beams = v @ h.T
    np.testing.assert_allclose(least_squares(beams, h), v, atol=1e-12)
    for dropped in range(4):  # any three beams still solve it exactly
        three = beams.copy()
        three[:, dropped] = np.nan
        np.testing.assert_allclose(least_squares(three, h), v, atol=1e-12)
    two = beams.copy()
    two[:, :2] = np.nan
    assert np.isnan(least_squares(two, h)).all()


def test_least_squares_matches_the_normal_equations_with_noise():
    h = beam_matrix(math.radians(25))
    y = RNG.normal(size=(50, 4))
    expected = np.linalg.solve(h.T @ h, h.T @ y.T).T  # eq. 9 literally
    np.testing.assert_allclose(least_squares(y, h), expected, atol=1e-12)


def test_error_model_residual_has_the_configured_noise():
    config = DvlConfig(scale_factor=(0.007, -0.01, 0.02, 0.0), bias=0.001, bias_std=0.0005,
                       noise_std=0.042)
    errors = draw_errors(config, np.random.default_rng(3))
    h = beam_matrix(math.radians(30))
    v = np.column_stack([np.linspace(0.5, 3, 50_000), np.zeros(50_000), np.zeros(50_000)])
    true = v @ h.T
    y = measure(true, np.ones_like(true, dtype=bool), errors=errors,
                noise_std=config.noise_std, rng=np.random.default_rng(4))
    residual = y - true * (1 + errors.scale_factor) - errors.bias
    std = residual.std(axis=0)
    assert np.all(np.abs(std / 0.042 - 1) < 0.03)
    assert np.all(np.abs(residual.mean(axis=0)) < 4 * 0.042 / math.sqrt(len(v)))
    # The realised parameters are the configured means plus the configured spread.
    np.testing.assert_allclose(errors.scale_factor, [0.007, -0.01, 0.02, 0.0])
    assert not np.allclose(errors.bias, 0.001)


def test_invalid_beams_read_nan_and_noise_does_not_depend_on_validity():
    h = beam_matrix(math.radians(30))
    true = np.tile(h @ [2.0, 0.1, 0.0], (10, 1))
    errors = DvlErrors(np.zeros(4), np.zeros(4))
    valid = np.ones((10, 4), dtype=bool)
    all_valid = measure(true, valid, errors=errors, noise_std=0.01,
                        rng=np.random.default_rng(1))
    valid[3, 2] = False
    some = measure(true, valid, errors=errors, noise_std=0.01, rng=np.random.default_rng(1))
    assert np.isnan(some[3, 2])
    np.testing.assert_array_equal(some[valid], all_valid[valid])


def test_scale_factor_spread_is_drawn_per_beam():
    config = DvlConfig(scale_factor_std=0.002, bias_std=0.001)
    draws = np.array([draw_errors(config, np.random.default_rng(s)).scale_factor
                      for s in range(3000)])
    assert abs(draws.std() / 0.002 - 1) < 0.05
    assert abs(np.corrcoef(draws[:, 0], draws[:, 1])[0, 1]) < 0.06


def test_lever_arm_pure_yaw_rotation():
    """Yawing at r with the DVL x ahead of the origin: the DVL point moves sideways at r x,
    so the beams read H (0, r x, 0) even though the origin is still."""
    geometry = DvlGeometry.from_config(DvlConfig(), lever_arm=np.array([1.0, 0.0, 0.23]))
    r = 0.2
    v = geometry.velocity(np.zeros((1, 3)), np.array([[0.0, 0.0, r]]))
    np.testing.assert_allclose(v, [[0.0, r * 1.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(v @ geometry.h.T, [geometry.h @ [0.0, r, 0.0]], atol=1e-15)


def test_mounting_rotation_expresses_velocity_in_the_dvl_frame():
    """A DVL yawed 45 deg on the body (as on the Snapir: mean velocity (1.13, -1.17, 0) in
    its frame for forward motion) sees forward motion split between its x and -y."""
    geometry = DvlGeometry.from_config(DvlConfig(mounting_rpy_deg=(0, 0, 45)),
                                       lever_arm=np.zeros(3))
    v = geometry.velocity(np.array([[1.6, 0.0, 0.0]]), np.zeros((1, 3)))
    np.testing.assert_allclose(v, [[1.6 / math.sqrt(2), -1.6 / math.sqrt(2), 0.0]], atol=1e-12)


def test_rays_point_down_and_out_in_ned():
    geometry = DvlGeometry.from_config(DvlConfig(beam_angle_deg=30), lever_arm=np.zeros(3))
    level = rotation_matrices(np.array([[1.0, 0, 0, 0]]))
    origins, directions = geometry.rays(np.array([[5.0, 6.0, 20.0]]), level)
    np.testing.assert_allclose(origins, [[5, 6, 20]])
    np.testing.assert_allclose(directions[0, :, 2], math.cos(math.radians(30)))
    # Rolled 180 deg the beams point up.
    upside_down = rotation_matrices(np.array([[0.0, 1, 0, 0]]))
    _, up = geometry.rays(np.zeros((1, 3)), upside_down)
    np.testing.assert_allclose(up[0, :, 2], -math.cos(math.radians(30)))


def test_rotation_helpers_agree():
    roll, pitch, yaw = 0.1, -0.2, 0.7
    cr, sr, cp, sp, cy, sy = (math.cos(roll / 2), math.sin(roll / 2), math.cos(pitch / 2),
                              math.sin(pitch / 2), math.cos(yaw / 2), math.sin(yaw / 2))
    q = np.array([[cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                   cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]])
    np.testing.assert_allclose(rotation_matrices(q)[0], rotation_rpy(roll, pitch, yaw),
                               atol=1e-12)


@pytest.mark.parametrize("kwargs,field", [
    (dict(beam_angle_deg=0), "beam_angle_deg"), (dict(beam_angle_deg=90), "beam_angle_deg"),
    (dict(rate_hz=0), "rate_hz"), (dict(noise_std=-1), "noise_std"),
    (dict(bias=float("nan")), "bias"), (dict(scale_factor=(1, 2)), "scale_factor"),
    (dict(min_range=10, max_range=5), "min_range"),
])
def test_bad_dvl_config_names_the_field(kwargs, field):
    from auvsim.errors import ConfigError

    with pytest.raises(ConfigError, match=field):
        DvlConfig(**kwargs)


def _mission_in_blocks(config, seconds: float, block_steps: int) -> dict[str, np.ndarray]:
    """The fields of the first ``seconds`` of a config's first mission, ``MissionRun.measure``
    called on blocks of ``block_steps`` physics steps (the environment's 10, generate's
    6000), concatenated."""
    run = MissionRun(config, config.missions[0])
    vehicle, dt = run.vehicle, run.vehicle.dt
    vehicle.reset(**run.scenario.initial_state())
    run.scenario.reset()
    steps = np.arange(round(seconds / dt))
    traj = run.scenario.run(vehicle, steps * dt)
    parts: dict[str, list[np.ndarray]] = {}
    for start in range(0, len(steps), block_steps):
        block = slice(start, start + block_steps)
        fields = run.measure(steps[block], Trajectory(*(x[block] for x in traj)))
        for path, value in fields.items():
            parts.setdefault(path, []).append(value)
    return {path: np.concatenate(values) for path, values in parts.items()}


def _every_dvl_effect() -> Config:
    """The navigator's DVL (every effect beyond eq. 7 on: water track, outliers, dropouts,
    grazing and echo loss, range- and speed-dependent noise, sound speed, misalignment),
    its beam failure and soft bottom moved inside the first two minutes."""
    nav = preset("navigator")
    dvl = dataclasses.replace(nav.dvl, beam_failures=((1, 20.0, 35.0),),
                              lock_loss_intervals=((50.0, 70.0),))
    return dataclasses.replace(nav, dvl=dvl)


@pytest.mark.parametrize("config", [preset("paper-sim"), _every_dvl_effect()],
                         ids=["paper-sim", "every-dvl-effect"])
def test_the_environments_small_blocks_give_generates_60_s_blocks(config):
    """A mission measured in the environment's 10-step blocks (no ping or one) equals it
    in 60 s blocks (60 pings) bit for bit, but for the products with the beam matrix, its
    pseudo-inverse and a misaligned DVL's mounting matrix: numpy's matmul may round
    (1, 3) @ (3, k) and (60, 3) @ (3, k) differently in the last bit (as it did before the
    DVL's small-block paths; with the mounting only on some CPUs' OpenBLAS kernels, e.g.
    OPENBLAS_CORETYPE=Haswell or Zen), so those fields and the ones computed from them
    agree to a few 1e-16 m/s, with the same NaNs."""
    small = _mission_in_blocks(config, 120.0, 10)
    large = _mission_in_blocks(config, 120.0, 6000)
    assert small.keys() == large.keys()
    rounded = {"dvl/velocity", "dvl/beam_velocity_true", "dvl/beam_velocity",
               "dvl/velocity_ls", "dvl/error_velocity"}
    for path in large:
        assert small[path].dtype == large[path].dtype, path
        if path in rounded:
            np.testing.assert_allclose(small[path], large[path], rtol=0, atol=1e-14,
                                       err_msg=path)
        else:
            assert small[path].tobytes() == large[path].tobytes(), path  # -0.0 != 0.0
    if config.dvl.water_track:  # the effects showed up, so their branches ran
        seen = set(large["dvl/status"].ravel().tolist())
        assert {Status.OK, Status.DROPOUT, Status.BEAM_FAILED, Status.LOCK_LOST} <= seen
        assert (large["dvl/mode"] == Mode.WATER_TRACK).any()


def test_the_compiled_helpers_give_numpys_bits():
    """The DVL's compiled elementwise loops against the numpy expressions they replaced,
    on many random inputs (with NaN and infinities where a ping may have them)."""
    from auvsim.sensors import dvl

    rng = np.random.default_rng(8)
    for m in (1, 2, 60, 1000):
        q = rng.normal(size=(m, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        w_, x, y, z = q.T  # the numpy formula rotation_matrices was before it was compiled
        stacked = np.stack([
            1 - 2 * (y * y + z * z), 2 * (x * y - w_ * z), 2 * (x * z + w_ * y),
            2 * (x * y + w_ * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w_ * x),
            2 * (x * z - w_ * y), 2 * (y * z + w_ * x), 1 - 2 * (x * x + y * y),
        ], axis=-1).reshape(-1, 3, 3)
        assert rotation_matrices(q).tobytes() == stacked.tobytes()
        v, w, r = rng.normal(size=(m, 3)), rng.normal(size=(m, 3)), rng.normal(size=3)
        cross = np.stack([w[:, 1] * r[2] - w[:, 2] * r[1], w[:, 2] * r[0] - w[:, 0] * r[2],
                          w[:, 0] * r[1] - w[:, 1] * r[0]], axis=-1)
        assert dvl._add_cross(v, w, r).tobytes() == (v + cross).tobytes()
        d = rng.normal(size=(m, 4, 3))
        assert dvl._longest_horizontal(d) == np.linalg.norm(d[..., :2], axis=-1).max()
        signal, noise = rng.normal(size=(m, 4)), rng.normal(0, 0.02, (m, 4))
        signal[rng.random((m, 4)) < 0.1] = np.nan
        scale, bias, ratio = rng.normal(0, 0.01, 4), rng.normal(0, 0.001, 4), 1.003
        y = (1.0 + scale) * (signal / ratio) + bias + noise
        assert dvl._measured_beams(signal, scale, bias, ratio, noise).tobytes() == y.tobytes()
        valid = rng.random((m, 4)) < 0.7
        np.testing.assert_array_equal(dvl._three_or_more(valid), valid.sum(axis=1) >= 3)
        ranges = rng.uniform(0, 90, (m, 4))
        ranges[rng.random((m, 4)) < 0.2] = rng.choice([np.nan, np.inf, -np.inf])
        assert dvl._nan_to_zero(ranges).tobytes() == np.nan_to_num(ranges).tobytes()
    d[0, 0, 0] = np.nan
    assert math.isnan(dvl._longest_horizontal(d))


def test_the_bias_is_drawn_per_beam_about_its_mean_with_its_spread():
    from auvsim.sensors.dvl import draw_errors

    config = DvlConfig(bias=0.001, bias_std=0.0005)
    draws = np.array([draw_errors(config, np.random.default_rng(s)).bias
                      for s in range(3000)])
    np.testing.assert_allclose(draws.std(axis=0), 0.0005, rtol=0.06)
    assert np.all(np.abs(draws.mean(axis=0) - 0.001) < 4 * 0.0005 / np.sqrt(3000))
