"""A DVL velocity on every ping, whatever beams it lost: missing beams regressed from the
beams that are there and the past pings, then least squares (paper eq. 9) on all four.

In the spirit of MissBeamNet (Yona & Klein 2024, which regresses a missing beam from the
past beams with a network), but linear: one least-squares regressor per missing-beam
pattern (the 15 patterns of 1 to 4 missing beams) and number of past pings, from the
available current beams and the past pings' four beams, fitted on the complete pings of
the training split with each pattern masked synthetically.

A Janus DVL's four beams are linearly dependent (``H`` has rank 3; for the x-configuration
of ``auvsim.data.beams.beam_matrix`` ``h_1 + h_3 = h_2 + h_4``), so one missing beam is
fixed by the other three: ``y_m = h_m . v_3``, v_3 their LS velocity, exact on noise-free
data without scale factors and biases, and LS on the four filled beams is then LS on the
three. Two or more missing beams leave v underdetermined by the current ping; the past
pings carry it.

The regressors are written as the last ping's beams plus a linear map of beam CHANGES:
``y_M(k) = y_M(k-1) + W [y_A(k) - y_A(k-1), y(k-1) - y(k-2), ...]`` (M the missing beams,
A the available ones), a linear regression on the same inputs constrained to hold the beams
when nothing changes. Why: fitted on straight lines, the free regression (inputs with an
intercept) fits its cross-beam terms to the beam noise, as ``AffineCalibration`` does its
cross-axis terms, and applies them in a turn; the constrained one learns from straight
lines little more than "hold", which is exact at constant velocity (and, with 2 past
pings, at constant acceleration when the training split has accelerations). The biases
cancel in the changes.
"""

from __future__ import annotations

import numpy as np

from auvsim.data.beams import least_squares
from beamsnet.data import DataError, Windows
from beamsnet.estimators.baselines import MORE_DATA, check_fitted
from beamsnet.estimators.registry import Needs, Spec

# Singular values below this fraction of the largest are round-off: a noise-free training
# set has exact linear dependencies (the four beams of a ping; past and current pings at
# constant velocity), which then get no weight instead of a huge one.
RCOND = 1e-10


def _design(current: np.ndarray, past: np.ndarray, miss: np.ndarray):
    """The regression of the missing beams ``miss`` (4,) bool from the current beams
    (N, 4; the missing ones are not read) and p >= 1 past pings (N, p, 4), m/s: inputs
    (N, a + 4 (p - 1)), the changes since the last ping of the a available beams and the
    past pings' changes, and the base (N, m), the missing beams of the last ping."""
    last = past[:, -1]
    x = np.column_stack([current[:, ~miss] - last[:, ~miss],
                         np.diff(past, axis=1).reshape(len(past), -1)])
    return x, last[:, miss]


