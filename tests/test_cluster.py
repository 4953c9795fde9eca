"""``auvsim generate --cluster`` on real Dask LocalClusters of worker processes (issue 12):
the same data as the built-in pool for any number of workers, resume after ``kill -9`` of
the client or of a worker, the first failure and Ctrl-C stopping the run, one line for a
bad or unreachable address, and no process left behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from contextlib import suppress
from pathlib import Path

import psutil
import pytest
from conftest import FAILING_TOML, CountingBar, flat, mission
from test_kill import as_from_a_terminal, process_tree, still_running, wait_for
from test_shards import assert_same_data

from auvsim import cli
from auvsim.data.schema import INDEX, SHARDS
from auvsim.errors import ConfigError
from auvsim.runs.generate import generate

pytest.importorskip("distributed")
pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(),
                                reason="follows the process tree in /proc")

CONFIG = flat(*(mission(f"m{i}", 10 + i, duration=25.0 + 5 * i, heading_deg=30.0 * i)
                for i in range(4)))
# Long enough to be killed midway, short enough for CI: 10 manoeuvres of 120 s.
RUN = ["--preset", "maneuvers", "--duration", "120", "--quiet"]
# So long that a Ctrl-C always finds the run under way (one as it ends is a test of its own).
ENDLESS = ["--preset", "maneuvers", "--duration", "3600", "--quiet"]


def _children() -> set[int]:
    """This process's descendants but multiprocessing's resource tracker and forkserver,
    which it starts once and which end with it (the workers the forkserver forks count)."""
    me = psutil.Process()
    servers = {p.pid for p in me.children()
               if any(s in " ".join(p.cmdline()) for s in ("resource_tracker", "forkserver"))}
    return {p.pid for p in me.children(recursive=True)} - servers


@pytest.fixture(autouse=True)
def no_process_left():
    """Every test's clusters, workers and children end with it."""
    before = _children()
    yield
    wait_for(lambda: not _children() - before, "the test's processes to end", timeout=20)


def _cli(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "auvsim.cli", "generate", *args],
                            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=as_from_a_terminal)


def _finished(*args: str) -> str:
    proc = _cli(*args)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    return out


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """``RUN`` uninterrupted, by the built-in path, as one file."""
    path = tmp_path_factory.mktemp("ref") / "ref.h5"
    _finished(*RUN, "--workers", "1", "--out", str(path))
    return path


def test_local_1_local_2_and_the_pool_give_the_same_data(tmp_path, monkeypatch):
    pool = tmp_path / "pool.h5"
    generate(CONFIG, pool, workers=2, progress=False)
    monkeypatch.setattr("auvsim.runs.generate.tqdm", CountingBar)
    for name, cluster in (("one", "local:1"), ("two", "local:2")):
        monkeypatch.setattr(CountingBar, "updates", [])
        summary = generate(CONFIG, f"{tmp_path / name}/", cluster=cluster, progress=False)
        assert (summary["shards"], summary["kept"]) == (4, 0)
        assert sum(CountingBar.updates) == sum(m.scenario.duration for m in CONFIG.missions)
        assert_same_data(pool, tmp_path / name)
    generate(CONFIG, tmp_path / "file.h5", cluster="local:2", progress=False)  # parts, copied
    assert_same_data(pool, tmp_path / "file.h5")


def _shards_done(folder: Path) -> int:
    return len(list((folder / SHARDS).glob("part-*.h5")))


def test_kill_9_of_the_client_resumes_to_the_same_data(tmp_path, reference):
    out = tmp_path / "rm"
    proc = _cli(*RUN, "--cluster", "local:2", "--out", f"{out}/")
    try:
        wait_for(lambda: proc.poll() is None and _shards_done(out) >= 1, "a first shard",
                  timeout=240)
        tree = process_tree(proc.pid)
        assert len(tree) >= 3, tree  # the client and its two workers (and a tracker)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        proc.kill()
        proc.communicate()
    wait_for(lambda: not still_running(tree), "the workers to end with their client", timeout=20)
    kept = _shards_done(out)
    assert 1 <= kept < 10 and not (out / INDEX).exists()
    said = _finished(*RUN, "--cluster", "local:2", "--out", f"{out}/")
    assert f"10 mission(s) in 10 shard(s), {kept} kept from an earlier run" in said
    assert_same_data(reference, out)
    assert sorted(p.name for p in out.iterdir()) == [INDEX, SHARDS]
    assert len(list((out / SHARDS).iterdir())) == 10  # no temporaries left


