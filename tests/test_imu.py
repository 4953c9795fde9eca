"""The IMU error model: presets, white noise, turn-on bias, Gauss-Markov bias, streaming."""

from __future__ import annotations

import math

import numpy as np
import pytest

from auvsim.config import Config, ImuConfig
from auvsim.sensors.imu import IMU_GRADES, ImuBiases, ImuErrorModel, draw_biases

ZERO = ImuBiases(np.zeros(3), np.zeros(3))
G0 = 9.80665


def model(config: ImuConfig, seed: int, biases: ImuBiases | None = None) -> ImuErrorModel:
    rng = np.random.default_rng(seed)
    return ImuErrorModel(config, draw_biases(config, rng) if biases is None else biases, rng)


def errors(config: ImuConfig, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) accel and gyro errors (measured - true) of one mission on a zero truth."""
    zeros = np.zeros((n, 3))
    return model(config, seed, ZERO).corrupt(zeros, zeros)


def truth(n: int, seed: int = 99) -> tuple[np.ndarray, np.ndarray]:
    """A wiggly (n, 3) specific force and angular rate, with some -0.0 entries."""
    rng = np.random.default_rng(seed)
    f = np.array([0.0, 0.0, -9.81]) + rng.normal(0.0, 0.5, (n, 3))
    w = rng.normal(0.0, 0.1, (n, 3))
    f[::7, 0] = -0.0
    w[::5, 1] = -0.0
    return f, w


def test_ideal_grade_passes_truth_through_bitwise():
    config = IMU_GRADES["ideal"]
    assert all(getattr(config, name) == 0.0 for name in (
        "accel_noise_density", "gyro_noise_density", "accel_turn_on_bias", "gyro_turn_on_bias",
        "accel_bias_instability", "gyro_bias_instability"))
    f, w = truth(5000)
    m = model(config, seed=3)
    for part in (slice(0, 1234), slice(1234, None)):
        f_meas, w_meas = m.corrupt(f[part], w[part])
        assert f_meas.tobytes() == f[part].tobytes()  # bitwise, sign of zero included
        assert w_meas.tobytes() == w[part].tobytes()
        assert f_meas is not f[part] and not np.shares_memory(f_meas, f)


@pytest.mark.parametrize("rate_hz", [100.0, 400.0])
def test_white_noise_std_is_density_times_root_rate(rate_hz):
    config = ImuConfig(rate_hz=rate_hz, accel_noise_density=2e-3, gyro_noise_density=3e-5)
    n = 200_000
    accel, gyro = errors(config, n, seed=11)
    for err, density in ((accel, 2e-3), (gyro, 3e-5)):
        sigma = density * math.sqrt(rate_hz)
        np.testing.assert_allclose(err.std(axis=0), sigma, rtol=0.03)
        assert np.all(np.abs(err.mean(axis=0)) < 4 * sigma / math.sqrt(n))
        lag1 = (err[1:] * err[:-1]).mean(axis=0) / err.var(axis=0)
        assert np.all(np.abs(lag1) < 0.01)  # white in time
    corr = np.corrcoef(np.hstack([accel, gyro]).T)
    off_diagonal = corr[~np.eye(6, dtype=bool)]
    assert np.all(np.abs(off_diagonal) < 0.01)  # axes and sensors uncorrelated


def test_turn_on_biases_have_the_configured_spread():
    config = ImuConfig(accel_turn_on_bias=5e-4, gyro_turn_on_bias=2e-6)
    seeds = 2000
    draws = [draw_biases(config, np.random.default_rng(seed)) for seed in range(seeds)]
    accel = np.array([d.accel for d in draws])
    gyro = np.array([d.gyro for d in draws])
    assert accel.shape == gyro.shape == (seeds, 3)
    for b, std in ((accel, 5e-4), (gyro, 2e-6)):
        np.testing.assert_allclose(b.std(axis=0), std, rtol=0.05)
        assert np.all(np.abs(b.mean(axis=0)) < 4 * std / math.sqrt(seeds))
    # one sensor's zero spread gives exact zeros and leaves the other's draw unchanged
    only_gyro = draw_biases(ImuConfig(gyro_turn_on_bias=2e-6), np.random.default_rng(0))
    assert only_gyro.accel.tobytes() == np.zeros(3).tobytes()
    np.testing.assert_array_equal(only_gyro.gyro, draws[0].gyro)


def test_turn_on_bias_is_constant_within_a_mission():
    config = ImuConfig(accel_turn_on_bias=5e-4, gyro_turn_on_bias=2e-6)
    m = model(config, seed=5)
    assert np.all(m.biases.accel != 0) and np.all(m.biases.gyro != 0)
    zeros = np.zeros((3000, 3))
    for _ in range(3):
        accel, gyro = m.corrupt(zeros, zeros)
        np.testing.assert_array_equal(accel, np.broadcast_to(m.biases.accel, accel.shape))
        np.testing.assert_array_equal(gyro, np.broadcast_to(m.biases.gyro, gyro.shape))


def test_gauss_markov_std_and_autocorrelation():
    tau, rate, sigma_a, sigma_g = 100.0, 100.0, 3e-4, 5e-6
    config = ImuConfig(rate_hz=rate, accel_bias_instability=sigma_a,
                       gyro_bias_instability=sigma_g, bias_correlation_time=tau)
    # 8 independent two-hour runs x 6 channels: ~3500 correlation times, so the std is
    # estimated to ~1.2 % and a lag's autocorrelation to ~0.002 (1 sigma).
    lags = (100, 1000)  # 1 s and 10 s
    sum_sq, sum_lag, count, count_lag = 0.0, np.zeros(2), 0, np.zeros(2)
    for seed in range(8):
        accel, gyro = errors(config, 720_000, seed)
        b = np.hstack([accel / sigma_a, gyro / sigma_g])
        sum_sq += np.sum(b**2)
        count += b.size
        for i, lag in enumerate(lags):
            sum_lag[i] += np.sum(b[lag:] * b[:-lag])
            count_lag[i] += b[lag:].size
    variance = sum_sq / count  # the mean is known (0), so this is unbiased
    assert abs(math.sqrt(variance) - 1.0) < 0.05
    phi = math.exp(-1.0 / (rate * tau))
    for lag, r, tol in zip(lags, sum_lag / count_lag / variance, (0.002, 0.01), strict=True):
        assert abs(r - phi**lag) < tol, (lag, r, phi**lag)
    # the first sample already has the stationary spread (no start-up transient)
    first = np.array([errors(config, 1, seed)[0][0] for seed in range(2000)]) / sigma_a
    np.testing.assert_allclose(first.std(axis=0), 1.0, rtol=0.05)


def test_output_does_not_depend_on_how_the_mission_is_split():
    config = ImuConfig(accel_noise_density=1e-3, gyro_noise_density=1e-5,
                       accel_turn_on_bias=1e-3, gyro_turn_on_bias=1e-5,
                       accel_bias_instability=1e-3, gyro_bias_instability=1e-5,
                       bias_correlation_time=10.0)
    f, w = truth(10_007)
    whole_f, whole_w = model(config, seed=21).corrupt(f, w)
    m = model(config, seed=21)
    edges = [0, 1, 1, 1000, 4321, 4322, 9999, 10_007]  # uneven, with an empty block
    parts = [m.corrupt(f[a:b], w[a:b]) for a, b in zip(edges[:-1], edges[1:], strict=True)]
    np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), whole_f)
    np.testing.assert_array_equal(np.concatenate([p[1] for p in parts]), whole_w)
    assert np.all(whole_f != f) and np.all(whole_w != w)


def test_same_seed_same_output_other_seed_other_output():
    config = IMU_GRADES["mems"]
    f, w = truth(2000)
    a = model(config, seed=8).corrupt(f, w)
    b = model(config, seed=8).corrupt(f, w)
    c = model(config, seed=9).corrupt(f, w)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert np.all(a[0] != c[0]) and np.all(a[1] != c[1])


def test_static_vehicle_reads_gravity_plus_biases():
    config = IMU_GRADES["navigation"]
    n = round(60 * config.rate_hz)
    f = np.tile([0.0, 0.0, -9.81], (n, 1))
    w = np.zeros((n, 3))
    biases = draw_biases(config, np.random.default_rng(4))
    f_meas, w_meas = model(config, seed=4, biases=biases).corrupt(f, w)
    # The same seed with only the Gauss-Markov part on a zero truth: the four streams are
    # separate, so this is exactly the realised b(t) of the run above.
    gm_only = ImuConfig(accel_bias_instability=config.accel_bias_instability,
                        gyro_bias_instability=config.gyro_bias_instability,
                        bias_correlation_time=config.bias_correlation_time)
    gm_accel, gm_gyro = model(gm_only, seed=4, biases=ZERO).corrupt(w, w)
    for meas, true, bias, gm, density in (
            (f_meas, f, biases.accel, gm_accel, config.accel_noise_density),
            (w_meas, w, biases.gyro, gm_gyro, config.gyro_noise_density)):
        standard_error = density * math.sqrt(config.rate_hz) / math.sqrt(n)
        expected = true[0] + bias + gm.mean(axis=0)
        assert np.all(np.abs(meas.mean(axis=0) - expected) < 4 * standard_error)
    # the accelerometer's turn-on bias stands far above the standard error: the test sees it
    standard_error = config.accel_noise_density * math.sqrt(config.rate_hz / n)
    without_bias = f[0] + gm_accel.mean(axis=0)
    assert np.any(np.abs(f_meas.mean(axis=0) - without_bias) > 10 * standard_error)
    # additive, not scaled: the error is the same whatever the truth
    f_zero, _ = model(config, seed=4, biases=biases).corrupt(np.zeros((n, 3)), w)
    np.testing.assert_allclose(f_meas - f_zero, f, rtol=0, atol=1e-12)


def test_grades_convert_the_datasheet_figures():
    nav, mems = IMU_GRADES["navigation"], IMU_GRADES["mems"]
    assert {c.rate_hz for c in IMU_GRADES.values()} == {100.0}
    # deg/sqrt(h) -> rad/s/sqrt(Hz): deg -> rad, and sqrt(h) = 60 sqrt(s)
    assert nav.gyro_noise_density == pytest.approx(0.0025 * math.pi / 180 / 60, rel=1e-12)
    assert nav.gyro_noise_density == pytest.approx(7.27e-7, rel=1e-3)
    assert mems.gyro_noise_density == pytest.approx(5.818e-5, rel=1e-3)
    # deg/h -> rad/s
    assert nav.gyro_bias_instability == pytest.approx(4.848e-8, rel=1e-3)
    assert mems.gyro_bias_instability == pytest.approx(5 * math.pi / 180 / 3600, rel=1e-12)
    # mg, micro-g -> m/s^2
    assert mems.accel_noise_density == pytest.approx(0.14e-3 * G0, rel=1e-12)
    assert mems.accel_noise_density == pytest.approx(1.373e-3, rel=1e-3)
    assert mems.accel_bias_instability == pytest.approx(3.923e-4, rel=1e-3)
    assert nav.accel_bias_instability == pytest.approx(10e-6 * G0, rel=1e-12)
    assert nav.accel_turn_on_bias == pytest.approx(50e-6 * G0, rel=1e-12)
    assert mems.accel_turn_on_bias == pytest.approx(1e-3 * G0, rel=1e-12)
    # navigation grade beats MEMS on every figure
    for name in ("accel_noise_density", "gyro_noise_density", "accel_turn_on_bias",
                 "gyro_turn_on_bias", "accel_bias_instability", "gyro_bias_instability"):
        assert 0 < getattr(nav, name) < getattr(mems, name), name
    for grade in IMU_GRADES.values():  # each preset is a valid, storable config
        config = Config(imu=grade)
        assert Config.from_json(config.to_json()) == config


def test_bad_shapes_name_the_argument():
    m = model(IMU_GRADES["mems"], seed=0)
    with pytest.raises(ValueError, match=r"specific_force: expected .*\(N, 3\).*\(10, 4\)"):
        m.corrupt(np.zeros((10, 4)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"angular_rate: expected .*\(10, 3\).*\(9, 3\)"):
        m.corrupt(np.zeros((10, 3)), np.zeros((9, 3)))
    with pytest.raises(ValueError, match=r"biases.gyro: expected .*\(3,\)"):
        ImuErrorModel(IMU_GRADES["mems"], ImuBiases(np.zeros(3), np.zeros(2)),
                      np.random.default_rng(0))
