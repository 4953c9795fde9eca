"""MCAP export speed: a `navigator` mission exported as a ROS 2 bag, against generating it.

Generates one `navigator` mission (the preset's sensors, one mission) of ``--duration``
seconds, then exports it with ``auvsim export --to mcap`` once per chunk compression
(zstd, the default, lz4 and none), all in this process, and prints the CPU seconds of
each, the export/generate ratio, the file sizes and the messages written. Generation and
exports alternate over ``--repeats`` rounds; medians are reported.

Target: the one-hour mission exports (default compression) in at most 2x the CPU time it
took to generate.

    .venv/bin/python benchmarks/export.py [--duration 3600] [--repeats 1] [--write]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
import time
from pathlib import Path

import perf_page

from auvsim.interop.ros2 import COMPRESSIONS, export_mcap
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset


def cpu_seconds(fn) -> tuple[float, object]:
    start = time.process_time()
    result = fn()
    return time.process_time() - start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3600.0, help="mission length, s")
    parser.add_argument("--repeats", type=int, default=1)
    perf_page.add_write_option(parser, "export")
    args = parser.parse_args()

    config = preset("navigator")
    first = config.missions[0]
    config = dataclasses.replace(config, missions=(dataclasses.replace(
        first, scenario=dataclasses.replace(first.scenario, duration=args.duration)),))
    times: dict[str, list[float]] = {"generate": [], **{c: [] for c in COMPRESSIONS}}
    with tempfile.TemporaryDirectory() as tmp:
        h5 = Path(tmp) / "navigator.h5"
        generate(config, h5, workers=1, progress=False)  # numba's cache loaded once
        sizes, counts = {}, {}
        for _ in range(args.repeats):
            h5.unlink()
            times["generate"].append(cpu_seconds(
                lambda: generate(config, h5, workers=1, progress=False))[0])
            for c in COMPRESSIONS:
                out = Path(tmp) / f"navigator-{c}.mcap"
                seconds, counts = cpu_seconds(lambda c=c, out=out: export_mcap(
                    h5, out, compression=c))
                times[c].append(seconds)
                sizes[c] = out.stat().st_size / 1e6
        h5_mb = h5.stat().st_size / 1e6
    med = {k: statistics.median(v) for k, v in times.items()}
    total = sum(counts.values())
    print(f"navigator mission of {args.duration:g} s: {total} messages ("
          + ", ".join(f"{t} {n}" for t, n in counts.items())
          + f"); median of {args.repeats} (CPU seconds)")
    print(f"{'':16s} {'CPU s':>8s} {'x generate':>11s} {'us/message':>11s} {'MB':>8s}")
    print(f"{'generate':16s} {med['generate']:8.2f} {1:11.2f} {'':>11s} {h5_mb:8.1f}")
    for c in COMPRESSIONS:
        print(f"{'export ' + c:16s} {med[c]:8.2f} {med[c] / med['generate']:11.2f} "
              f"{med[c] / total * 1e6:11.2f} {sizes[c]:8.1f}")
    ratio = med["zstd"] / med["generate"]
    print(f"target: export (zstd, the default) <= 2x generate -> {ratio:.2f}x, "
          f"{'met' if ratio <= 2 else 'MISSED'}")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