def _workers(pid: int) -> list[psutil.Process]:
    """The local cluster's workers: what its forkserver, a child of ``pid``, forked."""
    return [w for server in psutil.Process(pid).children()
            if "forkserver import main" in " ".join(server.cmdline())
            for w in server.children()]


def test_kill_9_of_a_worker_midway_retries_its_mission(tmp_path, reference):
    out = tmp_path / "rm"
    proc = _cli(*RUN, "--cluster", "local:2", "--out", f"{out}/")
    try:
        def simulating() -> bool:
            assert proc.poll() is None, proc.communicate()
            return bool(list(out.glob(".*.parts/*.progress"))) and len(_workers(proc.pid)) == 2

        wait_for(simulating, "a mission under way", timeout=240)
        victim = _workers(proc.pid)[0]
        victim.kill()
        # The nanny's new worker forks from the forkserver too, as the first did.
        wait_for(lambda: proc.poll() is None and len(_workers(proc.pid)) == 2
                 and victim.pid not in {w.pid for w in _workers(proc.pid)},
                 "the nanny's new worker, forked", timeout=120)
        out_text, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert not victim.is_running()
    assert "10 mission(s) in 10 shard(s)" in out_text
    assert_same_data(reference, out)
    assert len(list((out / SHARDS).iterdir())) == 10


