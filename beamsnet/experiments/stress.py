"""``beamsnet stress``: where each DVL estimator holds and where it breaks under manoeuvres.

BeamsNetV2 takes the beams of the past pings as context, which the paper justifies by an
AUV that "travels in straight-line trajectories" most of the time. This module trains
the networks the paper's way, on straight lines (the ``paper-sim`` missions, or a file the
user gives), and tests them with least squares, the affine calibration and the Kalman
filter on every manoeuvre of the ``maneuvers`` preset, where the velocity does change:

* per manoeuvre, the speed RMSE (the paper's metric) and the vector RMSE;
* the dead-reckoning error each estimator's velocity leaves after the manoeuvre: the
  velocities, rotated to NED with the true attitude, summed over the pings, minus the
  same sum of the true DVL velocities (so only the estimator's error counts);
* the error against the manoeuvre's intensity at each ping (true yaw rate, and how fast
  the true velocity in the DVL frame, the frame the beams see, changed since the last
  ping: what V2's premise is about; a steady turn rotates the velocity in NED but not in
  the DVL frame), and over time with the manoeuvre's phases shaded.

Every estimator sees the same pings: every ping of each manoeuvre with its past pings and
IMU interval valid (``beamsnet.data``). The whole manoeuvre file is test data.

With ``faults=True`` the same trained models are tested instead on faulted versions of the
manoeuvres (dropouts, a dead beam, outliers, water track): ``beamsnet.experiments.faults``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path

import numpy as np

from auvsim.data.files import save_figure, staged_dir, write_text
from auvsim.data.reader import open_dataset
from auvsim.errors import ConfigError
from beamsnet import metrics
from beamsnet.data import Windows, check_dataset, load_windows, split
from beamsnet.estimators import short_name, spec, specs
from beamsnet.evaluate import predictions
from beamsnet.experiments.defaults import (
    FAULT_DURATION,
    MANEUVER_DURATION,
    NOISE,
    TRAIN_DURATION,
)
from beamsnet.experiments.faults import check_options, fault_stress
from beamsnet.experiments.runner import check_duration, ensure_dataset, settings, train_runs
from beamsnet.experiments.wording import as_published, count, why_worse
from beamsnet.navigation import (
    dead_reckoning_error,
    dead_reckoning_track,
    held,
    own_position_error,
    truth_at_pings,
)
from beamsnet.plotstyle import decades_only, figure_legend, panel_grid, styles
from beamsnet.training.checkpoints import SENSOR_GEOMETRY, sensor_setup
from beamsnet.training.config import TrainConfig

INTENSITY = {"yaw_rate": "true yaw rate |r|, deg/s",
             "acceleration": "change of the true DVL-frame velocity since the last ping, "
                             "m/s^2"}


def stress(*, train_data: Path | None, maneuver_data: Path | None, out: Path,
           training: TrainConfig | None = None, restarts: int | None = None,
           train_duration: float = TRAIN_DURATION,
           maneuver_duration: float = MANEUVER_DURATION, runs: Path = Path("runs"),
           faults: bool = False, fault_duration: float | None = None,
           fault_missions: tuple[str, ...] | None = None, noise: str = "code",
           progress: bool = True, cluster: str | None = None) -> Path:
    """Train on straight lines, test on manoeuvres, write ``out/stress.md`` and figures.

    Args:
        train_data: a dataset to train on (default: ``paper-sim`` with ``train_duration``
            s per speed, generated under ``datasets/`` if missing). Every mission is used.
        maneuver_data: a dataset of manoeuvres to test on (default: the ``maneuvers``
            preset with ``maneuver_duration`` s each, generated if missing).
        out: the report's directory.
        training: the training settings, the model set per run (default: the ``stress``
            profile of ``beamsnet.training.config.PROFILES``: the paper's settings, Polyak
            averaging over the last epochs).
        restarts: seeds per model, kept by training fit (default: the profile's).
        runs: where the trained models go (``runs/stress/<file stem>/v1|v2``).
        faults: test on the fault sweep of ``beamsnet.experiments.faults`` instead of the manoeuvres
            (``out/faults.md``); ``maneuver_data`` must then be None.
        fault_duration: s per manoeuvre of the faulted test data (default
            ``beamsnet.experiments.faults.FAULT_DURATION``).
        fault_missions: the manoeuvres of the faulted test data (default
            ``beamsnet.experiments.faults.FAULT_MISSIONS``).
        noise: the beam noise of the generated training and test data: ``"code"``, the
            paper's code's 0.042^2 m/s (``paper-sim``), or ``"text"``, its text's 0.042
            m/s (``paper-sim-text``, and the manoeuvres flown with it).
        progress: progress bars.
        cluster: generate missing datasets and train on this Dask cluster instead
            (``auvsim.runs.generate``, ``beamsnet.training.runs.train_all``).

    Returns:
        The report's path.

    Raises:
        ConfigError: a bad setting, before any data is generated or model trained.
    """
    from auvsim.runs.presets import maneuvers, preset

    training, restarts = settings("stress", training, restarts, out=out, cluster=cluster)
    if noise not in NOISE:
        raise ConfigError(f"expected one of {', '.join(NOISE)} (the paper's code's or text's "
                          f"beam noise), got {noise!r}", argument="noise")
    if faults:
        if maneuver_data is not None:
            raise ConfigError("is not used by the fault sweep, which generates its own "
                              "faulted manoeuvres; expected no manoeuvre file with faults",
                              argument="maneuver_data")
        fault_duration, fault_missions = check_options(
            FAULT_DURATION if fault_duration is None else fault_duration, fault_missions)
    else:
        for name, value in (("fault_duration", fault_duration),
                            ("fault_missions", fault_missions)):
            if value is not None:
                raise ConfigError("is a setting of the fault sweep; expected it only "
                                  "together with faults", argument=name)
    # The given files too: a wrong one is refused before any other is generated.
    if train_data is not None:
        check_dataset(train_data, argument="train_data")
    if maneuver_data is not None:
        check_dataset(maneuver_data, argument="maneuver_data", truth=True)
        if train_data is not None:
            _check_geometry(train_data, maneuver_data)
    train_preset, noise_std, suffix = NOISE[noise]
    # Both configs (their durations checked) before either file is generated.
    train_config = maneuver_config = None
    if train_data is None:
        check_duration(train_duration, "train_duration")
        train_config = preset(train_preset).with_duration(train_duration)
    if maneuver_data is None and not faults:
        check_duration(maneuver_duration, "maneuver_duration")
        maneuver_config = maneuvers(maneuver_duration, noise_std=noise_std)
    if train_config is not None:
        train_data = ensure_dataset(train_config,
                                    Path("datasets") / f"{train_preset}_{train_duration:g}s.h5",
                                    progress=progress, cluster=cluster)
    if maneuver_config is not None:
        maneuver_data = ensure_dataset(
            maneuver_config, Path("datasets") / f"maneuvers{suffix}_{maneuver_duration:g}s.h5",
            progress=progress, cluster=cluster)

    if maneuver_data is not None:
        _check_geometry(train_data, maneuver_data)
    windows = load_windows(train_data)  # the models' own (default) n_past
    if not faults:  # the test's pings too, so that a file too short is refused before training
        phases = _phases(maneuver_data)  # also gives the missions in the config's order
        test_w = load_windows(maneuver_data, missions=list(phases) or None)
    # Every network of the registry that the file can feed (V1 needs IMU data, which an
    # imported stream has none of); every mission. The masked ones (V2M, CorrectionNet)
    # run on the fault sweep's missing beams.
    names = [s.name for s in specs("network") if windows.accel is not None or not s.needs.imu]
    kept = train_runs(train_data, {name: dataclasses.replace(training, model=name)
                                   for name in names},
                      runs / "stress" / Path(train_data).stem, restarts, progress=progress,
                      cluster=cluster)
    models = [k.loaded() for k in kept.values()]
    train_w, _ = split(windows)
    if faults:
        return fault_stress(models=models, train_w=train_w, train_data=train_data,
                            trained_on=_scenarios(train_data), out=out,
                            duration=fault_duration, missions=fault_missions,
                            noise_std=noise_std, progress=progress)
    trained_on = _scenarios(train_data)
    unstarted = _unstarted(maneuver_data, phases)
    if unstarted:
        longer = ("longer missions in --maneuvers" if maneuver_config is None
                  else "a longer --maneuver-duration")  # it generated the file, or not
        warnings.warn(f"{', '.join(unstarted)}: flew one phase only, their manoeuvre starting "
                      "later than the mission ends; their rows are of straight flight "
                      f"(expected {longer} to test them)", stacklevel=2)
    positions: dict[str, np.ndarray] = {}
    estimates = predictions(models, train_w, test_w, dataset=maneuver_data,
                            positions=positions)
    truth = truth_at_pings(maneuver_data, test_w)
    rows = _table(test_w, estimates, truth, positions)

    binned = {key: _binned(test_w, estimates, truth[key]) for key in INTENSITY}
    with staged_dir(out) as stage:  # the report and every figure, or none of them
        _plot_intensity(binned, stage / "stress_intensity.png")
        _plot_time(test_w, estimates, phases, stage / "stress_time.png")
        plot_tracks(test_w, estimates, truth, positions, stage / "stress_tracks.png")
        write_text(stage / "stress.json", json.dumps(rows, indent=1))
        write_text(stage / "stress.md",
                   _report(train_data, trained_on, maneuver_data, models, binned, rows,
                           unstarted))
    return Path(out) / "stress.md"


def _table(windows: Windows, estimates: dict[str, np.ndarray],
           truth: dict[str, np.ndarray], positions: dict[str, np.ndarray] | None = None
           ) -> dict[str, dict[str, dict[str, float]]]:
    """{manoeuvre: {estimator: speed RMSE, vector RMSE, dead-reckoning error}}. An
    estimator with its own position solution (``positions``) is scored by that position's
    error instead of its integrated velocity's."""
    positions = positions or {}
    rows = {}
    for i, name in enumerate(windows.names):
        mine = windows.mission == i
        rows[name] = {}
        for estimator, pred in estimates.items():
            drift, travelled = dead_reckoning_error(windows, pred, truth, i)
            if estimator in positions:
                drift = own_position_error(windows, positions[estimator], truth, i)
            rows[name][estimator] = dict(
                rmse=metrics.rmse(pred[mine], windows.target[mine]),
                rmse_vector=metrics.rmse_vector(pred[mine], windows.target[mine]),
                dr_error=drift, dr_percent=100 * drift / travelled if travelled else math.nan,
                pings=int(mine.sum()))
    return rows


def _generated_missions(path: Path) -> list[dict] | None:
    """The missions of a dataset's generating config (its stored JSON), in the config's
    order; None for a file whose config does not name its missions (a recording or an
    import)."""
    with open_dataset(path) as f:
        text = f.config_json
        names = set(f.missions)
    try:
        missions = json.loads(text)["missions"]
        listed = {m["name"] for m in missions}
        named = all(isinstance(m["scenario"]["name"], str) for m in missions)
    except (ValueError, TypeError, KeyError):
        return None
    return missions if named and listed == names else None


def _scenarios(path: Path) -> str:
    """What the training file's missions fly, in words for the report."""
    missions = _generated_missions(path)
    if missions is None:
        return "the missions of that file"
    kinds = sorted({m["scenario"]["name"] for m in missions})
    if kinds == ["straight"]:
        return "straight lines, as in the paper"
    return "missions flying " + ", ".join(kinds)


def _phases(path: Path) -> dict[str, list[tuple[float, float, str]]]:
    """The manoeuvre phases of every mission, (start s, end s, label) each, as the file
    stores them, by mission in the config's order (empty for a file whose config does not
    name its missions, such as a recording)."""
    missions = _generated_missions(path)
    if missions is None:
        return {}
    with open_dataset(path) as f:
        return {m["name"]: list(f.missions[m["name"]].phases) for m in missions}


def _unstarted(path: Path, phases: dict[str, list]) -> list[str]:
    """The missions whose manoeuvre never started: not a straight line by their config,
    yet flown as one phase (a 60 s depth_steps, whose first step is at 60 s)."""
    kinds = {m["name"]: m["scenario"]["name"] for m in _generated_missions(path) or []}
    return [name for name, parts in phases.items()
            if kinds.get(name, "straight") != "straight" and len(parts) <= 1]


def _check_geometry(train_data: Path, maneuver_data: Path) -> None:
    """Refuse test data whose DVL or IMU geometry and rates (``SENSOR_GEOMETRY``) are not
    the training data's, before anything is trained: every estimator learned one beam
    matrix and one ping spacing."""
    def geometry(path: Path) -> dict[str, list[float] | float]:
        first = next(iter(sensor_setup(path).values()), {})
        return {k: first[k] for k in SENSOR_GEOMETRY if k in first}

    trained, tested = geometry(train_data), geometry(maneuver_data)
    differ = [k for k in trained if k in tested
              and not np.allclose(trained[k], tested[k], rtol=0, atol=1e-9)]
    if differ:
        said = "; ".join(f"{k} {tested[k]} against {trained[k]}" for k in differ)
        raise ConfigError(f"{str(maneuver_data)!r}: its sensors differ from the training "
                          f"data's ({said}); expected manoeuvres flown with the training "
                          "data's DVL and IMU (or training data of the same sensors)",
                          argument="maneuver_data")


def _report(train_data, trained_on, maneuver_data, models, binned, rows, unstarted=()
            ) -> str:
    names = list(next(iter(rows.values())))
    head = "| manoeuvre | pings | " + " | ".join(short_name(n) for n in names) + " |"
    rule = "|---|---|" + "---|" * len(names)

    raw = unlearned(binned)

    def table(cell) -> list[str]:
        return [head, rule] + [
            f"| {m} | {next(iter(r.values()))['pings']} | "
            + " | ".join(cell(r[n]) for n in names) + " |" for m, r in rows.items()]

    trained = ", ".join(
        f"{spec(c['model']).short}{as_published(c['train_config'])} "
        f"({c['samples']['train']} pings, lr "
        f"{c['train_config']['lr']:g}, {count(c['train_config']['epochs'], 'epoch')})"
        for _, _, c in models)
    lines = [
        "# Manoeuvre stress test: where each DVL estimator holds and where it breaks",
        "",
        f"Made by `beamsnet stress` (trained on `{train_data}`, tested on "
        f"`{maneuver_data}`). The networks were trained on {trained_on}: "
        f"{trained}; the calibrations, the Kalman filters, the missing-beam regressor and "
        "the INS/DVL filter's beam calibration were fitted on the same "
        "training split. Every row uses the same pings of each manoeuvre.",
        *([] if not unstarted else [
            "", f"At this size {', '.join(unstarted)} flew one phase only: their manoeuvre "
            "starts later than the mission ends, so their rows are of straight flight."]),
        "",
        "## Speed RMSE (m/s) / vector RMSE (m/s)",
        "",
        *table(lambda c: f"{c['rmse']:.4f} / {c['rmse_vector']:.4f}"),
        "",
        "Best estimator per manoeuvre by vector RMSE, and how far below LS it is:",
        "",
        "| manoeuvre | best | vector RMSE (m/s) | LS (m/s) | below LS |",
        "|---|---|---|---|---|",
        *[f"| {m} | {short_name(b)} | {r[b]['rmse_vector']:.4f} | {r['LS']['rmse_vector']:.4f} | "
          f"{100 * (1 - r[b]['rmse_vector'] / r['LS']['rmse_vector']):.1f} % |"
          for m, r in rows.items()
          for b in [min(r, key=lambda n, r=r: r[n]["rmse_vector"])]],
        "",
        "## Dead-reckoning error after each manoeuvre",
        "",
        "Horizontal position error (m) from integrating each estimator's velocity instead "
        "of the true DVL velocity, with the true attitude (the INS/DVL filter: its own "
        "position solution against the true position), and as % of the distance "
        "travelled:",
        "",
        *table(lambda c: f"{c['dr_error']:.2f} m ({c['dr_percent']:.3f} %)"),
        "",
        "![error against manoeuvre intensity](stress_intensity.png)",
        "",
        "![error over time, phases shaded](stress_time.png)",
        "",
        "![each mission's track and every estimator's position error](stress_tracks.png)",
        "",
        "## Rows worse than LS, and why",
        "",
        "By vector RMSE:",
        "",
        *why_worse(rows, "rmse_vector", unlearned=raw),
        "",
        "By dead-reckoning error:",
        "",
        *why_worse(rows, "dr_error", unlearned=raw),
        "",
        "## What it shows",
        "",
        *_findings(binned, rows),
    ]
    return "\n".join(lines) + "\n"


def _binned(windows: Windows, estimates: dict, intensity: np.ndarray, bins: int = 6):
    """Bin edges over ``intensity`` (quantiles) and each estimator's vector RMSE per bin."""
    edges = np.unique(np.quantile(intensity, np.linspace(0, 1, bins + 1)))
    which = np.clip(np.searchsorted(edges, intensity, side="right") - 1, 0, len(edges) - 2)
    out = {}
    for name, pred in estimates.items():
        err = np.sum((pred - windows.target) ** 2, axis=1)
        out[name] = np.array([math.sqrt(err[which == b].mean()) if np.any(which == b)
                              else math.nan for b in range(len(edges) - 1)])
    return edges, out


def _findings(binned: dict, rows: dict) -> list[str]:
    """Plain sentences computed from the results: ``binned`` holds each intensity's
    ``_binned``, ``rows`` the ``_table``."""
    names = list(next(iter(rows.values())))
    v2 = next((n for n in names if short_name(n) == spec("v2").short), None)
    lines = []
    calm = rows.get("straight")
    for key, label in INTENSITY.items():
        edges, rmse = binned[key]
        ratios = ", ".join(f"{short_name(n)} {rmse[n][-1] / rmse[n][0]:.1f}x" for n in names)
        lines.append(f"- From the calmest to the most intense sixth of the pings by {label} "
                     f"({edges[0]:.3g} to {edges[1]:.3g} against {edges[-2]:.3g} to "
                     f"{edges[-1]:.3g}), the vector RMSE grows: {ratios}.")
    if v2 is not None:
        worse = [m for m, r in rows.items() if r[v2]["rmse_vector"] > r["LS"]["rmse_vector"]]
        best = {m: min(r, key=lambda n: r[n]["rmse_vector"]) for m, r in rows.items()}
        lines.append(
            f"- BeamsNetV2 is worse than plain least squares (vector RMSE) on "
            f"{len(worse)} of {len(rows)} missions"
            + (f": {', '.join(worse)}." if worse else "."))
        if calm is not None:
            worst = max(rows, key=lambda m: rows[m][v2]["rmse_vector"])
            lines.append(
                f"- On the straight line, BeamsNetV2's vector RMSE is "
                f"{calm[v2]['rmse_vector']:.4f} m/s against LS {calm['LS']['rmse_vector']:.4f};"
                f" its largest, on {worst}, is {rows[worst][v2]['rmse_vector']:.4f} m/s "
                f"against LS {rows[worst]['LS']['rmse_vector']:.4f}.")
        lines.append("- Best estimator (vector RMSE) per manoeuvre: "
                     + ", ".join(f"{m}: {short_name(b)}" for m, b in best.items()) + ".")
        lines += _verdict(binned, rows, v2)
    return lines


# An estimator fitted to data whose error on the calmest pings is this many times least
# squares' has not learned the instrument: one trained on it sits near LS there or below
# (within 6 % above it on the straight line of the realistic manoeuvres, reports/stress-rm),
# one trained for a single epoch some hundred times above (a smoke run: BeamsNetV1 at
# 1.96 m/s against 0.014).
UNLEARNED_FACTOR = 2.0


def unlearned(binned: dict) -> list[str]:
    """The estimators fitted to data (not LS, not a filter) ``UNLEARNED_FACTOR`` times as
    far off as least squares even on the calmest pings (the first bin of every intensity
    in ``binned``): they have not learned the instrument (too few epochs or too little
    data, a smoke run), so how their error grows says nothing of their premise."""
    calm, filters = _calmest(binned), _filters()
    return [n for n in calm if n != "LS" and n not in filters
            and calm[n] > UNLEARNED_FACTOR * calm["LS"]]


def _calmest(binned: dict) -> dict[str, float]:
    """Each estimator's error on the calmest pings: the least of every intensity's first
    bin (``_binned``)."""
    names = list(next(iter(binned.values()))[1])
    return {n: min(rmse[n][0] for _, rmse in binned.values()) for n in names}


def _filters() -> set[str]:
    """The filters' rows: they integrate the IMU, where the others are fitted to data."""
    return {s.name for s in specs("filter")}


def _verdict(binned: dict, rows: dict, v2: str) -> list[str]:
    """What the growth of each estimator's error with the manoeuvres' intensity says:
    which estimators degrade at all, whether V2 degrades more than the memoryless affine
    calibration fitted on the same data (its past-ping premise), and each one's worst
    manoeuvre."""
    names = list(next(iter(rows.values())))
    growth = {n: max(rmse[n][-1] / rmse[n][0] for _, rmse in binned.values()) for n in names}
    lines = []
    raw = unlearned(binned)
    fitted = set(names) - _filters() - set(raw) - {"LS"}  # fitted to data, and learned
    grows = [n for n in names if n in fitted
             and growth[n] > 2 * growth["LS"]]
    if grows:
        lines.append(
            "- Wherever the vehicle turns or changes depth or speed, the estimators fitted "
            "to data lose accuracy and least squares, fitted to nothing, does not: from the "
            "calmest to the most intense pings the error grows "
            + ", ".join(f"{growth[n]:.1f}x ({short_name(n)})" for n in grows)
            + f" against {growth['LS']:.1f}x (LS). Much of it is extrapolation: training data "
            "of straight lines never show a sway or heave velocity, so what an estimator "
            "learns for them is a constant, which a turn contradicts even when it is steady.")
    if raw:
        calm = _calmest(binned)
        lines.append(
            f"- At least {UNLEARNED_FACTOR:g}x as far off as least squares even on the "
            "calmest pings (" + ", ".join(f"{short_name(n)} {calm[n]:.4f}" for n in raw)
            + f" against LS {calm['LS']:.4f} m/s vector RMSE), so not fitted to the "
            "instrument at all (too few epochs or too little training data: a smoke run): "
            "how their error grows with the manoeuvres says nothing of what they assume"
            + (" (BeamsNetV2: that the past pings show the motion of the current one)"
               if v2 in raw else "") + ".")
    if v2 not in raw:  # its premise, where it has learned the instrument
        lines += _premise(growth, v2)
    worst = {n: max(rows, key=lambda m, n=n: rows[m][n]["rmse_vector"]) for n in names}
    lines.append("- Worst manoeuvre per estimator (vector RMSE): " + "; ".join(
        f"{short_name(n)}: {m} ({rows[m][n]['rmse_vector']:.4f} m/s)" for n, m in worst.items())
        + ".")
    best_dr = {m: min(r, key=lambda n, r=r: r[n]["dr_error"]) for m, r in rows.items()}
    lines.append("- Smallest dead-reckoning error per manoeuvre: " + ", ".join(
        f"{m}: {short_name(n)}" for m, n in best_dr.items()) + ". Dead reckoning integrates "
        "the error, so a small bias (LS's scale factor) costs more there than a large "
        "error that changes sign (a zigzag's).")
    return lines


def _premise(growth: dict[str, float], v2: str) -> list[str]:
    """What BeamsNetV2's growth with the intensity says of its premise, that the past
    pings show the motion of the current one: held, failing (more than the memoryless
    affine calibration's), or not what fails first."""
    if growth[v2] <= 1.5 * growth["LS"]:
        return [f"- BeamsNetV2's error grows no more with the manoeuvres' intensity than least "
                f"squares' ({growth[v2]:.1f}x against {growth['LS']:.1f}x): at these "
                "manoeuvres' rates its premise, that the past pings show the motion of the "
                "current one, holds."]
    if "Affine" not in growth:
        return []
    if growth[v2] > 1.5 * growth["Affine"]:
        return [f"- BeamsNetV2 degrades more than the affine calibration fitted on the same "
                f"data but blind to the past ({growth[v2]:.1f}x against "
                f"{growth['Affine']:.1f}x): the difference is its premise, that the past "
                "pings show the motion of the current one, failing."]
    return [f"- BeamsNetV2 degrades no more than the affine calibration fitted on the same "
            f"data and blind to the past ({growth[v2]:.1f}x against "
            f"{growth['Affine']:.1f}x), so here its past-ping premise is not what fails "
            "first: the training data's reach is. Training on manoeuvres (`beamsnet "
            "stress --train FILE`) separates the two."]


TRACK_COLUMNS = 5  # missions per row of the tracks figure


def _plot_intensity(binned: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 4), layout="constrained")
    for ax, (key, label) in zip(axes, INTENSITY.items(), strict=True):
        edges, rmse = binned[key]
        centres = 0.5 * (edges[1:] + edges[:-1])
        look = styles(rmse)
        for name, values in rmse.items():
            ax.plot(centres, values, marker=look[name].marker, label=short_name(name),
                    **look[name].line())
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("vector RMSE, m/s")
        ax.grid(True, which="both", alpha=0.3)
    figure_legend(fig, axes[0], fontsize=8)
    fig.suptitle("Error against manoeuvre intensity (pings binned by sixths)")
    save_figure(fig, path, dpi=110)


