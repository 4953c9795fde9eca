"""beamsnet.baselines: LS, affine calibration and the Kalman filter on auvsim datasets."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import flat, mission, write

from auvsim.config import DvlConfig
from beamsnet.baselines import (
    AffineCalibration,
    KalmanFilter,
    LeastSquares,
)
from beamsnet.data import load_windows, select, split
from beamsnet.metrics import rmse_vector as rmse


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
    return [LeastSquares(), AffineCalibration(), KalmanFilter(),
            KalmanFilter(calibrate=False)]


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
