"""``auvsim serve --dvl a50``: a socket client reads every report of a mission and checks
each field against the dataset's arrays; the commands; stopping leaves no thread, process
or open port; a port in use, an unknown mission and a file that is no dataset are refused
in one line. Timing is not checked here (``benchmarks/serve.py`` measures it)."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import mission

from auvsim.config import MissionConfig
from auvsim.data.reader import open_dataset
from auvsim.interop.a50 import (
    SETTINGS,
    DeadReckoning,
    Lateness,
    figure_of_merit,
    respond,
    rpy_deg,
    serve,
)
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from auvsim.runs.presets import preset

REPO = Path(__file__).resolve().parent.parent
RATE = 5.0  # Hz, pings


@pytest.fixture(scope="module")
def dataset(dataset_of) -> Path:
    """Two 40 s zigzag missions with the navigator's sensors, pinging at 5 Hz, with
    more lost pings and beams than the preset (some pings without velocity, some on three
    beams, a stretch of water track) and beam noise that does not grow with speed, so
    that the covariance has a closed form."""
    base = preset("navigator")
    dvl = dataclasses.replace(base.dvl, rate_hz=RATE, noise_speed_coeff=0.0,
                              ping_dropout_rate=0.08, dropout_rate=0.08,
                              beam_failures=((1, 10.0, 16.0),),
                              lock_loss_intervals=((25.0, 29.0),))
    missions = tuple(MissionConfig(name=name, seed=seed, scenario=dataclasses.replace(
        mission(name="zigzag").scenario, name="zigzag", duration=40.0, depth=20.0))
        for name, seed in (("a", 3), ("b", 4)))
    return dataset_of(dataclasses.replace(base, dvl=dvl, missions=missions), "serve")


def play(path: Path, commands: list[dict] = (), **options) -> tuple[list[dict], dict]:
    """Serve ``path`` from a thread on an ephemeral port, waiting for the client; the
    client sends ``commands`` and reads every line until the server closes. Returns the
    objects read and the server's summary."""
    where: queue.Queue = queue.Queue()
    summary: dict = {}
    options = {"mission": "a", **options}
    thread = threading.Thread(target=lambda: summary.update(serve(
        path, port=0, wait_for_client=True, ready=lambda h, p, _: where.put((h, p)),
        **options)))
    thread.start()
    host, port = where.get(timeout=30)
    with socket.create_connection((host, port), timeout=30) as client:
        for command in commands:
            client.sendall((json.dumps(command) + "\n").encode())
        data = b""
        while chunk := client.recv(1 << 20):
            data += chunk
    thread.join(timeout=30)
    assert not thread.is_alive()
    return [json.loads(line) for line in data.decode().splitlines()], summary


