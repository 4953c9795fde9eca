"""Evaluating trained networks beside the baselines, on the test split of datasets.

Every row of a table is computed on the same samples: the test part (the last 25 % by
default) of each mission of a dataset. The baselines that need fitting (affine
calibration, Kalman filter) are fitted on the training part of the same file, as the
networks were trained on it.

A network learned one beam matrix and one ping spacing: ``evaluate`` refuses data whose
beam geometry or sensor rates differ from its training data's (as the checkpoint recorded
them) unless told to allow it, and warns (``SensorSetupWarning``) when only the DVL error
model differs, which is a legitimate robustness test. Every run and dataset is read and
checked before the output directory is made, so a refused evaluation leaves nothing
behind.

On a recorded mission (``auvsim import``) every score is against its reference (a
navigation solution, ``reference_source``), never a truth, and says so: the velocity
against the reference's moved to the DVL (``beamsnet.data.reference_velocity``), and
the horizontal position (``navigation_scores``: final, RMSE, % of the distance) of each
estimator's own position or its dead reckoning with the reference's attitude, the
filter's 3-sigma coverage, and two dead-reckoning baselines: the DVL's own velocity with
the reference's attitude and with the filter's. A simulated mission's scores are against
the simulator's truth, in the same words.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np

from auvsim.data.files import check_out_dir, save_figure, staged_dir, write_text
from auvsim.errors import AuvsimError, ConfigError
from beamsnet import metrics
from beamsnet.data import (
    NO_REFERENCE,
    TRUTHS,
    DataError,
    Windows,
    check_referenced,
    check_truth,
    load_windows,
    split,
)
from beamsnet.estimators import checked, predicted, spec, specs
from beamsnet.estimators.baselines import availability
from beamsnet.estimators.ins import (
    CONSISTENCY_PINGS,
    CONSISTENCY_PROBABILITY,
    at_pings,
    innovation_consistency,
)
from beamsnet.estimators.registry import WITHOUT_TORCH, torch_missing
from beamsnet.navigation import dead_reckoning_positions, position_report, truth_at_pings
from beamsnet.plotstyle import figure_legend, styles

COLUMNS = ("rmse", "mae", "r2", "vaf", "improvement", "rmse_vector", "rmse_x", "rmse_y",
           "rmse_z")


class SensorSetupWarning(UserWarning):
    """The evaluation data's sensors differ from the training data's: the DVL error model
    (a robustness test), a geometry or rate the caller allowed, or a run too old to
    tell."""


class FilterWarning(UserWarning):
    """A filter could not run on a file (its row is left out): the reason, in one line."""


class UnseenMissionWarning(UserWarning):
    """A run trained on some missions of its file is scored on others it never saw."""


def check_missions(run: str | Path, checkpoint: dict, dataset: str | Path,
                   missions: list[str]) -> None:
    """Warn when ``run`` was trained on a subset of its file's missions (``--mission``) and
    ``missions`` of ``dataset`` include others: its row then mixes what it learned with
    what it never saw (a network trained at 2 m/s, scored at 1, 2 and 3 m/s), which the
    table alone does not tell.

    Warns:
        UnseenMissionWarning: naming the missions it trained on and those it did not.
    """
    trained_on = checkpoint.get("train_config", {}).get("missions")
    if not trained_on:
        return  # every mission of its file
    unseen = [m for m in missions if m not in trained_on]
    if unseen:
        warnings.warn(f"run {str(run)!r} was trained on mission {', '.join(trained_on)} only; "
                      f"{str(dataset)!r} scores it on {', '.join(missions)}, and "
                      f"{', '.join(unseen)} {'is' if len(unseen) == 1 else 'are'} new to it "
                      "(evaluate --mission NAME, once per mission it trained on, compares "
                      "like with like)",
                      UnseenMissionWarning, stacklevel=2)


def estimates(runs: list[str | Path], dataset: str | Path,
              missions: list[str] | None = None) -> tuple[Windows, dict]:
    """Test-split windows of ``dataset`` (its ``missions``, default all) and every
    estimator's (S, 3) predictions on them."""
    return _estimates(_loaded(runs), dataset, missions)


def _loaded(runs: list[str | Path]) -> list[tuple[Path, object, dict]]:
    """(run, model, checkpoint) of each trained network's run. PyTorch is imported here,
    and only where there are runs: the model-based estimators and the filters run
    without it (``beamsnet.estimators.registry.NO_TORCH``)."""
    if not runs:
        return []
    from beamsnet.training.checkpoints import load

    return [(Path(r), *load(r)) for r in runs]


def _estimates(models: list[tuple[Path, object, dict]], dataset: str | Path,
               missions: list[str] | None = None, *, filter_config=None,
               **own) -> tuple[Windows, dict]:
    """``estimates`` for loaded models (run directory, model, checkpoint); ``own``: the
    dicts ``predictions`` fills with the filters' positions, sigmas, attitudes and
    divergence watches."""
    configs = [c["train_config"] for _, _, c in models]
    n_past = max([c["n_past"] for c in configs], default=3)
    fraction = configs[0]["train_fraction"] if configs else 0.75
    windows = load_windows(dataset, n_past=n_past, missions=missions)
    check_truth(windows, dataset)
    try:
        train_w, test_w = split(windows, fraction)
    except ValueError as e:
        raise DataError(f"{dataset}: {e}") from None
    return test_w, predictions(models, train_w, test_w, dataset=dataset,
                               filter_config=filter_config, **own)


