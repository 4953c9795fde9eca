"""Recorded logs as datasets (``auvsim import``, schema v7 ``recorded`` missions).

Small logs are built here with known motion: a tiny folder in the A-KIT layout and a CSV
log with its description in other conventions (FLU body, ENU reference, deg, ms, an axis
map, a clock offset). Every stream must come back as written, in auvsim's conventions,
on its own clock; bad logs are refused in one line with exit 2 and nothing written. The
six shared A-KIT segments are imported too where ``../shared/data/snapir-akit`` exists.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from h5compare import assert_same_contents

from auvsim.cli import main
from auvsim.data.reader import open_dataset, require_attitude
from auvsim.data.recorded import AKIT_DESCRIPTION, import_logs, parse_description, read_log
from auvsim.errors import ConfigError, DatasetError
from auvsim.physics.earth import normal_gravity, radii
from auvsim.physics.frames import euler_angles

REPO = Path(__file__).resolve().parents[1]
SHARED = next((p / "shared/data/snapir-akit" for p in REPO.parents
               if (p / "shared/data/snapir-akit").is_dir()), None)
LAT0, LON0, H0 = 32.85, 34.89, -20.0  # deg, deg, m: where the Snapir dived
T = 30.0  # s of log
V_NED = np.array([1.5, -0.5, 0.02])  # m/s, the reference's constant velocity
RPY = np.radians([2.0, -3.0, -15.0])  # constant attitude: the course, -18.4 deg, and a crab


def _write_csv(path: Path, header: list[str], columns: list[np.ndarray]) -> None:
    rows = np.column_stack(columns)
    lines = [",".join(header)] + [",".join(repr(float(x)) for x in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")


def _geodetic(t: np.ndarray, v: np.ndarray = V_NED) -> tuple[np.ndarray, ...]:
    """Latitude, longitude (deg) and height (m) of a constant-velocity track from the
    origin, to first order in the distance (metres of error per kilometre squared)."""
    m, n = radii(LAT0)
    m, n = m + H0, n + H0  # the radii of curvature at the vehicle's height
    lat = LAT0 + np.degrees(v[0] * t / m)
    lon = LON0 + np.degrees(v[1] * t / (n * math.cos(math.radians(LAT0))))
    return lat, lon, H0 - v[2] * t


def _akit(folder: Path, k: int = 3) -> dict[str, np.ndarray]:
    """A tiny A-KIT segment folder ``TrajectoryK``: IMU 100 Hz, DVL and GT 1 Hz; returns
    what it wrote."""
    seg = folder / f"Trajectory{k}"
    seg.mkdir(parents=True)
    rng = np.random.default_rng(0)
    t_imu = np.arange(int(T * 100)) * 0.01
    f = np.column_stack([0.01 * rng.standard_normal(len(t_imu)),
                         0.01 * rng.standard_normal(len(t_imu)),
                         -9.7956 + 0.01 * rng.standard_normal(len(t_imu))])
    w = 0.02 * rng.standard_normal((len(t_imu), 3))
    _write_csv(seg / f"IMU_trajectory{k}.csv",
               ["Time [s]", "ACC X [m/s^2]", "ACC Y [m/s^2]", "ACC Z [m/s^2]",
                "GYRO X [rad/s]", "GYRO Y [rad/s]", "GYRO Z [rad/s]"], [t_imu, f, w])
    t = np.arange(int(T)) * 1.0
    v_dvl = np.column_stack([np.full(len(t), 1.58), 0.01 * rng.standard_normal(len(t)),
                             np.zeros(len(t))])
    _write_csv(seg / f"DVL_trajectory{k}.csv",
               ["Time [s]", "DVL X [m/s]", "DVL Y [m/s]", "DVL Z [m/s]"], [t, v_dvl])
    lat, lon, h = _geodetic(t)
    _write_csv(seg / f"GT_trajectory{k}.csv",
               ["Time [s]", "Longitude [rad]", "Latitude [rad]", "Altitude [m]",
                "V North [m/s]", "V East [m/s]", "V Down [m/s]", "Roll [rad]", "Pitch [rad]",
                "Yaw [rad]"],
               [t, np.radians(lon), np.radians(lat), h, np.tile(V_NED, (len(t), 1)),
                np.tile(RPY, (len(t), 1))])
    return dict(t_imu=t_imu, f=f, w=w, t=t, v_dvl=v_dvl)


def run(args: list[str]) -> tuple[int, str]:
    """The CLI's exit code and what it printed to stderr."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(args)
    return code, err.getvalue()


def run_csv(folder: Path, out: Path, description: str = "log.toml") -> tuple[int, str]:
    """``run`` of ``auvsim import`` of a CSV log with its description (in the folder)."""
    return run(["import", str(folder), "--format", "csv", "--description",
                str(folder / description), "--out", str(out)])


@pytest.fixture(scope="module")
def akit(tmp_path_factory):
    folder = tmp_path_factory.mktemp("akit")
    written = _akit(folder)
    out = folder / "akit.h5"
    assert run([ "import", str(folder), "--format", "akit", "--out", str(out)]) == (0, "")
    return out, written


def test_akit_round_trip(akit):
    out, w = akit
    with open_dataset(out, verify=True) as f:
        assert f.version == 7 and list(f.missions) == ["trajectory3"]
        m = f.missions["trajectory3"]
        assert m.origin == "recorded" and m.groups == ["dvl", "imu", "reference"]
        assert json.loads(m.attrs["groups"]) == ["imu", "dvl", "reference"]
        # Every stream as written, on its own clock, nothing resampled.
        np.testing.assert_array_equal(m.imu.time, w["t_imu"])
        np.testing.assert_array_equal(m.imu.specific_force, w["f"])
        np.testing.assert_array_equal(m.imu.angular_rate, w["w"])
        np.testing.assert_array_equal(m.dvl.time, w["t"])
        np.testing.assert_array_equal(m.dvl.velocity_ls, w["v_dvl"])
        assert "velocity" not in m.dvl and m.attrs["dvl_beams_derived"] == 1
        np.testing.assert_array_equal(m.dvl.mode, 0)
        assert m.attrs["imu_rate_hz"] == pytest.approx(100.0)
        assert m.attrs["dvl_rate_hz"] == m.attrs["reference_rate_hz"] == pytest.approx(1.0)
        # The reference: local NED from its first point, exactly 0 there.
        ref = m.reference
        np.testing.assert_array_equal(ref.position_ned[0], 0.0)
        np.testing.assert_allclose(ref.position_ned, np.outer(w["t"], V_NED), atol=1e-3)
        np.testing.assert_array_equal(ref.velocity_ned, np.tile(V_NED, (len(w["t"]), 1)))
        np.testing.assert_allclose(euler_angles(ref.quaternion), np.tile(RPY, (30, 1)),
                                   atol=1e-12)
        np.testing.assert_allclose(ref.rpy_deg, np.degrees(np.tile(RPY, (30, 1))), atol=1e-9)
        assert (m.attrs["latitude_deg"], m.attrs["longitude_deg"], m.attrs["height_m"]) == \
            pytest.approx((LAT0, LON0, H0))
        assert m.attrs["gravity"] == normal_gravity(LAT0, H0)
        # What the reference is, as the layout states it: a navigation solution.
        text = AKIT_DESCRIPTION.replace("{k}", "3")
        assert m.attrs["reference_source"] == parse_description(text).reference_source
        assert "navigation solution" in m.attrs["reference_source"]
        assert m.attrs["log_description"] == text
        assert len(json.loads(m.attrs["source_sha256"])) == 3
        assert m.phases == []
        with pytest.raises(DatasetError, match=r"recorded missions have a reference, not a "
                           r"truth") as e:
            m.truth  # noqa: B018
        assert "\n" not in str(e.value)
        np.testing.assert_array_equal(require_attitude(m), ref.quaternion)


