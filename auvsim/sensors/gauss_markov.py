"""The first-order Gauss-Markov process of the sensors' slowly drifting errors (the IMU's
in-run biases, the DVL's velocity error the beams share), per axis, discretised exactly::

    x[k + 1] = phi x[k] + std sqrt(1 - phi^2) w[k],   phi = exp(-dt / tau),   w ~ N(0, 1)

with stationary std ``std`` and autocorrelation ``exp(-lag / tau)``. Not a plugin (no
``SENSOR``): a helper both sensors call. (The water's current has its own, a scalar path,
``auvsim.physics.water.gauss_markov``.)
"""

from __future__ import annotations

import math

import numba
import numpy as np


def gauss_markov_rows(state: np.ndarray, drive: np.ndarray, *, std: float,
                      dt_over_tau: float) -> np.ndarray:
    """The process at N consecutive samples, from ``state`` and N rows of drive.

    Args:
        state: (3,) x at the first sample; updated in place to x after the last one, so
            that blocks of any length give the same path.
        drive: (N, 3) standard normal draws w, one row per sample.
        std: stationary std, in the unit of ``state``.
        dt_over_tau: the sample interval over the correlation time, dt / tau (> 0).

    Returns:
        (N, 3) x[0], ..., x[N - 1].
    """
    phi = math.exp(-dt_over_tau)
    # sqrt(1 - phi^2) via expm1: 1 - phi^2 would lose digits as dt << tau sends phi -> 1.
    drive_std = std * math.sqrt(-math.expm1(-2.0 * dt_over_tau))
    out = np.empty(drive.shape)
    _advance(out, drive, state, phi, drive_std)
    return out


@numba.njit(cache=True)
def _advance(out, drive, state, phi, drive_std):
    """Write x[k] into row k of ``out`` and advance x[k + 1] = phi x[k] + drive_std w[k]
    (``state`` holds x)."""
    for k in range(out.shape[0]):
        for j in range(3):
            out[k, j] = state[j]
            state[j] = phi * state[j] + drive_std * drive[k, j]
