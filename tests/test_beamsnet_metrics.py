"""Metrics: the paper's speed figures by hand, the limits, what they hide, input checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from beamsnet import metrics
from beamsnet.metrics import (
    improvement,
    mae,
    r2,
    report,
    rmse,
    rmse_per_axis,
    rmse_vector,
    vaf,
)

# True speeds 1, 2, 3 m/s; predicted speeds 1, 2.5 (a 1.5-2-2.5 triangle), 3.5 m/s.
TRUE = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]])
PRED = np.array([[1.0, 0.0, 0.0], [1.5, 2.0, 0.0], [0.0, 0.0, 3.5]])


def test_hand_computed_values():
    # Speed errors e = |p| - |t| = [0, 0.5, 0.5].
    assert rmse(PRED, TRUE) == pytest.approx(math.sqrt((0 + 0.25 + 0.25) / 3))  # sqrt(1/6)
    assert mae(PRED, TRUE) == pytest.approx((0 + 0.5 + 0.5) / 3)  # 1/3
    # SSE = 0.5; SST = (1-2)^2 + 0 + (3-2)^2 = 2: R^2 = 1 - 0.5/2 = 0.75.
    assert r2(PRED, TRUE) == pytest.approx(0.75)
    # var(e) = mean(e^2) - mean(e)^2 = 1/6 - 1/9 = 1/18; var(|t|) = 2/3;
    # VAF = (1 - (1/18)/(2/3)) x 100 = (1 - 1/12) x 100 = 91.67: above R^2 x 100, as VAF
    # forgives the mean error.
    assert vaf(PRED, TRUE) == pytest.approx(100 * (1 - 1 / 12))
    # Component errors: x [0, 1.5, 0], y [0, 0, 0], z [0, 0, 0.5].
    np.testing.assert_allclose(rmse_per_axis(PRED, TRUE),
                               [math.sqrt(2.25 / 3), 0.0, math.sqrt(0.25 / 3)])
    # |p - t|^2 = [0, 2.25, 0.25]: sqrt(2.5 / 3).
    assert rmse_vector(PRED, TRUE) == pytest.approx(math.sqrt(2.5 / 3))


def test_report_holds_every_figure():
    got = report(PRED, TRUE)
    assert list(got) == ["rmse", "mae", "r2", "vaf", "rmse_x", "rmse_y", "rmse_z",
                         "rmse_vector"]
    assert all(type(v) is float for v in got.values())
    assert got["rmse"] == pytest.approx(math.sqrt(1 / 6))
    assert got["vaf"] == pytest.approx(100 * (1 - 1 / 12))
    assert got["rmse_x"] == pytest.approx(math.sqrt(0.75))
    assert got["rmse_z"] == pytest.approx(math.sqrt(1 / 12))
    assert got["rmse_vector"] == pytest.approx(math.sqrt(5 / 6))


def test_improvement():
    assert improvement(0.01, 0.01) == 0.0  # as good as LS
    assert improvement(0.0, 0.01) == 100.0  # perfect
    # The paper's Table 3, V1: 100 (1 - 0.003503 / 0.009938) = 64.75 %.
    assert improvement(0.003503, 0.009938) == pytest.approx(64.75, abs=0.005)
    assert improvement(0.02, 0.01) == pytest.approx(-100.0)  # twice the LS error
    with pytest.raises(ValueError, match="rmse_ls"):
        improvement(0.01, 0.0)
    with pytest.raises(ValueError, match="rmse_model"):
        improvement(float("nan"), 0.01)


def test_perfect_prediction():
    got = report(TRUE, TRUE)
    assert got["vaf"] == 100.0
    assert got["r2"] == 1.0
    assert got["rmse"] == got["mae"] == got["rmse_vector"] == 0.0


def test_predicting_the_mean_speed_scores_zero():
    true = np.array([[1.0, 0.0, 0.0], [0.0, 3.0, 0.0]])  # speeds 1 and 3, mean 2
    pred = np.array([[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]])  # speed 2 both times
    assert r2(pred, true) == pytest.approx(0.0)
    assert vaf(pred, true) == pytest.approx(0.0)  # e = 2 - |t| varies exactly as |t|


def test_constant_true_speed_leaves_r2_and_vaf_undefined():
    true = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    assert math.isnan(r2(true * 1.1, true))
    assert math.isnan(vaf(true * 1.1, true))


def test_a_rotation_fools_the_speed_metrics_but_not_the_vector_ones():
    true = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    pred = np.array([[0.0, 1.0, 0.0], [-2.0, 0.0, 0.0]])  # each rotated 90 deg about z
    got = report(pred, true)
    assert got["rmse"] == got["mae"] == 0.0
    assert got["r2"] == 1.0 and got["vaf"] == 100.0
    # Component errors: x [-1, -2], y [1, -2], z [0, 0]: sqrt(5/2), sqrt(5/2), 0.
    assert got["rmse_x"] == pytest.approx(math.sqrt(2.5))
    assert got["rmse_y"] == pytest.approx(math.sqrt(2.5))
    assert got["rmse_z"] == 0.0
    # |p - t|^2 = 1 + 1 = 2 and 4 + 4 = 8: sqrt(10 / 2) = sqrt(5).
    assert got["rmse_vector"] == pytest.approx(math.sqrt(5.0))


@pytest.mark.parametrize("func", [rmse, mae, r2, vaf, rmse_per_axis, rmse_vector, report])
def test_shapes_are_checked(func):
    with pytest.raises(ValueError, match=r"pred must have shape \(S, 3\).*got \(3, 4\)"):
        func(np.zeros((3, 4)), np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"pred must have shape \(S, 3\).*got \(3,\)"):
        func(np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match=r"got \(0, 3\)"):
        func(np.zeros((0, 3)), np.zeros((0, 3)))
    expected = r"true must have the shape of pred, \(3, 3\), got \(2, 3\)"
    with pytest.raises(ValueError, match=expected):
        func(np.zeros((3, 3)), np.zeros((2, 3)))


@pytest.mark.parametrize("func", [rmse, mae, r2, vaf, rmse_per_axis, rmse_vector, report])
def test_nan_rows_are_counted(func):
    true = TRUE.copy()
    true[0, 1] = np.nan
    true[2, :] = np.nan
    with pytest.raises(ValueError, match="true has 2 of 3 rows with NaN"):
        func(PRED, true)
    pred = PRED.copy()
    pred[1, 2] = np.inf
    with pytest.raises(ValueError, match="pred has 1 of 3 rows with NaN or inf"):
        func(pred, TRUE)


def test_r2_and_vaf_are_undefined_when_the_speed_only_varies_by_round_off():
    from beamsnet import metrics

    rng = np.random.default_rng(0)
    true = np.column_stack([2.0 + 1e-15 * rng.standard_normal(100), np.zeros(100),
                            np.zeros(100)])
    pred = true + 0.01
    assert np.isnan(metrics.r2(pred, true)) and np.isnan(metrics.vaf(pred, true))
    varied = true.copy()
    varied[:, 0] = np.linspace(1.0, 2.0, 100)  # a real speed change: defined again
    assert np.isfinite(metrics.r2(varied + 0.01, varied))


def test_the_errors_plot_goes_logarithmic_past_ls_own_spread():
    from beamsnet.evaluate import error_spread

    error = np.concatenate([-np.arange(101.0), [np.nan]])  # |e| = 0 .. 100, and a NaN
    assert error_spread(error) == pytest.approx(99.0)
    assert error_spread(None) == 0.0 and error_spread(np.array([np.nan])) == 0.0


def test_position_scores_on_a_known_track():
    """A 3-4-5 offset north-east at the end of a 10 m leg east, with 7 m of depth error
    everywhere, which horizontal errors ignore: errors 0, 0, 5 m; RMSE sqrt(25 / 3); the
    final 50 % of the distance travelled."""
    reference = np.array([[0.0, 0.0, 20.0], [0.0, 5.0, 20.0], [0.0, 10.0, 20.0]])
    position = reference + [[0.0, 0.0, 7.0], [0.0, 0.0, 7.0], [3.0, 4.0, 7.0]]
    np.testing.assert_allclose(metrics.horizontal_errors(position, reference), [0.0, 0.0, 5.0])
    scores = metrics.position_scores(position, reference)
    assert scores == pytest.approx({"final_m": 5.0, "rmse_m": math.sqrt(25.0 / 3.0),
                                    "distance_m": 10.0, "final_percent": 50.0})
