"""Model-based velocity estimators that BeamsNet is compared with, behind one interface:
``fit(train) -> self`` and ``predict(windows) -> (S, 3)`` DVL velocity in m/s, and a
``name`` for the row of a results table. Every estimator works on the samples of
``beamsnet.data`` (the same samples as V1 and V2), so every table has every row.

* ``LeastSquares``: paper eq. 9 on the current beams, nothing fitted.
* ``AffineCalibration``: ``v = A y + c`` fitted on the training split; removes the DVL's
  scale factors and biases (paper eq. 7), the systematic part of the LS error.
* ``BeamCalibration``: eq. 7's own 8 parameters, a scale factor and a bias per beam, then
  LS on the corrected beams (3 beams suffice).
* ``ScaleOffset``: ``v = k v_LS + c``, 4 parameters on the LS velocity (3 beams suffice).
* ``KalmanFilter``: a random-walk velocity filter over each mission's pings, on the
  affine-calibrated (default), the beam-calibrated or the raw LS velocity: removes much
  of the white-noise part, and restarts on a manoeuvre its innovations reveal.

``availability`` is the share of samples an estimator gives an estimate for.
"""

from __future__ import annotations

from functools import partial
from typing import Protocol

import numpy as np

from auvsim.data.beams import least_squares
from beamsnet.data import DataError, Windows
from beamsnet.estimators.registry import Needs, Spec

# q grid of the Kalman filter, m/s per sqrt(s): from "velocity constant to 10 um/s over
# an hour" to "changes by 1 m/s each second"; half-decade steps are finer than the RMSE's
# sensitivity to q near its optimum.
Q_GRID = np.logspace(-6.0, 0.0, 13)
# Manoeuvre gate of the Kalman filter: the 1 - 1e-3 quantile of chi-square with 3 degrees
# of freedom (scipy.stats.chi2.ppf(1 - 1e-3, 3)), so a filter whose model holds restarts
# on about one ping in 1000 (one false restart in 17 min at 1 Hz).
GATE = 16.266


class Estimator(Protocol):
    """What every baseline (and a trained BeamsNet wrapper) offers."""

    name: str

    def fit(self, train: Windows) -> Estimator: ...

    def predict(self, windows: Windows) -> np.ndarray: ...


class LeastSquares:
    """Paper eq. 9 on the current beams: ``v = (H^T H)^-1 H^T y``. Nothing to fit."""

    name = "LS"

    def fit(self, train: Windows) -> LeastSquares:
        return self

    def predict(self, windows: Windows) -> np.ndarray:
        return least_squares(windows.beams, windows.h)


# What a fit on too few training samples asks for (a DataError: a command line's one line).
MORE_DATA = "expected more training data (a longer dataset, or more of it in the training split)"


class AffineCalibration:
    """``v = A y + c``, A (3, 4), c (3,), by linear least squares from the measured beams
    to the true velocity of the training split.

    With eq. 7's errors, ``y = diag(1 + s) H v + b + n``, the noise-free inverse
    ``v = pinv(diag(1 + s) H) (y - b)`` is affine in y, so this removes the scale factors
    and biases, exactly on noise-free data. With noise it is the best linear predictor on
    the training distribution (regressing v on noisy y shrinks A a little towards the
    training mean: the errors-in-variables attenuation, small while the velocity varies
    much more than the beam noise).

    Attributes (after fit):
        a: (3, 4); c: (3,) m/s.
    """

    name = "Affine"
    # Beam directions whose spread in the training set is below this fraction of the
    # largest are round-off (noise-free data have no spread off H's column space): they
    # get no weight instead of a huge one.
    rcond = 1e-10

    def __init__(self) -> None:
        self.a: np.ndarray | None = None
        self.c: np.ndarray | None = None
        self.h: np.ndarray | None = None

    def fit(self, train: Windows) -> AffineCalibration:
        if len(train.target) < 5:
            raise DataError(f"{type(self).__name__}.fit: 15 parameters need at least 5 "
                            f"training samples, got {len(train.target)}; {MORE_DATA}")
        # Centred, so the intercept does not couple with A: better conditioned, same fit.
        y_mean, v_mean = train.beams.mean(axis=0), train.target.mean(axis=0)
        coef, *_ = np.linalg.lstsq(train.beams - y_mean, train.target - v_mean,
                                   rcond=self.rcond)
        self.a = coef.T
        self.c = v_mean - self.a @ y_mean
        self.h = train.h
        return self

    def predict(self, windows: Windows) -> np.ndarray:
        check_fitted(self, windows)
        return windows.beams @ self.a.T + self.c


