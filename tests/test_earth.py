"""WGS-84 helpers against published values and independent geometry."""

import math

import numpy as np
import pytest

from auvsim.physics import earth


def test_normal_gravity_at_equator_and_poles_is_wgs84s():
    # TR8350.2 table 3.4: gamma_e and gamma_p are the formula's values at 0 and 90 deg.
    assert earth.normal_gravity(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert earth.normal_gravity(90.0) == pytest.approx(9.8321849378, abs=1e-9)
    # The International Gravity Formula 1980's series (Moritz 1980, "Geodetic Reference
    # System 1980"), an independent closed form, agrees to its stated 1e-6 relative.
    for lat in np.arange(0.0, 91.0, 7.5):
        s = math.sin(math.radians(lat))
        series = 9.780327 * (1 + 0.0053024 * s**2 - 0.0000058 * math.sin(math.radians(2 * lat))**2)
        assert earth.normal_gravity(lat) == pytest.approx(series, rel=1e-6)


def test_free_air_gradient_is_about_3_086_um_per_s2_per_m():
    g0, g1 = earth.normal_gravity(32.85, 0.0), earth.normal_gravity(32.85, 100.0)
    assert (g0 - g1) / 100.0 == pytest.approx(3.086e-6, rel=2e-3)


def test_earth_rate_has_the_right_size_and_direction():
    w = earth.earth_rate_ned(32.85)
    assert np.linalg.norm(w) == pytest.approx(7.292115e-5, rel=1e-12)
    assert w[1] == 0.0 and w[0] > 0 and w[2] < 0
    assert math.degrees(math.atan2(-w[2], w[0])) == pytest.approx(32.85)


def test_small_steps_north_and_east_follow_the_radii_of_curvature():
    lat = 32.85
    rn, re = earth.radii(lat)
    d = 1e-4  # deg
    ned = earth.ned_from_geodetic([lat + d, lat], [35.0, 35.0 + d], [0.0, 0.0], (lat, 35.0, 0.0))
    assert ned[0, 0] == pytest.approx(rn * math.radians(d), rel=1e-6)
    assert ned[1, 1] == pytest.approx(re * math.cos(math.radians(lat)) * math.radians(d), rel=1e-6)
    deeper = earth.ned_from_geodetic([lat], [35.0], [-20.0], (lat, 35.0, 0.0))
    np.testing.assert_allclose(deeper, [[0.0, 0.0, 20.0]], atol=1e-6)
