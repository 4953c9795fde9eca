"""``auvsim check-log``: what a recorded log does not document, found from its data.

Known answers from simulated missions: the simulator's truth, sampled at 1 Hz, becomes
the reference (its point: the body origin), and its IMU and DVL become recorded streams
with injected faults: an axis map, clock offsets of either sign, a clock-rate error. The
lever arms are the ``navigator`` preset's sensor positions (the Snapir's: IMU at (-1.77,
-0.01, -0.14) m, DVL at (-1.85, -0.03, 0.13) m FRD), which the simulated sensors measure
at. The issue's targets: the axis map exactly, each clock offset within 0.05 s with its
sign, the lever arms within 0.1 m. The shared A-KIT segments, where
``../shared/data/snapir-akit`` exists, must come out of ``--apply`` self-consistent.
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from auvsim.cli import main
from auvsim.config import MissionConfig, ScenarioConfig
from auvsim.data.checklog import (
    T_3SIGMA,
    Log,
    Report,
    _exponential_sum,
    applied_clock_errors,
    applied_dvl_errors,
    axis_map_names,
    axis_maps,
    changes,
    check_arrays,
    check_file,
    fit_clock,
    least_squares,
    scan,
    serial_least_squares,
)
from auvsim.data.reader import open_dataset
from auvsim.data.schema import mission_attrs
from auvsim.data.writer import DatasetWriter
from auvsim.errors import ConfigError, DatasetError
from auvsim.physics.earth import radii
from auvsim.runs.generate import generate
from auvsim.runs.presets import SNAPIR_DVL_POSITION, SNAPIR_IMU_POSITION, preset

REPO = Path(__file__).resolve().parents[1]
SHARED = next((p / "shared/data/snapir-akit" for p in REPO.parents
               if (p / "shared/data/snapir-akit").is_dir()), None)
IMU_POSITION = np.array(SNAPIR_IMU_POSITION)  # m FRD: the navigator preset's, the Snapir's
DVL_POSITION = np.array(SNAPIR_DVL_POSITION)
OFFSET_TOL = 0.05  # s, the target
LEVER_TOL = 0.1  # m, the target
# A proper map that swaps and flips (det +1) and a reflection (det -1).
SWAP = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
REFLECT = np.diag([1.0, -1.0, 1.0])


# ---- pure functions -------------------------------------------------------------------


def test_axis_maps_are_the_24_proper_signed_permutations():
    proper = axis_maps()
    assert len(proper) == 24
    assert all(np.linalg.det(p) == pytest.approx(1.0) for p in proper)
    assert len({tuple(p.ravel()) for p in proper}) == 24
    everything = axis_maps(proper=False)
    assert len({tuple(p.ravel()) for p in everything}) == 48
    assert axis_map_names(SWAP) == ["y", "x", "-z"]
    assert axis_map_names(np.diag([1.0, -1.0, -1.0])) == ["x", "-y", "-z"]


def test_scan_finds_a_minimum_between_grid_points():
    offset, curvature = scan(lambda o: 3.0 * (o - 0.1234) ** 2 + 1.0)
    assert offset == pytest.approx(0.1234, abs=1e-9)
    assert curvature == pytest.approx(6.0)


def test_the_t_quantiles_are_students():
    stats = pytest.importorskip("scipy.stats")
    expected = stats.t.ppf(stats.norm.cdf(3.0), np.arange(1, len(T_3SIGMA) + 1))
    np.testing.assert_allclose(T_3SIGMA, expected, rtol=5e-3)


def test_fit_clock_keeps_a_significant_slope_and_drops_noise():
    s = np.array([50.0, 150.0, 250.0, 350.0])
    line = fit_clock(list(s), list(0.3 + 2.5e-3 * s + [1e-3, -1e-3, 1e-3, -1e-3]), 0.7)
    assert line.offset == pytest.approx(0.3, abs=3e-3)
    assert line.rate_error == pytest.approx(2.5e-3, rel=0.02)
    flat = fit_clock(list(s), [0.31, 0.29, 0.30, 0.31], 0.30)
    assert flat.rate_error == 0.0 and flat.offset == 0.30
    # Significant, but 20 ppm moves the clock 6 ms over the windows: not worth a rate.
    tiny = fit_clock(list(s), list(0.3 + 2e-5 * s), 0.303)
    assert tiny.rate_error == 0.0 and tiny.offset == 0.303


# ---- known answers from simulated missions ----------------------------------------------


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """Three missions of the ``navigator`` preset's sensors (noise, biases, scale factors,
    misalignments, DVL errors): a 300 s zigzag (turns all along: lever arms, clocks), a
    300 s lawnmower (straight legs: gravity) and a 300 s yoyo (dives and climbs: the
    depth sensor's clock).

    The preset's DVL carries a slow velocity error (9 mm/s over 19 s, Gauss-Markov),
    which the DVL clock's fit sees as noise correlated over several pings. Over 300 s of
    this zigzag, seeds 3-6 leave the DVL offset -0.004, +0.004, +0.005 and -0.002 s off
    (its slow error was 18 mm/s over 3 s before it was measured against the IMU: then
    300 s left it 0.07 s off, and the zigzag flew 600 s)."""
    base = preset("navigator")
    missions = (MissionConfig(name="zigzag", seed=3,
                              scenario=ScenarioConfig(name="zigzag", duration=300.0)),
                MissionConfig(name="lawnmower", seed=4,
                              scenario=ScenarioConfig(name="lawnmower", duration=300.0)),
                MissionConfig(name="yoyo", seed=5,
                              scenario=ScenarioConfig(name="yoyo", duration=300.0)))
    path = tmp_path_factory.mktemp("checklog") / "sim.h5"
    generate(dataclasses.replace(base, missions=missions), path, workers=1, progress=False)
    out = {}
    with open_dataset(path) as ds:
        for name, m in ds.missions.items():
            out[name] = dict(
                t=m.truth.time, q=m.truth.quaternion, v=m.truth.velocity_ned,
                p=m.truth.position_ned, imu_t=m.imu.time, f=m.imu.specific_force,
                w=m.imu.angular_rate, dvl_t=m.dvl.time, dvl_v=m.dvl.velocity_ls,
                depth_t=m.depth.time, depth=m.depth.depth,
                gravity=m.attrs["gravity"],
                imu_site=m.attrs["imu_position_body"], dvl_site=m.attrs["dvl_position_body"])
    return out


def recorded_log(sim: dict, *, axes: np.ndarray, imu_offset: float, imu_rate: float,
                 dvl_offset: float, start: float = 5.0, stretch: float = 0.0) -> Log:
    """The simulated mission as a recorded log: the truth at 1 Hz as the reference, the
    IMU's triads logged through ``axes`` (body = axes @ logged), and each stream stamped
    so that stamp s happened at reference time ``s + offset + rate * s`` (all stamps
    ``start`` s later, so none is negative). With ``stretch``, the reference's and the
    DVL's stamps are ``(1 + stretch)`` x the reference clock's (the A-KIT logs': 400/399
    - 1), the IMU's keep it."""
    step = int(round(1.0 / float(np.median(np.diff(sim["t"])))))
    ref = slice(0, None, step)
    imu_stamp = (sim["imu_t"] + start - imu_offset) / (1 + imu_rate)
    return Log((sim["t"][ref] + start) * (1 + stretch), sim["v"][ref], sim["q"][ref],
               sim["p"][ref], imu_stamp, sim["f"] @ axes, sim["w"] @ axes,
               (sim["dvl_t"] + start - dvl_offset) * (1 + stretch), sim["dvl_v"],
               gravity=sim["gravity"])


def findings(report) -> dict:
    return {f.name: f for f in report.findings}


@pytest.mark.parametrize("axes, imu_offset, imu_rate, dvl_offset", [
    (SWAP, 0.37, 2.5e-3, -0.8),  # the A-KIT IMU's stretch: 400 stamped s for 399 s
    (REFLECT, -0.62, 0.0, 0.45),
])
def test_injected_faults_are_recovered(simulated, axes, imu_offset, imu_rate, dvl_offset):
    sim = simulated["zigzag"]
    np.testing.assert_array_equal(sim["imu_site"], IMU_POSITION)  # what the answers rest on
    np.testing.assert_allclose(sim["dvl_site"], DVL_POSITION, atol=1e-12)
    log = recorded_log(sim, axes=axes, imu_offset=imu_offset, imu_rate=imu_rate,
                       dvl_offset=dvl_offset)
    report = check_arrays(log, "zigzag")
    found = findings(report)
    c = report.corrections
    np.testing.assert_array_equal(c["imu_axis_matrix"], axes)
    assert found["imu axes"].value["margin"] > 2
    assert found["imu axes"].value["determinant"] == round(np.linalg.det(axes))
    # The offset at the stamps' zero; with a rate error, the line through the windows.
    assert c["imu_time_offset_s"] == pytest.approx(imu_offset, abs=OFFSET_TOL)
    assert c["imu_rate_error"] == pytest.approx(imu_rate, abs=3e-4)
    assert c["dvl_time_offset_s"] == pytest.approx(dvl_offset, abs=OFFSET_TOL)
    assert c["dvl_rate_error"] == 0.0
    np.testing.assert_allclose(c["dvl_position_body"], DVL_POSITION, atol=LEVER_TOL)
    np.testing.assert_allclose(c["imu_position_body"], IMU_POSITION, atol=LEVER_TOL)
    # Over the whole log the IMU's corrected clock agrees with the reference's within
    # the target, at its first and its last sample.
    s = log.imu_time[[0, -1]]
    corrected = s + c["imu_time_offset_s"] + c["imu_rate_error"] * s
    truth = s + imu_offset + imu_rate * s
    np.testing.assert_allclose(corrected, truth, atol=OFFSET_TOL)


def test_the_imu_lever_arm_has_no_bias_from_the_attitude_between_samples(simulated):
    """The IMU's lever arm's z had come out 25 mm off on every simulated log (g dt / 4:
    the attitude propagated with each gyro sample held over the step before it, half a
    sample behind the instants every other sum takes, tilted gravity into the roll rate's
    column). Its x keeps 7-8 mm: the simulator's velocities are MuJoCo's end-of-step ones,
    5 ms behind its positions and specific force, which a log of instants cannot tell
    from a lever arm."""
    log = recorded_log(simulated["zigzag"], axes=REFLECT, imu_offset=-0.62, imu_rate=0.0,
                       dvl_offset=0.45)
    found = np.asarray(check_arrays(log, "zigzag").corrections["imu_position_body"])
    error = found - IMU_POSITION
    assert abs(error[2]) < 0.008, error
    assert np.all(np.abs(error) < 0.012), error


def test_the_imu_lever_arm_fit_takes_the_earths_rate_out_of_the_gyros(tmp_path):
    """A gyro on the rotating Earth reads the body's rate plus C^T Omega_ie; the fit's
    attitude turns with the body's rate in NED. With an ideal IMU at 32.85 deg N, the
    accelerometer bias it fits beside the lever arm is within 10 ug of none (its y was
    35 ug with the Earth's rate left in the gyros)."""
    from auvsim.sensors.imu import IMU_GRADES

    mission_config = MissionConfig(name="zigzag", seed=3,
                                   scenario=ScenarioConfig(name="zigzag", duration=300.0))
    path = tmp_path / "ideal.h5"
    generate(dataclasses.replace(preset("navigator"), imu=IMU_GRADES["ideal"],
                                 missions=(mission_config,)), path, workers=1, progress=False)
    with open_dataset(path) as ds:
        m = ds.missions["zigzag"]
        latitude = float(m.attrs["latitude_deg"])
        ref = slice(0, None, 100)
        log = Log(m.truth.time[ref] + 5, m.truth.velocity_ned[ref], m.truth.quaternion[ref],
                  m.truth.position_ned[ref], m.imu.time + 5, m.imu.specific_force,
                  m.imu.angular_rate, m.dvl.time + 5, m.dvl.velocity_ls,
                  gravity=m.attrs["gravity"], latitude_deg=latitude)
    assert latitude == pytest.approx(32.85, abs=0.01)
    found = findings(check_arrays(log, "zigzag"))["imu lever arm"].value
    micro_g = np.abs(found["accel_bias"]) / 9.80665e-6
    assert np.all(micro_g < 10), micro_g
    np.testing.assert_allclose(found["position_body_m"], IMU_POSITION, atol=0.012)


@pytest.mark.parametrize("offset", [0.7, -1.3])
def test_an_injected_depth_clock_offset_is_recovered_where_the_vehicle_dives(simulated,
                                                                              offset, tmp_path):
    """The yoyo's depth sensor stamped ``offset`` s early (a stamp s happened at s +
    offset): found within 0.05 s, with high or medium confidence, and applied (the file it
    writes checks at 0); a log whose depth never changes leaves it not observable, and
    nothing is applied."""
    sim = simulated["yoyo"]
    log = recorded_log(sim, axes=np.eye(3), imu_offset=0.0, imu_rate=0.0, dvl_offset=0.0)
    log = dataclasses.replace(log, depth_time=sim["depth_t"] + 5.0 - offset,
                              depth=sim["depth"])
    report = check_arrays(log, "yoyo")
    found = findings(report)["depth clock"]
    assert found.confidence in ("high", "medium"), found
    assert report.corrections["depth_time_offset_s"] == pytest.approx(offset, abs=OFFSET_TOL)
    raw, fixed = tmp_path / "raw.h5", tmp_path / "fixed.h5"
    write_recorded(raw, log)
    # (--accept-low: a yoyo turns too little for the IMU's clock, which is not this test's)
    status, out, err = run(["check-log", str(raw), "--apply", str(fixed), "--accept-low"])
    assert status == 0, err + out
    with open_dataset(fixed) as ds:
        assert ds.missions["sim"].attrs["depth_time_offset_s"] == pytest.approx(
            offset, abs=OFFSET_TOL)
    status, out, _ = run(["check-log", str(fixed), "--json"])
    assert status == 0 and abs(json.loads(out)[0]["corrections"]["depth_time_offset_s"]) \
        < OFFSET_TOL
    # Flown level, a vehicle still heaves by a few cm/s, which this depth sensor's noise
    # lets tell the clock (the zigzag's: found +0.695 s); a log whose depth never changes
    # does not.
    level = simulated["zigzag"]
    log = recorded_log(level, axes=np.eye(3), imu_offset=0.0, imu_rate=0.0, dvl_offset=0.0)
    flat_velocity = log.reference_velocity * [1.0, 1.0, 0.0]
    flat_position = log.reference_position * [1.0, 1.0, 0.0]
    report = check_arrays(dataclasses.replace(
        log, reference_velocity=flat_velocity, reference_position=flat_position,
        depth_time=level["depth_t"] + 5.0, depth=np.full(len(level["depth"]), 20.0)),
        "flat")
    assert findings(report)["depth clock"].confidence == "not observable"
    assert "depth_time_offset_s" not in report.corrections


def test_a_stream_alone_and_a_short_log(simulated):
    sim = simulated["zigzag"]
    log = recorded_log(sim, axes=SWAP, imu_offset=0.37, imu_rate=0.0, dvl_offset=-0.8)
    imu_only = check_arrays(dataclasses.replace(log, dvl_time=None, dvl_velocity=None))
    assert imu_only.corrections["imu_axis_map"] == ["y", "x", "-z"]
    assert imu_only.corrections["imu_time_offset_s"] == pytest.approx(0.37, abs=OFFSET_TOL)
    assert "dvl_time_offset_s" not in imu_only.corrections
    # The DVL alone turns with the reference's 1 Hz attitude rates: its clock is found
    # less well, and says so.
    dvl_only = check_arrays(dataclasses.replace(log, imu_time=None, specific_force=None,
                                                angular_rate=None))
    assert "imu_axis_map" not in dvl_only.corrections
    assert dvl_only.corrections["dvl_time_offset_s"] == pytest.approx(-0.8, abs=0.2)
    short = dataclasses.replace(log, reference_time=log.reference_time[:20],
                                reference_velocity=log.reference_velocity[:20],
                                reference_quaternion=log.reference_quaternion[:20],
                                reference_position=log.reference_position[:20])
    with pytest.raises(DatasetError, match="expected at least 30"):
        check_arrays(short, "short")


def test_gravity_on_the_straight_legs(simulated):
    sim = simulated["lawnmower"]
    report = check_arrays(recorded_log(sim, axes=np.eye(3), imu_offset=0.0, imu_rate=0.0,
                                       dvl_offset=0.0), "lawnmower")
    g = findings(report)["gravity"].value
    assert g["quiet_intervals"] >= 20
    # The simulated world's gravity (the WGS-84 normal gravity at the preset's latitude,
    # 9.7955 m/s^2): within 3 standard errors, and the vehicle's own accelerations on a
    # straight leg (a few mm/s^2).
    assert abs(g["mean_specific_force"] - sim["gravity"]) < 3 * g["se"] + 5e-3


# ---- the command on a recorded file -------------------------------------------------------


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


def write_recorded(path: Path, log: Log, name: str = "sim", description: str = "") -> None:
    """``log`` as a recorded mission (schema v7) at a made-up origin, sensors undescribed
    (positions, mountings and offsets 0), as ``auvsim import`` would write it."""
    lat0, lon0, h0 = 32.85, 34.89, -20.0
    m, n = radii(lat0)
    p = log.reference_position
    fields = {
        "imu/time": log.imu_time, "imu/specific_force": log.specific_force,
        "imu/angular_rate": log.angular_rate, "dvl/time": log.dvl_time,
        "dvl/velocity_ls": log.dvl_velocity,
        "dvl/mode": np.zeros(len(log.dvl_time), dtype=np.int64),
        "reference/time": log.reference_time,
        "reference/latitude_deg": lat0 + np.degrees(p[:, 0] / (m + h0)),
        "reference/longitude_deg": lon0 + np.degrees(
            p[:, 1] / ((n + h0) * math.cos(math.radians(lat0)))),
        "reference/height_m": h0 - p[:, 2], "reference/position_ned": p,
        "reference/velocity_ned": log.reference_velocity,
        "reference/quaternion": log.reference_quaternion,
        "reference/rpy_deg": np.zeros((len(p), 3)),
    }
    zero = np.zeros(3)
    attrs = mission_attrs(
        origin="recorded", scenario="recorded", seed=0,
        duration_s=float(max(log.imu_time[-1], log.dvl_time[-1], log.reference_time[-1])),
        groups=json.dumps(["imu", "dvl", "reference"]), latitude_deg=lat0,
        longitude_deg=lon0, height_m=h0, gravity=log.gravity, log_description=description,
        source_files="[]", source_sha256="[]",
        imu_rate_hz=1 / float(np.median(np.diff(log.imu_time))), imu_position_body=zero,
        imu_accel_noise_density=0.0, imu_gyro_noise_density=0.0,
        imu_accel_bias_instability=0.0, imu_gyro_bias_instability=0.0,
        imu_bias_correlation_time=3600.0, imu_time_offset_s=0.0,
        dvl_rate_hz=1 / float(np.median(np.diff(log.dvl_time))), beam_angle_deg=30.0,
        dvl_position_body=zero, dvl_mounting_rpy_deg=zero, dvl_noise_std=0.0,
        dvl_velocity_accuracy=0.02, dvl_time_offset_s=0.0, dvl_beams_derived=1,
        reference_source="the simulator's truth at 1 Hz", reference_rate_hz=1.0,
        reference_time_offset_s=0.0, log_time_origin_s=0.0)
    rows = {"imu": len(log.imu_time), "dvl": len(log.dvl_time), "reference": len(p)}
    if log.depth_time is not None:  # a depth sensor too
        fields.update({"depth/time": log.depth_time, "depth/depth": log.depth})
        attrs.update(groups=json.dumps(["imu", "dvl", "depth", "reference"]),
                     depth_rate_hz=1 / float(np.median(np.diff(log.depth_time))),
                     depth_time_offset_s=0.0)
        rows["depth"] = len(log.depth_time)
    with DatasetWriter(path, config_json="{}") as writer:
        sink = writer.mission(name, attrs, rows=rows)
        sink.append(fields)
        sink.flush()


def test_check_log_apply_writes_a_file_that_checks_clean(simulated, tmp_path):
    log = recorded_log(simulated["zigzag"], axes=SWAP, imu_offset=0.37, imu_rate=0.0,
                       dvl_offset=-0.8)
    raw, fixed = tmp_path / "raw.h5", tmp_path / "fixed.h5"
    write_recorded(raw, log)
    status, out, err = run(["check-log", str(raw), "--apply", str(fixed)])
    assert (status, err) == (0, "")
    assert "imu axes" in out and "[y, x, -z]" in out and f"wrote {fixed}" in out
    # What it corrected, said (it had said only "sim corrected").
    said = out.splitlines()[-1]
    assert said.startswith("  sim: IMU axes [y, x, -z]; onto the ") and "DVL -0.8" in said \
        and "; IMU at [" in said and "; DVL at [" in said, said
    with open_dataset(fixed) as ds:
        m = ds.missions["sim"]
        report = json.loads(m.attrs["check_log_json"])
        assert report["corrections"]["imu_axis_map"] == ["y", "x", "-z"]
        np.testing.assert_allclose(m.attrs["dvl_position_body"], DVL_POSITION, atol=LEVER_TOL)
        np.testing.assert_allclose(m.attrs["imu_position_body"], IMU_POSITION, atol=LEVER_TOL)
        assert m.attrs["imu_time_offset_s"] == pytest.approx(0.37, abs=OFFSET_TOL)
        assert m.attrs["dvl_time_offset_s"] == pytest.approx(-0.8, abs=OFFSET_TOL)
        # The IMU's triads are body FRD now: gravity levelled at the first sample.
        assert m.imu.specific_force[:100, 2].mean() == pytest.approx(-log.gravity, abs=0.1)
        assert m.reference.time[0] >= 0 and m.imu.time[0] >= 0 and m.dvl.time[0] >= 0
    status, out, _ = run(["check-log", str(fixed), "--json"])
    assert status == 0
    again = json.loads(out)[0]["corrections"]
    assert again["imu_axis_map"] == ["x", "y", "z"]
    assert abs(again["imu_time_offset_s"]) < OFFSET_TOL
    assert abs(again["dvl_time_offset_s"]) < OFFSET_TOL


STATED = "[imu]\nrate_hz = {imu}\n[dvl]\nrate_hz = 1.0\n[reference]\nrate_hz = 1.0\n"


def test_apply_puts_a_stretched_reference_on_the_imus_clock(simulated, tmp_path):
    """The A-KIT case: the reference's and the DVL's stamps stretched by 400/399 against
    their stated 1 Hz, the IMU's true to its stated rate. The corrected file must be on
    the IMU's (the true) clock: the reference's last stamp within the target of the truth's
    span, the IMU's stamps unchanged."""
    sim = simulated["zigzag"]
    stretch = 400 / 399 - 1
    log = recorded_log(sim, axes=SWAP, imu_offset=0.37, imu_rate=0.0, dvl_offset=-0.8,
                       stretch=stretch)
    imu_hz = 1 / float(np.median(np.diff(sim["imu_t"])))
    raw, fixed = tmp_path / "raw.h5", tmp_path / "fixed.h5"
    write_recorded(raw, log, description=STATED.format(imu=round(imu_hz, 6)))
    status, out, err = run(["check-log", str(raw), "--apply", str(fixed)])
    assert (status, err) == (0, "")
    assert "time base" in out
    with open_dataset(fixed) as ds:
        m = ds.missions["sim"]
        report = json.loads(m.attrs["check_log_json"])
        base = {f["name"]: f for f in report["findings"]}["time base"]["value"]
        assert report["corrections"]["time_base"] == base["clock"] == "imu"
        assert base["stamp_stretch"]["reference"] == pytest.approx(stretch, rel=1e-6)
        assert base["predicted_imu_rate_error"] == pytest.approx(stretch, rel=1e-6)
        # The IMU's stamps unchanged (but for the one shift to 0).
        np.testing.assert_allclose(np.diff(m.imu.time), np.diff(log.imu_time), atol=1e-9)
        # The reference's span back to the truth's (the stretch adds 1.5 s over 600 s).
        truth = sim["t"][::100]  # the reference's samples, truth's clock
        span = m.reference.time[-1] - m.reference.time[0]
        assert span == pytest.approx(truth[-1] - truth[0], abs=OFFSET_TOL)
        # The streams aligned on that clock: the IMU at the truth's times, the DVL too.
        ref0 = m.reference.time[0] - truth[0]
        assert (m.imu.time[0] - ref0) == pytest.approx(sim["imu_t"][0], abs=OFFSET_TOL)
        assert (m.dvl.time[-1] - ref0) == pytest.approx(sim["dvl_t"][-1], abs=OFFSET_TOL)
    # Without stated rates the reference's clock stays the time base, and says why.
    plain = tmp_path / "plain.h5"
    write_recorded(plain, log)
    status, out, _ = run(["check-log", str(plain), "--json"])
    found = {f["name"]: f for f in json.loads(out)[0]["findings"]}["time base"]
    assert found["value"]["clock"] == "reference" and "no stated rates" in found["evidence"]


def first_seconds(log: Log, seconds: float) -> Log:
    """``log`` cut to the stamps under ``seconds``."""
    r, i, d = (np.asarray(t) < seconds for t in (log.reference_time, log.imu_time,
                                                  log.dvl_time))
    return dataclasses.replace(
        log, reference_time=log.reference_time[r], reference_velocity=log.reference_velocity[r],
        reference_quaternion=log.reference_quaternion[r],
        reference_position=log.reference_position[r], imu_time=log.imu_time[i],
        specific_force=log.specific_force[i], angular_rate=log.angular_rate[i],
        dvl_time=log.dvl_time[d], dvl_velocity=log.dvl_velocity[d])


def test_apply_refuses_a_correction_of_low_confidence_unless_accepted(simulated, tmp_path):
    # 90 s of the zigzag: under three of the clock fit's 50 s windows, so the clocks'
    # offsets are found with low confidence, and --apply would write them.
    raw, out = tmp_path / "raw.h5", tmp_path / "out.h5"
    write_recorded(raw, first_seconds(recorded_log(
        simulated["zigzag"], axes=np.eye(3), imu_offset=0.2, imu_rate=0.0, dvl_offset=0.3), 90))
    status, said, err = run(["check-log", str(raw), "--apply", str(out)])
    assert status == 2 and err.count("\n") == 1, err
    assert "low confidence (sim: imu clock; sim: dvl clock)" in err and "--accept-low" in err
    assert "imu clock" in said and not out.exists()  # the table, then the refusal
    status, said, err = run(["check-log", str(raw), "--apply", str(out), "--accept-low"])
    assert (status, err) == (0, "") and f"wrote {out}" in said
    with open_dataset(out) as ds:
        assert "check_log_json" in ds.missions["sim"].attrs
    # A log long enough for three windows is written without it.
    write_recorded(raw, recorded_log(simulated["zigzag"], axes=np.eye(3), imu_offset=0.2,
                                     imu_rate=0.0, dvl_offset=0.3))
    assert run(["check-log", str(raw), "--apply", str(tmp_path / "full.h5")])[0] == 0


def test_bad_input_is_one_line_and_writes_nothing(simulated, tmp_path):
    raw = tmp_path / "raw.h5"
    write_recorded(raw, recorded_log(simulated["lawnmower"], axes=np.eye(3), imu_offset=0,
                                     imu_rate=0, dvl_offset=0))
    out = tmp_path / "out.h5"
    status, _, err = run(["check-log", str(raw), "--mission", "nope", "--apply", str(out)])
    assert status == 2 and err.count("\n") == 1 and "--mission: 'nope'" in err
    assert not out.exists()
    with pytest.raises(ConfigError, match="missions: 'nope' is not in .*; expected one of sim"):
        check_file(raw, ["nope"])
    status, _, err = run(["check-log", str(raw), "--apply", str(raw)])
    assert status == 2 and err.count("\n") == 1 and "is the log itself" in err
    (tmp_path / "notes.txt").write_text("mine\n")
    for out, message in ((tmp_path / "notes.txt", "a file that is not HDF5 is there"),
                         (tmp_path / "notes.txt" / "x.h5", "is a file, not a folder")):
        status, said, err = run(["check-log", str(raw), "--apply", str(out)])
        assert status == 2 and err.count("\n") == 1 and f"--apply {str(out)!r}: " in err, err
        assert said == ""  # refused before the checks' work, not after their report
        assert message in err and (tmp_path / "notes.txt").read_text() == "mine\n"
    status, _, err = run(["check-log", str(tmp_path / "missing.h5")])
    assert status == 2 and err.count("\n") == 1
    sim = tmp_path / "simulated.h5"
    generate(dataclasses.replace(preset("navigator"), missions=(MissionConfig(
        name="s", scenario=ScenarioConfig(duration=20.0)),)), sim, workers=1, progress=False)
    status, _, err = run(["check-log", str(sim)])
    assert status == 2 and err.count("\n") == 1 and "expected a recorded mission" in err


# ---- the shared A-KIT segments --------------------------------------------------------------


@pytest.mark.skipif(SHARED is None, reason="../shared/data/snapir-akit is not here")
def test_a_shared_segment_checks_clean_after_apply(tmp_path):
    raw, fixed = tmp_path / "akit.h5", tmp_path / "fixed.h5"
    assert run(["import", str(SHARED / "Trajectory2"), "--format", "akit",
                "--out", str(raw)])[0] == 0
    status, out, _ = run(["check-log", str(raw), "--json", "--apply", str(fixed)])
    assert status == 0
    first = {f["name"]: f for f in json.loads(out)[0]["findings"]}
    assert first["imu axes"]["confidence"] == "high"
    status, out, _ = run(["check-log", str(fixed), "--json"])
    again = json.loads(out)[0]
    assert again["corrections"]["imu_axis_map"] == ["x", "y", "z"]
    assert abs(again["corrections"]["imu_time_offset_s"]) < OFFSET_TOL
    assert abs(again["corrections"]["dvl_time_offset_s"]) < OFFSET_TOL
    # The lever arms found the second time agree with the first (within the target).
    after = {f["name"]: f for f in again["findings"]}
    for name in ("dvl lever arm", "imu lever arm"):
        np.testing.assert_allclose(after[name]["value"]["position_body_m"],
                                   first[name]["value"]["position_body_m"], atol=LEVER_TOL)


def test_a_log_that_never_turns_is_refused_in_one_line():
    """Every finding reads how the streams see the vehicle turn; a straight, level log
    gives none of them, and says so instead of dividing by its zero turn rate."""
    t = np.arange(120.0)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    v = np.tile([2.0, 0.0, 0.0], (len(t), 1))
    imu_t = np.arange(0.0, 120.0, 0.01)
    f = np.tile([0.0, 0.0, -9.8], (len(imu_t), 1))
    log = Log(t, v, q, None, imu_t, f, np.zeros_like(f), gravity=9.8)
    with pytest.raises(DatasetError, match="turns at 0 deg/s RMS; expected turns"):
        check_arrays(log, "straight")


def test_a_dvl_that_seldom_has_a_velocity_is_not_observable_and_not_applied(simulated):
    """With a handful of pings every trial clock offset would cost the same and a
    calibration fitted on no rows would look exact: the DVL is reported not observable
    and nothing of it is corrected."""
    log = recorded_log(simulated["zigzag"], axes=np.eye(3), imu_offset=0.0, imu_rate=0.0,
                       dvl_offset=0.3)
    v = np.full_like(log.dvl_velocity, np.nan)
    v[100:120] = log.dvl_velocity[100:120]  # 20 pings of 600 with a velocity
    report = check_arrays(dataclasses.replace(log, dvl_velocity=v), "sparse")
    found = findings(report)
    assert found["dvl clock"].confidence == "not observable"
    assert found["dvl clock"].value == {"pings": 20}
    assert not any(k.startswith("dvl_") for k in report.corrections)
    assert "imu_axis_matrix" in report.corrections  # the IMU is still checked
    # Nor does the filter's prior take anything of it from the corrected file.
    assert applied_dvl_errors({"check_log_json": json.dumps(report.to_json())}) == (None, None)


def test_an_injected_dvl_scale_and_mounting_are_recovered(simulated):
    """The simulated DVL's velocity read 1 % fast through a mounting yawed 0.5 deg and
    pitched -0.3 deg more (logged v' = 1.01 M^T v): check-log finds the scale 1.01 times,
    and the mounting that much further turned, as it finds them on the log as it was (the
    simulated DVL's own drawn errors), to within its standard errors."""
    from auvsim.physics.frames import rotation_rpy

    log = recorded_log(simulated["zigzag"], axes=np.eye(3), imu_offset=0.0, imu_rate=0.0,
                       dvl_offset=0.0)
    turn = rotation_rpy(0.0, math.radians(-0.3), math.radians(0.5))
    found = {}
    for name, v in (("as logged", log.dvl_velocity),
                    ("injected", 1.01 * log.dvl_velocity @ turn)):
        found[name] = findings(check_arrays(dataclasses.replace(log, dvl_velocity=v), name))
    before, after = found["as logged"], found["injected"]
    scale = after["dvl scale"].value["scale"] / before["dvl scale"].value["scale"]
    assert scale == pytest.approx(1.01, abs=3 * after["dvl scale"].value["se"] + 1e-4)
    moved = (np.array(after["dvl mounting"].value["rpy_deg"])
             - before["dvl mounting"].value["rpy_deg"])
    se = np.array(after["dvl mounting"].value["se_deg"])
    # Per axis, within 3 SE (roll 0.16 deg, pitch and yaw 0.05 deg here): found -0.006,
    # -0.301, +0.504 deg, and the scale 1.0099 (SE 0.0007).
    assert np.all(np.abs(moved - [0.0, -0.3, 0.5]) <= 3 * se + 0.01), (moved, se)
    assert after["dvl mounting"].confidence in ("high", "medium")


@pytest.mark.parametrize("dvl_axes", [np.diag([1.0, -1.0, -1.0]), SWAP])
def test_a_dvl_logged_through_other_axes_is_named_and_not_applied(simulated, tmp_path,
                                                                  dvl_axes):
    """The DVL's velocity logged through other axes (FLU declared FRD; x and y swapped, z
    flipped): check-log names the map (body = P logged), fits the DVL's clock and
    calibration through it (the lever arm then as without the fault), and --apply refuses
    in one line, since the description is where the axes are fixed. As logged, the same
    mission's DVL reads "as logged"."""
    log = recorded_log(simulated["zigzag"], axes=np.eye(3), imu_offset=0.0, imu_rate=0.0,
                       dvl_offset=-0.8)
    clean = findings(check_arrays(log, "clean"))
    assert clean["dvl axes"].text == "as logged"
    # margin 2.5x: the runner-up flips z, which the heave alone tells
    assert clean["dvl axes"].confidence in ("high", "medium")
    faulty = dataclasses.replace(log, dvl_velocity=log.dvl_velocity @ dvl_axes)
    report = check_arrays(faulty, "faulty")
    found = findings(report)
    assert found["dvl axes"].value["matrix"] == dvl_axes.tolist()
    assert found["dvl axes"].confidence in ("high", "medium"), found["dvl axes"].evidence
    assert report.corrections["dvl_time_offset_s"] == pytest.approx(-0.8, abs=OFFSET_TOL)
    np.testing.assert_allclose(report.corrections["dvl_position_body"], DVL_POSITION,
                               atol=LEVER_TOL)
    raw, out = tmp_path / "raw.h5", tmp_path / "out.h5"
    write_recorded(raw, faulty)
    status, said, err = run(["check-log", str(raw), "--apply", str(out), "--accept-low"])
    assert status == 2 and err.count("\n") == 1, err
    assert "the DVL's axes are not as logged (sim: [" in err and "dvl.axis_map" in err, err
    assert "dvl axes" in said and not out.exists()


@pytest.mark.parametrize("factor", [0.0, 0.5])
def test_a_dvl_far_off_the_reference_is_no_calibration(simulated, factor):
    """A DVL whose velocity is half the reference's, or none (zeros), fits "exactly" with
    a scale no sound speed gives: its scale, mounting and lever arm are reported not
    observable, saying why, and none is applied."""
    log = recorded_log(simulated["zigzag"], axes=np.eye(3), imu_offset=0.0, imu_rate=0.0,
                       dvl_offset=0.0)
    report = check_arrays(dataclasses.replace(log, dvl_velocity=factor * log.dvl_velocity),
                          "off")
    found = findings(report)
    assert abs(found["dvl scale"].value["scale"] - factor) < 0.01
    for name in ("dvl scale", "dvl mounting", "dvl lever arm"):
        assert found[name].confidence == "not observable"
        assert "beyond any DVL's calibration" in found[name].evidence
    assert applied_dvl_errors({"check_log_json": json.dumps(report.to_json())}) == (None, None)


def test_the_exponential_sum_is_the_dense_product():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.5, 3.0, 60))  # irregular pings, gaps too
    a = rng.standard_normal((60, 4))
    r = np.exp(-np.abs(t[:, None] - t[None, :]) / 7.0)
    np.testing.assert_allclose(_exponential_sum(t, a, 7.0), a.T @ r @ a, rtol=1e-12)


