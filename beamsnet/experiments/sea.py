"""``beamsnet reproduce sea``: every estimator on a real vehicle's own errors, scored
against its recorded reference (issue 24, items 5 and 9).

The data are a folder of recorded logs (default the Snapir AUV's six A-KIT segments,
``../shared/data/snapir-akit``: Phins IMU at 100 Hz, Navigator DVL at 1 Hz, the Delph INS
post-processed solution as the reference). Every segment is imported
(``auvsim.data.recorded.import_logs``, the layout ``akit``), one recorded mission each,
and corrected by ``auvsim check-log --apply`` (the IMU's axes, the streams' clocks, the
sensors' positions, found from the data) into ``datasets/sea.h5``. The scores are
against that reference, never a truth: the target velocity is the reference's, moved to
the DVL (``beamsnet.data.reference_velocity``), and positions are in the mission's
local frame (origin: the reference's first point).

What runs on each segment, from its fourth ping (three past pings, as every table):

* the INS/DVL filter at its defaults, on the beams as logged (the segment has no
  training split of its own to calibrate on), with its own position, its reported
  sigma (the 3-sigma coverage) and its attitude;
* two dead-reckoning baselines: the DVL's own velocity with the reference's attitude, and
  with the filter's (``beamsnet.evaluate.navigation_scores``);
* sim-to-real (item 9): every model-based estimator (LS, the calibrations, the Kalman
  filters, robust LS) fitted, and CorrectionNet trained, only on auvsim data of the
  ``realistic-maneuvers`` preset (the navigator's DVL and IMU, generated here through
  ``beamsnet.experiments.runner.ensure_dataset``), each dead-reckoned with the
  reference's attitude; and the filter again with the noise settings of the simulated
  instrument (its DVL beam noise, its IMU's noise densities and bias instabilities, as
  the generated file records them) in place of the real one's;
* beside them, the same model-based estimators fitted on the other real segments (each
  segment left out of its own fit): what a calibration could learn from this vehicle.

A segment's log has no beams (the A-KIT files hold the DVL's velocity only): the beams
are ``H v`` of the DVL's own velocity (``dvl_beams_derived``), which carries the
instrument's velocity errors onto the beams but no error of one beam alone. The report
says so.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from pathlib import Path

import numpy as np
from tqdm import tqdm

from auvsim.data.files import check_out_dir, save_figure, staged_dir, write_text
from auvsim.data.reader import Dataset, open_dataset
from auvsim.errors import AuvsimError, ConfigError
from auvsim.runs.cluster import check_address
from beamsnet import metrics
from beamsnet.data import Windows, load_windows, split
from beamsnet.estimators import predicted, short_name
from beamsnet.evaluate import (
    baseline_names,
    baselines,
    navigation_scores,
    own_rotations,
    reported_stds,
    trimmed,
    watch_scores,
)
from beamsnet.experiments.defaults import DEFAULT_SEA, SEA_DURATION, SEA_SEEDS
from beamsnet.experiments.runner import check_duration, ensure_dataset, train_seeds
from beamsnet.experiments.wording import count
from beamsnet.navigation import (
    dead_reckoning_positions,
    dvl_against_reference,
    earth_fixed_fit,
    reference_departure,
    truth_at_pings,
)
from beamsnet.plotstyle import figure_legend, styles
from beamsnet.training.config import PROFILES, TrainConfig
from beamsnet.training.train import predict

# The default logs and the training set's size and seeds: ``beamsnet.experiments.defaults``.
DURATION = SEA_DURATION
SEEDS = SEA_SEEDS
FILTER = "INS/DVL"
SIM_FILTER = "INS/DVL (simulated instrument's noise)"
OTHERS = " (other segments)"  # the rows of estimators fitted on the other real segments
LEARNED = {"CorrectionNet": ("corr", dict(model="corr"))}
# The logs do not document the IMU's axes, the streams' clocks or the sensors' positions:
# ``auvsim check-log`` finds them from the data and ``--apply`` writes a corrected file,
# which every estimator here runs on (``sea_dataset``).


def sea(data: Path = DEFAULT_SEA, *, out: Path, duration: float = DURATION,
        seeds: int = SEEDS, training: TrainConfig | None = None,
        runs: Path = Path("runs"), datasets: Path = Path("datasets"),
        workers: int | None = None, progress: bool = True,
        cluster: str | None = None) -> Path:
    """Import every segment of ``data``, run every applicable estimator on each, write
    ``out/sea.md``, ``sea.json`` and ``sea.png``.

    Args:
        data: a folder of A-KIT logs (``TrajectoryK/`` folders) or one such folder.
        out: the report's directory.
        duration: s per manoeuvre of the generated auvsim training set.
        seeds: CorrectionNet seeds, every one scored.
        training: the networks' training settings (default: the ``snapir`` profile, the
            paper's sea-data learning rate and epochs, as ``sim2real``).
        runs: where the networks go (``runs/sea/<training file stem>/corr/seed_<s>``).
        datasets: where the imported segments and the training set go.
        workers, progress: training processes; progress bars.
        cluster: generate the training set and train on this Dask cluster instead.

    Returns:
        The report's path.

    Raises:
        ConfigError: ``data`` holds no A-KIT segment, ``duration`` or ``seeds`` are out of
            range; and what the import refuses of a log (one line each).
    """
    from auvsim.runs.presets import realistic_maneuvers

    training = PROFILES["snapir"].config if training is None else training
    _check(duration, seeds)
    check_out_dir(out)
    if cluster is not None:
        check_address(cluster)
    dataset, corrections = sea_dataset(Path(data), datasets)
    sim = ensure_dataset(realistic_maneuvers(duration), datasets / f"sea-train_{duration:g}s.h5",
                         progress=progress, cluster=cluster)
    nets = train_seeds(sim, {key: dataclasses.replace(training, **change)
                             for key, change in LEARNED.values()},
                       runs / "sea" / Path(sim).stem, seeds, workers=workers,
                       progress=progress, cluster=cluster)
    sim_train, sim_test = split(load_windows(sim), training.train_fraction)
    fitted = [b.fit(sim_train) for b in baselines()]
    held_out = dict(motion=motion(sim_test, sim_train),
                    departure=_departures(sim_test, _learned(sim_test, nets)),
                    train_fraction=training.train_fraction)
    with open_dataset(dataset) as f:  # each file opened once for what the report says of it
        segments, geometry, logged_noise = list(f.missions), _geometry(f), _logged_noise(f)
        speed = _logged_speed(f)
    with open_dataset(sim) as f:
        noise, sim_geometry = simulated_noise(f, speed), _geometry(f)
    results = {}
    for name in tqdm(segments, desc="segments", unit=" segment", leave=False,
                     disable=None if progress else True):
        others = [s for s in segments if s != name]
        real = ([b.fit(load_windows(dataset, missions=others)) for b in baselines()]
                if others else [])
        results[name] = _segment(dataset, name, fitted, real, nets, noise, sim_train)
    # The data folder by its name only: a report names no path outside the repository.
    setup = dict(data=Path(data).name, dataset=str(dataset), sim=str(sim), duration=duration,
                 seeds=seeds, epochs=training.epochs, lr=training.lr, noise=noise,
                 corrections=corrections, held_out=held_out,
                 geometry={"auvsim": sim_geometry, "logs": geometry},
                 logged_noise=logged_noise)
    with staged_dir(out) as stage:  # the report, its data and its figure, or none
        write_text(stage / "sea.json", json.dumps(
            {"setup": setup, "segments": {n: r["scores"] for n, r in results.items()},
             "motion": {n: r["shift"] for n, r in results.items()}},
            indent=1, default=float))
        _figure(results, stage / "sea.png")
        write_text(stage / "sea.md", report(results, setup))
    return Path(out) / "sea.md"


def _check(duration, seeds) -> None:
    check_duration(duration, "duration", unit="seconds per manoeuvre")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ConfigError(f": expected a whole number of seeds >= 1, got {seeds!r}",
                          argument="seeds")


def sea_dataset(data: Path, datasets: Path = Path("datasets")) -> tuple[Path, dict]:
    """``datasets/sea.h5``: every A-KIT segment of ``data`` imported as a recorded mission
    (``auvsim import --format akit``, into ``datasets/sea-logged.h5``) and corrected by
    ``auvsim check-log --apply``; made again only when the logs' SHA-256 digests or
    check-log's findings differ from those the files record.

    Returns:
        The file, and what check-log found and applied per segment ({mission: [(finding,
        value, confidence)]}).

    Raises:
        ConfigError: ``data`` is not a folder of A-KIT segments (the importer's line), named
            as the argument ``data`` (``--data``: its default is beside a checkout of this
            project, which an installed package has not).
    """
    from auvsim.data.checklog import apply, check_file
    from auvsim.data.recorded import akit_segments, import_logs

    try:
        segments = akit_segments(data)
    except ConfigError as e:
        raise ConfigError(e.message, argument="data") from None
    digests = sorted(hashlib.sha256(p.read_bytes()).hexdigest()
                     for folder, _ in segments for p in sorted(folder.glob("*.csv")))
    logged, dataset = datasets / "sea-logged.h5", datasets / "sea.h5"
    if not _imported_from(logged, digests):
        import_logs([data], logged, format="akit")
    reports = check_file(logged)
    said = _said(reports)
    if not _imported_from(dataset, digests, said):
        # Every finding and its confidence is in the report's table.
        apply(logged, dataset, reports, accept_low=True)
    return dataset, said


def _said(reports) -> dict:
    """What check-log found, per mission: [(finding, value in words, confidence)]."""
    return {r.mission: [[f.name, f.text, f.confidence] for f in r.findings] for r in reports}


def _imported_from(dataset: Path, digests: list[str], findings: dict | None = None) -> bool:
    """Whether ``dataset`` holds recorded missions imported from exactly these logs with
    this auvsim's built-in A-KIT description (its instrument specifications and stated
    rates are what the estimators and check-log read) and, given ``findings`` (``_said``),
    corrected by exactly those (its missions' ``check_log_json``)."""
    from auvsim.data.recorded import AKIT_DESCRIPTION

    if not dataset.exists():
        return False
    try:
        with open_dataset(dataset) as f:
            found = sorted(d for m in f.missions.values()
                           for d in json.loads(m.attrs.get("source_sha256", "[]")))
            described = all(
                m.attrs.get("log_description") == AKIT_DESCRIPTION.replace("{k}", k)
                for k, m in ((name.removeprefix("trajectory"), m)
                             for name, m in f.missions.items()))
            applied = {name: [[x["name"], x["text"], x["confidence"]]
                              for x in json.loads(m.attrs.get("check_log_json", "{}"))
                              .get("findings", [])]
                       for name, m in f.missions.items()}
    except (AuvsimError, OSError, ValueError):
        return False
    return found == digests and described and (findings is None or applied == findings)


def _geometry(f: Dataset) -> dict:
    """The DVL geometry of an open file's missions: their beam angles (deg) and mountings
    (roll, pitch, yaw, deg), each mission's."""
    return {"beam_angle_deg": sorted({float(m.attrs["beam_angle_deg"])
                                      for m in f.missions.values()}),
            "mounting_rpy_deg": [[float(x) for x in m.attrs["dvl_mounting_rpy_deg"]]
                                 for m in f.missions.values()]}


def _geometry_words(geometry: dict) -> str:
    """auvsim's DVL geometry against the logs', in words: beams, and how far the logs'
    mountings lie from auvsim's."""
    sim, logs = geometry["auvsim"], geometry["logs"]

    def angles(g):
        return " and ".join(f"{a:g}" for a in g["beam_angle_deg"]) + " deg beams"

    reference = np.asarray(sim["mounting_rpy_deg"][0])
    apart = float(np.abs(np.asarray(logs["mounting_rpy_deg"]) - reference).max())
    return (f"auvsim's, {angles(sim)} mounted at "
            f"({', '.join(f'{x:g}' for x in reference)}) deg; the logs', {angles(logs)} "
            f"mounted within {apart:.2g} deg of that on every axis")


def _logged_noise(f: Dataset) -> float:
    """The logged DVL's white beam noise, m/s: the median over an open file's missions of
    their ``dvl_noise_std`` (the instrument's specification the log description gives)."""
    return float(np.median([float(m.attrs["dvl_noise_std"]) for m in f.missions.values()]))


def _logged_speed(f: Dataset) -> float:
    """The logs' speed, m/s: the median over an open file's missions of the median norm
    of their DVL velocity (``dvl/velocity_ls``)."""
    return float(np.median([np.nanmedian(np.linalg.norm(m.dvl.velocity_ls, axis=1))
                            for m in f.missions.values()]))


def simulated_noise(f: Dataset, speed: float) -> dict[str, float]:
    """The simulated instrument's noise settings, as its file (open, ``f``) records them
    (its first mission's attributes: every mission of a preset has one instrument): the
    DVL's white beam noise at rest and, with its config's growth with speed
    (``noise_speed_coeff``), at ``speed`` (m/s, the logs' speed: ``dvl_beam_noise``),
    the IMU's noise densities and the bias instabilities with their correlation time; and
    from its config the spreads of the DVL's scale factor and bias
    (``dvl_scale_factor_std``, -, and ``dvl_bias_std``, m/s)."""
    a = next(iter(f.missions.values())).attrs
    dvl = json.loads(f.config_json or "{}").get("dvl", {})
    keys = ("dvl_noise_std", "imu_accel_noise_density", "imu_gyro_noise_density",
            "imu_accel_bias_instability", "imu_gyro_bias_instability",
            "imu_bias_correlation_time")
    growth = float(dvl.get("noise_speed_coeff", 0.0))
    return {**{k: float(a[k]) for k in keys}, "dvl_noise_speed_coeff": growth,
            "speed": speed, "dvl_beam_noise": float(a["dvl_noise_std"]) + growth * speed,
            "dvl_scale_factor_std": float(dvl.get("scale_factor_std", math.nan)),
            "dvl_bias_std": float(dvl.get("bias_std", math.nan))}


def _filters(dataset: Path, noise: dict[str, float]) -> dict[str, object]:
    """The INS/DVL filter at its defaults, and with the simulated instrument's noise
    settings (beam noise at the logs' speed, noise densities, bias random walks 2 sigma^2
    / tau), both on the beams as logged (no calibration: a segment has no split of its own
    to fit on)."""
    from beamsnet.estimators.ins import FilterConfig, InsDvlFilter

    tau = noise["imu_bias_correlation_time"]
    simulated = FilterConfig(
        beam_noise_std=noise["dvl_beam_noise"],
        accel_noise_density=noise["imu_accel_noise_density"],
        gyro_noise_density=noise["imu_gyro_noise_density"],
        accel_bias_psd=2 * noise["imu_accel_bias_instability"] ** 2 / tau,
        gyro_bias_psd=2 * noise["imu_gyro_bias_instability"] ** 2 / tau)
    out = {FILTER: InsDvlFilter(dataset, calibrate=False),
           SIM_FILTER: InsDvlFilter(dataset, simulated, calibrate=False)}
    for label, estimator in out.items():
        estimator.name = label  # its rows' name in this report
    return out


def motion(windows: Windows, train: Windows) -> dict[str, float]:
    """What a network trained on ``train`` meets of the motion in ``windows``: their
    pings, median speed (m/s, least squares), the RMS of the beams' change from the last
    past ping to the current one (m/s a ping: the vehicle's acceleration between pings,
    which CorrectionNet and BeamsNetV2M take as input), and the share of pings with a
    current beam or a change from any past ping outside the range ``train`` spans (where
    CorrectionNet clips its inputs to that range)."""
    def features(w: Windows) -> np.ndarray:
        changes = w.past_beams - w.beams[:, None, :]
        return np.concatenate([w.beams, changes.reshape(len(w.beams), -1)], axis=1)

    x, seen = features(windows), features(train)
    low, high = np.nanmin(seen, axis=0), np.nanmax(seen, axis=0)
    outside = ((x < low) | (x > high)).any(axis=1)  # a missing value is never outside
    change = windows.past_beams[:, -1] - windows.beams
    return dict(pings=len(x),
                speed=float(np.nanmedian(np.linalg.norm(windows.velocity_ls, axis=1))),
                change_rms=float(np.sqrt(np.nanmean(change ** 2))),
                outside=float(outside.mean()))


def _learned(windows: Windows, nets: dict) -> dict[str, np.ndarray]:
    """Each trained network's (S, 3) velocity on ``windows``, by its row's label."""
    return {f"{label} ({run.name})": predict(model, trimmed(windows, checkpoint))
            for label, (key, _) in LEARNED.items() for run, model, checkpoint in nets[key]}


def _departures(windows: Windows, learned: dict[str, np.ndarray]) -> dict[str, float]:
    """Each network's RMS departure from least squares on ``windows``, m/s (vector, over
    the pings where both give a velocity), by its row's label (``_learned``)."""
    out = {}
    for label, velocity in learned.items():
        gap = velocity - windows.velocity_ls
        have = np.isfinite(gap).all(axis=1)
        out[label] = (float(np.sqrt(np.mean(np.sum(gap[have] ** 2, axis=1))))
                      if have.any() else math.nan)
    return out


def _segment(dataset: Path, name: str, fitted: list, real: list, nets: dict,
             noise: dict[str, float], sim_train: Windows) -> dict:
    """Every estimator on segment ``name``: velocities, positions and their scores, and
    its motion against the training set's (``motion``) with each network's departure
    from least squares."""
    windows = load_windows(dataset, missions=[name])
    truth = truth_at_pings(dataset, windows)
    predictions = {b.name: predicted(b, windows) for b in fitted}
    learned = _learned(windows, nets)
    predictions.update(learned)
    predictions.update({f"{b.name}{OTHERS}": predicted(b, windows) for b in real})
    positions, stds, rotations, failed, watched = {}, {}, {}, {}, {}
    for label, estimator in _filters(dataset, noise).items():
        try:
            predictions[label] = predicted(estimator, windows)
            positions[label] = estimator.positions(windows)
            stds.update(reported_stds(estimator, windows))
            watched[label] = watch_scores(estimator.tracks(windows)[name])
            if label == FILTER:
                rotations.update(own_rotations(estimator, windows))
        except AuvsimError as e:  # said in the report, not hidden
            predictions.pop(label, None)
            failed[label] = str(e).strip().splitlines()[0]
    # Each track once, for the scores and the figure: an estimator's own position, or its
    # velocity dead-reckoned with the reference's attitude; none for a velocity it never
    # gave (navigation_scores leaves it unscored), and the rows fitted on the other
    # segments, which only their velocity RMSE reports, are dead-reckoned there.
    tracks = {label: positions[label] if label in positions
              else dead_reckoning_positions(windows, pred, truth, 0)
              for label, pred in predictions.items()
              if label in positions or (not label.endswith(OTHERS)
                                        and np.isfinite(pred).any())}
    navigation = navigation_scores(windows, predictions, truth, positions=tracks,
                                   stds=stds, rotations=rotations)[name]
    scores = {}
    for label, pred in predictions.items():
        have = np.isfinite(pred).all(axis=1)
        scores[label] = dict(
            velocity_rmse=(metrics.rmse_vector(pred[have], windows.target[have])
                           if have.any() else math.nan),
            availability=float(have.mean()), **navigation.get(label, {}))
        scores[label].update(watched.get(label, {}))  # a filter's: the pings it accepted
    by_reference, by_filter = baseline_names(windows.reference)
    for label in (by_reference, by_filter):
        if label in navigation:
            scores[label] = dict(navigation[label])
    scores[by_reference]["velocity_rmse"] = metrics.rmse_vector(
        windows.velocity_ls, windows.target)
    tracks[by_reference] = dead_reckoning_positions(windows, windows.velocity_ls, truth, 0)
    earth = earth_fixed_fit(*dvl_against_reference(windows, truth))
    with open_dataset(dataset) as f:
        ref = f.missions[name].reference
        t = np.asarray(ref.time, dtype=float)
        span = (t >= windows.time[0]) & (t <= windows.time[-1])
        departure = reference_departure(t[span], np.asarray(ref.position_ned)[span],
                                        np.asarray(ref.velocity_ned)[span])
    return dict(scores=dict(scores, failed=failed, pings=len(windows.time),
                            against=windows.reference, derived=bool(windows.derived),
                            earth_fixed=earth, reference_departure_m=float(departure.max())),
                time=windows.time, reference=truth["position"], tracks=tracks,
                shift=dict(motion=motion(windows, sim_train),
                           departure=_departures(windows, learned)))


def watch_words(results: dict, labels) -> list[str]:
    """For each filter of ``labels`` in ``results`` (as ``median_score`` takes them, each
    row with ``watch_scores``): the share of pings whose measurement it accepted, median
    over the missions and the lowest, and every restart of its divergence watch."""
    accepted, restarts = [], []
    for label in labels:
        rows = {name: r["scores"][label] for name, r in results.items()
                if "events" in r["scores"].get(label, {})}
        if not rows:
            continue
        low = min(rows, key=lambda name: rows[name]["availability"])
        accepted.append(f"{label} {100 * median_score(results, label, 'availability'):.1f} "
                        f"% (lowest {100 * rows[low]['availability']:.1f} %, {low})")
        restarts += [f"{label} on {name}: {text}" for name, row in rows.items()
                     for text in row["events"]]
    if not accepted:
        return []
    return [f"The share of pings whose measurement each filter accepted (its availability: "
            f"the gate passed it), median over the {len(results)} missions: "
            + "; ".join(accepted) + ". "
            + ("The divergence watch, which restarts a filter whose gate keeps rejecting "
               "the measurements, restarted none of them." if not restarts else
               "The divergence watch, which restarts a filter whose gate keeps rejecting "
               f"the measurements, restarted them {count(len(restarts), 'time')}: "
               + "; ".join(restarts) + ".")]


def consistency_lines(results: dict, labels) -> list[str]:
    """For each filter of ``labels``: per mission, its innovations' mean NIS and the
    windows beyond their chi-square bound (``ins.innovation_consistency``, in each row as
    ``watch_scores`` gives it): what the filter's covariance says of itself, with no
    reference."""
    from beamsnet.estimators.ins import CONSISTENCY_PINGS, CONSISTENCY_PROBABILITY

    parts = []
    for label in labels:
        rows = {name: r["scores"][label] for name, r in results.items()
                if "mean_nis" in r["scores"].get(label, {})}
        if rows:
            parts.append(f"{label}: " + ", ".join(
                f"{name} {_fmt(row['mean_nis'])} ({row['windows_above']} of "
                f"{row['windows']})" for name, row in rows.items()))
    if not parts:
        return []
    return [f"Whether each filter's innovations are as large as it predicts, which needs no "
            f"reference (the NIS test: each offered measurement's nu^2 / S, summed over "
            f"windows of {CONSISTENCY_PINGS} pings against the chi-square "
            f"{100 * CONSISTENCY_PROBABILITY:g} % bound; `beamsnet.estimators.ins"
            ".innovation_consistency`): the mean NIS per mission (1 where the covariance "
            "is right), and in brackets the windows beyond the bound of all. "
            + "; ".join(parts) + "."]


def median_score(results: dict, label: str, key: str) -> float:
    """The median over the missions of ``results`` ({mission: {"scores": {row: {key:
    value}}}}, as ``reproduce sea`` and ``reproduce adaptive`` keep them) of row ``label``'s
    ``key``, over the missions that have it; NaN if none does."""
    values = [r["scores"][label][key] for r in results.values()
              if label in r["scores"] and key in r["scores"][label]]
    return float(np.median(values)) if values else math.nan


def pooled_coverage(results: dict, label: str) -> float:
    """Row ``label``'s 3-sigma coverage over every mission's pings together (each
    mission's share weighted by its ``pings``); NaN if no mission has one."""
    rows = [(r["scores"][label]["coverage_3sigma"], r["scores"]["pings"])
            for r in results.values() if "coverage_3sigma" in r["scores"].get(label, {})]
    return sum(c * n for c, n in rows) / sum(n for _, n in rows) if rows else math.nan


def _fmt(value: float, spec: str = ".2f") -> str:
    return "n/a" if value is None or not math.isfinite(value) else format(value, spec)


def report(results: dict, setup: dict) -> str:
    """``sea.md``: the per-segment table, the medians, sim-to-real, and what it shows."""
    first = next(iter(results.values()))["scores"]
    against = first["against"]
    by_reference, by_filter = baseline_names(against)
    lines = [
        "# sea: every estimator on a real vehicle's own errors",
        "",
        "Made by `beamsnet reproduce sea --data DIR` (DIR: a folder of A-KIT logs, "
        "`TrajectoryK/{IMU,DVL,GT}_trajectoryK.csv`; by default the Snapir AUV's six "
        "segments). Every segment imported with `auvsim import --format akit`, then "
        f"corrected by `auvsim check-log --apply` into `{setup['dataset']}`. Every score "
        f"is **against {against}**, a navigation solution with errors of its own: "
        "velocities against the reference's velocity moved to the DVL, "
        "`M^T (C_ref^T v_ref + w x L)`, positions in the mission's local frame (origin: "
        "the reference's first point), from each segment's fourth ping (three past pings, "
        "as every table) to its last.",
        "",
    ]
    if first["derived"]:
        lines += ["The logs hold the DVL's velocity, not its beams: the beams are **derived** "
                  "as `H v` of the DVL's own velocity (30 deg Janus geometry), so they carry "
                  "the instrument's velocity errors but no error of one beam alone.", ""]
    lines += ["Every segment was corrected by `auvsim check-log --apply` before any "
              "estimator ran: what it found, from the data alone (value; confidence):",
              "", *_corrections_table(setup["corrections"]), ""]
    lines += [
        "## Per segment",
        "",
        "Horizontal position error, m: final / RMSE / final as % of the distance "
        "travelled; the filter's share of pings whose horizontal error lies within its "
        "reported 3 sigma (the radius 3 sqrt(sigma_N^2 + sigma_E^2)); velocity RMSE "
        "(vector, DVL frame, m/s).",
        "",
        f"| segment | distance (m) | {FILTER} | {FILTER} within 3 sigma (%) | "
        f"{by_reference} | {by_filter} | velocity RMSE {FILTER} | velocity RMSE DVL |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def triple(row: dict | None) -> str:
        if not row or "final_m" not in row:
            return "n/a"
        return (f"{row['final_m']:.2f} / {row['rmse_m']:.2f} / "
                f"{row['final_percent']:.2f} %")

    for name, r in results.items():
        s = r["scores"]
        f = s.get(FILTER, {})
        cover = f.get("coverage_3sigma")
        lines.append(
            f"| {name} | {s[by_reference]['distance_m']:.0f} | {triple(f)} | "
            f"{_fmt(100 * cover if cover is not None else math.nan, '.1f')} | "
            f"{triple(s[by_reference])} | {triple(s.get(by_filter))} | "
            f"{_fmt(f.get('velocity_rmse', math.nan), '.4f')} | "
            f"{s[by_reference]['velocity_rmse']:.4f} |")
    med = {label: {k: median_score(results, label, k) for k in
                   ("final_m", "rmse_m", "final_percent", "velocity_rmse", "coverage_3sigma",
                    "distance_m")}
           for label in (FILTER, by_reference, by_filter)}

    def mtriple(label: str) -> str:
        m = med[label]
        if not math.isfinite(m["final_m"]):
            return "n/a"
        return f"{m['final_m']:.2f} / {m['rmse_m']:.2f} / {m['final_percent']:.2f} %"

    lines.append(
        f"| **median** | {med[by_reference]['distance_m']:.0f} | {mtriple(FILTER)} | "
        f"{_fmt(100 * med[FILTER]['coverage_3sigma'], '.1f')} | {mtriple(by_reference)} | "
        f"{mtriple(by_filter)} | {_fmt(med[FILTER]['velocity_rmse'], '.4f')} | "
        f"{med[by_reference]['velocity_rmse']:.4f} |")
    for words in (_coverage_words(results), watch_words(results, (FILTER, SIM_FILTER)),
                  consistency_lines(results, (FILTER, SIM_FILTER)),
                  _earth_fixed_words(results)):
        lines += ["", *words] if words else []
    failed: dict[tuple[str, str], list[str]] = {}  # (filter, why) -> segments
    for name, r in results.items():
        for label, why in r["scores"]["failed"].items():
            failed.setdefault((label, why.replace(name, "SEGMENT")), []).append(name)
    if failed:
        lines += ["", "Filters that did not run: " + "; ".join(
            f"{label} on {'every segment' if len(names) == len(results) else ', '.join(names)}"
            f" ({why})" for (label, why), names in failed.items()) + "."]
    lines += ["", "![each segment's track and every estimator's error along it](sea.png)",
              "", *_sim_to_real(results, setup, by_reference)]
    return "\n".join(lines) + "\n"


def _coverage_words(results: dict) -> list[str]:
    """The filter's 3-sigma coverage over every segment's pings together, and per
    segment: the lowest, where it is under 90 %."""
    rows = [(name, r["scores"][FILTER]["coverage_3sigma"])
            for name, r in results.items()
            if "coverage_3sigma" in r["scores"].get(FILTER, {})]
    if not rows:
        return []
    pooled = pooled_coverage(results, FILTER)
    under = [f"{name} {100 * c:.1f} %" for name, c in rows if c < 0.9]
    return [f"Over every segment's pings together, the {FILTER} filter's horizontal error "
            f"lies within its reported 3 sigma {100 * pooled:.1f} % of the time; per "
            "segment, " + (f"under 90 % on {len(under)} of {len(rows)}: "
                           + ", ".join(under) if under else "at least 90 % on every one")
            + "."]


def _earth_fixed_words(results: dict) -> list[str]:
    """Per segment, what the DVL's velocity differs from the reference's by, as a constant
    in NED plus a constant in the DVL frame (``beamsnet.navigation.earth_fixed_fit``)."""
    rows = {name: r["scores"]["earth_fixed"] for name, r in results.items()
            if math.isfinite(r["scores"].get("earth_fixed", {}).get("rms", math.nan))}
    if not rows:
        return []
    lines = ["What the DVL's velocity differs from the reference's by, horizontally in NED "
             "at the pings, fitted as a constant in NED plus a constant in the DVL frame "
             "(mm/s, the rms per axis; `beamsnet.navigation.earth_fixed_fit`; n/a where "
             "the headings do not vary enough to tell the two apart). An error of the DVL (scale, "
             "bias, mounting, lever arm, clock) turns with the vehicle; a difference fixed "
             "to the Earth does not: a current one of the two took for motion, or the "
             "reference's own (a fix spread over its velocities). No model of the IMU and "
             "the DVL follows it; over a segment it amounts to the NED constant's size "
             "times the segment's duration. Beside it, how far the reference's own "
             "positions move from the integral of its own velocities over the scored pings, "
             "at most (`beamsnet.navigation.reference_departure`): what its positions hold "
             "that its velocities do not, and so how closely a score against them can tell "
             "two estimators apart.",
             "",
             "| segment | NED: north, east | DVL frame: x, y | rms left: none / NED alone / "
             "DVL frame alone / both | NED size x duration (m) | reference: positions less "
             "its velocities' integral, most (m) |",
             "|---|---|---|---|---|---|"]
    for name, e in rows.items():
        mm = {k: 1e3 * v for k, v in e.items()}
        duration = float(np.ptp(results[name]["time"]))
        lines.append(f"| {name} | {_fmt(mm['north'], '+.1f')}, {_fmt(mm['east'], '+.1f')} | "
                     f"{_fmt(mm['x'], '+.1f')}, {_fmt(mm['y'], '+.1f')} | {mm['rms']:.1f} / "
                     f"{mm['rms_ned']:.1f} / {mm['rms_dvl']:.1f} / {mm['rms_both']:.1f} | "
                     f"{_fmt(math.hypot(e['north'], e['east']) * duration, '.1f')} | "
                     f"{_fmt(results[name]['scores'].get('reference_departure_m', math.nan))}"
                     " |")
    earthward = [name for name, e in rows.items()
                 if math.isfinite(e["north"]) and e["rms_ned"] < e["rms_dvl"]]
    lines += ["", f"The NED constant alone explains more than the DVL-frame one on "
              f"{len(earthward)} of {len(rows)} segments"
              + (f" ({', '.join(earthward)})." if earthward else ".")]
    return lines


def _corrections_table(corrections: dict) -> list[str]:
    """check-log's findings, a row per segment, a column per finding."""
    names = list(dict.fromkeys(f[0] for found in corrections.values() for f in found))
    lines = ["| segment | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    for mission, found in corrections.items():
        by_name = {name: f"{text}; {confidence}" for name, text, confidence in found}
        lines.append(f"| {mission} | "
                     + " | ".join(by_name.get(n, "") for n in names) + " |")
    return lines


def _beam_noise_words(noise: dict) -> str:
    """The simulated DVL's white beam noise in words: at rest, its growth with speed and
    its value at the logs' speed."""
    if not noise["dvl_noise_speed_coeff"]:
        return f"{noise['dvl_noise_std']:g} m/s"
    return (f"{noise['dvl_noise_std']:g} m/s + {noise['dvl_noise_speed_coeff']:g} m/s per "
            f"m/s of speed: {noise['dvl_beam_noise']:.2g} m/s at the logs' median speed, "
            f"{noise['speed']:.2f} m/s")


def _sim_to_real(results: dict, setup: dict, by_reference: str) -> list[str]:
    """Item 9's table (medians over the segments) and what transfers, from the numbers."""
    first = next(iter(results.values()))["scores"]
    skip = {"failed", "pings", "against", "derived", "earth_fixed", "reference_departure_m",
            by_reference}
    labels = [k for k in first if k not in skip and not k.startswith("DR: ")]
    sim = [k for k in labels if not k.endswith(OTHERS)]
    ls = median_score(results, "LS", "velocity_rmse")
    noise = setup["noise"]
    lines = [
        "## Sim-to-real: trained on auvsim, run on the real segments",
        "",
        f"Model-based estimators fitted, and CorrectionNet trained (lr {setup['lr']:g}, "
        f"{count(setup['epochs'], 'epoch')}, {count(setup['seeds'], 'seed')}, every seed "
        "a row), only on auvsim's `realistic-maneuvers` preset "
        f"({setup['duration']:g} s per manoeuvre, `{setup['sim']}`): the navigator's 30 deg "
        f"DVL (white beam noise {_beam_noise_words(noise)}) and navigation-grade IMU. "
        f"`{SIM_FILTER}` is the filter with that simulated instrument's noise settings "
        f"(beam noise {noise['dvl_beam_noise']:.2g} m/s, accelerometer "
        f"{noise['imu_accel_noise_density']:.3g} m/s^2/sqrt(Hz), gyro "
        f"{noise['imu_gyro_noise_density']:.3g} rad/s/sqrt(Hz)) in place of the real "
        "instrument's. Beside them, each model-based estimator fitted on the other real "
        f"segments (the segment scored left out). The DVL's geometry: "
        f"{_geometry_words(setup['geometry'])}. Medians over the segments; the position "
        "of a velocity estimator is its velocity dead-reckoned with the reference's "
        "attitude:",
        "",
        "| estimator | velocity RMSE (m/s) | vs LS (%) | final (m) | RMSE (m) | "
        "fitted on the other real segments: velocity RMSE (m/s) |",
        "|---|---|---|---|---|---|",
    ]
    for label in sim:
        v = median_score(results, label, "velocity_rmse")
        real = median_score(results, f"{label}{OTHERS}", "velocity_rmse")
        lines.append(f"| {label} | {_fmt(v, '.4f')} | "
                     f"{_fmt(100 * (1 - v / ls) if ls > 0 else math.nan, '.1f')} | "
                     f"{_fmt(median_score(results, label, 'final_m'))} | "
                     f"{_fmt(median_score(results, label, 'rmse_m'))} | {_fmt(real, '.4f')} |")
    lines += ["", "### What transfers, and why", "",
              *_transfers(results, sim, ls, noise, setup["logged_noise"]),
              "", *_motion_lines(results, setup["held_out"])]
    return lines


def _rank_correlation(a: list[float], b: list[float]) -> float:
    """Spearman's rank correlation of ``a`` and ``b`` (no ties expected)."""
    ranks = [np.argsort(np.argsort(np.asarray(x, float))) for x in (a, b)]
    return float(np.corrcoef(*ranks)[0, 1])


def _motion_lines(results: dict, held_out: dict) -> list[str]:
    """Where the networks trained on auvsim meet motion their training never showed:
    a table of each segment's motion against the training set's (``motion``) beside
    each network's departure from least squares, and what the numbers say."""
    nets = list(dict.fromkeys(short_name(k) for k in held_out["departure"]))
    if not nets:
        return []
    lines = [
        "Where the networks meet motion their training never showed, measured: each "
        "segment's pings against the training set's (the preset's missions' first "
        f"{100 * held_out['train_fraction']:g} %), beside the held-out simulated pings (its "
        f"last {100 * (1 - held_out['train_fraction']):g} %). The beams' change "
        "from ping to ping is the vehicle's acceleration between pings, an input of "
        "CorrectionNet; a ping is outside the training range where a current beam or a "
        "change from a past ping lies beyond what the training pings span (there "
        "CorrectionNet clips its inputs). The departure is how far a network's velocity "
        "lies from least squares' (RMS, vector), the median over its seeds.",
        "",
        "| pings of | pings | median speed (m/s) | beams' change from ping to ping, RMS "
        "(m/s) | outside the training range (%) | "
        + " | ".join(f"{k}: departure from LS (m/s)" for k in nets) + " |",
        "|---|---|---|---|---|" + "---|" * len(nets),
    ]

    def row(label: str, shift: dict) -> tuple[str, dict]:
        m = shift["motion"]
        by_net: dict[str, list[float]] = {}
        for k, v in shift["departure"].items():
            by_net.setdefault(short_name(k), []).append(v)
        med = {k: float(np.median(v)) for k, v in by_net.items()}
        lines.append(f"| {label} | {m['pings']} | {m['speed']:.2f} | {m['change_rms']:.4f} | "
                     f"{100 * m['outside']:.1f} | "
                     + " | ".join(f"{v:.4f}" for v in med.values()) + " |")
        return label, med

    _, sim_med = row("auvsim, held out", held_out)
    real = {name: row(name, r["shift"])[1] for name, r in results.items()}
    net = next(iter(sim_med))
    dep = {n: real[n][net] for n in real}
    out = {n: results[n]["shift"]["motion"]["outside"] for n in real}
    change = {n: results[n]["shift"]["motion"]["change_rms"] for n in real}
    train_change = held_out["motion"]["change_rms"]
    worst = sorted(dep, key=dep.get, reverse=True)[:2]
    lines += [
        "",
        f"- {net} departs from least squares by {1000 * sim_med[net]:.1f} mm/s on the "
        f"held-out simulated pings and by {1000 * min(dep.values()):.1f} to "
        f"{1000 * max(dep.values()):.1f} mm/s on the real segments, most on "
        f"{' and '.join(worst)}. Their beams change from ping to ping "
        f"{min(change.values()) / train_change:.2g} to "
        f"{max(change.values()) / train_change:.2g} times as much as the held-out "
        f"simulated pings' ({train_change:.4f} m/s RMS), and {100 * min(out.values()):.1f} "
        f"to {100 * max(out.values()):.1f} % of their pings lie outside the training range, "
        f"against {100 * held_out['motion']['outside']:.1f} % of the held-out ones.",
    ]
    if len(real) >= 3:
        lines.append(
            f"- Over the {len(real)} segments, the departure's rank correlation (Spearman) "
            f"with the share of pings outside the training range is "
            f"{_rank_correlation(list(dep.values()), list(out.values())):+.2f}, and with "
            "the change from ping to ping "
            f"{_rank_correlation(list(dep.values()), list(change.values())):+.2f}.")
    return lines


def _transfers(results: dict, sim: list[str], ls: float, noise: dict,
               logged: float) -> list[str]:
    """Statements computed from the medians: which sim-trained estimators beat LS on the
    real segments, which lose, and the filter's two noise settings."""
    derived = next(iter(results.values()))["scores"]["derived"]
    def v(label):
        return median_score(results, label, "velocity_rmse")

    def said(labels):
        return ", ".join(f"{k} ({100 * (1 - v(k) / ls):+.1f} %)" for k in labels) or "none"

    better = [k for k in sim if k not in ("LS", FILTER, SIM_FILTER) and v(k) < ls]
    worse = [k for k in sim if k not in ("LS", FILTER, SIM_FILTER) and v(k) > ls]
    lines = [
        f"- Better than LS (the DVL's own velocity) against the reference, by the median "
        f"velocity RMSE: {said(better)}. Worse: {said(worse)}. (The filters: below.)",
        "- Why a calibration learned in auvsim cannot remove the real DVL's errors: each "
        "simulated mission draws its own scale factors and biases (the simulated DVL's "
        f"spreads: {100 * noise['dvl_scale_factor_std']:g} % and "
        f"{1000 * noise['dvl_bias_std']:g} mm/s), so a fit over all the training missions "
        "learns their mean, about none, and what it carries over is the shrinking of the "
        "simulated noise and the cross-axis terms of the simulated manoeuvres (our "
        "reading, not measured here). "
        + ("The real segments' beams are derived from the DVL's velocity, so no per-beam "
           "error is there to undo. " if derived else "")
        + "What the real DVL's velocity differs from the reference by (the instrument's "
        "slow errors, the reference's own error, what check-log's corrections leave) is "
        "nothing any auvsim mission had; the same estimators fitted on the other "
        "real segments show how much of it is systematic, and so learnable, on this "
        "vehicle.",
    ]
    ratio = noise["dvl_beam_noise"] / logged if logged > 0 else math.nan
    lines.append(
        f"- Noise: the simulated DVL's white beam noise is {noise['dvl_beam_noise']:.2g} m/s "
        f"at the logs' speed, the figure the log description states {logged:g} m/s "
        f"({ratio:.2g} times that; the built-in A-KIT description's is the same Navigator's "
        "error velocity over every speed of a long log, and the simulated noise follows "
        "that error velocity speed by speed, `benchmarks/dvl_error.py`, so at one speed "
        "the two are alike)."
        + (" An estimator that learned to average the simulated noise (the Kalman filters' "
           "random walk, CorrectionNet's past pings) smooths the real velocity's changes "
           "instead, which the real DVL, quieter, did not need: that is how we read the "
           "rows worse than LS." if ratio > 2 and worse else ""))
    f, s = median_score(results, FILTER, "final_m"), median_score(results, SIM_FILTER, "final_m")
    if math.isfinite(f) and math.isfinite(s):
        lines.append(
            f"- The filter with the simulated instrument's noise settings ends {_fmt(s)} m "
            f"off (median) against {_fmt(f)} m with the real instrument's ({s / f:.2f} "
            f"times), its 3-sigma coverage {_coverage(results, SIM_FILTER)} % against "
            f"{_coverage(results, FILTER)} %: what changes is only the noise the filter "
            "assumes, so the difference is what the simulated instrument's figures cost on "
            "this one.")
    else:
        lines.append("- The filter's rows are n/a where it did not run on the recorded "
                     "missions (see above).")
    return lines


def _coverage(results: dict, label: str) -> str:
    return _fmt(100 * median_score(results, label, "coverage_3sigma"), ".1f")


def _figure(results: dict, path: Path) -> None:
    """Each segment: its track (the reference, the filter, the DVL's dead reckoning) and
    every estimator's horizontal error along it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(results)
    fig, axes = plt.subplots(n, 2, figsize=(14, 3.6 * n), layout="constrained",
                             squeeze=False, gridspec_kw=dict(width_ratios=(1, 2)))
    names = list(dict.fromkeys(label for r in results.values() for label in r["tracks"]))
    look = styles(names)
    for (ax_track, ax_error), (segment, r) in zip(axes, results.items(), strict=True):
        reference = r["reference"]
        ax_track.plot(reference[:, 1], reference[:, 0], color="black", lw=2,
                      label="reference")
        for label, track in r["tracks"].items():
            error = np.linalg.norm(track[:, :2] - reference[:, :2], axis=1)
            ax_error.plot(r["time"], error, label=label, **look[label].line())
            if label in (FILTER, "LS") or label.startswith("DR: "):
                ax_track.plot(track[:, 1], track[:, 0], lw=1, **look[label].line())
        ax_track.set_aspect("equal", adjustable="datalim")
        ax_track.set_xlabel("east, m")
        ax_track.set_ylabel("north, m")
        ax_track.set_title(f"{segment}: track")
        ax_error.set_xlabel("time, s")
        ax_error.set_ylabel("horizontal error, m")
        ax_error.set_yscale("symlog", linthresh=1.0)
        ax_error.set_title(f"{segment}: error against the reference")
        ax_error.grid(alpha=0.3)
    figure_legend(fig, axes[0, 1], fontsize=7)
    save_figure(fig, path, dpi=90)
