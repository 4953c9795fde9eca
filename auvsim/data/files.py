"""Writing outputs whole or not at all, and cleaning up after runs that were killed.

Every output is written under a temporary name beside its final one and renamed when
complete, so an interrupted run leaves no half-written dataset, report or figure. The
temporary names say what they are and whose they are: ``.{name}.auvsim-tmp.{host}.{pid}``
(reports and figures add their suffix, which matplotlib needs to pick the format).

A dataset takes longer than a report and its run may be killed (``kill -9``, a lost
node), so its temporaries are a ``Claim``: the file, a ``.parts`` folder for pieces, and a
``.lock`` file flocked for as long as they are in use. The kernel drops an flock with its
owner's last descriptor, however the owner ended, so a lock that can be taken proves its
temporaries dead even if the pid has been reused since; ``sweep`` (run by every new
claim) removes those, and leaves anything else alone.

Output folders are checked before any work (``check_out_dir``) and made only once every
input has been (``make_out_dir``), so a refused command leaves no empty folder. A command
that writes several files into a folder builds them in a temporary sibling
(``staged_dir``) and moves them in at the end, so one that fails half-way (a full disk)
leaves neither some of its files nor an empty folder. Each command line runs its command in
``all_or_nothing``, the same promise for what is written outside a ``staged_dir`` (the
figures of ``auvsim plot``, a report's folder): if it fails (a full disk, Ctrl-C) the
folders it made go, and so do the files it wrote into its output folders. An ``OSError``
while writing becomes an ``OutputError`` naming the output (``writing``).

Some steps must not be cut in half by Ctrl-C or SIGTERM either: ``interrupts_held``
delivers them after the step.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import shlex
import shutil
import signal
import socket
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

from auvsim.errors import ConfigError, OutputError

TAG = "auvsim-tmp"
HOST = socket.gethostname()
# A claim's temporary file (the parts folder and the lock add a suffix): only this
# host's, since a lock held on another host may not be visible here.
_CLAIMED = re.compile(rf"\..+\.{TAG}\.{re.escape(HOST)}\.\d+")
_held: set[Path] = set()  # this process's claims: a second one would wait on its own lock


def temporary(path: Path, *, suffix: str = "") -> Path:
    """The temporary name this process writes ``path`` under, beside it."""
    return path.with_name(f".{path.name}.{TAG}.{HOST}.{os.getpid()}{suffix}")


class Claim:
    """The temporaries of an output that takes a while to build, held until ``release``
    (or the end of a ``with`` block); claiming first sweeps the folder (``sweep``).

    Args:
        path: the final output, whose folder exists.
        exclusive: refuse an output that a live run of this host writes (two would each
            rename theirs over the other's); not for a run's own jobs, a cancelled one of
            which may still be writing the shard its retry writes, the same data.

    Attributes:
        file: the temporary file to build the output in (``temporary(path)``).
        folder: a folder for pieces, ``file`` + ``.parts``, made by whoever needs it.

    Raises:
        OutputError: ``exclusive``, and another process of this host holds a claim on
            ``path`` (where the file system has no flock, nothing can be told).
        FileExistsError: this process holds one.
    """

    def __init__(self, path: str | os.PathLike, *, exclusive: bool = True) -> None:
        path = Path(path)
        self.file = temporary(path)
        self.folder, self._lock = _parts(self.file), _lock(self.file)
        if self._lock in _held:
            raise FileExistsError(f"{str(path)!r} is being written by this process already")
        sweep(path.parent)
        while True:
            fd = os.open(self._lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX)
            except OSError:  # a file system without flock (Lustre, say): never swept then
                break
            if _still_named(fd, self._lock):
                break
            os.close(fd)  # a sweep removed a dead namesake's lock as we opened it
        self._fd = fd
        _held.add(self._lock)
        try:  # after ours is held: of two runs started at once, one at least sees the other
            others = _writers(path) if exclusive else []
        except BaseException:
            self.release()
            raise
        if others:
            self.release()
            raise OutputError(f"{str(path)!r} is being written by another run (pid "
                              f"{', '.join(map(str, others))} on this machine); expected one "
                              "run per output at a time: wait for it to end, or stop it")

    def release(self) -> None:
        """Remove the temporaries (the lock last: see ``sweep``) and let the name go; a
        Ctrl-C waits until it is done, so no lock is left behind."""
        if self._fd is None:
            return
        with interrupts_held():
            self.file.unlink(missing_ok=True)
            shutil.rmtree(self.folder, ignore_errors=True)
            self._lock.unlink(missing_ok=True)
            os.close(self._fd)
            self._fd = None
            _held.discard(self._lock)

    def __enter__(self) -> Claim:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def _writers(path: Path) -> list[int]:
    """The pids of the other processes of this host whose claim on ``path`` is live (its
    lock held; ``sweep`` has removed the dead ones)."""
    name = re.compile(rf"\.{re.escape(path.name)}\.{TAG}\.{re.escape(HOST)}\.(\d+)\.lock")
    live = []
    for entry in sorted(os.listdir(path.parent)):
        match = name.fullmatch(entry)
        if match is None or int(match[1]) == os.getpid():
            continue
        try:
            fd = os.open(path.parent / entry, os.O_RDONLY | os.O_CLOEXEC)
        except OSError:
            continue  # ended meanwhile, or not ours to judge
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            live.append(int(match[1]))
        except OSError:
            pass  # a file system without flock: nothing can be told
        finally:
            os.close(fd)
    return live


def sweep(folder: str | os.PathLike) -> None:
    """Remove from ``folder`` the claims of this host whose owner has ended: those whose
    lock can be taken, and parts folders whose lock is gone (a claim's lock is made first
    and removed last, so such a folder was made again by a dead run's straggler). Other
    files, including other hosts' and live claims, are left alone."""
    folder = Path(folder)
    try:
        names = os.listdir(folder)
    except OSError:
        return
    claims = {n.removesuffix(".lock").removesuffix(".parts") for n in names}
    for name in sorted(n for n in claims if _CLAIMED.fullmatch(n)):
        file = folder / name
        lock, parts = _lock(file), _parts(file)
        try:
            fd = os.open(lock, os.O_RDONLY | os.O_CLOEXEC)
        except FileNotFoundError:
            shutil.rmtree(parts, ignore_errors=True)
            continue
        except OSError:
            continue  # not ours to judge (another user's, say)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # BlockingIOError: in use
            if _still_named(fd, lock):  # not swept and claimed again meanwhile
                file.unlink(missing_ok=True)
                shutil.rmtree(parts, ignore_errors=True)
                if not parts.exists():
                    lock.unlink()
        except OSError:
            pass
        finally:
            os.close(fd)


def leftovers(folder: str | os.PathLike, *, name: str | None = None,
              swept: bool = True) -> list[Path]:
    """The temporaries of auvsim runs in ``folder`` (of the output ``name`` only, if
    given): the files and folders named ``.<output>.auvsim-tmp.*``, which readers ignore.
    With ``swept``, those of this host's ended runs are removed first (``sweep``: only
    claims whose lock nobody holds), so what is left belongs to a run still writing, or
    to one that ended on another host.

    Returns:
        Their paths, in name order.
    """
    folder = Path(folder)
    if swept:
        sweep(folder)
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    prefix = "." if name is None else f".{name}."
    return [folder / n for n in names if n.startswith(prefix) and f".{TAG}." in n]


def leftovers_note(found: Sequence[Path]) -> str:
    """One line on temporaries that ``leftovers`` found: what they are, and the command
    that removes them."""
    folders = sorted({str(p.parent) for p in found})
    globs = " ".join(f"{shlex.quote(f)}/.*.{TAG}.*" for f in folders)
    return (f"note: {len(found)} temporary file(s) of another auvsim run beside the data "
            "(still writing, or ended on another host), which readers ignore; once no run "
            f"writes there, remove them: rm -rf {globs}")


def _lock(file: Path) -> Path:
    return file.with_name(file.name + ".lock")


def _parts(file: Path) -> Path:
    return file.with_name(file.name + ".parts")


def _still_named(fd: int, path: Path) -> bool:
    """Whether ``path`` is still the file open as ``fd``."""
    try:
        return os.path.samestat(os.fstat(fd), os.stat(path))
    except FileNotFoundError:
        return False


@contextmanager
def interrupts_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends, then deliver the first (in the main
    thread, where Python runs signal handlers; elsewhere a no-op). For steps that a
    KeyboardInterrupt would break: a process pool starting a worker loses track of it,
    and some swallow it, so the run goes on: MuJoCo's extension init, importing, and
    LLVM's callbacks as numba loads compiled code from its cache."""
    held: list[int] = []
    try:
        with interrupt_handler(lambda signum, frame: held.append(signum)):
            yield
    finally:  # an error the interrupt caused (a worker it stopped) gives way to it
        if held:
            signal.raise_signal(held[0])


@contextmanager
def interrupt_handler(handler: Callable | int) -> Iterator[None]:
    """Set ``handler`` for SIGINT and SIGTERM while the block runs (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, previous in old.items():
            if previous is not None:  # None: set outside Python, cannot be restored
                signal.signal(sig, previous)


def names_folder(out: str | os.PathLike) -> bool:
    """Whether ``out`` is written as a folder: ``datasets/rm/`` (a trailing /; a file name
    that is an existing folder is refused, as a slip, by the dataset writer)."""
    return os.fspath(out).endswith((os.sep, "/"))


# Names of single files, never of a folder to write several into: ``--out run.png`` or
# ``--out model.pt`` for a folder is a slip that would have made a folder of that name.
FILE_SUFFIXES = frozenset({".h5", ".hdf5", ".csv", ".txt", ".json", ".toml", ".md", ".png",
                           ".pdf", ".svg", ".npy", ".npz", ".pt", ".mcap", ".pd0", ".nc",
                           ".tif", ".tiff"})


def check_out_dir(out: str | os.PathLike) -> Path:
    """``out`` as a Path, after checking that it can be made a directory (it is one, or the
    nearest existing path above it is), so that no work is spent before a bad output path
    is refused.

    Raises:
        ConfigError: ``out`` is the root directory; ``out`` is new and named as a file
            (``FILE_SUFFIXES``); ``out``, or a path above it, exists and is not a
            directory; or the nearest existing one cannot be written in (a file is made
            there and removed, so that a read-only place is refused before the work, not
            after it).
    """
    out = Path(out)
    if not Path(os.path.abspath(out)).name:
        raise ConfigError(f"{str(out)!r}: the root directory; expected a directory below it "
                          "to write into", argument="out")
    if not out.exists() and out.suffix.lower() in FILE_SUFFIXES:
        raise ConfigError(f"{str(out)!r}: a {out.suffix} file's name; expected a folder to "
                          "write the files into", argument="out")
    for path in (out, *out.parents):
        if path.exists():
            if not path.is_dir():
                what = "exists" if path == out else f"is inside {str(path)!r}, which exists"
                raise ConfigError(f"{str(out)!r}: {what} and is not a directory; expected a "
                                  "directory to write into", argument="out")
            try:
                fd, probe = tempfile.mkstemp(prefix=f".{TAG}-probe-", dir=path)
                os.close(fd)
                os.unlink(probe)
            except OSError as e:
                raise ConfigError(f"{str(out)!r}: cannot write in {str(path)!r} "
                                  f"({e.strerror or e}); expected a directory you can write "
                                  "in", argument="out") from None
            break
    return out


def check_writable_path(path: Path, argument: str = "out", *, hint: str = "") -> None:
    """Refuse an output file's path that is a folder (``hint`` adds what to give
    instead) or lies under a file: what nothing can write.

    Raises:
        ConfigError: naming ``argument``.
    """
    if path.is_dir():
        raise ConfigError(f"{str(path)!r}: is a directory; expected a file name{hint}",
                          argument=argument)
    above = next((p for p in path.parents if p.exists()), None)
    if above is not None and not above.is_dir():
        raise ConfigError(f"{str(path)!r}: {str(above)!r} is a file, not a folder; "
                          "expected a path in a folder", argument=argument)


def check_out_file(out: str | os.PathLike, kind: str, suffix: str, signature: bytes
                   ) -> Path:
    """``out`` as a Path, after checking that it names a file that can be written (an
    export's output: refused before any work; its folder is made as it is written, as a
    dataset's is: ``make_parent_dirs``), and that it is not a user's other file:
    an existing file is replaced only where it is of this ``kind`` (its first bytes are
    ``signature``) or empty, and a name of another of auvsim's formats (``FILE_SUFFIXES``:
    ``x.mcap`` for PD0, say) is refused as a slip. Other names (a PD0 file's ``.000``, a
    ``.bin``) are the user's to choose.

    Raises:
        ConfigError: ``out`` is a directory or lies under a file (``check_writable_path``),
            it is another format's name, or another file is there.
    """
    out = Path(out)
    check_writable_path(out)
    if out.suffix.lower() in FILE_SUFFIXES - {suffix}:
        raise ConfigError(f"{str(out)!r}: a {out.suffix} name for a {kind} file; expected a "
                          f"{suffix} name", argument="out")
    if out.is_file() and out.stat().st_size > 0:
        with open(out, "rb") as f:
            if f.read(len(signature)) != signature:
                raise ConfigError(f"{str(out)!r}: a file that is not {kind} is there; "
                                  f"expected a new path, or a {kind} file to replace",
                                  argument="out")
    return out


def make_parent_dirs(folder: Path) -> None:
    """Make ``folder`` (and its parents) for a file to be written into it; inside
    ``all_or_nothing``, a failure removes again the folders made here that are left empty
    (a dataset written whole into one stays: a cache for the next run).

    Raises:
        OSError: the folder cannot be made.
    """
    made = [p for p in (folder, *folder.parents) if not p.exists()]  # innermost first
    folder.mkdir(parents=True, exist_ok=True)
    for scope in _scopes:
        scope.parents += made


def make_out_dir(out: Path, *, whole: bool = True) -> None:
    """Make the directory ``out`` (and its parents), or raise ConfigError naming it.

    Args:
        out: the directory.
        whole: its outputs make one whole: inside ``all_or_nothing``, a failure removes
            the files written into it (and it, if made here). False for a folder whose
            files are each whole on their own (a sharded dataset's shards).
    """
    top = None  # the outermost folder made here
    for path in (out, *out.parents):
        if path.exists():
            break
        top = path
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"{str(out)!r}: cannot be made a directory ({e.strerror}); expected "
                          "a directory to write into", argument="out") from None
    if whole:
        for scope in _scopes:
            scope.folders.append(out)
            if top is not None:
                scope.made.append(top)


@dataclass(eq=False)  # each block's record is itself, however alike
class Outputs:
    """What a block of ``all_or_nothing`` wrote.

    Attributes:
        folders: the output folders it made or wrote into (``make_out_dir``).
        made: the outermost folders it made.
        parents: the folders made for a file written into them (``make_parent_dirs``),
            innermost first: removed on failure where left empty.
        written: the files it wrote whole (``commit``), in order.
        removed: those it removed again on failure.
        finished: what its workers finished whole and it keeps whatever follows (a
            trained model's folder, ``finished``), in order.
    """

    folders: list[Path] = field(default_factory=list)
    made: list[Path] = field(default_factory=list)
    parents: list[Path] = field(default_factory=list)
    written: list[Path] = field(default_factory=list)
    removed: list[Path] = field(default_factory=list)
    finished: list[Path] = field(default_factory=list)
    dropped: list[Path] = field(default_factory=list)  # a user's files the block removed

    @property
    def kept(self) -> list[Path]:
        """The files written and still there, and what was finished, each once (a file
        written into a ``staged_dir`` that was then thrown away is not)."""
        return list(dict.fromkeys(p for p in (*self.written, *self.finished)
                                  if p not in self.removed and p.exists()))


def finished(path: str | os.PathLike) -> None:
    """Record ``path`` (a file or folder another process made whole: a trained model's
    run folder) as kept by every open ``all_or_nothing`` block, which then names it
    among what an interrupted command leaves; no block removes it."""
    for scope in _scopes:
        scope.finished.append(Path(path))


def dropped(path: str | os.PathLike) -> None:
    """Record ``path``, a file that was there before the command (a sharded dataset's old
    index), as removed by it: an interrupted command names it among what it changed,
    where it would otherwise say nothing else was."""
    for scope in _scopes:
        scope.dropped.append(Path(path))


_scopes: list[Outputs] = []  # the open ``all_or_nothing`` blocks, outermost first


@contextmanager
def all_or_nothing() -> Iterator[Outputs]:
    """Keep what the block writes only if it ends without an exception.

    On one (an error, Ctrl-C; not a closed pipe, which ends a command whose outputs are
    written), the folders that ``make_out_dir`` made in the block are removed with all
    that is in them, and the files ``commit`` wrote into the folders given to
    ``make_out_dir`` (the whole of a run folder or a report) are removed. Other files
    written whole stay (a generated dataset, cached for the next run): ``Outputs.kept``
    lists them. Blocks nest; each rolls back its own.
    """
    scope = Outputs()
    _scopes.append(scope)
    try:
        yield scope
    except BrokenPipeError:
        raise
    except BaseException:
        _roll_back(scope)
        raise
    finally:
        _scopes.remove(scope)


def _roll_back(scope: Outputs) -> None:
    with interrupts_held():
        for path in reversed(scope.written):
            if any(folder == path.parent for folder in scope.folders):
                path.unlink(missing_ok=True)
                scope.removed.append(path)
        for folder in reversed(scope.made):
            scope.removed += [p for p in scope.written if folder in p.parents]
            shutil.rmtree(folder, ignore_errors=True)
        for folder in scope.parents:
            with contextlib.suppress(OSError):  # not empty: a file written whole stays
                folder.rmdir()
        for outer in _scopes:
            if outer is not scope:
                outer.removed += scope.removed


def commit(tmp: str | os.PathLike, path: str | os.PathLike) -> None:
    """Rename the complete temporary ``tmp`` to ``path``, recorded for ``all_or_nothing``;
    a Ctrl-C waits until both are done, so what a command says it wrote is what it did."""
    with interrupts_held():
        os.replace(tmp, path)
        for scope in _scopes:
            scope.written.append(Path(path))


# Whose errno says the output could not be written (not a lost connection, say).
_WRITE_ERRORS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO,
                 errno.EACCES, errno.EPERM, errno.ENOENT, errno.EISDIR, errno.ENOTDIR}


def output_error(path: str | os.PathLike, error: OSError) -> OutputError:
    """``error``, raised while writing ``path``, as one line that names the output."""
    if error.errno is not None and error.errno in (errno.ENOSPC, errno.EDQUOT):
        expected = "expected room for it there: free some space, or write elsewhere"
    else:
        expected = "expected a path in a folder that can be written"
    return OutputError(f"{str(path)!r}: cannot be written ({reason(error)}); {expected}")


def reason(error: OSError) -> str:
    """What went wrong, in a few words: the errno's text, or the error's first 200 characters
    (h5py's HDF5 errors may come without an errno)."""
    if error.errno:
        return os.strerror(error.errno)
    return " ".join(str(error).split())[:200] or type(error).__name__


@contextmanager
def writing(path: str | os.PathLike) -> Iterator[None]:
    """Turn an ``OSError`` raised in the block, while ``path`` is written, into an
    ``OutputError`` naming it (a connection's error is left as it is)."""
    try:
        yield
    except OSError as e:
        if not is_write_error(e):
            raise
        raise output_error(_as_named(Path(path)), e) from e


_staged: list[tuple[Path, Path]] = []  # open ``staged_dir`` blocks: (stage, out)


def _as_named(path: Path) -> Path:
    """``path`` by the name the user gave its folder: a file in a ``staged_dir``'s hidden
    stage is named in ``out``, where it was to go."""
    for stage, out in reversed(_staged):
        if path.is_relative_to(stage):
            return out / path.relative_to(stage)
    return path


def is_write_error(error: BaseException) -> bool:
    """Whether ``error`` may come from writing a file (a full disk, a read-only folder, an
    HDF5 error without an errno), as opposed to a lost connection or worker, say."""
    return (isinstance(error, OSError) and not isinstance(error, ConnectionError)
            and (error.errno is None or error.errno in _WRITE_ERRORS))


@contextmanager
def written_whole(path: Path) -> Iterator[Path]:
    """A temporary beside ``path`` for the block to write; renamed to ``path`` when the
    block ends, removed whatever happens (nothing of it is left on an error).

    Raises:
        OutputError: it cannot be written.
    """
    tmp = temporary(path, suffix=path.suffix)
    try:
        with writing(path):
            yield tmp
            commit(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def check_not_source(out: str | os.PathLike, source: str | os.PathLike) -> None:
    """Refuse an output ``out`` that is the dataset ``source`` it is written from, by
    whatever name (a symbolic or hard link too): writing it would destroy the dataset.

    Raises:
        ConfigError: ``out`` is ``source`` (argument ``out``).
    """
    out = Path(out)
    if out.exists() and Path(source).exists() and out.samefile(source):
        raise ConfigError(f"{str(out)!r}: is the dataset itself; expected another file",
                          argument="out")


def write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically.

    Raises:
        OutputError: it cannot be written (nothing of it is left then).
    """
    path = Path(path)
    with written_whole(path) as tmp:
        tmp.write_bytes(data)
    return path


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return write_bytes(path, text.encode("utf-8"))


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Save a matplotlib figure to ``path`` atomically and close it.

    Raises:
        OutputError: it cannot be written (nothing of it is left then).
    """
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        with written_whole(path) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        plt.close(fig)
    return path


@contextmanager
def staged_dir(out: str | os.PathLike) -> Iterator[Path]:
    """A temporary folder to write the files of the folder ``out`` into, moved into place
    when the block ends without an error, removed (with any folder above ``out`` that it
    made) when it ends with one.

    The folder is a ``Claim``'s parts folder beside ``out``, so a killed run's is swept by
    the next claim there. ``out`` that does not exist yet is the folder renamed, in one
    step; one that exists gets each file moved in (replacing a namesake), its other files
    left as they are.

    Raises:
        ConfigError: ``out`` cannot be a directory.
    """
    out = check_out_dir(out)
    if out.name in ("", ".", ".."):  # "." or "keep/..": the folder by a name of its own
        out = Path(os.path.abspath(out))
    made = [p for p in (out.parent, *out.parent.parents) if not p.exists()]  # deepest first
    make_out_dir(out.parent)
    try:
        with Claim(out) as claim:
            claim.folder.mkdir()
            _staged.append((claim.folder, out))
            try:
                yield claim.folder
            finally:
                _staged.remove((claim.folder, out))
            _move_into(claim.folder, out)
    except BaseException:
        for folder in made:
            try:
                folder.rmdir()
            except OSError:  # not empty: someone else's files are in it now
                break
        raise


def _move_into(source: Path, out: Path) -> None:
    """Move the folder ``source`` to ``out``: renamed if ``out`` does not exist, else entry
    by entry (folders merged the same way)."""
    if not out.exists():
        source.rename(out)
        return
    for entry in sorted(source.iterdir()):
        target = out / entry.name
        if entry.is_dir() and target.is_dir():
            _move_into(entry, target)
        else:
            entry.replace(target)
