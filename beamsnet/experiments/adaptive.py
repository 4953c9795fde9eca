"""``beamsnet reproduce adaptive``: the INS/DVL filter whose measurement noise a small
network sets (``beamsnet.estimators.noisenet``), trained on auvsim data only, beside the
model-based adaptive filter (innovation-based, Mohamed & Schwarz 1999) and the fixed
filter.

* **Training**: the ``realistic-maneuvers`` preset (the navigator's DVL with every failure,
  its calibrated IMU, the rotating Earth off Haifa, the real turning envelope), generated
  here at ``duration`` s per manoeuvre (the file ``reproduce sea`` trains on too), one
  model per seed (``seeds`` of them from ``seed``); the first goes to
  ``runs/adaptive/noise-model.npz`` and is the one the tables and figures show, the others
  to ``noise-model-seedK.npz``, each scored on the same missions (the report's "Every
  seed": how much of a result is the seed's).
* **Held-out simulated missions**: the same manoeuvres with other seeds (every mission's
  seed + ``HELD_OUT_SEED``: other currents, noise, failures' draws), scored against their
  truth.
* **Recorded segments** of a folder (default the Snapir AUV's six A-KIT segments),
  imported and corrected by ``check-log --apply`` as ``reproduce sea`` does, scored
  against their reference, never a truth.

Every filter runs on the beams as measured (no calibration: a segment has no split of
its own), from its start to the last ping; the scores are ``reproduce sea``'s, from each
mission's fourth ping. The report gives, per mission and as medians, the final and RMSE
horizontal error, the velocity RMSE and the 3-sigma coverage; the targets; a figure of
the learned noise over time beside the manoeuvre and the innovations; and where the
learned filter does worse at sea than the fixed one, which of its inputs moved between
the simulated and the recorded data (their histograms and a two-sample
Kolmogorov-Smirnov distance).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from auvsim.data.files import check_out_dir, save_figure, staged_dir, write_text
from auvsim.data.reader import open_dataset
from auvsim.errors import ConfigError
from auvsim.runs.cluster import check_address
from beamsnet import metrics
from beamsnet.data import load_windows
from beamsnet.estimators import predicted
from beamsnet.evaluate import navigation_scores, reported_stds, watch_scores
from beamsnet.experiments.defaults import ADAPTIVE_DURATION, ADAPTIVE_SEEDS
from beamsnet.experiments.runner import check_duration, ensure_dataset
from beamsnet.experiments.sea import (
    DEFAULT_SEA,
    median_score,
    pooled_coverage,
    sea_dataset,
    watch_words,
)
from beamsnet.navigation import truth_at_pings

if TYPE_CHECKING:
    from beamsnet.estimators.ins import FilterConfig

DURATION = ADAPTIVE_DURATION  # beamsnet.experiments.defaults
SEED = 0
SEEDS = ADAPTIVE_SEEDS
# The DVL noise's std multiples (white part and drive together) of the constant scales
# the report runs the filter with at sea: how far any constant scale moves it.
CONSTANT_STD = (0.6, 0.8, 1.25, 1.6, 2.0, 3.0, 5.0, 8.0)
# The IMU's process noise's std multiples (Q: white noise densities and bias drives) the
# report runs the fixed filter with at sea, alone and with each DVL multiple above: what
# A-KIT adapts, as far as a constant scale of it moves this filter.
CONSTANT_PROCESS_STD = (0.5, 2.0, 5.0, 10.0)
HELD_OUT_SEED = 1000  # added to each mission's seed for the held-out simulated set
FIXED, MODEL_BASED, LEARNED = "INS/DVL", "INS/DVL (adaptive)", "INS/DVL (learned noise)"
FILTERS = (FIXED, MODEL_BASED, LEARNED)
# The targets on the recorded segments (the learned filter against the fixed one).
TARGET_GAIN = 0.30  # median final at least 30 % below
TARGET_WORSE = 0.10  # no segment's final more than 10 % worse
TARGET_COVERAGE = 0.90


def held_out(duration: float = DURATION):
    """``realistic-maneuvers`` with every mission's seed moved by ``HELD_OUT_SEED``."""
    from auvsim.runs.presets import realistic_maneuvers

    config = realistic_maneuvers(duration)
    return dataclasses.replace(config, missions=tuple(
        dataclasses.replace(m, seed=m.seed + HELD_OUT_SEED) for m in config.missions))


