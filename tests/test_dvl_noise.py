"""The DVL's noise split into white beam noise, which the error velocity shows, and a slow
velocity error the beams share, which it does not (issue 24, item 8): known answers."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import flat, mission

from auvsim.config import DvlConfig
from auvsim.data.streams import STREAMS, stream_names
from auvsim.errors import ConfigError
from auvsim.runs.mission import MissionRun
from auvsim.runs.presets import preset
from auvsim.sensors.dvl import (
    Effects,
    beam_matrix,
    beam_noise_std,
    draw_calibration,
    draw_errors,
    error_velocity,
    least_squares,
    ping,
    slow_velocity_error,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from dvl_error import (  # noqa: E402  (the measurement behind the navigator's slow error)
    SLOW_FIT_LAGS,
    autocovariance,
    gauss_markov_fit,
    predicted_structure,
)

H30 = beam_matrix(math.radians(30))


def fly(dvl: DvlConfig, duration: float) -> tuple[MissionRun, dict]:
    """A straight 2 m/s mission at 20 m over a 60 m flat floor with this DVL; its fields,
    concatenated over blocks."""
    config = flat(mission(duration=duration, depth=20.0), dvl=dvl)
    run = MissionRun(config, config.missions[0])
    blocks = list(run.blocks())
    return run, {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}


def test_a_missions_error_velocity_has_the_analytic_std_and_does_not_see_the_slow_error():
    """White beam noise sigma: std(e) = sigma / (sqrt(2) sin(alpha)) over a mission's
    3000 pings (the sample std within 3 sigma / sqrt(2 N)). The slow error has its own
    stream: switched on, it leaves the white draws, so e changes only by rounding (its
    combination of the beams is orthogonal to H's columns) and LS moves by dv exactly."""
    sigma = 0.01
    white = DvlConfig(rate_hz=10.0, noise_std=sigma)
    run, plain = fly(white, 300.0)
    e = plain["dvl/error_velocity"]
    expected = sigma / (math.sqrt(2) * math.sin(math.radians(30)))
    assert len(e) == 3000 and np.isfinite(e).all()
    assert abs(e.std() - expected) < 3 * expected / math.sqrt(2 * len(e))
    assert run.attrs["dvl_slow_error_std"] == 0.0
    np.testing.assert_array_equal(run.attrs["dvl_slow_error_start"], 0.0)

    run, slow = fly(dataclasses.replace(white, slow_error_std=0.05, slow_error_time=20.0),
                    300.0)
    # Rounding of beams of about 1 m/s: a few units of 1e-16.
    np.testing.assert_allclose(slow["dvl/error_velocity"], e, rtol=0, atol=1e-15)
    dv = slow["dvl/velocity_ls"] - plain["dvl/velocity_ls"]
    assert dv.std(axis=0).min() > 0.02  # it is there, in the velocity
    np.testing.assert_allclose(dv[0], run.attrs["dvl_slow_error_start"], rtol=0, atol=1e-12)
    assert run.attrs["dvl_slow_error_time"] == 20.0


def test_slow_error_is_gauss_markov_with_its_std_and_correlation_time():
    """Autocorrelation exp(-lag / tau): e^-1 at lag tau; stationary std. An AR(1) of
    N samples estimates its lag-k autocorrelation and its variance within about
    sqrt((1 + phi^2) / ((1 - phi^2) N)) (Box & Jenkins): 0.007 here per axis."""
    std, tau, n = 0.018, 10.0, 200_000
    rng = np.random.default_rng(5)
    state = std * rng.standard_normal(3)
    dv = slow_velocity_error(state, n, std=std, time=tau, dt=1.0, rng=rng)
    x = dv - dv.mean(axis=0)
    lag = int(tau)
    r = (x[lag:] * x[:-lag]).sum(axis=0) / (x * x).sum(axis=0)
    assert np.all(np.abs(r - math.exp(-1.0)) < 0.03), r
    r1 = (x[1:] * x[:-1]).sum(axis=0) / (x * x).sum(axis=0)
    assert np.all(np.abs(r1 - math.exp(-0.1)) < 0.01), r1
    assert np.all(np.abs(dv.std(axis=0) / std - 1) < 0.03), dv.std(axis=0)


def test_slow_error_blocks_of_any_length_give_the_same_path():
    def path(sizes):
        rng, state = np.random.default_rng(9), np.array([0.01, -0.02, 0.005])
        return np.concatenate([slow_velocity_error(state, m, std=0.02, time=50.0, dt=0.5,
                                                   rng=rng) for m in sizes])
    np.testing.assert_array_equal(path([100]), path([1, 37, 0, 62]))


def test_error_velocity_ignores_a_velocity_error_and_ls_recovers_it():
    dv = np.random.default_rng(1).normal(scale=0.1, size=(50, 3))
    beams = dv @ H30.T
    assert np.all(np.abs(error_velocity(beams, H30)) <= 1e-16)
    np.testing.assert_allclose(least_squares(beams, H30), dv, rtol=0, atol=1e-15)


def test_the_navigators_velocity_error_per_axis_is_its_budget():
    """Over 400 missions of 600 pings at 2 m/s along the DVL's x, the along-track error of
    LS (white beam noise, per-beam scale factors and biases, the sound speed, the slow
    error, each drawn per mission as the plugin draws them) has the RMS of the analytic
    budget: sigma / (sqrt(2) sin a), s_std U / 2, c_std U, b_std / (sqrt(2) sin a) and
    the slow std, in quadrature (12.2 mm/s; the preset's docstring gives the terms'
    sources). With 400 missions the per-mission terms and the Gauss-Markov (19 s) give
    thousands of independent samples: the RMS within about 2 % (1 sigma), 6 % asked."""
    c = preset("navigator").dvl
    speed, pings, missions = 2.0, 600, 400
    v = np.tile([speed, 0.0, 0.0], (pings, 1))
    ranges = np.full((pings, 4), 40.0 / math.cos(math.radians(30)))
    rng = np.random.default_rng(11)
    errors_x = []
    for _ in range(missions):
        errors = draw_errors(c, rng)
        calibration = draw_calibration(c, rng)
        state = c.slow_error_std * rng.standard_normal(3)
        dv = slow_velocity_error(state, pings, std=c.slow_error_std, time=c.slow_error_time,
                                 dt=1.0 / c.rate_hz, rng=rng)
        std = beam_noise_std(ranges, np.linalg.norm(v, axis=1), c)
        extra = np.sqrt(np.maximum(std**2 - c.noise_std**2, 0.0)) * rng.standard_normal(
            (pings, 4))
        effects = Effects(status=np.zeros((pings, 4), dtype=np.int64),
                          sound_speed_ratio=calibration.sound_speed_ratio, extra_noise=extra,
                          outlier=None, outlier_error=np.zeros((pings, 4)),
                          water_velocity=None, water_lock=np.zeros((pings, 4), dtype=bool),
                          water_noise=np.zeros((pings, 4)), slow_error=dv)
        out = ping(v, np.ones((pings, 4), dtype=bool), h=H30, errors=errors,
                   noise_std=c.noise_std, rng=rng, effects=effects)
        errors_x.append(out["velocity_ls"][:, 0] - speed)
    rms = math.sqrt(np.mean(np.concatenate(errors_x) ** 2))
    sin_a = math.sin(math.radians(c.beam_angle_deg))
    sigma = c.noise_std + c.noise_speed_coeff * speed + c.noise_range_coeff * ranges[0, 0]
    budget = math.sqrt((sigma / (math.sqrt(2) * sin_a)) ** 2 + (c.scale_factor_std * speed / 2)
                       ** 2 + (c.sound_speed_std * speed) ** 2
                       + (c.bias_std / (math.sqrt(2) * sin_a)) ** 2 + c.slow_error_std**2)
    assert abs(rms / budget - 1) < 0.06, (rms, budget)


def test_the_navigators_white_beam_noise_gives_the_real_error_velocity():
    """At 2 m/s (no range term) sigma = 1.2 + 1.2 x 2 = 3.6 mm/s: e 5.1 mm/s, inside the
    4.3-5.6 mm/s the real Navigator shows at 1.2-4 m/s (benchmarks/dvl_error.py)."""
    c = preset("navigator").dvl
    assert c.noise_range_coeff == 0.0
    sigma = c.noise_std + c.noise_speed_coeff * 2.0
    e = sigma / (math.sqrt(2) * math.sin(math.radians(c.beam_angle_deg)))
    assert 0.0043 <= e <= 0.0056


def test_only_the_navigators_dvl_has_the_slow_error():
    for name in ("paper-sim", "paper-sim-text", "maneuvers", "sim2real"):
        assert preset(name).dvl.slow_error_std == 0.0, name
    assert preset("realistic-maneuvers").dvl == preset("navigator").dvl


def test_the_slow_errors_stream_comes_after_every_earlier_one():
    names = stream_names()
    assert names[:len(STREAMS)] == STREAMS
    assert "dvl_slow_error" in names[len(STREAMS):]


@pytest.mark.parametrize("kwargs,field", [
    (dict(slow_error_std=-0.01), "dvl.slow_error_std"),
    (dict(slow_error_std=float("nan")), "dvl.slow_error_std"),
    (dict(slow_error_time=0.0), "dvl.slow_error_time"),
    (dict(slow_error_time=float("inf")), "dvl.slow_error_time"),
])
def test_bad_slow_error_settings_are_refused_naming_the_field(kwargs, field):
    with pytest.raises(ConfigError, match=field.replace(".", r"\.")):
        DvlConfig(**kwargs)


def test_the_slow_error_fit_and_its_structure_function_on_known_series():
    """What ``benchmarks/dvl_error.py`` fits to the real DVL, on series of known errors: a
    Gauss-Markov error of 9 mm/s over 19 s beside white noise of 5 mm/s, twelve series of
    400 pings (the six real segments' two horizontal axes), each series' mean removed as
    there. Over 20 such draws the fit through lags 1-20 s gives 8.5 +/- 0.4 mm/s and 14.9
    +/- 2.3 s (mean +/- std, seed 0): the mean's removal biases both low (by 5 % and
    22 %), so the real fit's 9.0 mm/s and 18.8 s say about 9.5 mm/s over 24 s, within
    two of one draw's std. The structure function 2 w^2 + 2 s^2 (1 - exp(-k / tau))
    is the mean square of the series' k-ping differences (within 5 %, 20 x 12 x 400
    pings)."""
    rng = np.random.default_rng(0)
    fits, diffs = [], {k: [] for k in (1, 3, 10)}
    for _ in range(20):
        series = []
        for _ in range(12):
            dv = slow_velocity_error(np.array([0.009 * rng.standard_normal(), 0.0, 0.0]), 400,
                                     std=0.009, time=19.0, dt=1.0, rng=rng)[:, 0]
            series.append(dv + 0.005 * rng.standard_normal(400))
            for k in diffs:
                diffs[k].append(series[-1][k:] - series[-1][:-k])
        c = autocovariance(series, np.arange(0, SLOW_FIT_LAGS[-1] + 1))
        fits.append(gauss_markov_fit(SLOW_FIT_LAGS, c[SLOW_FIT_LAGS], 1.0))
    sigma, tau = np.mean(fits, axis=0)
    assert 0.0082 < sigma < 0.0090 and 14.0 < tau < 18.0, (sigma, tau)
    for k, d in diffs.items():
        measured = np.mean(np.concatenate(d) ** 2)
        assert measured == pytest.approx(predicted_structure(0.005, 0.009, 19.0, [k])[0],
                                         rel=0.05), k