@pytest.mark.parametrize("residuals", ["slow error", "short correlation"])
def test_serial_least_squares_errors_hold_for_a_dvls_slow_error(residuals):
    """Known answer by Monte Carlo, as the DVL calibration meets it: 300 pings at 1 Hz of
    a vehicle at 2 m/s that turns now and then. With residuals of white noise (3 mm/s)
    and a Gauss-Markov error of 9 mm/s over 19 s (the Navigator's), over 300 draws the
    estimates' spread is what the errors say given the correlation time (within 25 %,
    their median); Newey-West's alone, which sees about 8 independent stretches of the
    error, are under 70 % of it. With residuals correlated over a few pings only (AR(1)
    of 0.6 per ping), which the 19 s model does not describe, the errors still hold
    within 25 %: the slow error's size is fitted over the lags, not read off the first
    (which had made them 2.3 times too wide)."""
    rng = np.random.default_rng(11)
    t = np.arange(300.0)
    heading = np.cumsum(np.where((t // 40) % 2 == 0, 0.0, 0.03))
    u = 2.0 * np.stack([np.cos(heading), np.sin(heading), np.zeros_like(t)], -1)
    a = np.stack([u, np.broadcast_to(np.eye(3)[1], u.shape)], axis=2)  # scale, y bias
    truth = np.array([0.002, -0.001])
    decay = math.exp(-1.0 / 19.0) if residuals == "slow error" else 0.6

    def ar1() -> np.ndarray:
        e = np.empty((len(t), 3))
        e[0] = rng.standard_normal(3)
        for k in range(1, len(t)):
            e[k] = decay * e[k - 1] + math.sqrt(1 - decay ** 2) * rng.standard_normal(3)
        return e

    estimates, modelled, serial = [], [], []
    for _ in range(300):
        if residuals == "slow error":
            noise = 0.009 * ar1() + 0.003 * rng.standard_normal((len(t), 3))
        else:
            noise = 0.01 * ar1()
        b = a @ truth + noise
        x, se, _, _ = serial_least_squares(a, b, times=t, correlation_time=19.0)
        estimates.append(x)
        modelled.append(se)
        serial.append(serial_least_squares(a, b)[1])
    spread = np.std(estimates, axis=0)
    assert np.median(modelled, axis=0) == pytest.approx(spread, rel=0.25)
    if residuals == "slow error":
        assert np.all(np.median(serial, axis=0) < 0.7 * spread)


def test_serial_least_squares_refuses_times_it_cannot_use():
    a, b = np.ones((5, 3, 1)), np.zeros((5, 3))
    for times, tau in ((np.arange(5.0), 0.0), (np.arange(5.0), -1.0),
                       (np.array([0.0, 2.0, 1.0, 3.0, 4.0]), 19.0),
                       (np.array([0.0, 1.0, np.nan, 3.0, 4.0]), 19.0)):
        with pytest.raises(ValueError):
            serial_least_squares(a, b, times=times, correlation_time=tau)


def test_serial_least_squares_errors_hold_for_residuals_correlated_over_pings():
    """Known answer by Monte Carlo: a slowly varying design (a velocity that turns, as the
    DVL calibration's is) with AR(1) residuals of 0.9 per ping (a slow error over about
    ten pings). Over 400 draws the estimates' spread is what the Newey-West errors say
    (within 25 %, their median), where the OLS errors, which take every ping as new, are
    under half of it."""
    rng = np.random.default_rng(7)
    t = np.arange(400.0)
    heading = 2 * np.pi * t / 150
    u = np.stack([np.cos(heading), np.sin(heading), np.full_like(t, 0.2)], -1)  # (T, 3)
    a = np.stack([u, np.broadcast_to(np.eye(3)[2], u.shape)], axis=2)  # (T, 3, 2)
    truth = np.array([0.01, -0.02])
    estimates, serial, plain = [], [], []
    for _ in range(400):
        e = np.empty((len(t), 3))
        e[0] = rng.standard_normal(3)
        for k in range(1, len(t)):
            e[k] = 0.9 * e[k - 1] + math.sqrt(1 - 0.81) * rng.standard_normal(3)
        b = a @ truth + 0.01 * e
        x, se, _, lags = serial_least_squares(a, b)
        estimates.append(x)
        serial.append(se)
        plain.append(least_squares(a.reshape(-1, 2), b.ravel())[1])
    spread = np.std(estimates, axis=0)
    assert np.median(serial, axis=0) == pytest.approx(spread, rel=0.25)
    assert np.all(np.median(plain, axis=0) < 0.5 * spread)
    assert 5 <= lags <= 80


def test_apply_records_how_well_it_knows_what_it_wrote(simulated):
    """The filter's prior on a corrected file: the standard errors of the DVL mounting
    and lever arm check-log applied, None for what it did not. On the zigzag both are
    found; on the lawnmower's straight legs the mounting's roll is not (the velocity is
    nearly all along x, which a roll leaves alone: its standard error is over 0.3 deg),
    so the mounting has no prior from it."""
    def applied(name):
        log = recorded_log(simulated[name], axes=np.eye(3), imu_offset=0.0, imu_rate=0.0,
                           dvl_offset=0.3)
        report = check_arrays(log, "sim")
        return findings(report), applied_dvl_errors(
            {"check_log_json": json.dumps(report.to_json())})

    found, (mounting, lever) = applied("zigzag")
    for name, errors, key in (("dvl lever arm", lever, "se_m"),
                              ("dvl mounting", mounting, "se_deg")):
        assert found[name].confidence != "not observable"
        np.testing.assert_allclose(errors, found[name].value[key])
        assert np.all(errors > 0)
    found, (mounting, lever) = applied("lawnmower")
    assert found["dvl mounting"].confidence == "not observable" and mounting is None
    assert found["dvl mounting"].value["se_deg"][0] > 0.3
    assert applied_dvl_errors({}) == (None, None)


def test_apply_records_how_well_it_knows_the_clocks(simulated):
    """The filter's clock uncertainty on a corrected file: how well check-log knew the
    clock offsets it applied, at least the standard error its finding states and under
    the 0.05 s its targets ask for; None without a report. With what the log leaves open
    of a sample's stamp (which instant of its interval it marks: up to 5 ms at 100 Hz)
    they hold the offsets' actual errors: the injected offsets are found within 4 of
    them."""
    log = recorded_log(simulated["zigzag"], axes=REFLECT, imu_offset=-0.62, imu_rate=0.0,
                       dvl_offset=0.45)
    report = check_arrays(log, "sim")
    found = findings(report)
    imu, dvl = applied_clock_errors({"check_log_json": json.dumps(report.to_json())})
    for name, se, injected in (("imu clock", imu, -0.62), ("dvl clock", dvl, 0.45)):
        assert found[name].value["offset_se_s"] <= se < 0.05
        assert abs(found[name].value["offset_s"] - injected) < 4 * math.hypot(se, 0.005)
    assert applied_clock_errors({}) == (None, None)


def test_a_clock_found_stretched_but_not_shifted_is_named_among_the_changes():
    """``changes`` names every stream whose stamps ``corrected`` moved: one with a rate
    error and no offset moves too, and had gone unsaid."""
    report = Report("m", corrections={"time_base": "reference",
                                               "dvl_time_offset_s": 0.0,
                                               "dvl_rate_error": 400e-6})
    before = {"dvl_time_offset_s": 0.0, "imu_time_offset_s": 0.0}
    said = changes(before, dict(before), report)
    assert said == ["onto the reference's clock: DVL +0.000 s and +400 ppm"], said
    report.corrections["dvl_rate_error"] = 0.0
    assert changes(before, dict(before), report) == []
    # On the IMU's clock, an IMU that runs at its own rate rescales every other stream.
    report = Report("m", corrections={"time_base": "imu", "imu_time_offset_s": 0.0,
                                      "imu_rate_error": 400e-6, "dvl_time_offset_s": 0.0,
                                      "dvl_rate_error": 0.0})
    said = changes(before, dict(before), report)
    assert said == ["onto the IMU's clock (it runs +400 ppm against the reference's)"], said
