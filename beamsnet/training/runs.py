"""Running many trainings: jobs in parallel processes or on a Dask cluster
(``train_all``), the seeds of one config (``seed_runs``), and the random-restart remedy
of ``beamsnet.training.train``'s docstring: train several seeds and keep the one whose
final weights fit the training split best (``keep_best``, ``train_best``).
"""

from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import filecmp
import functools
import json
import math
import multiprocessing
import os
import shutil
import threading
from collections.abc import Mapping
from pathlib import Path

from tqdm import tqdm

from auvsim.data.files import check_out_dir, finished, staged_dir, sweep, write_text
from auvsim.errors import ConfigError, SimulationError
from auvsim.processes import end_with, start_forkserver, this_process
from auvsim.runs.cluster import check_address, executor, local_workers, lost_worker
from beamsnet.training.checkpoints import load
from beamsnet.training.config import TrainConfig, check_restarts
from beamsnet.training.train import DivergedError, train


def train_all(jobs: list[tuple[str | Path, TrainConfig, str | Path]], *,
              workers: int | None = None, progress: bool = True,
              diverged: str = "raise", cluster: str | None = None) -> list[dict]:
    """Run ``train(dataset, config, out)`` for every job, in parallel processes, or as
    tasks on a Dask cluster.

    Every job trains with the same torch threads wherever it runs (``train``: one,
    ``beamsnet.estimators.networks.TRAINING_THREADS``), so it gives the same weights here,
    in a pool of any size and on a cluster: small batches parallelise across runs, not
    within one.

    Args:
        jobs: (dataset, config, out) triples. On a cluster every path must be one the
            workers see (a shared folder), and means the same file there.
        workers: processes (default: as many as cores, at most one per job); unused on a
            cluster, whose workers each take one job at a time.
        progress: a progress bar over the jobs' epochs (over steps when there is one
            process here; over jobs on a cluster).
        diverged: ``"raise"``: a job whose loss became non-finite stops the others, as
            any error does; ``"record"``: its summary is ``{"diverged": why,
            "final_train_loss": nan}`` and the others go on (restarts: a seed that
            diverged is dropped, the others are compared).
        cluster: run the jobs on this Dask cluster (``auvsim.runs.cluster``: ``local:N`` or a
            scheduler's address), one at a time per worker process.

    Returns:
        The summaries of ``train``, in job order.

    Raises:
        ConfigError: a bad ``diverged`` or ``cluster``, or no scheduler answers there.
        SimulationError: a job's worker process kept dying (Dask gave up on it).
    """
    if diverged not in ("raise", "record"):
        raise ConfigError(f": expected 'raise' or 'record', got {diverged!r}",
                          argument="diverged")
    if cluster is not None:
        check_address(cluster)
    if not jobs:
        return []
    job = functools.partial(_job, record=diverged == "record")
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs)))
    if workers == 1 and cluster is None:
        done = []
        for d, c, o in jobs:
            done.append(job(d, c, o, progress=progress))
            finished(o)
        return done
    epochs = None  # each local worker's epochs, as they end (a cluster's: its jobs)
    if cluster is None:
        context = multiprocessing.get_context("forkserver")
        # Its workers fork from a server that has imported torch and beamsnet once (about
        # 3 s each), unless a pool of this process started the server before; a server
        # deaf to Ctrl-C and SIGTERM, as every pool's and cluster's of auvsim: this
        # process hears them and stops the workers (``_stop_workers``).
        start_forkserver(["beamsnet.training.runs"])
        epochs = context.SimpleQueue()
        # Each worker ends with this process, even one killed with -9 (``end_with``).
        runner = cf.ProcessPoolExecutor(workers, mp_context=context, initializer=_worker,
                                        initargs=(this_process(), epochs))
        total, unit = sum(c.epochs for _, c, _ in jobs), " epochs"
    else:
        runner = executor(cluster, threads=1)
        if local_workers(cluster) is None:  # a scheduler's workers have their own cwd
            jobs = [(Path(d).absolute(), c, Path(o).absolute()) for d, c, o in jobs]
        total, unit = len(jobs), " models"
    with runner as pool, tqdm(total=total, disable=None if progress else True,
                              leave=False, unit=unit, desc="training") as bar:
        futures = {pool.submit(job, d, c, o, progress=False): o
                   for d, c, o in jobs}
        try:
            pending = set(futures)
            while pending:
                done, pending = cf.wait(pending, timeout=0.5,
                                        return_when=cf.FIRST_COMPLETED)
                while epochs is not None and not epochs.empty():
                    bar.update(epochs.get())
                for future in done:
                    future.result()  # the first error stops here, naming what went wrong
                    finished(futures[future])  # whole, and kept for the next run
                    if epochs is None:
                        bar.update()
        except BaseException as e:
            for future in futures:
                future.cancel()  # the jobs not started yet; the running ones finish
            if isinstance(e, KeyboardInterrupt) and cluster is None:
                _stop_workers(pool)  # Ctrl-C or SIGTERM: no job of the run is wanted now
                for out in futures.values():  # the killed jobs' staged run folders
                    sweep(Path(out).parent)
            lost = lost_worker(e)
            if lost is not None:  # Dask's KilledWorker: its traceback would say no more
                raise lost from None
            if isinstance(e, cf.CancelledError):
                raise SimulationError("the cluster cancelled a training job (its scheduler "
                                      "restarted, or lost this client?): expected it to run "
                                      "every job") from None
            raise
        return [f.result() for f in futures]