class MissingBeamRegressor:
    """Missing beams from the available current beams and the past pings (see the module
    docstring), then LS on the four beams.

    One regressor per pattern of missing beams (bit k of the code: beam k missing) and per
    number p = n_past down to 1 of past pings used; a ping uses the largest p whose past
    pings are all known. One missing beam is filled from the other three by the geometry
    (p = 0: nothing fitted; LS on the filled four is LS on the three), unless
    ``one_from_past``: then by the regressors too, which lower the filled beam's noise
    where the vehicle's dynamics are those of the training split, and lag where they are
    not (a straight-line fit holds through a turn).

    ``fill`` runs sequentially over each mission's samples in time order: a past
    ping that is itself a sample of the windows contributes its own filled beams (so a
    dead beam is carried by the earlier estimates of it), any other its measured beams;
    consecutive samples are consecutive pings only when their times differ by one ping
    period (the median step of the mission), and a gap's pings count as unknown. So it
    gives an estimate on every ping of a mission from the first whose past pings are known
    (with 3 valid beams, from the first ping), including pings without any valid beam.

    Attributes (after fit):
        n_past: past pings the regressors use (that of the training windows).
        coef: {(pattern code, p): (n_inputs, n_missing) coefficients W}; for p = 0 the
            (3, 1) geometric map from the three available beams.
    """

    name = "Missing-beam LS"

    def __init__(self, *, one_from_past: bool = False) -> None:
        self.one_from_past = one_from_past
        self.coef: dict[tuple[int, int], np.ndarray] = {}
        self.n_past: int | None = None
        self.h: np.ndarray | None = None

    def fit(self, train: Windows) -> MissingBeamRegressor:
        n_past = train.past_beams.shape[1]
        ok = np.isfinite(train.beams).all(axis=1) & np.isfinite(train.past_beams).all(axis=(1, 2))
        if ok.sum() < 4 * n_past:
            raise DataError(f"{type(self).__name__}.fit: {4 * n_past - 1} inputs need at "
                            f"least {4 * n_past} complete training pings (all beams of "
                            f"the ping and its {n_past} past pings valid), got {ok.sum()}; "
                            f"{MORE_DATA}")
        y, past, h = train.beams[ok], train.past_beams[ok], train.h
        self.coef = {}
        for code in range(1, 16):
            miss = (code >> np.arange(4)) & 1 == 1
            if miss.sum() == 1:
                self.coef[code, 0] = (h[miss] @ np.linalg.inv(h[~miss])).T
                if not self.one_from_past:
                    continue
            for p in range(1, n_past + 1):
                x, base = _design(y, past[:, n_past - p:], miss)
                self.coef[code, p] = (np.linalg.lstsq(x, y[:, miss] - base, rcond=RCOND)[0]
                                      if x.shape[1] else np.zeros((0, miss.sum())))
        self.n_past, self.h = n_past, train.h
        return self

    def fill(self, windows: Windows, *, missing: np.ndarray | None = None) -> np.ndarray:
        """The (S, 4) beams, m/s, with every missing beam replaced by its regression; NaN
        where no regressor applies (before a mission's past pings are known, with two or
        more beams missing).

        Args:
            windows: the samples, with at least ``n_past`` past pings each.
            missing: (S, 4) bool, the beams to treat as missing (default: the NaN ones);
                what a masked beam holds is never read.
        """
        check_fitted(self, windows)
        n, s = self.n_past, len(windows.beams)
        if windows.past_beams.shape[1] < n:
            raise ValueError(f"{type(self).__name__}: fitted with {n} past pings, the windows "
                             f"have {windows.past_beams.shape[1]}")
        missing = ~np.isfinite(windows.beams) if missing is None else np.asarray(missing)
        if missing.shape != (s, 4) or missing.dtype != bool:
            raise ValueError(f"missing: expected a ({s}, 4) bool mask, got "
                             f"{missing.dtype} {missing.shape}")
        missing = missing | ~np.isfinite(windows.beams)
        filled = np.where(missing, np.nan, windows.beams)
        past = windows.past_beams[:, -n:]
        earlier = _earlier_samples(windows.mission, windows.time, n)
        order = np.lexsort((windows.time, windows.mission))
        for i in order[missing[order].any(axis=1)]:
            known = past[i].copy()  # (n, 4), oldest first
            for d in range(1, n + 1):  # a past ping that is a sample: its own filled beams
                if earlier[i, d - 1] >= 0:
                    known[n - d] = filled[earlier[i, d - 1]]
            complete = np.isfinite(known).all(axis=1)
            miss = missing[i]
            code = int(miss @ (1 << np.arange(4)))
            p = next((p for p in range(n, -1, -1)
                      if (code, p) in self.coef and complete[n - p:].all()), None)
            if p == 0:
                filled[i, miss] = filled[i, ~miss] @ self.coef[code, 0]
            elif p is not None:
                x, base = _design(filled[i][None], known[None, n - p:], miss)
                filled[i, miss] = (base + x @ self.coef[code, p])[0]
        return filled

    def predict(self, windows: Windows) -> np.ndarray:
        return least_squares(self.fill(windows), windows.h)


def _earlier_samples(mission: np.ndarray, time: np.ndarray, n: int) -> np.ndarray:
    """(S, n) index of the sample that is the ping d = 1..n before each sample in its
    mission, -1 where that ping is not a sample. A mission's ping period is the median
    step between its samples' times (s); times are matched to a tenth of it."""
    out = np.full((len(time), n), -1, dtype=np.int64)
    for m in np.unique(mission):
        rows = np.flatnonzero(mission == m)
        rows = rows[np.argsort(time[rows], kind="stable")]
        t = time[rows]
        if len(t) < 2:
            continue
        period = float(np.median(np.diff(t)))
        for d in range(1, n + 1):
            j = np.minimum(np.searchsorted(t, t - (d + 0.5) * period), len(t) - 1)
            hit = np.abs(t[j] - (t - d * period)) < 0.1 * period
            out[rows[hit], d - 1] = rows[j[hit]]
    return out


ESTIMATORS = (
    Spec("Missing-beam LS", "missing beams regressed from the others and the past pings, "
         "then LS", "model-based", make=MissingBeamRegressor,
         needs=Needs(beams=0, history=1, text="needs past pings"), order=70,
         why="its regressed beams are noisier than LS's exact solution on three"),
)
