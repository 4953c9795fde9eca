"""The INS/DVL filter fit for a real vehicle (issue 24, item 3): the array API, the
rotating Earth, the divergence watch, availability that counts accepted pings, settings
from a TOML file, and the shared A-KIT segments where they are present."""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import Fields, zigzag

from auvsim.data.beams import beam_matrix, beam_noise_from_error_velocity
from auvsim.data.reader import open_dataset
from auvsim.physics.earth import earth_rate_ned, normal_gravity
from auvsim.physics.frames import quaternion_from_euler, rotation_matrices, rotation_rpy
from auvsim.runs.presets import PAPER_NOISE_CODE
from auvsim.sensors.imu import IMU_GRADES
from beamsnet.cli import main
from beamsnet.data import DataError
from beamsnet.estimators import ins
from beamsnet.experiments.sea import sea_dataset

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import sea_filter  # noqa: E402  (the product path on the shared segments, and its scores)


@pytest.fixture(scope="module")
def navigation(dataset_of):
    """A 90 s zigzag: the navigation-grade IMU, the paper's beam noise."""
    return dataset_of(zigzag(PAPER_NOISE_CODE, 90.0), "navigation")


def arrays_of(m) -> dict:
    """A simulated mission as plain arrays and the instrument its attributes state (the
    formulas of the module docstring), nothing read through ``run_mission``."""
    a = m.attrs
    imu = json.loads(m.dataset.config_json)["imu"]
    c0 = rotation_matrices(m.truth.quaternion[:1])[0]
    start = ins.Start(time=float(m.truth.time[0]), position_ned=m.truth.position_ned[0],
                      velocity_ned=m.truth.velocity_ned[0], rotation=c0,
                      position_std=np.full(3, 0.1), velocity_std=np.full(3, 0.01),
                      attitude_std=np.radians([0.01, 0.01, 0.05]),
                      angular_rate=m.truth.angular_rate[0])
    instrument = ins.Instrument(
        accel_noise_density=a["imu_accel_noise_density"],
        gyro_noise_density=a["imu_gyro_noise_density"],
        accel_bias_std=math.hypot(imu["accel_turn_on_bias"], a["imu_accel_bias_instability"]),
        gyro_bias_std=math.hypot(imu["gyro_turn_on_bias"], a["imu_gyro_bias_instability"]),
        accel_bias_psd=2 * a["imu_accel_bias_instability"] ** 2
        / a["imu_accel_bias_correlation_time"],
        gyro_bias_psd=2 * a["imu_gyro_bias_instability"] ** 2
        / a["imu_gyro_bias_correlation_time"],
        measurement_std=np.full(4, a["dvl_noise_std"]))
    return dict(imu_time=m.truth.time, specific_force=m.imu.specific_force,
                angular_rate=m.imu.angular_rate, dvl_time=m.dvl.time,
                beams=m.dvl.beam_velocity, valid=m.dvl.valid & (m.dvl.mode != 1)[:, None],
                beam_angle_deg=a["beam_angle_deg"], mounting_rpy_deg=a["dvl_mounting_rpy_deg"],
                imu_position_body=a["imu_position_body"],
                dvl_position_body=a["dvl_position_body"], start=start,
                instrument=instrument, gravity=m.gravity,
                config=ins.FilterConfig(beam_states=False), timing_std=0.0,
                imu_samples="held")  # auvsim's simulated IMU


def test_the_array_api_on_a_simulated_mission_equals_run_mission(navigation):
    """Pings placed by their times (searchsorted) land on the file's own IMU rows, and
    the arrays give the very track ``run_mission`` gives (15 states, flat Earth)."""
    with open_dataset(navigation) as f:
        m = f.missions["zz"]
        inputs = arrays_of(m)
        rows = np.searchsorted(m.truth.time, m.dvl.time, side="right") - 1
        np.testing.assert_array_equal(rows, m.imu.index_of_dvl)
        mission = ins.run_mission(m)
        assert "latitude_deg" not in m.attrs  # no geographic origin: no Earth rate
    arrays = ins.run_arrays(**inputs)
    for field in ("velocity_dvl", "position_ned", "position_std", "velocity_cov",
                  "gyro_bias", "accepted", "beams_used"):
        np.testing.assert_allclose(getattr(arrays, field), getattr(mission, field),
                                   rtol=1e-12, atol=1e-12, err_msg=field)
    assert arrays.availability == mission.availability == 1.0 and not arrays.events


def stationary(latitude: float, seconds: float = 600.0, heading_deg: float = 30.0):
    """An ideal IMU at rest on the rotating Earth, level, heading ``heading_deg``: it reads
    f = C^T (0, 0, -g) and w = C^T Omega_ie (Groves eqs. 5.46, 5.54 at v = 0)."""
    c = rotation_rpy(0.0, 0.0, math.radians(heading_deg))
    t = np.arange(0.0, seconds, 0.01)
    f = np.tile(c.T @ [0.0, 0.0, -normal_gravity(latitude)], (len(t), 1))
    w = np.tile(c.T @ earth_rate_ned(latitude), (len(t), 1))
    start = ins.Start(time=0.0, position_ned=np.zeros(3), velocity_ned=np.zeros(3),
                      rotation=c, position_std=np.full(3, 0.1),
                      velocity_std=np.full(3, 0.01), attitude_std=np.radians([0.01] * 3))
    grade = IMU_GRADES["navigation"]
    instrument = ins.Instrument(grade.accel_noise_density, grade.gyro_noise_density,
                                grade.accel_turn_on_bias, grade.gyro_turn_on_bias, 0.0, 0.0,
                                np.full(3, 0.01))
    dvl_time = np.arange(0.0, seconds, 1.0)
    return dict(imu_time=t, specific_force=f, angular_rate=w, dvl_time=dvl_time,
                velocity=np.zeros((len(dvl_time), 3)), start=start, instrument=instrument)