def check_sensors(run: str | Path, checkpoint: dict, dataset: str | Path, *,
                  allow_mismatch: bool = False, setup: dict | None = None) -> None:
    """Compare the sensors of every mission of ``dataset`` with those of the missions
    ``run`` was trained on (``checkpoint["sensors"]``, see
    ``beamsnet.training.checkpoints.sensor_setup``).

    A value matches when it equals that of any training mission (a mounting and a rate
    within ``SENSOR_TOLERANCE``). An attribute either side
    lacks (an imported stream has no IMU rate) is not compared. ``setup`` is
    ``sensor_setup(dataset)`` when the caller has read it already (once for many runs).

    Raises:
        ConfigError: the beam geometry (angle, mounting) or a rate differs, naming both
            values, unless ``allow_mismatch`` (then a ``SensorSetupWarning`` says so).

    Warns:
        SensorSetupWarning: only the DVL error model differs; or the checkpoint has no
            sensor setup (trained before it was recorded), so nothing can be checked.
    """
    trained_on = checkpoint.get("sensors")
    if not isinstance(trained_on, dict) or not trained_on:
        warnings.warn(f"run {str(run)!r}: its checkpoint does not record its training "
                      f"data's sensors (trained by an older beamsnet), so {str(dataset)!r}'s "
                      "beam geometry, rates and DVL errors cannot be checked against them",
                      SensorSetupWarning, stacklevel=2)
        return
    from beamsnet.training.checkpoints import SENSOR_ERRORS, SENSOR_GEOMETRY, sensor_setup

    setup = sensor_setup(dataset) if setup is None else setup
    geometry = _differences(setup, trained_on, SENSOR_GEOMETRY)
    if geometry and not allow_mismatch:
        raise ConfigError(f"{str(dataset)!r}: its sensors differ from those run {str(run)!r} "
                          f"was trained on: {geometry}; expected the training data's beam "
                          "geometry and DVL and IMU rates (allow_mismatch evaluates "
                          "anyway)", argument="datasets", mentions=("allow_mismatch",))
    if geometry:
        warnings.warn(f"{str(dataset)!r}: its sensors differ from those run {str(run)!r} was "
                      f"trained on: {geometry}; evaluated anyway, as allowed",
                      SensorSetupWarning, stacklevel=2)
    errors = _differences(setup, trained_on, SENSOR_ERRORS)
    if errors and _drawn_alike(dataset, checkpoint):
        errors = ""  # other draws of one error model: held-out seeds, not another model
    if errors:
        warnings.warn(f"{str(dataset)!r}: its DVL error model differs from the training data "
                      f"of run {str(run)!r}: {errors}; a test of robustness to other sensor "
                      "errors", SensorSetupWarning, stacklevel=2)


# The DVL config's fields that make its error model (paper eq. 7 and the noise's growth):
# two files whose configs agree on them drew their missions' errors from one model.
ERROR_MODEL = ("scale_factor", "scale_factor_std", "bias", "bias_std", "noise_std",
               "noise_speed_coeff", "noise_range_coeff")


def _drawn_alike(dataset: str | Path, checkpoint: dict) -> bool:
    """Whether ``dataset`` and the run's training data were generated with one DVL
    error model (``ERROR_MODEL`` of each file's config): then missions that differ in their
    realised scale factors and biases are other draws of it (held-out seeds), not another
    sensor. False where either file has no generating config (an imported stream)."""
    from auvsim.data.reader import read_attrs

    def model(config_json) -> dict | None:
        try:
            dvl = json.loads(config_json or "")["dvl"]
        except (ValueError, KeyError, TypeError):
            return None
        return {k: dvl.get(k) for k in ERROR_MODEL} if isinstance(dvl, dict) else None

    ours = model(read_attrs(dataset)[0].get("config_json"))
    theirs = model(checkpoint.get("dataset", {}).get("config_json"))
    return ours is not None and ours == theirs


# What is the same sensor setup though not the same number (rtol, atol): a DVL mounting
# within a degree of the training data's (the residual a calibration finds: auvsim
# check-log's are a few tenths of a degree on a real vehicle) and a rate within 1 % (a
# clock's error, thousands of ppm at most). Anything else matches to the last bits.
SENSOR_TOLERANCE = {"dvl_mounting_rpy_deg": (0.0, 1.0), "dvl_rate_hz": (0.01, 0.0),
                    "imu_rate_hz": (0.01, 0.0)}


def _differences(setup: dict[str, dict], trained_on: dict[str, dict], keys) -> str:
    """The values of ``keys`` in the missions of ``setup`` that no training mission has
    (within ``SENSOR_TOLERANCE``), in words ("beam_angle_deg 30 (mission a) against 20");
    empty when all match."""
    said = []
    for key in keys:
        reference = [s[key] for s in trained_on.values() if key in s]
        rtol, atol = SENSOR_TOLERANCE.get(key, (1e-9, 0.0))
        seen: dict[str, list[str]] = {}  # value -> the missions that have it
        for name, attrs in setup.items():
            if key in attrs and reference and not any(
                    np.shape(attrs[key]) == np.shape(r)
                    and np.allclose(attrs[key], r, rtol=rtol, atol=atol) for r in reference):
                seen.setdefault(_value(attrs[key]), []).append(name)
        theirs = " or ".join(dict.fromkeys(_value(r) for r in reference))
        said += [f"{key} {value} ({_missions(names, len(setup))}) against {theirs}"
                 for value, names in seen.items()]
    return "; ".join(said)


