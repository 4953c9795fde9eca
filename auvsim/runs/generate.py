"""``auvsim generate``: simulate the missions of a config into a dataset: one file, or a
folder of shards and their index.

Orchestration only: each mission is an ``auvsim.runs.mission.MissionRun`` streamed into a
file. With one worker the missions run in this process, two at a time on threads,
straight into the output; with more (or with an executor or a Dask cluster given), each
runs as a job of a ``concurrent.futures`` executor into a part file of its own, and the
dataset is then assembled in mission order by copying those missions
(``auvsim.data.writer.copy_mission``). A sharded dataset needs no copy: each job writes its
shard into the output folder, sealed with its config's hash and its data's digest, and
the index is written last (``auvsim.data.shards.write_index``); running again keeps the
shards that are whole and this config's (resume). So memory stays flat in mission
length, and the output is the same whatever the number of workers.

Jobs talk back through a folder of the run's in the output folder, which works with any
executor whose workers share this file system: each job writes the simulated seconds it
has done to a ``.progress`` file after every block, and stops at its next block once the
folder holds ``STOP`` (the first error, Ctrl-C or SIGTERM in this process) or has gone.
This process then waits for them, so nothing is left behind.

A killed parent (``kill -9``) cannot write ``STOP``: each job's process watches it instead
(``auvsim.processes.end_with``) and ends at once when it has gone, first removing the
run's temporaries (``auvsim.data.files.sweep``); the forkserver ends with its last
client, a ``local:N`` cluster's workers with their nannies (``auvsim.runs.cluster``). The
default pool's forkserver, and so its workers, ignore SIGINT and SIGTERM, which a terminal or a
scheduler sends to the whole process group: only this process acts on them, stopping its
jobs through ``STOP``, and no worker prints a traceback.
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import fcntl
import hashlib
import multiprocessing
import os
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, suppress
from pathlib import Path

from tqdm import tqdm

from auvsim import __version__
from auvsim.config import Config
from auvsim.data.files import (
    HOST,
    Claim,
    check_out_dir,
    commit,
    dropped,
    finished,
    interrupts_held,
    make_out_dir,
    names_folder,
    sweep,
    writing,
)
from auvsim.data.reader import Block
from auvsim.data.schema import INDEX, SHARDS, Shard
from auvsim.data.shards import shard_state, write_index
from auvsim.data.writer import (
    DatasetWriter,
    check_output_path,
    copy_mission,
    foreign_hdf5,
)
from auvsim.errors import ConfigError, SimulationError
from auvsim.physics.vehicle import model_path
from auvsim.processes import (
    Parent,
    end_with,
    refuse_while_bootstrapping,
    start_forkserver,
    this_process,
)
from auvsim.runs.cluster import check_address, lost_worker
from auvsim.runs.mission import MissionRun, check_reachable
from auvsim.world.grid import pin_grid

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
    _check_run_folder(part.parent)
    if parent is not None:
        end_with(parent, part.parent.parent)
    report = _reporter(part.with_name(part.name + ".progress"))
    with DatasetWriter(part, config_json="", compression=config.compression,
                       exclusive=False) as writer:
        _stream_mission(config, index, writer, report=report,
                        stop=lambda: (part.parent / "STOP").exists() or not part.parent.is_dir())


def write_shard(config: Config, indices: Sequence[int], path: str, folder: str,
                parent: Parent | None = None) -> Shard:
    """A job: simulate missions ``indices`` into the shard file ``path`` of a sharded
    dataset, sealed with its config's hash and its data's digest (``DatasetWriter.seal``).

    The shard is renamed into place only when whole, so one that exists is complete.
    Progress goes to ``<folder>/<shard>.progress`` after each block; the job stops
    (``Cancelled``) at its next block once ``folder`` (the run's, in the output folder)
    holds ``STOP`` or has gone, and its process ends once ``parent`` has.
    """
    part, run = Path(path), Path(folder)
    _check_run_folder(run)
    if parent is not None:
        end_with(parent, part.parent)
    sub = shard_config(config, indices)
    report = _reporter(run / f"{part.stem}.progress")
    # Not exclusive: a cancelled job of this run (a straggler after a Ctrl-C, on a
    # cluster's host) may still be writing the shard its retry writes, the same data.
    with DatasetWriter(part, config_json=sub.to_json(), compression=config.compression,
                       exclusive=False) as w:
        for i in indices:
            _stream_mission(config, i, w,
                            stop=lambda: (run / "STOP").exists() or not run.is_dir(),
                            report=report)
        sha = config_sha256(sub)
        digest = w.seal(sha)
    return Shard(part.name, tuple(m.name for m in sub.missions), sha, digest)


def _check_run_folder(folder: Path) -> None:
    """A job starts only while its run's folder is there: one that is not was removed at
    the end of its run (a task that started late) or is not on this worker's storage."""
    if not folder.is_dir():
        raise ConfigError(f"{str(folder)!r}: the run's folder is not there on {HOST}: "
                          "expected the output on storage that every worker reaches at the "
                          "same path", argument="out")


def shard_config(config: Config, indices: Sequence[int]) -> Config:
    """The config of one shard: ``config`` with only the missions ``indices`` (each
    mission depends on the config and its own settings, not on the others)."""
    return dataclasses.replace(config, missions=tuple(config.missions[i] for i in indices))


def config_sha256(config: Config) -> str:
    """SHA-256 of what makes a shard's data: the config, the vehicle's model file and the
    heightmap's (the config holds only their paths), and this auvsim's version."""
    digest = hashlib.sha256(f"{__version__}\n{config.to_json()}".encode())
    files = [model_path(config.vehicle.model)]
    if config.seafloor.kind == "heightmap":
        files.append(Path(config.seafloor.heightmap))
    for file in files:
        digest.update(file.read_bytes())
    return digest.hexdigest()


def shard_plan(config: Config, per_shard: int) -> list[tuple[str, list[int]]]:
    """The shards of a sharded dataset: file names and the missions each holds, in order."""
    n = len(config.missions)
    return [(f"part-{k:05d}.h5", list(range(start, min(start + per_shard, n))))
            for k, start in enumerate(range(0, n, per_shard))]


def default_workers(missions: int) -> int:
    """One worker process per two cores, at most one per mission group: a process keeps two
    missions in flight, whose physics threads release the GIL, which about fills two cores
    (measured by benchmarks/datasets.py; separate processes per mission cost more in start
    up and in copying their files together than they gain)."""
    return max(1, min(-(-missions // MISSIONS_IN_FLIGHT), (os.cpu_count() or 1) // 2))


def generate(config: Config, out: str | os.PathLike, *, workers: int | None = None,
             executor: cf.Executor | None = None, cluster: str | None = None,
             shards: int | None = None, progress: bool = True) -> dict:
    """Simulate every mission of ``config`` into the dataset ``out``.

    Args:
        config: what to simulate (a ``Config``).
        out: the HDF5 file to write (replaced only once it is complete), or a folder (a
            path ending in a separator) for a sharded dataset.
        workers: worker processes (default ``default_workers``); with 1 the missions run
            in this process, ``MISSIONS_IN_FLIGHT`` at a time on threads, and stream
            straight into ``out``.
        executor: any ``concurrent.futures`` executor to run the missions' jobs
            (``write_mission``, ``write_shard``) instead of the default process pool;
            its workers must see this file system, and those on this host end once this
            process has.
        cluster: run the jobs on this Dask cluster instead (``auvsim.runs.cluster``):
            ``local:N`` or a scheduler's address; the output must be on storage that
            every worker reaches.
        shards: missions per shard of a sharded dataset in the folder ``out``: one HDF5
            file per shard in ``out/shards/`` and an index ``out/index.h5`` that reads as
            one dataset (``auvsim.data.shards.write_index``). Default 1 when ``out`` names a
            folder; one file otherwise. Running again into the same folder keeps every
            shard that is complete and holds this config's data (its config hash and data
            digest say so) and makes the others.
        progress: show a progress bar on a terminal.

    Returns:
        A summary: number of missions, seconds simulated by this run (not a kept
        shard's), wall seconds, the seconds this process spent compiling the physics
        (``compile_s``: a first run's, 0 once numba's cache has it); for a sharded dataset
        also its shards and how many were kept from an earlier run.
    """
    if not isinstance(config, Config):  # a preset's name, say: one line, not deep inside
        raise ConfigError(f"config: expected an auvsim Config (auvsim.preset(NAME), "
                          f"auvsim.load_config(FILE), or Config(...)), got "
                          f"{type(config).__name__} {config!r}")
    refuse_while_bootstrapping("generate() was called")  # before it claims ``out``
    with _compile_clock() as compiling:
        summary = _generate(config, out, workers=workers, executor=executor,
                            cluster=cluster, shards=shards, progress=progress)
    return dict(summary, compile_s=compiling())


@contextmanager
def _compile_clock() -> Iterator[Callable[[], float]]:
    """Seconds numba spends compiling in this process while the block runs (loading what
    its cache holds is not compiling): what a first run costs and later runs do not. The
    missions of worker processes compile there, unseen here."""
    from numba.core import event

    listener = event.TimingListener()  # nested compilations counted once
    with event.install_listener("numba:compile", listener):
        yield lambda: listener.duration if listener.done else 0.0


def _generate(config: Config, out: str | os.PathLike, *, workers: int | None,
              executor: cf.Executor | None, cluster: str | None, shards: int | None,
              progress: bool) -> dict:
    sharded = shards is not None or names_folder(out)
    if sharded and Path(out).suffix in (".h5", ".hdf5"):
        raise ConfigError(f"{os.fspath(out)!r}: a sharded dataset is a folder: expected a "
                          "folder name (datasets/rm/), or a file name without --shards",
                          argument="out")
    if not sharded:  # a user's other file is refused, never replaced, as on the command line
        check_output_path(out, hint=f" (or {os.path.join(out, '')!r}, with a trailing /, "
                          "for a sharded dataset)")
    config = pin_grid(config)  # the stored config names a grid by its SHA-256 too
    with interrupts_held():  # its first compiled calls would swallow a KeyboardInterrupt
        check_reachable(config)
    for name, value in (("workers", workers), ("shards", shards)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int)
                                  or value < 1):
            raise ConfigError(f": expected a whole number >= 1, got {value!r}", argument=name)
    if cluster is not None:
        check_address(cluster)
        for name, given in (("executor", executor), ("workers", workers)):
            if given is not None:
                raise ConfigError(": given with a cluster, whose own workers run the "
                                  "jobs; expected one or the other", argument=name)
    out = Path(out).absolute()  # a worker's working folder is not this process's
    workers = min(workers or default_workers(len(config.missions)), len(config.missions))
    started = time.perf_counter()
    simulated = sum(m.scenario.duration for m in config.missions)
    summary: dict = dict(missions=len(config.missions), simulated_s=simulated)
    with tqdm(total=round(simulated), unit=" sim s", disable=None if progress else True,
              leave=False) as bar:
        if sharded:
            summary.update(_sharded(config, out, shards or 1, workers, executor, cluster,
                                    bar))
        elif workers == 1 and executor is None and cluster is None:
            with DatasetWriter(out, config_json=config.to_json(),
                               compression=config.compression) as ds:
                _in_threads(config, ds, lambda seconds: bar.update(round(seconds)))
        else:
            with _jobs_executor(executor, cluster) as jobs, \
                    DatasetWriter(out, config_json=config.to_json(),
                                  compression=config.compression) as ds:
                _in_jobs(config, ds, workers, jobs, bar, watch=cluster is None)
    return dict(summary, wall_s=time.perf_counter() - started)


@contextmanager
def _jobs_executor(executor: cf.Executor | None, cluster: str | None
                   ) -> Iterator[cf.Executor | None]:
    """The executor given, one on the Dask cluster ``cluster``, or None (the default
    process pool)."""
    if cluster is None:
        yield executor
        return
    from auvsim.runs.cluster import executor as cluster_executor

    with cluster_executor(cluster) as dask_executor:
        yield dask_executor


def _sharded(config: Config, folder: Path, per_shard: int, workers: int,
             executor: cf.Executor | None, cluster: str | None, bar) -> dict:
    """Write (or finish) the sharded dataset ``folder``: keep each shard that is already
    complete and this config's, make the others as jobs, then write the index (the old
    one stays until the first shard is to be made, so a check that is cut short leaves a
    complete dataset as it was), and remove the shards of an earlier plan. A cluster is
    stopped before the run's folder goes, so no worker writes into it as it does."""
    folder = check_out_dir(folder)
    plan = shard_plan(config, per_shard)
    index = folder / INDEX
    for path, what in ((index, "the index file"), (folder / SHARDS, "the shards' folder")):
        if path.exists() and path.is_dir() != (path.name == SHARDS):
            kind = "a folder" if path.is_dir() else "a file"
            raise ConfigError(f"{str(path)!r} is {kind}: expected {what} of a sharded "
                              "dataset there (or nothing); move it aside", argument="out")
    if index.is_file() and foreign_hdf5(index):
        raise ConfigError(f"{str(index)!r}: an HDF5 file that is not an auvsim index is "
                          "there (another program's); expected a new folder, or a sharded "
                          "dataset's to write again", argument="out")
    fresh = not folder.exists()
    make_out_dir(folder / SHARDS, whole=False)  # each shard is whole on its own
    # The temporaries of runs that were killed (kill -9, a lost node) go before any work.
    for place in (folder, folder / SHARDS):
        sweep(place)
    try:
        with _only_writer(folder), _claimed(index) as claim:
            shards: list[Shard | None] = []
            for name, indices in plan:
                shards.append(shard_state(folder / SHARDS / name,
                                          config_sha256(shard_config(config, indices))))
                if shards[-1] is not None:
                    bar.update(round(sum(config.missions[i].scenario.duration
                                         for i in indices)))
            todo = [k for k, shard in enumerate(shards) if shard is None]
            if todo:
                with _jobs_executor(executor, cluster) as given:
                    if index.exists():  # it would list shards about to change
                        index.unlink()
                        dropped(index)  # said if the run is stopped: the folder is no
                        # dataset until it is run again
                    claim.folder.mkdir()
                    parent = None if cluster is not None else this_process()
                    jobs = [(write_shard, (config, plan[k][1],
                                           str(folder / SHARDS / plan[k][0]),
                                           str(claim.folder), parent)) for k in todo]
                    progress = [claim.folder / f"{Path(plan[k][0]).stem}.progress"
                                for k in todo]
                    pool = given or (
                        ThreadPoolExecutor(MISSIONS_IN_FLIGHT) if workers == 1 else
                        _process_pool(workers, this_process(), folder / SHARDS))
                    try:
                        _run_jobs(pool, jobs, claim.folder, progress, bar,
                                  lambda j, shard: shards.__setitem__(todo[j], shard))
                    finally:
                        if given is None:
                            pool.shutdown(wait=True)
                sweep(folder / SHARDS)  # the temporaries of workers that were killed
            with writing(index):
                write_index(claim.file, shards, config_json=config.to_json())
                commit(claim.file, index)
    except BaseException:
        if fresh:  # a run refused or stopped before its first shard leaves no folder
            for made in (folder / SHARDS, folder):
                with suppress(OSError):
                    made.rmdir()
        # A shard is renamed into place only when whole, and kept for the same command
        # to finish the dataset: a run that stops names those there among what it leaves.
        for name, _ in plan:
            if (folder / SHARDS / name).is_file():
                finished(folder / SHARDS / name)
        raise
    planned = {name for name, _ in plan}
    for stale in (folder / SHARDS).glob("part-*.h5"):
        if stale.name not in planned and not foreign_hdf5(stale):  # a shard, not a user's
            stale.unlink()
    return dict(out=str(index), shards=len(plan), kept=len(plan) - len(todo),
                simulated_s=sum(config.missions[i].scenario.duration
                                for k in todo for i in plan[k][1]))


@contextmanager
def _only_writer(folder: Path) -> Iterator[None]:
    """Hold the sharded dataset ``folder`` for this run: a second run into it at the same
    time is refused (an flock on the folder itself, which the kernel drops with its owner
    however it ends)."""
    fd = os.open(folder, os.O_RDONLY | os.O_CLOEXEC)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ConfigError(f"{str(folder)!r}: another auvsim generate is writing this "
                              "dataset: expected one run at a time into a folder",
                              argument="out") from None
        except OSError:  # a file system without flock (Lustre, say): not guarded then
            pass
        yield
    finally:
        os.close(fd)


@contextmanager
def _claimed(index: Path) -> Iterator[Claim]:
    """The claim on a sharded dataset's index, or one line if its folder is read-only."""
    try:
        claim = Claim(index)
    except OSError as e:
        raise ConfigError(f"{str(index.parent)!r}: cannot write there ({e.strerror or e}); "
                          "expected a writable folder", argument="out") from None
    with claim:
        yield claim


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
             executor: cf.Executor | None, bar, *, watch: bool = True) -> None:
    """Run the missions as jobs, each into a part file of its own, and copy each into
    ``ds`` in mission order as soon as it and those before it are done. ``watch``: the
    jobs' processes end with this one (not on a cluster, whose workers are its own)."""
    parts = ds.claim.folder  # named and locked with the output's temporary file
    parts.mkdir()
    parent = this_process() if watch else None
    paths = [parts / f"{i}.h5" for i in range(len(config.missions))]

    def copy(i: int, result: None) -> None:
        copy_mission(paths[i], config.missions[i].name, ds)
        paths[i].unlink()

    pool = None
    try:
        if executor is None:
            with interrupts_held():
                executor = pool = _process_pool(workers, this_process(), ds.path.parent)
        _run_jobs(executor, [(write_mission, (config, i, str(path), parent))
                             for i, path in enumerate(paths)],
                  parts, [p.with_name(p.name + ".progress") for p in paths], bar, copy)
    finally:
        if pool is not None:
            pool.shutdown(wait=True)


def _run_jobs(executor: cf.Executor, jobs: Sequence[tuple[Callable, tuple]], folder: Path,
              progress: Sequence[Path], bar, done: Callable[[int, object], None]) -> None:
    """Submit ``jobs`` (function, arguments) to ``executor`` and hand each result to
    ``done`` in job order, as soon as it and those before it have finished; the progress
    files the jobs write move ``bar``. The first error is raised at once; then (or on an
    interrupt) ``folder/STOP`` stops the running jobs at their next block and the others
    are cancelled. This returns once the executor's futures are done: a pool's jobs have
    ended then; a Dask task that was running ends at its next block, when it sees
    ``STOP`` or that ``folder`` has gone (a ``local:N`` cluster is stopped anyway)."""
    reported = [0.0] * len(jobs)
    futures: list[cf.Future] = []
    try:
        with interrupts_held():
            for fn, args in jobs:
                futures.append(executor.submit(fn, *args))
        finished = 0
        while finished < len(futures):
            ready, _ = cf.wait(futures[finished:], timeout=POLL_S,
                               return_when=cf.FIRST_EXCEPTION)
            for future in ready:
                _raise_error_of(future)
            for i, path in enumerate(progress):
                seconds = _progress(path)
                bar.update(round(seconds) - round(reported[i]))
                reported[i] = max(reported[i], seconds)
            while finished < len(futures) and futures[finished].done():
                done(finished, futures[finished].result())
                finished += 1
    finally:
        (folder / "STOP").touch()  # jobs still running stop at their next block
        for future in futures:
            future.cancel()  # those not started (on a cluster: its tasks, all of them)
        cf.wait(futures)


def _raise_error_of(future: cf.Future) -> None:
    """A job's error, raised here as soon as it happens; a lost worker in one line."""
    try:
        future.result()
    except BrokenProcessPool:  # a traceback would say no more
        raise SimulationError("a worker process ended abruptly (killed, out of memory, or it "
                              "failed as it started: its error is printed above): expected "
                              "it to finish its missions") from None
    except cf.CancelledError:
        raise SimulationError("the cluster cancelled a job (its scheduler restarted, or lost "
                              "this client?): expected it to run every job") from None
    except Exception as e:
        lost = lost_worker(e)
        if lost is not None:
            raise lost from None
        raise


def _reporter(progress: Path) -> Callable[[float], None]:
    """A job's ``report``: the simulated seconds done so far, written to ``progress``."""
    done = 0.0

    def report(seconds: float) -> None:
        nonlocal done
        done += seconds
        tmp = progress.with_name(progress.name + ".tmp")
        tmp.write_text(f"{done:.6f}")
        tmp.replace(progress)

    return report


def _process_pool(workers: int, parent: Parent, folder: Path) -> cf.ProcessPoolExecutor:
    """The default pool: forkserver workers, which fork from a server that has imported
    auvsim (numba, MuJoCo) once, so they start in milliseconds, without inheriting this
    process's threads. Each watches this process from its start (``end_with``), so an
    idle one also ends with it."""
    start_forkserver(["auvsim.runs.generate"])
    return cf.ProcessPoolExecutor(max_workers=workers,
                                  mp_context=multiprocessing.get_context("forkserver"),
                                  initializer=end_with, initargs=(parent, folder))


def _progress(path: Path) -> float:
    """The simulated seconds a job has written to its progress file ``path`` so far."""
    try:
        return float(path.read_text())
    except (OSError, ValueError):
        return 0.0