def availability(prediction: np.ndarray) -> float:
    """Share of the rows of ``prediction`` (S, 3) that are an estimate (all finite): 1.0
    for an estimator that gives one on every sample, NaN for no rows."""
    prediction = np.asarray(prediction, dtype=float)
    if prediction.ndim != 2 or prediction.shape[1] != 3:
        raise ValueError(f"availability: expected (S, 3) velocities, got shape "
                         f"{prediction.shape}")
    return float(np.isfinite(prediction).all(axis=1).mean()) if len(prediction) else np.nan


class BeamCalibration:
    """Eq. 7 per beam: ``y_k = (1 + s_k) h_k . v + b_k``, the scale factor s_k and bias b_k
    (m/s) of each beam fitted by linear least squares against the true velocity of the
    training split (one 2-parameter regression of y_k on ``h_k . v`` per beam, over the
    samples where beam k is valid); prediction is LS (paper eq. 9) on the corrected beams
    ``(y_k - b_k) / (1 + s_k)``, so that 3 valid beams suffice and fewer give NaN.

    Why it transfers: its 8 parameters are the error model's own, and each beam's pair is
    fixed by that beam's line of sight alone, so any training velocity that varies along
    every beam (a straight line at two or more speeds does) determines all of them. An
    ``AffineCalibration`` (15 parameters) also has cross-axis terms, which only data that
    vary across the axes constrain: trained on straight lines (velocity along x) they are
    fitted to noise and then applied to a turn's sway. Noise-free, both are exact on the
    training directions; only this one is exact on the others.

    Attributes (after fit):
        scale: (4,) s_k, dimensionless; bias: (4,) b_k, m/s.
    """

    name = "Beam calibration"

    def __init__(self) -> None:
        self.scale: np.ndarray | None = None
        self.bias: np.ndarray | None = None
        self.h: np.ndarray | None = None

    def fit(self, train: Windows) -> BeamCalibration:
        u = train.target @ train.h.T  # (S, 4) true beam velocities, m/s
        scale, bias = np.empty(4), np.empty(4)
        for k in range(4):
            ok = np.isfinite(train.beams[:, k]) & np.isfinite(u[:, k])
            if ok.sum() < 2 or np.ptp(u[ok, k]) == 0:
                raise DataError(f"{type(self).__name__}.fit: beam {k} needs at least two "
                                f"training samples with different velocities along it, got "
                                f"{ok.sum()} sample(s); {MORE_DATA}")
            design = np.column_stack([u[ok, k], np.ones(ok.sum())])
            (gain, bias[k]), *_ = np.linalg.lstsq(design, train.beams[ok, k], rcond=None)
            scale[k] = gain - 1.0
        self.scale, self.bias, self.h = scale, bias, train.h
        return self

    def predict(self, windows: Windows) -> np.ndarray:
        check_fitted(self, windows)
        return least_squares((windows.beams - self.bias) / (1.0 + self.scale), windows.h)


