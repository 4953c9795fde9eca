"""Jobs on a Dask cluster: ``--cluster local:N`` or a scheduler's address.

Dask distributed is the engine (optional: ``pip install 'auvsim[cluster]'``). Its
``Client.get_executor`` is a ``concurrent.futures`` executor, so the code that runs jobs
(``auvsim.runs.generate``, ``beamsnet.training.runs.train_all``) is the same for the
built-in process pool and for a cluster; this module only opens and closes the cluster.

``local:N`` starts a ``LocalCluster`` of N worker processes (nannied, so a killed worker is
restarted and its task run again) with ``THREADS`` threads each, and stops it at the end
(killing its workers if the cluster does not stop within ``CLOSE_S``);
its workers end with this process however it ends (each holds a pipe to its nanny, which
lives in this process). Any other address is a running scheduler (``tcp://host:8786``,
``dask ssh``, ``dask-jobqueue``): it must answer within ``CONNECT_TIMEOUT_S``, and its
workers are left running. Tasks are submitted with ``pure=False``: two missions that look
alike are still two tasks.
"""

from __future__ import annotations

import concurrent.futures as cf
import logging
import re
import signal
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress

from auvsim.data.files import interrupts_held
from auvsim.errors import ConfigError, SimulationError
from auvsim.processes import start_forkserver

CONNECT_TIMEOUT_S = 10.0
CLOSE_S = 30.0  # a local cluster's shutdown, client and all; past it, its workers are killed
MIN_CLOSE_S = 1.0  # the cluster's own close, however long the client's took
HANDSHAKE_S = 5.0  # beyond the connect timeout, for a peer that connects but never answers
THREADS = 2  # per local worker: two missions in flight, as the built-in pool's process
# A local cluster's settings, each measured by benchmarks/cluster.py against the built-in
# pool: Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers, and an explicit threshold
# turns off glibc's adaptive mmap threshold, so every block's arrays are mapped and
# page-faulted afresh (12 % more CPU per mission); the workers' sampling profiler and a
# 20 ms event-loop tick cost a few % more of a busy core.
LOCAL_CONFIG = {
    "distributed.nanny.pre-spawn-environ": {
        "OMP_NUM_THREADS": 1, "MKL_NUM_THREADS": 1, "OPENBLAS_NUM_THREADS": 1},
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
}
FORKED = {"distributed.worker.multiprocessing-method": "forkserver"}  # see _local
_LOCAL = re.compile(r"local:(\d+)")
_REMOTE = re.compile(r"(?:(tcp|tls|ws|wss|inproc|ucx)://)?([\w.\-\[\]:]+):(\d+)/?")
EXPECTED = "expected local:N (N worker processes here) or a scheduler's address, host:port"


def check_address(address: str) -> str:
    """``address`` if it is ``local:N`` (N >= 1) or looks like a scheduler's address.

    Raises:
        ConfigError: it is neither.
    """
    local = _LOCAL.fullmatch(address)
    if local is not None and int(local.group(1)) < 1:
        raise ConfigError(f"{address!r}: expected at least one worker (local:1 or more)",
                          argument="cluster")
    remote = None if local is not None else _REMOTE.fullmatch(address)
    if local is None and remote is None:
        raise ConfigError(f"{address!r}: not a cluster address; {EXPECTED} "
                          "(tcp://10.0.0.5:8786)", argument="cluster")
    if remote is not None:
        port = int(remote.group(3))
        if not 1 <= port <= 65535:
            raise ConfigError(f"{address!r}: port {port} is not a TCP port (1 to 65535); "
                              f"{EXPECTED}", argument="cluster")
    return address


def local_workers(address: str) -> int | None:
    """N of ``local:N``, None for a scheduler's address."""
    local = _LOCAL.fullmatch(address)
    return None if local is None else int(local.group(1))


@contextmanager
def executor(address: str, *, threads: int = THREADS,
             timeout: float | None = None) -> Iterator[cf.Executor]:
    """A ``concurrent.futures`` executor whose jobs run on the Dask cluster ``address``.

    Args:
        address: ``local:N`` or a scheduler's address (``check_address``).
        threads: threads per worker of a ``local:N`` cluster (jobs at once in each).
        timeout: seconds to wait for the scheduler (and a local cluster's workers);
            None: ``CONNECT_TIMEOUT_S``.

    Raises:
        ConfigError: the address is malformed, Dask distributed is not installed, or no
            scheduler answers there within ``timeout``.
    """
    check_address(address)
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    try:
        import dask
        import distributed
    except ImportError:
        raise ConfigError("needs Dask distributed, which is not installed: expected "
                          "pip install 'auvsim[cluster]'", argument="cluster") from None
    if local_workers(address) is None:
        client = _connect(distributed, address, timeout)
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
        return
    # For the cluster's whole life: a worker its nanny restarts is made as the first were.
    with dask.config.set({**LOCAL_CONFIG, **FORKED}):
        client, cluster = _local(distributed, local_workers(address), threads, timeout)
        try:
            yield client.get_executor(pure=False)
        finally:
            _stop_local(client, cluster)


