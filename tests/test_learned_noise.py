"""The INS/DVL filter with a learned DVL noise (``FilterConfig.adaptive = "learned"``,
``beamsnet.estimators.noisenet``): a small training run on a generated mission, known
answers for what it learns, the network's bounds, its file, and ``beamsnet reproduce
adaptive`` at a tiny size."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from conftest import zigzag

from auvsim.data.reader import open_dataset
from beamsnet.cli import main
from beamsnet.data import load_windows
from beamsnet.estimators import ins, noisemodel, noisenet, spec
from beamsnet.experiments import adaptive
from beamsnet.navigation import truth_at_pings

NOISE = 0.01  # m/s, the beams' true white noise (and what the file states)
WARM_UP = 1 / 3  # the share of the pings left out of the statistics (the window filling)
D = noisemodel.WINDOW * len(noisemodel.FEATURES)  # the network's inputs


@pytest.fixture(scope="module")
def noisy(dataset_of):
    """200 s of zigzag, a navigation-grade IMU, beams of white noise ``NOISE`` at 1 Hz, no
    slow error (so the scale is R's alone)."""
    return dataset_of(zigzag(NOISE, 200.0), "noisy")


@pytest.fixture(scope="module")
def trained(noisy):
    return noisenet.train_noise_model(noisy, seed=0)


@pytest.fixture(scope="module")
def seeds(noisy):
    """Five seeds' models, trained in one call."""
    return noisenet.train_noise_models(noisy, seeds=range(5))


def run(path, model, **settings) -> tuple[ins.FilterTrack, np.ndarray]:
    with open_dataset(path) as f:
        m = f.missions["zz"]
        track = ins.run_mission(m, ins.FilterConfig(**settings), noise_model=model)
        return track, np.asarray(m.dvl.velocity)


def later(x: np.ndarray) -> np.ndarray:
    return x[round(WARM_UP * len(x)):]


def coverage(track: ins.FilterTrack, truth: np.ndarray) -> float:
    return float(np.mean(np.abs(track.velocity_dvl - truth) < 3 * track.velocity_std))


def constant(z: float) -> noisemodel.NoiseModel:
    """A model whose output is tanh-bounded z whatever its inputs."""
    return noisemodel.NoiseModel(w1=np.zeros((4, D)), b1=np.zeros(4), w2=np.zeros(4), b2=z,
                               mean=np.zeros(D), std=np.ones(D))


@pytest.mark.parametrize("told, ratio", [(0.5, 4.0), (1.0, 1.0), (1 / 1.5, 2.25)])
def test_it_learns_the_noise_the_innovations_show(noisy, trained, told, ratio):
    """Trained with the stated noise at 0.5, 1 and 2 times the true one, the network sets
    the variance scale to (true / told)^2 within 30 %: 4 told half, 1 told right, and
    2.25 told 1/1.5 of it, a factor it never trained at."""
    track, _ = run(noisy, trained, adaptive="learned", beam_noise_std=told * NOISE)
    assert np.median(later(track.noise_scale)) == pytest.approx(ratio, rel=0.3)


def test_told_half_the_noise_it_covers_the_truth_where_the_fixed_filter_does_not(
        noisy, trained):
    """Told half the true noise, the fixed filter's 3 sigma covers the velocity error on
    0.75 of the pings; the learned one's on 0.98 (told the truth, the fixed filter covers
    0.998)."""
    fixed, truth = run(noisy, None, beam_noise_std=NOISE / 2)
    learned, _ = run(noisy, trained, adaptive="learned", beam_noise_std=NOISE / 2)
    assert coverage(learned, truth) > 0.9 and coverage(fixed, truth) < 0.8
    # Still a Kalman filter: every offered measurement is used or gated, and counted.
    offered = np.isfinite(truth).all(axis=1).sum() * 4
    assert learned.beams_used.sum() + learned.beams_rejected.sum() == offered


def test_every_seed_learns_the_same_scale_and_covers_the_truth(noisy, seeds):
    """Told half the noise, each of five seeds' models sets the scale within 30 % of the
    true 4 and covers the truth on 90 % of the pings or more. Before the network's inputs
    were made independent of its own output and the gated innovations counted by their
    probability (the noisenet docstring), five seeds of this fit learned 2.9 to 5.9."""
    for model in seeds:
        track, truth = run(noisy, model, adaptive="learned", beam_noise_std=NOISE / 2)
        assert np.median(later(track.noise_scale)) == pytest.approx(4.0, rel=0.3)
        assert coverage(track, truth) > 0.9


def test_models_of_several_seeds_are_those_of_one_call_each(noisy, trained, seeds):
    """``train_noise_models`` makes the fixed filter's first-round runs once for every
    seed; the models are still each seed's own, array for array."""
    models = seeds
    alone = noisenet.train_noise_model(noisy, seed=1)
    for got, want in ((models[0], trained), (models[1], alone)):
        for name in ("w1", "b1", "w2", "mean", "std"):
            assert np.array_equal(getattr(got, name), getattr(want, name)), name
        assert got.b2 == want.b2 and got.trained_on == want.trained_on
    assert not np.array_equal(models[0].w1, models[1].w1)


@pytest.mark.parametrize("settings", [dict(rounds=0), dict(epochs=0), dict(seeds=())])
def test_training_without_a_round_epoch_or_seed_is_refused(noisy, settings):
    """No round, epoch or seed would return untrained (or no) models: refused."""
    with pytest.raises(ValueError, match="at least one round, epoch and seed"):
        noisenet.train_noise_models(noisy, **settings)


def test_the_loop_runs_the_network_as_numpy_does(noisy, trained):
    """The compiled loop's scale after each ping (used at the next) is the numpy
    forward pass on the same features, windowed as ``noisemodel.windows`` does."""
    track, _ = run(noisy, trained, adaptive="learned")
    expected = trained.scale(noisemodel.windows(track.features))
    np.testing.assert_allclose(track.noise_scale[1:], expected[:-1], rtol=1e-9)
    assert track.noise_scale[0] == 1.0  # the stated noise until the network has spoken
    np.testing.assert_allclose(track.measurement_std,
                               np.sqrt(expected)[:, None] * track.stated_std, rtol=1e-9)


def test_a_constant_model_scales_the_stated_noise_by_its_constant(noisy):
    """``constant_model(1)`` is the fixed filter, array by array (to the rounding of
    exp(log 1) in the loop); ``constant_model(4)``
    doubles every measurement's std from the first ping the network speaks; a scale the
    bounded output cannot reach is refused."""
    fixed, _ = run(noisy, None)
    same, _ = run(noisy, noisemodel.constant_model(1.0), adaptive="learned")
    for name in ("velocity_dvl", "velocity_std", "position_ned", "position_std",
                 "beams_used", "beams_rejected"):
        np.testing.assert_allclose(getattr(same, name), getattr(fixed, name), rtol=1e-9,
                                   atol=1e-12, err_msg=name)
    four, _ = run(noisy, noisemodel.constant_model(4.0), adaptive="learned")
    assert four.noise_scale[1:] == pytest.approx(4.0, rel=1e-12)
    np.testing.assert_allclose(four.measurement_std, np.broadcast_to(
        2 * four.stated_std, four.measurement_std.shape), rtol=1e-12)
    for scale in (0.25, 100.0, 0.0, math.nan):
        with pytest.raises(ValueError, match="strictly between 0.25 and 100"):
            noisemodel.constant_model(scale)


@pytest.mark.parametrize("z, variance", [(50.0, 100.0), (-50.0, 0.25)])
def test_the_scale_is_bounded_by_construction(noisy, z, variance):
    """However large the network's output, the variance scale stays within the squares of
    the std bounds (0.5 and 10): R diagonal and positive."""
    track, _ = run(noisy, constant(z), adaptive="learned")
    assert track.noise_scale[1:] == pytest.approx(variance, rel=1e-12)
    rng = np.random.default_rng(0)
    wild = noisemodel.NoiseModel(**{**vars(constant(0.0)),
                                  "w1": 1e3 * rng.standard_normal((4, D)),
                                  "w2": 1e3 * rng.standard_normal(4)})
    track, _ = run(noisy, wild, adaptive="learned")
    assert (track.noise_scale >= 0.25 * (1 - 1e-12)).all()
    assert (track.noise_scale <= 100 * (1 + 1e-12)).all()


def test_a_constant_scale_scales_the_white_noise_from_the_second_ping(noisy):
    """With no slow error, a constant scale lambda is the fixed filter told sqrt(lambda)
    times the noise, from the second ping on (the first uses the stated)."""
    z = 0.3
    model = constant(z)
    lam = float(model.scale(np.zeros((1, D)))[0])
    learned, _ = run(noisy, model, adaptive="learned")
    np.testing.assert_allclose(learned.measurement_std, math.sqrt(lam) * NOISE, rtol=1e-12)
    fixed, _ = run(noisy, None, beam_noise_std=math.sqrt(lam) * NOISE)
    assert np.abs(learned.velocity_dvl - fixed.velocity_dvl)[-50:].max() < 1e-3


def test_the_model_file_round_trips_and_foreign_files_are_refused(trained, tmp_path):
    path = tmp_path / "noise.npz"
    noisemodel.save_noise_model(trained, path)
    back = noisemodel.load_noise_model(path)
    for name in ("w1", "b1", "w2", "mean", "std"):
        np.testing.assert_array_equal(getattr(back, name), getattr(trained, name))
    assert back.b2 == trained.b2 and back.trained_on["missions"] == 1
    text = tmp_path / "notes.npz"
    text.write_text("not a model\n")
    other = tmp_path / "other.npz"
    np.savez(other, w1=np.zeros(3))
    cut = tmp_path / "cut.npz"
    cut.write_bytes(path.read_bytes()[:200])
    for bad in (text, other, cut):
        with pytest.raises(noisemodel.NoiseModelError, match="is not a beamsnet noise model"):
            noisemodel.load_noise_model(bad)
    with pytest.raises(noisemodel.NoiseModelError, match="cannot read"):
        noisemodel.load_noise_model(tmp_path / "missing.npz")


def test_the_command_line_refuses_a_foreign_model_in_one_line(noisy, tmp_path, capsys):
    bad = tmp_path / "bad.npz"
    bad.write_text("not a model\n")
    settings = tmp_path / "filter.toml"
    settings.write_text(f'adaptive = "learned"\nnoise_model = "{bad}"\n')
    code = main(["estimate", str(noisy), "--estimator", "INS/DVL", "--filter-config",
                 str(settings), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "is not a beamsnet noise model" in err[0]
    assert not (tmp_path / "out").exists()


def test_learned_without_a_model_says_what_it_needs(noisy):
    with pytest.raises(ins.DataError, match="^FilterConfig.noise_model: expected"):
        run(noisy, None, adaptive="learned")


def rows(n: int, window: int = noisenet.WINDOW) -> noisenet.Records:
    """``n`` rows of the loss, of one mission, with every measurement offered."""
    rng = np.random.default_rng(0)
    return noisenet.Records(
        inputs=rng.standard_normal((n, 2 * window)), nu2=np.full((n, 4), 1e-6),
        s0=np.full((n, 4), 1e-6), log_scale0=np.zeros(n),
        censored=np.zeros((n, 4), bool), mask=np.ones((n, 4), bool), group=np.zeros(n, int))


def test_too_few_rows_to_hold_any_out_are_refused_in_one_line():
    # One mission: the fifth block of 2 WINDOW rows is the first held out, so 8 WINDOW
    # rows hold none (a 60 s mission's training split gave 156 and a traceback).
    need = 8 * noisenet.WINDOW + 1
    with pytest.raises(noisemodel.NoiseModelError, match=f"expected at least {need} ") as e:
        noisenet.fit(rows(need - 1), epochs=2)
    assert "\n" not in str(e.value)
    model = noisenet.fit(rows(need), epochs=2)
    assert math.isfinite(model.trained_on["validation_nll"])


def test_it_is_registered_and_trains_on_the_training_split(noisy):
    from beamsnet.data import load_windows, split

    s = spec("INS/DVL (learned noise)")
    assert s.kind == "filter" and s.needs.imu
    train, test = split(load_windows(noisy))
    made = s.make(noisy, None).fit(train)
    assert made.config.adaptive == "learned"
    # Trained on the training split's pings only: 6 runs (2 forms x 3 factors) of the
    # pings up to the split, less each run's first.
    assert made.noise_model.trained_on["pings"] == 6 * (
        int(np.sum(np.asarray(made.tracks(train)["zz"].ping_time) <= train.time.max())) - 1)
    assert np.isfinite(made.predict(test)).all()


def test_it_trains_on_simulated_missions_only(tmp_path):
    from test_sea import write_akit

    from auvsim.data.recorded import import_logs

    write_akit(tmp_path / "logs", 1, surge=0.0)
    import_logs([tmp_path / "logs"], tmp_path / "sea.h5", format="akit")
    with pytest.raises(noisemodel.NoiseModelError, match="simulated data only"):
        noisenet.train_noise_model(tmp_path / "sea.h5")
    # The estimator, fitted on the log itself (beamsnet estimate), says the same and what
    # to give instead (not that the log lacks measured beams, which it does too).
    from beamsnet.data import load_windows, split

    train = split(load_windows(tmp_path / "sea.h5"))[0]
    with pytest.raises(noisemodel.NoiseModelError, match="simulated data only.*noise_model"):
        noisenet.LearnedInsDvlFilter(tmp_path / "sea.h5").fit(train)


@pytest.mark.parametrize("flag, said", [
    (["--lr", "0.1"], "is not used by adaptive"), (["--epochs", "3"], "is not used by adaptive"),
    (["--seeds", "0"], "--seeds: expected a whole number of seeds, at least 1, got 0")])
def test_reproduce_adaptive_refuses_the_networks_settings(flag, said, tmp_path, capsys):
    code = main(["reproduce", "adaptive", *flag, "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and said in err[0], err
    assert not (tmp_path / "r").exists()


@pytest.mark.slow
def test_reproduce_adaptive_writes_its_report(tmp_path, monkeypatch, capsys):
    """Two weaving segments the test writes, a tiny training set (20 s per manoeuvre):
    every filter scored on every held-out mission against the truth and every segment
    against the reference, the targets stated met or missed, the figures and the model."""
    from test_sea import write_akit

    logs = tmp_path / "logs"
    for k in (1, 2):
        write_akit(logs, k, sway_bias=0.0, scale=0.01 * k, weave_deg_s=3.0)
    monkeypatch.chdir(tmp_path)
    # Fewer constant scales than the report's, to keep the test short (each is a run of
    # every mission).
    monkeypatch.setattr(adaptive, "CONSTANT_STD", (0.6, 2.0))
    monkeypatch.setattr(adaptive, "CONSTANT_PROCESS_STD", (2.0,))
    assert main(["reproduce", "adaptive", "--data", str(logs), "--duration", "20",
                 "--seeds", "2", "--out", "report", "--quiet"]) == 0
    said = capsys.readouterr().out  # what it made outside --out, said
    assert "its datasets are in datasets/" in said and "runs/adaptive/" in said
    assert sorted(p.name for p in (tmp_path / "runs" / "adaptive").iterdir()) == [
        "noise-model-seed1.npz", "noise-model.npz"]
    results = json.loads((tmp_path / "report" / "adaptive.json").read_text())
    assert list(results["recorded"]) == ["trajectory1", "trajectory2"]
    assert len(results["simulated"]) == 20
    for part in ("simulated", "recorded"):
        for scores in results[part].values():
            for label in ("INS/DVL", "INS/DVL (adaptive)", "INS/DVL (learned noise)"):
                row = scores[label]
                assert all(np.isfinite(row[k]) for k in (
                    "final_m", "rmse_m", "velocity_rmse", "coverage_3sigma"))
                assert 0.5 < row["availability"] <= 1 and isinstance(row["events"], list)
    assert set(results["features"]) == set(noisemodel.FEATURES)
    # Every seed's model scored on every mission; the first's are the tables'.
    assert list(results["seeds"]) == ["0", "1"]
    for part in ("simulated", "recorded"):
        first = results["seeds"]["0"][part]
        assert {n: r["scores"]["INS/DVL (learned noise)"] for n, r in first.items()} == {
            n: s["INS/DVL (learned noise)"] for n, s in results[part].items()}
        assert list(results["seeds"]["1"][part]) == list(results[part])
    report = (tmp_path / "report" / "adaptive.md").read_text()
    seeds = report[report.index("## Every seed"):report.index("## What a constant")]
    assert [line.split("|")[1].strip() for line in seeds.splitlines()
            if re.match(r"\| \d", line)] == ["0", "1"]
    recorded = report[report.index("## Recorded"):]
    assert "truth" not in recorded.split("## How much")[0]  # its simulated control names one
    assert len(re.findall(r"(?:\bmet|\*\*missed\*\*)[;.]", report)) == 4
    assert report.count("| **median** |") == 4
    assert report.count("whose measurement each filter accepted") == 2  # simulated, recorded
    # The fixed filter with every constant scale, each segment's best in hindsight.
    assert list(results["constant"]) == ["trajectory1", "trajectory2"]
    for name, row in results["constant"].items():
        assert set(row) == {"1", *(f"{k:g}" for k in adaptive.CONSTANT_STD)}
        assert row["1"] == results["recorded"][name]["INS/DVL"]["final_m"]  # the fixed filter
    best = np.median([min(row.values()) for row in results["constant"].values()])
    assert f"median final {best:.2f} m" in report
    # And with the IMU's process noise scaled, alone and with the DVL's: (1, q) is the
    # fixed filter told q times the IMU's noise std, as the filter itself gives it.
    assert list(results["process"]) == ["trajectory1", "trajectory2"]
    for row in results["process"].values():
        assert set(row) == {f"{d:g},{q:g}" for d in (1, *adaptive.CONSTANT_STD)
                            for q in adaptive.CONSTANT_PROCESS_STD}
    with open_dataset(tmp_path / "datasets" / "sea.h5") as f:
        windows = load_windows(tmp_path / "datasets" / "sea.h5", missions=["trajectory2"])
        told = ins.run_mission(f.missions["trajectory2"],
                               ins.FilterConfig(process_noise_scale=2.0))
    reference = truth_at_pings(tmp_path / "datasets" / "sea.h5", windows)["position"]
    at = np.searchsorted(told.ping_time, windows.time[-1])
    assert results["process"]["trajectory2"]["1,2"] == pytest.approx(
        float(np.linalg.norm(told.position_ned[at, :2] - reference[-1, :2])), rel=1e-9)
    # The process section's median row, recomputed from the file's finals: per IMU multiple
    # with the DVL's at 1, then each segment's own best IMU multiple and own best pair.
    section = report[report.index("## What a constant process noise"):
                     report.index("## How much of a choice")]
    imu = sorted({1.0, *adaptive.CONSTANT_PROCESS_STD})

    def final(row_c, row_p, d, q):
        return row_c[f"{d:g}"] if q == 1 else row_p[f"{d:g},{q:g}"]

    def own(part_c, part_p, dvl, qs):
        return np.median([min(final(part_c[n], part_p[n], d, q) for d in dvl for q in qs)
                          for n in part_c])

    dvl = (1.0, *adaptive.CONSTANT_STD)
    medians = [np.median([final(results["constant"][n], results["process"][n], 1.0, q)
                          for n in results["constant"]]) for q in imu]
    expected = ("| **median** | " + " | ".join(f"{m:.2f}" for m in medians)
                + f" | {own(results['constant'], results['process'], (1.0,), imu):.2f}"
                f" | {own(results['constant'], results['process'], dvl, imu):.2f} |")
    assert expected in section
    # The chance section: the same figures on the held-out simulated missions, against
    # their truth, and at sea, each as "one for all / each its own" below the fixed filter.
    assert list(results["simulated_constant"]) == list(results["simulated"])
    assert list(results["simulated_process"]) == list(results["simulated"])
    for part_c, part_p, label in (
            (results["constant"], results["process"], "2 recorded segments, against the "
             "reference"),
            (results["simulated_constant"], results["simulated_process"],
             "20 held-out simulated missions, against their truth")):
        fixed = np.median([row["1"] for row in part_c.values()])
        cells = []
        for ds, qs in (((1.0,) + adaptive.CONSTANT_STD, (1.0,)), ((1.0,), imu), (dvl, imu)):
            one = min(np.median([final(part_c[n], part_p[n], d, q) for n in part_c])
                      for d in ds for q in qs)
            cells.append(f"{100 * (1 - one / fixed):.1f} / "
                         f"{100 * (1 - own(part_c, part_p, ds, qs) / fixed):.1f}")
        assert f"| {label} | {fixed:.2f} | " + " | ".join(cells) + " |" in report
    # A held-out mission's fixed-filter final, recomputed from the filter's own track and
    # the truth at its last scored ping, as the recorded one above.
    test_file = tmp_path / "datasets" / "adaptive-test_20s.h5"
    name = next(iter(results["simulated_constant"]))
    with open_dataset(test_file) as f:
        windows = load_windows(test_file, missions=[name])
        fixed = ins.run_mission(f.missions[name])
    truth = truth_at_pings(test_file, windows)["position"]
    at = np.searchsorted(fixed.ping_time, windows.time[-1])
    assert results["simulated_constant"][name]["1"] == pytest.approx(
        float(np.linalg.norm(fixed.position_ned[at, :2] - truth[-1, :2])), rel=1e-9)
    for figure in ("adaptive.png", "adaptive-features.png"):
        assert (tmp_path / "report" / figure).stat().st_size > 10_000
    model = noisemodel.load_noise_model(tmp_path / "runs" / "adaptive" / "noise-model.npz")
    assert model.trained_on["missions"] == 20
    other = noisemodel.load_noise_model(tmp_path / "runs" / "adaptive" /
                                        "noise-model-seed1.npz")
    assert other.trained_on["seed"] == 1 and not np.array_equal(other.w1, model.w1)
    # Run again with one seed: the earlier run's second model does not stay beside it.
    assert main(["reproduce", "adaptive", "--data", str(logs), "--duration", "20",
                 "--seeds", "1", "--out", "again", "--quiet"]) == 0
    assert sorted(p.name for p in (tmp_path / "runs" / "adaptive").iterdir()) == [
        "noise-model.npz"]