def adaptive(data: Path = DEFAULT_SEA, *, out: Path, duration: float = DURATION,
             seed: int = SEED, seeds: int = SEEDS, runs: Path = Path("runs"),
             datasets: Path = Path("datasets"), progress: bool = True,
             cluster: str | None = None) -> Path:
    """Train the noise model on auvsim data (``seeds`` models, from seeds ``seed``,
    ``seed + 1``, ...), score the three filters on held-out simulated missions and on the
    recorded segments of ``data`` (the learned one with every model); write
    ``out/adaptive.md``, ``adaptive.json``, ``adaptive.png`` (the noise over time) and
    ``adaptive-features.png`` (the inputs, simulated against recorded).

    Raises:
        ConfigError: ``duration`` or ``seeds`` out of range, ``data`` not a folder of
            A-KIT segments, and what the import refuses of a log (one line each).
    """
    from auvsim.runs.presets import realistic_maneuvers
    from beamsnet.estimators.noisemodel import save_noise_model
    from beamsnet.estimators.noisenet import train_noise_models

    check_duration(duration, "duration", unit="seconds per manoeuvre")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ConfigError(f": expected a whole number of seeds, at least 1, got {seeds!r}",
                          argument="seeds")
    check_out_dir(out)
    if cluster is not None:
        check_address(cluster)
    real, corrections = sea_dataset(Path(data), datasets)
    train = ensure_dataset(realistic_maneuvers(duration),
                           datasets / f"sea-train_{duration:g}s.h5", progress=progress,
                           cluster=cluster)
    test = ensure_dataset(held_out(duration), datasets / f"adaptive-test_{duration:g}s.h5",
                          progress=progress, cluster=cluster)
    models = train_noise_models(train, seeds=range(seed, seed + seeds), progress=progress)
    model, model_path = models[0], Path(runs) / "adaptive" / "noise-model.npz"
    model_path.parent.mkdir(parents=True, exist_ok=True)
    paths = [model_path, *(model_path.with_name(f"noise-model-seed{seed + k}.npz")
                           for k in range(1, seeds))]
    for stale in set(model_path.parent.glob("noise-model-seed*.npz")) - set(paths):
        stale.unlink()  # an earlier run's, with more seeds: not this run's models
    for each, path in zip(models, paths, strict=True):
        save_noise_model(each, path)
    sim = {name: _mission(test, name, model, models[1:], CONSTANT_STD, CONSTANT_PROCESS_STD)
           for name in _names(test)}
    sea = {name: _mission(real, name, model, models[1:], CONSTANT_STD, CONSTANT_PROCESS_STD)
           for name in _names(real)}
    every = {seed + k: dict(simulated={n: _learned_of(([r] + r["others"])[k])
                                       for n, r in sim.items()},
                            recorded={n: _learned_of(([r] + r["others"])[k])
                                      for n, r in sea.items()})
             for k in range(seeds)}
    constant = {name: r["constant"] for name, r in sea.items()}
    process = {name: r["process"] for name, r in sea.items()}
    sim_constant = {name: r["constant"] for name, r in sim.items()}
    sim_process = {name: r["process"] for name, r in sim.items()}
    features = dict(
        simulated=np.concatenate([_started(r["track"].features) for r in sim.values()]
                                 + _velocity_features(test, model)),
        recorded=np.concatenate([_started(r["track"].features) for r in sea.values()]))
    setup = dict(data=Path(data).name, train=str(train), test=str(test), real=str(real),
                 duration=duration, seed=seed, seeds=seeds, model=str(model_path),
                 trained_on=model.trained_on, corrections=corrections)
    with staged_dir(out) as stage:
        write_text(stage / "adaptive.json", json.dumps(
            {"setup": setup, "simulated": {n: r["scores"] for n, r in sim.items()},
             "recorded": {n: r["scores"] for n, r in sea.items()},
             "seeds": every, "constant": constant, "process": process,
             "simulated_constant": sim_constant, "simulated_process": sim_process,
             "features": _shift(features)},
            indent=1, default=float))
        _noise_figure(sim, sea, stage / "adaptive.png")
        _feature_figure(features, stage / "adaptive-features.png")
        write_text(stage / "adaptive.md",
                   report(sim, sea, features, setup, every, _grid(constant, process),
                          _grid(sim_constant, sim_process)))
    return Path(out) / "adaptive.md"


def _names(dataset: Path) -> list[str]:
    with open_dataset(dataset) as f:
        return list(f.missions)


def _learned_of(result: dict) -> dict:
    """A ``_mission`` result's learned filter alone, in the same shape (for
    ``median_score`` and ``pooled_coverage``), with the median of its std scale."""
    scores = result["scores"]
    return dict(scores={LEARNED: scores[LEARNED], "pings": scores["pings"]},
                scale=float(np.median(_scale(result["track"]))))


def _filters(dataset: Path, model, labels: tuple[str, ...] = FILTERS,
             config: FilterConfig | None = None) -> dict:
    """The filters ``labels`` (default the three), the learned one with ``model``, each
    with ``config`` (default ``FilterConfig()``)."""
    from beamsnet.estimators.ins import AdaptiveInsDvlFilter, InsDvlFilter
    from beamsnet.estimators.noisenet import LearnedInsDvlFilter

    make = {FIXED: lambda: InsDvlFilter(dataset, config, calibrate=False),
            MODEL_BASED: lambda: AdaptiveInsDvlFilter(dataset, config, calibrate=False),
            LEARNED: lambda: LearnedInsDvlFilter(dataset, config, calibrate=False,
                                                 model=model)}
    out = {label: make[label]() for label in labels}
    for label, estimator in out.items():
        estimator.name = label
    return out


def _mission(dataset: Path, name: str, model, others=(), scales=(), process=()) -> dict:
    """The three filters on mission ``name``: their scores against its truth or
    reference, and each filter's track (for the figures); ``others``: the learned filter
    with each of these models too (``_scored``'s, in ``"others"``); ``scales``: its final
    error with a constant model at each of these std multiples of the DVL's noise
    (``"constant"``, keys as ``"2"``, and ``"1"`` the fixed filter's); ``process``: the
    final error with the IMU's process noise at each of these std multiples, the DVL's at
    1 and at each of ``scales`` (``"process"``, keys as ``"2,0.5"``: the DVL's multiple,
    the IMU's), all on the same windows."""
    windows = load_windows(dataset, missions=[name])
    truth = truth_at_pings(dataset, windows)
    result = dict(_scored(name, windows, truth, _filters(dataset, model)),
                  others=[_scored(name, windows, truth, _filters(dataset, other, (LEARNED,)))
                          for other in others])
    if scales:
        result["constant"] = {"1": result["scores"][FIXED]["final_m"], **{
            f"{k:g}": _grid_final(dataset, name, windows, truth, k, 1.0)
            for k in scales}}
    if process:
        result["process"] = {f"{k:g},{q:g}": _grid_final(dataset, name, windows, truth, k, q)
                             for k in (1.0, *scales) for q in process}
    return result


