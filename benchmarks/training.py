"""Training throughput of BeamsNetV1 and V2 at batch size 4 on this machine (samples/s),
one epoch each on the paper-sim 2 m/s mission, side by side in one run, with the torch
threads every training uses (``networks.TRAINING_THREADS``, one, so that a seed gives
the same weights on any machine) and with one per core, and their ratio; with
``--reproduce``, also the wall time of the whole ``beamsnet reproduce paper-sim`` (every
model trained afresh in a temporary directory) against its 15-minute target.

    .venv/bin/python benchmarks/training.py [--data datasets/paper-sim_7200s.h5] [--reproduce]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import perf_page
import torch

from beamsnet.estimators import networks
from beamsnet.training.config import TrainConfig
from beamsnet.training.train import train


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("datasets/paper-sim_7200s.h5"))
    parser.add_argument("--mission", default="speed_2")
    parser.add_argument("--epochs", type=int, default=1)
    parser.add_argument("--reproduce", action="store_true",
                        help="also time beamsnet reproduce paper-sim on --data")
    perf_page.add_write_option(parser, "training")
    args = parser.parse_args()
    fixed, cores = networks.TRAINING_THREADS, os.cpu_count() or 1
    print(f"torch {torch.__version__}; threads: {fixed} (what training uses) against "
          f"{cores} (one per core)")
    speed = {}
    with tempfile.TemporaryDirectory() as tmp:
        for model in ("v2", "v1", "v2", "v1"):
            for threads in (fixed, cores):
                networks.TRAINING_THREADS = threads  # this run's comparison only
                try:
                    summary = train(args.data, TrainConfig(model=model, epochs=args.epochs,
                                                           missions=(args.mission,)),
                                    Path(tmp) / model, progress=False)
                finally:
                    networks.TRAINING_THREADS = fixed
                speed.setdefault((model, threads), []).append(summary["samples_per_second"])
                print(f"BeamsNet{model.upper()}, {threads} thread(s): "
                      f"{summary['samples_per_second']:8.0f} samples/s "
                      f"({summary['seconds']:.1f} s for {args.epochs} epoch(s))")
    for model in ("v2", "v1"):
        ratio = max(speed[model, cores]) / max(speed[model, fixed])
        print(f"BeamsNet{model.upper()}: {cores} threads train {ratio:.2f}x as fast as {fixed} "
              "(best of two each)")
    if args.reproduce:
        target = 15 * 60
        with tempfile.TemporaryDirectory() as tmp:  # runs/ and reports/ land here, fresh
            started = time.perf_counter()
            subprocess.run([Path(sys.executable).with_name("beamsnet"), "reproduce",
                            "paper-sim", "--data", args.data.resolve(), "--quiet",
                            "--out", "reports"], cwd=tmp, check=True)
            wall = time.perf_counter() - started
        print(f"beamsnet reproduce paper-sim: {wall / 60:.1f} min wall, "
              f"{wall / target:.2f}x the 15 min target -> "
              f"{'met' if wall <= target else 'MISSED'}")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
