"""beamsnet.data: samples cut from auvsim datasets, checked against the file itself."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest
from conftest import flat, mission, write

from auvsim.config import DvlConfig, ImuConfig
from auvsim.data.reader import open_dataset
from beamsnet.data import DataError, Windows, load_windows, select, split

CONFIG = flat(mission("a", 1, speed=2.0, duration=120.0), mission("b", 2, speed=1.0, duration=80.0),
              dvl=DvlConfig(beam_angle_deg=20.0, scale_factor=0.007, bias=1e-4, noise_std=0.01),
              imu=ImuConfig(accel_noise_density=1e-3, gyro_noise_density=1e-4))
PINGS = {"a": 120, "b": 80}
W = 100  # IMU samples per ping: 100 Hz / 1 Hz


@pytest.fixture(scope="module")
def path(dataset_of):
    return dataset_of(CONFIG, "two")


def edited_copy(path, tmp_path, edit) -> str:
    """A copy of the dataset file, changed in place by ``edit(h5py.File)``."""
    out = tmp_path / "edited.h5"
    shutil.copy(path, out)
    with h5py.File(out, "r+") as f:
        edit(f)
    return out


def ping_index(w: Windows) -> np.ndarray:
    return np.rint(w.time * CONFIG.dvl.rate_hz).astype(int)


@pytest.mark.parametrize("n_past", [1, 3, 5])
def test_shapes_and_one_sample_per_ping_after_the_first_n_past(path, n_past):
    w = load_windows(path, n_past=n_past)
    s = sum(PINGS.values()) - 2 * n_past
    assert w.names == ("a", "b")
    assert w.beams.shape == (s, 4) and w.past_beams.shape == (s, n_past, 4)
    assert w.accel.shape == w.gyro.shape == (s, W, 3)
    assert w.target.shape == w.velocity_ls.shape == (s, 3)
    assert w.mission.shape == w.time.shape == (s,)
    assert w.h.shape == (4, 3)
    for field in (w.beams, w.past_beams, w.accel, w.gyro, w.target, w.velocity_ls, w.time):
        assert field.dtype == np.float64
    for i, name in enumerate(w.names):
        assert np.sum(w.mission == i) == PINGS[name] - n_past
        # the first sample of each mission is ping n_past: nothing reaches into the mission
        # before it, and every window is whole pings one period apart
        assert w.time[w.mission == i][0] == n_past / CONFIG.dvl.rate_hz
        np.testing.assert_allclose(np.diff(w.time[w.mission == i]), 1 / CONFIG.dvl.rate_hz)


def test_every_field_is_the_files_rows_of_its_own_mission(path):
    w = load_windows(path, n_past=3)
    k = ping_index(w)
    with open_dataset(path) as f:
        for i, name in enumerate(w.names):
            m = f.missions[name]
            rows, kk = w.mission == i, k[w.mission == i]
            beams = m.dvl.beam_velocity
            np.testing.assert_array_equal(w.beams[rows], beams[kk])
            np.testing.assert_array_equal(w.time[rows], m.dvl.time[kk])
            np.testing.assert_array_equal(w.target[rows], m.dvl.velocity[kk])
            np.testing.assert_array_equal(w.velocity_ls[rows], m.dvl.velocity_ls[kk])
            for j, ping in enumerate(kk):  # oldest first, the three pings just before
                np.testing.assert_array_equal(w.past_beams[rows][j], beams[ping - 3:ping])
            index = m.imu.index_of_dvl
            force, rate = m.imu.specific_force, m.imu.angular_rate
            for j, ping in enumerate(kk):
                end = index[ping]
                np.testing.assert_array_equal(w.accel[rows][j], force[end - W:end])
                np.testing.assert_array_equal(w.gyro[rows][j], rate[end - W:end])


def test_missions_are_chosen_by_name_in_the_order_given(path):
    w = load_windows(path, missions=["b"])
    assert w.names == ("b",) and np.all(w.mission == 0) and len(w.target) == PINGS["b"] - 3
    both = load_windows(path, missions=("b", "a"))
    assert both.names == ("b", "a")
    np.testing.assert_array_equal(both.beams[both.mission == 0], w.beams)


def test_a_dataset_without_missions_is_refused_in_one_line(path, tmp_path):
    def empty(f):
        for name in list(f["missions"]):
            del f["missions"][name]

    bare = edited_copy(path, tmp_path, empty)
    with pytest.raises(DataError, match="holds no missions; expected a dataset with at least "
                       "one") as e:
        load_windows(bare)
    assert "\n" not in str(e.value)
    with pytest.raises(DataError, match="expected at least one mission name; .* has a, b"):
        load_windows(path, missions=[])


def test_pings_without_bottom_lock_are_skipped_now_and_as_past_beams(path, tmp_path):
    def lose_lock(f):
        m = f["missions/a/dvl"]
        for key, value in (("beam_velocity", np.nan), ("valid", False)):
            d = m[key][()]
            d[10, 2] = value
            m[key][...] = d

    w = load_windows(edited_copy(path, tmp_path, lose_lock), n_past=3)
    k = ping_index(w)[w.mission == 0]
    # ping 10 is no sample, nor are pings 11..13, whose past beams hold it
    assert set(range(3, 120)) - set(k.tolist()) == {10, 11, 12, 13}
    assert np.sum(w.mission == 1) == PINGS["b"] - 3
    assert np.isfinite(w.beams).all() and np.isfinite(w.past_beams).all()


def test_a_beam_out_of_range_loses_lock_for_the_whole_mission(tmp_path):
    # mission "deep" flies 55 m above the floor: slant range 58.5 m, beyond max_range 50 m
    config = flat(mission("near", 1, duration=30.0, depth=30.0),
                  mission("deep", 2, duration=30.0, depth=5.0), dvl=DvlConfig(max_range=50.0))
    write(config, tmp_path / "lost.h5")
    # A mission that gives no sample is refused, not left out without a word.
    with pytest.raises(DataError, match="mission deep: every beam velocity is NaN"):
        load_windows(tmp_path / "lost.h5")
    w = load_windows(tmp_path / "lost.h5", missions=["near"])
    assert w.names == ("near",) and len(w.target) == 27
    with pytest.raises(DataError, match="mission deep: every beam velocity is NaN"):
        load_windows(tmp_path / "lost.h5", missions=["deep"])


def test_a_file_without_imu_gives_no_imu_windows_and_the_same_samples(path, tmp_path):
    """Missions without an IMU group (schema v2 lets imported ones go without) give the
    same samples, with no IMU windows."""
    def drop_imu(f):
        for name in f["missions"]:
            m = f["missions"][name]
            del m["imu"]
            m.attrs.update(origin="imported", source_file="recorded.npy",
                           source_sha256="0" * 64)

    w = load_windows(edited_copy(path, tmp_path, drop_imu))
    assert w.accel is None and w.gyro is None
    np.testing.assert_array_equal(w.beams, load_windows(path).beams)


def test_errors_say_what_is_wrong(path, tmp_path):
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["x"] = 1.0
    with pytest.raises(DataError, match="not an auvsim dataset"):
        load_windows(plain)
    with pytest.raises(DataError, match="no such file"):
        load_windows(tmp_path / "missing.h5")
    with pytest.raises(DataError,
                       match=r"mission 'c': not in .*; expected one of its missions: a, b"):
        load_windows(path, missions=["a", "c"])
    with pytest.raises(DataError, match="mission a: 120 DVL ping.*needs at least 201"):
        load_windows(path, n_past=200)
    for bad in (0, -1, 1.5):
        with pytest.raises(DataError, match="n_past: expected an integer >= 1"):
            load_windows(path, n_past=bad)

    def other_angle(f):
        f["missions/b"].attrs["beam_angle_deg"] = 30.0

    with pytest.raises(DataError, match="different beam angles.*a 20 deg, b 30 deg"):
        load_windows(edited_copy(path, tmp_path, other_angle))
    assert issubclass(DataError, ValueError)


def test_split_is_sequential_per_mission_and_keeps_order(path):
    w = load_windows(path)
    train, test = split(w)
    assert len(train.target) + len(test.target) == len(w.target)
    for i, name in enumerate(w.names):
        n = PINGS[name] - 3
        t_train, t_test = train.time[train.mission == i], test.time[test.mission == i]
        assert len(t_train) == int(0.75 * n) and len(t_test) == n - int(0.75 * n)
        np.testing.assert_array_equal(np.concatenate([t_train, t_test]), w.time[w.mission == i])
    # order of the input kept within each part: missions one after the other, time rising
    for part in (train, test):
        key = part.mission * 1e6 + part.time
        assert np.all(np.diff(key) > 0)
    np.testing.assert_array_equal(split(w, 0.5)[0].mission, np.repeat([0, 1], [58, 38]))
    for bad in (0, 1, 1.5, -0.2):
        with pytest.raises(ValueError, match="train_fraction"):
            split(w, bad)


def test_select_takes_every_per_sample_field(path):
    w = load_windows(path)
    s = select(w, w.mission == 1)
    assert s.names == w.names and s.h is w.h
    for field in ("beams", "past_beams", "accel", "gyro", "target", "velocity_ls", "time"):
        np.testing.assert_array_equal(getattr(s, field), getattr(w, field)[w.mission == 1])
    np.testing.assert_array_equal(select(w, [0, 5]).time, w.time[[0, 5]])