def circle(seconds: float = 60.0, speed: float = 2.0, rate_deg: float = 10.0):
    """A level turning circle at constant speed and yaw rate on a flat Earth that does not
    rotate, sampled at 100 Hz by an ideal IMU: f = (0, U r, -g) and w = (0, 0, r) in the
    body, constant, so each sample is both the reading at its time and the mean over the
    interval before it. Known answer: v = U (cos r t, sin r t, 0), p = U / r (sin r t,
    1 - cos r t, 0)."""
    r = math.radians(rate_deg)
    t = np.arange(0.0, seconds + 1e-9, 0.01)
    f = np.tile([0.0, speed * r, -9.81], (len(t), 1))
    w = np.tile([0.0, 0.0, r], (len(t), 1))
    start = ins.Start(time=0.0, position_ned=np.zeros(3), velocity_ned=[speed, 0.0, 0.0],
                      rotation=np.eye(3), position_std=np.full(3, 0.1),
                      velocity_std=np.full(3, 0.01), attitude_std=np.radians([0.01] * 3))
    grade = IMU_GRADES["navigation"]
    instrument = ins.Instrument(grade.accel_noise_density, grade.gyro_noise_density,
                                grade.accel_turn_on_bias, grade.gyro_turn_on_bias, 0.0, 0.0,
                                np.full(3, 0.01))
    dvl_time = np.arange(1.0, seconds + 1e-9, 1.0)
    known = speed / r * np.stack([np.sin(r * dvl_time), 1 - np.cos(r * dvl_time),
                                  0 * dvl_time], axis=1)
    return dict(imu_time=t, specific_force=f, angular_rate=w, dvl_time=dvl_time,
                velocity=np.zeros((len(dvl_time), 3)), start=start, instrument=instrument,
                gravity=9.81, config=ins.FilterConfig(dvl_updates=False)), known


def test_a_real_imus_samples_are_taken_at_their_intervals_middle():
    """A real IMU's sample describes the interval that ends at its time, and the step to it
    turns it by the attitude at the interval's middle (``imu_samples="interval"``, the
    default of the array API and ``run_mission``'s for a recorded log): the turning circle
    integrates back to its known answer to the midpoint rule's O((dt r)^2) (under 0.1 mm
    after 60 s). Held from the interval's start instead (auvsim's simulated IMU, exact for
    MuJoCo's step), the specific force turns a step's rotation late, dt r / 2, and the
    solution leaves the circle (the speed grows by that angle's share of the turn's
    acceleration each step)."""
    data, known = circle()
    interval = ins.run_arrays(**data)
    held = ins.run_arrays(**data, imu_samples="held")
    off = np.linalg.norm(interval.position_ned - known, axis=1).max()
    late = np.linalg.norm(held.position_ned - known, axis=1).max()
    assert off < 1e-4 and late > 100 * off
    with pytest.raises(ValueError, match="imu_samples: expected one of interval, held"):
        ins.run_arrays(**data, imu_samples="mean")


def test_a_stationary_imu_at_a_latitude_stays_put_with_earth_rate_and_normal_gravity():
    """Pure inertial navigation for 10 minutes at 45 deg: with the latitude, the filter
    compensates the Earth's rate and uses the WGS-84 normal gravity there, so it stays at
    rest to rounding. Known answers without them: g0 = 9.81 leaves dg = 9.81 - g
    downward, and the gravity's growth with depth g' (the normal gravity's free-air term)
    makes the vertical channel unstable, p'' = dg + g' p: p = dg / g' (cosh(sqrt(g') t) - 1)
    (750 m after 600 s at 45 deg, where dg t^2 / 2 alone is 680 m; the Schuler loop does not
    act on the vertical); the Earth's rate left in the gyros tilts the platform by
    Omega_N t, which gravity turns into metres within the first minute."""
    data = stationary(45.0)
    pure = ins.FilterConfig(dvl_updates=False)
    still = ins.run_arrays(**data, latitude_deg=45.0, config=pure)
    assert np.abs(still.position_ned).max() < 1e-9
    assert np.abs(still.velocity_dvl).max() < 1e-9
    heavy = ins.run_arrays(**data, latitude_deg=45.0, gravity=9.81, config=pure)
    t = still.ping_time[-1]
    growth = normal_gravity(45.0, -1.0) - normal_gravity(45.0)
    fall = (9.81 - normal_gravity(45.0)) / growth * (math.cosh(math.sqrt(growth) * t) - 1)
    assert heavy.position_ned[-1, 2] == pytest.approx(fall, rel=1e-3)
    flat_earth = ins.run_arrays(**data, gravity=normal_gravity(45.0), config=pure)
    assert np.abs(flat_earth.position_ned[:60, :2]).max() > 1.0


def test_a_stationary_imu_with_a_dvl_at_rest_stays_within_its_own_three_sigma():
    """The same at 32.85 deg (the Snapir's) with the DVL reading zero: the position stays
    at the start to rounding (the ideal data hold it there exactly), within 3 sigma of the
    reported std, and every ping is accepted."""
    data = stationary(32.85, seconds=300.0)
    track = ins.run_arrays(**data, latitude_deg=32.85)
    assert np.all(np.abs(track.position_ned) <= 3 * track.position_std)
    assert np.abs(track.position_ned).max() < 1e-9 and track.availability == 1.0