def test_every_report_holds_the_dataset(dataset):
    lines, summary = play(dataset, [{"command": "get_config"}], mission="b", speed=200.0)
    responses = [x for x in lines if x.get("type") == "response"]
    assert responses == [{"response_to": "get_config", "success": True, "error_message": "",
                          "result": SETTINGS, "format": "json_v3.1", "type": "response"}]
    reports = [x for x in lines if x.get("type") != "response"]
    velocity, position = reports[0::2], reports[1::2]  # in ping order, one of each per ping
    assert [r["type"] for r in velocity] == ["velocity"] * len(velocity)
    assert [r["type"] for r in position] == ["position_local"] * len(position)

    with open_dataset(dataset) as ds:
        m = ds.missions["b"]
        dvl, a = m.dvl, m.attrs
        t, v_ls, beams, ranges = dvl.time, dvl.velocity_ls, dvl.beam_velocity, dvl.beam_range
        valid, status, mode = dvl.valid, dvl.status, dvl.mode
        quaternion = m.truth.quaternion[m.imu.index_of_dvl]
        position_ned = m.truth.position_ned[m.imu.index_of_dvl]
    assert len(velocity) == len(position) == len(t) == summary["reports"] == 200
    assert summary["mission"] == "b" and summary["clients"] == 1

    alpha = math.radians(30.0)
    h = np.array([[math.cos(p) * math.sin(alpha), math.sin(p) * math.sin(alpha),
                   math.cos(alpha)] for p in np.arange(4) * math.pi / 2 + math.pi / 4])
    noise, slow = a["dvl_noise_std"], a["dvl_slow_error_std"]
    locked_all = valid & np.isfinite(beams) & np.isin(status, (0, 9))
    kinds = set()
    for n, r in enumerate(velocity):
        locked = locked_all[n]
        ok = bool(mode[n] == 0 and np.isfinite(v_ls[n]).all())
        kinds.add((ok, int(locked.sum())))
        assert r["velocity_valid"] is ok
        assert r["format"] == "json_v3.1" and r["status"] == 0
        assert r["time"] == pytest.approx(1e3 * ((t[n] - t[n - 1]) if n else 1 / RATE))
        assert r["time_of_validity"] - velocity[0]["time_of_validity"] == pytest.approx(
            1e6 * (t[n] - t[0]), abs=1)
        assert isinstance(r["time_of_transmission"], int)
        assert [x["id"] for x in r["transducers"]] == [0, 1, 2, 3]
        for k, x in enumerate(r["transducers"]):
            assert x["beam_valid"] is bool(locked[k])
            assert x["velocity"] == (beams[n, k] if locked[k] else 0.0)  # exact, via repr
            assert x["distance"] == (ranges[n, k] if locked[k] else -1.0)
            assert x["rssi"] >= x["nsd"]
        altitude = np.mean(ranges[n, locked]) * math.cos(alpha) if locked.any() else -1.0
        assert r["altitude"] == pytest.approx(altitude, rel=1e-12)
        if not ok:
            assert [r["vx"], r["vy"], r["vz"], r["fom"]] == [0.0, 0.0, 0.0, -1.0]
            assert np.all(np.array(r["covariance"]) == -1.0)
            continue
        assert [r["vx"], r["vy"], r["vz"]] == v_ls[n].tolist()
        # White beam noise of one std through the LS over the beams used, plus the shared
        # slow error: the inverse normal matrix, in closed form on four beams.
        hu = h[locked]
        expected = noise**2 * np.linalg.inv(hu.T @ hu) + slow**2 * np.eye(3)
        if locked.all():
            closed = np.diag([1 / (2 * math.sin(alpha) ** 2)] * 2 + [1 / (4 * math.cos(alpha)
                                                                        ** 2)])
            np.testing.assert_allclose(expected, noise**2 * closed + slow**2 * np.eye(3),
                                       atol=1e-15)
        np.testing.assert_allclose(r["covariance"], expected, rtol=1e-9, atol=1e-15)
        assert r["fom"] == pytest.approx(math.sqrt(np.linalg.eigvalsh(expected)[-1]),
                                         rel=1e-9)
    # The mission had every case: four beams, three, and no velocity.
    assert {(True, 4), (True, 3)} <= kinds and any(not ok for ok, _ in kinds)

    # Dead reckoning: the DVL's attitude relative to the first ping's, exactly; the
    # position within the DVL's errors of the truth's displacement in that frame.
    mounting = rotation_rpy(*np.radians(a["dvl_mounting_rpy_deg"])) @ rotation_rpy(
        *np.radians(a["dvl_misalignment_rpy_deg"]))
    frames = rotation_matrices(quaternion) @ mounting
    for n, r in enumerate(position):
        relative = frames[0].T @ frames[n]
        assert [r["roll"], r["pitch"], r["yaw"]] == pytest.approx(rpy_deg(relative),
                                                                  abs=1e-9)
        assert r["ts"] == pytest.approx(velocity[n]["time_of_validity"] / 1e6, abs=1e-6)
        assert r["status"] == (0 if velocity[n]["velocity_valid"] else 1)
    lever = np.asarray(a["dvl_position_body"])
    rotation = rotation_matrices(quaternion)
    dvl_ned = position_ned + rotation @ lever
    moved = frames[0].T @ (dvl_ned[-1] - dvl_ned[0])
    last = position[-1]
    assert abs(moved[0]) > 50  # it went somewhere
    # 40 s at a few cm/s of DVL error (biases, the slow error) and the rectangle rule
    np.testing.assert_allclose([last["x"], last["y"], last["z"]], moved, atol=2.0)
    assert 0 < position[1]["std"] < last["std"]
    yaws = [r["yaw"] for r in position]
    assert max(yaws) - min(yaws) > 10  # a zigzag: the attitude moved


def test_several_clients_read_the_same_stream(dataset):
    """Two clients connected before the first ping read the same bytes: every report,
    written once for all."""
    clients: queue.Queue = queue.Queue()

    def connect(host, port, _):  # from the server's thread, before it plays
        for _ in range(2):
            clients.put(socket.create_connection((host, port), timeout=30))

    thread = threading.Thread(target=serve, args=(dataset, "a"), kwargs=dict(
        port=0, speed=500.0, wait_for_client=True, ready=connect))
    thread.start()
    streams = [b"", b""]

    def read(i: int, client: socket.socket) -> None:
        with client:
            while chunk := client.recv(1 << 20):
                streams[i] += chunk

    readers = [threading.Thread(target=read, args=(i, clients.get(timeout=30)))
               for i in range(2)]
    for reader in readers:
        reader.start()
    for reader in [*readers, thread]:
        reader.join(timeout=30)
    assert streams[0] == streams[1] and streams[0].count(b"\n") == 400  # 200 pings x 2


