"""A killed or interrupted ``auvsim generate`` leaves no process and no temporary file
behind (issue #9), with real processes: the CLI in a session of its own, its default
pool of forkserver workers, and signals as a terminal, a scheduler or ``kill -9`` send
them."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest

from auvsim.data import files
from auvsim.errors import OutputError

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(),
                                reason="follows the process tree in /proc")

# Long enough that it is still simulating when the signal comes; 2 worker processes.
LONG = ["--preset", "maneuvers", "--duration", "3000", "--workers", "2", "--quiet"]
INTERRUPTED = "auvsim: interrupted; nothing was written"


def _generate(out: Path | str, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "auvsim.cli", "generate", *args, "--out", str(out)],
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,  # a process group of its own, as a terminal makes
        preexec_fn=as_from_a_terminal)


def as_from_a_terminal() -> None:
    """In a child: SIGINT as a terminal leaves it, whatever this process has (a shell
    starts a background job, CI's perhaps, with SIGINT ignored, which a child inherits)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _stat(pid: int | str) -> list[bytes]:
    """The fields of /proc/PID/stat after the command's name (state first); OSError once
    the process has gone."""
    with open(f"/proc/{pid}/stat", "rb") as f:
        return f.read().rsplit(b")", 1)[1].split()


def processes() -> dict[int, tuple[int, bytes, bytes]]:
    """Every process: pid -> (parent pid, state, start time), from /proc."""
    table = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            with contextlib.suppress(OSError):
                fields = _stat(entry)
                table[int(entry)] = (int(fields[1]), fields[0], fields[19])
    return table


def cpu_seconds(pid: int) -> float:
    """User plus system CPU time of process ``pid`` so far, s (0 once it has gone)."""
    try:
        fields = _stat(pid)
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def deaf_to_interrupts(pid: int) -> bool:
    """Whether process ``pid`` ignores both SIGINT and SIGTERM (its SigIgn mask in
    /proc/PID/status: bit n - 1 for signal n)."""
    with open(f"/proc/{pid}/status") as f:
        mask = next(int(line.split()[1], 16) for line in f if line.startswith("SigIgn:"))
    return all(mask >> (sig - 1) & 1 for sig in (signal.SIGINT, signal.SIGTERM))


def process_tree(pid: int) -> set[tuple[int, bytes]]:
    """``pid`` and its descendants, as (pid, start time): a reused pid is another."""
    table = processes()
    found, i = [pid], 0
    while i < len(found):
        found += [p for p, (parent, _, _) in table.items() if parent == found[i]]
        i += 1
    return {(p, table[p][2]) for p in found if p in table}


def still_running(tree: set[tuple[int, bytes]]) -> set[int]:
    """The processes of ``tree`` that have not ended (a zombie has)."""
    table = processes()
    return {p for p, start in tree if p in table and table[p][2] == start
            and table[p][1] != b"Z"}


def wait_for(condition, what: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"waited {timeout} s for {what}"
        time.sleep(0.1)


def _simulating(proc: subprocess.Popen, folder: Path) -> set[tuple[int, bytes]]:
    """Wait until a worker has simulated a block (its progress file is in the part
    folder), then the run's processes."""
    def progress() -> bool:
        assert proc.poll() is None, proc.communicate()
        return any(folder.glob(f".*.{files.TAG}.*.parts/*.progress"))

    wait_for(progress, "a worker's progress", timeout=120)  # numba may compile first
    tree = process_tree(proc.pid)
    assert len(tree) >= 4, tree  # this process, its forkserver, two workers (and a tracker)
    return tree


@contextlib.contextmanager
def _started(out: Path | str, *args: str):
    proc = _generate(out, *args)
    try:
        yield proc
    finally:  # whatever happened, nothing of the run stays
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


def test_kill_9_ends_the_workers_and_the_next_run_cleans_up(tmp_path):
    out = tmp_path / "x.h5"
    with _started(out, *LONG) as proc:
        tree = _simulating(proc, tmp_path)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        wait_for(lambda: not still_running(tree), "the run's processes to end", timeout=10)
    # What a killed run can leave (a lost node's, say): its claim, pieces and all.
    dead = tmp_path / f".x.h5.{files.TAG}.{files.HOST}.999999999"
    (dead.parent / (dead.name + ".parts")).mkdir()
    (dead.parent / (dead.name + ".parts") / "0.h5").write_bytes(b"stale")
    for name in (dead.name, dead.name + ".lock"):
        (tmp_path / name).write_bytes(b"")
    with _started(out, "--duration", "20", "--quiet") as proc:
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
    assert [p.name for p in tmp_path.iterdir()] == ["x.h5"]


@pytest.mark.parametrize("sig, to_group", [(signal.SIGINT, True), (signal.SIGTERM, False),
                                           (signal.SIGTERM, True)],
                         ids=["ctrl-c", "sigterm", "sigterm-to-group"])
def test_an_interrupt_prints_one_line_and_leaves_nothing(tmp_path, sig, to_group):
    out = tmp_path / "x.h5"
    with _started(out, *LONG) as proc:
        tree = _simulating(proc, tmp_path)
        (os.killpg if to_group else os.kill)(proc.pid, sig)
        _, err = proc.communicate(timeout=60)  # the workers' stderr too: the pipe's end
        assert proc.returncode == 130  # for SIGTERM too: tests/test_datasets.py
        assert err.splitlines() == [INTERRUPTED]
        assert list(tmp_path.iterdir()) == []
        wait_for(lambda: not still_running(tree), "the run's processes to end", timeout=10)


def test_sweep_removes_the_temporaries_of_dead_claims_only(tmp_path):
    def claim_of(host: str, pid: int, *, lock: bool = True) -> list[Path]:
        file = tmp_path / f".x.h5.{files.TAG}.{host}.{pid}"
        made = [file, file.with_name(file.name + ".parts")]
        made[0].write_bytes(b"")
        made[1].mkdir()
        (made[1] / "0.h5").write_bytes(b"")
        if lock:
            made.append(file.with_name(file.name + ".lock"))
            made[-1].write_bytes(b"")
        return made

    dead = claim_of(files.HOST, 999999999)  # nobody holds its lock
    straggler = claim_of(files.HOST, 999999998, lock=False)[1:]  # a folder made again
    elsewhere = claim_of("another-host", 999999999)  # its lock is not ours to judge
    others = [tmp_path / "x.h5", tmp_path / f".x.md.{files.TAG}.{files.HOST}.1.md"]
    for path in others:
        path.write_bytes(b"")
    with files.Claim(tmp_path / "y.h5") as live:  # sweeps first, then holds its lock
        live.file.write_bytes(b"")
        live.folder.mkdir()
        files.sweep(tmp_path)
        left = set(tmp_path.iterdir())
        assert not left & {*dead, *straggler}
        assert left >= {*elsewhere, *others, live.file, live.folder}
    assert not live.file.exists() and not live.folder.exists()


def test_a_second_run_into_an_output_being_written_is_refused(tmp_path):
    """Two runs writing one output would each rename theirs over the other's at the end:
    the second is refused in one line, naming the first, whose claim it leaves alone."""
    out = tmp_path / "x.h5"
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom auvsim.data.files import Claim\n"
         f"with Claim({str(out)!r}):\n    print('held', flush=True)\n    time.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline() == "held\n"
        with pytest.raises(OutputError, match=rf"is being written by another run \(pid "
                           rf"{holder.pid} on this machine\); expected one run per output"):
            files.Claim(out)
        assert [p.name for p in tmp_path.iterdir()] == [
            f".x.h5.{files.TAG}.{files.HOST}.{holder.pid}.lock"]
    finally:
        holder.kill()
        holder.communicate()
    with files.Claim(out):  # once it has ended, its claim is swept and the name is free
        pass


def _claimed(proc: subprocess.Popen, folder: Path) -> None:
    """Wait until the run has claimed its output (its temporary file's lock is there)."""
    def claimed() -> bool:
        assert proc.poll() is None, proc.communicate()
        return any(folder.glob(f".*.{files.TAG}.*.lock"))

    wait_for(claimed, "the run's claim", timeout=120)


def _hidden(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob(".*"))


@pytest.mark.parametrize("sharded", [False, True], ids=["one-file", "sharded"])
def test_kill_9_of_a_run_in_one_process_is_swept_by_the_next(tmp_path, sharded):
    """One worker (a two-core machine's default): the missions run on threads of the
    killed process itself, so nobody is left to clean up; its claims are named with its
    host and pid, and the next run into the folder sweeps them before any work."""
    out = f"{tmp_path / 'rm'}/" if sharded else str(tmp_path / "x.h5")
    single = ["--preset", "maneuvers", "--workers", "1", "--quiet"]
    with _started(out, *single, "--duration", "3000") as proc:
        _claimed(proc, tmp_path / "rm" / "shards" if sharded else tmp_path)
        time.sleep(1.0)  # into the simulation
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    left = _hidden(tmp_path)
    pid = f".{files.HOST}.{proc.pid}"
    assert left and all(pid in name for name in left), left  # recognisably the dead run's
    with _started(out, *single, "--duration", "5") as proc:
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
    assert _hidden(tmp_path) == []


def test_an_interrupted_sharded_run_names_the_shards_it_keeps(tmp_path):
    """A sharded dataset keeps each shard made whole, for the same command to finish: an
    interrupt names them (it said nothing was written), and the next run keeps them."""
    out = tmp_path / "rm"
    with _started(f"{out}/", *LONG) as proc:
        wait_for(lambda: proc.poll() is None and any((out / "shards").glob("part-*.h5")),
                 "a whole shard", timeout=120)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    whole = sorted((out / "shards").glob("part-*.h5"))
    assert proc.returncode == 130 and whole
    assert err.startswith(f"auvsim: interrupted; {whole[0]}") and err.count("\n") == 1, err
    assert err.rstrip().endswith("had been written whole before it, nothing else was")
    assert not (out / "index.h5").exists()


@pytest.mark.parametrize("status", [0, 2])
def test_a_ctrl_c_in_the_teardown_changes_nothing(status):
    """Once the command has ended (its outputs whole, or removed), a Ctrl-C while the
    interpreter tears down (a pool's or a cluster's finalizers: atexit) neither prints a
    traceback nor changes the status; without ``exit_with`` it did both."""
    code = ("import atexit, os, signal, time\n"
            "atexit.register(lambda: (os.kill(os.getpid(), signal.SIGINT), time.sleep(0.3)))\n"
            "from auvsim.cli_support import exit_with\n"
            f"exit_with('auvsim', lambda: {status})\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, preexec_fn=as_from_a_terminal)
    assert (done.returncode, done.stderr) == (status, "")
    bare = code.replace(f"exit_with('auvsim', lambda: {status})", f"raise SystemExit({status})")
    done = subprocess.run([sys.executable, "-c", bare], capture_output=True, text=True,
                          timeout=60, preexec_fn=as_from_a_terminal)
    assert "KeyboardInterrupt" in done.stderr  # what the test guards against


def test_an_interrupt_held_through_a_failed_step_is_what_the_step_raises():
    """A Ctrl-C held while a step ran (a cluster starting, whose worker it stopped) is
    delivered even when the step then failed: the run ends as interrupted, its error only
    the context, where the interrupt had been lost with it."""
    with pytest.raises(KeyboardInterrupt) as raised:
        with files.interrupts_held():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)  # the handler runs: held, not raised
            raise RuntimeError("Nanny failed to start.")
    assert isinstance(raised.value.__context__, RuntimeError)
    with files.interrupts_held():  # nothing held, nothing raised
        pass


@pytest.mark.parametrize("sig, after", [("SIGINT", "time.sleep(5)"), ("SIGINT", "pass"),
                                        ("SIGTERM", "time.sleep(5)")],
                         ids=["ctrl-c", "ctrl-c-at-the-end", "sigterm-with-sigint-ignored"])
def test_an_interrupt_swallowed_by_a_c_callback_still_stops_the_command(sig, after):
    """numba loads a kernel's compiled code from its cache through LLVM's callbacks, and a
    KeyboardInterrupt raised in one is printed as "Exception ignored" and lost: the
    command ran to its end with status 0. It is sent again once the callback returns, the
    same signal (a SIGTERM where SIGINT is ignored, as in a background job, too), or
    raised as the command ends if that comes first."""
    code = ("import ctypes, os, signal, time\n"
            "from auvsim.cli_support import exit_with, run_command\n"
            + ("signal.signal(signal.SIGINT, signal.SIG_IGN)\n" if sig == "SIGTERM" else "")
            + "def callback():\n"
            f"    os.kill(os.getpid(), signal.{sig})\n"
            "    time.sleep(0.1)\n"
            "def work():\n"
            "    ctypes.CFUNCTYPE(None)(callback)()\n"
            f"    {after}\n"
            "    print('ran to its end')\n"
            "exit_with('auvsim', lambda: run_command('auvsim', work, {}))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, preexec_fn=as_from_a_terminal)
    ran = "ran to its end\n" if after == "pass" else ""  # it ends before the resend
    assert (done.returncode, done.stdout, done.stderr) == (
        130, ran, "auvsim: interrupted; nothing was written\n")


def test_a_numba_call_an_interrupt_broke_into_is_the_interrupt():
    """A compiled call that an interrupt broke into raises SystemError ("returned a result
    with an exception set") from the KeyboardInterrupt: one line, 130; any other
    SystemError is not hidden."""
    from auvsim.cli_support import run_command

    def broken():  # each array the kernel hands back after the first adds a link
        try:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as e:
                raise SystemError("_numba_unpickle returned a result with an exception "
                                  "set") from e
        except SystemError as e:
            raise SystemError("CPUDispatcher returned a result with an exception set") from e

    assert run_command("auvsim", broken, {}) == 130

    def other():
        raise SystemError("something else")

    with pytest.raises(SystemError, match="something else"):
        run_command("auvsim", other, {})


def test_an_interrupt_in_a_kernels_callback_is_taken_after_it():
    """Python first runs a signal's handler that came while a numba kernel ran as the
    kernel hands back a tuple of arrays, inside numba's ``_numba_unpickle``. A
    KeyboardInterrupt raised there was a chain of SystemErrors (a traceback), a swallowed
    interrupt (exit 0) or a segmentation fault. The command's handler sends it again
    instead, and takes it outside the kernel: one line and 130, every time, and no
    kernel call broken into. The loop leaves Python a short time between the kernel's
    runs, as a command does."""
    code = ("import os, signal, sys, threading, time\n"
            "import numba, numpy as np\n"
            "from auvsim.cli_support import exit_with, run_command\n"
            "@numba.njit\n"
            "def kernel(n):\n"
            "    s = 0.0\n"
            "    for i in range(n):\n"
            "        s += np.sin(i * 1e-9)\n"
            "    return np.full(2, s), np.zeros((2, 3)), np.zeros(4)\n"
            "kernel(10)  # compiled\n"
            "n, took = 10, 0.0\n"
            "while took < 0.2:  # a run of the kernel takes 0.2 s or more\n"
            "    n *= 2\n"
            "    started = time.perf_counter()\n"
            "    kernel(n)\n"
            "    took = time.perf_counter() - started\n"
            "def work():\n"
            "    threading.Timer(float(sys.argv[1]), os.kill,\n"
            "                    (os.getpid(), signal.SIGINT)).start()\n"
            "    for _ in range(100):\n"
            "        try:\n"
            "            kernel(n)\n"
            "        except SystemError:  # the interrupt, raised in the callback\n"
            "            print('broken into')\n"
            "            raise\n"
            "        time.sleep(0.01)\n"
            "    print('ran to its end')\n"
            "exit_with('auvsim', lambda: run_command('auvsim', work, {}))\n")
    for delay in (0.03, 0.09, 0.15):  # into the first kernel run
        done = subprocess.run([sys.executable, "-c", code, str(delay)], capture_output=True,
                              text=True, timeout=120, preexec_fn=as_from_a_terminal)
        assert (done.returncode, done.stdout, done.stderr) == (
            130, "", "auvsim: interrupted; nothing was written\n"), delay


def test_an_interrupt_that_lands_in_a_compiled_callback_is_deferred(monkeypatch):
    """The command's handler, run in ``_numba_unpickle``'s frame, raises nothing there and
    sends the same signal again a moment later, which raises where it lands."""
    from numba.core import serialize

    from auvsim import cli_support

    sent = []
    monkeypatch.setattr(cli_support._later, "send", sent.append)
    frame = types.SimpleNamespace(f_code=serialize._numba_unpickle.__code__)
    cli_support._stop(signal.SIGTERM, frame)  # no KeyboardInterrupt
    assert sent == [signal.SIGTERM]
    with pytest.raises(KeyboardInterrupt):
        cli_support._stop(signal.SIGTERM, sys._getframe())