def _missions(names: list[str], of: int) -> str:
    """``mission a``, ``missions a, b, c and 17 more``, ``every mission``: short, for a
    line that a file of 20 missions filled."""
    if len(names) == of and of > 1:
        return "every mission"
    shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
    return f"mission{'s' if len(names) > 1 else ''} {shown}"


def _value(value) -> str:
    """A float or a list of floats, short (``20``, ``[0.007, 0.007, 0.007, 0.007]``)."""
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    return f"{value:g}"


def baselines() -> list:
    """Every model-based estimator of the registry (``beamsnet.estimators``), unfitted,
    in its table order: LS first (every table's reference row)."""
    return [s.make() for s in specs("model-based")]


def filters(dataset: str | Path, *, strict: bool = False, filter_config=None) -> list:
    """The registry's filters, which run on the file itself (``dataset``, the one the test
    windows come from), unfitted: the INS/DVL filter integrates the IMU between pings,
    which a window holds only in part. ``filter_config``: its settings
    (``beamsnet.estimators.ins.FilterConfig``; None: the defaults).

    Raises:
        DataError: with ``strict``, a filter needs the IMU record and the file has none
            (one line saying so); without, that filter is left out.
    """
    from auvsim.data.reader import open_dataset

    with open_dataset(dataset) as f:
        lacking = [name for name in f.missions if not f.missions[name].has("imu")]
    out = []
    for s in specs("filter"):
        if s.needs.imu and lacking:
            if strict:
                raise DataError(f"{dataset}: mission {lacking[0]} has no IMU record; the "
                                f"{s.name} filter integrates the IMU, so it cannot run on "
                                "it")
            continue
        out.append(s.make(dataset, filter_config))  # None: the filter's defaults
    return out


def fit_filters(dataset: str | Path, train_w: Windows, *, filter_config=None) -> list:
    """The registry's filters on ``dataset`` (``filters``), each fitted on ``train_w``;
    one that cannot be (the learned noise, given windows of another file) is left out,
    with a ``FilterWarning`` saying why."""
    out = []
    for estimator in filters(dataset, filter_config=filter_config):
        try:
            out.append(estimator.fit(train_w))
        except AuvsimError as e:
            _left_out(estimator, dataset, e)
    return out


def _left_out(estimator, dataset, error: AuvsimError) -> None:
    """A filter the file cannot feed (a reference without attitude to start from, say)
    or that cannot be fitted: its row is left out, and the warning says why."""
    warnings.warn(f"{estimator.name} left out on {dataset}: "
                  f"{str(error).strip().splitlines()[0]}", FilterWarning, stacklevel=3)


def predictions(models: list[tuple[Path, object, dict]], train_w: Windows,
                test_w: Windows, *, dataset: str | Path | None = None,
                positions: dict | None = None, stds: dict | None = None,
                rotations: dict | None = None, watched: dict | None = None,
                filter_config=None) -> dict[str, np.ndarray]:
    """Every estimator's (S, 3) predictions on ``test_w``: the baselines fitted on
    ``train_w`` (and the INS/DVL filter run on ``dataset``, the file ``test_w`` comes
    from, if given), then the loaded ``models`` (run directory, model, checkpoint).
    ``positions``, a dict, receives the (S, 3) NED position of every estimator with a
    position solution of its own; ``stds`` its reported (S, 3) 1 sigma where it reports
    one, ``rotations`` its (S, 3, 3) body -> NED attitude where it has one, ``watched``
    a filter's ``watch_scores`` per mission."""
    out = {b.name: predicted(b.fit(train_w), test_w) for b in baselines()}
    own = [] if dataset is None else fit_filters(dataset, train_w, filter_config=filter_config)
    for estimator in own:
        try:
            made = estimator.predict(test_w)
        except AuvsimError as e:
            _left_out(estimator, dataset, e)
            continue
        out[estimator.name] = checked(estimator, made, test_w)  # a wrong shape: refused
        if positions is not None:  # every filter has its own position
            positions[estimator.name] = estimator.positions(test_w)
        if stds is not None:
            stds.update(reported_stds(estimator, test_w))
        if rotations is not None:
            rotations.update(own_rotations(estimator, test_w))
        if watched is not None:
            watched[estimator.name] = {mission: watch_scores(track) for mission, track
                                       in estimator.tracks(test_w).items()}
    if models:
        from beamsnet.training.train import predict
    for run, model, checkpoint in models:
        name = f"{spec(checkpoint['model']).short} ({run.name})"
        # check_sensors refused a mismatch, or allowed it: the caller's choice stands
        out[name] = predict(model, trimmed(test_w, checkpoint), allow_mismatch=True)
    return out


def trimmed(windows: Windows, checkpoint: dict) -> Windows:
    """Windows for a model trained with fewer past pings than the others use."""
    n = checkpoint["train_config"]["n_past"]
    return windows._replace(past_beams=windows.past_beams[:, -n:])


