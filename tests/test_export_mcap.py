"""``auvsim export --to mcap``: a mission as a ROS 2 bag, read back by an independent reader.

The bag is read with rosbags (its own MCAP parser and CDR deserialiser, and the message
definitions embedded in the file: marine_acoustic_msgs is in none of its type stores), and
every message is compared with the dataset's arrays: float64 fields exactly, float32
fields as the float32 of the dataset's value, stamps as the nearest nanosecond. The
vectorised CDR bytes are checked against mcap_ros2's own encoder, and the file against
the mcap package's reader with its CRCs checked.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from auvsim.cli import main
from auvsim.data.beams import beam_matrix
from auvsim.data.reader import open_dataset
from auvsim.interop.cdr import FixedLayout
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset

rosbags = pytest.importorskip("rosbags.highlevel")
pytest.importorskip("mcap_ros2")

REPO = Path(__file__).resolve().parents[1]


def run(args: list[str]) -> tuple[int, str, str]:
    """The CLI's exit code, stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        code = main(args)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """12 s of the navigator preset, its DVL at 5 Hz with many dropouts (beams and pings
    that measured nothing, so validity and the no-velocity case are exercised) and
    mounted turned 45 deg, as Janus DVLs often are."""
    config = preset("navigator")
    first = config.missions[0]
    config = dataclasses.replace(
        config, missions=(dataclasses.replace(first, scenario=dataclasses.replace(
            first.scenario, duration=12.0)),),
        dvl=dataclasses.replace(config.dvl, rate_hz=5.0, dropout_rate=0.3,
                                ping_dropout_rate=0.1, mounting_rpy_deg=(0.0, 0.0, 45.0)))
    path = tmp_path_factory.mktemp("export") / "nav.h5"
    generate(config, path, workers=1, progress=False)
    return path


@pytest.fixture(scope="module")
def bag(dataset) -> Path:
    out = dataset.with_name("nav.mcap")
    code, printed, err = run(["export", str(dataset), "--to", "mcap", "--out", str(out)])
    assert (code, err) == (0, "")
    assert printed.startswith(f"wrote {out}: /imu/data ")
    return out


def read_bag(path: Path) -> dict[str, list[tuple[int, object]]]:
    """Topic -> [(log time ns, message)], by rosbags."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list] = {}
    with AnyReader([path]) as reader:
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, reader.deserialize(raw,
                                                                              conn.msgtype)))
        types = {c.topic: c.msgtype for c in reader.connections}
    out["_types"] = types
    return out