class ScaleOffset:
    """``v = k v_LS + c``: one scale k for the LS velocity (paper eq. 9, 3 or 4 valid beams)
    and an offset c (3,) m/s, fitted by linear least squares against the true velocity of
    the training split (the 3 axes of every sample are rows of one regression).

    With the paper's error model (one scale factor s for all beams, a small bias) LS gives
    ``(1 + s) v + pinv(H) b`` exactly, which this inverts with ``k = 1 / (1 + s)``. Per-beam
    scale factors that differ are beyond it (``BeamCalibration`` has them), and so is a
    ping with 3 beams when there is a bias: LS then gives ``inv(H_3) b_3``, not the
    ``pinv(H) b`` that c was fitted on (the training split has 4 beams). Like
    ``BeamCalibration`` it has no cross-axis term, so straight-line training fixes it.

    Attributes (after fit):
        k: dimensionless; c: (3,) m/s.
    """

    name = "LS scale+offset"

    def __init__(self) -> None:
        self.k: float | None = None
        self.c: np.ndarray | None = None
        self.h: np.ndarray | None = None

    def fit(self, train: Windows) -> ScaleOffset:
        v_ls = least_squares(train.beams, train.h)
        ok = np.isfinite(v_ls).all(axis=1) & np.isfinite(train.target).all(axis=1)
        if ok.sum() < 2:
            raise DataError(f"{type(self).__name__}.fit: 4 parameters need at least 2 "
                            f"training samples with an LS velocity, got {ok.sum()}; {MORE_DATA}")
        n = int(ok.sum())
        design = np.column_stack([v_ls[ok].ravel(), np.tile(np.eye(3), (n, 1))])
        coef, *_ = np.linalg.lstsq(design, train.target[ok].ravel(), rcond=None)
        self.k, self.c, self.h = float(coef[0]), coef[1:], train.h
        return self

    def predict(self, windows: Windows) -> np.ndarray:
        check_fitted(self, windows)
        return self.k * least_squares(windows.beams, windows.h) + self.c


