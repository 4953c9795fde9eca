"""Opening a dataset again: the per-mission check once per process against every time.

``open_dataset`` checks every mission of a file (its fields, attributes, clocks and
indices) before it hands the file over. A file opened again unchanged in the same process
skips that check (``auvsim.data.reader.REMEMBER_CHECKED``, on by default). Side by side in
one run, on the ``realistic-maneuvers`` preset at ``--duration`` s per manoeuvre (20
missions), its file left alone for ``reader.QUIET_S`` first:

* one ``open_dataset`` and close, checked every time and known;
* what ``beamsnet reproduce adaptive`` does per mission: ``load_windows`` of that mission
  and its truth at the pings (each opens the file), for every mission, both ways.

Each figure is the median of ``--repeats`` runs, CPU seconds of this process.

    .venv/bin/python benchmarks/opening.py [--duration 60] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import perf_page

from auvsim.data import reader
from auvsim.data.reader import open_dataset
from auvsim.runs.generate import generate
from auvsim.runs.presets import realistic_maneuvers
from beamsnet.data import load_windows
from beamsnet.navigation import truth_at_pings


def cpu(fn, repeats: int, *, checked: bool) -> float:
    """Median CPU seconds of ``fn()``, with every open checking whole (``checked``:
    ``reader.REMEMBER_CHECKED`` off) or the file known after a first open."""
    times = []
    reader.REMEMBER_CHECKED = not checked
    try:
        fn()  # the first open checks, and records the file
        for _ in range(repeats):
            start = time.process_time()
            fn()
            times.append(time.process_time() - start)
    finally:
        reader.REMEMBER_CHECKED = True
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=60.0,
                        help="s per manoeuvre of the dataset")
    parser.add_argument("--repeats", type=int, default=5)
    perf_page.add_write_option(parser, "opening")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rm.h5"
        generate(realistic_maneuvers(args.duration), path, progress=False)
        time.sleep(reader.QUIET_S + 0.1)  # a file is remembered once it has been quiet
        with open_dataset(path) as f:
            names = list(f.missions)

        def one_open() -> None:
            open_dataset(path).close()

        def per_mission() -> None:
            for name in names:
                windows = load_windows(path, missions=[name])
                truth_at_pings(path, windows)

        print(f"realistic-maneuvers at {args.duration:g} s per manoeuvre: {len(names)} "
              f"missions, {path.stat().st_size / 1e6:.1f} MB; median of {args.repeats}, "
              "CPU s")
        print(f"{'':34s} {'checked':>9s} {'known':>9s} {'ratio':>7s}")
        for label, fn in (("one open", one_open),
                          ("windows + truth, every mission", per_mission)):
            whole, known = (cpu(fn, args.repeats, checked=c) for c in (True, False))
            print(f"{label:34s} {whole:9.3f} {known:9.3f} {whole / known:6.1f}x")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
