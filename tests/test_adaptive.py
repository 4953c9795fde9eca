"""The model-based adaptive INS/DVL filter (``FilterConfig.adaptive = "innovation"``,
the estimator ``INS/DVL (adaptive)``): known answers on a generated mission whose beams
are noisier than the filter is told."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from conftest import zigzag

from auvsim.data.reader import open_dataset
from auvsim.errors import ConfigError
from beamsnet.cli import main
from beamsnet.estimators import ins, spec

NOISE = 0.01  # m/s, the beams' true white noise
WARM_UP = 1 / 3  # the share of the pings left out of the statistics (the window filling)


@pytest.fixture(scope="module")
def noisy(dataset_of):
    """200 s of zigzag, a navigation-grade IMU, beams of white noise ``NOISE`` at 1 Hz."""
    return dataset_of(zigzag(NOISE, 200.0), "noisy")


def run(path, **settings) -> tuple[ins.FilterTrack, np.ndarray]:
    """The track with ``settings``, and the true DVL-frame velocity at its pings."""
    with open_dataset(path) as f:
        m = f.missions["zz"]
        return ins.run_mission(m, ins.FilterConfig(**settings)), np.asarray(m.dvl.velocity)


def variance_ratio(track: ins.FilterTrack) -> float:
    """The adapted beam variance over the true one, averaged after the warm-up."""
    later = track.measurement_std[round(WARM_UP * len(track.ping_time)):]
    return float(np.mean(later**2) / NOISE**2)


def coverage(track: ins.FilterTrack, truth: np.ndarray) -> float:
    """Share of the velocity components within 3 sigma of the truth."""
    return float(np.mean(np.abs(track.velocity_dvl - truth) < 3 * track.velocity_std))


def test_told_a_third_of_the_noise_it_learns_the_noise_and_covers_the_truth(noisy):
    """Beams 3x noisier than told (9x the variance): the fixed filter's gate rejects
    about a quarter of the good measurements, its divergence watch restarts, and its
    3-sigma bounds cover the truth far less than 99.7 %; the adaptive filter's beam
    variance settles within 20 % of the true one, and it covers the truth."""
    fixed, truth = run(noisy, beam_noise_std=NOISE / 3)
    adaptive, _ = run(noisy, beam_noise_std=NOISE / 3, adaptive="innovation")
    np.testing.assert_array_equal(fixed.measurement_std, NOISE / 3)
    assert variance_ratio(adaptive) == pytest.approx(1.0, abs=0.2)
    assert coverage(fixed, truth) < 0.9 and len(fixed.events) > 0
    assert coverage(adaptive, truth) > 0.98 > coverage(fixed, truth) + 0.08
    rmse = [np.sqrt(np.mean((t.velocity_dvl - truth) ** 2)) for t in (fixed, adaptive)]
    assert rmse[1] < rmse[0]
    # Still a Kalman filter: every offered measurement is used or gated, and counted.
    offered = np.isfinite(truth).all(axis=1).sum() * 4
    assert adaptive.beams_used.sum() + adaptive.beams_rejected.sum() == offered


def test_told_the_right_noise_it_stays_near_it(noisy):
    adaptive, truth = run(noisy, beam_noise_std=NOISE, adaptive="innovation")
    assert variance_ratio(adaptive) == pytest.approx(1.0, abs=0.2)
    assert coverage(adaptive, truth) > 0.98 and not adaptive.events


def test_the_adapted_noise_stays_within_its_bounds(noisy):
    """Told a third of the noise with a ceiling of 2x, and ten times it with the floor of
    0.5x: each ends at its bound, and no ping's noise is outside them."""
    capped, _ = run(noisy, beam_noise_std=NOISE / 3, adaptive="innovation",
                    adaptive_range=(0.5, 2.0))
    floored, _ = run(noisy, beam_noise_std=10 * NOISE, adaptive="innovation")
    assert capped.measurement_std.max() == pytest.approx(2 * NOISE / 3, rel=1e-12)
    np.testing.assert_allclose(capped.measurement_std[-1], 2 * NOISE / 3, rtol=1e-12)
    assert floored.measurement_std.min() == pytest.approx(0.5 * 10 * NOISE, rel=1e-12)
    np.testing.assert_allclose(floored.measurement_std[-1], 0.5 * 10 * NOISE, rtol=1e-12)


@pytest.mark.parametrize("beam_states", [False, True])
def test_adaptive_none_is_the_default_filter_array_by_array(noisy, beam_states):
    default, _ = run(noisy, beam_states=beam_states)
    none, _ = run(noisy, beam_states=beam_states, adaptive="none")
    for field, value in default._asdict().items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(getattr(none, field), value, err_msg=field)
    assert default.events == none.events


def test_it_is_registered_as_a_filter_that_adapts_whatever_the_settings(noisy):
    s = spec("INS/DVL (adaptive)")
    assert s.kind == "filter" and s.needs.imu
    made = s.make(noisy, None)
    assert made.name == s.name and made.config.adaptive == "innovation"
    window = s.make(noisy, ins.FilterConfig(adaptive_window=7)).config
    assert (window.adaptive, window.adaptive_window) == ("innovation", 7)
    assert spec("INS/DVL").make(noisy, None).config.adaptive == "none"


@pytest.mark.parametrize("settings, said", [
    (dict(adaptive="sage-husa"), "FilterConfig.adaptive: expected one of none, innovation"),
    (dict(adaptive_window=1), "FilterConfig.adaptive_window: expected a whole number"),
    (dict(adaptive_window=True), "FilterConfig.adaptive_window: expected a whole number"),
    (dict(adaptive_range=(2.0, 10.0)), "FilterConfig.adaptive_range: expected (floor"),
    (dict(adaptive_range=(0.5,)), "FilterConfig.adaptive_range: expected (floor"),
])
def test_bad_adaptive_settings_are_refused_by_name(settings, said):
    with pytest.raises(ValueError, match="^" + re.escape(said)):
        ins.FilterConfig(**settings)


def test_the_settings_come_from_the_filter_config_toml(tmp_path):
    good = tmp_path / "good.toml"
    good.write_text('adaptive = "innovation"\nadaptive_window = 40\n'
                    'adaptive_range = [0.25, 4.0]\n')
    config = ins.load_config(good)
    assert (config.adaptive, config.adaptive_window, config.adaptive_range) == (
        "innovation", 40, (0.25, 4.0))
    bad = tmp_path / "bad.toml"
    bad.write_text('adaptive = "always"\n')
    with pytest.raises(ConfigError, match="FilterConfig.adaptive: expected one of"):
        ins.load_config(bad)


def test_beamsnet_estimate_runs_it_by_name(noisy, tmp_path, capsys):
    settings = tmp_path / "filter.toml"
    settings.write_text("adaptive_window = 20\n")
    out = tmp_path / "est"
    assert main(["estimate", str(noisy), "--estimator", "ins/dvl (adaptive)",
                 "--filter-config", str(settings), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["estimator"] == "INS/DVL (adaptive)"
    assert summary["filter_config"]["adaptive"] == "innovation"
    assert summary["filter_config"]["adaptive_window"] == 20
    assert summary["availability"] == 1.0