def test_commands():
    settings, dr = dict(SETTINGS), DeadReckoning()

    def ask(command) -> dict:
        line = command if isinstance(command, bytes) else json.dumps(command).encode()
        reply = respond(line, settings, dr)
        assert set(reply) == {"response_to", "success", "error_message", "result", "format",
                              "type"} and reply["type"] == "response"
        assert bool(reply["error_message"]) is not reply["success"]
        return reply

    assert ask({"command": "set_config", "parameters": {"speed_of_sound": 1480,
                                                        "range_mode": "wt"}})["success"]
    assert ask({"command": "get_config"})["result"] == {
        **SETTINGS, "speed_of_sound": 1480.0, "range_mode": "wt"}
    for bad in ({"speed_of_sound": 900}, {"mounting_rotation_offset": "x"},
                {"acoustic_enabled": 1}, {"colour": "red"}, {}):
        reply = ask({"command": "set_config", "parameters": bad})
        assert not reply["success"] and reply["response_to"] == "set_config"
    assert settings["speed_of_sound"] == 1480.0  # a refused set changes nothing
    assert ask({"command": "calibrate_gyro"})["success"]
    assert ask({"command": "reset_dead_reckoning"})["success"] and dr.origin is None
    assert not ask({"command": "trigger_ping"})["success"]
    reply = ask({"command": "get_protocol_version"})
    assert not reply["success"] and "get_protocol_version" in reply["error_message"]
    assert ask(b"{not json")["response_to"] is None
    assert ask(b"[1, 2]")["response_to"] is None


def test_reset_over_the_socket_zeroes_the_dead_reckoning(dataset):
    lines, _ = play(dataset, [{"command": "reset_dead_reckoning"}], speed=100.0)
    reply = next(i for i, x in enumerate(lines) if x.get("type") == "response")
    after = next(x for x in lines[reply:] if x.get("type") == "position_local")
    assert (after["x"], after["y"], after["z"], after["std"]) == (0.0,) * 4
    # the attitude relative to itself: zero but for the rounding of R^T R
    assert [after["roll"], after["pitch"], after["yaw"]] == pytest.approx([0, 0, 0],
                                                                          abs=1e-12)


def test_lateness_is_measured_once_the_lines_are_written(dataset, monkeypatch):
    """Encoding a report's lines takes 2 x 4 ms here: the lateness counts it (it is
    measured after the lines are written, not when the report is built)."""
    dumps = json.dumps

    def slow(*args, **kwargs):
        end = time.monotonic() + 0.004
        while time.monotonic() < end:
            pass
        return dumps(*args, **kwargs)

    monkeypatch.setattr(json, "dumps", slow)
    _, summary = play(dataset, speed=20.0)
    lateness = summary["lateness"]
    assert lateness.count == summary["reports"] == 200
    assert lateness.median() >= 0.008 and lateness.largest >= 0.008
    assert lateness.over == lateness.count  # all over 5 ms


def test_lateness_statistics_keep_constant_memory():
    """Over more reports than the reservoir holds: the count, the largest and the count
    over 5 ms exact, the median from the sample within a few percentiles of the true
    one, the memory the reservoir's."""
    values = np.random.default_rng(1).exponential(0.002, 50_000)
    lateness = Lateness()
    for v in values[:100]:
        lateness.add(float(v))
    assert lateness.median() == np.median(values[:100])  # exact while the sample is all
    for v in values[100:]:
        lateness.add(float(v))
    assert lateness.count == len(values) and lateness.largest == values.max()
    assert lateness.over == int((values > 0.005).sum())
    assert len(lateness.sample) == Lateness.RESERVOIR
    rank = (values < lateness.median()).mean()
    assert 0.47 < rank < 0.53  # the sample median's rank among all values


def test_figure_of_merit_of_the_documents_example():
    """The protocol document's example report: its covariance and its fom."""
    covariance = np.array([
        [2.4471841442164077e-08, -3.3937477272871774e-09, -1.6659699175747278e-09],
        [-3.3937477272871774e-09, 1.4654466085062268e-08, 4.0409570134514183e-10],
        [-1.6659699175747278e-09, 4.0409570134514183e-10, 1.5971971523143225e-09]])
    assert figure_of_merit(covariance) == pytest.approx(0.00016016385052353144, rel=1e-8)