def table(windows: Windows, predictions: dict[str, np.ndarray]) -> dict[str, dict]:
    """Metrics of every estimator on ``windows``, with the improvement over LS."""
    rows = {name: metrics.report(pred, windows.target) for name, pred in predictions.items()}
    ls = rows[specs()[0].short]["rmse"]
    for row in rows.values():
        row["improvement"] = metrics.improvement(row["rmse"], ls)
    return rows


def markdown(rows: dict[str, dict], title: str) -> str:
    head = "| estimator | speed RMSE (m/s) | MAE (m/s) | R^2 | VAF (%) | vs LS (%) | " \
           "vector RMSE (m/s) | RMSE x | RMSE y | RMSE z |"
    lines = [f"### {title}", "", head, "|" + "---|" * (len(COLUMNS) + 1)]
    for name, row in rows.items():
        cells = [f"{row['rmse']:.6f}", f"{row['mae']:.6f}", _or_na(row["r2"], ".4f"),
                 _or_na(row["vaf"], ".2f"), f"{row['improvement']:.2f}",
                 f"{row['rmse_vector']:.6f}",
                 f"{row['rmse_x']:.6f}", f"{row['rmse_y']:.6f}", f"{row['rmse_z']:.6f}"]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def _or_na(value: float, spec: str) -> str:
    """A number, or n/a where it is undefined (R^2 and VAF at constant speed)."""
    return "n/a" if np.isnan(value) else format(value, spec)


def evaluate(runs: list[str | Path], datasets: list[str | Path], out: str | Path, *,
             allow_mismatch: bool = False, filter_config=None, progress: bool = False,
             missions: list[str] | None = None) -> dict:
    """Tables (terminal, Markdown, JSON) and plots for every dataset; returns the rows.

    Args:
        runs: run directories (``beamsnet.training.train``), one table row each.
        datasets: auvsim datasets; the test split of each gets a table.
        out: directory for ``evaluation.md``, ``evaluation.json`` and the plots; made only
            once every run and dataset has been read and checked.
        allow_mismatch: evaluate on data whose beam geometry or rates differ from a run's
            training data (with a warning) instead of refusing it.
        filter_config: the INS/DVL filter's settings (``FilterConfig``; None: defaults).
        progress: a progress bar on a terminal, over each dataset's stages (estimates,
            scores, plots).
        missions: score these missions of every dataset only (default: all of each).

    Raises:
        ConfigError: ``out`` cannot be a directory; a dataset's sensors do not match.
        CheckpointError: a run is missing or not a readable beamsnet run.
        DataError: a dataset is not an auvsim dataset or gives no samples.
    """
    from tqdm import tqdm

    out = check_out_dir(out)
    models = _loaded(runs)
    results, sections, figures = {}, [], []
    with tqdm(total=3 * len(datasets), disable=None if progress else True, leave=False,
              unit=" stages", desc="evaluating") as bar:  # closed on an error too
        for dataset in datasets:
            if models:
                from beamsnet.training.checkpoints import sensor_setup

                setup = sensor_setup(dataset, missions)  # read once for every run
            for run, _, checkpoint in models:
                check_sensors(run, checkpoint, dataset, allow_mismatch=allow_mismatch, setup=setup)
            own, watched = dict(positions={}, stds={}, rotations={}), {}
            bar.set_postfix_str(f"every estimator on {Path(dataset).name}")
            windows, predictions = _estimates(models, dataset, missions,
                                              filter_config=filter_config, watched=watched,
                                              **own)
            bar.update()
            bar.set_postfix_str(f"scores on {Path(dataset).name}")
            for run, _, checkpoint in models:
                check_missions(run, checkpoint, dataset, list(windows.names))
            rows = table(windows, predictions)
            per_mission = {
                name: {windows.names[m]: metrics.rmse(pred[windows.mission == m],
                                                      windows.target[windows.mission == m])
                       for m in np.unique(windows.mission)}
                for name, pred in predictions.items()}
            results[str(dataset)] = dict(rows=rows, rmse_per_mission=per_mission,
                                         against=windows.reference)
            sections.append(markdown(rows, f"{dataset}: test split, {len(windows.target)} pings, "
                                           f"against {windows.reference}"
                                           + _derived_words(windows)))
            if _has_truth(dataset, windows.names):
                navigation = navigation_scores(windows, predictions,
                                               truth_at_pings(dataset, windows), **own,
                                               since_first=True)
                results[str(dataset)]["navigation"] = navigation
                sections.append(navigation_markdown(navigation, windows.reference))
            if watched:
                results[str(dataset)]["watch"] = watched
                sections.append(watch_markdown(watched))
            figures.append((windows, predictions, per_mission, f"{Path(dataset).stem}_errors.png"))
            bar.update()
        # Only now, every input checked, is ``out`` made: whole, or not at all.
        with staged_dir(out) as stage:
            bar.set_postfix_str("plots")
            for windows, predictions, per_mission, name in figures:
                _plot(windows, predictions, per_mission, stage / name)
                bar.update()
            write_text(stage / "evaluation.md", "\n\n".join(sections) + "\n")
            write_text(stage / "evaluation.json", json.dumps(results, indent=1))
    return results