class KalmanFilter:
    """Random-walk velocity filter, run over each mission's samples in time order.

    Model, per mission: ``v_k = v_{k-1} + w_k``, ``w_k ~ N(0, q^2 dt_k I)`` (dt_k the time
    since the previous sample, s: with one ping per second this is q^2 per ping, and a
    ping skipped for lost bottom lock counts as the time it took); beams
    ``y_k = H v_k + n_k``, ``n_k ~ N(0, r^2 I)``.

    The filter is run on the velocity measurement ``z_k`` that the beams give, with
    ``H_z = I``: ``z = LS(y)``, ``R = r^2 (H^T H)^-1`` without calibration, which is the
    same filter as on the four beams (LS is a sufficient statistic of y for v), or, with
    ``calibrate=True`` (or ``"affine"``), ``z = A y + c`` of an ``AffineCalibration``
    fitted on the same training split and ``R = r^2 A A^T`` (the beam noise carried through
    the calibration), or with ``calibrate="beam"`` the LS velocity of a
    ``BeamCalibration``'s corrected beams, ``R = pinv(H_A) diag(r^2 / (1 + s_k)^2)
    pinv(H_A)^T`` over the valid beams A. LS and the beam calibration give z on 3 beams
    too, each ping with the R of its beams. Calibration is the default because the DVL's
    scale factor and bias are systematic: a filter only averages noise, it cannot remove
    them, and they dominate the LS error at the paper's settings. ``"beam"`` transfers
    from straight-line training to manoeuvres, the affine map does not (see
    ``BeamCalibration``).

    r is the RMS residual of the four-beam least-squares fit on the training beams
    (``|y - H v_ls|^2`` has one degree of freedom per ping: ``E = r^2``), so it needs no
    truth. On beams derived from a log's velocity (``Windows.derived``: no residual, and
    the noise is the velocity's), R is instead the covariance of the measurement's error
    against the training target (``r_velocity``), and r the RMS of its axes. q is the
    value of ``Q_GRID`` with the least velocity RMSE on the training split.
    Each mission starts from its first measurement (``x_0 = z_0``, ``P_0 = R``: the same as
    a diffuse prior), so nothing carries over a mission boundary.

    A manoeuvre restarts it the same way. q fitted on constant-velocity training is tiny,
    and a filter that has averaged n pings then follows a speed step with a gain of about
    1/n: the step's error decays as ``n / (n + j)`` over the next j pings. So each
    measurement is tested against the prediction first, with the normalised innovation
    squared ``d^2 = nu^T S^-1 nu`` (``nu = z - x``, ``S = P + q^2 dt I + R``), which is
    chi-square with 3 degrees of freedom while the random-walk model holds; above ``gate``
    (default ``GATE``, 1e-3 false restarts per ping) the model is rejected and the filter
    restarts from the measurement (``x = z``, ``P = R``), which then holds through the
    manoeuvre (after a restart S = 2R: a change of more than about 6 sigma per ping
    restarts every ping, a slower one whenever the lag reaches about 4 sigma) and averages
    again from the first ping the model fits. The test is the standard consistency test of
    a Kalman filter's innovations, used as a manoeuvre detector (Bar-Shalom, Li &
    Kirubarajan 2001, Estimation with Applications to Tracking and Navigation, chs. 5
    and 11); it needs R right, which the r from the beams' residual gives, and no truth.
    A step of dv along an axis with measurement std sigma is caught on the first ping when
    ``dv^2 / sigma^2 > gate`` (dv > 4.0 sigma). ``gate=None``: no test, the filter of
    before.

    A sample without a measurement (a beam without bottom lock for the affine calibration,
    which needs all four; two for LS and the beam calibration) is a prediction step only:
    the estimate holds and its covariance grows; before a mission's first measurement
    there is no estimate (NaN).

    Attributes (after fit): r (m/s), r_velocity (R, (m/s)^2, on derived beams; else None),
    q (m/s per sqrt(s)), calibration (or None), train_rmse (q -> training RMSE, m/s).
    """

    def __init__(self, *, calibrate: bool | str = True, q_grid: np.ndarray | None = None,
                 gate: float | None = GATE) -> None:
        if calibrate not in (True, False, "affine", "beam"):
            raise ValueError(f"calibrate: expected True, False, 'affine' or 'beam', got "
                             f"{calibrate!r}")
        if gate is not None and not gate > 0:
            raise ValueError(f"gate: expected a positive chi-square threshold (3 degrees of "
                             f"freedom) or None, got {gate!r}")
        self.gate = gate
        self.calibrate = calibrate
        notes = [n for n, on in (("LS input", not calibrate),
                                 ("beam calibration", calibrate == "beam"),
                                 ("no gate", gate is None)) if on]
        self.name = "KF" + (f" ({', '.join(notes)})" if notes else "")
        self.q_grid = Q_GRID if q_grid is None else np.asarray(q_grid, dtype=float)
        if self.q_grid.ndim != 1 or len(self.q_grid) == 0 or not np.all(self.q_grid > 0):
            raise ValueError(f"q_grid: expected positive values, m/s per sqrt(s), got "
                             f"{q_grid!r}")
        self.calibration: AffineCalibration | BeamCalibration | None = None
        self.h: np.ndarray | None = None
        self.r = self.q = None
        self.r_velocity: np.ndarray | None = None  # R where the beams are derived
        self.train_rmse: dict[float, float] = {}

    def fit(self, train: Windows) -> KalmanFilter:
        self.h = train.h
        self.calibration = (BeamCalibration().fit(train) if self.calibrate == "beam" else
                            AffineCalibration().fit(train) if self.calibrate else None)
        derived = [k for k, name in enumerate(train.names) if name in train.derived]
        measured = ~np.isin(train.mission, derived)
        self.r_velocity = None
        if measured.any():
            beams = train.beams[measured]
            residual = beams - least_squares(beams, train.h) @ train.h.T
            self.r = float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))))  # 4 - 3 = 1 dof
        else:
            # Beams derived from the instrument's velocity (H v, a log without beams) leave
            # no residual to measure their noise by (r would be 0, and the filter the
            # calibration alone), and their noise is the velocity's, not the beams'
            # through H: R is the measurement's error covariance against the training
            # target, and r the RMS of its axes.
            z = self._velocity(train)
            ok = np.isfinite(z).all(axis=1) & np.isfinite(train.target).all(axis=1)
            error = z[ok] - train.target[ok]
            self.r_velocity = error.T @ error / max(len(error) - 1, 1)
            self.r = float(np.sqrt(np.trace(self.r_velocity) / 3))
        z, cov = self._measurement(train)
        sse = _filter(z, cov, train.mission, train.time, self.q_grid, gate=self.gate,
                      target=train.target)
        errors = np.sqrt(sse / len(train.target))
        self.train_rmse = dict(zip(self.q_grid.tolist(), errors.tolist(), strict=True))
        self.q = float(self.q_grid[np.argmin(errors)])
        return self

    def predict(self, windows: Windows) -> np.ndarray:
        check_fitted(self, windows)
        z, cov = self._measurement(windows)
        return _filter(z, cov, windows.mission, windows.time, np.array([self.q]),
                       gate=self.gate)

    def _velocity(self, windows: Windows) -> np.ndarray:
        """z (S, 3) m/s: the calibration's velocity, or LS's without one."""
        c = self.calibration
        return least_squares(windows.beams, windows.h) if c is None else c.predict(windows)

    def _measurement(self, windows: Windows) -> tuple[np.ndarray, np.ndarray]:
        """z (S, 3) m/s and its noise covariance R (S, 3, 3), (m/s)^2."""
        c, z, n = self.calibration, self._velocity(windows), len(windows.beams)
        if self.r_velocity is not None:
            return z, np.broadcast_to(self.r_velocity, (n, 3, 3))
        if isinstance(c, AffineCalibration):
            return z, np.broadcast_to(self.r ** 2 * c.a @ c.a.T, (n, 3, 3))
        std = np.full(4, self.r) if c is None else self.r / (1.0 + c.scale)
        return z, _ls_covariance(np.isfinite(windows.beams), windows.h, std)