def _grid_final(dataset: Path, name: str, windows, truth, dvl: float, imu: float) -> float:
    """The final horizontal error on mission ``name`` of the fixed filter with the DVL's
    noise std (its white part and its slow error's drive: the learned filter with a
    constant noise model, the fixed filter itself at 1) times ``dvl`` and the IMU's process
    noise std times ``imu``."""
    from beamsnet.estimators.ins import FilterConfig
    from beamsnet.estimators.noisemodel import constant_model

    label = FIXED if dvl == 1 else LEARNED
    model = None if dvl == 1 else constant_model(dvl * dvl)
    filters = _filters(dataset, model, (label,), FilterConfig(process_noise_scale=imu))
    return _scored(name, windows, truth, filters)["scores"][label]["final_m"]


def _scored(name: str, windows, truth, filters: dict) -> dict:
    """``filters`` (label: estimator) on mission ``name``'s ``windows``: their scores
    against ``truth`` and the learned and model-based filters' tracks (None without)."""
    predictions, positions, stds, tracks = {}, {}, {}, {}
    for label, estimator in filters.items():
        predictions[label] = predicted(estimator, windows)
        positions[label] = estimator.positions(windows)
        stds.update(reported_stds(estimator, windows))
        tracks[label] = estimator.tracks(windows)[name]
    navigation = navigation_scores(windows, predictions, truth, positions=positions,
                                   stds=stds)[name]
    scores = {}
    for label, pred in predictions.items():
        have = np.isfinite(pred).all(axis=1)
        scores[label] = dict(velocity_rmse=metrics.rmse_vector(pred[have],
                                                               windows.target[have]),
                             **navigation[label], **watch_scores(tracks[label]))
    return dict(scores=dict(scores, against=windows.reference, pings=len(windows.time)),
                time=windows.time,
                track=tracks.get(LEARNED), model_based=tracks.get(MODEL_BASED))


def _started(features: np.ndarray) -> np.ndarray:
    """A track's features at the pings after its start."""
    return features[np.isfinite(features).all(axis=1)]


def _velocity_features(dataset: Path, model) -> list[np.ndarray]:
    """The learned filter's inputs on every mission of a simulated ``dataset`` with the
    DVL's velocity as its measurements (the scoring ran it on the beams; it trained on
    both forms)."""
    from beamsnet.estimators.ins import FilterConfig, run_mission

    with open_dataset(dataset) as f:
        return [_started(run_mission(m, FilterConfig(adaptive="learned"), noise_model=model,
                                     measurements="velocity").features)
                for m in f.missions.values()]


