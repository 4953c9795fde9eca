"""Scale-out: the Dask path against the built-in pool, and sharded datasets against one file.

Side by side in one run, alternating, median of ``--repeats`` (these machines are noisy):

* **throughput**, missions per minute (wall clock) of the ``maneuvers`` preset written as a
  sharded dataset, by the built-in pool (``workers=N``: a new pool each run, as a run
  makes it) and by a Dask ``local:N`` cluster at equal N, started and warmed once per N
  (its start-up is printed apart: a run pays it once, however long);
* **per-mission overhead** of the Dask path: ``--tiny`` missions of 1 s each through
  ``local:1`` and through the built-in single-process path, the difference per mission;
* **merge or index cost** for 100 short missions: copying 100 part files into one file
  (what the single-file output does with several workers) against writing the index of
  100 shards;
* **reading**: every field of those 100 missions read through ``open_dataset`` from one
  file and through the index.

    .venv/bin/python benchmarks/cluster.py [--duration 120] [--repeats 3]
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
from generation import wall_seconds  # the sibling script (its directory is on sys.path)

from auvsim.config import MissionConfig, ScenarioConfig
from auvsim.data.reader import dataset_paths, open_dataset
from auvsim.data.schema import INDEX, SHARDS
from auvsim.data.shards import shard_state, write_index
from auvsim.data.writer import DatasetWriter, copy_mission
from auvsim.runs.cluster import THREADS, executor
from auvsim.runs.generate import config_sha256, generate, shard_config, shard_plan
from auvsim.runs.presets import preset


def read_all(path: Path) -> None:
    with open_dataset(path) as f:
        for m in f.missions.values():
            for key in dataset_paths(m._group):
                m.read(key)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=120.0,
                        help="seconds per manoeuvre of the throughput runs")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--tiny", type=int, default=40, help="missions of the overhead runs")
    parser.add_argument("--threads", type=int, default=THREADS,
                        help="threads per worker of the local:N clusters")
    perf_page.add_write_option(parser, "cluster")
    args = parser.parse_args()

    config = preset("maneuvers").with_duration(args.duration)
    n = len(config.missions)
    first = config.missions[0]
    tiny = dataclasses.replace(config, missions=tuple(
        dataclasses.replace(first, name=f"t{i:03d}", seed=i, scenario=ScenarioConfig(
            duration=1.0)) for i in range(args.tiny)))
    hundred = dataclasses.replace(config, missions=tuple(
        MissionConfig(name=f"m{i:03d}", seed=i, scenario=ScenarioConfig(duration=5.0))
        for i in range(100)))

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        generate(tiny, tmp / "warm.h5", workers=1, progress=False)  # numba's cache, once
        times: dict[str, list[float]] = {}
        starts: dict[str, float] = {}

        def run(name: str, **how) -> None:
            out = tmp / f"{name}/"
            times.setdefault(name, []).append(
                wall_seconds(lambda: generate(config, f"{out}/", progress=False, **how)))
            for shard in (out / SHARDS).iterdir():
                shard.unlink()  # the next repeat simulates them again

        for workers in (1, 2):
            started = time.perf_counter()
            with executor(f"local:{workers}", threads=args.threads) as dask:
                # Start-up: the workers' processes, then their first missions, which load
                # auvsim and numba's compiled code (each pool run pays that afresh).
                starts[f"local:{workers}"] = time.perf_counter() - started
                generate(tiny, f"{tmp / 'warm'}/", executor=dask, progress=False)
                starts[f"local:{workers}"] = time.perf_counter() - started
                for _ in range(args.repeats):
                    run(f"pool, {workers} worker(s)", workers=workers)
                    run(f"local:{workers}", executor=dask)
            with executor("local:1") as dask:
                for _ in range(args.repeats):
                    times.setdefault("tiny, this process", []).append(wall_seconds(lambda: generate(
                        tiny, f"{tmp / 'tiny-here'}/", workers=1, progress=False)))
                    times.setdefault("tiny, local:1", []).append(wall_seconds(lambda: generate(
                        tiny, f"{tmp / 'tiny-dask'}/", executor=dask, progress=False)))
                    for name in ("tiny-here", "tiny-dask"):
                        for shard in (tmp / name / SHARDS).iterdir():
                            shard.unlink()

        # 100 short missions: one file and 100 shards, the same data.
        generate(hundred, tmp / "one.h5", workers=1, progress=False)
        generate(hundred, f"{tmp / 'hundred'}/", workers=1, progress=False)
        plan = shard_plan(hundred, 1)
        shards = [shard_state(tmp / "hundred" / SHARDS / name,
                              config_sha256(shard_config(hundred, indices)))
                  for name, indices in plan]
        assert all(shards)
        parts = [tmp / "hundred" / SHARDS / name for name, _ in plan]
        for _ in range(args.repeats):
            def merge() -> None:
                with DatasetWriter(tmp / "merged.h5", config_json=hundred.to_json()) as ds:
                    for part, m in zip(parts, hundred.missions, strict=True):
                        copy_mission(part, m.name, ds)
            times.setdefault("merge 100 parts into one file", []).append(wall_seconds(merge))
            times.setdefault("write the index of 100 shards", []).append(wall_seconds(
                lambda: write_index(tmp / "hundred" / "index-bench.h5", shards,
                                    config_json=hundred.to_json())))
            times.setdefault("read 100 missions, one file", []).append(
                wall_seconds(lambda: read_all(tmp / "one.h5")))
            times.setdefault("read 100 missions, index", []).append(
                wall_seconds(lambda: read_all(tmp / "hundred" / INDEX)))

    med = {k: statistics.median(v) for k, v in times.items()}
    simulated = sum(m.scenario.duration for m in config.missions)
    print(f"maneuvers preset, {n} missions x {args.duration:g} s ({simulated:g} s simulated), "
          f"sharded output; local:N clusters of {args.threads} thread(s) per worker; median "
          f"of {args.repeats}, wall seconds")
    print(f"{'path':28s} {'wall s':>8s} {'missions/min':>13s} {'vs pool':>8s}")
    for workers in (1, 2):
        pool = med[f"pool, {workers} worker(s)"]
        for name in (f"pool, {workers} worker(s)", f"local:{workers}"):
            print(f"{name:28s} {med[name]:8.2f} {60 * n / med[name]:13.1f} "
                  f"{pool / med[name]:8.3f}")
    for name, seconds in starts.items():
        print(f"{name} cluster start-up, first missions included: {seconds:.2f} s (once "
              "per run)")
    here, dask = med["tiny, this process"], med["tiny, local:1"]
    print(f"per-mission overhead of the Dask path: {1000 * (dask - here) / args.tiny:.1f} ms "
          f"({args.tiny} missions of 1 s: {here:.2f} s here, {dask:.2f} s on local:1)")
    for name in ("merge 100 parts into one file", "write the index of 100 shards",
                 "read 100 missions, one file", "read 100 missions, index"):
        print(f"{name:34s} {med[name]:8.3f} s")
    worst = min(med[f"pool, {w} worker(s)"] / med[f"local:{w}"] for w in (1, 2))
    reading = med["read 100 missions, index"] / med["read 100 missions, one file"]
    print("targets: Dask path within 10 % of the pool's throughput at equal workers -> "
          f"{'met' if worst >= 0.9 else 'MISSED'} (worst {worst:.3f}); index of 100 shards "
          f"< 1 s -> {'met' if med['write the index of 100 shards'] < 1 else 'MISSED'}; "
          f"reading through the index within 10 % of one file -> "
          f"{'met' if reading <= 1.1 else 'MISSED'} ({reading:.3f})")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