def _stop_local(client, cluster) -> None:
    """Close the client and the local cluster, both within ``CLOSE_S``; if the cluster does
    not close in time, kill its worker processes: a worker busy in a job (or starved of CPU)
    that does not answer its nanny in time must neither hold up the end of the run nor
    outlive it. The workers are known as processes (``psutil``, which refuses a pid that a
    new process has taken since), not as bare pids. A Ctrl-C or SIGTERM meanwhile is held
    and delivered once the cluster has gone: one that broke into the close would leave the
    cluster half closed, for Dask's exit hook to wait on and its workers to outlive."""
    import psutil  # Dask distributed's own dependency

    workers = []
    for worker in cluster.workers.values():
        with suppress(psutil.Error, TypeError):  # ended, or never started
            workers.append(psutil.Process(worker.pid))
    deadline = time.monotonic() + CLOSE_S
    with interrupts_held():
        with suppress(TimeoutError, OSError):  # the cluster is what holds the workers
            client.close(timeout=CLOSE_S)
        try:
            cluster.close(timeout=max(deadline - time.monotonic(), MIN_CLOSE_S))
        except (TimeoutError, OSError):
            for process in workers:
                with suppress(psutil.Error):  # ended meanwhile
                    process.kill()


def _local(distributed, n: int, threads: int, timeout: float):
    """A client of a new ``LocalCluster`` of ``n`` workers, and the cluster, under
    ``LOCAL_CONFIG`` and ``FORKED`` (the caller's ``dask.config.set``).

    Its workers never see SIGINT, which a terminal sends to the whole process group: this
    process stops them. They fork from the forkserver (``start_forkserver``; restarted
    ones too), so they ignore it from their start, where spawned ones would stop in their
    imports with a traceback each, and they have its one thread per numerical library
    (the nanny's environment reaches a spawned worker only); ``_IgnoreSigint`` tells
    every worker as well. A Ctrl-C or SIGTERM to this process while the cluster starts is
    held (a cluster stopped half-started would leave its workers), and stops it once
    started.
    """
    cluster = None
    start_forkserver(["distributed"])
    try:
        with interrupts_held():
            # ":0": the scheduler's HTTP server (and dashboard) on any free port; the
            # workers' logs silenced (a failed task is this process's error to report).
            cluster = distributed.LocalCluster(
                n_workers=n, threads_per_worker=threads, processes=True,
                dashboard_address=":0", silence_logs=logging.CRITICAL)
            client = distributed.Client(cluster, timeout=timeout)
            client.register_plugin(_ignore_sigint(distributed)())
        return client, cluster
    except BaseException:
        if cluster is not None:
            cluster.close()
        raise


def _ignore_sigint(distributed):
    class _IgnoreSigint(distributed.WorkerPlugin):
        """Every worker of a local cluster, restarted ones too, ignores SIGINT."""

        def setup(self, worker) -> None:
            if threading.current_thread() is threading.main_thread():
                signal.signal(signal.SIGINT, signal.SIG_IGN)

    return _IgnoreSigint


def _connect(distributed, address: str, timeout: float):
    """A client of the scheduler at ``address``, within ``timeout`` s (a bit more for the
    handshake): Dask's own timeout does not bound a peer that accepts the connection and
    never answers, so the client is made in a thread that is given up on at the deadline.

    Raises:
        ConfigError: nothing answered there as a Dask scheduler in time.
    """
    _refused_at_once(address)
    made: dict = {}

    def connect() -> None:
        try:
            made["client"] = distributed.Client(address, timeout=timeout)
        except Exception as e:  # whatever it is, there is no scheduler to use there
            made["error"] = e

    thread = threading.Thread(target=connect, daemon=True, name="auvsim-connect")
    thread.start()
    thread.join(timeout + HANDSHAKE_S)
    if "client" in made:
        return made["client"]
    error = made.get("error")
    reason = ("it accepted the connection but never answered as a Dask scheduler"
              if error is None else " ".join(str(error).split()) or type(error).__name__)
    if error is not None and not isinstance(error, (OSError, TimeoutError)):
        # A peer answered, in another protocol: its bytes read as no Dask message (an
        # HTTP server's as a 3 EiB frame, say), so what the reading made of them (a
        # MemoryError, "Unable to allocate 3.07 EiB ...") says nothing of the peer.
        raise ConfigError(f"{address!r}: something answered there, but its reply read as "
                          f"no Dask message; {EXPECTED} (a scheduler listens on 8786 by "
                          "default, its dashboard on 8787)", argument="cluster")
    raise ConfigError(f"{address!r}: no Dask scheduler answered within {timeout:g} s "
                      f"({reason[:200]}); {EXPECTED}", argument="cluster")


def _refused_at_once(address: str) -> None:
    """Refuse a TCP address whose host refuses the connection: Dask's client retries it
    until its timeout (10 s), where the host has said at once that nothing listens there.
    Any other outcome (accepted, no answer, unreachable) is left to the client."""
    remote = _REMOTE.fullmatch(address)  # checked by check_address
    if remote is None or remote[1] in ("inproc", "ucx"):
        return
    try:
        with socket.create_connection((remote[2].strip("[]"), int(remote[3])), timeout=1.0):
            return
    except ConnectionRefusedError:
        raise ConfigError(f"{address!r}: nothing listens there (the connection was "
                          f"refused); {EXPECTED} (a scheduler listens on 8786 by default)",
                          argument="cluster") from None
    except (OSError, ValueError):
        return


def lost_worker(error: BaseException) -> SimulationError | None:
    """The one-line error for a job whose workers kept dying (Dask gave up on it after
    ``distributed.scheduler.allowed-failures`` tries), None for any other error."""
    if type(error).__name__ != "KilledWorker":
        return None
    return SimulationError("a job's worker process ended abruptly on every try (killed, or "
                           "out of memory?): expected the job to finish on one of them")
