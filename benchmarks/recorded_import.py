"""Time ``auvsim import --format akit`` on the shared Snapir segments (target: one segment in
under 2 s, issue 24).

For each ``TrajectoryK`` folder it runs the whole command in a fresh interpreter (start-up,
imports, reading, checks, writing), ``--passes`` times, and prints the median wall time;
then the library call ``auvsim.data.recorded.import_logs`` alone (imports warm), and the
whole folder of segments in one command.

    .venv/bin/python benchmarks/recorded_import.py [--data ../shared/data/snapir-akit]
        [--passes 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def command(args: list[str], env: dict) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "auvsim.cli", *args], env=env, check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=REPO.parent / "shared/data/snapir-akit")
    parser.add_argument("--passes", type=int, default=3)
    args = parser.parse_args()
    if not args.data.is_dir():
        print(f"{args.data}: no such folder (the A-KIT segments)", file=sys.stderr)
        return 2
    env = dict(os.environ, PYTHONPATH=str(REPO))
    sys.path.insert(0, str(REPO))
    from auvsim.data.recorded import akit_segments, import_logs

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for folder, k in akit_segments(args.data):
            walls = [command(["import", str(folder), "--format", "akit", "--out",
                              str(out / f"c{k}_{i}.h5")], env) for i in range(args.passes)]
            start = time.perf_counter()
            import_logs([folder], out / f"l{k}.h5", format="akit")
            library = time.perf_counter() - start
            print(f"{folder.name}: command {statistics.median(walls):.2f} s (median of "
                  f"{args.passes}), import_logs {library:.2f} s")
        wall = command(["import", str(args.data), "--format", "akit", "--out",
                        str(out / "all.h5")], env)
        print(f"all segments in one command: {wall:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
