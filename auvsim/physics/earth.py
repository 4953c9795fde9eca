"""The Earth as navigation sees it: WGS-84 constants, the normal gravity and the Earth's
rate at a latitude, and geodetic positions as a local NED frame.

One copy for the simulated IMU, the recorded-log import, ``auvsim check-log`` and the
INS/DVL filter. A simulated mission without a geographic origin keeps auvsim's flat world
that does not rotate; with one (and always for a recorded log), these give the gravity and
the rotation a real inertial sensor sees there.

Sources: NIMA TR8350.2 "Department of Defense World Geodetic System 1984", 3rd ed. (2000),
tables 3.1 and 3.4, for the constants; Somigliana's closed formula for the normal gravity
on the ellipsoid (TR8350.2 eq. 4-1) and its free-air decrease with height to second order
(eq. 4-3); Groves 2013, "Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems", 2nd ed., eqs. 2.105-2.106 for the radii of curvature and 2.133 for
the Earth's rate in NED.
"""

from __future__ import annotations

import math

import numpy as np

# WGS-84 defining and derived constants (TR8350.2 tables 3.1, 3.3, 3.4).
A = 6378137.0  # m, semi-major axis
F = 1.0 / 298.257223563  # flattening
E2 = F * (2.0 - F)  # first eccentricity squared
OMEGA = 7.292115e-5  # rad/s, the Earth's rate
GM = 3.986004418e14  # m^3/s^2
GAMMA_E = 9.7803253359  # m/s^2, normal gravity at the equator
GAMMA_P = 9.8321849378  # m/s^2, at the poles
B = A * (1.0 - F)  # m, semi-minor axis
K_SOMIGLIANA = B * GAMMA_P / (A * GAMMA_E) - 1.0
M_GEODETIC = OMEGA**2 * A**2 * B / GM


def normal_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Magnitude of the WGS-84 normal gravity, m/s^2, at a geodetic latitude (deg) and a
    height above the ellipsoid (m; negative below it, as under water): Somigliana's
    formula, then the free-air term to second order in the height (TR8350.2 eq. 4-1 and
    4-3). The plumb line and the ellipsoid's normal agree to a few arc seconds, so the
    vector is (0, 0, g) in NED."""
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    gamma = GAMMA_E * (1.0 + K_SOMIGLIANA * s2) / math.sqrt(1.0 - E2 * s2)
    h = height_m
    return gamma * (1.0 - 2.0 / A * (1.0 + F + M_GEODETIC - 2.0 * F * s2) * h
                    + 3.0 * h * h / A**2)


def earth_rate_ned(latitude_deg: float) -> np.ndarray:
    """(3,) the Earth's rate in a local NED frame, rad/s (Groves eq. 2.133): a north
    component Omega cos(lat) and a down one -Omega sin(lat)."""
    lat = math.radians(latitude_deg)
    return np.array([OMEGA * math.cos(lat), 0.0, -OMEGA * math.sin(lat)])


def radii(latitude_deg: float) -> tuple[float, float]:
    """Meridian (north-south) and transverse (east-west) radii of curvature, m
    (Groves eqs. 2.105, 2.106)."""
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    d = 1.0 - E2 * s2
    return A * (1.0 - E2) / d**1.5, A / math.sqrt(d)


def ned_from_geodetic(latitude_deg, longitude_deg, height_m, origin: tuple[float, float, float]
                      ) -> np.ndarray:
    """(N, 3) local NED positions, m, of geodetic points relative to ``origin`` (latitude
    deg, longitude deg, height m): exact through Earth-centred coordinates, so it holds
    for any distance a vehicle covers."""
    lat0, lon0, h0 = (math.radians(origin[0]), math.radians(origin[1]), float(origin[2]))
    xyz = _ecef(np.radians(latitude_deg), np.radians(longitude_deg), np.asarray(height_m, float))
    d = xyz - _ecef(np.array(lat0), np.array(lon0), np.array(h0))[..., None, :]
    sl, cl, so, co = math.sin(lat0), math.cos(lat0), math.sin(lon0), math.cos(lon0)
    rot = np.array([[-sl * co, -sl * so, cl], [-so, co, 0.0], [-cl * co, -cl * so, -sl]])
    return d @ rot.T


def _ecef(lat: np.ndarray, lon: np.ndarray, h: np.ndarray) -> np.ndarray:
    n = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - E2) + h) * np.sin(lat)], axis=-1)
