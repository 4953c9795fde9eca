"""Robust least squares: LS on the current beams, with an outlying beam detected by the
four-beam redundancy and dropped.

A Janus DVL's four beams over-determine a 3-D velocity by one: the residual of the
four-beam LS fit lies in the 1-D left null space of the beam matrix H (unit vector n,
``n^T H = 0``), so the whole redundancy is one number per ping, the error velocity
``e = n . y`` (m/s). A spike on any beam moves it; noise alone keeps it within a few
noise standard deviations.

That same geometry means one ping cannot say WHICH beam is wrong: the residual of a
spike on beam k is ``n n_k e_k``, and for a Janus DVL every ``|n_k|`` is 1/2, so the four
residuals have one size whichever beam spiked, and a Huber or Tukey reweighting of the
residuals (IRLS) weights the four beams alike and returns LS. So the estimator works in
two steps:

1. **Detect** with the error velocity: a ping of four valid beams is an outlier ping when
   ``|e - c| > K s``, with c the median and s the MAD-based standard deviation
   (``1.4826 MAD``) of the training split's error velocities, and ``K = 3.5`` the usual
   cut of the modified z-score (Iglewicz & Hoaglin 1993, How to Detect and Handle
   Outliers): a robust scale of the DVL's own noise (and of the error velocity its scale
   factors leave at the training speeds), which a spike does not inflate.
2. **Isolate** with the past pings: of the four three-beam LS solutions, the one that
   drops the spiked beam is exact (without noise) and the three others carry the spike;
   the one closest to the reference, the component-wise median of the past pings' LS
   velocities (each from three or four beams, outlier pings left out), is kept. Its
   estimate is that ping's own three beams: the past only chooses which beam to drop, it
   never biases the velocity. A ping whose past gives no reference keeps its four-beam LS.

With three valid beams there is no redundancy: the estimate is plain LS (and no
estimate below three, as LS). On clean data it is LS except on the rare ping (about one
in 2,000 for Gaussian noise) past the cut, which it solves from three beams.
"""

from __future__ import annotations

import numpy as np

from auvsim.data.beams import least_squares
from beamsnet.data import DataError, Windows
from beamsnet.estimators.baselines import MORE_DATA, check_fitted
from beamsnet.estimators.registry import Needs, Spec

K = 3.5  # the modified z-score's outlier cut (Iglewicz & Hoaglin 1993)
MAD_TO_STD = 1.4826  # a Gaussian's standard deviation per median absolute deviation
# m/s: the smallest scale taken, round-off in the error velocity of noise-free beams
# (about 1e-16 of a few m/s), so that exact data are not all outliers.
MIN_SCALE = 1e-12


def null_vector(h: np.ndarray) -> np.ndarray:
    """(4,) unit vector n with ``n^T h = 0``, for a (4, 3) beam matrix of rank 3."""
    return np.linalg.svd(h)[0][:, -1]


def error_velocity(beams: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(...,) error velocity ``n . y`` of beam velocities ``beams`` (..., 4), m/s; NaN
    where a beam is NaN."""
    return beams @ null_vector(h)


class RobustLeastSquares:
    """LS with an outlying beam detected by the error velocity and isolated by the past
    pings (see the module docstring).

    Attributes (after fit):
        center, scale: median and MAD-based standard deviation of the training split's
            error velocities, m/s; a ping is an outlier beyond ``center +- K scale``.
        h: (4, 3) beam matrix.
    """

    name = "Robust LS"

    def __init__(self) -> None:
        self.center: float | None = None
        self.scale: float | None = None
        self.h: np.ndarray | None = None

    def fit(self, train: Windows) -> RobustLeastSquares:
        e = error_velocity(train.beams, train.h)
        e = e[np.isfinite(e)]
        if len(e) == 0:
            raise DataError(f"{type(self).__name__}.fit: needs training samples with four "
                            f"valid beams, got none; {MORE_DATA}")
        self.center = float(np.median(e))
        self.scale = max(MAD_TO_STD * float(np.median(np.abs(e - self.center))), MIN_SCALE)
        self.h = train.h
        return self

    def outliers(self, beams: np.ndarray) -> np.ndarray:
        """(...,) bool: pings of four valid beams (..., 4) whose error velocity is past
        the cut."""
        e = error_velocity(beams, self.h)
        return np.isfinite(e) & (np.abs(e - self.center) > K * self.scale)

    def predict(self, windows: Windows) -> np.ndarray:
        check_fitted(self, windows)
        v = least_squares(windows.beams, self.h)
        bad = np.flatnonzero(self.outliers(windows.beams))
        if len(bad) == 0:
            return v
        reference = self._reference(windows.past_beams[bad])
        known = np.isfinite(reference).all(axis=1)
        bad, reference = bad[known], reference[known]
        # (B, 4, 3): the LS velocity of each ping without beam k.
        candidates = np.empty((len(bad), 4, 3))
        for k in range(4):
            beams = windows.beams[bad].copy()
            beams[:, k] = np.nan
            candidates[:, k] = least_squares(beams, self.h)
        distance = np.linalg.norm(candidates - reference[:, None, :], axis=2)
        v[bad] = candidates[np.arange(len(bad)), np.argmin(distance, axis=1)]
        return v

    def _reference(self, past: np.ndarray) -> np.ndarray:
        """(B, 3) component-wise median of the LS velocities of the past pings ``past``
        (B, p, 4), outlier pings left out; NaN where no past ping gives one."""
        v = least_squares(past.reshape(-1, 4), self.h).reshape(*past.shape[:2], 3)
        v[self.outliers(past)] = np.nan
        have = np.isfinite(v).all(axis=2)  # (B, p)
        out = np.full((len(past), 3), np.nan)
        for count in np.unique(have.sum(axis=1)):
            rows = np.flatnonzero(have.sum(axis=1) == count)
            if count == 0:
                continue
            # Each row's usable pings first (stable), then the median of those.
            order = np.argsort(~have[rows], axis=1, kind="stable")[:, :count]
            out[rows] = np.median(np.take_along_axis(v[rows], order[:, :, None], axis=1),
                                  axis=1)
        return out


ESTIMATORS = (
    Spec("Robust LS", "LS with an outlying beam dropped: detected by the error velocity, "
         "isolated by the past pings", "model-based", make=RobustLeastSquares,
         needs=Needs(), order=80,
         why="a ping whose error velocity passes the cut loses the beam that least agrees "
             "with the past pings, and where the velocity changes fast between pings the "
             "past can point at the wrong beam"),
)