def test_the_dvl_calibration_prior_is_the_setting_else_the_calibrations_else_the_default():
    """How well the DVL's mounting and lever arm are known: a setting wins, else a
    calibration's standard errors (check-log's, per axis), else an uncalibrated DVL's
    0.5 deg and 0.1 m. Without updates the states keep their prior at every ping."""
    data = stationary(32.85, seconds=20.0)
    pure = ins.FilterConfig(dvl_updates=False)
    default = ins.run_arrays(**data, latitude_deg=32.85, config=pure)
    np.testing.assert_allclose(default.misalignment_std[-1],
                               np.radians(np.full(3, ins.MISALIGNMENT_STD_DEG)))
    np.testing.assert_allclose(default.lever_arm_std[-1], np.full(3, ins.LEVER_ARM_STD))
    calibrated = dict(mounting_std_deg=[0.04, 0.006, 0.07], dvl_position_std=[0.01, 0.02, 0.03])
    known = ins.run_arrays(**data, latitude_deg=32.85, config=pure, **calibrated)
    np.testing.assert_allclose(known.misalignment_std[-1], np.radians([0.04, 0.006, 0.07]))
    np.testing.assert_allclose(known.lever_arm_std[-1], [0.01, 0.02, 0.03])
    set_by_hand = ins.FilterConfig(dvl_updates=False, misalignment_std_deg=0.2,
                                   lever_arm_std=0.05)
    hand = ins.run_arrays(**data, latitude_deg=32.85, config=set_by_hand, **calibrated)
    np.testing.assert_allclose(hand.misalignment_std[-1], np.radians(np.full(3, 0.2)))
    np.testing.assert_allclose(hand.lever_arm_std[-1], np.full(3, 0.05))


def same(a: ins.FilterTrack, b: ins.FilterTrack) -> bool:
    """Whether two tracks have the very same velocity, position and stds."""
    return all(np.array_equal(getattr(a, k), getattr(b, k), equal_nan=True)
               for k in ("velocity_dvl", "velocity_cov", "position_ned", "position_std"))


def test_run_arrays_takes_the_place_and_the_dvl_noise_from_its_settings(navigation):
    """A setting wins over the argument it names: ``latitude_deg`` over the arrays',
    ``beam_noise_std`` (at least the floor) and ``velocity_noise_std`` over the
    instrument's, a beam noise reaching a velocity through the Janus geometry. Each run
    is the very run given the value as an argument, and not the run without the
    setting; an instrument that states no noise needs one."""
    data = stationary(45.0, seconds=60.0)
    config = ins.FilterConfig
    at_45 = ins.run_arrays(**data, latitude_deg=45.0)
    assert same(ins.run_arrays(**data, latitude_deg=10.0, config=config(latitude_deg=45.0)),
                at_45)
    assert not same(ins.run_arrays(**data, latitude_deg=10.0), at_45)

    def stating(std) -> dict:
        return {**data, "instrument": data["instrument"]._replace(measurement_std=std)}

    for setting, stated in ((config(velocity_noise_std=0.05), np.full(3, 0.05)),
                            (config(beam_noise_std=0.02), ins.janus_velocity_std(0.02, 30.0))):
        by_setting = ins.run_arrays(**data, latitude_deg=45.0, beam_angle_deg=30.0,
                                    config=setting)
        assert same(by_setting, ins.run_arrays(**stating(stated), latitude_deg=45.0))
        assert not same(by_setting, at_45)
        unstated = ins.run_arrays(**stating(np.full(3, np.nan)), latitude_deg=45.0,
                                  beam_angle_deg=30.0, config=setting)
        assert same(unstated, by_setting)
    with pytest.raises(ValueError, match="instrument.measurement_std: expected finite"):
        ins.run_arrays(**stating(np.full(3, np.nan)), latitude_deg=45.0)

    with open_dataset(navigation) as f:
        beams = arrays_of(f.missions["zz"])
    plain = ins.run_arrays(**beams)
    for noise, stated in ((0.02, 0.02), (0.0, ins.BEAM_NOISE_FLOOR)):
        setting = config(beam_states=False, beam_noise_std=noise)
        by_setting = ins.run_arrays(**{**beams, "config": setting})
        instrument = beams["instrument"]._replace(measurement_std=np.full(4, stated))
        assert same(by_setting, ins.run_arrays(**{**beams, "instrument": instrument}))
        assert not same(by_setting, plain)


def test_the_divergence_watch_restarts_after_an_injected_transient(navigation):
    """A start 2 m/s off in north with a velocity std of 1 cm/s: every beam is gated out
    (innovations of 100 sigma). Without the watch the filter never recovers: it accepts
    nothing, yet outputs a number at every ping. With it, the watch restarts the
    velocity from the beams after its window, records the event, and the track comes back
    to the truth."""
    with open_dataset(navigation) as f:
        m = f.missions["zz"]
        inputs = arrays_of(m)
        truth = np.asarray(m.dvl.velocity)
    inputs["start"] = inputs["start"]._replace(
        velocity_ned=inputs["start"].velocity_ned + np.array([2.0, 0.0, 0.0]))
    blind = ins.run_arrays(**{**inputs, "config": ins.FilterConfig(beam_states=False,
                                                                   watch_pings=0)})
    watched = ins.run_arrays(**inputs)
    assert np.isfinite(blind.velocity_dvl).all() and not blind.events
    assert blind.availability < 0.05
    assert np.abs(blind.velocity_dvl - truth)[-10:].max() > 0.5
    assert len(watched.events) >= 1 and watched.events[0].kind == "restart"
    first = watched.events[0].ping
    assert first <= ins.FilterConfig().watch_pings + 1
    assert watched.accepted[first + 2:].mean() > 0.95
    assert watched.availability > 0.85
    error = np.abs(watched.velocity_dvl - truth)[first + 20:]
    assert error.max() < 0.05 and np.mean(error < 3 * watched.velocity_std[first + 20:]) > 0.95