def ns_of(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def vec(items, fields="xyz") -> np.ndarray:
    return np.array([[getattr(v, f) for f in fields] for v in items])


def test_every_message_is_the_dataset(dataset, bag):
    topics = read_bag(bag)
    assert topics.pop("_types") == {
        "/imu/data": "sensor_msgs/msg/Imu", "/dvl/data": "marine_acoustic_msgs/msg/Dvl",
        "/depth/pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
        "/truth/odometry": "nav_msgs/msg/Odometry", "/tf_static": "tf2_msgs/msg/TFMessage"}
    with open_dataset(dataset) as ds:
        m = next(iter(ds.missions.values()))
        a = m.attrs

        imu = [msg for _, msg in topics["/imu/data"]]
        t = m.imu.time
        assert len(imu) == len(t)
        assert [s for s, _ in topics["/imu/data"]] == [ns_of(x) for x in imu]
        np.testing.assert_array_equal([ns_of(x) for x in imu], np.round(t * 1e9))
        assert np.abs(np.array([ns_of(x) for x in imu]) / 1e9 - t).max() <= 0.5e-9 + 1e-12
        np.testing.assert_array_equal(vec(x.angular_velocity for x in imu), m.imu.angular_rate)
        np.testing.assert_array_equal(vec(x.linear_acceleration for x in imu),
                                      m.imu.specific_force)
        rate = a["imu_rate_hz"]
        gyro = np.diag([a["imu_gyro_noise_density"] ** 2 * rate] * 3).ravel()
        accel = np.diag([a["imu_accel_noise_density"] ** 2 * rate] * 3).ravel()
        assert gyro[0] > 0 and accel[0] > 0
        for x in imu[::50]:
            np.testing.assert_array_equal(x.angular_velocity_covariance, gyro)
            np.testing.assert_array_equal(x.linear_acceleration_covariance, accel)
            assert x.orientation_covariance[0] == -1
            assert x.header.frame_id == "imu_link"

        dvl = [msg for _, msg in topics["/dvl/data"]]
        d = m.dvl
        valid, beams, ranges, mode = d.valid, d.beam_velocity, d.beam_range, d.mode
        measured = valid & np.isfinite(beams)
        locked = measured & np.isin(d.status, (0, 9))  # Status.OK, OUTLIER: bottom lock
        assert len(dvl) == len(d.time) and (~valid).any() and valid.any()
        np.testing.assert_array_equal([ns_of(x) for x in dvl], np.round(d.time * 1e9))
        np.testing.assert_array_equal(vec(x.velocity for x in dvl), d.velocity_ls)
        v = d.velocity_ls
        np.testing.assert_array_equal([x.course_gnd for x in dvl], np.arctan2(v[:, 1], v[:, 0]))
        np.testing.assert_array_equal([x.speed_gnd for x in dvl], np.hypot(v[:, 0], v[:, 1]))
        np.testing.assert_array_equal([x.range for x in dvl],
                                      np.where(locked, ranges, np.nan))
        np.testing.assert_array_equal([x.beam_velocity for x in dvl],
                                      beams.astype(np.float32))
        np.testing.assert_array_equal([x.beam_quality for x in dvl], locked.astype(float))
        np.testing.assert_array_equal([x.num_good_beams for x in dvl], measured.sum(axis=1))
        expected_mode = np.select([mode == 0, mode == 1], [1, 2], 0)
        np.testing.assert_array_equal([x.velocity_mode for x in dvl], expected_mode)
        angle = math.radians(a["beam_angle_deg"])
        h = beam_matrix(angle)
        for x in dvl:
            np.testing.assert_array_equal(vec(x.beam_unit_vec), h)
        good = locked & np.isfinite(ranges)
        with np.errstate(invalid="ignore", divide="ignore"):
            altitude = math.cos(angle) * (np.where(good, ranges, 0).sum(axis=1)
                                          / good.sum(axis=1))
        np.testing.assert_allclose([x.altitude for x in dvl], altitude, rtol=1e-12)
        none = ~np.isfinite(d.velocity_ls[:, 0])
        assert none.any()
        assert all(x.velocity_covar[0] == -1 for x in np.array(dvl, dtype=object)[none])

        depth = [msg for _, msg in topics["/depth/pose"]]
        np.testing.assert_array_equal([ns_of(x) for x in depth], np.round(m.depth.time * 1e9))
        np.testing.assert_array_equal([x.pose.pose.position.z for x in depth], m.depth.depth)
        z = a["depth_noise_std"] ** 2 + a["depth_resolution"] ** 2 / 12
        # only z is measured: every other pose component's variance is huge (unknown)
        np.testing.assert_array_equal(np.reshape(depth[0].pose.covariance, (6, 6)),
                                      np.diag([1e9, 1e9, z, 1e9, 1e9, 1e9]))
        assert depth[0].header.frame_id == "odom_ned"

        odom = [msg for _, msg in topics["/truth/odometry"]]
        truth = m.truth
        np.testing.assert_array_equal([ns_of(x) for x in odom], np.round(truth.time * 1e9))
        np.testing.assert_array_equal(vec(x.pose.pose.position for x in odom),
                                      truth.position_ned)
        np.testing.assert_array_equal(vec((x.pose.pose.orientation for x in odom), "wxyz"),
                                      truth.quaternion)
        np.testing.assert_array_equal(vec(x.twist.twist.linear for x in odom),
                                      truth.velocity_body)
        np.testing.assert_array_equal(vec(x.twist.twist.angular for x in odom),
                                      truth.angular_rate)
        assert (odom[0].header.frame_id, odom[0].child_frame_id) == ("odom_ned",
                                                                     "base_link_frd")

        [(_, tf)] = topics["/tf_static"]
        frames = {(x.header.frame_id, x.child_frame_id): x.transform for x in tf.transforms}
        np.testing.assert_array_equal(vec([frames["base_link_frd", "imu_link"].translation]),
                                      [a["imu_position_body"]])
        np.testing.assert_array_equal(vec([frames["base_link_frd", "dvl_link"].translation]),
                                      [a["dvl_position_body"]])
        q = frames["base_link_frd", "dvl_link"].rotation
        np.testing.assert_allclose(_rotation(q.w, q.x, q.y, q.z),
                                   rotation_rpy(*np.radians(a["dvl_mounting_rpy_deg"])),
                                   atol=1e-15)
        assert list(a["dvl_mounting_rpy_deg"]) == [0, 0, 45]
        # odom_ned's north is odom's (ENU) y, its down odom's -z.
        q = frames["odom", "odom_ned"].rotation
        rot = _rotation(q.w, q.x, q.y, q.z)
        np.testing.assert_allclose(rot @ [1, 0, 0], [0, 1, 0], atol=1e-15)
        np.testing.assert_allclose(rot @ [0, 0, 1], [0, 0, -1], atol=1e-15)


def _janus_covariance(sigma: float, slow: float, angle: float) -> np.ndarray:
    """The covariance of the least squares of four Janus beams at ``angle`` from the z
    axis, each with white noise ``sigma`` and all sharing a velocity error of std
    ``slow`` per axis: H^T H = diag(2 sin^2, 2 sin^2, 4 cos^2) for beams at azimuths 90 deg
    apart, so the white part is sigma^2 diag(1 / (2 sin^2), 1 / (2 sin^2), 1 / (4 cos^2)),
    and the shared error passes through the least squares unchanged."""
    white = sigma**2 * np.diag([1 / (2 * math.sin(angle) ** 2)] * 2
                               + [1 / (4 * math.cos(angle) ** 2)])
    return white + slow**2 * np.eye(3)


def test_the_dvl_covariances_are_the_noise_models(dataset, bag):
    """The velocity's and each beam's covariance from the config's noise settings, in
    closed form on the pings of four beams: in bottom track the white beam noise grows
    with the true speed (noise_std + noise_speed_coeff |v|), in water track it is
    water_track_noise_std, and the Gauss-Markov slow error (slow_error_std per axis) adds
    to both."""
    from auvsim.config import Config

    dvl = [msg for _, msg in read_bag(bag)["/dvl/data"]]
    with open_dataset(dataset) as ds:
        m = next(iter(ds.missions.values()))
        c = Config.from_json(ds.config_json).dvl
        d = m.dvl
        measured = d.valid & np.isfinite(d.beam_velocity)
        speed = np.linalg.norm(d.velocity, axis=1)
        mode = d.mode
    assert c.noise_speed_coeff > 0 and c.slow_error_std > 0 and c.water_track
    assert c.noise_range_coeff == 0  # the navigator's: no range term
    angle = math.radians(c.beam_angle_deg)
    seen = set()
    for n, x in enumerate(dvl):
        if not measured[n].all() or mode[n] not in (0, 1):
            continue
        sigma = (c.noise_std + c.noise_speed_coeff * speed[n] if mode[n] == 0
                 else c.water_track_noise_std)
        np.testing.assert_allclose(np.reshape(x.velocity_covar, (3, 3)),
                                   _janus_covariance(sigma, c.slow_error_std, angle),
                                   rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(x.beam_velocity_covar,
                                   np.float32(sigma**2 + c.slow_error_std**2), rtol=1e-6)
        seen.add(int(mode[n]))
    assert seen == {0, 1}  # bottom track and water track were both checked
    for n, x in enumerate(dvl):
        assert all((cov == -1) == (not used) for cov, used in
                   zip(x.beam_velocity_covar, measured[n], strict=True))


def test_water_track_beams_give_no_seafloor(dataset, bag):
    """A water-track ping's beams measured the water: a beam without bottom lock gives
    no range, no altitude and no beam quality, though ``dvl/valid`` flags it."""
    dvl = [msg for _, msg in read_bag(bag)["/dvl/data"]]
    with open_dataset(dataset) as ds:
        d = next(iter(ds.missions.values())).dvl
        measured = d.valid & np.isfinite(d.beam_velocity)
        unlocked = measured & ~np.isin(d.status, (0, 9))
        water = d.mode == 1
        ranges = d.beam_range
    # water-track pings with measured, unlocked beams that have a seafloor range
    cases = np.flatnonzero(water & (unlocked & np.isfinite(ranges)).any(axis=1))
    assert len(cases) > 0
    for n in cases:
        x = dvl[n]
        assert x.velocity_mode == 2
        for k in np.flatnonzero(unlocked[n]):
            assert x.beam_quality[k] == 0 and math.isnan(x.range[k])
        # the altitude: the locked beams' ranges alone (NaN with none)
        locked = measured[n] & ~unlocked[n] & np.isfinite(ranges[n])
        expected = (np.mean(ranges[n, locked]) * math.cos(math.radians(30.0))
                    if locked.any() else math.nan)
        np.testing.assert_allclose(x.altitude, expected, rtol=1e-12)


def _rotation(w, x, y, z) -> np.ndarray:
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _plain(value):
    """A rosbags message as the dicts and lists mcap_ros2's encoder takes."""
    if dataclasses.is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


def test_the_vectorised_bytes_are_mcap_ros2s(bag):
    """Sample messages of every topic, decoded by rosbags and encoded again by mcap_ros2's
    own (one message at a time) encoder, give the bag's bytes."""
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    from auvsim.interop.ros2 import encoded_once  # mcap_ros2.writer.Writer's encoding

    raw: dict[str, list[bytes]] = {}
    with open(bag, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        for _, channel, message in reader.iter_messages():
            raw.setdefault(channel.topic, []).append(message.data)
    assert summary.statistics.message_count == sum(map(len, raw.values()))
    with AnyReader([bag]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for topic, payloads in raw.items():
            for data in payloads[:: max(1, len(payloads) // 7)]:
                message = reader.deserialize(data, types[topic])
                assert encoded_once(types[topic], _plain(message)) == data, topic


def test_tf_static_is_offered_latched_as_rosbag2_records_it(bag):
    """/tf_static's channel offers one QoS profile, in rosbag2's YAML (rosbag2_storage,
    qos.cpp, the integer form of metadata versions up to 8): keep last 1, reliable (1),
    transient local (1), so that ``ros2 bag play`` latches it for late subscribers; the
    other topics offer none (the player's defaults). The "rosbag2" Metadata record
    without serialized metadata makes newer players read that integer form."""
    import yaml
    from mcap.reader import make_reader

    with open(bag, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        channels = {c.topic: c.metadata for c in reader.get_summary().channels.values()}
        records = {r.name: r.metadata for r in reader.iter_metadata()}
    [profile] = yaml.safe_load(channels.pop("/tf_static")["offered_qos_profiles"])
    assert profile == {"history": 1, "depth": 1, "reliability": 1, "durability": 1,
                       "deadline": {"sec": 0, "nsec": 0}, "lifespan": {"sec": 0, "nsec": 0},
                       "liveliness": 1,
                       "liveliness_lease_duration": {"sec": 0, "nsec": 0},
                       "avoid_ros_namespace_conventions": False}
    assert all(m == {"offered_qos_profiles": ""} for m in channels.values())
    assert "serialized_metadata" not in records["rosbag2"]


def test_blocks_of_time_change_nothing_but_the_chunks(dataset, bag, tmp_path):
    """Written a second of mission at a time (12 blocks, each its own chunks), the bag holds
    the same messages, byte for byte, in the same order."""
    from mcap.reader import make_reader

    from auvsim.interop.ros2 import export_mcap

    small = tmp_path / "blocks.mcap"
    export_mcap(dataset, small, block_s=1.0)

    def messages(path):
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            chunks = reader.get_summary().statistics.chunk_count
            return chunks, [(c.topic, m.log_time, m.sequence, m.data)
                            for _, c, m in reader.iter_messages(log_time_order=False)]

    (chunks, expected), (more, got) = messages(bag), messages(small)
    assert more >= 12 > chunks
    assert got == expected


def test_the_progress_counts_the_missions_seconds(dataset, tmp_path, monkeypatch):
    """A long mission's export (a minute for 24 h) shows its progress in mission seconds,
    block by block, up to the mission's span."""
    from conftest import CountingBar

    from auvsim.interop import ros2

    monkeypatch.setattr(ros2, "tqdm", CountingBar)
    CountingBar.updates = []
    ros2.export_mcap(dataset, tmp_path / "p.mcap", block_s=1.0, progress=True)
    assert len(CountingBar.updates) >= 12 and all(n >= 0 for n in CountingBar.updates)
    assert sum(CountingBar.updates) == pytest.approx(12.0, abs=0.02)


def test_a_fixed_layout_refuses_what_it_cannot_hold():
    with pytest.raises(ValueError, match="sequence"):
        FixedLayout("tf2_msgs/msg/TFMessage", {})
    with pytest.raises(ValueError, match="header.frame_id"):
        FixedLayout("sensor_msgs/msg/Imu", {})
    with pytest.raises(ValueError, match="no string field child"):
        FixedLayout("sensor_msgs/msg/Imu", {"header.frame_id": "a", "child_frame_id": "b"})
    imu = FixedLayout("sensor_msgs/msg/Imu", {"header.frame_id": "imu_link"})
    # encapsulation 4; from the payload start: stamp 8, string length 4 and "imu_link\0" 9,
    # 3 bytes to reach 24 (a multiple of 8), then 4 + 9 + 3 + 9 + 3 + 9 float64
    assert imu.size == 4 + 8 + 4 + 9 + 3 + 8 * (4 + 9 + 3 + 9 + 3 + 9)


def test_topics_are_renamed_from_a_file(dataset, tmp_path):
    names = tmp_path / "topics.toml"
    names.write_text('imu = "/auv/imu"\ntruth = "/sim/truth"\n')
    out = tmp_path / "renamed.mcap"
    code, _, err = run(["export", str(dataset), "--to", "mcap", "--out", str(out),
                        "--topics", str(names), "--compression", "lz4"])
    assert (code, err) == (0, "")
    types = read_bag(out)["_types"]
    assert {"/auv/imu", "/sim/truth", "/dvl/data"} <= set(types)
    assert "/imu/data" not in types


@pytest.mark.parametrize("case", ["not a dataset", "unknown mission", "unknown topic key",
                                  "bad topic name", "unknown mission, new folder",
                                  "folder as out"])
def test_bad_input_is_one_line_and_nothing_written(case, dataset, tmp_path):
    out = tmp_path / "out.mcap"
    args = ["export", str(dataset), "--to", "mcap", "--out", str(out)]
    if case == "not a dataset":
        junk = tmp_path / "junk.h5"
        junk.write_bytes(b"not hdf5 at all")
        args[1] = str(junk)
    elif case == "unknown mission":
        args += ["--mission", "mission_999"]
    elif case in ("unknown topic key", "bad topic name"):
        names = tmp_path / "topics.toml"
        names.write_text('imu_raw = "/x"\n' if case == "unknown topic key" else
                         'imu = "imu data"\n')
        args += ["--topics", str(names)]
    elif case == "unknown mission, new folder":  # the folder is not made for nothing
        out = tmp_path / "nowhere" / "out.mcap"
        args[-1] = str(out)
        args += ["--mission", "mission_999"]
    else:
        out = tmp_path
        args[-1] = str(out)
    before = sorted(tmp_path.iterdir())
    code, printed, err = run(args)
    assert code == 2 and printed == ""
    assert err.startswith("auvsim: error: ") and err.count("\n") == 1, err
    assert sorted(tmp_path.iterdir()) == before  # nothing written, not even a temporary
    assert out == tmp_path or not out.exists()
    if case == "unknown topic key":
        assert "--topics 'imu_raw': no such topic key; expected keys among imu, dvl" in err


def test_a_missing_package_is_named_with_its_extra(dataset, tmp_path, monkeypatch):
    for name in ("mcap_ros2", "mcap_ros2.writer"):  # importing them fails
        monkeypatch.setitem(sys.modules, name, None)
    out = tmp_path / "x.mcap"
    code, _, err = run(["export", str(dataset), "--to", "mcap", "--out", str(out)])
    assert code == 2 and err.count("\n") == 1
    assert "mcap-ros2-support is missing" in err and "pip install 'auvsim[io]'" in err
    assert list(tmp_path.iterdir()) == []


_KILLED = """
import sys, time
from pathlib import Path
import auvsim.interop.mcapfile as mcapfile
original = mcapfile.compressor
def slow(name):
    compress = original(name)
    def one(data):
        Path(sys.argv[3]).touch()  # a chunk is being written: the parent kills us now
        time.sleep(60)
        return compress(data)
    return one
mcapfile.compressor = slow
from auvsim.cli import main
sys.exit(main(["export", sys.argv[1], "--to", "mcap", "--out", sys.argv[2]]))
"""


def test_a_killed_export_leaves_nothing_at_the_output(dataset, tmp_path):
    out, started = tmp_path / "killed.mcap", tmp_path / "started"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-c", textwrap.dedent(_KILLED), str(dataset),
                             str(out), str(started)], env=env)
    try:
        deadline = time.monotonic() + 60
        while not started.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert started.exists()
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if ".auvsim-tmp." in p.name]  # it was writing
    # the next export into the folder sweeps the dead one's temporaries, and writes whole
    assert run(["export", str(dataset), "--to", "mcap", "--out", str(out)])[0] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["killed.mcap", "started"]


def _akit(folder: Path, seconds: int = 20) -> None:
    """A tiny A-KIT log: IMU 100 Hz, DVL and reference 1 Hz, level, heading 30 deg while
    moving north."""
    seg = folder / "Trajectory1"
    seg.mkdir(parents=True)
    rng = np.random.default_rng(3)

    def csv(name: str, header: list[str], columns) -> None:
        rows = np.column_stack(columns)
        (seg / name).write_text(",".join(header) + "\n" + "\n".join(
            ",".join(repr(float(v)) for v in row) for row in rows) + "\n")

    t_imu = np.arange(seconds * 100) * 0.01
    csv("IMU_trajectory1.csv", ["Time [s]", "ACC X [m/s^2]", "ACC Y [m/s^2]",
                                "ACC Z [m/s^2]", "GYRO X [rad/s]", "GYRO Y [rad/s]",
                                "GYRO Z [rad/s]"],
        [t_imu, 0.01 * rng.standard_normal((len(t_imu), 2)),
         -9.7956 + 0.01 * rng.standard_normal(len(t_imu)),
         0.001 * rng.standard_normal((len(t_imu), 3))])
    t = np.arange(seconds) * 1.0
    csv("DVL_trajectory1.csv", ["Time [s]", "DVL X [m/s]", "DVL Y [m/s]", "DVL Z [m/s]"],
        [t, np.full(len(t), 1.5), 0.01 * rng.standard_normal((len(t), 2))])
    lat = np.radians(32.85 + np.degrees(1.5 * t / 6.36e6))
    csv("GT_trajectory1.csv", ["Time [s]", "Longitude [rad]", "Latitude [rad]",
                               "Altitude [m]", "V North [m/s]", "V East [m/s]",
                               "V Down [m/s]", "Roll [rad]", "Pitch [rad]", "Yaw [rad]"],
        [t, np.full(len(t), np.radians(34.89)), lat, np.full(len(t), -20.0),
         np.full(len(t), 1.5), np.zeros((len(t), 2)), np.zeros((len(t), 2)),
         np.full(len(t), np.radians(30.0))])


def test_a_recorded_mission_exports_its_reference_never_a_truth(tmp_path):
    _akit(tmp_path / "log")
    h5, out = tmp_path / "rec.h5", tmp_path / "rec.mcap"
    assert run(["import", str(tmp_path / "log"), "--format", "akit", "--out", str(h5)])[0] == 0
    code, _, err = run(["export", str(h5), "--to", "mcap", "--out", str(out)])
    assert (code, err) == (0, "")
    topics = read_bag(out)
    types = topics.pop("_types")
    assert "/reference/odometry" in types and not any("truth" in t for t in types)
    with open_dataset(h5) as ds:
        m = next(iter(ds.missions.values()))
        ref = [msg for _, msg in topics["/reference/odometry"]]
        np.testing.assert_array_equal(vec(x.pose.pose.position for x in ref),
                                      m.reference.position_ned)
        np.testing.assert_array_equal(vec((x.pose.pose.orientation for x in ref), "wxyz"),
                                      m.reference.quaternion)
        assert all(x.pose.covariance[0] == -1 for x in ref)  # a reference's accuracy: unknown
        # the twist is in the body frame: C^T v
        body = np.einsum("nji,nj->ni", rotation_matrices(m.reference.quaternion),
                         m.reference.velocity_ned)
        assert np.abs(body[:, 1]).min() > 0.7  # 30 deg off the velocity: a real rotation
        np.testing.assert_allclose(vec(x.twist.twist.linear for x in ref), body, atol=1e-12)
        assert all(np.isnan(vec([x.twist.twist.angular])).all() for x in ref)
        imu = [msg for _, msg in topics["/imu/data"]]
        np.testing.assert_array_equal(vec(x.angular_velocity for x in imu),
                                      m.imu.angular_rate)
        dvl = [msg for _, msg in topics["/dvl/data"]]
        np.testing.assert_array_equal(vec(x.velocity for x in dvl), m.dvl.velocity_ls)
        assert not dvl[0].beam_velocities_valid  # A-KIT logs no beams
        # ... but a velocity, known to the instrument's stated accuracy (0.02 m/s for the
        # Navigator): not the "no velocity" marker
        accuracy = m.attrs["dvl_velocity_accuracy"]
        assert accuracy > 0
        for x in dvl:
            np.testing.assert_allclose(np.reshape(x.velocity_covar, (3, 3)),
                                       accuracy**2 * np.eye(3))


@pytest.mark.parametrize("to, option, value", [("mcap", "--coordinates", "beam"),
                                                ("pd0", "--topics", "t.toml"),
                                                ("pd0", "--compression", "lz4")])
def test_an_option_of_the_other_format_is_refused(to, option, value, dataset, tmp_path):
    out = tmp_path / f"x.{to}"
    code, _, err = run(["export", str(dataset), "--to", to, option, value, "--out", str(out)])
    only = "pd0" if to == "mcap" else "mcap"
    assert code == 2 and err == f"auvsim: error: {option}: only for --to {only}\n"
    assert list(tmp_path.iterdir()) == []
