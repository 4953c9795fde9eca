"""``beamsnet`` command line: train, evaluate, reproduce the paper's tables, stress-test
under manoeuvres."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from auvsim.errors import AuvsimError, OneLineErrorParser

# The flag each library argument is given on this command line (errors name arguments).
FLAGS = {"out": "--out", "data": "--data", "seed": "--seed", "missions": "--mission",
         "lr": "--lr", "epochs": "--epochs", "restarts": "--restarts",
         "average_epochs": "--average-epochs", "batch_size": "--batch-size",
         "model": "--model", "train_data": "--train", "maneuver_data": "--maneuvers"}
DEFAULT_SNAPIR_TEXT = "../shared/data/snapir beside the repository"


def _parser() -> argparse.ArgumentParser:
    parser = OneLineErrorParser(prog="beamsnet", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True,
                                parser_class=OneLineErrorParser)
    tr = sub.add_parser("train", help="train BeamsNetV1 or V2 on a dataset",
                        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    tr.add_argument("dataset", type=Path)
    tr.add_argument("--model", choices=("v1", "v2"), default="v2")
    tr.add_argument("--out", type=Path, required=True, help="run directory to write")
    tr.add_argument("--epochs", type=int, default=30)
    tr.add_argument("--lr", type=float, default=0.01, help="0.001 for sea data in the paper")
    tr.add_argument("--batch-size", type=int, default=4)
    tr.add_argument("--seed", type=int, default=0)
    tr.add_argument("--average-epochs", type=int, default=0,
                    help="average the weights over the last N epochs (0: the last weights, "
                    "as the paper)")
    tr.add_argument("--restarts", type=int, default=1,
                    help="train seeds SEED .. SEED+N-1 in parallel and keep the one that fits "
                    "the training split best")
    tr.add_argument("--mission", action="append", dest="missions",
                    help="train on this mission only (repeatable; default: all)")
    tr.add_argument("--quiet", action="store_true")
    ev = sub.add_parser("evaluate", help="compare a trained run with the baselines")
    ev.add_argument("run", type=Path, help="run directory written by beamsnet train")
    ev.add_argument("datasets", type=Path, nargs="+", help="datasets (.h5) to evaluate on")
    ev.add_argument("--also", type=Path, action="append", default=[],
                    help="another run to put in the same tables (repeatable)")
    ev.add_argument("--out", type=Path, default=Path("reports/evaluation"))
    rp = sub.add_parser(
        "reproduce", help="reproduce the paper's experiments: the simulation's Table 1, "
        "the Snapir sea data's Table 3",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    rp.add_argument("experiment", choices=("paper-sim", "paper-sim-text", "snapir"))
    rp.add_argument("--data", type=Path,
                    help="paper-sim: use this dataset instead of generating one; snapir: the "
                    f"directory with V.npy and V_test.npy (default {DEFAULT_SNAPIR_TEXT})")
    rp.add_argument("--duration", type=float, default=7200.0, help="s per speed (paper-sim)")
    rp.add_argument("--epochs", type=int, help="default: 30 for paper-sim, 50 for snapir")
    rp.add_argument("--lr", type=float,
                    help="default: the paper's, 0.01 for paper-sim, 0.001 for snapir")
    rp.add_argument("--average-epochs", type=int,
                    help="average the weights over the last N epochs (0: the paper's last "
                    "weights; default 5, at most the epochs)")
    rp.add_argument("--restarts", type=int, default=3,
                    help="paper-sim: seeds per model; the best on the training split is kept")
    rp.add_argument("--out", type=Path, default=Path("reports"))
    rp.add_argument("--quiet", action="store_true")
    st = sub.add_parser(
        "stress", help="train on straight lines, test every estimator on manoeuvres",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    st.add_argument("--train", type=Path, dest="train_data",
                    help="dataset to train on (default: paper-sim, generated)")
    st.add_argument("--maneuvers", type=Path, dest="maneuver_data",
                    help="dataset of manoeuvres to test on (default: the maneuvers preset, "
                    "generated)")
    st.add_argument("--train-duration", type=float, default=1800.0,
                    help="s per speed of the generated paper-sim training data")
    st.add_argument("--maneuver-duration", type=float, default=600.0,
                    help="s per manoeuvre of the generated test data")
    st.add_argument("--epochs", type=int, default=30)
    st.add_argument("--lr", type=float, default=0.01)
    st.add_argument("--average-epochs", type=int,
                    help="average the weights over the last N epochs (default 5, at most the "
                    "epochs)")
    st.add_argument("--restarts", type=int, default=1, help="seeds per model")
    st.add_argument("--out", type=Path, default=Path("reports"))
    st.add_argument("--quiet", action="store_true")
    return parser


def _averaged(given: int | None, epochs: int) -> int:
    """Epochs to average over: as given, else 5, or all of them when there are fewer."""
    return min(5, epochs) if given is None else given


def _stress(args) -> None:
    from .stress import stress

    report = stress(train_data=args.train_data, maneuver_data=args.maneuver_data,
                    out=args.out, epochs=args.epochs, lr=args.lr,
                    average_epochs=_averaged(args.average_epochs, args.epochs),
                    restarts=args.restarts,
                    train_duration=args.train_duration,
                    maneuver_duration=args.maneuver_duration, progress=not args.quiet)
    print(f"wrote {report} and its figures")


def _train(args) -> None:
    from .train import TrainConfig, train, train_best

    config = TrainConfig(model=args.model, epochs=args.epochs, lr=args.lr,
                         batch_size=args.batch_size, seed=args.seed,
                         average_epochs=args.average_epochs,
                         missions=tuple(args.missions) if args.missions else None)
    if args.restarts == 1:
        summary = train(args.dataset, config, args.out, progress=not args.quiet)
    else:
        summary = train_best(args.dataset, config, args.out, restarts=args.restarts,
                             progress=not args.quiet)
        print(f"kept {summary['kept']} of {args.restarts} seeds (lowest final training loss; "
              f"all in {args.out / 'restarts.json'})")
    print(f"trained BeamsNet{args.model.upper()}: final loss "
          f"{summary['final_train_loss']:.3g} (training), {summary['final_test_loss']:.3g} "
          f"(test split), {summary['samples_per_second']:.0f} samples/s; wrote "
          f"{summary['checkpoint']} and {summary['plot']}")


def _evaluate(args) -> None:
    from .evaluate import evaluate, markdown

    results = evaluate([args.run, *args.also], args.datasets, args.out)
    for dataset, result in results.items():
        print(markdown(result["rows"], str(dataset)))
    print(f"wrote {args.out / 'evaluation.md'}, evaluation.json and the plots")


def _reproduce(args) -> None:
    from .reproduce import DEFAULT_SNAPIR, paper_sim, snapir

    def given(value, default):
        return default if value is None else value

    if args.experiment == "snapir":
        epochs = given(args.epochs, 50)
        report = snapir(given(args.data, DEFAULT_SNAPIR), epochs=epochs,
                        lr=given(args.lr, 0.001),
                        average_epochs=_averaged(args.average_epochs, epochs),
                        out=args.out, progress=not args.quiet)
    else:
        epochs = given(args.epochs, 30)
        report = paper_sim(args.experiment, data=args.data, duration=args.duration,
                           epochs=epochs, lr=given(args.lr, 0.01), restarts=args.restarts,
                           average_epochs=_averaged(args.average_epochs, epochs),
                           out=args.out, progress=not args.quiet)
    print(f"wrote {report}")


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        {"train": _train, "evaluate": _evaluate, "reproduce": _reproduce,
         "stress": _stress}[args.command](args)
    except AuvsimError as e:
        print(f"beamsnet: error: {e.for_cli(FLAGS)}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
