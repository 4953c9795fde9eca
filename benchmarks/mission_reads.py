"""Reading a mission's fields again and again: each group and field looked up once per
open (``reader.Mission._item``) against a lookup at every read.

What ``beamsnet reproduce adaptive`` and the learned noise's training do: the INS/DVL
filter over every mission of one open file, several times each (the stated-noise factors,
the measurement forms, the rounds), each run reading the mission's fields anew. Side by
side in one run, alternated, on the ``realistic-maneuvers`` preset at ``--duration`` s
per manoeuvre (20 missions); each figure is the median of ``--repeats`` runs, CPU seconds
of this process.

    .venv/bin/python benchmarks/mission_reads.py [--duration 20] [--runs 5] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import perf_page

from auvsim.data.reader import Mission, open_dataset
from auvsim.runs.generate import generate
from auvsim.runs.presets import realistic_maneuvers
from beamsnet.estimators.ins import run_mission


def every_time(self, path):
    """The lookup at every read (what ``Mission._item`` replaced)."""
    return self._group.get(path)


def cpu(path: Path, runs: int) -> float:
    start = time.process_time()
    with open_dataset(path) as f:
        for mission in f.missions.values():
            for _ in range(runs):
                run_mission(mission)
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=20.0, help="s per manoeuvre")
    parser.add_argument("--runs", type=int, default=5, help="filter runs per mission")
    parser.add_argument("--repeats", type=int, default=5)
    perf_page.add_write_option(parser, "mission_reads")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rm.h5"
        generate(realistic_maneuvers().with_duration(args.duration), path, progress=False)
        once = Mission._item
        cpu(path, 1)  # untimed: the compiled loop's cache, the file's check
        times: dict[str, list[float]] = {"every read": [], "once": []}
        for _ in range(args.repeats):  # alternated: a slow spell falls on both
            for way, lookup in (("every read", every_time), ("once", once)):
                Mission._item = lookup
                try:
                    times[way].append(cpu(path, args.runs))
                finally:
                    Mission._item = once
        before, after = (statistics.median(times[w]) for w in times)
        print(f"realistic-maneuvers at {args.duration:g} s per manoeuvre: 20 missions, the "
              f"filter {args.runs} times over each in one open; median of {args.repeats}, "
              "CPU s")
        print(f"{'':30s} {'every read':>10s} {'once':>8s} {'ratio':>6s}")
        print(f"{'lookups of groups and fields':30s} {before:10.2f} {after:8.2f} "
              f"{before / after:5.2f}x")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
