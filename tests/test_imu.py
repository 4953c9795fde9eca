"""The IMU error model: presets, white noise, turn-on bias, Gauss-Markov bias, streaming,
scale factors, misalignment, g-sensitivity and the two triads' correlation times."""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import flat, mission, write

from auvsim.cli import main
from auvsim.config import Config, ImuConfig, MissionConfig, ScenarioConfig
from auvsim.data.describe import describe
from auvsim.data.reader import open_dataset
from auvsim.data.streams import STREAMS, mission_streams
from auvsim.errors import ConfigError
from auvsim.runs.presets import preset
from auvsim.sensors.imu import (
    IMU_GRADES,
    Imu,
    ImuBiases,
    ImuCalibration,
    ImuErrorModel,
    draw_biases,
    draw_calibration,
)

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
                       bias_correlation_time=10.0, accel_vibration_std=(0.02, 0.03, 0.01),
                       gyro_vibration_std=(1e-3, 0.0, 2e-4),
                       accel_vibration_per_rate=(0.2, 0.3, 0.0),
                       gyro_vibration_per_rate=(0.0, 5e-3, 2e-3))
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


# --- Errors a strapdown user calibrates (issue 10, item 5) -------------------------------

NEW_STDS = ("accel_scale_factor_std", "gyro_scale_factor_std", "accel_misalignment_std",
            "gyro_misalignment_std", "gyro_g_sensitivity_std")


