"""Training throughput of BeamsNetV1 and V2 at batch size 4 on this machine (samples/s),
one epoch each on the paper-sim 2 m/s mission, side by side in one run.

    .venv/bin/python benchmarks/training.py [--data datasets/paper-sim_7200s.h5]

The wall time of the whole reproduction is measured by ``time beamsnet reproduce
paper-sim``; see the README.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import torch

from beamsnet.train import TrainConfig, train


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("datasets/paper-sim_7200s.h5"))
    parser.add_argument("--mission", default="speed_2")
    parser.add_argument("--epochs", type=int, default=1)
    args = parser.parse_args()
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads")
    with tempfile.TemporaryDirectory() as tmp:
        for model in ("v2", "v1", "v2", "v1"):
            summary = train(args.data, TrainConfig(model=model, epochs=args.epochs,
                                                   missions=(args.mission,)),
                            Path(tmp) / model, progress=False)
            print(f"BeamsNet{model.upper()}: {summary['samples_per_second']:8.0f} samples/s "
                  f"({summary['seconds']:.1f} s for {args.epochs} epoch(s))")


if __name__ == "__main__":
    main()
