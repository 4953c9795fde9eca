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


def geodetic_from_ned(ned: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """(N, 3) geodetic latitude (deg), longitude (deg) and height (m) of (N, 3) local NED
    positions relative to ``origin`` (latitude deg, longitude deg, height m): the inverse
    of ``ned_from_geodetic``, through Earth-centred coordinates, the latitude by fixed-point
    iteration of ``tan(lat) = (z + e^2 N(lat) sin(lat)) / p`` (Groves section 2.4.2), eight
    steps: the round trip through ``ned_from_geodetic`` is within 1e-8 m up to 60 km away
    (tests/test_seafloor_grid.py)."""
    lat0, lon0, h0 = (math.radians(origin[0]), math.radians(origin[1]), float(origin[2]))
    sl, cl, so, co = math.sin(lat0), math.cos(lat0), math.sin(lon0), math.cos(lon0)
    rot = np.array([[-sl * co, -sl * so, cl], [-so, co, 0.0], [-cl * co, -cl * so, -sl]])
    xyz = np.asarray(ned, float).reshape(-1, 3) @ rot + _ecef(np.array(lat0), np.array(lon0),
                                                               np.array(h0))
    x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - E2))
    for _ in range(8):
        n = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
        lat = np.arctan2(z + E2 * n * np.sin(lat), p)
    n = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    # The height from whichever of p and z is better conditioned at this latitude.
    steep = np.abs(np.cos(lat)) <= 0.5
    height = np.where(steep, z / np.where(steep, np.sin(lat), 1.0) - n * (1.0 - E2),
                      p / np.where(steep, 1.0, np.cos(lat)) - n)
    return np.stack([np.degrees(lat), np.degrees(np.arctan2(y, x)), height], axis=-1)


def _ecef(lat: np.ndarray, lon: np.ndarray, h: np.ndarray) -> np.ndarray:
    n = A / np.sqrt(1.0 - E2 * np.sin(lat) ** 2)
    return np.stack([(n + h) * np.cos(lat) * np.cos(lon), (n + h) * np.cos(lat) * np.sin(lon),
                     (n * (1.0 - E2) + h) * np.sin(lat)], axis=-1)


# What an inertial sensor measures over this Earth, for the simulator (``auvsim.config.
# LocationConfig``). MuJoCo flies the vehicle in a flat NED frame fixed to the ground,
# with the model's gravity along its down axis; with a geographic origin that frame is
# read as the local NED frame at the origin, turning with the Earth. Order of magnitude
# of what is and is not added, at the Snapir's 2 m/s and 32.85 N, against the navigation
# grade's in-run biases (10 micro-g, 0.01 deg/h; auvsim.sensors.imu):
# - the Earth's rate, 15.04 deg/h: added (gyro);
# - normal gravity instead of the model's 9.81: 9.7955 m/s^2 at 32.85 N, 1.5 milli-g
#   less; its free-air increase with depth, 3.09e-6 m/s^2 per m (6 micro-g at 20 m):
#   added (accelerometer). Under water the water above pulls up, 4 pi G rho = 0.86e-6
#   m/s^2 per m less (Bouguer), 1.8 micro-g at 20 m: left out, as normal gravity does;
# - the Coriolis term 2 w_ie x v: at 2 m/s, 2 Omega sin(lat) v = 1.6e-4 m/s^2 (16
#   micro-g) across the track, and up to 2 Omega cos(lat) v = 2.4e-4 m/s^2 vertically on
#   an east or west heading: one and a half to two and a half times the in-run bias, and
#   what a navigation filter subtracts whenever it models the Earth's rate (left in the
#   data, a filter would read it as a bias that turns with the heading): added
#   (accelerometer);
# - the transport rate v / R, 3.1e-7 rad/s (0.065 deg/h) at 2 m/s, and its term in the
#   accelerometers, 6e-7 m/s^2 (0.06 micro-g): left out. The flat world does not curve,
#   so its frame does not turn as the vehicle moves; over a 600 s mission it would turn
#   the heading by 0.011 deg;
# - the latitude held at the origin's: 1 km north changes the Earth's rate by 0.002
#   deg/h and gravity by 7.4e-6 m/s^2 (0.8 micro-g).
def specific_force_on_earth(flat_specific_force: np.ndarray, rotation: np.ndarray,
                            velocity_ned: np.ndarray, depth: np.ndarray, *,
                            latitude_deg: float, flat_gravity: float) -> np.ndarray:
    """(N, 3) specific force an ideal accelerometer reads on the rotating Earth, m/s^2,
    body: ``f = C^T (a + 2 w_ie x v - g_n)`` (the velocity equation of Groves' local
    navigation frame, ch. 5, without the transport rate), with
    g_n = (0, 0, ``normal_gravity(latitude_deg, -depth)``), from the flat world's
    ``f_flat = C^T (a - g_flat)``, whose gravity is (0, 0, ``flat_gravity``)::

        f = f_flat + C^T ((g_flat - g_n) e_down + 2 w_ie x v)

    Args:
        flat_specific_force: (N, 3) m/s^2, body, the flat world's.
        rotation: (N, 3, 3) body -> NED, C.
        velocity_ned: (N, 3) m/s, the sensor's velocity over the ground, NED.
        depth: (N,) m, the sensor's depth (positive down).
        latitude_deg: deg, the origin's.
        flat_gravity: m/s^2, the flat world's gravity.
    """
    extra = 2.0 * np.cross(earth_rate_ned(latitude_deg), velocity_ned)
    extra[:, 2] += flat_gravity - normal_gravity(latitude_deg, -np.asarray(depth, float))
    return flat_specific_force + np.einsum("nji,nj->ni", rotation, extra)


def earth_rate_body(rotation: np.ndarray, latitude_deg: float) -> np.ndarray:
    """(N, 3) the Earth's rate in body axes, rad/s: ``C^T w_ie`` with C the (N, 3, 3)
    body -> NED rotations, what a gyro at rest in the local NED frame reads."""
    return np.einsum("nji,j->ni", rotation, earth_rate_ned(latitude_deg))