def additive_reference(config: ImuConfig, biases: ImuBiases, seed: int, f: np.ndarray,
                       w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The additive model as it was before scale factors, misalignment and g-sensitivity,
    written out independently: the same draws in the same order and the same float
    operations, one tau for both triads (``bias_correlation_time``)."""
    accel_noise, gyro_noise, accel_gm, gyro_gm = np.random.default_rng(seed).spawn(4)
    dt_over_tau = 1.0 / (config.rate_hz * config.bias_correlation_time)
    phi = math.exp(-dt_over_tau)
    gain = math.sqrt(-math.expm1(-2.0 * dt_over_tau))
    out = []
    for truth, bias, density, sigma, noise_rng, gm_rng in (
            (f, biases.accel, config.accel_noise_density, config.accel_bias_instability,
             accel_noise, accel_gm),
            (w, biases.gyro, config.gyro_noise_density, config.gyro_bias_instability,
             gyro_noise, gyro_gm)):
        state = sigma * gm_rng.standard_normal(3)
        meas = truth + bias
        noise = noise_rng.standard_normal(truth.shape)
        noise *= density * math.sqrt(config.rate_hz)
        meas += noise
        drive = gm_rng.standard_normal(truth.shape)
        for k in range(len(truth)):
            meas[k] += state
            state = phi * state + sigma * gain * drive[k]
        out.append(meas)
    return out[0], out[1]


@pytest.mark.parametrize("grade", ["navigation", "mems"])
def test_without_the_new_terms_the_output_is_bitwise_the_additive_model(grade):
    config = IMU_GRADES[grade]
    assert all(getattr(config, name) == 0.0 for name in NEW_STDS)
    assert config.accel_bias_correlation_time is config.gyro_bias_correlation_time is None
    f, w = truth(3000)
    biases = draw_biases(config, np.random.default_rng(1))
    expected = additive_reference(config, biases, 7, f, w)
    # zero calibration errors, explicitly drawn ones of zero spread, and the two triads'
    # times set to the shared one: all the same bits as the additive model
    tau = config.bias_correlation_time
    explicit = dataclasses.replace(config, accel_bias_correlation_time=tau,
                                   gyro_bias_correlation_time=tau)
    for c, calibration in ((config, None), (config, draw_calibration(config, rng(5))),
                           (explicit, None)):
        kwargs = {} if calibration is None else {"calibration": calibration}
        m = ImuErrorModel(c, biases, np.random.default_rng(7), **kwargs)
        got = [m.corrupt(f[:1234], w[:1234]), m.corrupt(f[1234:], w[1234:])]
        assert np.concatenate([g[0] for g in got]).tobytes() == expected[0].tobytes()
        assert np.concatenate([g[1] for g in got]).tobytes() == expected[1].tobytes()


def rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def calibration_of(accel_sf=(0.0, 0.0, 0.0), gyro_sf=(0.0, 0.0, 0.0), accel_m=None,
                   gyro_m=None, g=None) -> ImuCalibration:
    zero = np.zeros((3, 3))
    return ImuCalibration(np.array(accel_sf, float), np.array(gyro_sf, float),
                          zero if accel_m is None else np.array(accel_m, float),
                          zero if gyro_m is None else np.array(gyro_m, float),
                          zero if g is None else np.array(g, float))


def test_scale_factor_and_misalignment_give_the_analytic_output():
    s_a, s_g = (1e-3, -2e-3, 5e-4), (3e-4, 7e-4, -1e-4)
    m_a = [[0.0, 1e-3, -2e-3], [3e-4, 0.0, 5e-4], [-7e-4, 2e-4, 0.0]]
    m_g = [[0.0, -4e-4, 1e-4], [6e-4, 0.0, -3e-4], [2e-4, 8e-4, 0.0]]
    cal = calibration_of(s_a, s_g, m_a, m_g)
    m = ImuErrorModel(ImuConfig(), ZERO, rng(0), calibration=cal)
    # A truth along one axis j, times a power of two c (exact products): axis i reads
    # c (delta_ij + A_ij), A = S + M, column j of the matrix (I + S + M).
    for j in range(3):
        for c in (1.0, -4.0, 0.5):
            e = np.zeros((1, 3))
            e[0, j] = c
            f_meas, w_meas = m.corrupt(e, e)
            for meas, sf, mis in ((f_meas, s_a, m_a), (w_meas, s_g, m_g)):
                expected = [c * (1.0 + sf[j]) if i == j else c * mis[i][j] for i in range(3)]
                assert meas[0].tolist() == expected
    # a general truth: (I + S + M) x, to the last few bits
    f, w = truth(500)
    f_meas, w_meas = m.corrupt(f, w)
    a_mat = np.eye(3) + np.diag(s_a) + np.array(m_a)
    g_mat = np.eye(3) + np.diag(s_g) + np.array(m_g)
    np.testing.assert_allclose(f_meas, np.einsum("ij,kj->ki", a_mat, f), rtol=0, atol=1e-14)
    np.testing.assert_allclose(w_meas, np.einsum("ij,kj->ki", g_mat, w), rtol=0, atol=1e-15)
    # a mounting rotation by a small angle eps about z is the antisymmetric M: gravity
    # (0, 0, -g) stays on z, a forward force leaks eps of itself into y
    eps = 1e-4
    rot = calibration_of(accel_m=[[0, -eps, 0], [eps, 0, 0], [0, 0, 0]])
    f_meas, _ = ImuErrorModel(ImuConfig(), ZERO, rng(0), calibration=rot).corrupt(
        np.array([[0.0, 0.0, -G0], [2.0, 0.0, 0.0]]), np.zeros((2, 3)))
    assert f_meas.tolist() == [[0.0, 0.0, -G0], [2.0, 2 * eps, 0.0]]


def test_gyro_g_sensitivity_is_g_times_the_specific_force():
    g_mat = np.array([[1e-5, -2e-5, 3e-5], [-4e-5, 5e-5, -6e-5], [7e-5, -8e-5, 9e-5]])
    m = ImuErrorModel(ImuConfig(), ZERO, rng(0), calibration=calibration_of(g=g_mat))
    # at rest and level: w_meas = G (0, 0, -g0), the third column times -g0, exactly
    f = np.tile([0.0, 0.0, -G0], (4, 1))
    f_meas, w_meas = m.corrupt(f, np.zeros((4, 3)))
    assert f_meas.tobytes() == f.tobytes()  # the accelerometers do not feel it
    np.testing.assert_array_equal(w_meas, np.tile(-G0 * g_mat[:, 2], (4, 1)))
    # a general specific force and rate: w + G f
    f, w = truth(300)
    _, w_meas = m.corrupt(f, w)
    np.testing.assert_allclose(w_meas, w + f @ g_mat.T, rtol=0, atol=1e-17)
    # an axis-by-axis coefficient is a diagonal G
    diag = ImuErrorModel(ImuConfig(), ZERO, rng(0),
                         calibration=calibration_of(g=np.diag([2e-5, 3e-5, 4e-5])))
    _, w_meas = diag.corrupt(np.array([[1.0, 2.0, -G0]]), np.zeros((1, 3)))
    assert w_meas[0].tolist() == [2e-5 * 1.0, 3e-5 * 2.0, 4e-5 * -G0]


def bartlett_std(phi: float, lag: int, n: int) -> float:
    """Large-sample std of the lag-``lag`` autocorrelation estimate of an AR(1) series of
    ``n`` samples with coefficient ``phi`` (Bartlett's formula)."""
    p2, p2k = phi * phi, phi ** (2 * lag)
    return math.sqrt(((1 + p2) * (1 - p2k) / (1 - p2) - 2 * lag * p2k) / n)


def test_separate_correlation_times_show_in_the_autocorrelation():
    rate, tau_a, tau_g = 10.0, 20.0, 200.0
    config = ImuConfig(rate_hz=rate, accel_bias_instability=3e-4, gyro_bias_instability=5e-6,
                       bias_correlation_time=1e4, accel_bias_correlation_time=tau_a,
                       gyro_bias_correlation_time=tau_g)
    assert (config.accel_tau, config.gyro_tau) == (tau_a, tau_g)
    # 6 runs of 40,000 s: 2000 accelerometer and 200 gyro correlation times each
    runs, n = 6, 400_000
    lags = (round(tau_a * rate), round(tau_g * rate))
    series = {"accel": [], "gyro": []}
    for seed in range(runs):
        accel, gyro = errors(config, n, seed)
        series["accel"].append(accel / config.accel_bias_instability)
        series["gyro"].append(gyro / config.gyro_bias_instability)
    for name, tau in (("accel", tau_a), ("gyro", tau_g)):
        b = np.hstack(series[name])  # (n, 3 runs) independent channels, known mean 0
        phi = math.exp(-1.0 / (rate * tau))
        for lag in lags:
            r = np.sum(b[lag:] * b[:-lag]) / np.sum(b[:-lag] ** 2)
            sigma = bartlett_std(phi, lag, n) / math.sqrt(b.shape[1])
            assert abs(r - phi**lag) < 3 * sigma, (name, lag, r, phi**lag, sigma)
    # the one shared time of older configs: accel and gyro decorrelate alike
    old = ImuConfig(rate_hz=rate, accel_bias_instability=3e-4, gyro_bias_instability=5e-6,
                    bias_correlation_time=tau_a)
    new = dataclasses.replace(old, accel_bias_correlation_time=tau_a,
                              gyro_bias_correlation_time=tau_a)
    a_old, g_old = errors(old, 5000, 3)
    a_new, g_new = errors(new, 5000, 3)
    assert a_old.tobytes() == a_new.tobytes() and g_old.tobytes() == g_new.tobytes()


def test_configs_before_the_split_load_and_mean_the_same():
    # an ImuConfig as config_json stored it before the new fields existed
    old = {"rate_hz": 100.0, "accel_noise_density": 1e-3, "gyro_noise_density": 1e-5,
           "accel_turn_on_bias": 0.0, "gyro_turn_on_bias": 0.0,
           "accel_bias_instability": 1e-4, "gyro_bias_instability": 1e-6,
           "bias_correlation_time": 250.0}
    config = Config.from_dict({"imu": old}).imu
    assert config.accel_tau == config.gyro_tau == 250.0
    assert all(getattr(config, name) == 0.0 for name in NEW_STDS)
    written = Config(imu=config)
    assert Config.from_json(written.to_json()) == written  # and round-trips with them
    # a config that sets only one triad's time keeps the shared one for the other
    one = ImuConfig(bias_correlation_time=250.0, gyro_bias_correlation_time=40.0)
    assert (one.accel_tau, one.gyro_tau) == (250.0, 40.0)


def test_realised_calibration_has_the_configured_statistics():
    config = ImuConfig(accel_scale_factor_std=5e-4, gyro_scale_factor_std=3e-4,
                       accel_misalignment_std=1e-3, gyro_misalignment_std=2e-4,
                       gyro_g_sensitivity_std=5e-6)
    seeds = 4000  # missions, each drawing from its own imu_calibration stream
    draws = [draw_calibration(config, mission_streams(seed)["imu_calibration"])
             for seed in range(seeds)]
    off = ~np.eye(3, dtype=bool)
    columns = []
    for name, std, pick in (
            ("accel_scale_factor", 5e-4, lambda x: x),
            ("gyro_scale_factor", 3e-4, lambda x: x),
            ("accel_misalignment", 1e-3, lambda x: x[off]),
            ("gyro_misalignment", 2e-4, lambda x: x[off]),
            ("gyro_g_sensitivity", 5e-6, lambda x: x.ravel())):
        values = np.array([pick(getattr(d, name)) for d in draws]) / std  # (seeds, k) N(0,1)
        # A sample of n unit normals has a std within 1 / sqrt(2 n) of 1 and a mean within
        # 1 / sqrt(n) of 0 (1 sigma): the group's pooled figures within 3 sigma, and each
        # of the 27 elements within 4 sigma (the largest of 27 is expected near 2.9 sigma).
        pooled = values.size
        assert abs(math.sqrt(np.mean(values**2)) - 1.0) < 3 / math.sqrt(2 * pooled), name
        assert abs(values.mean()) < 3 / math.sqrt(pooled), name
        assert np.all(np.abs(values.std(axis=0) - 1.0) < 4 / math.sqrt(2 * seeds)), name
        assert np.all(np.abs(values.mean(axis=0)) < 4 / math.sqrt(seeds)), name
        columns.append(values)
    for d in draws[:10]:
        assert not d.accel_misalignment.diagonal().any()
        assert not d.gyro_misalignment.diagonal().any()
    # 27 independent elements: every pair's correlation within 3 sigma of 0 (1/sqrt(n)),
    # allowing for the largest of the 351 pairs (about 3.6 sigma expected): 4.5 sigma
    corr = np.corrcoef(np.hstack(columns).T)
    assert corr.shape == (27, 27)
    assert np.all(np.abs(corr[~np.eye(27, dtype=bool)]) < 4.5 / math.sqrt(seeds))
    # one setting never shifts another's draw; a zero std gives exact zeros
    only = draw_calibration(ImuConfig(gyro_g_sensitivity_std=5e-6),
                            mission_streams(0)["imu_calibration"])
    np.testing.assert_array_equal(only.gyro_g_sensitivity, draws[0].gyro_g_sensitivity)
    for name in ImuCalibration._fields[:4]:
        assert getattr(only, name).tobytes() == np.zeros_like(getattr(only, name)).tobytes()


def test_the_plugin_draws_from_its_own_stream_and_stores_what_it_drew():
    assert STREAMS.index("imu_calibration") >= 8 and "imu_calibration" in Imu.streams[2:]
    config = Config(imu=IMU_GRADES["mems-full"])
    platform = SimpleNamespace(vehicle=SimpleNamespace(imu_position=np.zeros(3)))
    streams = mission_streams(42)
    imu = Imu(config, platform, streams["imu_biases"], streams["imu_calibration"])
    again = mission_streams(42)
    assert imu.biases.accel.tolist() == draw_biases(config.imu,
                                                    again["imu_biases"]).accel.tolist()
    expected = draw_calibration(config.imu, again["imu_calibration"])
    attrs = imu.attrs()
    assert attrs["imu_accel_scale_factor"].tolist() == expected.accel_scale_factor.tolist()
    assert attrs["imu_gyro_misalignment"].tolist() == expected.gyro_misalignment.ravel().tolist()
    assert attrs["imu_gyro_g_sensitivity"].reshape(3, 3).tolist() == \
        expected.gyro_g_sensitivity.tolist()
    assert attrs["imu_accel_bias_correlation_time"] == 150.0
    assert attrs["imu_gyro_bias_correlation_time"] == 300.0
    # every attribute it writes is declared, with the declared shape
    declared = {a.name: a for a in Imu.attributes}
    assert set(attrs) == set(declared)
    for name, value in attrs.items():
        assert np.shape(value) == declared[name].shape, name
    assert all(a.since == 4 for a in Imu.attributes if a.name not in (
        "imu_rate_hz", "imu_position_body", "imu_accel_turn_on_bias", "imu_gyro_turn_on_bias",
        "imu_accel_noise_density", "imu_gyro_noise_density", "imu_accel_bias_instability",
        "imu_gyro_bias_instability", "imu_bias_correlation_time"))
    # measured data: the model with the drawn calibration
    f, w = truth(200)
    t = SimpleNamespace(specific_force=f, angular_rate=w, time=np.arange(200) / 100.0)
    fields = imu.measure(t, again["imu_noise"])
    ref = ImuErrorModel(config.imu, imu.biases, mission_streams(42)["imu_noise"],
                        calibration=expected).corrupt(f, w)
    assert fields["imu/specific_force"].tobytes() == ref[0].tobytes()
    assert fields["imu/angular_rate"].tobytes() == ref[1].tobytes()


def test_full_grades_add_the_cited_terms_to_their_base_grades():
    for base, full in (("navigation", "navigation-full"), ("mems", "mems-full")):
        b, f = IMU_GRADES[base], IMU_GRADES[full]
        same = [x.name for x in dataclasses.fields(ImuConfig)
                if x.name not in NEW_STDS + ("accel_bias_correlation_time",
                                              "gyro_bias_correlation_time")]
        assert all(getattr(b, n) == getattr(f, n) for n in same), full
        assert f.gyro_tau == b.bias_correlation_time and f.accel_tau < f.gyro_tau
    nav, mems = IMU_GRADES["navigation-full"], IMU_GRADES["mems-full"]
    # ppm and deg -> dimensionless and rad; deg/h/g -> rad/s per m/s^2
    assert nav.accel_scale_factor_std == pytest.approx(100e-6, rel=1e-12)
    assert mems.accel_misalignment_std == pytest.approx(0.05 * math.pi / 180, rel=1e-12)
    assert mems.gyro_g_sensitivity_std == pytest.approx(
        1.1 * math.pi / 180 / 3600 / G0, rel=1e-12)
    assert nav.gyro_g_sensitivity_std == 0.0  # optical gyros: no proof mass
    for name in NEW_STDS[:4]:
        assert 0 < getattr(nav, name) < getattr(mems, name), name
    # The navigator's IMU is this grade on the Snapir's hull, with its vibration.
    assert dataclasses.replace(preset("navigator").imu, accel_vibration_std=(0, 0, 0),
                               gyro_vibration_std=(0, 0, 0), accel_vibration_per_rate=(0, 0, 0),
                               gyro_vibration_per_rate=(0, 0, 0)) == nav
    for name in ("paper-sim", "paper-sim-text", "maneuvers"):  # the paper's protocol
        assert preset(name).imu == IMU_GRADES["navigation"]


BAD_IMU = [
    ("accel_scale_factor_std", -1e-4, "a value >= 0"),
    ("accel_scale_factor_std", 0.2, "a std of at most 0.1 (10 %)"),
    ("gyro_scale_factor_std", math.nan, "a finite number"),
    ("gyro_scale_factor_std", 0.5, "a std of at most 0.1 (10 %)"),
    ("accel_misalignment_std", "1e-3", "a finite number"),
    ("accel_misalignment_std", 0.1, "a std of at most 0.05 rad"),
    ("gyro_misalignment_std", -0.0001, "a value >= 0"),
    ("gyro_misalignment_std", math.inf, "a finite number"),
    ("gyro_g_sensitivity_std", 0.01, "a std of at most 0.001 rad/s per m/s^2"),
    ("gyro_g_sensitivity_std", True, "a finite number"),
    ("accel_bias_correlation_time", 0.0, "a time > 0 s"),
    ("accel_bias_correlation_time", -5.0, "a value >= 0"),
    ("accel_bias_correlation_time", "long", "a finite number"),
    ("gyro_bias_correlation_time", 0.0, "a time > 0 s"),
    ("gyro_bias_correlation_time", math.nan, "a finite number"),
    ("accel_vibration_std", (0.02, -0.01, 0.0), "3 values in [0, 9.80665] m/s^2"),
    ("accel_vibration_std", (0.02, 0.03), "3 finite numbers"),
    ("gyro_vibration_std", (2.0, 0.0, 0.0), "3 values in [0, 1] rad/s"),
    ("gyro_vibration_std", (0.0, math.nan, 0.0), "3 finite numbers"),
    ("accel_vibration_per_rate", (0.0, 0.0, -1.0), "3 values in [0, 9.80665] m/s^2 per rad/s"),
    ("gyro_vibration_per_rate", "0.01", "3 finite numbers"),
]


@pytest.mark.parametrize("name,value,expected", BAD_IMU)
def test_bad_new_imu_settings_are_refused_naming_the_field(name, value, expected):
    with pytest.raises(ConfigError) as error:
        ImuConfig(**{name: value})
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"imu.{name}: expected {expected}")
    assert "got" in message


@pytest.mark.parametrize("name,value", [(n, v) for n, v, _ in BAD_IMU
                                        if isinstance(v, float) and math.isfinite(v)])
def test_bad_new_imu_settings_in_a_file_give_one_line_and_exit_2(tmp_path, capfd,
                                                                  monkeypatch, name, value):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.toml").write_text(f"[imu]\n{name} = {value!r}\n"
                                       "[[missions]]\n[missions.scenario]\nduration = 5\n")
    assert main(["generate", "--config", "bad.toml", "--out", "x.h5", "--quiet"]) == 2
    out, err = capfd.readouterr()
    assert err.count("\n") == 1 and err.startswith("auvsim: error: ") and f"imu.{name}" in err
    assert out == "" and sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_a_generated_mission_stores_and_shows_the_realised_calibration(tmp_path):
    config = flat(mission(seed=9, duration=2.0), imu=IMU_GRADES["mems-full"])
    path = write(config, tmp_path / "full.h5")
    with open_dataset(path) as f:  # its checks pass: every attribute of the schema, shaped
        m = f.missions["mission_000"]
        a = m.attrs
        stored = Config.from_json(f.config_json)
        f_meas, w_meas = m.imu.specific_force, m.imu.angular_rate
        f_true, w_true = m.truth.specific_force, m.truth.angular_rate
    assert stored == config
    expected = draw_calibration(config.imu, mission_streams(9)["imu_calibration"])
    assert a["imu_accel_scale_factor"].tolist() == expected.accel_scale_factor.tolist()
    assert a["imu_accel_misalignment"].tolist() == expected.accel_misalignment.ravel().tolist()
    assert a["imu_gyro_g_sensitivity"].tolist() == expected.gyro_g_sensitivity.ravel().tolist()
    assert (a["imu_accel_bias_correlation_time"], a["imu_gyro_bias_correlation_time"]) == (
        150.0, 300.0)
    # the file's measurements are the model's, from the mission's own streams
    streams = mission_streams(9)
    model = ImuErrorModel(config.imu, draw_biases(config.imu, streams["imu_biases"]),
                          streams["imu_noise"], calibration=expected)
    ref_f, ref_w = model.corrupt(f_true, w_true)
    assert f_meas.tobytes() == ref_f.tobytes() and w_meas.tobytes() == ref_w.tobytes()
    text = describe(path)
    assert "IMU calibration: scale factors accel" in text
    assert "bias correlation times accel 150 s, gyro 300 s" in text


