"""The processes auvsim starts, and how they end: the forkserver every local pool and
``local:N`` cluster forks its workers from (deaf to Ctrl-C and SIGTERM, one thread per
numerical library), and the watch by which a worker ends as soon as the process that
started it has, however that ended (``kill -9`` too), first sweeping the run's
temporaries. Stopping workers on an interrupt is their parent's job: it hears the
interrupt, the workers do not."""

from __future__ import annotations

import multiprocessing
import multiprocessing.forkserver
import os
import select
import signal
import threading
import time
from pathlib import Path

from auvsim.data.files import HOST, interrupt_handler, sweep

Parent = tuple[str, int, str | None]  # host, pid, start time (``this_process``)
POLL_S = 0.5  # how often a worker looks at its parent where there is no pidfd, s


# The numerical libraries' threads in a forked worker: one, as the workers are one
# process per core (a library reads them as it loads, in the forkserver).
ONE_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def refuse_while_bootstrapping(what: str) -> None:
    """Raise, saying ``what`` happened, if this process is a worker still importing its
    parent's main script (as multiprocessing's forkserver and spawn start one): a script
    that does ``what`` at its top level, not under ``if __name__ == "__main__":``, would
    otherwise do it again in every worker, which then fails on something further away
    (the output another run holds) or starts workers of its own. multiprocessing's own
    check (``spawn._check_not_importing_main``) reads the same flag, but only where a
    process is started."""
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise RuntimeError(f"{what} in a worker process importing the main script as it "
                           "started: a script that does so at its top level must do it under "
                           "if __name__ == \"__main__\":, as each worker imports the script "
                           "again")


def start_forkserver(preload: list[str]) -> None:
    """Start multiprocessing's forkserver, importing ``preload``, deaf to Ctrl-C and SIGTERM
    and with ``ONE_THREAD`` in its environment (if it runs already: nothing; one per
    process, so the first start's preload and settings hold). Ignored signals stay ignored
    across exec and fork, and Python then installs no KeyboardInterrupt handler: the
    server and the workers it forks (a pool's, a local cluster's) never see the group's
    Ctrl-C or SIGTERM, even while they import; this process stops them. A signal to this
    process in these milliseconds is lost. From a thread other than the main one, the
    signals cannot be set, and the workers then hear Ctrl-C. Refused in a worker still
    importing the main script (``refuse_while_bootstrapping``)."""
    refuse_while_bootstrapping("a pool of worker processes was started")
    multiprocessing.get_context("forkserver").set_forkserver_preload(preload)
    saved = {k: os.environ.get(k) for k in ONE_THREAD}
    os.environ.update(ONE_THREAD)
    try:
        with interrupt_handler(signal.SIG_IGN):
            multiprocessing.forkserver.ensure_running()
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def this_process() -> Parent:
    """This process as a worker watches it (``end_with``): host, pid and start time."""
    pid = os.getpid()
    return HOST, pid, _start_time(pid)


_watched: dict[Parent, set[Path]] = {}  # parent -> the folders of its temporaries
_watched_lock = threading.Lock()


def end_with(parent: Parent, folder: Path | None = None) -> None:
    """End this process as soon as ``parent`` has ended, first sweeping ``folder`` (if
    given) of the temporaries that run left (``files.sweep``): a job is of no
    use once the process that submitted it has gone, and a pool's workers would wait for
    it forever, idle ones too (so the watch outlives the job). Not in ``parent`` itself (a
    thread pool), nor on another host, where its pid means nothing. A pool's initializer
    (generate's, beamsnet's training pools'), and called by every generate job."""
    host, pid, _ = parent
    if host != HOST or pid == os.getpid():
        return
    with _watched_lock:
        if parent not in _watched:
            _watched[parent] = set()
            threading.Thread(target=_watch, args=(parent, _watched[parent]), daemon=True,
                             name="auvsim-parent-watch").start()
        if folder is not None:
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