def _stop_workers(pool: cf.ProcessPoolExecutor) -> None:
    """End a local pool's workers now, with SIGKILL: they ignore Ctrl-C and SIGTERM
    (``start_forkserver``), and the pool would otherwise wait minutes for its running jobs
    before this process could exit. Returns once they have gone, so the claims of the
    run folders they staged can be swept."""
    workers = list((getattr(pool, "_processes", None) or {}).values())  # the pool's record
    kill = getattr(pool, "kill_workers", None)  # Python 3.14+
    if kill is not None:
        kill()
    else:
        for process in workers:
            process.kill()
        pool.shutdown(wait=False, cancel_futures=True)
    for process in workers:
        process.join(timeout=5.0)


_epochs = None  # a local pool worker's queue to its parent's progress bar (``_worker``)


def _worker(parent, epochs) -> None:
    """A local training pool's initializer: end with the parent (``end_with``), and
    report each epoch that ends into ``epochs`` (a queue the parent's bar reads).

    tqdm's lock here is a thread lock: its default, a multiprocessing lock, is a named
    semaphore in a forkserver child, which a worker ended by Ctrl-C or by the parent
    (``_stop_workers``) never unlinks, and the resource tracker then warned of "leaked
    semaphore objects" after the one-line interrupt. A worker draws no bar of its own."""
    global _epochs
    end_with(parent)
    tqdm.set_lock(threading.RLock())
    _epochs = epochs


def _job(dataset: str | Path, config: TrainConfig, out: str | Path, *, progress: bool,
         record: bool) -> dict:
    """One job of ``train_all`` (module level, so worker processes can run it)."""
    queue = _epochs
    told = {} if queue is None else {"on_epoch": lambda: queue.put(1)}
    try:
        return train(dataset, config, out, progress=progress, **told)
    except DivergedError as e:
        if not record:
            raise
        return dict(diverged=str(e), final_train_loss=math.nan)


def keep_best(runs: list[str | Path], out: str | Path, *,
              diverged: Mapping[str | Path, str] | None = None) -> dict:
    """Copy the run whose final weights fit their training split best into ``out`` and
    write ``out/restarts.json`` with every run's final training loss.

    A file already equal to the kept one is left as it is, so that a report that reuses
    its runs does not rewrite them.

    Args:
        runs: run directories.
        out: where the kept run is copied.
        diverged: runs of ``runs`` whose training diverged (they have no checkpoint), with
            the reason; they are recorded, never kept.

    Returns:
        ``{"kept": run, "losses": {run: loss}, "diverged": {run: why}}``.

    Raises:
        DivergedError: every run diverged.
    """
    diverged = {str(r): why for r, why in (diverged or {}).items()}
    losses = {str(r): math.nan if str(r) in diverged else load(r)[1]["final_train_loss"]
              for r in runs}
    finite = {r: loss for r, loss in losses.items() if math.isfinite(loss)}
    if not finite:
        raise DivergedError(f": every run diverged (training loss not finite): "
                            f"{', '.join(losses)}; expected at least one to train, with a "
                            "smaller learning rate", argument="lr")
    kept = Path(min(finite, key=finite.get))
    out = Path(out)
    record = dict(kept=str(kept), losses=losses, diverged=diverged,
                  rule="lowest final MSE on the training split (evaluation mode)")
    with staged_dir(out) as stage:  # every file of the kept run, or none
        for name in ("model.pt", "history.json", "losses.png"):
            if (out / name).is_file() and filecmp.cmp(kept / name, out / name, shallow=False):
                continue
            shutil.copyfile(kept / name, stage / name)
        write_text(stage / "restarts.json", json.dumps(record, indent=1))
    return record




def seed_runs(config: TrainConfig, out: str | Path,
              restarts: int) -> list[tuple[TrainConfig, Path]]:
    """The restarts of ``config``: seeds ``config.seed .. config.seed + restarts - 1``,
    each with its run directory ``out/seed_<s>``."""
    check_restarts(restarts)
    seeds = range(config.seed, config.seed + restarts)
    return [(dataclasses.replace(config, seed=s), Path(out) / f"seed_{s}") for s in seeds]


def train_best(dataset: str | Path, config: TrainConfig, out: str | Path, *,
               restarts: int = 3, workers: int | None = None, progress: bool = True,
               cluster: str | None = None) -> dict:
    """Train the ``seed_runs`` of ``config`` and keep the best on the training split in
    ``out`` (see the module docstring). A seed that diverges is recorded and dropped.
    ``workers``, ``progress`` and ``cluster`` are ``train_all``'s.

    Returns:
        ``keep_best``'s record plus the kept run's ``train`` summary.

    Raises:
        DivergedError: every seed diverged (and what ``train`` raises for bad input).
    """
    check_out_dir(out)
    pairs = seed_runs(config, out, restarts)
    fresh = not Path(out).exists()
    try:
        summaries = train_all([(dataset, c, r) for c, r in pairs], workers=workers,
                              progress=progress, diverged="record", cluster=cluster)
        runs = [r for _, r in pairs]
        record = keep_best(runs, out, diverged={r: s["diverged"] for r, s in
                                                zip(runs, summaries, strict=True)
                                                if "diverged" in s})
    except BaseException:
        if fresh:  # the seeds that did train are no run without the kept copy: none left
            shutil.rmtree(out, ignore_errors=True)
        raise
    return {**record, **summaries[[str(r) for r in runs].index(record["kept"])],
            "checkpoint": str(Path(out) / "model.pt"), "plot": str(Path(out) / "losses.png")}