def ks_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The two-sample Kolmogorov-Smirnov statistic: the largest gap between the empirical
    distribution functions of ``a`` and ``b``."""
    a, b = np.sort(a), np.sort(b)
    x = np.concatenate([a, b])
    return float(np.abs(np.searchsorted(a, x, side="right") / len(a)
                        - np.searchsorted(b, x, side="right") / len(b)).max())


def _shift(features: dict) -> dict:
    """Per input: the simulated and recorded medians and 5-95 % ranges, the share of
    recorded pings outside the simulated 1-99 % range, and the KS distance."""
    from beamsnet.estimators.noisemodel import FEATURES

    sim, real = features["simulated"], features["recorded"]
    out = {}
    for j, name in enumerate(FEATURES):
        lo, hi = np.percentile(sim[:, j], [1, 99])
        out[name] = dict(simulated=np.percentile(sim[:, j], [5, 50, 95]).tolist(),
                         recorded=np.percentile(real[:, j], [5, 50, 95]).tolist(),
                         outside=float(((real[:, j] < lo) | (real[:, j] > hi)).mean()),
                         ks=ks_distance(sim[:, j], real[:, j]))
    return out


def _table(results: dict, against: str) -> list[str]:
    head = ("| mission | " + " | ".join(
        f"{label}: final / RMSE (m), velocity RMSE (m/s), within 3 sigma (%)"
        for label in FILTERS) + " |")
    lines = [f"Horizontal position error against {against}: final / RMSE, m; velocity "
             "RMSE (vector, DVL frame), m/s; the share of pings whose horizontal error lies "
             "within the filter's reported 3 sigma, %.", "", head,
             "|---|" + "---|" * len(FILTERS)]

    def cell(s: dict) -> str:
        return (f"{s['final_m']:.2f} / {s['rmse_m']:.2f}, {s['velocity_rmse']:.4f}, "
                f"{100 * s.get('coverage_3sigma', math.nan):.1f}")

    for name, r in results.items():
        lines.append(f"| {name} | " + " | ".join(cell(r["scores"][label]) for label in FILTERS)
                     + " |")
    keys = ("final_m", "rmse_m", "velocity_rmse", "coverage_3sigma")
    lines.append("| **median** | " + " | ".join(
        cell({k: median_score(results, label, k) for k in keys}) for label in FILTERS) + " |")
    lines.append("")
    lines.append("Over every mission's pings together, within 3 sigma: " + ", ".join(
        f"{label} {100 * pooled_coverage(results, label):.1f} %" for label in FILTERS) + ".")
    watched = watch_words(results, FILTERS)
    return lines + (["", *watched] if watched else [])


def _against(results: dict) -> str:
    return next(iter(results.values()))["scores"]["against"]


def report(sim: dict, sea: dict, features: dict, setup: dict, every: dict, grid: dict,
           sim_grid: dict) -> str:
    """The report's Markdown; ``grid`` and ``sim_grid``: the constant scales' finals
    (``_grid``) at sea and on the held-out simulated missions."""
    from beamsnet.estimators.noisemodel import BOUNDS, FEATURES, HIDDEN, WINDOW

    t = setup["trained_on"]
    hindsight = _hindsight(grid)
    lines = [
        "# adaptive: a filter that learns its noise in simulation, at sea", "",
        f"Made by `beamsnet reproduce adaptive --data DIR` (DIR: a folder of A-KIT logs; by "
        f"default the Snapir AUV's six segments; here `{setup['data']}`).", "",
        "Three INS/DVL filters, each on the beams as measured (no calibration), from its "
        "start to the last ping, scored from each mission's fourth ping:", "",
        f"- **{FIXED}**: the stated noise throughout;",
        f"- **{MODEL_BASED}**: the model-based adaptive baseline, the stated beam noise "
        "scaled by an innovation-based estimate (Mohamed & Schwarz 1999);",
        f"- **{LEARNED}**: the stated DVL noise (its white part and its slow error's "
        f"drive) scaled by a small network (the last "
        f"{WINDOW} pings' {len(FEATURES)} features, {HIDDEN} tanh units, the std bounded "
        f"to {BOUNDS[0]:g}-{BOUNDS[1]:g} times the stated) fitted by the innovations' "
        "negative log-likelihood, **trained only on auvsim data**: the "
        f"`realistic-maneuvers` preset at {setup['duration']:g} s per manoeuvre, "
        f"{t['missions']} missions, each run in both measurement forms (beams, DVL velocity) "
        f"and at {len(t['stated_factors'])} stated-noise factors "
        f"({', '.join(f'{x:g}' for x in t['stated_factors'])}): {t['pings']:,} pings, "
        f"{t['measurements']:,} measurements per round, {t['rounds']} rounds of "
        f"{t['epochs']} epochs (seed {t['seed']}; {len(every)} models in all, one per "
        f"seed, all scored under \"Every seed\"). The model: `{setup['model']}`.", "",
        f"## Held-out simulated missions (against {_against(sim)})", "",
        f"The `realistic-maneuvers` manoeuvres again, every mission's seed + "
        f"{HELD_OUT_SEED} (other currents, noise and failures), {len(sim)} missions.", "",
        *_table(sim, _against(sim)), "",
        f"## Recorded segments (against {_against(sea)})", "",
        "Every segment imported with `auvsim import --format akit` and corrected by "
        "`auvsim check-log --apply`, as `beamsnet reproduce sea` does; a segment's beams "
        "are derived from the DVL's velocity, so the filters use that velocity.", "",
        *_table(sea, _against(sea)), "",
        *_targets(sea, every), "",
        "![the learned noise over time, beside the manoeuvre and the innovations]"
        "(adaptive.png)", "",
        *_seeds(sim, sea, every), "",
        *_constant_lines(grid, hindsight), "",
        *_process_lines(grid, hindsight), "",
        *_chance_lines(hindsight, _hindsight(sim_grid)), "",
        "## Where the learned filter does worse at sea, and why", "",
        *_failures(sea, features), "",
        "![the learned filter's inputs, simulated against recorded](adaptive-features.png)",
        ""]
    return "\n".join(lines)


def _against_fixed(sea: dict, recorded: dict) -> dict:
    """The learned filter's figures for the targets, with one model's scores on the
    recorded segments (``every[seed]["recorded"]``) against the fixed filter's (``sea``):
    the gain of the median final, the worst segment's final against the fixed filter's,
    and the coverage over every ping and on the least-covered segment."""
    fixed = median_score(sea, FIXED, "final_m")
    worse = {n: r["scores"][LEARNED]["final_m"] / sea[n]["scores"][FIXED]["final_m"] - 1
             for n, r in recorded.items()}
    covered = {n: r["scores"][LEARNED].get("coverage_3sigma", math.nan)
               for n, r in recorded.items()}
    worst, least = max(worse, key=worse.get), min(covered, key=covered.get)
    return dict(final=median_score(recorded, LEARNED, "final_m"), fixed=fixed,
                gain=1 - median_score(recorded, LEARNED, "final_m") / fixed,
                worst=worst, worse=worse[worst], pooled=pooled_coverage(recorded, LEARNED),
                least=least, least_share=covered[least])


def _targets(sea: dict, every: dict) -> list[str]:
    """The targets with the first seed's model, and whether every seed's meets them."""
    figures = [_against_fixed(sea, parts["recorded"]) for parts in every.values()]
    first = figures[0]
    seeds = list(every)
    tests = dict(gain=lambda f: f["gain"] >= TARGET_GAIN,
                 worse=lambda f: f["worse"] <= TARGET_WORSE,
                 pooled=lambda f: f["pooled"] >= TARGET_COVERAGE,
                 least=lambda f: f["least_share"] >= TARGET_COVERAGE)

    def met(key: str, spread: str) -> str:
        ok = sum(tests[key](f) for f in figures)
        said = f" (every seed's model, {seeds[0]} to {seeds[-1]}: {spread})" \
            if len(figures) > 1 else ""
        if ok == len(figures):
            return f"{said}; met"
        return f"{said}; **missed**" if ok == 0 else \
            f"{said}; met by {ok} of {len(figures)} models, **missed**"

    def spread(key: str, scale: float = 100, spec: str = ".1f") -> str:
        values = [scale * f[key] for f in figures]
        return f"{min(values):{spec}} to {max(values):{spec}}"

    return [
        "Targets on the recorded segments, the learned filter against the fixed one (the "
        "model of the tables; every seed's model in brackets, and a target is met only if "
        "every model meets it):", "",
        f"- median final horizontal error at least {100 * TARGET_GAIN:.0f} % below the "
        f"fixed filter's: {first['final']:.2f} m against {first['fixed']:.2f} m, "
        f"{100 * abs(first['gain']):.1f} % {'below' if first['gain'] >= 0 else 'above'}"
        f"{met('gain', spread('gain') + ' % below')};",
        f"- no segment's final error more than {100 * TARGET_WORSE:.0f} % worse: the worst, "
        f"{first['worst']}, {100 * first['worse']:+.1f} %"
        f"{met('worse', 'the worst ' + spread('worse', spec='+.1f') + ' %')};",
        f"- 3-sigma coverage at least {100 * TARGET_COVERAGE:.0f} %: "
        f"{100 * first['pooled']:.1f} % over every segment's pings"
        f"{met('pooled', spread('pooled') + ' %')}; per segment the least "
        f"{first['least']}'s {100 * first['least_share']:.1f} %"
        f"{met('least', spread('least_share') + ' %')}."]


def _seeds(sim: dict, sea: dict, every: dict) -> list[str]:
    """The learned filter with every seed's model: medians held out and at sea."""
    lines = [
        "## Every seed", "",
        f"The learned filter with each of the {len(every)} noise models, trained on the "
        "same data from their own seeds (the tables above show the first). Beside them, the "
        f"fixed filter's median final: {median_score(sim, FIXED, 'final_m'):.2f} m held out, "
        f"{median_score(sea, FIXED, 'final_m'):.2f} m at sea.", "",
        "| seed | held out: median final / RMSE (m) | at sea: median final / RMSE (m) | at "
        "sea: median final below the fixed filter's (%) | at sea: worst segment's final "
        "against the fixed filter's (%) | at sea: within 3 sigma, every ping / least "
        "segment (%) | at sea: learned std over the stated, median per segment (in the "
        "table's order) |",
        "|---|---|---|---|---|---|---|"]
    for seed, parts in every.items():
        held, f = parts["simulated"], _against_fixed(sea, parts["recorded"])
        lines.append(
            f"| {seed} | {median_score(held, LEARNED, 'final_m'):.2f} / "
            f"{median_score(held, LEARNED, 'rmse_m'):.2f} | {f['final']:.2f} / "
            f"{median_score(parts['recorded'], LEARNED, 'rmse_m'):.2f} | "
            f"{100 * f['gain']:.1f} | {100 * f['worse']:+.1f} ({f['worst']}) | "
            f"{100 * f['pooled']:.1f} / {100 * f['least_share']:.1f} ({f['least']}) | "
            + ", ".join(f"{r['scale']:.2f}" for r in parts["recorded"].values()) + " |")
    return lines