def _plot(windows: Windows, predictions: dict, per_mission: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(14, 4.5), layout="constrained",
                                     gridspec_kw=dict(width_ratios=(2, 1)))
    look = styles(predictions)
    speed = np.linalg.norm(windows.target, axis=1)
    # The missions one after another, each from its test split's first ping, a line
    # between them: on one time axis they would lie over each other.
    x = np.empty(len(windows.time))
    offset = 0.0
    for k, mission in enumerate(windows.names):
        rows = windows.mission == k
        if not rows.any():
            continue
        x[rows] = windows.time[rows] - windows.time[rows].min() + offset
        if offset > 0:
            ax_t.axvline(offset, color="k", lw=0.6)
        ax_t.text(offset, 1.0, f" {mission}", transform=ax_t.get_xaxis_transform(),
                  va="bottom", fontsize=7)
        offset = x[rows].max() + 1.0
    errors = {name: np.linalg.norm(pred, axis=1) - speed for name, pred in predictions.items()}
    for name, error in errors.items():
        ax_t.plot(x, error, ms=2, label=name, **look[name].points())
    ax_t.set_xlabel("time from each mission's first test ping, s (missions one after another)")
    ax_t.set_ylabel("speed error, m/s")
    ax_t.set_title("error over the test split", pad=12)
    # An estimator far off (a network that did not learn) would flatten the others at 0:
    # past LS's own spread the axis goes logarithmic.
    spread = error_spread(errors.get("LS"))
    if spread > 0 and max(np.nanmax(np.abs(e), initial=0.0) for e in errors.values()) \
            > 20 * spread:
        ax_t.set_yscale("symlog", linthresh=spread)
        ax_t.set_ylabel("speed error, m/s (logarithmic beyond LS's 99th percentile)")
    names = list(per_mission)
    missions = list(next(iter(per_mission.values())))
    width = 0.8 / len(names)
    for i, name in enumerate(names):
        ax_m.bar(np.arange(len(missions)) + i * width,
                 [per_mission[name][m] for m in missions], width, **look[name].bar())
    ax_m.set_xticks(np.arange(len(missions)) + 0.4 - width / 2, missions)
    ax_m.set_ylabel("speed RMSE, m/s")
    rmses = [v for name in names for v in per_mission[name].values() if v > 0]
    if "LS" in per_mission and rmses and max(rmses) > 20 * max(per_mission["LS"].values()):
        ax_m.set_yscale("log")  # so that the others still show beside one far off
    ax_m.set_title("per mission")
    figure_legend(fig, ax_t, markerscale=3, fontsize=8)
    save_figure(fig, path, dpi=110)


def error_spread(error) -> float:
    """The 99th percentile of |error| (NaN ignored), 0 without one: where the errors plot
    of ``_plot`` goes logarithmic."""
    if error is None:
        return 0.0
    error = np.abs(np.asarray(error, dtype=float))
    error = error[np.isfinite(error)]
    return float(np.percentile(error, 99)) if error.size else 0.0


def find_estimator(name: str, dataset: str | Path, *, filter_config=None) -> object:
    """The model-based estimator (or filter on ``dataset``) whose table name is ``name``,
    unfitted; case, spaces and punctuation do not matter (``beam-calibration``,
    ``ins-dvl``).

    Raises:
        ConfigError: no estimator has that name (the message lists them).
        DataError: the INS/DVL filter on a file without an IMU record.
    """
    try:
        s = spec(name)  # matched as the command line matches (``auvsim.checks.loose_key``)
    except KeyError:
        s = None
    if s is None or s.kind == "network":
        known = [s.name for s in specs() if s.kind != "network"]
        raise ConfigError(f": no estimator is called {name!r}; expected one of "
                          f"{', '.join(map(repr, known))}"
                          + (f" ({WITHOUT_TORCH})" if torch_missing() else ""),
                          argument="estimator")
    if s.kind == "model-based":
        return s.make()
    # A file that cannot feed the filter (no IMU record) raises DataError naming the file.
    return next(f for f in filters(dataset, strict=True, filter_config=filter_config)
                if f.name == s.name)


TRAIN_FRACTION = 0.75  # ``estimate``'s training split of a file (the paper's 75 %)