def test_outliers_on_single_beams_do_not_set_off_the_watch_a_wrong_state_still_does(
        dataset_of):
    """A fifth of the beam-pings carry an outlier (Student t, 0.5 m/s scale): three pings
    in five hold one or more, and the gate rejects about a fifth of the measurements,
    near the watch's quarter. A ping whose four beams disagree among themselves (the
    parity check, the Janus error velocity) holds an outlier, not a wrong state, so its
    rejections do not count: no restart, and the track keeps to the truth. (Counting
    every rejection, the watch restarted here and opened the gate to the next outlier: a
    fifth of the measurements rose to 0.28 rejected; in ``beamsnet stress --faults``'s 20 %
    row the filter's vector RMSE was 0.3551 m/s, 0.0020 with the check.) A start 2 m/s
    off, where every beam agrees and all disagree with the state, is still restarted
    within the watch's window."""
    config = zigzag(PAPER_NOISE_CODE, 120.0)
    config = dataclasses.replace(config, dvl=dataclasses.replace(
        config.dvl, outlier_rate=0.2, outlier_std=0.5))
    path = dataset_of(config, "outliers")
    with open_dataset(path) as f:
        m = f.missions["zz"]
        inputs = arrays_of(m)
        truth = np.asarray(m.dvl.velocity)
    track = ins.run_arrays(**inputs)
    offered = track.beams_used.sum() + track.beams_rejected.sum()
    assert 0.15 < track.beams_rejected.sum() / offered < 0.22
    assert not track.events
    error = np.abs(track.velocity_dvl - truth)
    assert error.max() < 0.02 and np.mean(error < 3 * track.velocity_std) > 0.95
    inputs["start"] = inputs["start"]._replace(
        velocity_ned=inputs["start"].velocity_ned + np.array([2.0, 0.0, 0.0]))
    wrong = ins.run_arrays(**inputs)
    assert wrong.events and wrong.events[0].ping <= 2 * ins.FilterConfig().watch_pings
    first = wrong.events[0].ping
    assert len(wrong.events) == 1
    assert np.abs(wrong.velocity_dvl - truth)[first + 20:].max() < 0.02