def test_inspect_and_plot_show_a_recorded_mission(akit, tmp_path, capsys):
    out, _ = akit
    assert main(["inspect", str(out)]) == 0
    text = capsys.readouterr().out
    assert "trajectory3: recorded, 29.99 s" in text
    assert "imu: 3000 samples at 100 Hz" in text and "dvl: 30 samples at 1 Hz" in text
    assert "reference (a navigation solution, not the truth)" in text
    assert "track 46 m" in text  # |V_NED horizontal| 1.581 m/s x 29 s
    assert main(["plot", str(out), "--out", str(tmp_path / "figs")]) == 0
    png = tmp_path / "figs" / "akit_trajectory3.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


DESCRIPTION = """\
[log]
name = "dive"
reference_source = "the vehicle's own INS, real time"

[imu]
file = "imu.csv"
time = "t_ms"
time_unit = "ms"
frame = "FLU"
axis_map = ["y", "x", "z"]  # the log's y axis points forward
position_body = [0.5, 0.0, 0.1]
columns = {specific_force = ["fx", "fy", "fz"], angular_rate = ["wx", "wy", "wz"]}
units = {specific_force = "g", angular_rate = "deg/s"}
ignore = ["temperature"]

[imu.noise]
accel_noise_density = 1e-4
gyro_noise_density = 1e-6
accel_bias_instability = 1e-4
gyro_bias_instability = 1e-7
bias_correlation_time = 600.0

[dvl]
file = "dvl.csv"
time = "t_ms"
time_unit = "ms"
time_offset_s = 0.25
frame = "FRD"
beam_angle_deg = 30.0
noise_std = 0.003
velocity_accuracy = 0.02
invalid = -32768
columns = {velocity = ["vx", "vy", "vz"], error_velocity = "err", altitude = "alt"}
units = {velocity = "mm/s", error_velocity = "mm/s"}

[depth]
file = "depth.csv"
time = "t_ms"
time_unit = "ms"
columns = {depth = "depth"}

[reference]
file = "nav.csv"
time = "t_ms"
time_unit = "ms"
frame = "ENU"
body = "FLU"
columns.latitude = "lat"
columns.longitude = "lon"
columns.height = "h"
columns.velocity = ["ve", "vn", "vu"]
columns.attitude = ["roll", "pitch", "yaw"]
units = {latitude = "deg", longitude = "deg", attitude = "deg"}
"""