def estimate(name: str, dataset: str | Path, out: str | Path, *,
             train: str | Path | None = None, filter_config=None) -> dict:
    """Run one model-based estimator over every ping of ``dataset`` (from each mission's
    fourth: every estimator is scored on the pings with three past pings) and write its
    velocity (and position, for a filter) beside the truth: ``out/estimates.csv``, and
    ``out/summary.json`` with its availability, vector RMSE and position scores per
    mission (``navigation_scores``: its own position, or its velocity dead-reckoned; and
    the dead-reckoning baselines).

    Args:
        name: the estimator's table name (``find_estimator``).
        dataset: the file to estimate on: every ping with its past pings
            (``load_windows(every_ping=True, water_track=False)``: a water-track ping's
            beams are NaN, a ping no estimator measures the velocity over ground at).
        out: the directory to write, made once every input has been checked.
        train: the file whose training split the estimator is fitted on (default the
            training split of ``dataset`` itself: the first ``TRAIN_FRACTION`` of each
            mission's pings, which every ping's scores then include; the summary's
            ``fitted_on_scored_pings`` says so).
        filter_config: the INS/DVL filter's settings (``FilterConfig``; None: defaults).

    Returns:
        The summary.

    Raises:
        ConfigError: an unknown estimator or the filter on a file without IMU; DataError:
            a file gives no samples.
    """
    out = check_out_dir(out)
    estimator = find_estimator(name, dataset, filter_config=filter_config)
    # A water-track ping measured no velocity over ground: no estimator is handed its
    # beams as if it had (the filter leaves it too), and its velocity is held over it.
    windows = load_windows(dataset, every_ping=True, water_track=False)
    scored = windows.reference != NO_REFERENCE  # a log without one: estimates alone
    if scored:
        check_truth(windows, dataset)
    # A filter fits its beam calibration where it can (without a reference, none: the
    # beams as measured); any other estimator that is fitted needs a reference or truth.
    made_by = spec(estimator.name)
    is_filter = made_by.kind == "filter"  # tracks, positions and a config
    fitted = made_by.needs.training and not is_filter
    if fitted and train is None and not scored:
        raise DataError(f"{dataset}: a log without a reference, and {estimator.name} is "
                        "fitted on one; expected --train FILE.h5 with a reference or the "
                        "truth")
    train_windows = load_windows(dataset if train is None else train)
    _check_same_beams(train, train_windows, dataset, windows)
    if fitted:
        check_referenced(train_windows, train or dataset)
    try:
        train_w = split(train_windows, TRAIN_FRACTION)[0]
    except ValueError as e:
        raise DataError(f"{train or dataset}: {e}") from None
    try:
        estimator.fit(train_w)
    except ValueError as e:  # a training split it cannot be fitted on, in one line
        raise DataError(f"{train or dataset}: {e}") from None
    pred = predicted(estimator, windows)
    positions = estimator.positions(windows) if is_filter else None
    summary = dict(estimator=estimator.name, dataset=str(dataset),
                   train=str(train or dataset), pings=len(pred), against=windows.reference,
                   availability=availability(pred), missions={})
    if is_filter and estimator.calibrate and estimator.correction is None:
        summary["unfitted"] = (f"its beams are used as measured: {train or dataset} has no "
                               "reference to calibrate them against (--train FILE.h5 "
                               "calibrates them on a file that has one)")
    if train is None and scored and made_by.needs.training:
        summary["fitted_on_scored_pings"] = (
            f"fitted on the first {100 * TRAIN_FRACTION:.0f} % of each mission's pings of "
            "this file (its training split), which the scores include; --train OTHER.h5 "
            "fits it on another file")
    if windows.derived:
        summary["beams_derived"] = list(windows.derived)
    if is_filter:
        import dataclasses

        summary["filter_config"] = dataclasses.asdict(estimator.config)
    truth = (truth_at_pings(dataset, windows) if _has_truth(dataset, windows.names)
             else None)
    navigation = (navigation_scores(windows, {estimator.name: pred}, truth,
                                    positions={} if positions is None
                                    else {estimator.name: positions},
                                    stds=reported_stds(estimator, windows),
                                    rotations=own_rotations(estimator, windows))
                  if truth is not None else {})
    tracks = estimator.tracks(windows) if is_filter else {}
    for i, mission in enumerate(windows.names):
        mine = windows.mission == i
        have = mine & np.isfinite(pred).all(axis=1)
        row = dict(pings=int(mine.sum()), availability=float(have.sum() / mine.sum()))
        if is_filter:
            # A filter outputs a number at every ping, diverged or not: its availability
            # is the share of pings whose measurement it accepted, and its events say when
            # its divergence watch restarted it.
            track = tracks[mission]
            row.update(watch_scores(track))
            if track.noise is not None:
                row["noise"] = noise_record(track.noise)
        if have.any() and scored:
            row["rmse_vector"] = metrics.rmse_vector(pred[have], windows.target[have])
        if truth is not None:
            scores = navigation[mission]
            row["position"] = scores.pop(estimator.name)
            row["baselines"] = scores
        summary["missions"][mission] = row
    if is_filter:
        summary["availability"] = float(np.mean(np.concatenate(
            [t.accepted for t in tracks.values()])))
    target = "true" if windows.reference in TRUTHS else "reference"
    columns = ["mission", "time", "vx", "vy", "vz"]
    table = [windows.names[m] for m in windows.mission], windows.time, *pred.T
    if scored:
        columns += [f"{target}_vx", f"{target}_vy", f"{target}_vz"]
        table += tuple(windows.target.T)
    if positions is not None:
        # The estimator's own position, in the mission's local frame (the truth's, or
        # the reference's: its origin is the reference's first point; without a
        # reference, where the filter started).
        columns += ["north_m", "east_m", "down_m"]
        table += tuple(positions.T)
    lines = [",".join(columns)] + [
        ",".join(v if isinstance(v, str) else f"{v:.9g}" for v in row)
        for row in zip(*table, strict=True)]
    with staged_dir(out) as stage:  # both files or neither
        write_text(stage / "estimates.csv", "\n".join(lines) + "\n")
        write_text(stage / "summary.json", json.dumps(summary, indent=1))
    return summary


def baseline_names(reference: str) -> tuple[str, str]:
    """The two dead-reckoning baselines' row names, for windows whose target is
    ``reference`` (``Windows.reference``): the DVL's own velocity integrated with the
    reference's (or the truth's) attitude, and with the filter's own attitude."""
    whose = "true" if reference in TRUTHS else "reference"
    return f"DR: DVL + {whose} attitude", "DR: DVL + filter attitude"


