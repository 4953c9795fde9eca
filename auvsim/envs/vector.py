"""``AuvVectorEnv``: a batch of ``auvsim/AUV-v0`` environments stepped by worker processes
over shared memory, for policies that want many episodes at once.

## Description

``num_envs`` plain ``AuvEnv`` instances (``auvsim.envs.env``), split into contiguous slices,
one per worker process and the last for this process, which steps its own envs while the
workers step theirs (by default one process per core). Actions, observations, rewards,
terminations, truncations and the info arrays live in one shared-memory block
(``multiprocessing.shared_memory``), so a step costs this process one copy of the
actions in, a one-byte message to each worker and a one-byte answer back, and copies of
the results out. A process waiting for a message polls for it for up to ``SPIN_S``
(2 ms) before it blocks, when every process has a core of its own: a process that blocks
gives up its core and gets it back later than the next message comes. The results are
exactly those of ``gymnasium.make_vec("auvsim/AUV-v0", num_envs,
vectorization_mode="sync")`` (tests/test_vector.py compares them bitwise): env ``i`` is
reset with seed ``s + i`` by ``reset(seed=s)``, autoreset follows gymnasium's
``AutoresetMode.NEXT_STEP`` (the step after an episode's end resets that env and returns
its reset observation and info, reward 0, neither flag set), and ``info[key]`` is
batched with its ``info["_key"]`` mask as gymnasium's vector envs do.

## How it differs from ``gymnasium.vector.AsyncVectorEnv``

``AsyncVectorEnv`` runs one process per env and, per step, pickles each env's action and
its whole result (a 10-key info dict) through a pipe and merges the infos key by key
(``VectorEnv._add_info``): 0.16 ms of the parent's CPU per step in the README's run
(0.4 ms on slower days), more than two steps of the env, so two of them on 2 cores gave
0.31 to 0.39x the steps/s of one env (0.23 to 0.46x over earlier runs).
Here a process steps several envs per message, nothing is pickled per step, the info
arrays are filled in place, and the parent steps envs too instead of waiting: its share
stays small however fast ``AuvEnv.step`` gets. What it gives up: only ``AuvEnv`` itself
(no wrappers inside the workers, no other env ids), infos of ``AuvEnv``'s own float64
fields only (``auvsim.envs.env.INFO``: each env's info is one row, ``AuvEnv.info_row``,
shared in one copy; a field added there is shared too), and only
``AutoresetMode.NEXT_STEP``.

## Arguments

``AuvVectorEnv(num_envs=N, workers=None, config=None, frame_skip=10,
max_episode_seconds=600.0)``, or ``gymnasium.make_vec("auvsim/AUV-v0", num_envs=N,
vectorization_mode="vector_entry_point", workers=..., config=..., ...)``:

    num_envs             environments in the batch
    workers              worker processes beside this one (default
                         min(num_envs, cores) - 1, cores those this process may run
                         on: one process per core), at most num_envs; 0 steps every
                         env in this process
    config, frame_skip,  passed to every ``AuvEnv``
    max_episode_seconds
    context              multiprocessing start method, "forkserver" (default; it
                         imports auvsim.envs.env once for all workers) or "spawn"; never
                         "fork" (MuJoCo, numba and threads)

As with ``AsyncVectorEnv``, the workers import the main script: guard a script that
makes one with ``if __name__ == "__main__":``. A worker exits when the env is closed,
garbage-collected, at interpreter exit, and when the parent dies (its end of the pipe
closes: the worker reads EOF); the shared memory is unlinked by ``close()`` (or by
multiprocessing's resource tracker if the parent is killed). Actions of the wrong shape
or not finite are refused in the parent, naming the env, before any env steps: the env
stays open. An exception in a worker (a seed gymnasium refuses, say) closes the env and
is re-raised in the parent, same type and message, with the worker's traceback as its
cause; a worker that died, mid-step or idle, is a ``RuntimeError`` naming it and its
exit code, the env closed; a Ctrl-C closes the env too. Polling counts the cores this
process may run on (``os.sched_getaffinity``), not the machine's.

## Performance

On 2 cores, 8 or more native envs reach 0.91 to 0.94 of what two free processes get
(``benchmarks/env.py``; the README has the table). What is lost is the lock step (each
vector step waits for the slower slice) and the parent's own cost per vector step with
the round trip to the workers: both weigh less the more envs a vector step holds.

    .venv/bin/python benchmarks/env.py --repeats 7
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
import select
import signal
import time
import traceback
import weakref
from multiprocessing import shared_memory
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from auvsim.processes import start_forkserver

# The pipe protocol, one raw byte per message and answer on the fast path (no pickling,
# no framing: one write and one read per worker per step). Parent to worker: STEP, NOOP,
# or COMMAND followed by a framed pickled (name, *args) (Connection.send_bytes); worker to
# parent: OK, or ERROR followed by a framed pickled (exception, traceback text).
STEP = b"s"  # step the slice's envs
NOOP = b"n"  # answer without stepping (benchmarks/env.py times the parent with it)
COMMAND = b"c"
OK = b"k"
ERROR = b"e"
ALIGN = 64  # bytes: each shared array starts on its own cache line
SPIN_S = 0.002  # s a process polls for the next message before it blocks (_readable)


def _fields(num_envs: int, observation_space: gym.spaces.Box,
            action_space: gym.spaces.Box, info_size: int) -> list[tuple[str, str, tuple]]:
    """The shared arrays: (name, dtype string, shape), each with the batch first."""
    n = num_envs
    return [("actions", "float64", (n, *action_space.shape)),  # exact for any float input
            ("observations", observation_space.dtype.str, (n, *observation_space.shape)),
            ("rewards", "float64", (n,)),
            ("terminations", "bool", (n,)),
            ("truncations", "bool", (n,)),
            ("info", "float64", (n, info_size))]  # each env's AuvEnv.info_row


def _offsets(fields) -> tuple[list[int], int]:
    """Each field's byte offset in the shared block (on a 64-byte boundary), and the
    block's size."""
    offsets, offset = [], 0
    for _, dtype, shape in fields:
        offsets.append(offset)
        nbytes = int(np.prod(shape, dtype=np.int64)) * np.dtype(dtype).itemsize
        offset += -(-nbytes // ALIGN) * ALIGN
    return offsets, max(offset, ALIGN)


def _views(buffer, fields) -> dict[str, np.ndarray]:
    """Numpy arrays over ``buffer`` (the shared block), laid out as ``fields`` say."""
    offsets, _ = _offsets(fields)
    return {name: np.ndarray(shape, dtype, buffer=buffer, offset=offset)
            for (name, dtype, shape), offset in zip(fields, offsets, strict=True)}


class _Slice:
    """The envs ``start .. stop - 1`` of the batch, reset and stepped in place over the
    batch's arrays (in a worker, or in the parent: its own slice).

    Args:
        views: the batch's arrays (``_views``).
        start, stop: the slice, indices into the batch.
        env_kwargs: ``AuvEnv``'s arguments.
    """

    def __init__(self, views: dict[str, np.ndarray], start: int, stop: int,
                 env_kwargs: dict) -> None:
        from auvsim.envs.env import AuvEnv  # MuJoCo and numba: only where envs run

        self.start, self.stop = start, stop
        self.envs = [AuvEnv(**env_kwargs) for _ in range(start, stop)]
        self.actions = views["actions"]
        self.observations = views["observations"]
        self.rewards = views["rewards"]
        self.terminations = views["terminations"]
        self.truncations = views["truncations"]
        self.info = views["info"]
        # NEXT_STEP autoreset: the envs whose episode ended at the last step.
        self.autoreset = np.zeros(stop - start, dtype=bool)

    def reset(self, seeds: list, options: dict | None, mask: np.ndarray | None) -> None:
        """Reset the slice's envs (those of ``mask``, if given), env ``i`` with
        ``seeds[i]`` (batch indices)."""
        for j, env in enumerate(self.envs):
            i = self.start + j
            if mask is not None and not mask[i]:
                continue
            try:
                self.observations[i], _ = env.reset(seed=seeds[i], options=options)
                self.info[i] = env.info_row
            except Exception as exc:
                exc.add_note(f"in env {i} of the AuvVectorEnv")
                raise
            self.terminations[i] = self.truncations[i] = False
            self.autoreset[j] = False

    def step(self) -> None:
        """Step each env with its row of ``actions``, or reset it if its episode ended
        at the last step (gymnasium's NEXT_STEP autoreset, as SyncVectorEnv does)."""
        for j, env in enumerate(self.envs):
            i = self.start + j
            try:
                if self.autoreset[j]:
                    self.observations[i], _ = env.reset()
                    self.rewards[i] = 0.0
                    self.terminations[i] = self.truncations[i] = False
                else:
                    (self.observations[i], self.rewards[i], self.terminations[i],
                     self.truncations[i], _) = env.step(self.actions[i].copy())
                self.info[i] = env.info_row  # the info's values, in one copy
            except Exception as exc:
                exc.add_note(f"in env {i} of the AuvVectorEnv")
                raise
            self.autoreset[j] = self.terminations[i] or self.truncations[i]

    def close(self) -> None:
        for env in self.envs:
            env.close()


def _failure(exc: BaseException) -> bytes:
    """A worker's answer for ``exc``: the exception itself (or, unpicklable, a
    RuntimeError of its type and message) and its traceback text."""
    text = "".join(traceback.format_exception(exc))
    try:
        return pickle.dumps((exc, text))
    except Exception:
        return pickle.dumps((RuntimeError(f"{type(exc).__name__}: {exc}"), text))


def _answer(conn, failure: bytes | None) -> None:
    """A worker's answer: ``OK``, or ``ERROR`` and the failure."""
    if failure is None:
        os.write(conn.fileno(), OK)
    else:
        os.write(conn.fileno(), ERROR)
        conn.send_bytes(failure)


def _readable(fd: int, spin: bool) -> None:
    """Return once ``fd`` has data (or EOF). With ``spin``, poll it for up to ``SPIN_S``
    first: a process that blocks gives up its core, and getting it back costs more than a
    step's worth of the time it is away (measured: ``benchmarks/env.py``), while the next
    message usually comes within a step."""
    poller = select.poll()  # not select.select, which refuses descriptors >= 1024
    poller.register(fd, select.POLLIN)
    if spin:
        deadline = time.perf_counter() + SPIN_S
        while time.perf_counter() < deadline:
            if poller.poll(0):
                return
    poller.poll()


def _worker(conn, shm_name: str, fields, start: int, stop: int, env_kwargs: dict,
            spin: bool) -> None:
    """A worker process: build the slice's envs, answer (``OK`` or the failure), then
    serve messages until ``close`` or EOF (the parent closed or died); with ``spin``, wait
    for each by polling a while first (``_readable``)."""
    # Ctrl-C reaches the whole process group: the parent handles it and closes us.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    shm = shared_memory.SharedMemory(name=shm_name)
    fd = conn.fileno()
    part = None
    try:
        try:
            part = _Slice(_views(shm.buf, fields), start, stop, env_kwargs)
        except Exception as exc:
            _answer(conn, _failure(exc))
            return
        _answer(conn, None)
        while True:
            try:
                _readable(fd, spin)
                message = os.read(fd, 1)
            except OSError:
                return
            if not message:
                return  # EOF: the parent is gone
            failure = None
            try:
                if message == STEP:
                    part.step()
                elif message == COMMAND:
                    command, *args = pickle.loads(conn.recv_bytes())
                    if command == "close":
                        _answer(conn, None)
                        return
                    part.reset(*args)
            except Exception as exc:
                failure = _failure(exc)
            try:
                _answer(conn, failure)
            except OSError:
                return  # the parent is gone
    finally:
        if part is not None:
            part.close()
        del part
        try:
            shm.close()
        except BufferError:
            pass  # a view still alive (in a traceback); the process is ending anyway
        conn.close()


class _RemoteTraceback(Exception):
    """A worker's traceback, attached as the cause of the exception it raised."""

    def __str__(self) -> str:
        return self.args[0]


def _shutdown(processes: list, conns: list, shm, views: dict) -> None:
    """Stop the workers (politely, then by force) and free the shared memory. Holds no
    reference to the env: it runs at ``close()``, garbage collection or exit."""
    for conn in conns:
        try:
            os.write(conn.fileno(), COMMAND)
            conn.send_bytes(pickle.dumps(("close",)))
        except OSError:
            pass  # that worker is gone
    for process in processes:
        process.join(timeout=5.0)
        if process.is_alive():
            process.terminate()
            process.join(timeout=2.0)
        if process.is_alive():
            process.kill()
            process.join()
    for conn in conns:
        conn.close()
    views.clear()  # the parent's arrays over the block, so that it can be unmapped
    if shm is not None:
        try:
            shm.close()
        except BufferError:
            pass  # an array still in use elsewhere: it is unmapped when that goes
        shm.unlink()


class AuvVectorEnv(gym.vector.VectorEnv):
    """A batch of ``AuvEnv`` stepped by worker processes over shared memory (see the
    module docstring).

    Args:
        num_envs: environments in the batch.
        workers: worker processes beside this one, which steps a slice too (default
            ``min(num_envs, cores) - 1``, cores those this process may run on,
            ``os.sched_getaffinity``; at most ``num_envs``); 0 runs every env in this
            process.
        config: ``AuvEnv``'s config, for every env (default: the paper-sim preset's).
        frame_skip: physics steps per env step (10: dt = 0.1 s).
        max_episode_seconds: truncation time of each episode, s.
        context: multiprocessing start method, "forkserver" or "spawn".
        render_mode: None; gymnasium passes it, and, as ``AuvEnv``, this draws nothing.

    Raises:
        ValueError: a bad ``num_envs``, ``workers`` or ``context``.
        ConfigError: a ``render_mode`` (``AuvEnv``'s one line).
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, *, num_envs: int, workers: int | None = None, config=None,
                 frame_skip: int = 10, max_episode_seconds: float = 600.0,
                 context: str = "forkserver", render_mode: str | None = None) -> None:
        from auvsim.envs.env import INFO, INFO_SIZE, AuvEnv

        if render_mode is not None:  # refused as the single environment refuses it
            AuvEnv(render_mode=render_mode)
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs: expected a whole number >= 1, got {num_envs!r}")
        # The cores this process may run on (fewer than the machine's under taskset).
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") \
            else os.cpu_count() or 1
        if workers is None:  # this process steps envs too: one process per core
            workers = min(num_envs, cores) - 1
        if not isinstance(workers, int) or workers < 0:
            raise ValueError(f"workers: expected a whole number >= 0, got {workers!r}")
        if context not in ("forkserver", "spawn"):
            raise ValueError(f"context: expected 'forkserver' or 'spawn' (not 'fork': "
                             f"MuJoCo, numba and threads), got {context!r}")
        self.num_envs = num_envs
        self.workers = min(workers, num_envs)
        # Poll while waiting only when every process has a core to itself.
        self._spin = self.workers + 1 <= cores
        self._context = mp.get_context(context)
        if self.workers and context == "forkserver":
            # Started now, it imports auvsim.envs.env (once for all workers) while this
            # process builds its probe env.
            start_forkserver(["auvsim.envs.env"])
        env_kwargs = dict(config=config, frame_skip=frame_skip,
                          max_episode_seconds=max_episode_seconds)
        # One env here for the spaces (and to refuse a bad config before any process
        # starts).
        probe = AuvEnv(**env_kwargs)
        self.single_observation_space = probe.observation_space
        self.single_action_space = probe.action_space
        probe.close()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.metadata = dict(self.metadata)
        self.render_mode = None
        self.info_keys = list(INFO)
        fields = _fields(num_envs, self.single_observation_space, self.single_action_space,
                         INFO_SIZE)

        self._processes: list = []
        self._conns: list = []
        self._fds: list[int] = []  # the parent's ends of the pipes, for the fast path
        self._shm = None
        self._views: dict[str, np.ndarray] = {}
        self._slice = None
        self._finalizer = weakref.finalize(self, _shutdown, self._processes, self._conns,
                                           None, self._views)
        if self.workers == 0:
            self._views.update(_views(np.zeros(_offsets(fields)[1], np.uint8), fields))
            self._slice = _Slice(self._views, 0, num_envs, env_kwargs)
        else:
            self._start(fields, env_kwargs)
            # The last slice is this process's own (empty when there are as many
            # workers as envs): it steps its envs while the workers step theirs.
            try:
                self._slice = _Slice(self._views, self._starts[-1], num_envs, env_kwargs)
            except Exception:
                self.close()
                raise
        views = self._views
        self._actions = views["actions"]
        # Per step: info's (key, mask key, shared view: a column or columns of the rows),
        # and its masks' values.
        self._info_views = [(key, f"_{key}", views["info"][:, place])
                            for key, place in INFO.items()]
        self._all_true = np.ones((len(self.info_keys), num_envs), dtype=bool)

    def _start(self, fields, env_kwargs: dict) -> None:
        """Allocate the shared block and start the workers, each on a contiguous slice
        (this process's own, the last, included: sizes differing by at most one); wait
        until each has built its envs."""
        self._shm = shared_memory.SharedMemory(create=True, size=_offsets(fields)[1])
        self._finalizer.detach()
        self._finalizer = weakref.finalize(self, _shutdown, self._processes, self._conns,
                                           self._shm, self._views)
        self._views.update(_views(self._shm.buf, fields))
        ctx = self._context
        slices = self.workers + 1
        sizes = [self.num_envs // slices + (k < self.num_envs % slices)
                 for k in range(slices)]
        start = 0
        self._starts = []
        for size in sizes[:-1]:
            parent, child = ctx.Pipe()
            process = ctx.Process(target=_worker, daemon=True, name=f"auvsim-vector-{start}",
                                  args=(child, self._shm.name, fields, start, start + size,
                                        env_kwargs, self._spin))
            process.start()
            child.close()  # the worker's end: only the worker holds it, so EOF reaches it
            self._processes.append(process)
            self._conns.append(parent)
            self._fds.append(parent.fileno())
            start += size
        self._starts.append(start)
        self._wait(starting=True)

    @property
    def worker_pids(self) -> list[int]:
        """The worker processes' ids (empty with ``workers=0``)."""
        return [process.pid for process in self._processes]

    def _wait(self, own: Exception | None = None, *, starting: bool = False) -> None:
        """Each worker's answer to the last command (``starting``: to its start); on a
        failure (``own``: this process's slice's, first), close the env and raise it."""
        failure = None if own is None else (own, None)
        for k, conn in enumerate(self._conns):
            try:
                _readable(self._fds[k], self._spin)
                answer = os.read(self._fds[k], 1)
                if answer == ERROR:
                    failure = failure or pickle.loads(conn.recv_bytes())
                    continue
            except (EOFError, OSError):
                answer = b""
            except BaseException:  # Ctrl-C: the answers are out of step with the commands
                self.close()
                raise
            if answer != OK:  # EOF: the worker died
                self._processes[k].join(timeout=1.0)  # for its exit code
                # A worker imports the main script again as it starts: one that makes the
                # env at its top level, not under ``if __name__ == "__main__":``, made
                # another env there, which multiprocessing refused in the worker.
                unguarded = (" as it started (if a script makes the env at its top level, "
                             "it must do so under if __name__ == \"__main__\":, as the worker "
                             "imports it again)"
                             if starting and self._processes[k].exitcode == 1 else "")
                failure = failure or (RuntimeError(
                    f"AuvVectorEnv: worker {k} (pid {self._processes[k].pid}) died, exit "
                    f"code {self._processes[k].exitcode}{unguarded}"), None)
        if failure is not None:
            exc, text = failure
            self.close()
            if text is not None:
                raise exc from _RemoteTraceback(text)
            raise exc

    def _run(self, message: bytes, method, name: str = "", *args) -> None:
        """Send ``message`` (``STEP``, ``NOOP``, or ``COMMAND``: then the command ``name``
        and its ``args``) to every worker, run ``method(*args)`` of this process's slice
        meanwhile (None: nothing), and wait for the workers' answers; on any failure,
        close the env and raise."""
        data = pickle.dumps((name, *args)) if message == COMMAND else None
        try:
            for k, (fd, conn) in enumerate(zip(self._fds, self._conns, strict=True)):
                try:
                    os.write(fd, message)
                    if data is not None:
                        conn.send_bytes(data)
                except OSError:  # its end of the pipe is closed: it died while idle
                    self._processes[k].join(timeout=1.0)  # for its exit code
                    raise RuntimeError(
                        f"AuvVectorEnv: worker {k} (pid {self._processes[k].pid}) died, exit "
                        f"code {self._processes[k].exitcode}") from None
            own = None
            if method is not None:
                try:
                    method(*args)
                except Exception as exc:
                    own = exc
        except BaseException:  # Ctrl-C too: the workers' answers would be out of step
            self.close()
            raise
        self._wait(own)

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError("AuvVectorEnv: the environment is closed")

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every env (or those of ``options["reset_mask"]``, a (num_envs,) bool
        array, as SyncVectorEnv does), env ``i`` with seed ``seed + i``, or ``seed[i]``
        from a list.

        Returns:
            observations (num_envs, 15) float32 and the batched info (module docstring).
        """
        self._check_open()
        n = self.num_envs
        if seed is None:
            seed = [None] * n
        elif isinstance(seed, int):
            seed = [seed + i for i in range(n)]
        if len(seed) != n:
            raise ValueError(f"seed: a list of num_envs={n} seeds expected, got {len(seed)}")
        mask = None
        if options is not None and "reset_mask" in options:
            options = dict(options)
            mask = options.pop("reset_mask")
            if not (isinstance(mask, np.ndarray) and mask.shape == (n,)
                    and mask.dtype == np.bool_ and mask.any()):
                raise ValueError(f"options['reset_mask']: expected a ({n},) bool numpy "
                                 f"array with a True value, got {mask!r}")
        self._run(COMMAND, self._slice.reset, "reset", seed, options, mask)
        return self._views["observations"].copy(), self._infos(mask)

    def step(self, actions) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                     dict[str, Any]]:
        """Step every env with its row of ``actions`` (num_envs, 3), in [-1, 1]; an env
        whose episode ended at the last step is reset instead (NEXT_STEP autoreset).

        Returns:
            observations (num_envs, 15) float32, rewards (num_envs,) float64,
            terminations and truncations (num_envs,) bool, and the batched info.

        Raises:
            ValueError: ``actions`` of the wrong shape, or not finite (naming the env);
                the vector env stays open.
        """
        return self._step(actions, STEP)

    def _step(self, actions, message: bytes):
        """``step``, with ``message`` (``STEP``, or ``NOOP`` for benchmarks/env.py's
        timing of the parent: the workers answer at once) sent to the workers."""
        self._check_open()
        actions = np.asarray(actions, dtype=float)
        if actions.shape != self._actions.shape:
            raise ValueError(f"actions: expected an array of shape {self._actions.shape} "
                             f"(num_envs, 3: propeller, rudder, stern planes), got shape "
                             f"{actions.shape}")
        if not np.isfinite(actions).all():  # refused here, before any env steps: open
            k = int(np.flatnonzero(~np.isfinite(actions).all(axis=1))[0])
            raise ValueError(f"actions: expected finite numbers (propeller, rudder, stern "
                             f"planes; each clipped to [-1, 1]), got {actions[k].tolist()!r} "
                             f"for env {k}")
        self._actions[:] = actions
        self._run(message, self._slice.step if message == STEP else None)
        views = self._views
        return (views["observations"].copy(), views["rewards"].copy(),
                views["terminations"].copy(), views["truncations"].copy(),
                self._infos(None))

    def _infos(self, mask: np.ndarray | None) -> dict[str, np.ndarray]:
        """Copies of the info arrays with their ``_key`` masks (every env's, or those of
        a reset's ``mask``: the others' values zero, as ``VectorEnv._add_info`` leaves
        them)."""
        infos = {}
        if mask is None:  # every step: the fast path (masks: rows of one fresh array)
            rows = self._all_true.copy()
            for (key, mask_key, view), row in zip(self._info_views, rows, strict=True):
                infos[key] = view.copy()
                infos[mask_key] = row
            return infos
        for key, mask_key, view in self._info_views:
            value = view.copy()
            value[~mask] = 0
            infos[key], infos[mask_key] = value, mask.copy()
        return infos

    def close_extras(self, **kwargs: Any) -> None:
        """Stop the workers and free the shared memory."""
        self._actions = None
        self._info_views = []
        if self._slice is not None:
            self._slice.close()
            self._slice = None
        self._finalizer()