def test_estimate_reports_the_filters_accepted_pings_and_its_events(navigation, tmp_path,
                                                                    capsys):
    """``beamsnet estimate --estimator INS/DVL``: availability is the share of pings the
    filter accepted (its own count), the events are listed (none here), and the settings
    of ``--filter-config`` are the ones used."""
    settings = tmp_path / "filter.toml"
    settings.write_text("watch_pings = 5\nattitude_std_deg = [0.02, 0.1]\n")
    out = tmp_path / "est"
    assert main(["estimate", str(navigation), "--estimator", "INS/DVL", "--filter-config",
                 str(settings), "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["filter_config"]["watch_pings"] == 5
    assert summary["filter_config"]["attitude_std_deg"] == [0.02, 0.1]
    with open_dataset(navigation) as f:
        track = ins.run_mission(f.missions["zz"], ins.load_config(settings))
    row = summary["missions"]["zz"]
    assert row["availability"] == track.availability and row["events"] == []
    # Its innovations as large as it predicts, on a simulated mission whose noise it knows.
    assert 0.5 < row["mean_nis"] < 1.5 and row["windows"] > 0
    said = capsys.readouterr().out
    assert "accepted" in said and "  innovations: mean NIS " in said


def test_the_chi_square_quantile_is_wilson_and_hilfertys_within_one_per_cent():
    stats = pytest.importorskip("scipy.stats")
    for dof in (10, 20, 40, 100, 400):
        assert ins.chi2_quantile(dof, 0.999) == pytest.approx(
            stats.chi2.ppf(0.999, dof), rel=0.01)


def test_the_innovations_consistency_test_knows_a_right_and_a_wrong_covariance():
    """Innovations drawn with the variance the filter predicts: mean NIS 1 and about 0.1 %
    of windows beyond the 99.9 % bound; three times as large: mean NIS 9, every window.
    A measurement not offered (NaN) counts in neither."""
    rng = np.random.default_rng(5)
    pings, k = 20_000, 3
    var = rng.uniform(1e-6, 1e-4, (pings, k))
    nu = rng.standard_normal((pings, k)) * np.sqrt(var)
    nu[::7, 1] = np.nan
    track = Fields(innovation=nu, innovation_var=var, ping_time=np.arange(pings) * 1.0)
    right = ins.innovation_consistency(track)
    assert right["mean_nis"] == pytest.approx(1.0, abs=0.02)
    assert right["windows"] == pings // ins.CONSISTENCY_PINGS
    assert right["windows_above"] <= 10  # 2 expected (0.1 % of 2000)
    wrong = ins.innovation_consistency(Fields(innovation=3 * nu, innovation_var=var,
                                              ping_time=track.ping_time))
    assert wrong["mean_nis"] == pytest.approx(9.0, rel=0.03)
    assert wrong["windows_above"] == wrong["windows"]
    assert wrong["worst_time"] % ins.CONSISTENCY_PINGS == 0
    # Capped at the gate, the mean is 1 where the covariance is right, and one outlier of
    # a thousand sigma (nu^2 / S = 1e6), which the plain mean takes to 17, moves it by at
    # most the gate over the count; a covariance three times too small still shows.
    assert right["gated_nis"] == pytest.approx(1.0, abs=0.02)
    nu[100, 0] = 1000 * math.sqrt(var[100, 0])
    one = ins.innovation_consistency(Fields(innovation=nu, innovation_var=var,
                                            ping_time=track.ping_time))
    assert one["mean_nis"] > 15 and one["gated_nis"] == pytest.approx(right["gated_nis"],
                                                                      abs=1e-3)
    assert wrong["gated_nis"] > 3


@pytest.mark.parametrize("text, said", [
    ("gain = 3\n", "'gain', which is not a filter setting; expected some of"),
    ("watch_ping = 5\n", "'watch_ping', which is not a filter setting (did you mean "
                         "'watch_pings'?); expected some of"),
    ("watch_share = 2.0\n", "watch_share: expected a share"),
    ("watch_pings = \n", "is not TOML"),
    ('dvl_updates = "no"\n', "dvl_updates: expected true or false, got 'no'"),
    ("earth_rate = 1\n", "earth_rate: expected true, false or None, got 1"),
    ("bias_time = 0.0\n", "bias_time: expected a positive number or None, got 0.0"),
    ("lever_arm_std = 0\n", "lever_arm_std: expected a positive number or None"),
    ("process_noise_scale = -1.0\n", "process_noise_scale: expected a positive std"),
    ("gyro_misalignment_std = -1e-4\n", "gyro_misalignment_std: expected a number >= 0"),
    ('initial_error_seed = "x"\n', "initial_error_seed: expected a whole number >= 0"),
    ("initial_error_seed = 1.5\n", "initial_error_seed: expected a whole number >= 0"),
])
def test_a_bad_filter_config_gets_one_line_and_exit_2(navigation, tmp_path, capsys, text,
                                                      said):
    settings = tmp_path / "filter.toml"
    settings.write_text(text)
    for command in (["estimate", str(navigation), "--estimator", "INS/DVL"],
                    ["evaluate", str(tmp_path / "no-run"), str(navigation)]):
        out = tmp_path / "out"
        assert main([*command, "--filter-config", str(settings), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--filter-config" in err and said in err, err
        assert not out.exists()


def test_a_simulated_dvls_noise_grows_with_its_speed_in_the_filter(dataset_of):
    """A DVL whose beams' white noise is 2 mm/s + 3 mm/s per m/s of speed (about 8 mm/s at
    2 m/s): the filter states each ping's noise at its predicted speed, within what a
    speed error of 2 cm/s moves it, and its normalised innovations are chi-square with one
    degree of freedom (median 0.455; over about 240 innovations within 0.3-0.65). Told
    the noise at rest alone (a ``beam_noise_std`` setting, held constant), the median is
    more than ten times too large. ``noise_scale`` multiplies the stated noise."""
    dvl = dataclasses.replace(zigzag(0.002, 60.0).dvl, noise_speed_coeff=0.003)
    path = dataset_of(dataclasses.replace(zigzag(0.002, 60.0), dvl=dvl), "growing")
    with open_dataset(path) as f:
        m = f.missions["zz"]
        track = ins.run_mission(m)
        speed = np.linalg.norm(m.dvl.velocity, axis=1)
        at_rest = ins.run_mission(m, ins.FilterConfig(beam_noise_std=0.002))
        doubled = ins.run_mission(m, ins.FilterConfig(noise_scale=2.0))

    def median_nis(t):
        ok = np.isfinite(t.innovation)
        return float(np.median(t.innovation[ok] ** 2
                               / (t.innovation_hph[ok] + t.measurement_std[ok] ** 2)))

    started = np.isfinite(track.stated_std).all(axis=1)
    assert started.sum() > 55
    np.testing.assert_allclose(track.stated_std[started],
                               np.repeat((0.002 + 0.003 * speed[started])[:, None], 4, 1),
                               rtol=0, atol=6e-5)
    assert 0.3 < median_nis(track) < 0.65
    np.testing.assert_array_equal(at_rest.stated_std[started], 0.002)
    assert median_nis(at_rest) > 10 * 0.455
    np.testing.assert_allclose(doubled.stated_std[started], 2 * track.stated_std[started],
                               rtol=0, atol=1e-4)


def test_the_process_noise_scale_multiplies_every_std_of_the_imus_q(dataset_of):
    """``process_noise_scale = k`` is the filter told the IMU's white noise densities times
    k and its biases' random-walk PSDs times k^2 (the same Q, reached through the
    settings: equal to rounding); it moves the track, and 1 is the stated Q exactly (the
    filter told the file's own Q through the settings)."""
    path = dataset_of(zigzag(0.002, 60.0), "process")
    with open_dataset(path) as f:
        m = f.missions["zz"]
        a = m.attrs
        stated = ins.run_mission(m, ins.FilterConfig(process_noise_scale=1.0))
        scaled = ins.run_mission(m, ins.FilterConfig(process_noise_scale=3.0))

        def psd(sensor):  # the bias drive the filter takes from the file: 2 sigma^2 / tau
            tau = a.get(f"imu_{sensor}_bias_correlation_time", a["imu_bias_correlation_time"])
            return 2 * float(a[f"imu_{sensor}_bias_instability"]) ** 2 / float(tau)

        def told(k):  # the file's Q times k^2, through the settings
            return ins.run_mission(m, ins.FilterConfig(
                accel_noise_density=k * float(a["imu_accel_noise_density"]),
                gyro_noise_density=k * float(a["imu_gyro_noise_density"]),
                accel_bias_psd=k * k * psd("accel"), gyro_bias_psd=k * k * psd("gyro")))

        one, three = told(1.0), told(3.0)
    for field in ("position_ned", "position_std", "velocity_dvl", "velocity_std"):
        np.testing.assert_array_equal(getattr(one, field), getattr(stated, field))
        np.testing.assert_allclose(getattr(scaled, field), getattr(three, field), rtol=1e-9,
                                   atol=1e-12)
    started = np.isfinite(stated.position_std).all(axis=1)
    assert (scaled.position_std[started][-1] > stated.position_std[started][-1]).all()
    with pytest.raises(ValueError, match="process_noise_scale: expected a positive std"):
        ins.FilterConfig(process_noise_scale=0.0)


def test_beam_noise_from_the_error_velocity_of_a_janus_dvl():
    """Beams of white noise sigma at 30 deg: the error velocity's std is
    sigma / (sqrt 2 sin 30 deg) = 1.41 sigma, and the function gives sigma back (to the
    sampling error of 20000 pings, 1 %); the horizontal axes' noise equals the error
    velocity's (RDI's scaling)."""
    rng = np.random.default_rng(0)
    sigma, angle = 0.01, 30.0
    beams = sigma * rng.standard_normal((20000, 4))
    a = math.radians(angle)
    error = (beams[:, 0] + beams[:, 1] - beams[:, 2] - beams[:, 3]) / (2 * math.sqrt(2)
                                                                       * math.sin(a))
    assert beam_noise_from_error_velocity(error, angle) == pytest.approx(sigma, rel=0.03)
    v_x = (beams[:, 0] - beams[:, 1]) / (2 * math.sin(a))
    assert ins.janus_velocity_std(sigma, angle)[0] == pytest.approx(v_x.std(), rel=0.03)
    assert ins.janus_velocity_std(sigma, angle)[0] == pytest.approx(error.std(), rel=0.03)


needs_akit = pytest.mark.skipif(not sea_filter.DATA.is_dir(), reason="the shared A-KIT "
                                "segments are absent (../shared/data/snapir-akit)")
SEGMENTS = tuple(range(1, 7))


@pytest.fixture(scope="module")
def akit_files(tmp_path_factory):
    """The six shared segments through the product's path: ``auvsim import --format
    akit``, then ``auvsim check-log --apply`` (``beamsnet.experiments.sea.sea_dataset``,
    as ``reproduce sea`` and ``sea_filter`` make them). Returns (imported, corrected)."""
    work = tmp_path_factory.mktemp("akit")
    checked = sea_dataset(sea_filter.DATA, work)[0]
    return work / "sea-logged.h5", checked


@needs_akit
@pytest.mark.parametrize("k", SEGMENTS)
def test_the_filter_converges_on_each_shared_segment_with_its_defaults(akit_files, k):
    """On each real segment as ``check-log --apply`` wrote it (the IMU's y axis mirrored
    back, every stream on the IMU's clock, the sensors' positions and the DVL's
    mounting found from the data) and started from its reference, ``run_mission`` with
    its defaults (no hand settings) ends under 5 m from the reference, accepting the
    pings, without a restart."""
    with open_dataset(akit_files[1]) as f:
        m = f.missions[f"trajectory{k}"]
        found = json.loads(m.attrs["check_log_json"])["corrections"]
        np.testing.assert_array_equal(found["imu_axis_matrix"], np.diag([1.0, -1.0, 1.0]))
        result = sea_filter.score(m)
    assert result["final"] < 5.0, result
    assert result["restarts"] == 0 and result["availability"] > 0.95, result


def test_run_mission_on_a_recorded_mission_starts_from_its_reference_on_a_rotating_earth():
    """A recorded mission as the schema-7 contract has it (``origin = "recorded"``,
    ``reference/`` instead of ``truth/``, the DVL's own ``velocity_ls``, the instrument's
    attributes): ``run_mission`` starts at the reference, turns the Earth at the mission's
    latitude with its gravity, takes the DVL's noise from ``dvl_velocity_accuracy``, and
    the IMU at rest stays put (the same answer as ``run_arrays`` on its arrays)."""
    latitude = 32.85
    data = stationary(latitude, seconds=120.0)
    n_ref = 121
    c = data["start"].rotation
    attrs = dict(origin="recorded", latitude_deg=latitude, longitude_deg=34.9, height_m=-20.0,
                 gravity=normal_gravity(latitude), imu_rate_hz=100.0,
                 imu_position_body=np.zeros(3), imu_accel_noise_density=2e-4,
                 imu_gyro_noise_density=7e-7, imu_accel_bias_instability=1e-4,
                 imu_gyro_bias_instability=5e-8, imu_bias_correlation_time=3600.0,
                 dvl_rate_hz=1.0, beam_angle_deg=30.0, dvl_position_body=np.zeros(3),
                 dvl_mounting_rpy_deg=np.zeros(3), dvl_velocity_accuracy=0.02,
                 dvl_beams_derived=True)
    mission = Fields(
        name="rest", origin="recorded", attrs=attrs, gravity=attrs["gravity"],
        has=lambda group: group in ("imu", "dvl", "reference"),
        imu=Fields(time=data["imu_time"], specific_force=data["specific_force"],
                   angular_rate=data["angular_rate"]),
        dvl=Fields(time=data["dvl_time"], velocity_ls=data["velocity"]),
        reference=Fields(time=np.arange(n_ref, dtype=float), position_ned=np.zeros((n_ref, 3)),
                         velocity_ned=np.zeros((n_ref, 3)),
                         quaternion=np.tile(quaternion_from_euler(0.0, 0.0, math.radians(30)),
                                            (n_ref, 1))),
        dataset=Fields(config_json=""))
    np.testing.assert_allclose(rotation_matrices(mission.reference.quaternion[:1])[0], c,
                               atol=1e-12)
    track = ins.run_mission(mission)
    assert np.abs(track.position_ned).max() < 1e-9 and track.availability == 1.0
    assert np.all(np.abs(track.position_ned) <= 3 * track.position_std)
    assert np.isnan(track.nees_velocity).all()  # a reference is not a truth
    without = ins.run_mission(mission, ins.FilterConfig(earth_rate=False, dvl_updates=False))
    assert np.abs(without.position_ned[:60, :2]).max() > 1.0  # the Earth's rate mattered
    no_attitude = Fields(time=mission.reference.time, position_ned=mission.reference.position_ned,
                         velocity_ned=mission.reference.velocity_ned)
    blind = Fields(**{**vars(mission), "reference": no_attitude})
    with pytest.raises(DataError, match="mission rest: its reference has no attitude to "
                       "start the filter from; expected start_heading_deg"):
        ins.run_mission(blind)
    # Given the heading, a coarse alignment starts it: levelled from the accelerometers,
    # at the reference's position and velocity, or (no reference at all) at the origin
    # with the DVL's velocity; at rest, either stays put within its own 3 sigma.
    given = ins.FilterConfig(start_heading_deg=30.0, start_heading_std_deg=2.0)
    alone = Fields(**{**vars(mission), "has": lambda group: group in ("imu", "dvl")})
    for log in (blind, alone):
        aligned = ins.run_mission(log, given)
        assert aligned.availability == 1.0 and not aligned.events
        assert np.abs(aligned.position_ned).max() < 0.05
        assert np.all(np.abs(aligned.position_ned) <= 3 * aligned.position_std)
        np.testing.assert_allclose(aligned.rotation, track.rotation, atol=1e-6)


def test_coarse_alignment_levels_a_tilted_imu_at_rest():
    """At rest, roll 3 deg and pitch -2 deg: the averaged accelerometers give them back
    (to rounding), the heading is the one given, and the level std is the floor (1 mrad)
    since nothing moves."""
    c = rotation_rpy(math.radians(3.0), math.radians(-2.0), math.radians(120.0))
    t = np.arange(0.0, 20.0, 0.01)
    f = np.tile(c.T @ [0.0, 0.0, -9.8], (len(t), 1))
    start = ins.coarse_alignment(t, f, heading_deg=120.0)
    np.testing.assert_allclose(start.rotation, c, atol=1e-12)
    assert start.attitude_std[:2] == pytest.approx([1e-3, 1e-3])
    assert start.attitude_std[2] == pytest.approx(math.radians(1.0))


def test_a_coarse_alignment_under_way_takes_the_acceleration_the_dvl_shows_out():
    """Level, heading 120 deg, speeding up at 0.2 m/s^2 from 1.5 m/s while turning at
    3 deg/s: the accelerometers read a - g with a = dv/dt + w x v = (0.2, u r, 0), which
    averaged alone tilts the start by atan(a / g) (1.2 deg in pitch, 0.5 deg in roll at
    the mean speed); the DVL's velocities (a 1 Hz ramp, mounted 180 deg in yaw) give the
    acceleration back, and the level comes out exact."""
    c = rotation_rpy(0.0, 0.0, math.radians(120.0))
    t = np.arange(0.0, 20.0, 0.01)
    r = math.radians(3.0)
    u = 1.5 + 0.2 * t
    f = np.column_stack([np.full(len(t), 0.2), u * r, np.full(len(t), -9.8)])
    w = np.tile([0.0, 0.0, r], (len(t), 1))
    pings = np.arange(0.0, 20.0)
    mounting = rotation_rpy(0.0, 0.0, math.pi)
    v_dvl = np.column_stack([1.5 + 0.2 * pings, 0 * pings, 0 * pings]) @ mounting  # M^T v
    a = ins.dvl_acceleration(pings, v_dvl, mounting, t, w)
    np.testing.assert_allclose(a, [0.2, 2.5 * r, 0.0], atol=1e-12)  # mean speed over 10 s
    tilted = ins.coarse_alignment(t, f, heading_deg=120.0)
    assert abs(math.degrees(math.asin(-tilted.rotation[2, 0])) - 1.17) < 0.01  # its pitch
    level = ins.coarse_alignment(t, f, heading_deg=120.0, acceleration_body=a)
    np.testing.assert_allclose(level.rotation, c, atol=1e-9)


def test_a_start_from_a_reference_is_as_uncertain_as_its_clock_lets_it_be():
    """A vehicle rolling at 33 deg/s when it starts: a clock known to 0.05 s leaves its
    roll uncertain by 1.65 deg (beside the reference's 0.01 deg), a 2 m/s speed its
    position by 0.1 m more along the track."""
    config = ins.FilterConfig(clock_std=0.05)
    start = ins.start_from_reference(0.0, np.zeros(3), np.array([2.0, 0.0, 0.0]), np.eye(3),
                                     angular_rate=np.radians([33.0, 0.0, 0.0]), config=config)
    assert math.degrees(start.attitude_std[0]) == pytest.approx(math.hypot(1.65, 0.01))
    assert math.degrees(start.attitude_std[2]) == pytest.approx(0.05)
    assert start.position_std[0] == pytest.approx(math.hypot(0.1, 0.1))
    assert start.position_std[1] == pytest.approx(0.1)


def test_a_corrected_files_clocks_are_as_uncertain_as_check_log_found_them():
    """The clock uncertainty of a file ``check-log --apply`` wrote: for the start, how
    well it knew the IMU's clock (its windows' standard error, widened by how far the
    applied offset lies from their mean: here 0.005 s) and the stamp's place in an IMU
    sample (uniform over 0.01 s: 0.01 / sqrt 12); for a ping, that and the DVL clock's;
    ``CLOCK_STD`` for a clock it did not find, or for both without a report; a setting
    wins over all."""
    windows = [[10.0, 0.41], [60.0, 0.40], [110.0, 0.405]]  # mean 0.405, applied 0.4
    found = [{"name": "imu clock", "value": {"offset_s": 0.4, "offset_se_s": 0.012,
                                             "rate_error": 0.0, "windows": windows}},
             {"name": "dvl clock", "value": {"offset_s": 1.4, "offset_se_s": 0.02}}]
    attrs = {"check_log_json": json.dumps({"findings": found})}
    imu = math.sqrt(0.012**2 + 0.005**2 + 0.01**2 / 12)
    start, ping = ins.clock_stds(attrs, ins.FilterConfig(), 100.0)
    assert start == pytest.approx(imu)
    assert ping == pytest.approx(math.hypot(imu, 0.02))
    dvl_only = {"check_log_json": json.dumps({"findings": found[1:]})}
    assert ins.clock_stds(dvl_only, ins.FilterConfig(), 100.0) == pytest.approx(
        (ins.CLOCK_STD, math.hypot(ins.CLOCK_STD, 0.02)))
    assert ins.clock_stds({}, ins.FilterConfig(), 100.0) == (ins.CLOCK_STD, ins.CLOCK_STD)
    assert ins.clock_stds(attrs, ins.FilterConfig(clock_std=0.03), 100.0) == (0.03, 0.03)


@needs_akit
def test_run_mission_on_the_imported_and_the_corrected_segment(akit_files):
    """Segment 5 as ``auvsim import --format akit`` wrote it (the IMU's y axis mirrored,
    the clocks apart): the filter does not converge and says so (restarts, far fewer
    pings accepted). As ``check-log --apply`` wrote it: under 5 m from the reference at
    the end, and its error within the reported 3 sigma (radius 3 sqrt(var N + var E))
    at least 90 % of the time."""
    imported, checked = akit_files
    with open_dataset(imported) as f:
        raw = ins.run_mission(f.missions["trajectory5"])
    with open_dataset(checked) as f:
        result = sea_filter.score(f.missions["trajectory5"])
    assert result["final"] < 5.0 and result["coverage"] >= 0.9, result
    assert result["availability"] > 0.95
    assert len(raw.events) > 10 and raw.availability < 0.9


@needs_akit
def test_the_evidence_on_segment_4_is_what_the_benchmark_docstring_quotes(akit_files):
    """``benchmarks/sea_filter.py --evidence`` on the corrected segment 4: the reference's
    positions leave the integral of its velocities by 1.34 m within 50 s (1.83 m over the
    segment), the gyros alone hold its heading to 0.03 deg (std), and the DVL's error
    along x has a mean of 4.7 mm/s and a slow part that lasts (tau over 10 s)."""
    with open_dataset(akit_files[1]) as f:
        m = f.missions["trajectory4"]
        drift, since = sea_filter.reference_drift(m)
        heading = sea_filter.gyro_heading(m)
        x = sea_filter.dvl_error(m)[0]
    assert drift[since <= sea_filter.EARLY].max() == pytest.approx(1.34, abs=0.005)
    assert drift.max() == pytest.approx(1.83, abs=0.005)
    assert np.std(heading) < 0.03 and len(heading) > 390
    assert 1e3 * x["mean"] == pytest.approx(4.7, abs=0.05)
    assert 1e3 * x["slow"] == pytest.approx(9.4, abs=0.05) and x["tau"] > 10.0


@needs_akit
def test_the_navigator_imu_vibrates_as_the_shared_segments_imu_does(akit_files):
    """The ``navigator`` preset's IMU vibration is the real Phins' (``benchmarks/
    imu_spectrum.py``): per axis, the line a + b |yaw rate| fitted to the r.m.s. above
    10 Hz of each second of the six segments, to its stated digits. The simulated vibration,
    fed each segment's own yaw rates (below 10 Hz: the real gyro's vibration left out) and
    measured the same way, gives the line back (times what the benchmark's high-pass keeps
    of its r.m.s.: the square root of the integral of sin^2(pi f / 100) |H(f)|^4 over that
    of sin^2(pi f / 100), 0-50 Hz, H the 4th-order Butterworth at 10 Hz run forward and
    back: 0.990)."""
    import imu_spectrum
    from scipy import signal

    from auvsim.runs.presets import SNAPIR_VIBRATION
    from auvsim.sensors.imu import ImuBiases, ImuErrorModel

    deg_h = math.degrees(1.0) * 3600.0
    with open_dataset(akit_files[1]) as f:
        missions = [m for _, m in sorted(f.missions.items())]
        real = imu_spectrum.vibration_fit(map(imu_spectrum.per_second, missions))
        gyro_z = [np.asarray(m.imu.angular_rate, dtype=float)[:, 2:] for m in missions]
    rates = [(z - imu_spectrum.high_passed(z))[:, 0] for z in gyro_z]
    shake = {k: np.asarray(v) for k, v in SNAPIR_VIBRATION.items()}
    np.testing.assert_allclose(1e3 * shake["accel_vibration_std"], 1e3 * real["accel_std"],
                               atol=0.05)
    np.testing.assert_allclose(1e3 * shake["accel_vibration_per_rate"],
                               1e3 * real["accel_per_rate"], atol=0.5)
    np.testing.assert_allclose(deg_h * shake["gyro_vibration_std"], deg_h * real["gyro_std"],
                               atol=0.05)
    np.testing.assert_allclose(deg_h * shake["gyro_vibration_per_rate"],
                               deg_h * real["gyro_per_rate"], atol=0.05)
    assert np.all(real["accel_r2"] > 0.6) and np.all(real["gyro_r2"] > 0.6)

    config = dataclasses.replace(IMU_GRADES["ideal"], **SNAPIR_VIBRATION)
    simulated = []
    for k, yaw in enumerate(rates):
        w = np.zeros((len(yaw), 3))
        w[:, 2] = yaw
        force, rate = ImuErrorModel(config, ImuBiases(np.zeros(3), np.zeros(3)),
                                    np.random.default_rng(k)).corrupt(np.zeros_like(w), w)
        simulated.append(Fields(imu=Fields(specific_force=force, angular_rate=rate)))
    freq, h = signal.sosfreqz(signal.butter(4, imu_spectrum.VIBRATION_HZ, btype="high",
                                            fs=100.0, output="sos"), worN=20_001, fs=100.0)
    shape = np.sin(np.pi * freq / 100.0) ** 2
    kept = math.sqrt(np.trapezoid(shape * np.abs(h) ** 4, freq) / np.trapezoid(shape, freq))
    assert kept == pytest.approx(0.990, abs=5e-4)
    back = imu_spectrum.vibration_fit(map(imu_spectrum.per_second, simulated))
    for name in ("accel", "gyro"):
        np.testing.assert_allclose(back[f"{name}_std"], kept * real[f"{name}_std"],
                                   rtol=0.05)
        np.testing.assert_allclose(back[f"{name}_per_rate"],
                                   kept * real[f"{name}_per_rate"], rtol=0.05)


@pytest.mark.parametrize("angle", [20.0, 30.0])
def test_the_janus_velocity_std_is_least_squares_noise_on_every_axis(angle):
    """White beam noise sigma through least squares: sigma sqrt(diag((H^T H)^-1)), from the
    beams' geometry, on all three axes."""
    h = beam_matrix(math.radians(angle))
    np.testing.assert_allclose(ins.janus_velocity_std(0.01, angle),
                               0.01 * np.sqrt(np.diag(np.linalg.inv(h.T @ h))), rtol=1e-12)


def test_a_steady_turn_gives_the_clock_uncertainty_nothing_to_add():
    """Level circle at 2 m/s and 10 deg/s: the DVL's velocity in the body, whose rate of
    change (f + C^T g - w x v) a ping's timing uncertainty turns into innovation
    variance, does not change, so a 0.05 s clock uncertainty adds nothing."""
    data, _ = circle(30.0)  # at 2 m/s and 10 deg/s, the DVL measuring (2, 0, 0) m/s
    data.update(velocity=np.tile([2.0, 0.0, 0.0], (len(data["dvl_time"]), 1)),
                config=ins.FilterConfig())
    runs = [ins.run_arrays(**data, timing_std=s) for s in (0.0, 0.05)]
    np.testing.assert_allclose(runs[1].innovation_var, runs[0].innovation_var, rtol=0,
                               atol=1e-8)