def navigation_scores(windows: Windows, predictions: dict[str, np.ndarray],
                      truth: dict[str, np.ndarray], *, positions: dict | None = None,
                      stds: dict | None = None, rotations: dict | None = None,
                      since_first: bool = False) -> dict[str, dict[str, dict]]:
    """Per mission, per estimator: its horizontal position error against
    ``truth["position"]`` (the truth, or a recorded mission's reference; see
    ``beamsnet.navigation.position_report``): its own position where it has one
    (``positions``, name -> (S, 3) m NED; with ``stds`` its 3-sigma coverage), else its
    velocity dead-reckoned with the truth's (reference's) attitude from the first sample
    on. Beside them the two baselines of ``baseline_names``: the DVL's own velocity
    (``windows.velocity_ls``) with that attitude, and with the attitude of each estimator
    of ``rotations`` (name -> (S, 3, 3) body -> NED), the filter's.

    ``since_first``: an estimator's own position is scored, like the dead reckonings, from
    the truth at the mission's first sample (by how far it moved from there), so that all
    are scored over the same interval where ``windows`` start mid-mission (``evaluate``'s
    test split); its coverage stays that of its own position.

    Returns:
        mission name -> row name -> the scores (``final_m``, ``rmse_m``,
        ``final_percent``, ``distance_m``, ``coverage_3sigma`` where a sigma is given).
    """
    positions, stds, rotations = positions or {}, stds or {}, rotations or {}
    by_reference, by_filter = baseline_names(windows.reference)
    out: dict[str, dict[str, dict]] = {}
    for i, mission in enumerate(windows.names):
        rows = {}
        for name, pred in predictions.items():
            if name in positions:
                rows[name] = position_report(windows, positions[name], truth, i,
                                             stds.get(name), since_first=since_first)
            elif np.isfinite(pred[windows.mission == i]).any():
                rows[name] = position_report(
                    windows, dead_reckoning_positions(windows, pred, truth, i), truth, i)
        dvl = windows.velocity_ls
        rows[by_reference] = position_report(
            windows, dead_reckoning_positions(windows, dvl, truth, i), truth, i)
        for name, rotation in rotations.items():
            theirs = dict(truth, rotation=rotation)
            label = by_filter if len(rotations) == 1 else f"{by_filter} ({name})"
            rows[label] = position_report(
                windows, dead_reckoning_positions(windows, dvl, theirs, i), truth, i)
        out[mission] = rows
    return out


def _derived_words(windows: Windows) -> str:
    """What a table must say when some missions' beams were derived from the DVL's own
    velocity (their log has no beams)."""
    if not windows.derived:
        return ""
    return (f" (beams of {', '.join(windows.derived)} derived as H v from the DVL's own "
            "velocity: the log has no beams)")


def reported_stds(estimator, windows: Windows) -> dict[str, np.ndarray]:
    """{name: (S, 3) the position 1 sigma it reports at each sample's ping, m} of an
    estimator with tracks of its own (the INS/DVL filter's ``position_std``); {} for
    the others."""
    std = _track_at_pings(estimator, windows, "position_std")
    return {} if std is None else {estimator.name: std}


def own_rotations(estimator, windows: Windows) -> dict[str, np.ndarray]:
    """{name: (S, 3, 3) body -> NED, its attitude at each sample's ping} of an estimator
    whose tracks carry an attitude (the INS/DVL filter's ``rotation``); {} for the
    others (NaN where it has no ping at that time)."""
    rotation = _track_at_pings(estimator, windows, "rotation")
    return {} if rotation is None else {estimator.name: rotation}


def _track_at_pings(estimator, windows: Windows, field: str) -> np.ndarray | None:
    """(S, ...) ``field`` of the estimator's per-mission tracks (``tracks(windows)``, each
    with ``ping_time``) at each sample's ping; None when it has no tracks or a track
    lacks the field."""
    if not hasattr(estimator, "tracks"):
        return None
    tracks = estimator.tracks(windows)
    if any(getattr(t, field, None) is None for t in tracks.values()):
        return None
    return at_pings(tracks, windows, field)


def watch_scores(track) -> dict:
    """A filter's track of one mission as its divergence watch saw it: its availability,
    the share of pings whose measurement it accepted (not of its finite outputs: a
    filter that has diverged still outputs numbers), the watch's restarts, one line
    each, and whether its innovations are as large as it predicts
    (``ins.innovation_consistency``: the mean NIS and the windows beyond its bound)."""
    return dict(availability=track.availability, events=[e.text for e in track.events],
                **innovation_consistency(track))


def noise_record(noise) -> dict:
    """The noise a filter used (``FilterTrack.noise``) as plain numbers for a summary."""
    return {k: (np.asarray(v, dtype=float).tolist() if v is not None else None)
            for k, v in noise._asdict().items()}


