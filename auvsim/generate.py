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
holds ``STOP`` (the first error, Ctrl-C or SIGTERM in this process). This process then
waits for them, so nothing is left behind.

A killed parent (``kill -9``) cannot write ``STOP``: each job's process watches it instead
(``_exit_with``) and ends at once when it has gone, first removing the run's temporaries
(``auvsim.files.sweep``); the forkserver ends with its last client. The default pool's
forkserver, and so its workers, ignore SIGINT and SIGTERM, which a terminal or a
scheduler sends to the whole process group: only this process acts on them, stopping its
jobs through ``STOP``, and no worker prints a traceback.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import multiprocessing.forkserver
import os
import select
import signal
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from tqdm import tqdm

from .config import Config
from .dataset import Block, DatasetWriter, copy_mission
from .errors import ConfigError, SimulationError
from .files import HOST, interrupt_handler, interrupts_held, sweep
from .mission import MissionRun, check_reachable

MISSIONS_IN_FLIGHT = 2  # per process: missions simulated at once on threads
POLL_S = 0.5  # how often the parent looks at its jobs (and, without pidfd, a job at it)
Parent = tuple[str, int, str | None]  # host, pid, start time (``this_process``)


def _stream_mission(config: Config, index: int, writer: DatasetWriter, *,
                    stop: Callable[[], bool] = lambda: False,
                    report: Callable[[float], None] = lambda seconds: None) -> None:
    """Simulate mission ``index`` and stream it into ``writer``; ``report`` gets the
    simulated seconds of each block, ``stop`` is asked before each."""
    mission = config.missions[index]
    run = MissionRun(config, mission)
    sink = writer.mission(mission.name, run.attrs, rows=run.rows, links=run.links)
    for arrays in run.blocks(stop):
        sink.append(arrays)
        report(len(Block(arrays).truth.time) / config.imu.rate_hz)
    sink.flush()


def write_mission(config: Config, index: int, path: str, parent: Parent | None = None) -> None:
    """A job: simulate mission ``index`` into its own file ``path`` (in the part folder).

    Progress goes to ``path + ".progress"`` after each block; the job stops at its next
    block once the folder holds ``STOP``, and its process ends once ``parent`` (the
    process that submitted it: ``this_process()``) has.
    """
    part = Path(path)
    if parent is not None:
        _exit_with(parent, part.parent.parent)
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
            see this file system, and those on this host end once this process has.
        progress: show a progress bar on a terminal.

    Returns:
        A summary: number of missions, simulated seconds, wall seconds.
    """
    with interrupts_held():  # its first compiled calls would swallow a KeyboardInterrupt
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
    parts = ds.claim.folder  # named and locked with the output's temporary file
    parts.mkdir()
    parent = this_process()
    pool = None
    paths = [parts / f"{i}.h5" for i in range(len(config.missions))]
    reported = [0.0] * len(paths)
    futures: list[cf.Future] = []
    try:
        with interrupts_held():
            if executor is None:
                executor = pool = _process_pool(workers, parent, ds.path.parent)
            for i, path in enumerate(paths):
                futures.append(executor.submit(write_mission, config, i, str(path), parent))
        copied = 0
        while copied < len(futures):
            done, _ = cf.wait(futures[copied:], timeout=POLL_S, return_when=cf.FIRST_EXCEPTION)
            for future in done:
                try:
                    future.result()  # a job's error is raised here, as soon as it happens
                except BrokenProcessPool:  # a traceback would say no more
                    raise SimulationError("a worker process ended abruptly (killed, or out "
                                          "of memory?): expected it to finish its missions"
                                          ) from None
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
        cf.wait(futures)  # before the part folder goes (``DatasetWriter`` removes it)
        if pool is not None:
            pool.shutdown(wait=True)


def _process_pool(workers: int, parent: Parent, folder: Path) -> cf.ProcessPoolExecutor:
    """The default pool: forkserver workers, which fork from a server that has imported
    auvsim (numba, MuJoCo) once, so they start in milliseconds, without inheriting this
    process's threads. Each watches this process from its start (``_exit_with``), so an
    idle one also ends with it."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["auvsim.generate"])
    # Ignored signals stay ignored across exec and fork, and Python then installs no
    # KeyboardInterrupt handler: the server and its workers (and the resource tracker it
    # starts) never see the group's Ctrl-C or SIGTERM, even while they import. A signal
    # to this process in these milliseconds is lost.
    with interrupt_handler(signal.SIG_IGN):
        multiprocessing.forkserver.ensure_running()
    return cf.ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                  initializer=_exit_with, initargs=(parent, folder))


def this_process() -> Parent:
    """This process as ``write_mission`` watches it: host, pid and start time."""
    pid = os.getpid()
    return HOST, pid, _start_time(pid)


_watched: dict[Parent, set[Path]] = {}  # parent -> the folders of its temporaries
_watched_lock = threading.Lock()


def _exit_with(parent: Parent, folder: Path) -> None:
    """End this process as soon as ``parent`` has ended, first sweeping ``folder`` of
    the temporaries that run left (``auvsim.files.sweep``): a job is of no use once the
    process that submitted it has gone, and a pool's workers would wait for it forever,
    idle ones too (so the watch outlives the job). Not in ``parent`` itself (a thread
    pool), nor on another host, where its pid means nothing."""
    host, pid, _ = parent
    if host != HOST or pid == os.getpid():
        return
    with _watched_lock:
        if parent not in _watched:
            _watched[parent] = set()
            threading.Thread(target=_watch, args=(parent, _watched[parent]), daemon=True,
                             name="auvsim-parent-watch").start()
        _watched[parent].add(Path(folder))


def _watch(parent: Parent, folders: set[Path]) -> None:
    _wait_for_end(*parent[1:])
    try:
        for folder in list(folders):
            sweep(folder)  # the dead parent's lock is free: the kernel dropped it first
    finally:
        os._exit(1)


def _wait_for_end(pid: int, started: str | None) -> None:
    """Return once process ``pid``, started at ``started``, has ended."""
    try:
        fd = os.pidfd_open(pid)  # Linux 5.3+: readable once the process has ended
    except (AttributeError, OSError):  # elsewhere, or it has ended already
        fd = None
    while _alive(pid, started):
        if fd is None:
            time.sleep(POLL_S)
        else:
            select.select([fd], [], [])


def _alive(pid: int, started: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # a process of another user: the start time tells
    return _start_time(pid) == started  # another start time: the pid was reused


def _start_time(pid: int) -> str | None:
    """When process ``pid`` started, in clock ticks after boot (Linux); None where there
    is no ``/proc``, and for a process that has gone or is a zombie (ended)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()  # after the command's name
    except (OSError, IndexError):
        return None
    return None if fields[0] == b"Z" else fields[19].decode()


def _progress(part: Path) -> float:
    try:
        return float(part.with_name(part.name + ".progress").read_text())
    except (OSError, ValueError):
        return 0.0

