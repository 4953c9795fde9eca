"""beamsnet.estimators.missing: missing beams regressed from the other beams and the past pings, on
synthetic samples with a known beam matrix, scale factors and biases."""

from __future__ import annotations

import numpy as np
import pytest
from test_beamsnet_baselines import BIAS, SCALE, H, synthetic

from auvsim.sensors.dvl import least_squares
from beamsnet.data import select
from beamsnet.estimators.baselines import LeastSquares, availability
from beamsnet.estimators.missing import MissingBeamRegressor, _earlier_samples
from beamsnet.metrics import rmse_vector as rmse

PATTERNS = [tuple(k for k in range(4) if (code >> k) & 1) for code in range(1, 16)]


def masked(windows, beams):
    """``windows`` with the current beams ``beams`` NaN on every sample."""
    return windows._replace(beams=np.where(np.isin(np.arange(4), beams), np.nan,
                                           windows.beams))


def random_velocities(rng, n):
    """(n, 3) independent velocities per ping, m/s: the past says nothing of the present."""
    return rng.uniform([-2.5, -2.5, -0.5], [2.5, 2.5, 0.5], (n, 3))


def ramps(rng, missions, n=60):
    """Missions each at its own constant acceleration, (n, 3) velocities each."""
    return [rng.uniform(-2, 2, 3) + np.arange(n)[:, None] * rng.uniform(-0.02, 0.02, 3)
            for _ in range(missions)]


def test_the_janus_beams_are_linearly_dependent():
    np.testing.assert_allclose(H[0] + H[2], H[1] + H[3], rtol=0, atol=1e-15)


@pytest.mark.parametrize("beam", range(4))
def test_one_missing_beam_is_exact_at_any_velocity(beam):
    rng = np.random.default_rng(0)
    train = synthetic([random_velocities(rng, 400)], scale=SCALE, bias=BIAS)
    test = synthetic([random_velocities(rng, 200)], scale=SCALE, bias=BIAS)
    # By the geometry: the other three's LS velocity gives it, and LS on the four filled
    # beams is then LS on the three.
    clean = synthetic([test.target])
    model = MissingBeamRegressor().fit(train)
    np.testing.assert_allclose(model.fill(masked(clean, [beam])), clean.beams,
                               rtol=0, atol=1e-9)
    one = masked(test, [beam])
    np.testing.assert_allclose(model.predict(one), LeastSquares().predict(one),
                               rtol=0, atol=1e-9)
    # With per-beam scale factors and biases the geometry is off (by up to 1.7 cm/s here);
    # the regressors of ``one_from_past`` learn the beams' relation with them, exactly.
    assert np.abs(model.fill(one) - test.beams).max() > 1e-3
    past = MissingBeamRegressor(one_from_past=True).fit(train)
    np.testing.assert_allclose(past.fill(one), test.beams, rtol=0, atol=1e-9)
    np.testing.assert_allclose(past.predict(one), least_squares(test.beams, H),
                               rtol=0, atol=1e-9)


@pytest.mark.parametrize("beams", [p for p in PATTERNS if len(p) > 1], ids=str)
def test_more_missing_beams_are_exact_at_constant_velocity_from_the_past(beams):
    """Trained on missions at constant accelerations (noise-free: the past pings
    extrapolate the present exactly), tested at constant velocities."""
    rng = np.random.default_rng(1)
    train = synthetic(ramps(rng, 12), scale=SCALE, bias=BIAS)
    test = synthetic([np.tile(rng.uniform(-2, 2, 3), (20, 1)) for _ in range(3)],
                     scale=SCALE, bias=BIAS)
    model = MissingBeamRegressor().fit(train)
    gone = masked(test, list(beams))
    np.testing.assert_allclose(model.fill(gone), test.beams, rtol=0, atol=1e-9)
    assert np.isnan(LeastSquares().predict(gone)).all()


def test_what_a_masked_beam_holds_is_never_read():
    rng = np.random.default_rng(2)
    train = synthetic(ramps(rng, 12), scale=SCALE, bias=BIAS, noise=1e-3)
    test = synthetic(ramps(rng, 2), scale=SCALE, bias=BIAS, noise=1e-3, seed=1)
    model = MissingBeamRegressor().fit(train)
    mask = rng.random(test.beams.shape) < 0.3
    nan = model.fill(test._replace(beams=np.where(mask, np.nan, test.beams)))
    for junk in (0.0, 1e3):
        out = model.fill(test._replace(beams=np.where(mask, junk, test.beams)), missing=mask)
        np.testing.assert_array_equal(out, nan)
    # the mask is what tells: unmasked, the junk would be a measurement
    assert not np.allclose(model.fill(test._replace(beams=np.where(mask, 0.0, test.beams))),
                           nan, equal_nan=True)


