"""Drawing the figures of many panels: ``beamsnet.plotstyle.panel_grid`` (margins fixed in
inches) against matplotlib's constrained layout, and ``decades_only`` (log axes without
minor ticks) against every tick, on ``beamsnet stress``'s own figures.

A small ``beamsnet stress`` run (``--train-duration``, ``--maneuver-duration``, one epoch:
every manoeuvre, every estimator) is made once and its figures' inputs kept; then each
figure of many panels (the tracks and their position errors, two panels per manoeuvre;
the velocity error over each manoeuvre) is drawn and saved ``--repeats`` times each way,
the three ways alternating, and the median CPU seconds of this process are printed with
the ratios to the last. The constrained side is the same function with ``panel_grid``
swapped for a figure of the same size laid out by ``layout="constrained"`` and every tick
kept (``decades_only`` swapped for nothing): what the figures drew before; the middle
side keeps ``panel_grid`` and every tick; the last is the figures as they are.

    .venv/bin/python benchmarks/figures.py [--maneuver-duration 60] [--repeats 3]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import perf_page

from beamsnet.experiments import stress
from beamsnet.plotstyle import decades_only, panel_grid

FIGURES = ("plot_tracks", "_plot_time")


def constrained_grid(rows: int, cols: int, **kwargs):
    """``panel_grid``'s figure, laid out by matplotlib's constrained layout instead."""
    fig, axes = panel_grid(rows, cols, **kwargs)
    fig.set_layout_engine("constrained")
    return fig, axes


def inputs(folder: Path, args) -> dict[str, tuple]:
    """Each figure's arguments but its path, from a small ``beamsnet stress`` run."""
    from beamsnet.cli import main

    kept, real = {}, {name: getattr(stress, name) for name in FIGURES}

    def keeper(name):
        def keep(*a, **k):
            kept[name] = (a[:-1], k)
            return real[name](*a, **k)
        return keep

    for name in FIGURES:
        setattr(stress, name, keeper(name))
    cwd = os.getcwd()
    try:
        os.chdir(folder)
        with contextlib.redirect_stdout(io.StringIO()):  # its own summary lines
            code = main(["stress", "--train-duration", str(args.maneuver_duration),
                     "--maneuver-duration", str(args.maneuver_duration), "--epochs", "1",
                         "--out", "run", "--quiet"])
    finally:
        os.chdir(cwd)
        for name in FIGURES:
            setattr(stress, name, real[name])
    if code != 0:
        raise SystemExit(f"beamsnet stress failed ({code})")
    return kept


def every_tick(ax) -> None:
    """``decades_only`` left out: the log axes keep their minor ticks."""


# Each way: the grid and what the figures do to a small log axis.
WAYS = {"constrained": (constrained_grid, every_tick), "panel_grid": (panel_grid, every_tick),
        "+ decades": (panel_grid, decades_only)}


def cpu(name: str, a: tuple, k: dict, out: Path, way: str) -> float:
    stress.panel_grid, stress.decades_only = WAYS[way]
    try:
        start = time.process_time()
        getattr(stress, name)(*a, out, **k)
        return time.process_time() - start
    finally:
        stress.panel_grid, stress.decades_only = panel_grid, decades_only


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--maneuver-duration", type=float, default=60.0,
                        help="s per manoeuvre of the stress run (and of its training)")
    parser.add_argument("--repeats", type=int, default=3)
    perf_page.add_write_option(parser, "figures")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        kept = inputs(Path(tmp), args)
        missions = len(kept["plot_tracks"][0][0].names)
        print(f"beamsnet stress at {args.maneuver_duration:g} s per manoeuvre: {missions} "
              f"manoeuvres, {len(kept['plot_tracks'][0][1])} estimators; median of "
              f"{args.repeats}, CPU s of drawing and saving")
        print(f"{'':46s} {'constrained':>11s} {'panel_grid':>10s} {'+ decades':>9s} "
              f"{'ratios to the last':>18s}")
        for name, label in (("plot_tracks", "tracks and position errors (2 per manoeuvre)"),
                            ("_plot_time", "velocity error over each manoeuvre")):
            a, k = kept[name]
            times: dict[str, list[float]] = {way: [] for way in WAYS}
            for way in WAYS:  # untimed: fonts, caches
                cpu(name, a, k, Path(tmp) / "first.png", way)
            for _ in range(args.repeats):  # alternated: a slow spell falls on each
                for way in WAYS:
                    times[way].append(cpu(name, a, k, Path(tmp) / "figure.png", way))
            grid, ticks, now = (statistics.median(times[w]) for w in WAYS)
            print(f"{label:46s} {grid:11.2f} {ticks:10.2f} {now:9.2f} "
                  f"{grid / now:8.1f}x {ticks / now:8.1f}x")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