def _constant_lines(grid: dict, h: dict) -> list[str]:
    """What a constant scale of the DVL's noise does at sea (``grid``'s settings with the
    IMU's at 1; ``h``: its ``_hindsight``): the table, the best one scale for every
    segment, and each segment's own best, both chosen in hindsight."""
    dvl = h["dvl"]
    finals = np.array([[row[d, 1.0] for d in dvl] for row in grid.values()])
    medians = np.median(finals, axis=0)
    best = h["DVL"]
    lines = [
        "## What a constant noise scale can do at sea", "",
        "The fixed filter with the DVL's noise (its white part and its slow error's drive, "
        "as the network scales them) multiplied by a constant, on every recorded segment: "
        "final horizontal error against the reference, m, at each multiple of the stated "
        "std (1: the fixed filter).", "",
        "| segment | " + " | ".join(f"x {d:g}" for d in dvl) + " | best, in hindsight |",
        "|---|" + "---|" * (len(dvl) + 1)]
    for name, row in zip(grid, finals, strict=True):
        j = int(np.argmin(row))
        lines.append(f"| {name} | " + " | ".join(f"{x:.2f}" for x in row)
                     + f" | {row[j]:.2f} (x {dvl[j]:g}) |")
    lines.append("| **median** | " + " | ".join(f"{m:.2f}" for m in medians)
                 + f" | {best['own']:.2f} |")
    lines += [
        "",
        f"- The one scale best for every segment together, chosen in hindsight: x "
        f"{best['setting'][0]:g}, median final {best['one']:.2f} m, "
        f"{_below(best['one'], h['fixed']):.1f} % below the fixed filter's "
        f"{h['fixed']:.2f} m.",
        f"- Each segment's own best scale, chosen in hindsight against the reference (which "
        f"no filter has): median final {best['own']:.2f} m, "
        f"{_below(best['own'], h['fixed']):.1f} % below. "
        "A noise network's scale varies along a segment, so this bounds it only among "
        f"constant scales; the target asks {100 * TARGET_GAIN:.0f} % below."]
    return lines


def _grid(constant: dict, process: dict) -> dict[str, dict[tuple[float, float], float]]:
    """Per mission, its final error at each (DVL multiple, IMU multiple) it was run with:
    its ``constant`` row (the IMU's at 1) and its ``process`` row (``_mission``'s)."""
    return {name: {**{(float(d), 1.0): v for d, v in constant[name].items()},
                   **{tuple(float(x) for x in k.split(",")): v
                      for k, v in process[name].items()}}
            for name in constant}