def faulty(rng, n, *, noise, dropout, dead):
    """A mission turning slowly at 1.5 m/s (n pings) whose beams drop out on a share
    ``dropout`` of the beam-pings (i.i.d.) and whose beam 0 is dead over the pings
    ``dead`` (a slice); the first 10 pings complete. Returns (velocities, beams)."""
    t = np.arange(n)
    v = np.column_stack([1.5 * np.cos(0.01 * t), 1.5 * np.sin(0.01 * t), 0.05 * np.sin(0.1 * t)])
    y = (1 + SCALE) * (v @ H.T) + BIAS + noise * rng.standard_normal((n, 4))
    lost = rng.random((n, 4)) < dropout
    lost[dead, 0] = True
    lost[:10] = False
    return v, np.where(lost, np.nan, y)


def test_an_estimate_on_every_ping_under_dropouts_and_a_dead_beam():
    """20 % of the beam-pings dropped and beam 0 dead for a third of the mission: LS
    (3 beams) has an estimate on 72 % of the pings on average (0.8^4 + 4 x 0.8^3 x 0.2 =
    0.82 off the dead leg, 0.8^3 = 0.51 on it; 69 % in this draw), the regressor on all of
    them: LS's own estimate where LS has one, and on the others (measured) 1.19 x LS's
    RMSE."""
    rng = np.random.default_rng(3)
    train = synthetic(ramps(rng, 10, n=200), scale=SCALE, bias=BIAS, noise=2e-3)
    model = MissingBeamRegressor().fit(train)
    v, y = faulty(rng, 600, noise=2e-3, dropout=0.2, dead=slice(200, 400))
    test = synthetic([v], beams=[y])
    pred, ls = model.predict(test), LeastSquares().predict(test)
    assert availability(pred) == 1.0
    assert 0.6 < availability(ls) < 0.8
    have = np.isfinite(ls).all(axis=1)
    np.testing.assert_allclose(pred[have], ls[have], rtol=0, atol=1e-9)
    ratio = rmse(pred[~have], test.target[~have]) / rmse(ls[have], test.target[have])
    assert ratio < 1.5


def test_one_missing_beam_with_noise_against_least_squares_on_three():
    """With noise, by default (the geometry) it is LS on the three beams; with
    ``one_from_past`` at slowly varying velocity, with the training split's dynamics, the
    past pings lower the filled beam's noise (measured: 0.93 x LS's RMSE)."""
    rng = np.random.default_rng(4)
    train = synthetic(ramps(rng, 10, n=200), scale=SCALE, bias=BIAS, noise=2e-3)
    test = masked(synthetic(ramps(rng, 3, n=200), scale=SCALE, bias=BIAS, noise=2e-3,
                            seed=1), [2])
    ls = rmse(LeastSquares().predict(test), test.target)
    np.testing.assert_allclose(MissingBeamRegressor().fit(train).predict(test),
                               LeastSquares().predict(test), rtol=0, atol=1e-9)
    past = MissingBeamRegressor(one_from_past=True).fit(train)
    assert rmse(past.predict(test), test.target) < 0.97 * ls


def test_a_dead_beam_from_the_first_ping_and_a_gap_in_the_samples():
    """Beam 0 dead all mission long and beam 1 lost on pings 113 and 114: those two pings
    have two beams missing, which the past pings 110-112 carry, with their own filled beam
    0. Without the samples of pings 103-112 (a gap: pings that are not samples), pings
    113 and 114 have no known past and so no estimate: never the samples before the gap
    taken for their past. Ping 115 has beam 0 alone missing, and an estimate again."""
    rng = np.random.default_rng(5)
    train = synthetic(ramps(rng, 10, n=200), scale=SCALE, bias=BIAS, noise=2e-3)
    model = MissingBeamRegressor().fit(train)
    v, y = faulty(rng, 300, noise=2e-3, dropout=0.0, dead=slice(None))
    y[:, 0] = np.nan
    y[113:115, 1] = np.nan
    test = synthetic([v], beams=[y])  # sample i is ping i + 3
    full = model.predict(test)
    assert availability(full) == 1.0
    assert np.isnan(LeastSquares().predict(test)[110:112]).all()
    keep = np.ones(len(test.target), dtype=bool)
    keep[100:110] = False
    kept = select(test, keep)
    earlier = _earlier_samples(kept.mission, kept.time, 3)
    np.testing.assert_array_equal(earlier[100], [-1, -1, -1])  # ping 113: 110-112 gone
    np.testing.assert_array_equal(earlier[103], [102, 101, 100])
    np.testing.assert_array_equal(earlier[99], [98, 97, 96])
    gapped = model.predict(kept)
    np.testing.assert_array_equal(gapped[:100], full[:100])
    assert np.isnan(gapped[100:102]).all() and np.isfinite(np.delete(gapped, [100, 101], 0)).all()
    np.testing.assert_array_equal(gapped[102:], full[112:])


def test_fit_needs_complete_pings_and_predict_a_fit():
    with pytest.raises(RuntimeError, match="call fit"):
        MissingBeamRegressor().predict(synthetic([np.ones((10, 3))]))
    with pytest.raises(ValueError, match="complete training pings"):
        MissingBeamRegressor().fit(synthetic([np.ones((10, 3))]))
