"""A DVL velocity on every ping, whatever beams it lost: missing beams regressed from the
beams that are there and the past pings, then least squares (paper eq. 9) on all four.

In the spirit of MissBeamNet (Yona & Klein 2024, which regresses a missing beam from the
past beams with a network), but linear: one least-squares regressor per missing-beam
pattern (the 15 patterns of 1 to 4 missing beams), with the inputs
``[available current beams, the last p pings' four beams (oldest first), 1]``, fitted on
the complete pings of the training split with each pattern masked synthetically.

Why linear suffices for the first missing beam: a Janus DVL's four beams are linearly
dependent (``H`` has rank 3; for the x-configuration of ``auvsim.sensors.dvl.beam_matrix``
``h_1 + h_3 = h_2 + h_4``), and with eq. 7's errors any three valid beams fix v and so the
fourth, affinely: one missing beam is exactly recoverable on noise-free data, and with
noise the past pings lower its noise. Two or more missing beams leave v underdetermined
by the current ping; the past pings carry it (exactly at constant velocity, or at constant
acceleration with 2 past pings, on noise-free data).
"""

from __future__ import annotations

import numpy as np

from auvsim.sensors.dvl import least_squares

from .baselines import _check_fitted
from .data import Windows

# Singular values below this fraction of the largest are round-off: a noise-free training
# set has exact linear dependencies (the four beams of a ping; past and current pings at
# constant velocity), which then get no weight instead of a huge one.
RCOND = 1e-10


def _inputs(current: np.ndarray, past: np.ndarray) -> np.ndarray:
    """(N, a + 4 p + 1) regressor inputs from the available current beams (N, a) and the
    past pings' beams (N, p, 4), m/s."""
    return np.column_stack([current, past.reshape(len(past), -1), np.ones(len(current))])


class MissingBeamRegressor:
    """Missing beams from the available current beams and the past pings, by linear least
    squares, then LS on the four beams (3 valid beams alone give LS's estimate exactly on
    noise-free data; see the module docstring).

    One regressor per pattern of missing beams (bit k of the code: beam k missing) and per
    number p of past pings used, p = n_past down to 0 (p = 0 only for one missing beam:
    two beams do not fix a velocity). A ping uses the largest p whose past pings are all
    known. ``fill`` runs sequentially over each mission's samples in time order: a past
    ping that is itself a sample of the windows contributes its own filled beams (so a
    dead beam is carried by the earlier estimates of it), any other its measured beams;
    consecutive samples are consecutive pings only when their times differ by one ping
    period (the median step of the mission), and a gap's pings count as unknown. So it
    gives an estimate on every ping of a mission from the first whose past pings are known
    (with 3 valid beams, from the first ping), including pings without any valid beam.

    Attributes (after fit):
        n_past: past pings the regressors use (that of the training windows).
        coef: {(pattern code, p): (n_inputs, n_missing) coefficients}.
    """

    name = "Missing-beam LS"

    def __init__(self) -> None:
        self.coef: dict[tuple[int, int], np.ndarray] = {}
        self.n_past: int | None = None
        self.h: np.ndarray | None = None

    def fit(self, train: Windows) -> MissingBeamRegressor:
        n_past = train.past_beams.shape[1]
        ok = np.isfinite(train.beams).all(axis=1) & np.isfinite(train.past_beams).all(axis=(1, 2))
        if ok.sum() < 4 * n_past + 5:
            raise ValueError(f"{type(self).__name__}.fit: {4 * n_past + 4} inputs need at "
                             f"least {4 * n_past + 5} complete training pings (all beams of "
                             f"the ping and its {n_past} past pings valid), got {ok.sum()}")
        y, past = train.beams[ok], train.past_beams[ok]
        self.coef = {}
        for code in range(1, 16):
            miss = (code >> np.arange(4)) & 1 == 1
            for p in range(n_past, -1, -1):
                if p == 0 and miss.sum() > 1:
                    continue
                x = _inputs(y[:, ~miss], past[:, n_past - p:])
                self.coef[code, p], *_ = np.linalg.lstsq(x, y[:, miss], rcond=RCOND)
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
        _check_fitted(self, windows)
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
            p = next(p for p in range(n, -1, -1) if complete[n - p:].all())
            miss = missing[i]
            code = int(miss @ (1 << np.arange(4)))
            coef = self.coef.get((code, p))
            if coef is not None:
                x = _inputs(filled[i, ~miss][None], known[None, n - p:])
                filled[i, miss] = (x @ coef)[0]
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