# The settings of the grid a hindsight choice picks among: the DVL's multiples (the IMU's
# at 1), the IMU's (the DVL's at 1), every pair.
FAMILIES = {"DVL": lambda d, q: q == 1, "IMU": lambda d, q: d == 1,
            "pair": lambda d, q: True}


def _hindsight(grid: dict) -> dict:
    """Over the missions of ``grid`` (``_grid``'s): the fixed filter's median final and,
    per family of settings (``FAMILIES``), the one setting best for every mission together
    (``one``: its median final; ``setting``: (DVL, IMU) multiples) and each mission's own
    best (``own``: the median of their least finals), both chosen in hindsight."""
    finals = list(grid.values())
    settings = sorted(finals[0])
    out = dict(fixed=float(np.median([f[1.0, 1.0] for f in finals])),
               missions=len(finals),
               dvl=sorted({d for d, _ in settings}), imu=sorted({q for _, q in settings}))
    for family, keep in FAMILIES.items():
        chosen = [x for x in settings if keep(*x)]
        medians = [float(np.median([f[x] for f in finals])) for x in chosen]
        k = int(np.argmin(medians))
        out[family] = dict(one=medians[k], setting=chosen[k],
                           own=float(np.median([min(f[x] for x in chosen) for f in finals])))
    return out


def _below(final: float, fixed: float) -> float:
    """How far ``final`` lies below the fixed filter's ``fixed``, %."""
    return 100 * (1 - final / fixed)


def _edge(value: float, values: list[float]) -> str:
    """Words for a best setting at the end of the multiples run: a larger (smaller) one
    might be better still."""
    return " (the grid's edge)" if value in (values[0], values[-1]) else ""


def _process_lines(grid: dict, h: dict) -> list[str]:
    """What a constant scale of the IMU's process noise does at sea, alone and with the
    DVL's (``grid``; ``h``: its ``_hindsight``): the table (the DVL's at 1), the best one
    scale (pair) for every segment and each segment's own, chosen in hindsight."""
    pairs = sorted(next(iter(grid.values())))
    fixed = h["fixed"]
    lines = [
        "## What a constant process noise scale can do at sea", "",
        "The fixed filter with the IMU's process noise (Q: the accelerometers' and gyros' "
        "white noise densities and their biases' drive) multiplied by a constant, on every "
        "recorded segment: final horizontal error against the reference, m, at each "
        "multiple of the stated std (1: the fixed filter); and with the DVL's noise "
        "multiplied too, at each multiple of the table above.", "",
        "| segment | " + " | ".join(f"x {q:g}" for q in h["imu"])
        + " | best, in hindsight | best with the DVL's, in hindsight (DVL x, IMU x) |",
        "|---|" + "---|" * (len(h["imu"]) + 2)]
    for name, finals in grid.items():
        alone = min(h["imu"], key=lambda q: finals[1.0, q])
        pair = min(pairs, key=finals.get)
        lines.append(f"| {name} | " + " | ".join(f"{finals[1.0, q]:.2f}" for q in h["imu"])
                     + f" | {finals[1.0, alone]:.2f} (x {alone:g}) | {finals[pair]:.2f} "
                     f"(x {pair[0]:g}, x {pair[1]:g}) |")
    lines.append("| **median** | " + " | ".join(
        f"{np.median([f[1.0, q] for f in grid.values()]):.2f}" for q in h["imu"])
        + f" | {h['IMU']['own']:.2f} | {h['pair']['own']:.2f} |")
    imu, pair = h["IMU"], h["pair"]
    d, q = pair["setting"]
    return lines + [
        "",
        f"- The one IMU scale best for every segment together, chosen in hindsight: x "
        f"{imu['setting'][1]:g}{_edge(imu['setting'][1], h['imu'])}, median final "
        f"{imu['one']:.2f} m, {_below(imu['one'], fixed):.1f} % below the fixed filter's "
        f"{fixed:.2f} m; each segment's own best: {imu['own']:.2f} m, "
        f"{_below(imu['own'], fixed):.1f} % below.",
        f"- Both noises scaled, the one pair best for every segment together: DVL x {d:g}"
        f"{_edge(d, h['dvl'])}, IMU x {q:g}{_edge(q, h['imu'])}, median final "
        f"{pair['one']:.2f} m, {_below(pair['one'], fixed):.1f} % below; each segment's own "
        f"best pair, chosen in hindsight against the reference: {pair['own']:.2f} m, "
        f"{_below(pair['own'], fixed):.1f} % below. The target asks "
        f"{100 * TARGET_GAIN:.0f} % below."]