def _ls_covariance(valid: np.ndarray, h: np.ndarray, std: np.ndarray) -> np.ndarray:
    """(S, 3, 3) covariance, (m/s)^2, of LS (paper eq. 9) on the ``valid`` (S, 4) beams of
    each ping, with independent beam noise of ``std`` (4,) m/s: ``pinv(H_A) diag(std_A^2)
    pinv(H_A)^T``; that of four beams where fewer than three are valid (no estimate)."""
    out = np.empty((len(valid), 3, 3))
    pattern = valid @ (1 << np.arange(4))
    for code in np.unique(pattern):
        use = (code >> np.arange(4)) & 1 == 1
        if use.sum() < 3:
            use[:] = True
        g = np.linalg.pinv(h[use])
        out[pattern == code] = g @ np.diag(std[use] ** 2) @ g.T
    return out


def _filter(z: np.ndarray, cov: np.ndarray, mission: np.ndarray, time: np.ndarray,
            q_grid: np.ndarray, *, gate: float | None = None,
            target: np.ndarray | None = None) -> np.ndarray:
    """Kalman filter (H = I, random walk) of z over each mission, for every q at once.

    The missions run side by side (padded to the longest), and every q of the grid too,
    so the Python loop is over the samples of the longest mission only.

    Args:
        z: (S, 3) velocity measurements, m/s, in any order (sorted by mission and time
            here, and the estimates put back in the input order); a row with a NaN is
            no measurement (a prediction step; NaN estimates until the first one).
        cov: (S, 3, 3) measurement noise covariance of each row, (m/s)^2.
        mission, time: (S,) mission index and time, s, of each sample.
        q_grid: (G,) random-walk intensities, m/s per sqrt(s).
        gate: restart from the measurement where its normalised innovation squared
            exceeds this (``KalmanFilter``); None: never.
        target: (S, 3) true velocities, m/s; given, return the sum of squared errors.

    Returns:
        (S, 3) estimates for q_grid[0] (for G = 1), or (G,) sums of squared errors, m^2/s^2.
    """
    if len(z) == 0:
        return np.zeros(len(q_grid)) if target is not None else np.empty((0, 3))
    order = np.lexsort((time, mission))
    m, t = mission[order], time[order]
    same = m[1:] == m[:-1]
    if np.any(same & (t[1:] <= t[:-1])):
        raise ValueError("Kalman filter: two samples of one mission at the same time; "
                         "filter the train and test windows separately")
    starts = np.flatnonzero(np.concatenate([[True], ~same]))
    lengths = np.diff(np.append(starts, len(m)))
    n_seq, n_steps = len(starts), int(lengths.max())
    # (n_seq, n_steps) padded index into the sorted samples; padding repeats the last row.
    step = np.minimum(np.arange(n_steps), lengths[:, None] - 1)
    rows = order[starts[:, None] + step]
    active = np.arange(n_steps) < lengths[:, None]
    dt = np.diff(t[starts[:, None] + step], axis=1, prepend=0.0)

    g = len(q_grid)
    eye = np.eye(3)
    measured = np.isfinite(z).all(axis=1)
    x = np.broadcast_to(z[rows[:, 0]], (g, n_seq, 3)).copy()
    p = np.broadcast_to(cov[rows[:, 0]], (g, n_seq, 3, 3)).copy()
    started = measured[rows[:, 0]]  # (n_seq,): a sequence's first measurement came
    out = np.empty((n_seq, n_steps, 3)) if target is None else None
    sse = np.zeros(g)
    q2 = q_grid[:, None, None, None] ** 2
    for k in range(n_steps):
        if k > 0:
            p_prior = p + q2 * dt[:, k, None, None] * eye
            r_k = cov[rows[:, k]]  # (n_seq, 3, 3)
            s_inv = np.linalg.inv(p_prior + r_k)
            gain = p_prior @ s_inv
            innovation = z[rows[:, k]] - x
            x_new = x + np.einsum("gnij,gnj->gni", gain, innovation)
            p_new = p_prior - gain @ p_prior
            p_new = 0.5 * (p_new + np.swapaxes(p_new, -1, -2))  # keep P symmetric
            live = active[:, k]
            seen = measured[rows[:, k]]
            update, first = live & seen & started, live & seen & ~started
            coast = live & ~seen & started  # no measurement: predict only
            # (G, n_seq): where to (re)start from the measurement: a sequence's first one,
            # or one whose innovation rejects the random-walk model
            reset = np.broadcast_to(first, (g, n_seq))
            update = np.broadcast_to(update, (g, n_seq))
            if gate is not None:
                nis = np.einsum("gni,gnij,gnj->gn", innovation, s_inv, innovation)
                restart = update & (nis > gate)  # NaN innovations compare False
                update, reset = update & ~restart, reset | restart
            x = np.where(update[..., None], x_new, np.where(reset[..., None], z[rows[:, k]], x))
            p = np.where(update[..., None, None], p_new,
                         np.where(reset[..., None, None], r_k,
                                  np.where(coast[:, None, None], p_prior, p)))
            started = started | first
        if target is None:
            out[:, k] = np.where(started[:, None], x[0], np.nan)
        else:
            err = x - target[rows[:, k]]
            sse += np.sum(np.where(active[:, k, None], err, 0.0) ** 2, axis=(1, 2))
    if target is not None:
        return sse
    estimate = np.empty_like(z)
    estimate[rows[active]] = out[active]
    return estimate


