"""Accuracy of estimated DVL velocities: the paper's figures and the ones they hide.

Every function takes ``pred`` and ``true``, (S, 3) velocities in m/s (S samples, the three
axes of one frame, e.g. the DVL or body frame, FRD), and checks them first.

The paper (sec. 4, eqs. 16-19) computes RMSE, MAE, R^2 and VAF on the SPEED, the Euclidean
norm of each velocity, exactly as its published evaluation scripts do. A speed metric is
blind to direction: a prediction rotated by 90 degrees with the right length scores
perfectly. ``rmse_per_axis`` and ``rmse_vector`` compare the vectors themselves.
"""

from __future__ import annotations

import numpy as np


def _check(pred: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Both as float arrays of one shape (S, 3), S >= 1, without non-finite rows."""
    pred = np.asarray(pred, dtype=float)
    true = np.asarray(true, dtype=float)
    if pred.ndim != 2 or pred.shape[1] != 3 or pred.shape[0] < 1:
        raise ValueError(f"pred must have shape (S, 3) with S >= 1, got {pred.shape}")
    if true.shape != pred.shape:
        raise ValueError(f"true must have the shape of pred, {pred.shape}, got {true.shape}")
    for name, x in (("pred", pred), ("true", true)):
        bad = int(np.count_nonzero(~np.isfinite(x).all(axis=1)))
        if bad:
            raise ValueError(f"{name} has {bad} of {len(x)} rows with NaN or inf; "
                             "expected finite velocities (drop invalid epochs first)")
    return pred, true


def _speeds(pred: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S,) predicted and true speeds, m/s."""
    pred, true = _check(pred, true)
    return np.linalg.norm(pred, axis=1), np.linalg.norm(true, axis=1)


def rmse(pred: np.ndarray, true: np.ndarray) -> float:
    """Root mean square error of the speed, m/s (paper eq. 16): sqrt(mean (|p| - |t|)^2).

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.
    """
    sp, st = _speeds(pred, true)
    return float(np.sqrt(np.mean((sp - st) ** 2)))


def mae(pred: np.ndarray, true: np.ndarray) -> float:
    """Mean absolute error of the speed, m/s (paper eq. 17): mean | |p| - |t| |.

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.
    """
    sp, st = _speeds(pred, true)
    return float(np.mean(np.abs(sp - st)))


# Below this spread (m/s) the true speed counts as constant and R^2 and VAF, which divide
# by its variance, are undefined: on a constant-speed line the variance is round-off
# (about 1e-15 m/s), and dividing by it gave figures of -1e27.
CONSTANT_SPEED_STD = 1e-6


def _speed_variance(st: np.ndarray) -> float:
    var = float(np.var(st))
    return var if var > CONSTANT_SPEED_STD**2 else 0.0


def r2(pred: np.ndarray, true: np.ndarray) -> float:
    """Coefficient of determination of the speed, unitless (paper eq. 18): 1 - SSE/SST.

    SSE = sum (|p| - |t|)^2, SST = sum (|t| - mean |t|)^2. 1 is perfect; predicting the mean
    speed scores 0; worse than that is negative. NaN when the true speed is constant (its
    std below ``CONSTANT_SPEED_STD``), as on a constant-speed straight line.

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.
    """
    sp, st = _speeds(pred, true)
    var = _speed_variance(st)
    return float(1.0 - np.mean((sp - st) ** 2) / var) if var > 0 else float("nan")


def vaf(pred: np.ndarray, true: np.ndarray) -> float:
    """Variance accounted for by the speed, % (paper eq. 19): (1 - var(e)/var(|t|)) x 100.

    e = |p| - |t| and var is the population variance (ddof 0, as the published code). 100 is
    perfect. Unlike R^2 it ignores a constant error: a speed bias alone still scores 100.
    NaN when the true speed is constant (std below ``CONSTANT_SPEED_STD``).

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.
    """
    sp, st = _speeds(pred, true)
    var = _speed_variance(st)
    return float((1.0 - np.var(sp - st) / var) * 100.0) if var > 0 else float("nan")


def improvement(rmse_model: float, rmse_ls: float) -> float:
    """RMSE improvement over least squares, % (paper Tables 1 and 3): 100 (1 - model/LS).

    0 means no better than LS, 100 a perfect model, negative worse than LS.

    Args:
        rmse_model: the model's RMSE, m/s, >= 0.
        rmse_ls: the least-squares RMSE on the same samples, m/s, > 0.
    """
    if not (np.isfinite(rmse_model) and rmse_model >= 0):
        raise ValueError(f"rmse_model must be a finite RMSE >= 0, got {rmse_model!r}")
    if not (np.isfinite(rmse_ls) and rmse_ls > 0):
        raise ValueError(f"rmse_ls must be a finite RMSE > 0, got {rmse_ls!r}")
    return float(100.0 * (1.0 - rmse_model / rmse_ls))


def rmse_per_axis(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """(3,) RMSE of each velocity component, m/s: sqrt(mean (p_i - t_i)^2), i = x, y, z.

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.
    """
    pred, true = _check(pred, true)
    return np.sqrt(np.mean((pred - true) ** 2, axis=0))


def rmse_vector(pred: np.ndarray, true: np.ndarray) -> float:
    """RMSE of the velocity vector, m/s: sqrt(mean |p - t|^2), the length of the error.

    Equal to the root sum of squares of ``rmse_per_axis``, and never below ``rmse`` (the
    speed error |(|p| - |t|)| never exceeds |p - t|).

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.
    """
    pred, true = _check(pred, true)
    return float(np.sqrt(np.mean(np.sum((pred - true) ** 2, axis=1))))


def report(pred: np.ndarray, true: np.ndarray) -> dict[str, float]:
    """All the figures for one set of estimates.

    Args:
        pred: (S, 3) estimated velocities, m/s.
        true: (S, 3) true velocities, m/s.

    Returns:
        ``rmse``, ``mae`` (m/s), ``r2`` (unitless) and ``vaf`` (%) of the speed, as in the
        paper; ``rmse_x``, ``rmse_y``, ``rmse_z`` of each component and ``rmse_vector`` of
        the vector error (m/s), which also see errors of direction.
    """
    pred, true = _check(pred, true)
    x, y, z = rmse_per_axis(pred, true)
    return {
        "rmse": rmse(pred, true),
        "mae": mae(pred, true),
        "r2": r2(pred, true),
        "vaf": vaf(pred, true),
        "rmse_x": float(x),
        "rmse_y": float(y),
        "rmse_z": float(z),
        "rmse_vector": rmse_vector(pred, true),
    }


# Position against a reference, and the filter's reported uncertainty. A reference is what
# the score is against: the simulator's truth for a simulated mission, a recorded
# navigation solution (``reference_source``) for a recorded one; the functions do not care.


def horizontal_errors(position: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(T,) horizontal position error, m: |(p - r)_NE|, the north and east components only.

    Args:
        position: (T, 2) or (T, 3) estimated positions, m, NED (down ignored).
        reference: the reference positions at the same epochs, same shape, m.

    Raises:
        ValueError: shapes differ or are not (T, 2|3) with T >= 1, or a row is not finite.
    """
    position = np.asarray(position, dtype=float)
    reference = np.asarray(reference, dtype=float)
    if position.ndim != 2 or position.shape[1] not in (2, 3) or len(position) < 1:
        raise ValueError(f"position must have shape (T, 2) or (T, 3) with T >= 1, got "
                         f"{position.shape}")
    if reference.shape != position.shape:
        raise ValueError(f"reference must have the shape of position, {position.shape}, got "
                         f"{reference.shape}")
    error = np.linalg.norm(position[:, :2] - reference[:, :2], axis=1)
    if not np.isfinite(error).all():
        raise ValueError(f"position or reference has {int((~np.isfinite(error)).sum())} of "
                         f"{len(error)} rows with NaN or inf; expected finite positions")
    return error


def distance_travelled(reference: np.ndarray) -> float:
    """Horizontal length of a track, m: the sum of |r_{k+1} - r_k|_NE over (T, 2|3) NED
    positions."""
    reference = np.asarray(reference, dtype=float)
    return float(np.linalg.norm(np.diff(reference[:, :2], axis=0), axis=1).sum())


def position_scores(position: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Horizontal position error of a track against a reference at the same epochs.

    Args:
        position: (T, 2|3) estimated positions, m, NED, in the reference's frame.
        reference: (T, 2|3) reference positions, m.

    Returns:
        ``final_m``: the error at the last epoch; ``rmse_m``: sqrt(mean e^2) over the
        epochs; ``distance_m``: the reference's horizontal track length; ``final_percent``:
        100 final / distance, the drift per distance travelled that navigation papers
        quote (NaN on a track that did not move).
    """
    error = horizontal_errors(position, reference)
    distance = distance_travelled(reference)
    return {"final_m": float(error[-1]),
            "rmse_m": float(np.sqrt(np.mean(error**2))),
            "distance_m": distance,
            "final_percent": 100.0 * float(error[-1]) / distance if distance > 0
            else float("nan")}


def coverage(error: np.ndarray, std: np.ndarray, *, k: float = 3.0) -> float:
    """Share of epochs whose error lies within ``k`` times the reported standard
    deviation, every component at once: |e_i| <= k sigma_i for each i.

    For a filter whose covariance is right and whose errors are Gaussian, one component
    lies within 3 sigma 99.73 % of the time (2 Phi(3) - 1); two independent components
    (north and east) both do 99.46 % of the time. A filter that reports too small a
    sigma covers less.

    Args:
        error: (T,) or (T, D) errors (estimate minus reference), any unit.
        std: the reported standard deviations, the shape of ``error``, same unit, >= 0.
        k: how many sigma, > 0.

    Returns:
        The share in [0, 1]; epochs where either is not finite are not counted (NaN if
        none is left).
    """
    error = np.asarray(error, dtype=float)
    std = np.asarray(std, dtype=float)
    if error.shape != std.shape or error.ndim not in (1, 2):
        raise ValueError(f"error and std must have one shape, (T,) or (T, D); got "
                         f"{error.shape} and {std.shape}")
    if not (np.isfinite(k) and k > 0):
        raise ValueError(f"k must be a finite number > 0, got {k!r}")
    if error.ndim == 1:
        error, std = error[:, None], std[:, None]
    have = np.isfinite(error).all(axis=1) & np.isfinite(std).all(axis=1)
    if not have.any():
        return float("nan")
    return float(np.mean((np.abs(error[have]) <= k * std[have]).all(axis=1)))