def _chance_lines(recorded: dict, simulated: dict) -> list[str]:
    """How much a choice per mission adds to the best one setting for all: at sea, and
    on the held-out simulated missions, where the filter is told the DVL noise the
    simulator drew (its white noise and slow error; not its failures)."""
    def adds(h: dict, family: str) -> float:
        return _below(h[family]["own"], h["fixed"]) - _below(h[family]["one"], h["fixed"])

    def row(label: str, h: dict) -> str:
        return (f"| {label} | {h['fixed']:.2f} | " + " | ".join(
            f"{_below(h[f]['one'], h['fixed']):.1f} / {_below(h[f]['own'], h['fixed']):.1f}"
            for f in FAMILIES) + " |")

    more = [f for f in FAMILIES if adds(recorded, f) > adds(simulated, f)]
    within = [f for f in FAMILIES if f not in more]
    verdict = (
        "no more than in simulation, so the per-segment bounds above lie within what a "
        "choice per mission gains where the noise is known, and do not show that a noise "
        "chosen without the reference would reach the target." if not more else
        f"more than in simulation for the {' and '.join(more)} settings (part of "
        f"{'that bound' if len(more) == 1 else 'those bounds'} may be a noise mis-stated at "
        "sea)" + (f", no more for the {' and '.join(within)} settings." if within else "."))
    return [
        "## How much of a choice in hindsight is chance", "",
        "Median final horizontal error of the fixed filter, m, and how far below it (%) the "
        "best one setting for every mission together and each mission's own best setting "
        "end, both chosen in hindsight among the constant scales above:", "",
        "| missions | fixed (m) | " + " | ".join(
            f"{f} scale{'s' if f == 'pair' else ''}: one for all / each its own (%)"
            for f in FAMILIES) + " |", "|---|---|---|---|---|",
        row(f"{recorded['missions']} recorded segments, against the reference", recorded),
        row(f"{simulated['missions']} held-out simulated missions, against their truth",
            simulated), "",
        "A choice per mission picks the least of a mission's final errors, each a noisy "
        "figure, so it ends lower even where no setting is better than the stated one. On "
        "the simulated missions the filter is told the DVL noise the simulator drew (its "
        "white noise and slow error, not its failures), and choosing per mission adds "
        + ", ".join(f"{adds(simulated, f):.1f} points ({f})" for f in FAMILIES)
        + " to the best one setting for all: an upper estimate of what the choice alone "
        "gains, since part of it may be what the filter is not told there. At sea it adds "
        + ", ".join(f"{adds(recorded, f):.1f} ({f})" for f in FAMILIES) + ": " + verdict]


def _failures(sea: dict, features: dict) -> list[str]:
    from beamsnet.estimators.noisemodel import FEATURES

    lines = []
    worse = {n: r["scores"] for n, r in sea.items()
             if r["scores"][LEARNED]["final_m"] > r["scores"][FIXED]["final_m"]
             or r["scores"][LEARNED]["rmse_m"] > r["scores"][FIXED]["rmse_m"]}
    for name, s in worse.items():
        a, b = s[FIXED], s[LEARNED]
        lines.append(f"- {name}: final {b['final_m']:.2f} m against the fixed filter's "
                     f"{a['final_m']:.2f} m ({100 * (b['final_m'] / a['final_m'] - 1):+.1f} %), "
                     f"RMSE {b['rmse_m']:.2f} against {a['rmse_m']:.2f} m "
                     f"({100 * (b['rmse_m'] / a['rmse_m'] - 1):+.1f} %).")
    if not worse:
        lines.append("- On no segment is the learned filter worse than the fixed one, by "
                     "final or RMSE error.")
    scales = {n: _scale(r["track"]) for n, r in sea.items()}
    lines += ["", "The learned std scale (the noise's std over the stated) per segment, "
              "median (5-95 %): " + "; ".join(
                  f"{n} {np.median(s):.2f} ({np.percentile(s, 5):.2f}-"
                  f"{np.percentile(s, 95):.2f})" for n, s in scales.items()) + ".", ""]
    shift = _shift(features)
    lines += ["Its inputs, simulated (the held-out missions, both measurement forms) "
              "against recorded (every segment): median (5-95 %), the share of recorded "
              "pings outside the simulated 1-99 % range, and the two-sample "
              "Kolmogorov-Smirnov distance (0: the same distribution, 1: disjoint):", "",
              "| input | simulated | recorded | recorded outside the simulated range (%) | "
              "KS distance |", "|---|---|---|---|---|"]
    for name in sorted(FEATURES, key=lambda n: -shift[n]["ks"]):
        s = shift[name]
        lines.append(f"| {name} | {_range(s['simulated'])} | {_range(s['recorded'])} | "
                     f"{100 * s['outside']:.1f} | {s['ks']:.2f} |")
    moved = sorted((n for n in FEATURES if shift[n]["ks"] >= MOVED),
                   key=lambda n: -shift[n]["ks"])
    lines += ["", f"Moved most (KS distance at least {MOVED:g}), their medians in their own "
              "units, simulated against recorded:", ""]
    lines += [f"- {n} (KS {shift[n]['ks']:.2f}): {NATURAL[n][0]}, "
              f"{_natural(n, shift[n]['simulated'][1])} against "
              f"{_natural(n, shift[n]['recorded'][1])}" for n in moved] or ["- none"]
    implied = [shift["log implied scale"][k][1] for k in ("simulated", "recorded")]
    scale = float(np.median(np.concatenate(list(scales.values()))))
    based = float(np.median(np.concatenate([_scale(r["model_based"]) for r in sea.values()])))
    least = min(sea, key=lambda n: sea[n]["scores"][FIXED].get("coverage_3sigma", 1.0))
    cover = [100 * sea[least]["scores"][label].get("coverage_3sigma", math.nan)
             for label in (FIXED, LEARNED)]
    lines += ["", "What it means (our reading of these figures): the network learned to follow "
              "the innovations, and the recorded ones are "
              f"{'smaller' if implied[1] < implied[0] else 'larger'} than the stated noise "
              "predicts: the scale they imply (the ping's lambda nu^2 / S) is "
              f"{_natural('log implied scale', implied[1])} at sea against "
              f"{_natural('log implied scale', implied[0])} on the held-out "
              "missions, where the filter's noise model is the simulator's own. So at sea it "
              f"sets the DVL's noise at {scale:.2f} times the stated std (median over the "
              "segments' pings), where the model-based filter, which reads the innovations "
              f"alone, sets its own at {based:.2f}; of the network's other inputs, "
              f"{_moved_words(shift, moved)}. What separates the "
              "filter from the reference is slow (the "
              "DVL's and the reference's own slow errors, which `benchmarks/sea_filter.py "
              "--evidence` measures): no ping-to-ping innovation shows it, so a noise that "
              "follows the innovations cannot take it out, and where the noise is made "
              "smaller the reported sigma shrinks with it. The segment the fixed filter "
              f"covers least, {least}: fixed {cover[0]:.1f} %, learned {cover[1]:.1f} %."]
    return lines


