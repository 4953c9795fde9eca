"""Water that moves: the ocean current around the vehicle, and the motion disturbances.

The current (``Water``) is, at time t and NED position p = (x, y, z)::

    c(t, p) = c_0 + f(z) [ U(t) (cos theta(t), sin theta(t), 0) + d(x, y) ]

- ``c_0``: the constant current of ``vehicle.current_ned`` (the setting that predates this
  module; it keeps working unchanged).
- ``U(t) = U_0 + u(t)``, ``theta(t) = theta_0 + a(t)``: the surface speed and the direction
  the water flows TOWARD (from north, clockwise), ``U_0`` and ``theta_0`` drawn per mission
  from the ``water`` stream (uniform in the configured ranges), ``u`` and ``a`` first-order
  Gauss-Markov processes (stationary std and correlation time in the config). U may pass
  through zero, as a turning tide's does.
- ``d(x, y)``: a slow spatial variation, a sum of ``SPATIAL_MODES`` plane waves of one
  wavelength with seeded directions and phases, each with a random (north, east)
  amplitude, so that its std over space is ``spatial_std`` per component.
- ``f(z)``: the depth law. ``power``: the 1/7 power law of a bottom boundary layer over
  the whole water column of depth H, ``f = ((H - z) / H) ** exponent`` (0 at the bed,
  1 at the surface; Soulsby 1997, Dynamics of Marine Sands, ch. 3, for tidal flows; ADCP
  profiles at tidal sites fit exponents 1/4.5 to 1/12.4: Korea Inst. of Ocean Sci. and
  Tech., J. Mar. Sci. Eng. 12 (2024) 1998). ``piecewise``: factors at given depths,
  linear between them, constant beyond the ends (a linear decrease is two points).

It is a pure function of time and position once the mission is built: the Gauss-Markov
paths are drawn in advance on a ``CURRENT_STEP`` grid for the whole mission (held at their
last value beyond it) and interpolated linearly, so the physics (``auvsim.physics.vehicle``, at
every step, by table lookup in the compiled loop) and any sensor (the DVL's water track,
``Platform.water.current_ned``) see the same water. One compiled function
(``current_at``) evaluates it for both.

The time derivative of the current (the Froude-Krylov and added-mass force of an
accelerating flow, (m + m_A) dc/dt) is neglected: with the navigator preset's water, along
the ``maneuvers`` tracks, the water at the vehicle accelerates by 1.0e-3 m/s^2 rms and
3.6e-3 m/s^2 at most, 1.4 N rms and 5 N at most on the A18-D's 1450 kg of mass and sway
added mass: below the turbulent forces it is given (18 N std in sway) and the 100 N class
forces of its hydrodynamics (``tests/test_water.py`` bounds it).

The motion disturbances (``Disturbance``) are seeded Gauss-Markov processes on a
``DISTURBANCE_STEP`` grid, interpolated linearly: a turbulent wrench (forces and moments in
body axes, added to the water's) and jitter of the shaft speed and of the fin angles
(added to the angles reached, in the force model and in the recorded controls). They are
drawn in segments as the mission proceeds, from the ``disturbance`` stream, so memory stays
flat in mission length; the values depend only on time, not on how the mission is cut into
blocks.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

CURRENT_STEP = 10.0  # s: grid of the current's Gauss-Markov paths (correlation times >= 60 s)
DISTURBANCE_STEP = 0.1  # s: grid of the disturbances (ten physics steps of 10 ms)
SEGMENT = 600  # disturbance grid points drawn at a time (60 s)
SPATIAL_MODES = 8  # plane waves of the spatial variation: a few, so it is a smooth field
PROFILES = ("power", "piecewise")


class WaterTable(NamedTuple):
    """The current as the compiled loop reads it (``current_at``); see ``Water``.

    Attributes:
        active: False when the water's own part is zero everywhere (only ``c_0`` moves).
        step: s between grid points of ``surface``.
        surface: (K, 2) m/s, the surface current (north, east) at times 0, step, ...
        profile: 0 power law, 1 piecewise linear.
        exponent: of the power law.
        water_depth: m, H of the power law.
        depths, factors: (P,) m and -, the piecewise-linear law.
        wave: (J, 2) rad/m, the spatial modes' wave vectors (north, east).
        phase: (J,) rad.
        amplitude: (J, 2) m/s, each mode's (north, east) amplitude.
    """

    active: bool
    step: float
    surface: np.ndarray
    profile: int
    exponent: float
    water_depth: float
    depths: np.ndarray
    factors: np.ndarray
    wave: np.ndarray
    phase: np.ndarray
    amplitude: np.ndarray


def still_water() -> WaterTable:
    """The table of water whose own part is zero (``active`` False): only ``c_0`` moves."""
    zeros = np.zeros((SPATIAL_MODES, 2))
    return WaterTable(active=False, step=CURRENT_STEP, surface=np.zeros((2, 2)), profile=0,
                      exponent=1.0 / 7.0, water_depth=100.0, depths=np.zeros(1),
                      factors=np.ones(1), wave=zeros, phase=np.zeros(SPATIAL_MODES),
                      amplitude=zeros.copy())


def gauss_markov(rng: np.random.Generator, n: int, std: float, tau: float, step: float,
                 start: float | None = None) -> np.ndarray:
    """A first-order Gauss-Markov path at ``n`` grid points ``step`` apart, exact in
    discrete time: ``x[k+1] = phi x[k] + std sqrt(1 - phi^2) w[k]``, ``phi = exp(-step /
    tau)``, ``w ~ N(0, 1)``; started from its stationary distribution N(0, std^2), or at
    ``start`` (the previous segment's last value) followed by n new points.

    Returns: (n,) path, in the unit of ``std``.
    """
    w = rng.standard_normal(n)
    phi = math.exp(-step / tau)
    drive = std * math.sqrt(1.0 - phi * phi)
    out = np.empty(n)
    x = std * w[0] if start is None else phi * start + drive * w[0]
    out[0] = x
    for k in range(1, n):
        x = phi * x + drive * w[k]
        out[k] = x
    return out


class Water:
    """The current of one mission (module docstring): drawn once, then a pure function.

    Args:
        config: the ``water`` section (``auvsim.config.WaterConfig``).
        rng: the mission's ``water`` stream.
        duration: s, the mission's length (the paths are drawn to cover it).
        constant_ned: (3,) m/s, the constant current ``c_0`` (``vehicle.current_ned``).
        water_depth: m, H of the power law when the config leaves it to the seafloor.
    """

    def __init__(self, config, rng: np.random.Generator, *, duration: float,
                 constant_ned=(0.0, 0.0, 0.0), water_depth: float = 100.0) -> None:
        self.config = config
        self.constant_ned = np.array(constant_ned, dtype=float)
        c = config
        # The per-mission draws and the spatial modes first, and each Gauss-Markov path
        # from a child stream of its own: a longer mission extends the paths of a shorter
        # one, so the water of a seed does not depend on the mission's duration.
        self.surface_speed = float(rng.uniform(c.speed_min, c.speed_max))
        spread = c.direction_spread_deg
        self.direction_deg = float(c.direction_deg + rng.uniform(-spread, spread))
        heading = rng.uniform(0.0, 2.0 * math.pi, SPATIAL_MODES)
        k = 2.0 * math.pi / c.spatial_wavelength
        wave = k * np.stack([np.cos(heading), np.sin(heading)], axis=1)
        phase = rng.uniform(0.0, 2.0 * math.pi, SPATIAL_MODES)
        # A cosine of random phase has variance 1/2, so N(0, 2 std^2 / J) amplitudes give
        # each component a variance of std^2 over space.
        amplitude = rng.normal(0.0, c.spatial_std * math.sqrt(2.0 / SPATIAL_MODES),
                               (SPATIAL_MODES, 2))
        speed_rng, direction_rng = rng.spawn(2)
        n = int(math.ceil(duration / CURRENT_STEP)) + 2  # grid points covering the mission
        speed = self.surface_speed + gauss_markov(speed_rng, n, c.speed_std, c.speed_time,
                                                  CURRENT_STEP)
        theta = math.radians(self.direction_deg) + gauss_markov(
            direction_rng, n, math.radians(c.direction_std_deg), c.direction_time,
            CURRENT_STEP)
        surface = np.stack([speed * np.cos(theta), speed * np.sin(theta)], axis=1)
        active = c.speed_max > 0 or c.speed_std > 0 or c.spatial_std > 0
        self.table = WaterTable(
            active=bool(active), step=CURRENT_STEP, surface=np.ascontiguousarray(surface),
            profile=PROFILES.index(c.profile), exponent=float(c.power_exponent),
            water_depth=float(water_depth if c.water_depth is None else c.water_depth),
            depths=np.array(c.profile_depths, dtype=float),
            factors=np.array(c.profile_factors, dtype=float), wave=wave, phase=phase,
            amplitude=amplitude)

    def current_ned(self, time: np.ndarray, position_ned: np.ndarray) -> np.ndarray:
        """The current at the given times and places, NED.

        Args:
            time: (M,) s from the mission start.
            position_ned: (M, 3) m, NED (z is depth).

        Returns:
            (M, 3) m/s, NED: exactly what the vehicle's physics sees at that time and place.
        """
        time = np.ascontiguousarray(time, dtype=float).reshape(-1)
        position_ned = np.ascontiguousarray(position_ned, dtype=float).reshape(-1, 3)
        if len(time) != len(position_ned):
            raise ValueError(f"time and position_ned: expected as many times as positions, "
                             f"got {len(time)} and {len(position_ned)}")
        out = np.empty((len(time), 3))
        _currents(self.table, self.constant_ned, time, position_ned, out)
        return out


@numba.njit(cache=True, nogil=True)
def depth_factor(w, z):
    """f(z) of the module docstring: the current at depth z (m) over the surface's."""
    if w.profile == 0:
        height = (w.water_depth - z) / w.water_depth
        if height <= 0.0:
            return 0.0
        return min(height, 1.0) ** w.exponent
    d, f = w.depths, w.factors
    if z <= d[0]:
        return f[0]
    for i in range(1, d.shape[0]):
        if z <= d[i]:
            return f[i - 1] + (f[i] - f[i - 1]) * (z - d[i - 1]) / (d[i] - d[i - 1])
    return f[d.shape[0] - 1]


@numba.njit(cache=True, nogil=True)
def current_at(w, t, x, y, z):
    """The water's own current (NED, m/s, a 3-tuple) at time t (s) and NED point (x, y, z)
    (m), without the constant ``c_0``: the surface path interpolated in time, plus the
    spatial modes, times the depth law."""
    s = t / w.step
    last = w.surface.shape[0] - 1
    if s <= 0.0:
        i, frac = 0, 0.0
    elif s >= last:
        i, frac = last - 1, 1.0
    else:
        i = int(s)
        frac = s - i
    north = w.surface[i, 0] + frac * (w.surface[i + 1, 0] - w.surface[i, 0])
    east = w.surface[i, 1] + frac * (w.surface[i + 1, 1] - w.surface[i, 1])
    for j in range(w.phase.shape[0]):
        c = math.cos(w.wave[j, 0] * x + w.wave[j, 1] * y + w.phase[j])
        north += w.amplitude[j, 0] * c
        east += w.amplitude[j, 1] * c
    f = depth_factor(w, z)
    return (f * north, f * east, 0.0)


@numba.njit(cache=True, nogil=True)
def _currents(w, constant, time, position, out):
    for m in range(time.shape[0]):
        if w.active:
            c = current_at(w, time[m], position[m, 0], position[m, 1], position[m, 2])
            for i in range(3):
                out[m, i] = constant[i] + c[i]
        else:
            for i in range(3):
                out[m, i] = constant[i]


# Channels of a disturbance row: force (3, N) and moment (3, N m) in body axes FRD at the
# centre of buoyancy, then shaft-speed (rpm), rudder and stern-plane (rad) jitter.
CHANNELS = 9


class Disturbance:
    """The motion disturbances of one mission (module docstring).

    Args:
        config: the ``water`` section (``auvsim.config.WaterConfig``), its turbulence and
            jitter settings.
        rng: the mission's ``disturbance`` stream.
    """

    def __init__(self, config, rng: np.random.Generator) -> None:
        c = config
        self.config = config
        self.std = np.array([*c.turbulence_force_std, *c.turbulence_moment_std,
                             c.rpm_jitter_std, math.radians(c.fin_jitter_std_deg),
                             math.radians(c.fin_jitter_std_deg)])
        self.tau = np.array([c.turbulence_time] * 6 + [c.jitter_time] * 3)
        self.active = bool(np.any(self.std > 0))
        self._start_state = rng.bit_generator.state
        self._rng = rng
        self.reset()

    def reset(self) -> None:
        """Back to the mission start: the same paths are drawn again."""
        self._rng.bit_generator.state = self._start_state
        self._segments: dict[int, np.ndarray] = {}
        self._drawn = 0  # segments drawn so far
        self._last = None  # the last drawn row, where the next segment continues

    def _segment(self, j: int) -> np.ndarray:
        while self._drawn <= j:
            rows = np.empty((SEGMENT, CHANNELS))
            for c in range(CHANNELS):
                start = None if self._last is None else self._last[c]
                rows[:, c] = gauss_markov(self._rng, SEGMENT, float(self.std[c]),
                                          float(self.tau[c]), DISTURBANCE_STEP, start)
            self._last = rows[-1].copy()
            self._segments[self._drawn] = rows
            self._drawn += 1
        return self._segments[j]

    def table(self, t0: float, t1: float) -> tuple[int, np.ndarray]:
        """The grid rows covering times [t0, t1] s: the index of the first grid point and a
        (R, 9) array of rows from it. Earlier segments are forgotten (time runs forward;
        ``reset`` starts again)."""
        first = int(math.floor(t0 / DISTURBANCE_STEP)) // SEGMENT
        last = (int(math.floor(t1 / DISTURBANCE_STEP)) + 1) // SEGMENT
        rows = np.concatenate([self._segment(j) for j in range(first, last + 1)])
        for j in [j for j in self._segments if j < first]:
            del self._segments[j]
        return first * SEGMENT, rows


@numba.njit(cache=True, nogil=True)
def disturbance_at(rows, base, t, out):
    """The disturbance row at time t (s) into ``out`` (9,), interpolated in ``rows``, whose
    first row is grid point ``base``."""
    s = t / DISTURBANCE_STEP - base
    i = min(max(int(s), 0), rows.shape[0] - 2)
    frac = s - i
    for c in range(rows.shape[1]):
        out[c] = rows[i, c] + frac * (rows[i + 1, c] - rows[i, c])
