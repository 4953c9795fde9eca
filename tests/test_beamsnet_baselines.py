"""beamsnet.estimators.baselines: LS, the calibrations and the Kalman filter, on auvsim datasets and
on synthetic samples with a known beam matrix, scale factors and biases."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import flat, mission, write

from auvsim.config import DvlConfig
from auvsim.sensors.dvl import beam_matrix, least_squares
from beamsnet.data import Windows, load_windows, select, split
from beamsnet.estimators.baselines import (
    AffineCalibration,
    BeamCalibration,
    KalmanFilter,
    LeastSquares,
    ScaleOffset,
    availability,
)
from beamsnet.estimators.missing import MissingBeamRegressor
from beamsnet.metrics import rmse_vector as rmse

H = beam_matrix(np.radians(20.0))
SCALE = np.array([0.007, -0.004, 0.01, 0.002])
BIAS = np.array([1e-3, -2e-3, 5e-4, 0.0])  # m/s


def synthetic(velocities, *, scale=0.0, bias=0.0, noise=0.0, seed=0, n_past=3,
              beams=None) -> Windows:
    """Windows of missions flying ``velocities`` (a list of (N, 3) DVL velocities per ping,
    m/s, pings 1 s apart) with eq. 7's errors ``y = (1 + s) H v + b + noise N(0, 1)``, or
    with the measured ``beams`` given (a list of (N, 4), NaN: missing). Every ping from
    n_past on is a sample, as ``load_windows(every_ping=True)`` cuts them."""
    rng = np.random.default_rng(seed)
    parts = []
    for i, v in enumerate(velocities):
        y = ((1 + np.asarray(scale)) * (v @ H.T) + bias
             + noise * rng.standard_normal((len(v), 4))) if beams is None else beams[i]
        ks = np.arange(n_past, len(v))
        parts.append(dict(beams=y[ks], past_beams=y[ks[:, None] + np.arange(-n_past, 0)],
                          target=v[ks], mission=np.full(len(ks), i), time=ks.astype(float)))
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return Windows(accel=None, gyro=None, velocity_ls=least_squares(cat["beams"], H),
                   names=tuple(f"m{i}" for i in range(len(velocities))), h=H, **cat)


def straight_and_turned(rng, *, n=600, sway=0.0):
    """Velocities of a straight line at 0.5 to 3 m/s along x (with a white sway of ``sway``
    m/s on y and z), of a leg along y at 0.5 to 2 m/s, and of random mostly horizontal
    directions at 0.5 to 2.5 m/s."""
    line = np.column_stack([np.linspace(0.5, 3.0, n), sway * rng.standard_normal((n, 2))])
    along_y = np.column_stack([0.02 * rng.standard_normal(n), np.linspace(0.5, 2.0, n),
                               np.zeros(n)])
    d = rng.standard_normal((n, 3)) * [1.0, 1.0, 0.2]
    mixed = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.5, 2.5, (n, 1))
    return line, along_y, mixed


def make(tmp_path_factory, name: str, dvl: DvlConfig, missions=None):
    """Windows of a generated dataset; by default one mission that accelerates from 0.5 to
    2 m/s, so the velocity varies enough for a calibration to be identifiable."""
    missions = missions or (mission("a", 1, speed=2.0, start_speed=0.5, duration=100.0),)
    return load_windows(write(flat(*missions, dvl=dvl),
                              tmp_path_factory.mktemp(name) / f"{name}.h5"))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    return make(tmp_path_factory, "clean", DvlConfig(beam_angle_deg=20.0))


@pytest.fixture(scope="module")
def biased(tmp_path_factory):
    return make(tmp_path_factory, "biased", DvlConfig(
        beam_angle_deg=20.0, scale_factor=(0.007, -0.004, 0.01, 0.002),
        bias=(1e-3, -2e-3, 5e-4, 0.0)))


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    """Two missions at constant speed (1 and 2 m/s), white beam noise only."""
    return make(tmp_path_factory, "noisy", DvlConfig(beam_angle_deg=20.0, noise_std=0.02),
                missions=(mission("a", 1, speed=2.0, duration=200.0),
                          mission("b", 2, speed=1.0, duration=160.0)))


def estimators():
    return [LeastSquares(), AffineCalibration(), BeamCalibration(), ScaleOffset(),
            KalmanFilter(), KalmanFilter(calibrate=False), KalmanFilter(calibrate="beam"),
            KalmanFilter(gate=None)]


def test_least_squares_is_the_files_velocity_ls(noisy):
    np.testing.assert_allclose(LeastSquares().predict(noisy), noisy.velocity_ls,
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("estimator", estimators(), ids=lambda e: e.name)
def test_every_estimator_is_exact_on_noise_free_data(clean, estimator):
    train, test = split(clean)
    np.testing.assert_allclose(estimator.fit(train).predict(test), test.target,
                               rtol=0, atol=1e-10)


def test_affine_removes_scale_factor_and_bias_least_squares_does_not(biased):
    train, test = split(biased)
    np.testing.assert_allclose(AffineCalibration().fit(train).predict(test), test.target,
                               rtol=0, atol=1e-10)
    np.testing.assert_allclose(KalmanFilter().fit(train).predict(test), test.target,
                               rtol=0, atol=1e-10)
    assert rmse(LeastSquares().predict(test), test.target) > 5e-3
    assert rmse(KalmanFilter(calibrate=False).fit(train).predict(test), test.target) > 5e-3


def test_kalman_filter_beats_least_squares_on_noisy_constant_velocity(noisy):
    train, test = split(noisy)
    ls = rmse(LeastSquares().predict(test), test.target)
    for kf in (KalmanFilter(), KalmanFilter(calibrate=False)):
        kf.fit(train)
        assert rmse(kf.predict(test), test.target) < 0.5 * ls, kf.name
        # r is the beam noise, found from the LS residual without the truth
        assert kf.r == pytest.approx(0.02, rel=0.15)
        assert kf.q < 1e-2  # m/s per sqrt(s): at constant speed, q goes to the small end


def test_kalman_filter_on_beams_derived_from_a_velocity_takes_r_from_the_target():
    """A log without beams: the beams are H v of the instrument's velocity, which carries
    white noise of 0.01 m/s per axis, so the four-beam residual is zero. R is then the
    measurement's error covariance against the training target (0.01^2 I), r its axes'
    RMS, and the filter averages the noise as on measured beams, where it was the
    calibration alone (R = 0) before."""
    rng = np.random.default_rng(3)
    v = [np.tile([1.5, 0.0, 0.1], (400, 1)), np.tile([0.8, 0.2, 0.0], (400, 1))]
    noisy_v = [x + 0.01 * rng.standard_normal(x.shape) for x in v]
    windows = synthetic(v, beams=[x @ H.T for x in noisy_v])._replace(derived=("m0", "m1"))
    train, test = split(windows)
    kf = KalmanFilter(calibrate=False).fit(train)
    assert kf.r == pytest.approx(0.01, rel=0.1)
    np.testing.assert_allclose(kf.r_velocity, 1e-4 * np.eye(3), atol=2e-5)
    ls = rmse(LeastSquares().predict(test), test.target)
    assert rmse(kf.predict(test), test.target) < 0.5 * ls
    calibrated = KalmanFilter().fit(train)
    assert calibrated.r > 0
    assert not np.allclose(calibrated.predict(test), calibrated.calibration.predict(test))


def test_kalman_filter_restarts_at_each_mission(noisy):
    train, test = split(noisy)
    kf = KalmanFilter().fit(train)
    both = kf.predict(test)
    b = test.mission == 1
    # mission b alone gives the same estimates: nothing of mission a carries over ...
    np.testing.assert_allclose(both[b], kf.predict(select(test, b)), rtol=0, atol=1e-15)
    # ... even when mission a's beams are far off
    shifted = test._replace(beams=np.where((test.mission == 0)[:, None], test.beams + 1.0,
                                           test.beams))
    np.testing.assert_allclose(kf.predict(shifted)[b], both[b], rtol=0, atol=1e-15)
    # and each mission starts from its own first (calibrated) measurement
    first = [np.flatnonzero(test.mission == i)[0] for i in range(2)]
    np.testing.assert_allclose(both[first], kf.calibration.predict(select(test, first)),
                               rtol=0, atol=1e-15)


def test_kalman_filter_sorts_by_mission_and_time_and_refuses_duplicates(noisy):
    train, test = split(noisy)
    kf = KalmanFilter(calibrate=False).fit(train)
    order = np.random.default_rng(0).permutation(len(test.target))
    np.testing.assert_allclose(kf.predict(select(test, order)), kf.predict(test)[order],
                               rtol=0, atol=1e-15)
    twice = select(test, np.concatenate([np.arange(len(test.target))] * 2))
    with pytest.raises(ValueError, match="same time"):
        kf.predict(twice)


def test_every_estimator_has_the_same_interface(noisy):
    train, test = split(noisy)
    names = set()
    for estimator in estimators():
        if not isinstance(estimator, LeastSquares):
            with pytest.raises(RuntimeError, match="call fit"):
                estimator.predict(test)
        assert estimator.fit(train) is estimator
        out = estimator.predict(test)
        assert out.shape == (len(test.target), 3) and out.dtype == np.float64
        assert np.isfinite(out).all()
        assert isinstance(estimator.name, str)
        names.add(estimator.name)
    assert len(names) == len(estimators())


def test_beam_calibration_recovers_eq7_and_transfers_where_affine_does_not():
    rng = np.random.default_rng(1)
    line, along_y, mixed = straight_and_turned(rng)
    train = synthetic([line], scale=SCALE, bias=BIAS)
    beam, affine = BeamCalibration().fit(train), AffineCalibration().fit(train)
    # noise-free: eq. 7's own 8 parameters exactly, from a straight line along x ...
    np.testing.assert_allclose(beam.scale, SCALE, rtol=0, atol=1e-12)
    np.testing.assert_allclose(beam.bias, BIAS, rtol=0, atol=1e-12)
    for v in (line, along_y, mixed):  # ... and so exact in every direction
        w = synthetic([v], scale=SCALE, bias=BIAS)
        np.testing.assert_allclose(beam.predict(w), w.target, rtol=0, atol=1e-12)
    # The affine map is exact on the line it saw, but nothing constrained its cross-axis
    # terms (the training beams span one direction): off it, it is far off (1.3 m/s here).
    np.testing.assert_allclose(affine.predict(train), train.target, rtol=0, atol=1e-12)
    for v in (along_y, mixed):
        w = synthetic([v], scale=SCALE, bias=BIAS)
        assert rmse(affine.predict(w), w.target) > 0.5


def test_beam_calibration_transfers_with_noise_and_sway():
    """A straight line with 1 cm/s of sway and 2 mm/s beam noise: the affine map fits its
    cross-axis terms to the sway and noise; the per-beam fit stays at the noise level."""
    rng = np.random.default_rng(1)
    line, along_y, mixed = straight_and_turned(rng, sway=0.01)
    train = synthetic([line], scale=SCALE, bias=BIAS, noise=2e-3, seed=2)
    beam, affine = BeamCalibration().fit(train), AffineCalibration().fit(train)
    assert np.abs(beam.scale - SCALE).max() < 2e-3 and np.abs(beam.bias - BIAS).max() < 1e-3
    # LS on 4 beams with noise sigma: x and y each sigma / (sqrt(2) sin a), z
    # sigma / (2 cos a), so sigma sqrt(1 / sin^2 a + 1 / (4 cos^2 a)) = 5.9 mm/s at 20 deg
    a = np.radians(20)
    floor = 2e-3 * np.sqrt(1 / np.sin(a) ** 2 + 1 / (4 * np.cos(a) ** 2))
    for seed, v in enumerate((along_y, mixed), start=3):
        w = synthetic([v], scale=SCALE, bias=BIAS, noise=2e-3, seed=seed)
        e_beam, e_affine = rmse(beam.predict(w), w.target), rmse(affine.predict(w), w.target)
        assert e_beam < 1.05 * floor  # measured: 1.006 and 0.99 x the noise floor
        assert e_affine > 10 * e_beam  # measured: 34 and 28 x on the y leg and mixed


def test_beam_calibration_and_scale_offset_work_on_three_beams():
    rng = np.random.default_rng(1)
    line, _, mixed = straight_and_turned(rng)
    common = np.full(4, 0.007)  # the paper's single scale factor: ScaleOffset's model
    train = synthetic([line], scale=common, bias=BIAS)
    w = synthetic([mixed], scale=common, bias=BIAS)
    dead = w._replace(beams=np.where(np.arange(4) == 1, np.nan, w.beams))
    two = w._replace(beams=np.where(np.arange(4) < 2, np.nan, w.beams))
    beam, scale_offset = BeamCalibration().fit(train), ScaleOffset().fit(train)
    np.testing.assert_allclose(beam.predict(dead), w.target, rtol=0, atol=1e-12)
    # LS of (1 + s) H v + b is (1 + s) v + pinv(H) b: k = 1 / (1 + s), exact on 4 beams
    assert scale_offset.k == pytest.approx(1 / 1.007, abs=1e-12)
    np.testing.assert_allclose(scale_offset.predict(w), w.target, rtol=0, atol=1e-12)
    # On 3 beams the bias enters LS as inv(H_3) b_3 instead: that difference, times k,
    # is the error of an offset fitted on 4 beams (3.6 mm/s here)
    use = np.arange(4) != 1
    shift = np.linalg.solve(H[use], BIAS[use]) - np.linalg.pinv(H) @ BIAS
    np.testing.assert_allclose(scale_offset.predict(dead) - w.target,
                               np.broadcast_to(scale_offset.k * shift, w.target.shape),
                               rtol=0, atol=1e-12)
    for estimator in (beam, scale_offset):
        assert np.isnan(estimator.predict(two)).all()
    # per-beam scale factors that differ are beyond its 4 parameters
    w = synthetic([mixed], scale=SCALE, bias=BIAS)
    train = synthetic([line], scale=SCALE, bias=BIAS)
    assert rmse(ScaleOffset().fit(train).predict(w), w.target) > 1e-3


def test_availability():
    assert availability(np.array([[1.0, 2, 3], [np.nan, 0, 0], [4, 5, 6], [7, 8, 9]])) == 0.75
    assert np.isnan(availability(np.empty((0, 3))))
    with pytest.raises(ValueError, match=r"\(S, 3\)"):
        availability(np.zeros((3, 4)))


def test_kalman_filter_restarts_on_a_speed_step_a_fixed_small_q_does_not():
    """Along x, a step of dv = 0.5 m/s after n0 = 200 samples at 1 m/s, beam noise 2 mm/s.

    The LS x-velocity's noise is sigma_x = sigma / (sqrt(2) sin 20 deg) = 4.1 mm/s, so the
    step's innovation squared is about (dv / sigma_x)^2 = 1.5e4, far above the gate (16.3): the
    filter restarts on the step's own ping (N = 0 pings late) and from then on its error is
    never more than the measurement's (below 5 sigma_x). With q -> 0 and no gate the
    estimate is the mean of all measurements, whose error j pings after the step is
    dv n0 / (n0 + j + 1): 0.25 m/s at the end.
    """
    n0, n1, dv, sigma = 200, 200, 0.5, 2e-3
    v = np.zeros((n0 + n1 + 3, 3))
    v[:, 0] = 1.0
    v[n0 + 3:, 0] += dv  # synthetic() drops the first n_past = 3 pings
    test = synthetic([v], noise=sigma, seed=5)
    train = synthetic([np.tile([1.0, 0.0, 0.0], (403, 1))], noise=sigma, seed=6)
    gated = KalmanFilter(calibrate=False, q_grid=[1e-6]).fit(train)
    fixed = KalmanFilter(calibrate=False, q_grid=[1e-6], gate=None).fit(train)
    sigma_x = sigma / (np.sqrt(2) * np.sin(np.radians(20)))
    after = slice(n0, None)
    error = gated.predict(test)[after, 0] - test.target[after, 0]
    assert np.abs(error).max() < 5 * sigma_x
    error = fixed.predict(test)[after, 0] - test.target[after, 0]
    j = np.arange(n1)
    np.testing.assert_allclose(error, -dv * n0 / (n0 + j + 1), rtol=0, atol=5 * sigma_x)
    assert abs(error[-1]) > 0.2
    # At constant velocity the gate costs little: about one false restart in 1000 pings.
    train_rmse = {}
    for kf in (gated, fixed):
        train_rmse[kf.name] = rmse(kf.predict(train), train.target)
    assert train_rmse["KF (LS input)"] < 1.1 * train_rmse["KF (LS input, no gate)"]


def test_kalman_filter_on_the_beam_calibration_filters_three_beam_pings():
    """Fitted on straight legs along x, run at a constant velocity across them with beam 1
    dead on the second half: the beam-calibrated filter keeps an estimate on every ping,
    with the 3-beam R there, and averages (measured: 0.18 x the beam calibration's RMSE);
    the affine one is off the line it was fitted on (measured: 940 x the error), and
    coasts through the dead leg."""
    legs = [np.tile([speed, 0.0, 0.0], (300, 1)) for speed in (1.0, 2.0, 3.0)]
    train = synthetic(legs, scale=SCALE, bias=BIAS, noise=2e-3, seed=8)  # as paper-sim
    w = synthetic([np.tile([0.3, 1.2, 0.05], (400, 1))], scale=SCALE, bias=BIAS,
                  noise=2e-3, seed=9)
    dead = (np.arange(len(w.time)) >= 200)[:, None] & (np.arange(4) == 1)
    w = w._replace(beams=np.where(dead, np.nan, w.beams))
    kf = KalmanFilter(calibrate="beam").fit(train)
    pred = kf.predict(w)
    assert availability(pred) == 1.0
    calibrated = BeamCalibration().fit(train).predict(w)
    assert rmse(pred, w.target) < 0.25 * rmse(calibrated, w.target)
    # its R on a 3-beam ping is that of LS on those three corrected beams
    _, cov = kf._measurement(w)
    g = np.linalg.pinv(H[[0, 2, 3]])
    std = kf.r / (1 + kf.calibration.scale[[0, 2, 3]])
    np.testing.assert_allclose(cov[-1], g @ np.diag(std ** 2) @ g.T, rtol=1e-12, atol=0)
    affine = KalmanFilter().fit(train).predict(w)
    assert rmse(affine, w.target) > 10 * rmse(pred, w.target)


@pytest.mark.parametrize("estimator", [AffineCalibration(), BeamCalibration(), ScaleOffset(),
                                       MissingBeamRegressor()])
def test_a_fit_on_too_few_samples_asks_for_more_data(estimator):
    """Too short a training set (``stress --train-duration 5``: 3 samples) is the user's
    data, not a bug: a DataError, which a command line prints as one line."""
    from beamsnet.data import DataError

    few = synthetic([np.tile([1.0, 0.0, 0.0], (4, 1))])  # one sample, one velocity
    with pytest.raises(DataError, match="expected more training data"):
        estimator.fit(few)


def test_the_kalman_filter_grows_its_random_walk_with_the_time_between_samples():
    """A random walk w ~ N(0, q^2 dt) seen twice, T apart, with noise R and P0 = R: the
    second estimate is z0 + K (z1 - z0), K = (R + q^2 T) / (2 R + q^2 T) (the Kalman
    gain in closed form), so a long gap trusts the new sample more."""
    from beamsnet.estimators.baselines import _filter

    r2, q = 0.01 ** 2, 0.05
    for gap in (1.0, 10.0):
        z = np.array([[1.0, 0.0, 0.0], [1.2, 0.0, 0.0]])
        cov = np.broadcast_to(r2 * np.eye(3), (2, 3, 3))
        got = _filter(z, cov, np.zeros(2, dtype=np.int64), np.array([0.0, gap]),
                      np.array([q]), gate=None)
        k = (r2 + q * q * gap) / (2 * r2 + q * q * gap)
        assert got[1, 0] == pytest.approx(1.0 + 0.2 * k, rel=1e-12)
