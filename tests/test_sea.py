"""Scores against a reference (issue 24, item 4) and ``beamsnet reproduce sea`` (items 5, 9):
the scoring functions on known answers, the reference moved to the DVL, and the
estimators on recorded missions."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from beamsnet import metrics
from beamsnet.data import body_rate, quaternions_at, reference_velocity


def yawing(t: np.ndarray, rate: float) -> np.ndarray:
    """(T, 4) quaternions of a vehicle level and yawing at ``rate`` rad/s from north."""
    return np.stack([np.cos(rate * t / 2), 0 * t, 0 * t, np.sin(rate * t / 2)], axis=1)


def test_a_straight_track_with_a_known_drift_scores_its_known_errors():
    """North at 2 m/s for 400 s, the estimate drifting east at 1 cm/s: the error at t is
    0.01 t m, so final 4 m, RMSE 0.01 sqrt(mean t^2) over t = 0..400 s
    (mean t^2 = 400 x 801 / 6 s^2), and 4 m over 800 m travelled is 0.5 %."""
    t = np.arange(401.0)
    reference = np.stack([2.0 * t, 0 * t, 20 + 0 * t], axis=1)
    estimate = reference + np.stack([0 * t, 0.01 * t, 0.3 + 0 * t], axis=1)  # depth ignored
    scores = metrics.position_scores(estimate, reference)
    assert scores["final_m"] == pytest.approx(4.0, rel=1e-12)
    assert scores["rmse_m"] == pytest.approx(0.01 * math.sqrt(400 * 801 / 6), rel=1e-12)
    assert scores["distance_m"] == pytest.approx(800.0, rel=1e-12)
    assert scores["final_percent"] == pytest.approx(0.5, rel=1e-12)


def test_position_scores_refuse_mismatched_or_missing_rows():
    with pytest.raises(ValueError, match="shape of position"):
        metrics.position_scores(np.zeros((4, 3)), np.zeros((5, 3)))
    bad = np.zeros((4, 3))
    bad[2, 0] = np.nan
    with pytest.raises(ValueError, match="1 of 4 rows"):
        metrics.position_scores(bad, np.zeros((4, 3)))


def test_coverage_of_a_known_gaussian_error():
    """Errors drawn from N(0, sigma^2) and reported with that sigma lie within 3 sigma
    2 Phi(3) - 1 = 99.73 % of the time; two independent components both 99.73 %^2; a
    filter that reports half its sigma covers 2 Phi(1.5) - 1 = 86.64 %."""
    rng = np.random.default_rng(0)
    n, sigma = 200_000, 0.7
    error = sigma * rng.standard_normal((n, 2))
    std = np.full((n, 2), sigma)
    within = 2 * 0.5 * (1 + math.erf(3 / math.sqrt(2))) - 1  # 0.99730
    tolerance = 5 * math.sqrt(within * (1 - within) / n)  # five binomial sd
    assert metrics.coverage(error[:, 0], std[:, 0]) == pytest.approx(within, abs=tolerance)
    assert metrics.coverage(error, std) == pytest.approx(within**2, abs=2 * tolerance)
    half = math.erf(1.5 / math.sqrt(2))
    assert metrics.coverage(error[:, 0], std[:, 0] / 2) == pytest.approx(
        half, abs=5 * math.sqrt(half * (1 - half) / n))
    # Epochs without a sigma are not counted.
    std[: n // 2, 0] = np.nan
    assert metrics.coverage(error[:, 0], std[:, 0]) == pytest.approx(within, abs=2 * tolerance)


def test_the_body_rate_and_the_attitude_between_reference_samples():
    """A vehicle yawing at 0.3 rad/s (17 deg/s, the real segments' peaks), sampled at 1 Hz:
    the rate comes back exactly (every step is the same rotation), and the attitude half
    way between samples is the one at that time (nlerp of a 17 deg step: within 1e-4 rad
    of slerp, and slerp is exact here)."""
    t = np.arange(0.0, 30.0)
    q = yawing(t, 0.3)
    q[5:] *= -1  # the same attitudes, on the other hemisphere from sample 5 on
    mid = t[:-1] + 0.5
    np.testing.assert_allclose(body_rate(t, q, mid), np.tile([0, 0, 0.3], (len(mid), 1)),
                               atol=1e-12)
    got = quaternions_at(t, q, mid)
    want = yawing(mid, 0.3)
    angle = 2 * np.arccos(np.minimum(np.abs(np.sum(got * want, axis=1)), 1.0))
    assert angle.max() < 1e-4


class Fields(SimpleNamespace):
    """A group of a mission: its fields as attributes, ``in`` as the reader's."""

    def __contains__(self, name: str) -> bool:
        return name in vars(self)


def recorded_stub(t: np.ndarray, rate: float, speed: float, lever: np.ndarray,
                  mounting_yaw_deg: float, imu: bool) -> SimpleNamespace:
    """The parts of a recorded mission ``reference_velocity`` reads: a vehicle yawing at
    ``rate`` while flying forward at ``speed`` (body velocity (speed, 0, 0) at the
    reference point), its DVL at ``lever`` and yawed ``mounting_yaw_deg``."""
    heading = rate * t
    imu_t = np.arange(0.0, t[-1], 0.01)
    groups = {"reference"} | ({"imu"} if imu else set())
    return SimpleNamespace(
        name="stub", has=groups.__contains__,
        reference=Fields(time=t, quaternion=yawing(t, rate), velocity_ned=np.stack(
            [speed * np.cos(heading), speed * np.sin(heading), 0 * t], axis=1)),
        imu=Fields(time=imu_t, angular_rate=np.tile([0, 0, rate], (len(imu_t), 1))),
        attrs={"dvl_position_body": lever,
               "dvl_mounting_rpy_deg": np.array([0.0, 0.0, mounting_yaw_deg])})


@pytest.mark.parametrize("imu", [True, False])
def test_the_reference_velocity_at_the_dvl_is_the_body_velocity_plus_the_lever_arms(imu):
    """Forward at 2 m/s, yawing at 0.2 rad/s, the DVL 1.5 m aft and 0.3 m down, yawed
    45 deg: w x L = (0, 0, 0.2) x (-1.5, 0, 0.3) = (0, -0.3, 0) m/s in the body, so the
    body velocity at the DVL is (2, -0.3, 0), and the DVL frame sees it rotated by -45
    deg. The rate from the gyro or from the reference's attitudes gives the same."""
    t = np.arange(0.0, 20.0)
    lever = np.array([-1.5, 0.0, 0.3])
    m = recorded_stub(t, 0.2, 2.0, lever, 45.0, imu)
    pings = t[2:-2] + 0.25  # between the reference's samples
    got = reference_velocity(m, pings)
    c, s = math.cos(math.radians(45)), math.sin(math.radians(45))
    body = np.array([2.0, -0.3, 0.0])
    want = np.array([c * body[0] + s * body[1], -s * body[0] + c * body[1], 0.0])
    # Interpolated in the body frame, where a steady turn's velocity is constant: exact.
    np.testing.assert_allclose(got, np.tile(want, (len(pings), 1)), atol=1e-12)