def csv_log(folder: Path, *, yaw_enu_deg: float = 90.0) -> dict[str, np.ndarray]:
    """A log in other conventions than auvsim's, with a known meaning in auvsim's."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "log.toml").write_text(DESCRIPTION)
    t = np.arange(200) * 10.0  # ms: 100 Hz for 2 s
    n = len(t)
    # FLU after the map: the log's (y, x, z) are the body's (x, y, z) in FLU.
    f_flu = np.tile([0.01, 0.02, 1.0], (n, 1))  # g
    w_flu = np.tile([10.0, 20.0, 30.0], (n, 1))  # deg/s: a turn
    _write_csv(folder / "imu.csv", ["t_ms", "fx", "fy", "fz", "wx", "wy", "wz", "temperature"],
               [t, f_flu[:, 1], f_flu[:, 0], f_flu[:, 2], w_flu[:, 1], w_flu[:, 0],
                w_flu[:, 2], np.full(n, 12.0)])
    t_dvl = np.arange(4) * 500.0
    v = np.array([[1500.0, 10.0, -5.0], [-32768.0, -32768.0, -32768.0],
                  [1490.0, 0.0, 0.0], [1510.0, 20.0, 5.0]])
    _write_csv(folder / "dvl.csv", ["t_ms", "vx", "vy", "vz", "err", "alt"],
               [t_dvl, v, np.array([2.0, -32768.0, -1.0, 3.0]), np.full(4, 12.5)])
    _write_csv(folder / "depth.csv", ["t_ms", "depth"], [np.arange(20) * 100.0,
                                                         np.full(20, 20.0)])
    t_ref = np.arange(2) * 1000.0
    lat, lon, h = _geodetic(t_ref / 1000)
    _write_csv(folder / "nav.csv", ["t_ms", "lat", "lon", "h", "ve", "vn", "vu", "roll",
                                    "pitch", "yaw"],
               [t_ref, lat, lon, h, np.tile([V_NED[1], V_NED[0], -V_NED[2]], (2, 1)),
                np.tile([0.0, 0.0, yaw_enu_deg], (2, 1))])
    return dict(f_flu=f_flu, w_flu=w_flu, v=v)


def test_a_described_csv_log_in_auvsim_conventions(tmp_path):
    w = csv_log(tmp_path / "dive")
    out = tmp_path / "dive.h5"
    assert run_csv(tmp_path / "dive", out) == (0, "")
    with open_dataset(out, verify=True) as f:
        m = f.missions["dive"]
        assert m.groups == ["depth", "dvl", "imu", "reference"]
        flu_to_frd = np.array([1.0, -1.0, -1.0])
        np.testing.assert_allclose(m.imu.specific_force, w["f_flu"] * 9.80665 * flu_to_frd)
        np.testing.assert_allclose(m.imu.angular_rate, np.radians(w["w_flu"]) * flu_to_frd)
        np.testing.assert_allclose(m.imu.time, np.arange(200) * 0.01)
        assert m.attrs["imu_rate_hz"] == pytest.approx(100.0)
        np.testing.assert_array_equal(m.attrs["imu_position_body"], [0.5, 0.0, 0.1])
        # The DVL's clock: its own stamps plus its offset; the no-data marker is NaN.
        np.testing.assert_allclose(m.dvl.time, np.arange(4) * 0.5 + 0.25)
        assert m.attrs["dvl_rate_hz"] == pytest.approx(2.0)
        v = m.dvl.velocity_ls
        assert np.isnan(v[1]).all() and m.dvl.mode.tolist() == [0, -1, 0, 0]
        np.testing.assert_allclose(v[[0, 2, 3]], w["v"][[0, 2, 3]] / 1000)
        np.testing.assert_allclose(m.dvl.error_velocity, [0.002, np.nan, -0.001, 0.003])
        np.testing.assert_array_equal(m.dvl.altitude, 12.5)
        assert m.attrs["depth_rate_hz"] == pytest.approx(10.0)
        # ENU velocity -> NED; heading north (ENU yaw 90 deg, FLU) is yaw 0 in NED/FRD.
        np.testing.assert_allclose(m.reference.velocity_ned, np.tile(V_NED, (2, 1)))
        np.testing.assert_allclose(m.reference.quaternion, np.tile([1.0, 0, 0, 0], (2, 1)),
                                   atol=1e-12)
        np.testing.assert_allclose(m.reference.position_ned[1], V_NED, atol=1e-6)
    east = tmp_path / "east"
    csv_log(east, yaw_enu_deg=0.0)  # heading east: NED yaw 90 deg
    recording = read_log(east, parse_description(DESCRIPTION))
    np.testing.assert_allclose(recording.fields["reference/rpy_deg"],
                               np.tile([0.0, 0.0, 90.0], (2, 1)), atol=1e-9)


def test_a_dvl_that_writes_nan_for_no_data_and_states_no_beam_noise(tmp_path):
    """``invalid = "nan"``: a NaN cell of the DVL is no bottom lock, as the marker is; a
    beam noise the description does not state is measured on the logged error velocity
    (2, -1, 3 mm/s: a robust std of 1.4826 mm/s, times sqrt(2) sin 30 deg)."""
    folder = tmp_path / "dive"
    csv_log(folder)
    _replace("log.toml", "invalid = -32768", 'invalid = "nan"')(folder)
    _replace("log.toml", "noise_std = 0.003\n", "")(folder)
    _edit("dvl.csv", lambda t: t.replace("-32768.0", "nan"))(folder)
    out = tmp_path / "dive.h5"
    assert run_csv(folder, out) == (0, "")
    with open_dataset(out, verify=True) as f:
        m = f.missions["dive"]
        assert np.isnan(m.dvl.velocity_ls[1]).all() and m.dvl.mode.tolist() == [0, -1, 0, 0]
        assert m.attrs["dvl_noise_std"] == pytest.approx(
            math.sqrt(2) * 0.5 * 1.4826e-3, rel=1e-9)
        assert "noise_std" not in m.attrs["log_description"].replace("_noise_std", "")


def test_a_dvl_that_leaves_its_no_data_cells_empty(tmp_path):
    """An empty cell is what pandas writes for NaN: with ``invalid = "nan"`` it is no data,
    as a nan cell is (it was refused as not a number); elsewhere it is still refused, with
    what to say."""
    folder = tmp_path / "dive"
    csv_log(folder)
    _replace("log.toml", "invalid = -32768", 'invalid = "nan"')(folder)
    _edit("dvl.csv", lambda t: t.replace("-32768.0", ""))(folder)
    out = tmp_path / "dive.h5"
    assert run_csv(folder, out) == (0, "")
    with open_dataset(out) as f:
        m = f.missions["dive"]
        assert np.isnan(m.dvl.velocity_ls[1]).all() and m.dvl.mode.tolist() == [0, -1, 0, 0]
    _edit("depth.csv", lambda t: t.replace("20.0", "", 1))(folder)
    status, err = run_csv(folder, tmp_path / "again.h5")
    assert status == 2 and err.endswith(
        "an empty cell is missing data, which only a DVL's no-data value may be: invalid = "
        "\"nan\" takes empty cells too\n"), err


def test_a_dvls_beams_as_logged(tmp_path):
    """``columns.beam_velocity`` and ``columns.beam_range``: the beams kept as logged (in
    auvsim's order, mm/s to m/s), a beam at the no-data marker not valid, the file's
    ``dvl_beams_derived`` 0; the beams of a logged velocity v are H v, so least squares
    gives v back."""
    from auvsim.data.beams import beam_matrix, least_squares

    folder = tmp_path / "dive"
    w = csv_log(folder)
    h = beam_matrix(math.radians(30.0))
    v = w["v"].copy()
    v[1] = 0.0
    beams = v @ h.T  # mm/s
    beams[1] = -32768.0  # the ping without bottom lock (its velocity at the marker too)
    beams[3, 2] = -32768.0  # and one beam of another
    _edit("dvl.csv", _lines(lambda ls: [ls[0] + ",b0,b1,b2,b3,r0,r1,r2,r3"] + [
        x + "," + ",".join(repr(float(b)) for b in row) + ",14.4,14.4,14.4,14.4"
        for x, row in zip(ls[1:], beams, strict=True)]))(folder)
    _replace("log.toml", 'altitude = "alt"}', 'altitude = "alt", beam_velocity = '
             '["b0", "b1", "b2", "b3"], beam_range = ["r0", "r1", "r2", "r3"]}')(folder)
    _replace("log.toml", 'error_velocity = "mm/s"}', 'error_velocity = "mm/s", '
             'beam_velocity = "mm/s"}')(folder)
    out = tmp_path / "beams.h5"
    assert run_csv(folder, out) == (0, "")
    with open_dataset(out, verify=True) as f:
        m = f.missions["dive"]
        assert m.attrs["dvl_beams_derived"] == 0
        valid = m.dvl.valid
        assert valid.sum() == 11 and not valid[1].any() and not valid[3, 2]
        np.testing.assert_allclose(m.dvl.beam_velocity[valid], beams[valid] / 1000)
        np.testing.assert_array_equal(m.dvl.beam_range, 14.4)
        solved = least_squares(m.dvl.beam_velocity, h)
        np.testing.assert_allclose(solved[[0, 2]], w["v"][[0, 2]] / 1000, atol=1e-12)


def test_a_dvls_status_codes_per_beam_are_kept_as_logged(tmp_path):
    """``columns.status``: four whole-number codes per ping, the no-data marker too (a
    code, not a measurement); a fraction is refused in one line."""
    folder = tmp_path / "dive"
    csv_log(folder)
    codes = ["0,0,0,0", "-32768,3,3,3", "0,1,0,0", "0,0,0,2"]
    _edit("dvl.csv", _lines(lambda ls: [ls[0] + ",s0,s1,s2,s3"] + [
        f"{x},{c}" for x, c in zip(ls[1:], codes, strict=True)]))(folder)
    _replace("log.toml", 'altitude = "alt"}', 'altitude = "alt", '
             'status = ["s0", "s1", "s2", "s3"]}')(folder)
    out = tmp_path / "dive.h5"
    assert run_csv(folder, out) == (0, "")
    with open_dataset(out, verify=True) as f:
        status = f.missions["dive"].dvl.status
        assert status.dtype.kind == "i"
        np.testing.assert_array_equal(status, [[0, 0, 0, 0], [-32768, 3, 3, 3],
                                               [0, 1, 0, 0], [0, 0, 0, 2]])
    _replace("dvl.csv", ",0,1,0,0", ",0,1.5,0,0")(folder)
    code, err = run_csv(folder, tmp_path / "frac.h5")
    assert code == 2 and "dvl.columns.status: expected whole-number codes, got 1.5" in err
    assert not (tmp_path / "frac.h5").exists()


def test_import_velocity_is_import_format_velocity(tmp_path):
    v = np.stack([np.full(20, 1.5), np.linspace(-0.2, 0.2, 20), np.full(20, 0.05)])
    np.save(tmp_path / "rec.npy", v)
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    assert run(["import-velocity", str(tmp_path / "rec.npy"), "--seed", "4",
                "--out", str(a)])[0] == 0
    assert run(["import", str(tmp_path / "rec.npy"), "--format", "velocity", "--seed", "4",
                "--out", str(b)])[0] == 0
    assert_same_contents(a, b)


def test_a_reference_without_attitude_is_refused_where_one_is_needed(tmp_path):
    folder = tmp_path / "noatt"
    csv_log(folder)
    text = DESCRIPTION.replace('columns.attitude = ["roll", "pitch", "yaw"]\n', "").replace(
        ', attitude = "deg"}', "}").replace('ignore = ["temperature"]', 'ignore = []')
    (folder / "nav.csv").write_text("\n".join(
        ",".join(line.split(",")[:7]) for line in (folder / "nav.csv").read_text().splitlines()))
    (folder / "imu.csv").write_text("\n".join(
        ",".join(line.split(",")[:7]) for line in (folder / "imu.csv").read_text().splitlines()))
    (folder / "log.toml").write_text(text)
    out = tmp_path / "noatt.h5"
    assert run_csv(folder, out) == (0, "")
    with open_dataset(out) as f:
        m = f.missions["dive"]
        assert "quaternion" not in m.reference and "rpy_deg" not in m.reference
        with pytest.raises(DatasetError, match="its reference has no attitude") as e:
            require_attitude(m)
        assert "\n" not in str(e.value)


# Bad logs: one line, exit 2, nothing at the output path --------------------------------

def _edit(file: str, change):
    def apply(folder: Path) -> None:
        path = folder / file
        path.write_text(change(path.read_text()))
    return apply


def _replace(file: str, old: str, new: str):
    return _edit(file, lambda text: text.replace(old, new))


def _both(*damages):
    return lambda folder: [damage(folder) for damage in damages]


def _lines(change):
    return lambda text: "\n".join(change(text.splitlines())) + "\n"


BAD_LOGS = {
    "lever_arm_absurd": (_replace("log.toml", "position_body = [0.5, 0.0, 0.1]",
                                  "position_body = [-1e300, 0.0, 0.1]"),
                         "imu.position_body: expected each at most 10 m from the reference "
                         "point (a sensor on the vehicle) either way"),
    "noise_absurd": (_replace("log.toml", "noise_std = 0.003", "noise_std = 1e300"),
                     "dvl.noise_std: expected m/s, at most 1"),
    "missing_column": (_edit("imu.csv", _lines(lambda ls: [",".join(x.split(",")[:-2])
                                                            for x in ls])),
                       "no column 'wz' (the log description's imu.columns)"),
    "time_column_typo": (_replace("log.toml", 'time = "t_ms"', 'time = "stamp"'),
                         "no column 'stamp' (the log description's imu.time)"),
    "extra_column": (_edit("depth.csv", _lines(lambda ls: [x + ",0" for x in ls])),
                     "column '0' is not in the log description"),
    "short_row": (_edit("imu.csv", _lines(lambda ls: ls[:5] + [ls[5].rsplit(",", 1)[0]]
                                          + ls[6:])), "line 6: 7 cells, the header has 8"),
    "not_a_number": (_edit("depth.csv", lambda t: t.replace("20.0", "deep", 1)),
                     "line 2: 'deep' under 'depth' is not a number"),
    "empty_cell": (_edit("depth.csv", lambda t: t.replace("20.0", "", 1)),
                   "line 2: '' under 'depth' is not a number"),
    "trailing_delimiter": (_edit("depth.csv", _lines(lambda ls: [x + "," for x in ls])),
                           "column 3 of the header has no name; expected a name for every "
                           "column (a delimiter at the end of each line?)"),
    "semicolons": (_edit("depth.csv", lambda t: t.replace(",", ";")),
                   "no column 't_ms' (the log description's depth.time); the file has "
                   "'t_ms;depth' (its cells are separated by ';': say depth.delimiter = ';')"),
    "units_key_typo": (_replace("log.toml", "angular_rate = \"deg/s\"",
                                "angular_rates = \"deg/s\""),
                       "imu.units: unknown field 'angular_rates' (did you mean "
                       "'angular_rate'?); expected one of"),
    "nan_row": (_edit("dvl.csv", _lines(lambda ls: ls[:3] + [",".join(["nan"] * 6)]
                                        + ls[4:])), "line 4: column 't_ms' is nan"),
    "time_backwards": (_edit("depth.csv", _lines(lambda ls: ls[:4] + [ls[5], ls[4]] + ls[6:])),
                       "line 6: time runs backwards"),
    "time_repeats": (_edit("depth.csv", _lines(lambda ls: ls[:5] + [ls[4]] + ls[6:])),
                     "line 6: time repeats"),
    # Epoch stamps differ in their last digits: the message gives them as written.
    "epoch_backwards": (_edit("depth.csv", _lines(lambda ls: [ls[0]] + [
        f"{1717000050000 + 100 * (k ^ (k == 4 or k == 5))},20.0" for k in range(1, 40)])),
        "line 6: time runs backwards (1717000050500.0, then 1717000050400.0 in column "
        "'t_ms'); expected increasing stamps"),
    "deg_s_as_rad_s": (_replace("log.toml", 'angular_rate = "deg/s"', 'angular_rate = "rad/s"'),
                       "the angular rate reaches 37.42 rad/s"),  # |(10, 20, 30)|
    "g_as_m_s2": (_replace("log.toml", 'specific_force = "g"', 'specific_force = "m/s^2"'),
                  "the specific force's median magnitude is 1 m/s^2"),
    "lat_deg_as_rad": (_replace("log.toml", 'latitude = "deg"', 'latitude = "rad"'),
                       "the latitude reaches 1882.17 deg"),
    "attitude_deg_as_rad": (_replace("log.toml", 'attitude = "deg"', 'attitude = "rad"'),
                            "an attitude angle reaches 90 rad"),
    "no_overlap": (_replace("log.toml", "time_offset_s = 0.25", "time_offset_s = 1000.0"),
                   "they do not overlap"),
    "ms_as_s": (_replace("log.toml", 'time_unit = "ms"\nframe = "FLU"', 'frame = "FLU"'),
                "imu.csv': its stamps come at 0.1 Hz; expected an IMU's rate, 1 to 10000 Hz "
                "(is imu.time_unit right"),
    "spans_apart": (_edit("depth.csv", _lines(lambda ls: [ls[0]] + [
        f"{100.0 * k!r},20.0" for k in range(2001)])),  # 200 s at 10 Hz beside 1 s
        "the depth stream spans 200 s and the reference stream 1 s; expected streams of one "
        "mission (is depth.time_unit or reference.time_unit right"),
    "no_data_value_unnamed": (_replace("log.toml", "invalid = -32768\n", ""),
                              "dvl.csv' line 3: the DVL's velocity reads -32.768 m/s, beyond "
                              "15 m/s; expected a vehicle's velocity (is it the instrument's "
                              "no-data value? name it in dvl.invalid"),
    "m_s_as_mm_s": (_edit("dvl.csv", _lines(lambda ls: [ls[0]] + [
        ",".join([x.split(",")[0]] + [repr(float(c) / 1000) if float(c) != -32768 else c
                                      for c in x.split(",")[1:4]] + x.split(",")[4:])
        for x in ls[1:]])), "the DVL's median speed is 0.0015 m/s and the reference's 1.581 "
                            "m/s; expected them alike (is dvl.units.velocity right"),
    "unknown_key": (_replace("log.toml", "beam_angle_deg", "beam_angel_deg"),
                    "dvl.beam_angel_deg: unknown key"),
    "no_spec": (_replace("log.toml", "velocity_accuracy = 0.02\n", ""),
                "dvl.velocity_accuracy: missing; expected the instrument's figure"),
    "no_noise_nor_error_velocity": (
        _edit("log.toml", lambda t: t.replace("noise_std = 0.003\n", "").replace(
            ', error_velocity = "err"', "").replace(', error_velocity = "mm/s"', "").replace(
            "invalid = -32768\n", 'invalid = -32768\nignore = ["err"]\n')),
        "dvl.noise_std: missing; expected the instrument's figure"),
    "nan_cell": (_replace("dvl.csv", "\n1000.0,1490.0", "\n1000.0,nan"),
                 "line 4: column 'vx' is nan; expected a number in every cell (a row of "
                 "missing data is dropped from the log, not left NaN; a DVL that writes nan "
                 "for no bottom lock: invalid = \"nan\")"),
    "nan_time_where_nan_is_no_data": (
        _both(_replace("log.toml", "invalid = -32768", 'invalid = "nan"'),
              _replace("dvl.csv", "\n1000.0,", "\nnan,")),
        "line 4: column 't_ms' is nan"),
    "one_row": (_edit("depth.csv", _lines(lambda ls: ls[:2])),
                "depth.csv': 1 row(s) under the header; expected a stream of samples"),
    "no_rows": (_edit("depth.csv", _lines(lambda ls: ls[:1])),
                "depth.csv': 0 row(s) under the header; expected a stream of samples"),
    "stamps_off_the_stated_rate": (
        _replace("log.toml", 'time_unit = "ms"\nframe = "FLU"',
                 'time_unit = "ms"\nrate_hz = 1.0\nframe = "FLU"'),
        "its stamps come at 100 Hz, the log description's imu.rate_hz says 1 Hz"),
    "name_with_a_slash": (_replace("log.toml", 'name = "dive"', 'name = "a/b"'),
                          "log.name: expected a name without '/'"),
    "beam_angle_beyond_90": (
        _replace("log.toml", "beam_angle_deg = 30.0", "beam_angle_deg = 95.0"),
        "dvl.beam_angle_deg: expected the beams' angle"),
    "origin_beyond_the_poles": (
        _replace("log.toml", 'name = "dive"', 'name = "dive"\norigin = [200.0, 34.9, -20.0]'),
        "log.origin: expected [latitude deg in -90..90"),
    "one_column_two_fields": (_replace("log.toml", 'altitude = "alt"', 'altitude = "err"'),
                              "dvl.columns.altitude: column 'err' is also the stream's "
                              "error_velocity"),
    "header_names_a_column_twice": (_edit("depth.csv", _lines(lambda ls: [
        x + ("," + x.split(",")[1]) if i else x + ",depth" for i, x in enumerate(ls)])),
        "column 'depth' appears 2 times in the header"),
    "comment_row": (_edit("depth.csv", _lines(lambda ls: ls[:3] + ["# a note"] + ls[3:])),
                    "line 4: 1 cells, the header has 2"),
    "empty_file": (_edit("depth.csv", lambda t: ""), "depth.csv': empty; expected a header"),
    "file_is_a_folder": (_replace("log.toml", 'file = "depth.csv"', 'file = "."'),
                         "is a folder; expected the CSV file of the log description's "
                         "depth.file"),
    # tomllib recurses once per level: Python's recursion limit, not a TOML error
    "nested_too_deeply": (_edit("log.toml", lambda t: "deep = " + "[" * 3000 + "]" * 3000
                                + "\n" + t), "not valid TOML (arrays or tables nested too deeply"),
}


@pytest.mark.filterwarnings("error")  # a warning would be a second line on stderr
@pytest.mark.parametrize("case", sorted(BAD_LOGS))
def test_bad_logs_are_refused_in_one_line(case, tmp_path):
    damage, message = BAD_LOGS[case]
    folder = tmp_path / "dive"
    csv_log(folder)
    damage(folder)
    out = tmp_path / "out" / "x.h5"
    code, err = run_csv(folder, out)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("auvsim: error: "), err
    assert message in err, err
    assert not out.exists() and not (tmp_path / "out").exists()


def test_a_header_of_quoted_names_reads_as_the_names(tmp_path):
    """R's write.csv and spreadsheets quote the header's names (and not the numbers):
    the names are those inside the quotes."""
    folder = tmp_path / "dive"
    csv_log(folder)
    _edit("depth.csv", _lines(lambda ls: ['"t_ms","depth"'] + ls[1:]))(folder)
    out = tmp_path / "x.h5"
    assert run_csv(folder, out) == (0, "")
    with open_dataset(out) as ds:
        np.testing.assert_array_equal(ds.missions["dive"].depth.depth, 20.0)


def test_the_output_is_never_a_file_it_would_destroy(tmp_path):
    """The import refuses to write over one of the log's own files, over a file that is
    not HDF5, into a path under a file, or to a folder's path (a trailing /): one line,
    exit 2, and the file there as it was."""
    folder = tmp_path / "dive"
    csv_log(folder)
    (tmp_path / "notes.txt").write_text("mine\n")
    cases = {folder / "imu.csv": "a file that is not HDF5 is there",
             folder / "log.toml": "a file that is not HDF5 is there",
             tmp_path / "notes.txt": "a file that is not HDF5 is there",
             tmp_path / "notes.txt" / "x.h5": "is a file, not a folder"}
    for out, message in cases.items():
        before = {p: p.read_bytes() for p in (*folder.iterdir(), tmp_path / "notes.txt")}
        code, err = run_csv(folder, out)
        assert code == 2 and err.count("\n") == 1 and message in err, err
        assert {p: p.read_bytes() for p in before} == before
    # The library refuses the log's own files whatever they hold (an HDF5 log, say).
    for own in (folder / "imu.csv", folder / "log.toml"):
        with pytest.raises(ConfigError, match="is one of the log's own files"):
            import_logs([folder], own, format="csv", description=folder / "log.toml")
    err = io.StringIO()
    with pytest.raises(SystemExit) as exit_, contextlib.redirect_stderr(err):
        main(["import", str(folder), "--format", "csv", "--description",
              str(folder / "log.toml"), "--out", f"{tmp_path / 'new'}/"])  # the parser's
    assert exit_.value.code == 2 and err.getvalue().count("\n") == 1
    assert "ends in /, a folder; expected the file to write" in err.getvalue()
    assert not (tmp_path / "new").exists()


def test_an_output_path_a_user_gives(tmp_path):
    """An empty file (``mktemp``'s) is replaced; a FIFO is refused at once, not opened
    (which would wait for a writer); a folder is refused without generate's hint of a
    sharded dataset, which import does not write."""
    folder = tmp_path / "dive"
    csv_log(folder)
    empty = tmp_path / "empty.h5"
    empty.write_bytes(b"")
    assert run_csv(folder, empty) == (0, "")
    fifo = tmp_path / "fifo.h5"
    os.mkfifo(fifo)
    code, err = run_csv(folder, fifo)
    assert code == 2 and "not a regular file" in err, err
    code, err = run_csv(folder, tmp_path)
    assert code == 2 and "is a directory; expected a file name\n" in err, err


def test_a_symlinked_log_keeps_its_links_name(tmp_path):
    """A mission is named after the folder as the user names it, a link's own name,
    and an A-KIT segment reached through a link named TrajectoryK is one."""
    csv_log(tmp_path / "raw_2024_05_01")
    (tmp_path / "raw_2024_05_01" / "log.toml").write_text(
        DESCRIPTION.replace('name = "dive"\n', ""))
    (tmp_path / "dive3").symlink_to(tmp_path / "raw_2024_05_01")
    assert run_csv(tmp_path / "dive3", tmp_path / "x.h5") == (0, "")
    with open_dataset(tmp_path / "x.h5") as f:
        assert list(f.missions) == ["dive3"]
    _akit(tmp_path / "akit", 3)
    (tmp_path / "akit" / "Trajectory3").rename(tmp_path / "seg3")
    (tmp_path / "linked").mkdir()
    (tmp_path / "linked" / "Trajectory3").symlink_to(tmp_path / "seg3")
    assert run(["import", str(tmp_path / "linked" / "Trajectory3"), "--format", "akit",
                "--out", str(tmp_path / "a.h5")]) == (0, "")


def test_ignored_columns_may_share_a_name(tmp_path):
    """Columns the description ignores may repeat a name (a logger's "Reserved" ones);
    a described column named twice is refused (which would it be?)."""
    folder = tmp_path / "dive"
    csv_log(folder)
    depth = folder / "depth.csv"
    lines = depth.read_text().splitlines()
    depth.write_text("\n".join([lines[0] + ",reserved,reserved"]
                               + [x + ",0,0" for x in lines[1:]]) + "\n")
    (folder / "log.toml").write_text(DESCRIPTION.replace(
        'columns = {depth = "depth"}', 'columns = {depth = "depth"}\nignore = ["reserved"]'))
    assert run_csv(folder, tmp_path / "x.h5") == (0, "")


def test_a_log_named_by_its_folder_as_dot(tmp_path, monkeypatch):
    """Run from inside the log's folder (``auvsim import .``), the mission is named by the
    folder, as from outside; a description with a byte-order mark reads as without."""
    folder = tmp_path / "dive"
    csv_log(folder)
    (folder / "log.toml").write_text("\ufeff" + DESCRIPTION.replace('name = "dive"\n', ""),
                                     encoding="utf-8")
    monkeypatch.chdir(folder)
    assert run(["import", ".", "--format", "csv", "--description", "log.toml", "--out",
                str(tmp_path / "x.h5")]) == (0, "")
    with open_dataset(tmp_path / "x.h5") as f:
        assert list(f.missions) == ["dive"]


def test_a_description_is_checked_before_any_file_is_read(tmp_path):
    """A description without the IMU's specifications is refused naming the description
    file, before the CSVs (absent here) are looked for."""
    folder = tmp_path / "dive"
    folder.mkdir()
    (folder / "log.toml").write_text(
        DESCRIPTION[:DESCRIPTION.index("[imu.noise]")] + DESCRIPTION[DESCRIPTION.index("[dvl]"):])
    code, err = run_csv(folder, tmp_path / "x.h5")
    assert code == 2 and err.count("\n") == 1, err
    assert f"{folder / 'log.toml'}: imu.noise: missing" in err, err


@pytest.mark.parametrize("layout", ["akit", "csv"])
@pytest.mark.parametrize("option", [["--rate", "7"], ["--preset", "paper-sim"],
                                    ["--noise-std", "0.01"], ["--seed", "3"]])
def test_velocity_options_are_refused_with_another_format(layout, option, tmp_path):
    folder = tmp_path / "logs"
    if layout == "akit":
        _akit(folder)
    else:
        csv_log(folder)
    out = tmp_path / "x.h5"
    extra = ["--description", str(folder / "log.toml")] if layout == "csv" else []
    code, err = run(["import", str(folder), "--format", layout, *extra, *option,
                     "--out", str(out)])
    assert code == 2 and err.count("\n") == 1, err
    assert f"{option[0]}: only for --format velocity" in err, err
    assert not out.exists()


def test_a_lat_lon_in_radians_declared_degrees_disagrees_with_the_velocity(tmp_path):
    folder = tmp_path / "dive"
    csv_log(folder)
    nav = folder / "nav.csv"
    lines = nav.read_text().splitlines()
    rows = [line.split(",") for line in lines[1:]]
    for r in rows:  # radians written where degrees are declared: 57x too short a track
        r[1], r[2] = repr(math.radians(float(r[1]))), repr(math.radians(float(r[2])))
    speed = 30.0  # m/s over 1 s: far enough for the check to mean something
    for r, k in zip(rows, range(2), strict=True):
        r[5] = repr(speed)
        r[1] = repr(math.radians(LAT0 + np.degrees(speed * k / radii(LAT0)[0])))
    nav.write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    code, err = run_csv(folder, tmp_path / "x.h5")
    assert code == 2 and "the positions travel" in err and err.count("\n") == 1
    assert not (tmp_path / "x.h5").exists()


def _turning_reference(folder: Path) -> None:
    """nav.csv of ``csv_log`` replaced by 60 s of a turn at 1.5 m/s (heading 0.05 t rad
    from north; positions its exact integral, about 60 m), in ENU as declared."""
    t = np.arange(61.0)
    psi, speed, rate = 0.05 * t, 1.5, 0.05
    north, east = speed / rate * np.sin(psi), speed / rate * (1 - np.cos(psi))
    m, n = (r + H0 for r in radii(LAT0))
    lat = LAT0 + np.degrees(north / m)
    lon = LON0 + np.degrees(east / (n * math.cos(math.radians(LAT0))))
    _write_csv(folder / "nav.csv", ["t_ms", "lat", "lon", "h", "ve", "vn", "vu", "roll",
                                    "pitch", "yaw"],
               [1000 * t, lat, lon, np.full_like(t, H0), speed * np.sin(psi),
                speed * np.cos(psi), 0 * t, 0 * t, 0 * t, 90 - np.degrees(psi)])


@pytest.mark.parametrize("mistake, said", [
    (None, None),
    (("frame = \"ENU\"", "frame = \"NED\""), "mean turn of"),  # ENU velocities as NED
    (("columns.latitude = \"lat\"\ncolumns.longitude = \"lon\"",
      "columns.latitude = \"lon\"\ncolumns.longitude = \"lat\""), "mean turn of"),
])
def test_a_reference_whose_positions_and_velocities_part_ways_is_refused(tmp_path, mistake,
                                                                         said):
    """A turning track whose positions are its velocities' integral imports; the same
    with the reference's frame declared NED for its ENU velocities, or its latitude and
    longitude columns swapped, moves its positions in another direction than its
    velocities and is refused in one line (the distances still agree)."""
    folder = tmp_path / "dive"
    csv_log(folder)
    _turning_reference(folder)
    if mistake is not None:
        _replace("log.toml", *mistake)(folder)
    code, err = run_csv(folder, tmp_path / "x.h5")
    if said is None:
        assert (code, err) == (0, "")
    else:
        assert code == 2 and err.count("\n") == 1 and said in err, err
        assert "the positions move in another direction than the velocities" in err
        assert not (tmp_path / "x.h5").exists()


def _diving_reference(folder: Path, *, depth_column: bool = False) -> None:
    """nav.csv of ``csv_log`` replaced by 60 s of a dive at 0.3 m/s on a heading of 45
    deg (north and east alike, so that the horizontal legs cannot tell them apart), in ENU
    as declared; with ``depth_column`` the height column holds the depth (positive down)."""
    t = np.arange(61.0)
    v = np.array([1.0, 1.0, 0.3])  # NED, m/s
    lat, lon, h = _geodetic(t, v)
    _write_csv(folder / "nav.csv", ["t_ms", "lat", "lon", "h", "ve", "vn", "vu", "roll",
                                    "pitch", "yaw"],
               [1000 * t, lat, lon, -h if depth_column else h, np.full_like(t, v[1]),
                np.full_like(t, v[0]), np.full_like(t, -v[2]), 0 * t, 0 * t, 0 * t + 45.0])


@pytest.mark.parametrize("mistake", [None, "frame", "depth"])
def test_a_reference_whose_heights_and_vertical_velocity_part_ways_is_refused(tmp_path,
                                                                              mistake):
    """A dive on a heading of 45 deg whose heights are its vertical velocity's integral
    imports; the same with its ENU velocities declared NED (up read as down), or with a
    depth in the height column, is refused in one line: its horizontal legs agree either
    way."""
    folder = tmp_path / "dive"
    csv_log(folder)
    _diving_reference(folder, depth_column=mistake == "depth")
    if mistake == "frame":
        _replace("log.toml", 'frame = "ENU"', 'frame = "NED"')(folder)
    code, err = run_csv(folder, tmp_path / "x.h5")
    if mistake is None:
        assert (code, err) == (0, "")
    else:
        assert code == 2 and err.count("\n") == 1, err
        assert "the heights go down where the vertical velocity goes up" in err, err
        assert not (tmp_path / "x.h5").exists()


def test_a_reference_a_thousandfold_apart_asks_for_the_time_unit():
    """Stamps in ms read as s: the velocities integrate over a thousand times the time the
    positions took, and the line asks for the time unit, not the latitude's."""
    from auvsim.data.recorded import _check_track

    t = np.arange(30.0)
    v = np.tile([1.0, 0.0, 0.0], (30, 1))
    with pytest.raises(ConfigError, match="a thousandfold or more: is reference.time_unit"):
        _check_track({"reference/time": 1000 * t, "reference/position_ned": t[:, None] * v,
                      "reference/velocity_ned": v}, "nav.csv")


def test_a_short_fast_reference_that_agrees_with_itself_passes():
    """Five samples (fewer than a leg) 40 m apart: the track's one leg is its whole span;
    its north and east swapped (a straight line north read as east) are refused."""
    from auvsim.data.recorded import _check_track

    t = np.arange(5.0)
    v = np.tile([10.0, 0.0, 0.0], (5, 1))
    _check_track({"reference/time": t, "reference/position_ned": t[:, None] * v,
                  "reference/velocity_ned": v}, "nav.csv")
    with pytest.raises(ConfigError, match="another direction than the velocities"):
        _check_track({"reference/time": t, "reference/position_ned": t[:, None] * v[:, [1, 0, 2]],
                      "reference/velocity_ned": v}, "nav.csv")


def test_a_recorded_mission_is_checked_by_the_reader(akit, tmp_path):
    out, _ = akit
    bad = tmp_path / "bad.h5"
    for change, message in (
            (lambda g: g.attrs.__setitem__("groups", '["imu", "sonar"]'), "attribute groups"),
            (lambda g: g.attrs.__setitem__("groups", '["imu", "reference"]'),
             "holds group dvl, which its groups attribute"),
            (lambda g: g.__delitem__("reference/velocity_ned"), "lacks reference/velocity_ned"),
            (lambda g: g.attrs.__delitem__("dvl_noise_std"), "lacks attribute dvl_noise_std"),
            # a hand-edited JSON attribute: refused at opening, not met by inspect's parser
            (lambda g: g.attrs.__setitem__("source_files", "IMU.csv"),
             r"its source_files attribute is not a JSON list \('IMU.csv'\)")):
        bad.write_bytes(out.read_bytes())
        with h5py.File(bad, "r+") as f:
            change(f["missions/trajectory3"])
        with pytest.raises(DatasetError, match=message):
            open_dataset(bad)
    with h5py.File(bad, "r+") as f:
        f.attrs["format_version"] = 6
    with pytest.raises(DatasetError, match="has origin 'recorded'"):
        open_dataset(bad)


# The shared A-KIT segments, where ../shared is present --------------------------------

@pytest.mark.skipif(SHARED is None, reason="../shared/data/snapir-akit is not here")
def test_the_six_shared_segments(tmp_path):
    out = tmp_path / "akit.h5"
    assert run(["import", str(SHARED), "--format", "akit", "--out", str(out)]) == (0, "")
    with open_dataset(out) as f:
        assert list(f.missions) == [f"trajectory{k}" for k in range(1, 7)]
        for k, m in enumerate(f.missions.values(), start=1):
            seg = SHARED / f"Trajectory{k}"
            imu = np.loadtxt(seg / f"IMU_trajectory{k}.csv", delimiter=",", skiprows=1)
            dvl = np.loadtxt(seg / f"DVL_trajectory{k}.csv", delimiter=",", skiprows=1)
            gt = np.loadtxt(seg / f"GT_trajectory{k}.csv", delimiter=",", skiprows=1)
            np.testing.assert_array_equal(m.imu.time, imu[:, 0])
            np.testing.assert_array_equal(m.imu.specific_force, imu[:, 1:4])
            np.testing.assert_array_equal(m.imu.angular_rate, imu[:, 4:7])
            np.testing.assert_array_equal(m.dvl.velocity_ls, dvl[:, 1:4])
            np.testing.assert_array_equal(m.reference.time, gt[:, 0])
            np.testing.assert_array_equal(m.reference.velocity_ned, gt[:, 4:7])
            np.testing.assert_allclose(np.radians(m.reference.latitude_deg), gt[:, 2],
                                       rtol=1e-15)
            assert m.attrs["imu_rate_hz"] == pytest.approx(100.0, rel=1e-4)
            assert m.attrs["dvl_rate_hz"] == pytest.approx(1.0, rel=0.01)
            pos = m.reference.position_ned
            np.testing.assert_array_equal(pos[0], 0.0)
            # Positions and velocities of the reference agree: the trapezoid integral of
            # its NED velocity lands within a few metres of its last position.
            t, v = m.reference.time, m.reference.velocity_ned
            flown = np.sum((v[1:] + v[:-1]) / 2 * np.diff(t)[:, None], axis=0)
            assert np.linalg.norm(flown[:2] - pos[-1, :2]) < 0.02 * np.abs(
                np.diff(pos[:, :2], axis=0)).sum()


def test_every_group_is_optional(tmp_path, capsys):
    """A log of a DVL alone, its origin given by the description: imported, inspected
    and drawn."""
    folder = tmp_path / "dvl_only"
    csv_log(folder)
    dvl = DESCRIPTION[DESCRIPTION.index("[dvl]"):DESCRIPTION.index("[depth]")]
    text = ('[log]\nname = "dvl_only"\norigin = [32.85, 34.89, -20.0]\n\n' + dvl)
    (folder / "only.toml").write_text(text)
    out = tmp_path / "only.h5"
    assert run_csv(folder, out, "only.toml") == (0, "")
    with open_dataset(out) as f:
        m = f.missions["dvl_only"]
        assert m.groups == ["dvl"] and json.loads(m.attrs["groups"]) == ["dvl"]
        assert m.attrs["gravity"] == normal_gravity(32.85, -20.0)
        np.testing.assert_allclose(m.dvl.time, np.arange(4) * 0.5)  # its own first stamp: 0
        with pytest.raises(DatasetError, match="has no reference group"):
            m.reference  # noqa: B018
        with pytest.raises(DatasetError, match="neither a reference nor a truth"):
            require_attitude(m)
    assert main(["inspect", str(out)]) == 0
    assert "dvl: 4 samples at 2 Hz" in capsys.readouterr().out
    assert main(["plot", str(out), "--out", str(tmp_path)]) == 0
    assert (tmp_path / "only_dvl_only.png").is_file()


def test_a_yaw_of_another_frame_than_the_velocity_is_refused():
    """A compass heading in an ENU yaw column (read as 90 - h) passed the import, and
    check-log then found nonsense in every stream; a yaw that is the velocity's course,
    or off it by a current's crab angle, passes."""
    from auvsim.data.recorded import _check_heading

    north = np.tile([1.5, 0.0, 0.0], (50, 1))
    velocity = np.concatenate([north, -north])  # a lawnmower's two legs: north, south
    right = np.zeros((100, 3))
    right[50:, 2] = 180.0
    crabbed = right + [0.0, 0.0, 25.0]  # a current on the beam: 25 deg off the course
    compass = right.copy()
    compass[:, 2] = 90.0 - right[:, 2]  # h written where an ENU yaw goes
    for yaw in (right, crabbed):
        _check_heading({"reference/velocity_ned": velocity, "reference/rpy_deg": yaw}, "nav")
    with pytest.raises(ConfigError, match=re.escape(
            "nav: the yaw differs from the course over the ground by 90 deg (median, where it "
            "moves faster than 1 m/s); expected them within 60 deg")):
        _check_heading({"reference/velocity_ned": velocity, "reference/rpy_deg": compass},
                       "nav")