def free_to_bind(host: str, port: int) -> bool:
    try:
        socket.create_server((host, port)).close()
        return True
    except OSError:
        return False


def test_stop_leaves_no_thread_and_no_port(dataset):
    before = threading.active_count()
    where: queue.Queue = queue.Queue()
    stop = threading.Event()
    thread = threading.Thread(target=serve, args=(dataset, "a"), kwargs=dict(
        port=0, loop=True, stop=stop, speed=50.0, ready=lambda h, p, _: where.put((h, p))))
    thread.start()
    host, port = where.get(timeout=30)
    with socket.create_connection((host, port), timeout=10) as client:
        assert json.loads(client.makefile().readline())["type"] == "velocity"
        stop.set()
        thread.join(timeout=10)
        assert not thread.is_alive()
        while client.recv(1 << 20):  # what was sent, then the end: the server closed it
            pass
    assert free_to_bind(host, port)
    assert threading.active_count() == before


def run_cli(*args: str, **popen) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen([sys.executable, "-m", "auvsim", *args], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **popen)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_the_command_says_what_it_served_and_frees_the_port(dataset, signum):
    process = run_cli("serve", str(dataset), "--dvl", "a50", "--mission", "a", "--port", "0",
                      "--loop")
    try:
        line = process.stdout.readline()
        port = int(line.split("127.0.0.1:")[1].split(":")[0])
        with socket.create_connection(("127.0.0.1", port), timeout=10) as client:
            client.makefile().readline()  # it serves
            process.send_signal(signum)
            out, err = process.communicate(timeout=20)
    finally:  # a server that ignored the signal is not left serving
        if process.poll() is None:
            process.kill()
            process.wait()
    # A server's stop: what it served, exit 0.
    assert (process.returncode, err) == (0, "")
    served = out.splitlines()[-1]
    assert served.startswith("served ") and served.endswith(
        " velocity reports of a to 1 client(s); stopped by a signal")
    assert int(served.split()[1]) >= 1
    assert free_to_bind("127.0.0.1", port)
    with pytest.raises(ProcessLookupError):  # no process left behind
        os.kill(process.pid, 0)


def test_the_command_ends_with_the_mission(dataset):
    process = run_cli("serve", str(dataset), "--dvl", "a50", "--port", "0",
                      "--speed", "1000", "--mission", "a")
    out, err = process.communicate(timeout=60)
    assert process.returncode == 0, err
    assert out.splitlines()[-1] == "served 200 velocity reports of a to 0 client(s)"


def test_bad_input_one_line_exit_2(dataset, tmp_path):
    with socket.create_server(("127.0.0.1", 0)) as held:
        port = held.getsockname()[1]
        process = run_cli("serve", str(dataset), "--dvl", "a50", "--mission", "a", "--port",
                          str(port))
        out, err = process.communicate(timeout=60)
        assert process.returncode == 2 and out == ""
        assert err.splitlines() == [f"auvsim: error: --port {port} is in use on 127.0.0.1; "
                                    "expected a free port (another server, or an A50 "
                                    "driver's simulator, holds it)"]
    text = tmp_path / "notes.h5"
    text.write_text("not a dataset")
    for args, says in (
            (["--mission", "nope"], "--mission 'nope': no such mission; expected one of a, b"),
            ([], "--mission: the dataset has 2 missions (a, b); expected one named"),
            (["--mission", "a", "--speed", "0"], "--speed expected a factor > 0"),
            (["--mission", "a", "--port", "70000"], "--port expected a TCP port in [0, 65535]"),
            (["--mission", "a", "--host", "nosuchhost.invalid"],
             "--host 'nosuchhost.invalid': not a host name or address here")):
        process = run_cli("serve", str(dataset), "--dvl", "a50", *args)
        out, err = process.communicate(timeout=60)
        assert process.returncode == 2 and len(err.splitlines()) == 1 and says in err, err
    process = run_cli("serve", str(text), "--dvl", "a50")
    out, err = process.communicate(timeout=60)
    assert process.returncode == 2 and len(err.splitlines()) == 1 and "notes.h5" in err, err
    process = run_cli("serve", str(dataset), "--dvl", "a125")
    out, err = process.communicate(timeout=60)
    assert process.returncode == 2 and len(err.splitlines()) == 1 and "--dvl" in err, err