def _plot_time(windows, estimates, phases, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")

    n = len(windows.names)
    cols = 2
    fig, axes = panel_grid(-(-n // cols), cols, panel=(5.2, 1.5), legend=2.2, hspace=0.6)
    look = styles(estimates)
    for i, name in enumerate(windows.names):
        ax = axes.flat[i]
        mine = windows.mission == i
        for k, (start, end, _) in enumerate(phases.get(name, [])):
            if k % 2:
                ax.axvspan(start, end, color="0.9", lw=0)
        for est, pred in estimates.items():
            err = np.linalg.norm(pred[mine] - windows.target[mine], axis=1)
            ax.semilogy(windows.time[mine], err, lw=0.7, label=short_name(est),
                        **look[est].line())
        decades_only(ax)
        ax.set_title(name, fontsize=9)
        ax.set_ylabel("|error|, m/s", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[n:]:
        ax.axis("off")
    figure_legend(fig, axes.flat[0], fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("time, s")
    fig.suptitle("Velocity error over each manoeuvre (grey: alternate phases)")
    save_figure(fig, path, dpi=100)


def plot_tracks(windows: Windows, estimates: dict[str, np.ndarray], truth: dict,
                positions: dict[str, np.ndarray], path: Path) -> None:
    """Per mission: the true track (north against east), and below it each estimator's
    horizontal position error over time, from dead reckoning (its velocity, NaN rows held
    at its last estimate, integrated with the true attitude) or from its own position
    solution (``positions``)."""
    import matplotlib

    matplotlib.use("Agg")

    n = len(windows.names)
    cols = min(n, TRACK_COLUMNS)
    rows = -(-n // cols)  # each mission's track above its error, rows of ``cols`` missions
    fig, axes = panel_grid(2 * rows, cols, panel=(2.45, 1.6), legend=2.2, wspace=0.45)
    look = styles(estimates)
    for i in range(n, rows * cols):  # the last row's empty places
        axes[2 * (i // cols), i % cols].set_visible(False)
        axes[2 * (i // cols) + 1, i % cols].set_visible(False)
    for i, name in enumerate(windows.names):
        mine = windows.mission == i
        t = windows.time[mine]
        p = truth["position"][mine]
        ax_t, ax_e = axes[2 * (i // cols), i % cols], axes[2 * (i // cols) + 1, i % cols]
        ax_t.plot(p[:, 1] - p[0, 1], p[:, 0] - p[0, 0], "k", lw=1)
        ax_t.plot(0, 0, "ko", ms=3)
        ax_t.set_aspect("equal", adjustable="datalim")
        ax_t.set_title(name, fontsize=9)
        ax_t.set_xlabel("east, m", fontsize=7)
        ax_t.tick_params(labelsize=6)
        if i % cols == 0:
            ax_t.set_ylabel("north, m", fontsize=7)
            ax_e.set_ylabel("horizontal position error, m", fontsize=7)
        reference = dead_reckoning_track(windows, windows.target, truth, i)
        for est, pred in estimates.items():
            if est in positions:
                q = positions[est][mine]
                err = (q - q[0]) - (p - p[0])
            else:
                err = dead_reckoning_track(windows, held(windows, pred), truth, i) - reference
            ax_e.semilogy(t, np.maximum(np.linalg.norm(err[:, :2], axis=1), 1e-4), lw=0.8,
                          label=short_name(est), **look[est].line())
        decades_only(ax_e)
        ax_e.set_xlabel("time, s", fontsize=7)
        ax_e.tick_params(labelsize=6)
    figure_legend(fig, axes[1, 0], fontsize=9)
    fig.suptitle("True track of each mission (from its start, the dot) and below it each "
                 "estimator's position error over it")
    save_figure(fig, path, dpi=100)