def noise_words(noise: dict) -> str:
    """``noise_record``'s figures in words: what a user checks against the datasheet."""
    def mm(values) -> str:
        shown = [f"{1e3 * v:.3g}" for v in np.atleast_1d(values)]
        return (shown[0] if len(set(shown)) == 1 else ", ".join(shown)) + " mm/s"

    white = np.atleast_1d(noise["measurement_std"])
    growth = np.atleast_1d(noise["noise_growth"])
    each = "per beam" if len(white) == 4 else "per axis (x, y, z)"
    words = [f"DVL white {mm(white)}" + (f" + {mm(growth)} per m/s" if np.any(growth > 0)
                                         else "") + f" {each}"]
    if noise["slow_error_std"] > 0:
        words.append(f"slow error {1e3 * noise['slow_error_std']:.3g} mm/s over "
                     f"{noise['slow_error_time']:.3g} s" if noise["slow_error_time"]
                     else f"slow error {1e3 * noise['slow_error_std']:.3g} mm/s")
    words.append(f"accelerometer {noise['accel_noise_density']:.3g} m/s^2/sqrt(Hz), bias "
                 f"{noise['accel_bias_std']:.3g} m/s^2")
    words.append(f"gyro {noise['gyro_noise_density']:.3g} rad/s/sqrt(Hz), bias "
                 f"{noise['gyro_bias_std']:.3g} rad/s")
    return "; ".join(words)


# A mean NIS (capped at the gate) this far above 1 says the noise the filter was given is
# too small for the data.
NIS_TOO_LARGE = 2.0


def consistency_words(row: dict) -> str:
    """``innovation_consistency``'s figures (in ``row``, as ``watch_scores`` gives them) in
    words."""
    if not math.isfinite(row.get("mean_nis", math.nan)):
        return "no innovation to test"
    gated = row.get("gated_nis", math.nan)
    # Outliers the gate rejects inflate the mean; the capped mean is the pings' typical size.
    typical = gated if math.isfinite(gated) else row["mean_nis"]
    return (f"mean NIS {row['mean_nis']:.2f} (1 where its covariance is right"
            + (f"; {gated:.2f} with each capped at the gate, which an outlier moves little"
               if math.isfinite(gated) else "") + "), "
            f"{row['windows_above']} of {row['windows']} windows of {CONSISTENCY_PINGS} pings "
            f"beyond the chi-square {100 * CONSISTENCY_PROBABILITY:g} % bound"
            + (f"; its innovations are {math.sqrt(typical):.1f} times the size it predicts: "
               "the noise it was given (the DVL's white noise first) is likely too small for "
               "these data" if typical > NIS_TOO_LARGE else ""))


def watch_markdown(watched: dict[str, dict[str, dict]]) -> str:
    """What each filter's divergence watch did on each mission (``watched``: {filter:
    {mission: ``watch_scores``}}): the share of pings it accepted and its restarts, over
    the whole mission (a filter runs each from its start, not the test split alone)."""
    lines = []
    for name, missions in watched.items():
        said = []
        for mission, row in missions.items():
            restarts = row["events"]
            said.append(f"{mission} {100 * row['availability']:.1f} % of the mission's pings "
                        "accepted, "
                        + (f"{len(restarts)} restart{'s' if len(restarts) > 1 else ''}: "
                           + "; ".join(restarts) if restarts else "no restart")
                        + f", {consistency_words(row)}")
        lines.append(f"{name}, what its divergence watch saw (a restart when its gate keeps "
                     "rejecting the measurements): " + "; ".join(said) + ".")
    return "\n\n".join(lines)


def navigation_markdown(scores: dict[str, dict[str, dict]], against: str) -> str:
    """``evaluate``'s ``navigation_scores`` (``since_first``) as a Markdown table per
    mission, saying what it is against and from where."""
    lines = []
    whose = "the truth's" if against in TRUTHS else "the reference's"
    start = (f"Every row starts at {whose} position at the mission's first scored ping (an "
             "estimator with its own position: scored by how far it moved from there); "
             "within 3 sigma: the error of its own position, which its sigma is of.")
    for mission, rows in scores.items():
        lines += [f"#### {mission}: horizontal position error against {against}", "",
                  start, "",
                  "| estimator | final (m) | RMSE (m) | final (% of distance) | "
                  "within 3 sigma (%) |", "|---|---|---|---|---|"]
        for name, row in rows.items():
            cover = row.get("coverage_3sigma")
            lines.append(f"| {name} | {row['final_m']:.2f} | {row['rmse_m']:.2f} | "
                         f"{row['final_percent']:.2f} | "
                         f"{'n/a' if cover is None else f'{100 * cover:.1f}'} |")
        lines.append("")
    return "\n".join(lines)


def _check_same_beams(train, train_windows: Windows, dataset, windows: Windows) -> None:
    """Refuse a training file whose beam geometry is not that of ``dataset``: an estimator
    fitted on one beam matrix cannot turn another's beams into velocities.

    Raises:
        ConfigError: naming both files' beam angles, against ``train``.
    """
    if train is None or np.allclose(train_windows.h, windows.h):
        return

    def angle(h: np.ndarray) -> str:  # every beam's angle from the vertical, equal
        return f"{np.degrees(np.arccos(abs(h[0, 2]))):.4g} deg"

    raise ConfigError(f"{str(train)!r}: its DVL's beams ({angle(train_windows.h)} from the "
                      f"vertical) are not those of {str(dataset)!r} ({angle(windows.h)}); "
                      "expected training data of the same DVL", argument="train")


def _has_truth(dataset, missions) -> bool:
    """Whether every one of ``missions`` of ``dataset`` has a truth group, or (recorded) a
    reference with an attitude, to score positions against (one open)."""
    from auvsim.data.reader import open_dataset

    with open_dataset(dataset) as f:
        return all(m.has("truth") or (m.has("reference") and "quaternion" in m.reference)
                   for m in (f.missions[name] for name in missions))
