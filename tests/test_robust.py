"""Robust least squares: an outlying beam found by the error velocity and dropped."""

from __future__ import annotations

import numpy as np
import pytest

from auvsim.data.beams import beam_matrix, least_squares
from beamsnet.data import Windows
from beamsnet.estimators import spec
from beamsnet.estimators.robust import K, RobustLeastSquares, error_velocity, null_vector

H = beam_matrix(np.radians(20.0))


def _windows(beams: np.ndarray, past: np.ndarray, target: np.ndarray) -> Windows:
    """Windows of pings ``beams`` (S, 4) with past pings ``past`` (S, p, 4)."""
    s = len(beams)
    return Windows(beams=beams, past_beams=past, accel=None, gyro=None, target=target,
                   velocity_ls=least_squares(beams, H), mission=np.zeros(s, dtype=int),
                   time=np.arange(s, dtype=float), names=["m"], h=H)


def _still(v: np.ndarray, s: int) -> Windows:
    """``s`` noise-free pings at the velocity ``v`` (1, 3), each with 3 past pings."""
    clean = v @ H.T
    return _windows(np.repeat(clean, s, axis=0), np.repeat(clean[:, None], s, axis=0)
                    .repeat(3, axis=1), np.repeat(v, s, axis=0))


def _clean(rng, s: int, noise: float, n_past: int = 3) -> Windows:
    """Pings at a slowly varying velocity, beams with white noise of ``noise`` m/s."""
    v = np.array([1.5, 0.1, 0.05]) + 0.01 * np.cumsum(rng.normal(size=(s + n_past, 3)), axis=0)
    beams = v @ H.T + noise * rng.normal(size=(s + n_past, 4))
    past = np.stack([beams[k:k + s] for k in range(n_past)], axis=1)
    return _windows(beams[n_past:], past, v[n_past:])


def test_the_error_velocity_is_blind_to_the_velocity_and_equal_for_every_beam():
    n = null_vector(H)
    np.testing.assert_allclose(n @ H, 0.0, atol=1e-15)
    # Why IRLS on one ping cannot isolate a beam: every beam's spike leaves residuals of
    # the same size on all four beams.
    np.testing.assert_allclose(np.abs(n), 0.5, rtol=1e-12)
    v = np.array([[2.0, -0.3, 0.2]])
    assert abs(error_velocity(v @ H.T, H)[0]) < 1e-14


@pytest.mark.parametrize("seed", range(50))
def test_one_gross_outlier_beam_is_recovered_exactly_on_noise_free_beams(seed):
    rng = np.random.default_rng(seed)
    v = rng.uniform(-3.0, 3.0, (1, 3))
    beam, spike = seed % 4, rng.choice([-1.0, 1.0]) * rng.uniform(0.05, 5.0)
    clean = v @ H.T
    robust = RobustLeastSquares().fit(_still(v, 5))
    spiked = clean.copy()
    spiked[0, beam] += spike
    w = _windows(spiked, np.repeat(clean[:, None], 3, axis=1), v)
    np.testing.assert_allclose(robust.predict(w), v, atol=1e-9)
    assert np.abs(least_squares(spiked, H) - v).max() > 0.01  # LS is thrown off


def test_equal_to_ls_on_clean_data_within_the_noise():
    rng = np.random.default_rng(7)
    noise = 0.01
    train, test = _clean(rng, 2000, noise), _clean(rng, 5000, noise)
    robust = RobustLeastSquares().fit(train)
    assert robust.scale == pytest.approx(0.5 * 2 * noise, rel=0.1)  # |n . noise| = noise
    got, ls = robust.predict(test), least_squares(test.beams, H)
    rmse = np.sqrt(np.mean(np.sum((got - test.target) ** 2, axis=1)))
    rmse_ls = np.sqrt(np.mean(np.sum((ls - test.target) ** 2, axis=1)))
    # A Gaussian ping passes the 3.5-sigma cut about once in 2,000: almost every ping is LS.
    assert np.mean(np.any(got != ls, axis=1)) < 0.005
    assert rmse == pytest.approx(rmse_ls, rel=0.02)


def test_spikes_on_five_percent_of_beam_pings_cost_far_less_than_with_ls():
    rng = np.random.default_rng(11)
    noise, outlier = 0.002, 0.5
    train, test = _clean(rng, 2000, noise), _clean(rng, 5000, noise)
    hit = rng.random(test.beams.shape) < 0.05
    spiked = test._replace(beams=test.beams + hit * outlier * rng.standard_t(3, hit.shape))
    robust = RobustLeastSquares().fit(train)

    def rmse(v):
        return np.sqrt(np.mean(np.sum((v - test.target) ** 2, axis=1)))

    ls = rmse(least_squares(spiked.beams, H))
    # Pings with two spiked beams (about 1 %) stay wrong; the one-beam ones are repaired.
    assert rmse(robust.predict(spiked)) < 0.35 * ls


def test_three_beams_are_plain_ls_and_two_give_no_estimate():
    rng = np.random.default_rng(3)
    w = _clean(rng, 50, 0.01)
    robust = RobustLeastSquares().fit(w)
    three = w.beams.copy()
    three[:, 1] = np.nan
    three[0, 1] += 9.0
    np.testing.assert_array_equal(robust.predict(w._replace(beams=three)),
                                  least_squares(three, H))
    two = three.copy()
    two[:, 2] = np.nan
    assert np.isnan(robust.predict(w._replace(beams=two))).all()


def test_without_a_past_reference_a_flagged_ping_keeps_its_ls():
    v = np.array([[1.0, 0.0, 0.0]])
    clean = v @ H.T
    robust = RobustLeastSquares().fit(_still(v, 3))
    spiked = clean + [[0.0, 0.0, 1.0, 0.0]]
    w = _windows(spiked, np.full((1, 3, 4), np.nan), v)
    assert robust.outliers(spiked)[0] and K * robust.scale < 1.0
    np.testing.assert_array_equal(robust.predict(w), least_squares(spiked, H))


def test_it_is_registered_with_its_needs():
    s = spec("Robust LS")
    assert s.kind == "model-based" and s.needs.beams == 3 and s.make().name == s.name


def test_outliers_among_the_past_pings_do_not_choose_the_beam_to_drop():
    """Two of three past pings spiked on one beam, the current ping on another: the spiked
    past pings are left out of the vote, so the current ping's bad beam is found."""
    v = np.array([[1.5, 0.2, 0.05]])
    y = (v @ H.T)[0]
    est = RobustLeastSquares().fit(_still(v, 50))
    worst = 0.0
    for bad_past in range(4):
        for bad_now in {0, 1, 2, 3} - {bad_past}:
            past = np.tile(y, (1, 3, 1))
            past[0, :2, bad_past] += 0.5
            now = y.copy()
            now[bad_now] += 0.5
            got = est.predict(_windows(now[None], past, v))
            worst = max(worst, np.abs(got[0] - v[0]).max())
    assert worst < 1e-9
