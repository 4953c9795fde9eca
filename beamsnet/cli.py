"""The beamsnet command line: train the networks, evaluate them beside the model-based
estimators, reproduce the paper's tables, stress-test every estimator under manoeuvres and
faults."""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

from auvsim.cli_support import exit_with, run_command
from auvsim.errors import ConfigError, OneLineErrorParser
from auvsim.runs.cluster import check_address
from beamsnet.data import NO_REFERENCE
from beamsnet.estimators import network_names, spec, specs
from beamsnet.estimators.registry import WITHOUT_TORCH
from beamsnet.evaluate import (
    TRAIN_FRACTION,
    FilterWarning,
    SensorSetupWarning,
    UnseenMissionWarning,
    consistency_words,
    noise_words,
)
from beamsnet.experiments.defaults import (
    ADAPTIVE_DURATION,
    ADAPTIVE_SEEDS,
    DEFAULT_SEA,
    DEFAULT_SNAPIR,
    FAULT_DURATION,
    FAULT_MISSIONS,
    MANEUVER_DURATION,
    NOISE,
    SEA_DURATION,
    SEA_SEEDS,
    SIM2REAL_DURATION,
    SIM2REAL_SEEDS,
    SIM_SEEDS,
    TRAIN_DURATION,
)
from beamsnet.training.config import MASK_RATE, PROFILES, TrainConfig

# The flag each library argument is given on this command line (errors name arguments).
FLAGS = {"out": "--out", "data": "--data", "seed": "--seed", "missions": "--mission",
         "lr": "--lr", "epochs": "--epochs", "restarts": "--restarts",
         "average_epochs": "--average-epochs", "batch_size": "--batch-size",
         "model": "--model", "train_data": "--train", "maneuver_data": "--maneuvers",
         "allow_mismatch": "--allow-mismatch", "faults": "--faults",
         "fault_duration": "--fault-duration", "fault_missions": "--fault-mission",
         "seeds": "--seeds", "duration": "--duration", "noise": "--noise",
         "estimator": "--estimator", "train": "--train", "datasets": "DATASET",
         "protocol": "--protocol",
         "mask_rate": "--mask-rate", "imu": "--imu", "cluster": "--cluster",
         "refresh_reports": "--refresh-reports", "train_duration": "--train-duration",
         "maneuver_duration": "--maneuver-duration", "filter_config": "--filter-config"}
FILTER_CONFIG_HELP = ("the INS/DVL filter's settings: a TOML file whose keys are fields of "
                      "beamsnet.estimators.ins.FilterConfig (default: its defaults)")
CLUSTER_HELP = ("run the training jobs on a Dask cluster: local:N or a scheduler's address "
                "(needs auvsim[cluster])")
QUIET_HELP = "no progress bars"
# The committed reports of a source checkout: written only with --refresh-reports.
REPORTS = Path(__file__).resolve().parents[1] / "reports"


class _Defaults(argparse.HelpFormatter):
    """Shows each option's default as a user reads it (``1800``, not ``1800.0``), except
    where it says nothing: None (the default depends on other options, and the help says
    what it is), a switch's False, an empty list."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        default = action.default
        if (default is None or default is argparse.SUPPRESS or isinstance(default, bool)
                or default == [] or not action.option_strings or "default" in text):
            return text
        shown = f"{default:g}" if isinstance(default, float) else str(default)
        return f"{text} (default: {shown})"


def _per_experiment(field: str, *names: str) -> str:
    """``"30 for paper-sim, 50 for snapir"``: a training profile field per experiment."""
    def value(name: str):
        profile = PROFILES[name]
        return profile.restarts if field == "restarts" else getattr(profile.config, field)

    return ", ".join(f"{value(name):g} for {name}" for name in names)


EXAMPLES = """examples:
  beamsnet train datasets/paper_sim.h5 --model v2 --out runs/v2
  beamsnet evaluate runs/v2 datasets/paper_sim.h5 --out evaluation/v2
  beamsnet estimate snapir-checked.h5 --estimator INS/DVL --out runs/ins
  beamsnet reproduce paper-sim
  beamsnet reproduce sea --data DIR
  beamsnet stress