def test_ctrl_c_cancels_the_run_and_ends_the_cluster(tmp_path):
    out = tmp_path / "rm"
    proc = _cli(*ENDLESS, "--cluster", "local:2", "--out", f"{out}/")
    try:
        wait_for(lambda: proc.poll() is None and bool(list(out.glob(".*.parts/*.progress"))),
                  "a mission under way", timeout=240)
        tree = process_tree(proc.pid)
        os.killpg(proc.pid, signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            alive = []
            for pid in still_running(tree):
                with suppress(psutil.Error):
                    alive.append(" ".join(psutil.Process(pid).cmdline())[:120])
            pytest.fail(f"the run did not end within 60 s of Ctrl-C; still running: {alive}")
    finally:
        with suppress(ProcessLookupError):  # the whole group, so nothing outlives a failure
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == 130, err
    wait_for(lambda: not still_running(tree), "the cluster to end", timeout=20)
    whole = sorted((out / SHARDS).glob("part-*.h5")) if out.exists() else []
    if out.exists():  # whole shards, kept for the next run, and nothing else
        assert [p.name for p in out.iterdir()] == [SHARDS]
        assert all(p.name.startswith("part-") for p in (out / SHARDS).iterdir())
    # One line (no worker's), naming the whole shards it leaves, or saying there are none.
    said = (f"auvsim: interrupted; {', '.join(map(str, whole[:3]))}"
            + (f" and {len(whole) - 3} more" if len(whole) > 3 else "")
            + " had been written whole before it, nothing else was" if whole
            else "auvsim: interrupted; nothing was written")
    assert err.splitlines() == [said]


def test_ctrl_c_while_the_cluster_starts_stops_the_run_once_it_has(tmp_path):
    """The workers fork from a forkserver deaf to the group's Ctrl-C, so none stops in its
    imports with a traceback of its own; the client holds the Ctrl-C until the cluster
    has started (one stopped half-started would leave its workers), then stops."""
    out = tmp_path / "rm"
    proc = _cli(*ENDLESS, "--cluster", "local:2", "--out", f"{out}/")
    try:
        def starting() -> bool:
            assert proc.poll() is None, proc.communicate()
            return any("forkserver import main" in " ".join(p.cmdline())
                       for p in psutil.Process(proc.pid).children())

        wait_for(starting, "the cluster's forkserver", timeout=60)
        # While it starts the forkserver, this process ignores SIGINT for a few ms, so that
        # the server is deaf to it (``auvsim.processes.start_forkserver``: a Ctrl-C then is
        # lost); the test's Ctrl-C comes after, as a person's would. Under load it had come
        # inside them: the run went on to its end, exit 0.
        wait_for(lambda: not _ignores(proc.pid, signal.SIGINT), "SIGINT heard again",
                 timeout=60)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        # Its session (it has one of its own): the workers started after the Ctrl-C too.
        wait_for(lambda: not _in_session(proc.pid), "the cluster to end", timeout=20)
    finally:
        with suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert (proc.returncode, err) == (130, "auvsim: interrupted; nothing was written\n")
    assert not any((out / SHARDS).glob("*")) if out.exists() else True


def _ignores(pid: int, signum: int) -> bool:
    """Whether process ``pid`` ignores signal ``signum`` now (Linux: its SigIgn mask)."""
    with open(f"/proc/{pid}/status") as f:
        mask = next(line for line in f if line.startswith("SigIgn:")).split()[1]
    return bool(int(mask, 16) >> (signum - 1) & 1)


def _in_session(sid: int) -> list[int]:
    """The processes of session ``sid`` still running (a zombie has ended)."""
    found = []
    for p in psutil.process_iter():
        with suppress(psutil.Error, OSError):  # ended meanwhile
            if os.getsid(p.pid) == sid and p.status() != psutil.STATUS_ZOMBIE:
                found.append(p.pid)
    return found


def test_a_local_cluster_that_does_not_close_in_time_has_its_workers_killed(monkeypatch):
    """A worker that never answers its nanny (here: the close itself gives up at once) must
    neither hold up the end of the run nor outlive it."""
    import distributed

    from auvsim.runs import cluster as cluster_module

    made = []
    real_local = cluster_module._local

    def local(*args):
        client, cluster = real_local(*args)
        made.append(cluster)
        monkeypatch.setattr(cluster, "close", _give_up)
        return client, cluster

    def _give_up(timeout=None):
        assert 0 < timeout <= cluster_module.CLOSE_S
        raise TimeoutError

    monkeypatch.setattr(cluster_module, "_local", local)
    try:
        with cluster_module.executor("local:1") as jobs:
            assert jobs.submit(sum, [1, 2]).result(timeout=60) == 3
            workers = [w.pid for w in made[0].workers.values()]
        assert len(workers) == 1
        wait_for(lambda: not psutil.pid_exists(workers[0])
                 or psutil.Process(workers[0]).status() == psutil.STATUS_ZOMBIE,
                 "the worker to be killed", timeout=10)
    finally:
        distributed.LocalCluster.close(made[0])  # its scheduler lives in this process


def test_a_ctrl_c_while_the_cluster_closes_is_held_until_it_has_closed(monkeypatch):
    """A Ctrl-C that came as the run ended broke into the cluster's close: Dask's exit hook
    then waited on the half-closed cluster and the workers outlived the command."""
    import distributed

    from auvsim.runs import cluster as cluster_module

    made = []
    real_local = cluster_module._local

    def local(*args):
        client, cluster = real_local(*args)
        made.append(cluster)
        real_close = cluster.close

        def close(timeout=None):
            signal.raise_signal(signal.SIGINT)  # as the close begins
            return real_close(timeout=timeout)

        monkeypatch.setattr(cluster, "close", close)
        return client, cluster

    monkeypatch.setattr(cluster_module, "_local", local)
    with pytest.raises(KeyboardInterrupt):
        with cluster_module.executor("local:1") as jobs:
            assert jobs.submit(sum, [1, 2]).result(timeout=60) == 3
            workers = [psutil.Process(w.pid) for w in made[0].workers.values()]
    assert made[0].status == distributed.core.Status.closed
    assert len(workers) == 1
    wait_for(lambda: not workers[0].is_running()
             or workers[0].status() == psutil.STATUS_ZOMBIE, "the worker to end", timeout=10)


def test_the_first_failure_stops_the_run(tmp_path, capsys):
    """Mission a reaches the seafloor within seconds; the long mission b is stopped."""
    toml = tmp_path / "fail.toml"
    toml.write_text(FAILING_TOML)
    started = time.perf_counter()
    assert cli.main(["generate", "--config", str(toml), "--cluster", "local:2", "--out",
                     f"{tmp_path / 'x'}/", "--quiet"]) == 2
    assert time.perf_counter() - started < 120  # b alone would take far longer
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "auvsim: error: a: the vehicle reached the seafloor" in err
    assert not (tmp_path / "x").exists()  # no shard was made: no folder either


@pytest.mark.parametrize("address, said", [
    ("nonsense", "--cluster 'nonsense': not a cluster address; expected local:N"),
    ("local:0", "--cluster 'local:0': expected at least one worker"),
    ("127.0.0.1:99999", "--cluster '127.0.0.1:99999': port 99999 is not a TCP port"),
    # Refused at once: said so, where the client had retried for its whole timeout.
    ("tcp://127.0.0.1:9", "--cluster 'tcp://127.0.0.1:9': nothing listens there (the "
     "connection was refused)"),
])
def test_a_bad_or_unreachable_address_gets_one_line(tmp_path, capsys, monkeypatch, address,
                                                    said):
    monkeypatch.setattr("auvsim.runs.cluster.CONNECT_TIMEOUT_S", 2.0)  # 10 s by default
    started = time.perf_counter()
    assert cli.main(["generate", "--duration", "5", "--cluster", address, "--out",
                     f"{tmp_path / 'x'}/", "--quiet"]) == 2
    assert time.perf_counter() - started < 30  # the connect timeout, no hang
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and said in err, err
    leftovers = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert leftovers == []


def test_a_peer_that_never_answers_is_given_up_on(tmp_path, monkeypatch):
    """Something that accepts the connection and says nothing: one line at the deadline."""
    import socket
    import threading

    from auvsim.runs.cluster import executor

    monkeypatch.setattr("auvsim.runs.cluster.HANDSHAKE_S", 1.0)  # 5 s by default
    server = socket.create_server(("127.0.0.1", 0))
    accepted = []
    threading.Thread(target=lambda: accepted.append(server.accept()), daemon=True).start()
    started = time.perf_counter()
    with pytest.raises(ConfigError, match="never answered as a Dask scheduler"):
        with executor(f"tcp://127.0.0.1:{server.getsockname()[1]}", timeout=1):
            pass
    assert time.perf_counter() - started < 15
    server.close()


def test_a_peer_that_answers_in_another_protocol_is_named_so(tmp_path, monkeypatch):
    """A web server where the scheduler was expected (its dashboard's port, say): its
    reply reads as no Dask message, and the line says something answered, not that
    nothing did."""
    import socket
    import threading

    from auvsim.runs.cluster import executor

    server = socket.create_server(("127.0.0.1", 0))

    def answer() -> None:
        while True:  # as a web server answers every connection (the address's probe too)
            conn, _ = server.accept()
            if not conn.recv(1024):  # the probe: connected, then gone
                conn.close()
                continue
            conn.sendall(b"HTTP/1.0 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 64)
            time.sleep(3)
            conn.close()
            return

    threading.Thread(target=answer, daemon=True).start()
    with pytest.raises(ConfigError, match="something answered there, but its reply read "
                                          "as no Dask message") as said:
        with executor(f"tcp://127.0.0.1:{server.getsockname()[1]}", timeout=2):
            pass
    assert "\n" not in str(said.value)
    assert "allocate" not in str(said.value)  # the misread bytes' size is not the user's
    server.close()


def test_without_dask_the_cluster_option_says_what_to_install(monkeypatch):
    from auvsim.runs.cluster import executor

    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails
    with pytest.raises(ConfigError, match=r"needs Dask distributed.*auvsim\[cluster\]"):
        with executor("local:1"):
            pass


def test_workers_and_a_cluster_are_one_or_the_other(tmp_path, capsys):
    assert cli.main(["generate", "--duration", "5", "--workers", "2", "--cluster", "local:1",
                     "--out", f"{tmp_path / 'x'}/", "--quiet"]) == 2
    assert "--workers: given with a cluster, whose own workers run the jobs" in \
        capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_scheduler_of_ones_own_with_a_worker_elsewhere(tmp_path, reference):
    """``dask scheduler`` and ``dask worker`` started apart, the worker in another working
    folder: a relative --out still lands where the command was run, the same data."""
    import json

    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    dask = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
    file = tmp_path / "scheduler.json"
    started = [subprocess.Popen(dask + ["--port", "0", "--no-dashboard", "--scheduler-file",
                                        str(file)], cwd=there, start_new_session=True,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        wait_for(file.exists, "the scheduler", timeout=60)
        wait_for(lambda: file.stat().st_size > 0, "the scheduler's file", timeout=10)
        address = json.loads(file.read_text())["address"]
        started.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads",
             "2", "--nworkers", "1", "--no-dashboard"], cwd=there, start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        proc = subprocess.run([sys.executable, "-m", "auvsim.cli", "generate", *RUN,
                               "--cluster", address, "--out", "rel/"], cwd=here,
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        assert_same_data(reference, here / "rel")
        assert list(there.iterdir()) == []  # nothing in the worker's working folder
    finally:
        for p in reversed(started):
            os.killpg(p.pid, signal.SIGTERM)
            p.wait(timeout=30)
