"""``auvsim generate``: simulate the missions of a config into one dataset file.

Orchestration only: each mission is an ``auvsim.mission.MissionRun`` streamed into a
file. With one worker the missions run in this process, two at a time on threads,
straight into the output; with more (or with an executor given), each runs as a job of
a ``concurrent.futures`` executor into a part file of its own, and the dataset is then
assembled in mission order by copying those missions (``auvsim.dataset.copy_mission``).
So memory stays flat in mission length, and the output is the same whatever the number
of workers.

Jobs talk back through the part folder, which works with any executor whose workers
share this file system: each job writes the simulated seconds it has done to
``<part>.progress`` after every block, and stops at its next block once the folder
holds ``STOP`` (the first error, Ctrl-C or SIGTERM in this process).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import shutil
import tempfile
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from tqdm import tqdm

from .config import Config
from .dataset import Block, DatasetWriter, copy_mission
from .errors import ConfigError
from .mission import MissionRun, check_reachable

MISSIONS_IN_FLIGHT = 2  # per process: missions simulated at once on threads
POLL_S = 0.5  # how often the parent looks at its jobs


def _stream_mission(config: Config, index: int, writer: DatasetWriter, *,
                    stop: Callable[[], bool] = lambda: False,
                    report: Callable[[float], None] = lambda seconds: None) -> None:
    """Simulate mission ``index`` and stream it into ``writer``; ``report`` gets the
    simulated seconds of each block, ``stop`` is asked before each."""
    mission = config.missions[index]
    run = MissionRun(config, mission)
    sink = writer.mission(mission.name, run.attrs, rows=run.rows, links=run.links)
    stopped = _Flag(stop)
    for arrays in run.blocks(stopped):
        sink.append(arrays)
        report(len(Block(arrays).truth.time) / config.imu.rate_hz)
    sink.flush()


class _Flag:
    """A ``threading.Event``-like view of a stop predicate, for ``MissionRun.blocks``."""

    def __init__(self, predicate: Callable[[], bool]) -> None:
        self.predicate = predicate

    def is_set(self) -> bool:
        return self.predicate()


def write_mission(config: Config, index: int, path: str) -> None:
    """A job: simulate mission ``index`` into its own file ``path`` (in the part folder).

    Progress goes to ``path + ".progress"`` after each block; the job stops at its next
    block once the folder holds ``STOP``.
    """
    part = Path(path)
    progress, stop_file = part.with_name(part.name + ".progress"), part.parent / "STOP"
    done = 0.0

    def report(seconds: float) -> None:
        nonlocal done
        done += seconds
        tmp = progress.with_name(progress.name + ".tmp")
        tmp.write_text(f"{done:.6f}")
        tmp.replace(progress)

    with DatasetWriter(part, config_json="", compression=config.compression) as writer:
        _stream_mission(config, index, writer, stop=stop_file.exists, report=report)


def default_workers(missions: int) -> int:
    """One worker process per two cores, at most one per mission group: a process keeps two
    missions in flight, whose physics threads release the GIL, which about fills two cores
    (measured by benchmarks/datasets.py; separate processes per mission cost more in start
    up and in copying their files together than they gain)."""
    return max(1, min(-(-missions // MISSIONS_IN_FLIGHT), (os.cpu_count() or 1) // 2))


def generate(config: Config, out: str | os.PathLike, *, workers: int | None = None,
             executor: cf.Executor | None = None, progress: bool = True) -> dict:
    """Simulate every mission of ``config`` into the dataset file ``out``.

    Args:
        config: what to simulate.
        out: the HDF5 file to write (replaced only once it is complete).
        workers: worker processes (default ``default_workers``); with 1 the missions run
            in this process, ``MISSIONS_IN_FLIGHT`` at a time on threads, and stream
            straight into ``out``.
        executor: any ``concurrent.futures`` executor to run the missions' jobs
            (``write_mission``) instead of the default process pool; its workers must
            see this file system.
        progress: show a progress bar on a terminal.

    Returns:
        A summary: number of missions, simulated seconds, wall seconds.
    """
    check_reachable(config)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise ConfigError(f": expected a whole number >= 1, got {workers!r}",
                          argument="workers")
    workers = min(workers or default_workers(len(config.missions)), len(config.missions))
    started = time.perf_counter()
    simulated = sum(m.scenario.duration for m in config.missions)
    with DatasetWriter(Path(out), config_json=config.to_json(),
                       compression=config.compression) as ds, \
            tqdm(total=round(simulated), unit=" sim s", disable=None if progress else True,
                 leave=False) as bar:
        if workers == 1 and executor is None:
            _in_threads(config, ds, lambda seconds: bar.update(round(seconds)))
        else:
            _in_jobs(config, ds, workers, executor, bar)
    return dict(missions=len(config.missions), simulated_s=simulated,
                wall_s=time.perf_counter() - started)


def _in_threads(config: Config, ds: DatasetWriter, report: Callable[[float], None]) -> None:
    """Missions on threads in this process, straight into the output file: their physics
    runs without the GIL, their sensors and writing take turns with it (h5py serialises
    its calls), and each mission touches only its own datasets. The first error (or an
    interrupt) stops the others at their next block."""
    stop = threading.Event()
    pool = ThreadPoolExecutor(max_workers=MISSIONS_IN_FLIGHT)
    futures = [pool.submit(_stream_mission, config, i, ds, stop=stop.is_set, report=report)
               for i in range(len(config.missions))]
    try:
        while True:
            done, pending = cf.wait(futures, timeout=POLL_S, return_when=cf.FIRST_EXCEPTION)
            for future in done:
                future.result()
            if not pending:
                return
    finally:
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)


def _in_jobs(config: Config, ds: DatasetWriter, workers: int,
             executor: cf.Executor | None, bar) -> None:
    """Run the missions as jobs, each into a part file of its own, and copy each into
    ``ds`` in mission order as soon as it and those before it are done."""
    parts = Path(tempfile.mkdtemp(prefix=f".{ds.path.name}.parts.", dir=ds.path.parent))
    own = executor is None
    if own:
        # forkserver: workers fork from a server that has imported auvsim (numba, MuJoCo)
        # once, so they start in milliseconds, without inheriting this process's threads.
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(["auvsim.generate"])
        executor = cf.ProcessPoolExecutor(max_workers=workers, mp_context=context)
    paths = [parts / f"{i}.h5" for i in range(len(config.missions))]
    reported = [0.0] * len(paths)
    futures: list[cf.Future] = []
    try:
        futures += [executor.submit(write_mission, config, i, str(p))
                   for i, p in enumerate(paths)]
        copied = 0
        while copied < len(futures):
            done, _ = cf.wait(futures[copied:], timeout=POLL_S, return_when=cf.FIRST_EXCEPTION)
            for future in done:
                future.result()  # a job's error is raised here, as soon as it happens
            for i, path in enumerate(paths):
                seconds = _progress(path)
                bar.update(round(seconds) - round(reported[i]))
                reported[i] = max(reported[i], seconds)
            while copied < len(futures) and futures[copied].done():
                copy_mission(paths[copied], config.missions[copied].name, ds)
                paths[copied].unlink()
                copied += 1
    finally:
        (parts / "STOP").touch()  # jobs still running stop at their next block
        for future in futures:
            future.cancel()  # those not started
        if own:
            executor.shutdown(wait=True, cancel_futures=True)
        shutil.rmtree(parts, ignore_errors=True)


def _progress(part: Path) -> float:
    try:
        return float(part.with_name(part.name + ".progress").read_text())
    except (OSError, ValueError):
        return 0.0