VIBRATION = ImuConfig(accel_vibration_std=(0.02, 0.03, 0.01),
                      gyro_vibration_std=(1e-3, 5e-4, 2e-4),
                      accel_vibration_per_rate=(0.2, 0.3, 0.4),
                      gyro_vibration_per_rate=(5e-3, 8e-3, 2e-3))
SHAKES = (("accel_vibration_std", "accel_vibration_per_rate"),
          ("gyro_vibration_std", "gyro_vibration_per_rate"))


def shaken(n: int, seed: int, yaw_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) accel and gyro errors of ``VIBRATION`` alone on a truth that turns at a
    steady ``yaw_rate`` (rad/s) and measures nothing else."""
    rate = np.zeros((n, 3))
    rate[:, 2] = yaw_rate
    f, w = model(VIBRATION, seed, ZERO).corrupt(np.zeros((n, 3)), rate)
    return f, w - rate


@pytest.mark.parametrize("yaw_rate", [0.0, -0.1, 0.25])
def test_vibration_has_its_std_no_mean_and_integrates_to_a_bounded_velocity(yaw_rate):
    """The vibration alone at a steady yaw rate r, x[k] = (sigma_0 + s |r|) (e[k] -
    e[k-1]) / sqrt(2): its std per axis is sigma_0 + s |r|, its lag-1 autocorrelation -1/2
    (a first difference of white noise), and its sum telescopes, so the velocity (angle) it
    integrates to over 1000 s is sigma dt (e[k] - e[0]) / sqrt(2), whose std over k is
    sigma dt / sqrt(2), where white noise of the same std would wander sigma dt sqrt(k)."""
    n, dt = 100_000, 0.01
    for error, (base, grows) in zip(shaken(n, 5, yaw_rate), SHAKES, strict=True):
        sigma = np.asarray(getattr(VIBRATION, base)) + np.asarray(
            getattr(VIBRATION, grows)) * abs(yaw_rate)
        np.testing.assert_allclose(error.std(axis=0), sigma, rtol=0.02)
        lag1 = np.mean(error[1:] * error[:-1], axis=0) / error.var(axis=0)
        np.testing.assert_allclose(lag1, -0.5, atol=0.01)
        integral = np.cumsum(error, axis=0) * dt
        np.testing.assert_allclose(integral.std(axis=0), sigma * dt / math.sqrt(2), rtol=0.03)
        assert np.all(np.abs(integral).max(axis=0) < 7 * sigma * dt)
        assert np.all(np.abs(error.mean(axis=0)) < 1e-3 * sigma)


def test_vibration_puts_its_power_above_10_hz():
    """Its spectrum goes as |1 - exp(-2 pi i f / rate)|^2, i.e. as sin^2(pi f / rate): at
    100 Hz the share of its power below 10 Hz is the integral of sin^2(pi f / 100) over
    0-10 Hz over that over 0-50 Hz, (5 - 100 sin(0.2 pi) / (4 pi)) / 25 = 1.29 %."""
    from scipy import signal

    f, _ = shaken(200_000, 6, 0.0)
    freq, p = signal.welch(f[:, 1], fs=100.0, nperseg=1000)
    below = np.sum(p[freq < 10.0]) / np.sum(p)
    analytic = (5.0 - 100.0 * math.sin(0.2 * math.pi) / (4 * math.pi)) / 25.0
    assert below == pytest.approx(analytic, abs=0.003)


def test_vibration_adds_to_the_other_terms_and_changes_none_of_their_draws():
    """A config with vibration measures what the same config without it does, plus the
    vibration drawn from the two streams spawned after the first four: (sigma_0 + s |r[k]|)
    (e[k] - e[k - 1]) / sqrt(2), e[-1] the stream's first draw, to the last bits of the
    sums. So the noise, bias and calibration draws are those a config without it makes."""
    base = IMU_GRADES["navigation-full"]
    with_shake = dataclasses.replace(base, **{k: getattr(VIBRATION, k) for pair in SHAKES
                                              for k in pair})
    f, w = truth(5000)
    without = model(base, seed=4).corrupt(f, w)
    with_it = model(with_shake, seed=4).corrupt(f, w)
    streams = np.random.default_rng(4).spawn(6)[4:]  # the vibration's: after the first four
    for a, b, (std, grows), rng in zip(with_it, without, SHAKES, streams, strict=True):
        e = np.concatenate([rng.standard_normal((1, 3)), rng.standard_normal((len(f), 3))])
        sigma = (np.asarray(getattr(VIBRATION, std))
                 + np.asarray(getattr(VIBRATION, grows)) * np.abs(w[:, 2:3]))
        np.testing.assert_allclose(a - b, sigma * np.diff(e, axis=0) / math.sqrt(2),
                                   rtol=0, atol=1e-13)
        assert np.all(a != b)


def test_the_navigator_preset_records_the_snapirs_vibration_and_the_paper_presets_none():
    from auvsim.runs.presets import SNAPIR_VIBRATION

    for name in ("navigator", "realistic-maneuvers"):
        imu = preset(name).imu
        assert {k: getattr(imu, k) for k in SNAPIR_VIBRATION} == SNAPIR_VIBRATION
    for name in ("paper-sim", "maneuvers"):
        c = preset(name).imu
        assert not any(any(getattr(c, k)) for pair in SHAKES for k in pair)


def test_a_generated_mission_records_the_vibration_and_inspect_shows_it(tmp_path):
    """Through ``generate``: the file's IMU samples are the model's with the vibration,
    from the mission's own streams at the truth's yaw rate, and ``auvsim inspect`` prints
    the config's vibration."""
    imu = dataclasses.replace(IMU_GRADES["navigation-full"], **{
        k: getattr(VIBRATION, k) for pair in SHAKES for k in pair})
    turning = MissionConfig(name="mission_000", seed=9, scenario=ScenarioConfig(
        name="turning_circle", duration=30.0, options={"lead_s": 2.0}))
    config = flat(turning, imu=imu)
    path = write(config, tmp_path / "shaken.h5")
    with open_dataset(path) as f:
        m = f.missions["mission_000"]
        f_meas, w_meas = m.imu.specific_force, m.imu.angular_rate
        f_true, w_true = m.truth.specific_force, m.truth.angular_rate
    streams = mission_streams(9)
    model = ImuErrorModel(imu, draw_biases(imu, streams["imu_biases"]), streams["imu_noise"],
                          calibration=draw_calibration(imu, streams["imu_calibration"]))
    ref_f, ref_w = model.corrupt(f_true, w_true)
    assert f_meas.tobytes() == ref_f.tobytes() and w_meas.tobytes() == ref_w.tobytes()
    assert np.abs(w_true[:, 2]).max() > 0.05  # it turns: the vibration's std grows
    assert "IMU vibration (config): accel [0.02, 0.03, 0.01] m/s^2 + [0.2, 0.3, 0.4] per " \
        "rad/s of yaw rate" in describe(path)