def check_fitted(estimator, windows: Windows) -> None:
    """Refuse ``predict`` before ``fit``, or on windows of another beam geometry than the
    training split's.

    Raises:
        RuntimeError: not fitted; ValueError: another beam geometry.
    """
    if estimator.h is None:
        raise RuntimeError(f"{type(estimator).__name__}: call fit(train) before predict")
    if not np.allclose(estimator.h, windows.h):
        raise ValueError(f"{type(estimator).__name__}: fitted on another beam geometry than "
                         "the windows to predict (beam angle differs)")


FOUR_BEAMS = Needs(beams=4, text="needs 4 beams")
ESTIMATORS = (
    Spec("LS", "least squares on the current beams (paper eq. 9), nothing fitted",
         "model-based", make=LeastSquares, needs=Needs(training=False),
         why="it is the reference", order=10),
    Spec("Affine", "affine calibration v = A y + c", "model-based", make=AffineCalibration,
         needs=FOUR_BEAMS, order=20,
         why="its 15 parameters were fitted on the training data; cross-axis terms that "
             "straight lines never constrain are exercised by every sway, heave and current"),
    Spec("Beam calibration", "a scale factor and a bias per beam, then LS", "model-based",
         make=BeamCalibration, needs=Needs(), order=30,
         why="its 8 per-beam parameters were fitted on the training data's sensor errors"),
    Spec("LS scale+offset", "v = k v_LS + c", "model-based", make=ScaleOffset,
         needs=Needs(), order=40,
         why="its scale and offset were fitted on the training data's sensor errors"),
    Spec("KF", "random-walk Kalman filter on the affine calibration", "model-based",
         make=KalmanFilter, needs=FOUR_BEAMS, order=50,
         why="it filters the affine calibration's velocity (and inherits its cross-axis "
             "errors), holding its estimate through pings without four beams"),
    Spec("KF (beam calibration)", "random-walk Kalman filter on the beam calibration",
         "model-based", make=partial(KalmanFilter, calibrate="beam"), needs=Needs(),
         order=60, why="a random walk lags a velocity that keeps changing, and holds "
                       "through gaps"),
)
