"""What both command lines (``auvsim``, ``beamsnet``) do at their boundary.

A command ends in one of four ways, each said on at most one line of stderr:

- it succeeds: exit 0;
- an error the libraries raise on purpose (``AuvsimError``) or the operating system's
  (``OSError``: a full disk, a folder that cannot be written): one line, exit 2;
- Ctrl-C, or SIGTERM from a scheduler: one line, exit 130;
- the reader of its output has gone (``auvsim inspect X.h5 | head -1``): nothing, and the
  exit status a shell reports for a process that SIGPIPE ended, 141.

A command runs in ``auvsim.data.files.all_or_nothing``: an error or Ctrl-C removes the
run folders, reports and figures it had begun, so the line can say nothing was written;
a file that was whole before it (a dataset) stays, and the line names it.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import NoReturn

from auvsim.data.files import all_or_nothing, reason
from auvsim.errors import AuvsimError

INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a Ctrl-C
PIPE_CLOSED = 128 + signal.SIGPIPE  # 141
ERROR = 2


def run_command(prog: str, command: Callable[[], object],
                flags: Mapping[str, str]) -> int:
    """Run ``command`` as the body of the command line ``prog``; returns its exit status.

    Args:
        prog: the command's name, which starts each line it prints to stderr.
        command: the work (parsed arguments already bound); what it returns is ignored.
        flags: the flag each library argument is given on this command line, so errors
            name ``--out`` rather than ``out`` (``AuvsimError.for_cli``).
    """
    with _interrupts_as_one():
        try:
            with all_or_nothing() as outputs:
                with _deferred_interrupts():
                    command()
                sys.stdout.flush()  # a closed pipe is found here, not at exit
        except AuvsimError as e:
            return _say(prog, f"error: {e.for_cli(flags)}", ERROR)
        except BrokenPipeError as e:
            if not _stdout_closed():
                return _say(prog, f"error: {_os_error(e)}", ERROR)
            # The interpreter flushes stdout again as it exits: that must find no pipe.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
            return PIPE_CLOSED
        except OSError as e:
            return _say(prog, f"error: {_os_error(e)}", ERROR)
        except KeyboardInterrupt:
            return _interrupted(prog, outputs)
        except SystemError as e:  # numba's call that an interrupt broke into
            if not _interrupt_beneath(e):
                raise
            return _interrupted(prog, outputs)
    return 0


def _interrupt_beneath(error: BaseException) -> bool:
    """Whether a KeyboardInterrupt lies beneath ``error``, however deep its chain."""
    while error is not None:
        if isinstance(error, KeyboardInterrupt):
            return True
        error = error.__cause__ or error.__context__
    return False


def _interrupted(prog: str, outputs) -> int:
    """The line for a command that Ctrl-C or SIGTERM stopped: what it left whole, if any."""
    kept = outputs.kept
    gone = (f"; it had removed {', '.join(str(p) for p in outputs.dropped)} (run it again "
            "to finish)" if outputs.dropped else "")
    if not kept:
        return _say(prog, f"interrupted; nothing was written{gone}", INTERRUPTED)
    named = ", ".join(str(p) for p in kept[:3])
    more = f" and {len(kept) - 3} more" if len(kept) > 3 else ""
    return _say(prog, f"interrupted; {named}{more} had been written whole before "
                f"it{gone or ', nothing else was'}", INTERRUPTED)


def exit_with(prog: str, main: Callable[[], int]) -> NoReturn:
    """The command-line process: ``main()``'s status, and from its end on deaf to Ctrl-C
    and SIGTERM. Its work is done and said by then (its outputs whole, or removed); what
    remains is the interpreter's teardown (a worker pool's and a cluster's finalizers),
    which an interrupt would only turn into a traceback, or a status of 130 for outputs
    that are whole. An interrupt before ``main`` has caught any (while its arguments are
    parsed) is one line and 130, as in a command."""
    try:
        status = main()
    except KeyboardInterrupt:
        status = _say(prog, "interrupted; nothing was written", INTERRUPTED)
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_IGN)
    sys.exit(status)


def _say(prog: str, line: str, status: int) -> int:
    print(f"{prog}: {line}", file=sys.stderr)
    return status


def _os_error(error: OSError) -> str:
    """An operating system's error as what was wrong and what is expected."""
    where = f"{os.fsdecode(error.filename)!r}: " if error.filename is not None else ""
    return f"{where}{reason(error)}; expected a path that can be read or written"