Each command has its own --help."""


def _parser() -> argparse.ArgumentParser:
    # Every training default shown and used here is read from beamsnet.training.train's
    # TrainConfig and PROFILES: the command line writes none of its own.
    train = PROFILES["train"]
    parser = OneLineErrorParser(prog="beamsnet", description=__doc__, epilog=EXAMPLES,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                parser_class=OneLineErrorParser)

    def command(name: str, help: str) -> argparse.ArgumentParser:
        """A command, its --help opening with what it does (the list's line)."""
        return sub.add_parser(name, help=help, description=f"{help[0].upper()}{help[1:]}.",
                              formatter_class=_Defaults)

    networks = specs("network")  # none without PyTorch: then train says what to install
    tr = command("train", f"train {', '.join(s.short for s in networks) or 'a network'} on "
                 "a dataset")
    tr.add_argument("dataset", type=Path, help="auvsim dataset (.h5 file or sharded folder)")
    tr.add_argument("--model", choices=network_names() or None, default=train.config.model,
                    help="; ".join(f"{s.name}: {s.title}" for s in networks)
                    or f"the network ({WITHOUT_TORCH})")
    tr.add_argument("--protocol", choices=("paper", "fixed"),
                    help="v2 only: 'paper' feeds the past beams raw, as published; 'fixed' "
                    "feeds their changes to the current beams, so it stays affine outside the "
                    f"training velocities (default {train.config.protocol})")
    tr.add_argument("--mask-rate", type=float, default=None,
                    help="v2m, corr: rate of beams dropped in training (default "
                    f"{MASK_RATE:g} for them, 0 for v1, v2)")
    tr.add_argument("--imu", action="store_true", help="corr: take the IMU window too")
    tr.add_argument("--out", type=Path, required=True, metavar="FOLDER",
                    help="run folder to write (model.pt, history.json, losses.png)")
    tr.add_argument("--epochs", type=int, default=train.config.epochs, help="epochs")
    tr.add_argument("--lr", type=float, default=train.config.lr,
                    help=f"learning rate ({PROFILES['snapir'].config.lr:g} for sea data in "
                    "the paper)")
    tr.add_argument("--batch-size", type=int, default=train.config.batch_size,
                    help="samples per step")
    tr.add_argument("--seed", type=int, default=train.config.seed,
                    help="seeds the weights and the batch order")
    tr.add_argument("--average-epochs", type=int, default=train.config.average_epochs,
                    metavar="N", help="average the weights over the last N epochs (0: the "
                    "last weights, as the paper)")
    tr.add_argument("--restarts", type=int, default=train.restarts, metavar="N",
                    help="train seeds SEED .. SEED+N-1 in parallel and keep the one that fits "
                    "the training split best")
    tr.add_argument("--mission", action="append", dest="missions", metavar="NAME",
                    help="train on this mission only (repeatable; default: all)")
    tr.add_argument("--cluster", metavar="ADDRESS", help=CLUSTER_HELP)
    tr.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    ev = command("evaluate", "compare trained runs with the model-based estimators on the "
                 "test split of datasets (or the model-based estimators alone)")
    ev.add_argument("paths", type=Path, nargs="+", metavar="[run] dataset",
                    help="a run folder written by beamsnet train (optional: without one, the "
                    "model-based estimators and filters alone), then the auvsim datasets to "
                    "evaluate on")
    ev.add_argument("--also", type=Path, action="append", default=[], metavar="RUN",
                    help="another run to put in the same tables (repeatable)")
    ev.add_argument("--out", type=Path, metavar="FOLDER",
                    help="report folder (evaluation.md, evaluation.json, plots; default: a "
                    "new runs/evaluation-DATE-TIME)")
    ev.add_argument("--filter-config", type=Path, metavar="FILE.toml",
                    help=FILTER_CONFIG_HELP)
    ev.add_argument("--mission", action="append", dest="missions", metavar="NAME",
                    help="score this mission of every dataset only (repeatable; default: all)")
    ev.add_argument("--allow-mismatch", action="store_true",
                    help="evaluate on data whose beam geometry or DVL/IMU rates differ from "
                    "a run's training data (with a warning) instead of refusing it")
    ev.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    runnable = [s for s in specs() if s.kind != "network"]
    es = command("estimate", "run one model-based estimator or filter over every ping of a "
                 "dataset (from each mission's fourth: every estimator is scored on the pings "
                 "that have three before them)")
    es.add_argument("dataset", type=Path, help="auvsim dataset to estimate on")
    es.add_argument("--estimator", required=True, metavar="NAME",
                    help="its name in the tables (case, spaces and punctuation do not matter): "
                    + ", ".join(s.name for s in runnable))
    es.add_argument("--train", type=Path, dest="train", metavar="DATASET",
                    help="fit on this file's training split (default: the dataset's own, "
                    f"the first {100 * TRAIN_FRACTION:.0f} %% of each mission's pings, which "
                    "the scores then include)")
    es.add_argument("--filter-config", type=Path, metavar="FILE.toml",
                    help=FILTER_CONFIG_HELP)
    es.add_argument("--out", type=Path, metavar="FOLDER",
                    help="folder for estimates.csv and summary.json (default: a new "
                    "runs/estimate-DATE-TIME)")
    rp = command("reproduce", "reproduce the paper's experiments (the simulation's Table 1, "
                 "the Snapir sea data's Table 3) and ours: sim-to-real, the real segments, "
                 "the learned noise")
    rp.add_argument("experiment", choices=("paper-sim", "paper-sim-text", "snapir", "sim2real",
                                           "sea", "adaptive"),
                    metavar="EXPERIMENT",
                    help="paper-sim: the paper's simulation (Table 1); paper-sim-text: the "
                    "same with its text's beam noise; snapir: the Snapir sea data (Table 3); "
                    "sim2real: train every estimator on auvsim data only, test on the "
                    "Snapir streams; sea: every estimator on recorded IMU, DVL and "
                    "reference logs, scored against the reference, with sim-to-real rows; "
                    "adaptive: the INS/DVL filter with a noise network trained on auvsim "
                    "data, beside the model-based adaptive and the fixed filters, on "
                    "held-out simulated missions and on recorded logs")
    rp.add_argument("--data", type=Path, metavar="PATH",
                    help="paper-sim: use this dataset instead of generating one; snapir, "
                    "sim2real: the folder with V.npy and V_test.npy (default "
                    f"{DEFAULT_SNAPIR}); sea, adaptive: a folder of A-KIT logs (default "
                    f"{DEFAULT_SEA})")
    rp.add_argument("--duration", type=float, metavar="SECONDS",
                    help="s per speed of paper-sim (default 7200), s per manoeuvre of "
                    f"sim2real's training sets (default {SIM2REAL_DURATION:g}) and of sea's "
                    f"(default {SEA_DURATION:g}) and adaptive's (default "
                    f"{ADAPTIVE_DURATION:g})")
    rp.add_argument("--seeds", type=int, metavar="N",
                    help="snapir, sim2real, sea, adaptive: seeds per network, every one "
                    "scored (default "
                    + ", ".join(f"{n} for {name}" for name, n in SIM2REAL_SEEDS.items())
                    + f" in snapir; {SIM_SEEDS} in sim2real on its auvsim set, whose V.npy "
                    "column takes snapir's runs and counts; "
                    f"{SEA_SEEDS} in sea; "
                    f"{ADAPTIVE_SEEDS} noise models in adaptive)")
    rp.add_argument("--epochs", type=int,
                    help="default: " + _per_experiment("epochs", "paper-sim", "snapir"))
    rp.add_argument("--lr", type=float,
                    help="default: the paper's, " + _per_experiment("lr", "paper-sim", "snapir"))
    rp.add_argument("--average-epochs", type=int, metavar="N",
                    help="average the weights over the last N epochs (0: the paper's last "
                    "weights; default " + _per_experiment("average_epochs", "paper-sim",
                                                          "snapir") + ", at most the epochs)")
    rp.add_argument("--restarts", type=int, metavar="N",
                    help="paper-sim: seeds per model; the best on the training split is kept "
                    "(default " + _per_experiment("restarts", "paper-sim") + ")")
    _report_options(rp, "a new runs/EXPERIMENT-YYYYmmdd-HHMMSS")
    rp.add_argument("--cluster", metavar="ADDRESS", help=CLUSTER_HELP)
    rp.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    stress = PROFILES["stress"]
    st = command("stress", "train on straight lines, test every estimator on manoeuvres")
    st.add_argument("--train", type=Path, dest="train_data", metavar="DATASET",
                    help="dataset to train on (default: paper-sim, generated)")
    st.add_argument("--maneuvers", type=Path, dest="maneuver_data", metavar="DATASET",
                    help="dataset of manoeuvres to test on (default: the maneuvers preset, "
                    "generated)")
    st.add_argument("--train-duration", type=float, default=TRAIN_DURATION, metavar="SECONDS",
                    help="s per speed of the generated paper-sim training data")
    st.add_argument("--maneuver-duration", type=float, default=MANEUVER_DURATION,
                    metavar="SECONDS", help="s per manoeuvre of the generated test data")
    st.add_argument("--epochs", type=int, default=stress.config.epochs, help="epochs")
    st.add_argument("--lr", type=float, default=stress.config.lr, help="learning rate")
    st.add_argument("--average-epochs", type=int, metavar="N",
                    help="average the weights over the last N epochs (default "
                    f"{stress.config.average_epochs}, at most the epochs)")
    st.add_argument("--restarts", type=int, default=stress.restarts, metavar="N",
                    help="seeds per model")
    st.add_argument("--faults", action="store_true",
                    help="test the same trained models on faulted manoeuvres instead "
                    "(dropouts, a dead beam, outliers, water track): writes faults.md, "
                    "faults.json and faults.png")
    st.add_argument("--fault-duration", type=float, metavar="SECONDS",
                    help=f"s per manoeuvre of the faulted test data (with --faults; default "
                    f"{FAULT_DURATION:g})")
    st.add_argument("--fault-mission", action="append", dest="fault_missions", metavar="NAME",
                    help="a manoeuvre of the faulted test data (repeatable; with --faults; "
                    f"default {', '.join(FAULT_MISSIONS)})")
    st.add_argument("--noise", choices=tuple(NOISE), default="code",
                    help="beam noise of the generated data: code, the paper's code's "
                    "0.042^2 m/s (paper-sim); text, its text's 0.042 m/s (paper-sim-text)")
    _report_options(st, "a new runs/stress-YYYYmmdd-HHMMSS (runs/faults-... with --faults)")
    st.add_argument("--cluster", metavar="ADDRESS", help=CLUSTER_HELP)
    st.add_argument("--quiet", action="store_true", help=QUIET_HELP)
    return parser


def _report_options(parser: argparse.ArgumentParser, default: str) -> None:
    """--out and --refresh-reports: a report is written to a new folder unless asked."""
    parser.add_argument("--out", type=Path, metavar="FOLDER",
                        help=f"report folder (default: {default})")
    parser.add_argument("--refresh-reports", action="store_true",
                        help="write into the repository's reports/ folder (or --out inside "
                        "it), replacing the committed reports")


def report_dir(out: Path | None, refresh: bool, name: str, *,
               reports: Path = REPORTS) -> Path:
    """Where a report of ``name`` goes: ``out``; with ``refresh`` and no ``out``, the
    committed ``reports`` folder; by default a new ``runs/<name>-<local time>`` folder,
    so that no run overwrites a committed report unless asked to.

    Raises:
        ConfigError: ``out`` is in the committed ``reports`` folder without ``refresh``.
    """
    if out is None:
        if refresh:
            return reports if reports.is_dir() else Path("reports")
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out, n = Path("runs") / f"{name}-{stamp}", 1
        while out.exists():  # two runs in the same second
            n += 1
            out = Path("runs") / f"{name}-{stamp}-{n}"
        return out
    inside = out.resolve()
    if not refresh and reports.is_dir() and (inside == reports or reports in inside.parents):
        raise ConfigError(f"{str(out)!r}: is the repository's committed reports folder; "
                          "expected another folder, or --refresh-reports to replace them",
                          argument="out")
    return out


def _train(args) -> None:
    from beamsnet.training.runs import train_all, train_best
    from beamsnet.training.train import train

    if args.protocol is not None and args.model != "v2":
        raise ConfigError(f": only v2 has the choice; {args.model} "
                          + ("has no past beams" if args.model == "v1" else
                             "always takes the past beams' changes")
                          + "; expected it without --protocol", argument="protocol")
    args.protocol = args.protocol or PROFILES["train"].config.protocol
    config = TrainConfig(model=args.model, epochs=args.epochs, lr=args.lr,
                         batch_size=args.batch_size, seed=args.seed,
                         average_epochs=args.average_epochs,
                         missions=tuple(args.missions) if args.missions else None,
                         protocol=args.protocol, mask_rate=args.mask_rate, imu=args.imu)
    if args.restarts == 1 and args.cluster is None:
        summary = train(args.dataset, config, args.out, progress=not args.quiet)
    elif args.restarts == 1:  # the one job, on the cluster
        summary = train_all([(args.dataset, config, args.out)], progress=not args.quiet,
                            cluster=args.cluster)[0]
    else:
        summary = train_best(args.dataset, config, args.out, restarts=args.restarts,
                             progress=not args.quiet, cluster=args.cluster)
        print(f"kept {summary['kept']} of {args.restarts} seeds (lowest final training loss; "
              f"all in {args.out / 'restarts.json'})")
    print(f"trained {spec(args.model).short}: final loss "
          f"{summary['final_train_loss']:.3g} (training), {summary['final_test_loss']:.3g} "
          f"(test split; least squares {summary['ls_test_loss']:.3g}), "
          f"{summary['samples_per_second']:.0f} samples/s; wrote "
          f"{summary['checkpoint']} and {summary['plot']}")
    loss, ls = summary["final_test_loss"], summary["ls_test_loss"]
    if loss > ls:
        times = f"{loss / ls:.3g} times its loss" if ls > 0 else "whose loss is 0"
        warnings.warn(f"{spec(args.model).short} does worse on the test split than least "
                      f"squares on the same beams ({times}): more epochs, "
                      "--restarts or a smaller --lr may let it learn; the losses plot shows "
                      "how it went", WorseThanLeastSquaresWarning, stacklevel=2)


def _evaluate(args) -> None:
    from beamsnet.evaluate import evaluate, markdown, navigation_markdown

    config = _filter_config(args.filter_config)
    first, *datasets = args.paths
    if not first.exists() and not datasets:
        raise ConfigError(f": {str(first)!r} does not exist; expected a run folder and the "
                          "datasets to evaluate it on, or datasets alone", argument="datasets")
    runs = [*([first] if _is_run(first) else []), *args.also]
    if not _is_run(first):
        datasets.insert(0, first)
    if not datasets:
        raise ConfigError(f": {str(first)!r} is a run; expected the datasets to evaluate it "
                          "on after it", argument="datasets")
    twice = next((d for d in datasets if datasets.count(d) > 1), None)
    if twice is not None:
        raise ConfigError(f": {str(twice)!r} is given twice; expected each dataset once (a "
                          "dataset first evaluates the model-based estimators alone)",
                          argument="datasets")
    args.out = report_dir(args.out, False, "evaluation")
    results = evaluate(runs, datasets, args.out,
                       allow_mismatch=args.allow_mismatch, filter_config=config,
                       progress=not args.quiet, missions=args.missions)
    for dataset, result in results.items():
        print(markdown(result["rows"], f"{dataset}, against {result['against']}"))
        if "navigation" in result:
            print()
            print(navigation_markdown(result["navigation"], result["against"]))
    print(f"wrote {args.out / 'evaluation.md'}, evaluation.json and the plots")


def _is_run(path: Path) -> bool:
    """Whether ``evaluate``'s first path is a run rather than a dataset: anything but an
    HDF5 file or a sharded dataset's folder (so a run whose training did not finish is
    refused as a run, saying so)."""
    if path.is_dir():
        return not (path / "index.h5").exists()
    try:
        with open(path, "rb") as f:
            return f.read(8) != b"\x89HDF\r\n\x1a\n"
    except OSError:
        return path.suffix not in (".h5", ".hdf5")


def _estimate(args) -> None:
    from beamsnet.evaluate import estimate

    config = _filter_config(args.filter_config)
    args.out = report_dir(args.out, False, "estimate")
    summary = estimate(args.estimator, args.dataset, args.out, train=args.train,
                       filter_config=config)
    print(f"{summary['estimator']} on {args.dataset}, "
          + ("not scored: the log has no reference" if summary["against"] == NO_REFERENCE
             else f"scored against {summary['against']}")
          + (f"; beams derived as H v from the DVL's own velocity in "
             f"{', '.join(summary['beams_derived'])} (the log has none)"
             if summary.get("beams_derived") else ""))
    if "fitted_on_scored_pings" in summary:
        print(f"note: {summary['estimator']} was {summary['fitted_on_scored_pings']}")
    if "unfitted" in summary:
        print(f"note: {summary['estimator']}: {summary['unfitted']}")
    for mission, row in summary["missions"].items():
        said = [f"{100 * row['availability']:.1f} % of {row['pings']} pings"
                + (" accepted" if "events" in row else "")]
        if "events" in row:
            said.append(f"{len(row['events'])} restart{'' if len(row['events']) == 1 else 's'}"
                        " by the divergence watch")
        if "rmse_vector" in row:
            said.append(f"velocity RMSE {row['rmse_vector']:.4f} m/s")
        if "position" in row:
            said.append(_position_words(row["position"]))
        print(f"{summary['estimator']} on {mission}: " + ", ".join(said))
        for event in row.get("events", []):
            print(f"  {event}")
        if "mean_nis" in row:  # a filter: are its innovations as large as it predicts?
            print(f"  innovations: {consistency_words(row)}")
        if "noise" in row:  # and what it was told to expect
            print(f"  noise it used: {noise_words(row['noise'])}")
        for name, scores in row.get("baselines", {}).items():
            print(f"  {name}: {_position_words(scores)}")
    print(f"wrote {args.out / 'estimates.csv'} and {args.out / 'summary.json'}")


def _position_words(scores: dict) -> str:
    """A position score in words: final, RMSE, % of the distance, 3-sigma coverage."""
    words = (f"horizontal position error final {scores['final_m']:.2f} m, RMSE "
             f"{scores['rmse_m']:.2f} m, {scores['final_percent']:.2f} % of "
             f"{scores['distance_m']:.0f} m travelled")
    if "coverage_3sigma" in scores:
        words += f", within its 3 sigma {100 * scores['coverage_3sigma']:.1f} % of the time"
    return words


def _filter_config(path: Path | None):
    """The filter's settings from ``--filter-config`` (read before anything is written)."""
    if path is None:
        return None
    from beamsnet.estimators.ins import load_config

    return load_config(path)


def _reproduce(args) -> None:
    from beamsnet.experiments.adaptive import adaptive
    from beamsnet.experiments.reproduce import paper_sim, sim2real, snapir
    from beamsnet.experiments.sea import sea

    if args.experiment == "adaptive":
        # Its network has its own training (noisenet): the paper's settings do not apply.
        for name in ("epochs", "lr", "average_epochs", "restarts"):
            if getattr(args, name) is not None:
                raise ConfigError("is not used by adaptive, whose noise network trains "
                                  "with its own settings (beamsnet.estimators.noisenet); "
                                  "expected --data, --duration, --seeds, --out",
                                  argument=name)
        args.out = report_dir(args.out, args.refresh_reports, args.experiment)
        report = adaptive(DEFAULT_SEA if args.data is None else args.data, out=args.out,
                          duration=ADAPTIVE_DURATION if args.duration is None
                          else args.duration,
                          seeds=ADAPTIVE_SEEDS if args.seeds is None else args.seeds,
                          progress=not args.quiet, cluster=args.cluster)
        print(f"wrote {report}")
        print(f"{MADE_BESIDE}; the noise models in runs/adaptive/ (noise-model.npz, seed 0, "
              "replaced by each run)")
        return

    # sim2real and sea test on sea data: they train with the paper's sea-data settings.
    profile = PROFILES["snapir" if args.experiment in ("sim2real", "sea")
                       else args.experiment]
    training, restarts = profile.resolve(
        epochs=args.epochs, lr=args.lr, average_epochs=args.average_epochs,
        restarts=args.restarts)
    seeded = args.experiment in ("snapir", "sim2real", "sea")
    if seeded and args.restarts is not None:
        raise ConfigError(f"is not used by {args.experiment}, which scores every seed; "
                          "expected --seeds N", argument="restarts")
    if args.experiment.startswith("paper-sim") and args.data is not None \
            and args.duration is not None:
        raise ConfigError("is not used with --data, whose file is the data as it is; "
                          "expected one of the two (--duration sizes the dataset generated "
                          "without --data)", argument="duration")
    if args.experiment == "snapir" and args.duration is not None:
        raise ConfigError("is not used by snapir, whose data are the recorded streams; "
                          "expected it with paper-sim or sim2real", argument="duration")
    if not seeded and args.seeds is not None:
        raise ConfigError(f"is not used by {args.experiment}, which keeps the best of "
                          "its seeds; expected --restarts N", argument="seeds")
    args.out = report_dir(args.out, args.refresh_reports, args.experiment)
    if args.experiment == "sea":
        report = sea(DEFAULT_SEA if args.data is None else args.data, out=args.out,
                     duration=SEA_DURATION if args.duration is None else args.duration,
                     seeds=SEA_SEEDS if args.seeds is None else args.seeds,
                     training=training, progress=not args.quiet, cluster=args.cluster)
    elif args.experiment == "sim2real":
        report = sim2real(DEFAULT_SNAPIR if args.data is None else args.data, out=args.out,
                          duration=SIM2REAL_DURATION if args.duration is None
                          else args.duration, training=training, seeds=args.seeds,
                          progress=not args.quiet, cluster=args.cluster)
    elif args.experiment == "snapir":
        report = snapir(DEFAULT_SNAPIR if args.data is None else args.data, out=args.out,
                        training=training, seeds=args.seeds, progress=not args.quiet,
                        cluster=args.cluster)
    else:
        report = paper_sim(args.experiment, data=args.data,
                           duration=7200.0 if args.duration is None else args.duration,
                           out=args.out, training=training, restarts=restarts,
                           progress=not args.quiet, cluster=args.cluster)
    print(f"wrote {report}")
    print(MADE_BESIDE)


# What reproduce and stress make outside --out, said after their reports.
MADE_BESIDE = ("its datasets are in datasets/ and its trained models under runs/: a later "
               "run of the same settings on the same data reuses them, any other replaces "
               "them")
STRESS_MADE_BESIDE = MADE_BESIDE.replace("its datasets are in datasets/",
                                         "its datasets are in datasets/ (those --train and "
                                         "--maneuvers name stay where they are)")


def _stress(args) -> None:
    from beamsnet.experiments.stress import stress

    training, restarts = PROFILES["stress"].resolve(
        epochs=args.epochs, lr=args.lr, average_epochs=args.average_epochs,
        restarts=args.restarts)
    args.out = report_dir(args.out, args.refresh_reports, "faults" if args.faults else "stress")
    report = stress(train_data=args.train_data, maneuver_data=args.maneuver_data,
                    out=args.out, training=training, restarts=restarts,
                    train_duration=args.train_duration,
                    maneuver_duration=args.maneuver_duration, faults=args.faults,
                    fault_duration=args.fault_duration,
                    fault_missions=None if args.fault_missions is None
                    else tuple(args.fault_missions), noise=args.noise,
                    progress=not args.quiet, cluster=args.cluster)
    print(f"wrote {report} and its figures")
    print(STRESS_MADE_BESIDE)


# The commands whose --out folder a user names and may name again: each says which files
# already there it replaced (a run trained again into its folder, say).
SAYS_REPLACED = ("train", "evaluate", "estimate")


class ReplacedWarning(UserWarning):
    """A command's --out folder held files it then changed."""


class WorseThanLeastSquaresWarning(UserWarning):
    """A trained network's test-split loss is above the beams' least-squares solution's."""


HASHED = 16 << 20  # bytes: a file up to this size is compared by its contents, a larger
# one by its size and time (hashing a dataset a folder holds would take long)


def _files_in(folder: Path | None) -> dict[Path, tuple]:
    """The files directly in ``folder`` (none if it is not a folder), each with what tells
    a rewrite: its contents' digest, or its size and modification time if large."""
    import hashlib

    if folder is None or not folder.is_dir():
        return {}
    out = {}
    for path in folder.iterdir():
        if path.is_file():
            stat = path.stat()
            out[path] = ((hashlib.sha256(path.read_bytes()).hexdigest(),)
                         if stat.st_size <= HASHED else (stat.st_size, stat.st_mtime_ns))
    return out


def _say_replaced(folder: Path | None, before: dict[Path, tuple]) -> None:
    """Warn of the files of ``before`` (``_files_in`` before the command) that the
    command changed."""
    now = _files_in(folder)
    changed = sorted(p.name for p, seen in before.items() if now.get(p, seen) != seen)
    if changed:
        words = (", ".join(changed[:-1]) + " and " if len(changed) > 1 else "") + changed[-1]
        warnings.warn(f"{str(folder)!r} held {words} already; this run replaced "
                      f"{'it' if len(changed) == 1 else 'them'}", ReplacedWarning, stacklevel=2)


def _warn(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning on one line of stderr, as errors are."""
    print(f"beamsnet: warning: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run a command line; returns the exit status: 0, 2 on an error, 130 on Ctrl-C or
    SIGTERM, 141 when the reader of its output has gone (``auvsim.cli_support``)."""
    args = _parser().parse_args(argv)

    def command() -> None:
        if getattr(args, "cluster", None) is not None:
            check_address(args.cluster)  # before any data is read or made
        out = args.out if args.command in SAYS_REPLACED else None
        before = _files_in(out)
        {"train": _train, "evaluate": _evaluate, "estimate": _estimate,
         "reproduce": _reproduce, "stress": _stress}[args.command](args)
        _say_replaced(out, before)

    with warnings.catch_warnings():
        warnings.showwarning = _warn
        # Each says something about this evaluation's inputs: never once per session.
        warnings.simplefilter("always", SensorSetupWarning)
        warnings.simplefilter("always", UnseenMissionWarning)
        warnings.simplefilter("always", FilterWarning)
        warnings.simplefilter("always", ReplacedWarning)
        warnings.simplefilter("always", WorseThanLeastSquaresWarning)
        return run_command("beamsnet", command, FLAGS)


def run() -> None:
    """The ``beamsnet`` program (``exit_with``: its status, and a teardown Ctrl-C cannot
    break)."""
    exit_with("beamsnet", main)


if __name__ == "__main__":
    run()