def _moved_words(shift: dict, moved: list[str]) -> str:
    """How far the inputs other than the implied scale moved, in words (``_failures``)."""
    others = [n for n in shift if n != "log implied scale"]
    farthest = max(others, key=lambda n: shift[n]["outside"])
    moved = [n for n in moved if n != "log implied scale"]
    return ((", ".join(moved) + (" moves" if len(moved) == 1 else " move") + " the most "
             if moved else "none moves far ") + "(above), and the one most often outside the "
            f"range it was trained on is {farthest}, at "
            f"{100 * shift[farthest]['outside']:.1f} % of the recorded pings")


MOVED = 0.5  # the KS distance from which an input counts as moved
# Each input in its own units: what it is, and from the feature x the value.
NATURAL = {
    "log rotation rate": ("mean rotation rate, deg/s",
                          lambda x: math.degrees(math.exp(x) - 1e-3)),
    "log rms |f| - g": ("r.m.s. of |f| - g, m/s^2", lambda x: math.exp(x) - 1e-3),
    "log speed": ("speed, m/s", lambda x: math.exp(x) - 0.1),
    "log implied scale": ("the scale the ping's innovations imply, lambda nu^2 / S",
                          lambda x: math.exp(x) - 0.01),
    "scaled noise share": ("share of S the scaled noise makes", lambda x: x),
    "offered share": ("share of the measurements offered", lambda x: x),
}


def _natural(name: str, x: float) -> str:
    return f"{NATURAL[name][1](x):.3g}"


def _range(q: list[float]) -> str:
    return f"{q[1]:.2f} ({q[0]:.2f} to {q[2]:.2f})"


def _scale(track) -> np.ndarray:
    """(P,) the learned std over the stated at the track's started pings."""
    s = np.asarray(track.measurement_std)[:, 0] / np.asarray(track.stated_std)[:, 0]
    return s[np.isfinite(s)]


def _noise_figure(sim: dict, sea: dict, path: Path) -> None:
    """Per column (the held-out mission and the recorded segment where the learned
    filter's final error differs most from the fixed one's): the rotation rate and speed,
    the innovations' RMS over the stated noise, and the learned and model-based std
    scales, over time."""
    import matplotlib.pyplot as plt

    def pick(results):
        return max(results, key=lambda n: abs(
            results[n]["scores"][LEARNED]["final_m"] - results[n]["scores"][FIXED]["final_m"]))

    columns = [("simulated", n := pick(sim), sim[n]), ("recorded", m := pick(sea), sea[m])]
    fig, axes = plt.subplots(3, 2, figsize=(11, 7.5), sharex="col")
    for c, (kind, name, r) in enumerate(columns):
        track, adaptive_track = r["track"], r["model_based"]
        t = track.ping_time
        x = track.features
        rate = np.degrees(np.exp(x[:, 0]) - 1e-3)
        ax = axes[0, c]
        ax.plot(t, rate, color="tab:blue", lw=0.8)
        ax.set_ylabel("rotation rate (deg/s)")
        ax.set_title(f"{kind}: {name}")
        twin = ax.twinx()
        twin.plot(t, np.exp(x[:, 2]) - 0.1, color="tab:gray", lw=0.8)
        twin.set_ylabel("speed (m/s)", color="tab:gray")
        offered = np.isfinite(track.innovation)
        rms = np.sqrt((np.where(offered, track.innovation, 0.0) ** 2).sum(axis=1) / np.maximum(
            offered.sum(axis=1), 1)) / np.nanmax(np.asarray(track.stated_std), axis=1)
        rms[~offered.any(axis=1)] = np.nan
        axes[1, c].semilogy(t, rms, color="tab:purple", lw=0.6)
        axes[1, c].set_ylabel("innovation RMS / stated std")
        for tr, label, style in ((track, LEARNED, "-"), (adaptive_track, MODEL_BASED, "--")):
            scale = np.asarray(tr.measurement_std)[:, 0] / np.asarray(tr.stated_std)[:, 0]
            axes[2, c].plot(t, scale, style, lw=1.0, label=label)
        axes[2, c].set_ylabel("noise std / stated")
        axes[2, c].set_xlabel("time (s)")
        axes[2, c].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def _feature_figure(features: dict, path: Path) -> None:
    """One histogram per input, simulated against recorded (densities)."""
    import matplotlib.pyplot as plt

    from beamsnet.estimators.noisemodel import FEATURES

    sim, real = features["simulated"], features["recorded"]
    cols = math.ceil(len(FEATURES) / 2)
    fig, axes = plt.subplots(2, cols, figsize=(3.25 * cols, 5.5))
    for j, name in enumerate(FEATURES):
        ax = axes.flat[j]
        both = np.concatenate([sim[:, j], real[:, j]])
        lo, hi = np.percentile(both, [0.5, 99.5])
        bins = np.linspace(lo, hi, 40) if hi > lo else np.linspace(lo - 0.5, lo + 0.5, 11)
        ax.hist(sim[:, j], bins=bins, density=True, alpha=0.5, label="simulated")
        ax.hist(real[:, j], bins=bins, density=True, alpha=0.5, label="recorded")
        ax.set_title(name, fontsize=9)
    axes.flat[0].legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
