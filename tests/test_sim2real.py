"""``beamsnet reproduce sim2real`` end to end at a tiny size, and the frame it matches."""

from __future__ import annotations

import json

import numpy as np
import pytest

from auvsim.runs.presets import SNAPIR_MOUNTING_YAW_DEG, sim2real
from beamsnet.cli import main
from beamsnet.experiments.sim2real import SEEDS


def stream(n: int, seed: int = 0) -> np.ndarray:
    """(3, n) a smooth, varying DVL-frame velocity, m/s, laid out as the Snapir's V.npy:
    forward flight seen by a DVL yawed 45 deg (x positive, y negative)."""
    t = np.arange(n)
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 3)
    return np.stack([1.2 + 0.5 * np.sin(t / 60 + phase[0]),
                     -1.1 + 0.5 * np.sin(t / 45 + phase[1]),
                     0.05 * np.sin(t / 20 + phase[2])])


def test_the_training_data_flies_the_snapirs_dvl_mounting():
    """The sim2real preset's DVL is yawed as on the Snapir, everything else its own."""
    config = sim2real(60.0)
    assert config.dvl.mounting_rpy_deg == (0.0, 0.0, SNAPIR_MOUNTING_YAW_DEG)
    assert sim2real(60.0, mounting_yaw_deg=0.0).dvl.mounting_rpy_deg == (0.0, 0.0, 0.0)
    # The paper's error model on the Snapir streams (beamsnet-reference.md).
    assert (config.dvl.beam_angle_deg, config.dvl.scale_factor, config.dvl.bias,
            config.dvl.noise_std) == (20.0, 0.007, 0.0001, 0.042 ** 2)
    assert {m.scenario.duration for m in config.missions} == {60.0}


@pytest.mark.slow
def test_reproduce_sim2real_scores_every_estimator_and_seed(tmp_path, monkeypatch):
    data = tmp_path / "snapir"
    data.mkdir()
    np.save(data / "V.npy", stream(400))
    np.save(data / "V_test.npy", stream(120, seed=1))
    monkeypatch.chdir(tmp_path)
    args = ["reproduce", "sim2real", "--data", str(data), "--duration", "30", "--seeds", "2",
            "--epochs", "1", "--out", "reports", "--quiet"]
    assert main(args) == 0
    results = json.loads((tmp_path / "reports" / "sim2real.json").read_text())
    report = (tmp_path / "reports" / "sim2real.md").read_text()
    assert len(results) == 3 and "V.npy (the real vehicle)" in results
    for source, tests in results.items():
        for rows in tests.values():
            assert rows["LS"][0]["improvement"] == 0.0
            # Every seed scored: 2 asked for, one on the set along the body, and on V.npy
            # those of ``reproduce snapir``.
            expected = (1 if "along the body" in source else
                        SEEDS["v2"] if source.startswith("V.npy") else 2)
            assert len(rows["BeamsNetV2"]) == expected
            for seeds in rows.values():
                assert all(np.isfinite(s["rmse"]) and s["availability"] == 1 for s in seeds)
    assert "| Affine |" in report and "test (V_test.npy): 117 pings" in report
    assert (tmp_path / "reports" / "sim2real.png").stat().st_size > 10_000
    # The networks are reused on a second run.
    run = next((tmp_path / "runs" / "sim2real").glob("sim2real_30s/v2/seed_0/model.pt"))
    stamp = run.stat().st_mtime_ns
    assert main(args) == 0
    assert run.stat().st_mtime_ns == stamp


def test_reproduce_sim2real_refuses_bad_seeds_before_any_work(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["reproduce", "sim2real", "--seeds", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--seeds" in err
    assert list(tmp_path.iterdir()) == []