def _stdout_closed() -> bool:
    """Whether stdout is a pipe whose reader has gone (poll says so with POLLERR)."""
    try:
        poll = select.poll()
        poll.register(sys.stdout.fileno(), 0)
        return any(events & select.POLLERR for _, events in poll.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll, or no stdout to ask
        return False


_last = [signal.SIGINT]  # the last interrupt ``_stop`` took, which a swallowed one was


def _stop(signum, frame) -> None:
    _last[0] = signum
    if _in_compiled_callback(frame):
        _later.send(signum)
        return
    raise KeyboardInterrupt


def _in_compiled_callback(frame) -> bool:
    """Whether ``frame`` is (or was called by) Python that compiled code calls back into
    and that cannot take an exception: numba's ``_numba_unpickle``, which a kernel calls as
    it hands back a tuple of arrays, and where Python first runs a handler for a signal
    that came while the kernel ran. An interrupt raised there was a chain of SystemErrors,
    an interrupt swallowed (the command went on to exit 0), or a segmentation fault."""
    while frame is not None:  # the handler may run in a function it called, too
        code = getattr(frame, "f_code", None)
        if code is not None and code.co_name == "_numba_unpickle" and \
                code.co_filename.endswith(os.path.join("numba", "core", "serialize.py")):
            return True
        frame = getattr(frame, "f_back", None)
    return False


@contextmanager
def _interrupts_as_one() -> Iterator[None]:
    """A scheduler's SIGTERM unwinds like Ctrl-C while the block runs: workers stop,
    temporary files go; both are taken by ``_stop``, which records which it was (main
    thread only, where Python runs signal handlers; a SIGINT this process ignores, as a
    background job does, stays ignored)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signal.SIGTERM: signal.signal(signal.SIGTERM, _stop)}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, _stop)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            if handler is not None:
                signal.signal(signum, handler)


RESEND_S = 0.01  # after a deferred interrupt, s: its callback has returned by then


class _SentAgain:
    """Interrupts sent again, the same signal, from a thread a moment later (again if that
    one lands in a callback too), while a command runs (``_deferred_interrupts``); one
    the command outran is raised as it ends, so none outlives it."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.pending: int | None = None  # the signal on its way, not yet taken
        self.sent = False
        self.over = True

    def send(self, signum: int) -> None:
        with self.lock:
            self.pending, self.sent = signum, False
        timer = threading.Timer(RESEND_S, self._resend)
        timer.daemon = True
        timer.start()

    def _resend(self) -> None:
        with self.lock:
            if self.over or self.pending is None:
                return
            self.sent = True
            os.kill(os.getpid(), self.pending)


_later = _SentAgain()


@contextmanager
def _deferred_interrupts() -> Iterator[None]:
    """While the block runs, an interrupt taken where it cannot be raised is sent again
    (``_SentAgain``). Two such places: a callback of compiled code (``_stop``), and a
    C callback that swallows what its Python raises: Python prints "Exception ignored
    on calling ctypes callback function" and goes on, and the run went on to its end
    (numba loads compiled code from its cache through such callbacks of LLVM's, for a
    second or so at a command's first call of a kernel); such an interrupt is not
    printed but sent again."""
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):
            _later.send(_last[0])
        else:
            previous(unraisable)

    sys.unraisablehook = hook
    _later.over, _later.pending = False, None
    try:
        yield
    except KeyboardInterrupt:
        _later.pending = None  # taken
        raise
    finally:
        sys.unraisablehook = previous
        with _later.lock:
            _later.over = True
            sent = _later.sent
    if _later.pending is not None:  # deferred, and not yet taken
        if sent:
            time.sleep(RESEND_S)  # the signal is on its way: its handler raises here
        raise KeyboardInterrupt
