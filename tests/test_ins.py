"""The INS/DVL filter (``beamsnet.estimators.ins``): known answers on small generated missions."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import Fields, flat
from scipy.stats import chi2

from auvsim.config import DvlConfig, ImuConfig, MissionConfig, ScenarioConfig
from auvsim.data.beams import beam_matrix
from auvsim.data.importer import import_velocity
from auvsim.data.reader import open_dataset
from auvsim.physics.earth import earth_rate_ned, normal_gravity, specific_force_on_earth
from auvsim.physics.frames import euler_angles, rotation_matrices, rotation_rpy
from auvsim.runs.presets import PAPER_NOISE_CODE
from auvsim.sensors.imu import IMU_GRADES
from beamsnet.cli import main
from beamsnet.data import DataError, load_windows, split
from beamsnet.estimators import ins


def zigzag(duration: float, seed: int = 0) -> MissionConfig:
    return MissionConfig(name="zz", seed=seed,
                         scenario=ScenarioConfig(name="zigzag", duration=duration))


@pytest.fixture(scope="module")
def ideal(dataset_of):
    """Noise-free: an ideal IMU and a DVL without noise, scale factor or bias."""
    return dataset_of(flat(zigzag(120.0), imu=IMU_GRADES["ideal"]), "ideal")


def lever_arm_error(m) -> tuple[np.ndarray, np.ndarray]:
    """The mechanisation's exact discretisation error on noise-free data, at every IMU
    sample: IMU-point velocity (N, 3) m/s and position (N, 3) m, NED.

    The body origin integrates back exactly (module docstring). At the IMU point, r from
    the origin, v_imu = v_o + C (w x r), and the accelerometer reads the point's
    acceleration a_o + C (alpha x r + w x (w x r)) at the start of each step, so step i
    adds to the velocity error
    e_i = dt C_{i-1} (alpha_{i-1} x r + w_{i-1} x (w_{i-1} x r)) - (u_i - u_{i-1}),
    u = C (w x r), alpha_{i-1} = (w_i - w_{i-1}) / dt (MuJoCo's Euler step): a Taylor
    remainder, |e_i| = O(dt^2 (|w| |alpha| + |alpha'|) |r|). p_i = p_{i-1} + dt v_i adds
    d_i = dt u_i - (C_i - C_{i-1}) r = O(dt^2 |w|^2 |r|) to the position error each step.
    """
    dt = 1.0 / m.attrs["imu_rate_hz"]
    r = np.asarray(m.attrs["imu_position_body"])
    c = rotation_matrices(m.truth.quaternion)
    w = m.truth.angular_rate
    alpha = np.diff(w, axis=0) / dt
    lever = np.cross(alpha, r) + np.cross(w[:-1], np.cross(w[:-1], r))
    u = np.einsum("nij,nj->ni", c, np.cross(w, r))
    e = dt * np.einsum("nij,nj->ni", c[:-1], lever) - np.diff(u, axis=0)
    dv = np.concatenate([np.zeros((1, 3)), np.cumsum(e, axis=0)])
    d = dt * u[1:] - np.diff(c, axis=0) @ r
    dp = np.concatenate([np.zeros((1, 3)), np.cumsum(dt * dv[1:] + d, axis=0)])
    return dv, dp


def test_noise_free_mechanisation_integrates_back_to_its_derived_discretisation_error(ideal):
    """Pure inertial navigation (no beam used) from the truth: the velocity and position
    errors are exactly the lever arm's discretisation error derived above, which stays
    below its bound sum |e_i| (3e-3 m/s over this zigzag; the error itself peaks at 1e-4)."""
    with open_dataset(ideal) as f:
        m = f.missions["zz"]
        track = ins.run_mission(m, ins.FilterConfig(dvl_updates=False))
        dv, dp = lever_arm_error(m)
        rows = m.imu.index_of_dvl
        c = rotation_matrices(m.truth.quaternion[rows])
        mounting = rotation_rpy(*np.radians(m.attrs["dvl_mounting_rpy_deg"]))
        predicted = np.einsum("ji,pkj,pk->pi", mounting, c, dv[rows])
        error = track.velocity_dvl - m.dvl.velocity
        position_error = track.position_ned - m.truth.position_ned[rows]
        assert track.beams_used.sum() == 0
        assert np.abs(m.truth.angular_rate[:, 2]).max() > 0.05  # it turns
    bound = np.cumsum(np.linalg.norm(np.diff(dv, axis=0), axis=1))[rows - 1].max()
    assert 1e-6 < np.abs(error).max() <= bound < 1e-2
    np.testing.assert_allclose(error, predicted, rtol=0, atol=1e-9)
    np.testing.assert_allclose(position_error, dp[rows], rtol=0, atol=1e-8)


def test_noise_free_filter_tracks_the_truth_within_the_mechanisation_error(ideal):
    """With the beams, the velocity error at every ping stays within the pure
    mechanisation's error bound and within 3 sigma of the filter's own std."""
    with open_dataset(ideal) as f:
        m = f.missions["zz"]
        track = ins.run_mission(m)
        dv, _ = lever_arm_error(m)
        error = track.velocity_dvl - m.dvl.velocity
    assert track.beams_used.min() == 4 and track.beams_rejected.sum() == 0
    assert np.abs(error).max() <= np.linalg.norm(dv, axis=1).max() < 1e-3


def test_earth_rate_compensation_undoes_an_earth_rate_put_into_noise_free_data(ideal):
    """The same motion seen from a local-level frame turning with the Earth at 45 deg,
    as auvsim's IMU reads it on the Earth: the gyros read w + C^T Omega_ie and the
    accelerometers f + C^T (2 Omega_ie x v) with the normal gravity at the IMU's depth
    (``auvsim.physics.earth.specific_force_on_earth``). With ``earth_rate`` (and the
    normal gravity at the surface, growing with depth) the filter navigates as on the
    original data, to a few parts in a million of what it would do otherwise: the
    attitude update takes the Earth's rate at the sample's own attitude, as the data hold
    it (with the previous sample's, a turn at r tilts the solution by dt r Omega per
    second, 1.6e-7 rad/s at 15 deg/s: 1.1 m north in 240 s of a turning circle; and with
    the surface's gravity at 20 m depth, 6e-5 m/s^2 more, 1.8 m down). Without it the
    uncompensated 10 deg/h (1e-4 rad/s at the gyro) tilts the solution far off."""
    omega = earth_rate_ned(45.0)
    with open_dataset(ideal) as f:
        m = f.missions["zz"]
        r = np.asarray(m.attrs["imu_position_body"])
        c = rotation_matrices(m.truth.quaternion)
        w = m.truth.angular_rate
        v_imu = m.truth.velocity_ned + np.einsum("nij,nj->ni", c, np.cross(w, r))
        depth = m.truth.position_ned[:, 2] + c[:, 2] @ r
        imu = Fields(
            angular_rate=m.imu.angular_rate + np.einsum("nji,j->ni", c, omega),
            specific_force=specific_force_on_earth(m.imu.specific_force, c, v_imu, depth,
                                                   latitude_deg=45.0, flat_gravity=m.gravity),
            index_of_dvl=m.imu.index_of_dvl)
        rotating = Fields(name=m.name, origin=m.origin, attrs=m.attrs, dataset=m.dataset,
                          imu=imu, truth=m.truth, dvl=m.dvl, has=m.has, gravity=m.gravity)
        config = ins.FilterConfig(dvl_updates=False, earth_rate=True, latitude_deg=45.0,
                                  gravity=normal_gravity(45.0, 0.0))
        compensated = ins.run_mission(rotating, config)
        plain = ins.run_mission(m, ins.FilterConfig(dvl_updates=False))
        ignored = ins.run_mission(rotating, ins.FilterConfig(dvl_updates=False))
    difference = np.abs(compensated.velocity_dvl - plain.velocity_dvl).max()
    speed = np.linalg.norm(plain.velocity_dvl, axis=1).max()
    assert difference < 1e-5 * speed, difference
    assert np.abs(compensated.position_ned - plain.position_ned).max() < 1e-3
    assert np.abs(ignored.velocity_dvl - plain.velocity_dvl).max() > 1e4 * difference


@pytest.mark.filterwarnings("ignore:The copy keyword is deprecated")  # pyins on pandas 3
def test_the_mechanisation_agrees_with_pyins_as_an_independent_integrator(ideal, monkeypatch):
    """pyins (python-ins, Savage's strapdown algorithm) with its Earth flattened (no
    rotation, a 1e12 m radius, constant gravity) is an independent flat-NED integrator.
    It reads the samples as rates varying linearly over each step; the simulated IMU's
    step instead holds the NED acceleration and rotates by the next rate, a difference
    of the rotation compensation (w x f) dt^2 / 2 per step, so pyins stays within
    sum dt^2 / 2 |w x f| of the truth (5e-2 m/s here; its error peaks at 5e-3), and the
    two integrators within that plus our own lever-arm error."""
    pytest.importorskip("pyins", reason="pyins (python-ins) is the reference integrator")
    import pandas as pd
    from pyins import earth, strapdown, util

    # Read by pyins' compiled integrator at its first compilation (never cached), so
    # this holds for the process; nothing else here uses pyins.
    for name, value in (("RATE", 0.0), ("A", 1e12), ("E2", 0.0), ("F", 0.0)):
        monkeypatch.setattr(earth, name, value)
    with open_dataset(ideal) as f:
        m = f.missions["zz"]
        monkeypatch.setattr(earth, "GE", m.gravity)
        dt = 1.0 / m.attrs["imu_rate_hz"]
        r = np.asarray(m.attrs["imu_position_body"])
        c = rotation_matrices(m.truth.quaternion)
        w, force = m.truth.angular_rate, m.imu.specific_force
        v_imu = m.truth.velocity_ned + np.einsum("nij,nj->ni", c, np.cross(w, r))
        imu = pd.DataFrame(np.hstack([m.imu.angular_rate, force]), index=m.truth.time,
                           columns=util.GYRO_COLS + util.ACCEL_COLS)
        roll, pitch, heading = np.degrees(euler_angles(m.truth.quaternion[:1])[0])
        start = pd.Series(dict(lat=0.0, lon=0.0, alt=-(m.truth.position_ned[0] + c[0] @ r)[2],
                               VN=v_imu[0, 0], VE=v_imu[0, 1], VD=v_imu[0, 2], roll=roll,
                               pitch=pitch, heading=heading))
        trajectory = strapdown.Integrator(start).integrate(
            strapdown.compute_increments_from_imu(imu, "rate"))
        rows = m.imu.index_of_dvl
        ours = ins.run_mission(m, ins.FilterConfig(dvl_updates=False))
        dv, _ = lever_arm_error(m)
        mounting = rotation_rpy(*np.radians(m.attrs["dvl_mounting_rpy_deg"]))
        lever = np.asarray(m.attrs["dvl_position_body"]) - r
    v_pyins = trajectory[util.VEL_COLS].to_numpy()[rows]
    # Ours at the IMU point in NED, with the true attitude (exact on noise-free data).
    body = ours.velocity_dvl @ mounting.T - np.cross(w[rows], lever)
    v_ours = np.einsum("pij,pj->pi", c[rows], body)
    bound = np.cumsum(dt**2 / 2 * np.linalg.norm(np.cross(w, force), axis=1))[rows]
    assert np.linalg.norm(v_pyins - v_imu[rows], axis=1).max() <= bound.max() < 0.1
    assert (np.linalg.norm(v_pyins - v_ours, axis=1)
            <= bound.max() + np.linalg.norm(dv[rows], axis=1)).all()
    assert ours.beams_used.sum() == 0


@pytest.fixture(scope="module")
def gyro_bias(dataset_of):
    """A constant gyro bias: a MEMS-class turn-on spread (10 deg/h), nothing else."""
    imu = ImuConfig(gyro_turn_on_bias=math.radians(10.0) / 3600.0)
    return dataset_of(flat(zigzag(200.0, seed=10), imu=imu,
                           dvl=DvlConfig(noise_std=PAPER_NOISE_CODE)), "gyro_bias")


def test_a_constant_gyro_bias_is_estimated_within_three_sigma(gyro_bias):
    with open_dataset(gyro_bias) as f:
        m = f.missions["zz"]
        truth = m.attrs["imu_gyro_turn_on_bias"]
        track = ins.run_mission(m)
    error = track.gyro_bias[-1] - truth
    sigma = track.gyro_bias_std[-1]
    prior = math.radians(10.0) / 3600.0
    assert np.all(np.abs(error) < 3 * sigma)
    assert np.all(sigma[:2] < 0.1 * prior)  # the level axes, observed through the tilt
    assert sigma[2] < prior  # heading: weakly, through the turns' accelerations


RUNS = 8  # Monte Carlo missions for the NEES


@pytest.fixture(scope="module")
def navigation(dataset_of):
    """Realistic noise: the navigation-grade IMU, the paper's beam noise; RUNS missions
    of independent seeds."""
    missions = [MissionConfig(name=f"zz_{i}", seed=20 + i,
                              scenario=ScenarioConfig(name="zigzag", duration=100.0))
                for i in range(RUNS)]
    return dataset_of(flat(*missions, imu=IMU_GRADES["navigation"],
                           dvl=DvlConfig(noise_std=PAPER_NOISE_CODE)), "navigation")


def test_velocity_nees_is_consistent_with_the_chi_square_bounds(navigation):
    """The filter's noise model matches the simulator's (Bar-Shalom, Li & Kirubarajan
    2001, sec. 5.4.2): over RUNS independent missions, each started with initial errors
    drawn from the filter's initial covariance, the run-averaged NEES of the DVL-frame
    velocity (3 dof) at each ping lies in its two-sided 95 % interval
    chi2(3 RUNS) / RUNS at about 95 % of the pings, and its average over the pings is
    near 3. The pings of one run are correlated, so the share outside is not binomial:
    the test asks for at least 85 % inside, and a mean within 20 % of 3."""
    with open_dataset(navigation) as f:
        nees = np.stack([ins.run_mission(f.missions[f"zz_{i}"],
                                         ins.FilterConfig(initial_error_seed=i)).nees_velocity
                         for i in range(RUNS)])
    average = nees.mean(axis=0)
    low, high = chi2.ppf([0.025, 0.975], 3 * RUNS) / RUNS
    inside = np.mean((average > low) & (average < high))
    assert inside >= 0.85, (inside, average.mean())
    assert abs(average.mean() - 3.0) < 0.6, (inside, average.mean())


def test_beam_scale_factors_and_biases_are_estimated_within_three_sigma(dataset_of):
    """Per-beam scale factors (std 0.5 %) and biases (std 5 mm/s), the navigator preset's
    spread made larger so that they matter, on the navigation-grade IMU: with
    ``beam_states`` each is estimated within 3 sigma, its std falls (to about 0.7 of the
    prior in 200 s: at one speed a beam's scale factor and bias look alike, and the INS
    tells either from a velocity only through the accelerometers), and the velocity is
    closer to the truth than without the states."""
    dvl = DvlConfig(noise_std=PAPER_NOISE_CODE, scale_factor_std=0.005, bias_std=0.005)
    path = dataset_of(flat(zigzag(200.0, seed=11), imu=IMU_GRADES["navigation"], dvl=dvl),
                      "beam_states")
    config = ins.FilterConfig(beam_states=True, beam_scale_std=0.005, beam_bias_std=0.005)
    with open_dataset(path) as f:
        m = f.missions["zz"]
        track = ins.run_mission(m, config)
        scale, bias = m.attrs["dvl_scale_factor"], m.attrs["dvl_bias"]
        without = ins.run_mission(m)
        truth = m.dvl.velocity
    assert np.all(np.abs(track.beam_scale[-1] - scale) < 3 * track.beam_scale_std[-1])
    assert np.all(np.abs(track.beam_bias[-1] - bias) < 3 * track.beam_bias_std[-1])
    assert np.all(track.beam_scale_std[-1] < 0.8 * 0.005)
    assert np.all(track.beam_bias_std[-1] < 0.8 * 0.005)
    rms = [np.sqrt(np.mean((t.velocity_dvl - truth) ** 2)) for t in (track, without)]
    assert rms[0] < rms[1]
    assert np.isnan(without.beam_scale).all()


def test_the_dvls_slow_velocity_error_is_estimated_within_its_reported_std(dataset_of):
    """A DVL with a Gauss-Markov velocity error of 9 mm/s over 19 s in its frame (the
    ``navigator`` preset's) and 2 mm/s of white beam noise: with the slow-error states (on
    by default where the beams are measured and the file states a slow error) the filter's
    estimate of that error lies within 3 sigma of the drawn one (what the beams hold
    beyond the true velocity, by LS; the LS of the white noise added to sigma) at every
    ping after the first 20 s, and its rms error is under 0.8 of the error's own spread on
    every axis: it sees the error, not its prior. Off, the four biases c_k hold it
    instead, each within 3 sigma of the drawn error along its beam (the white noise added)
    at 98 % of those pings or more."""
    dvl = DvlConfig(noise_std=0.002, slow_error_std=0.009, slow_error_time=19.0)
    path = dataset_of(flat(zigzag(200.0, seed=44), imu=IMU_GRADES["navigation"], dvl=dvl),
                      "slow_error")
    with open_dataset(path) as f:
        m = f.missions["zz"]
        h = beam_matrix(math.radians(float(m.attrs["beam_angle_deg"])))
        drawn = (np.asarray(m.dvl.beam_velocity)
                 - np.asarray(m.dvl.velocity) @ h.T) @ np.linalg.pinv(h).T
        track = ins.run_mission(m)
        off = ins.run_mission(m, ins.FilterConfig(slow_error_states=False))
    white = 0.002 * np.sqrt(np.diag(np.linalg.inv(h.T @ h)))
    late = track.ping_time - track.ping_time[0] >= 20.0
    error = (track.slow_error - drawn)[late]
    assert np.all(np.abs(error) < 3 * np.hypot(track.slow_error_std[late], white))
    assert np.all(np.sqrt(np.mean(error**2, axis=0)) < 0.8 * drawn[late].std(axis=0))
    assert np.isnan(off.slow_error).all()
    along = (drawn @ h.T)[late]
    held = np.abs(off.beam_bias[late] - along) < 3 * np.hypot(off.beam_bias_std[late], 0.002)
    assert np.all(held.mean(axis=0) >= 0.98), held.mean(axis=0)
    with pytest.raises(DataError, match="^mission zz: slow_error_states needs a DVL slow"):
        with open_dataset(path) as f:
            ins.run_mission(f.missions["zz"], ins.FilterConfig(slow_error_states=True,
                                                               beam_states=False))


def test_the_velocity_is_given_in_the_dvl_frame_the_filter_estimates(dataset_of):
    """A DVL mounted off its nominal frame as its file draws it (1 deg per axis: here
    -1.64, -1.14 and -0.21 deg), 1 mm/s of beam noise: with ``beam_states`` the filter
    takes the misalignment's prior from the file's spread (the same track as told 1 deg),
    estimates it within 3 sigma, and gives the velocity in the DVL frame so estimated:
    the true DVL frame's to 1.5 mm/s rms over the last 100 s, where the same velocity in
    the nominal frame is off by the speed times the misalignment (42 mm/s rms down). Its
    covariance holds the misalignment's (and the lever arm's) share: the mean velocity
    NEES lies within a factor 3.3 of a consistent filter's 3, either way (0.9 to 10: 1.3,
    pessimistic as the filter is on simulated data; with the misalignment's cross term of
    the wrong sign it was 0.6)."""
    dvl = DvlConfig(noise_std=0.001, misalignment_std_deg=1.0)
    path = dataset_of(flat(zigzag(200.0, seed=45), imu=IMU_GRADES["navigation"], dvl=dvl),
                      "misaligned")
    with open_dataset(path) as f:
        m = f.missions["zz"]
        drawn = np.radians(np.asarray(m.attrs["dvl_misalignment_rpy_deg"]))
        track = ins.run_mission(m, ins.FilterConfig(beam_states=True))
        told = ins.run_mission(m, ins.FilterConfig(beam_states=True, misalignment_std_deg=1.0))
        truth = np.asarray(m.dvl.velocity)
    np.testing.assert_array_equal(track.velocity_dvl, told.velocity_dvl)
    assert np.all(np.abs(track.misalignment[-1] - drawn) < 3 * track.misalignment_std[-1])
    late = track.ping_time - track.ping_time[0] >= 100.0
    error = track.velocity_dvl[late] - truth[late]
    nominal = track.velocity_dvl - np.cross(track.velocity_dvl, track.misalignment)
    rms = np.sqrt(np.mean(error**2, axis=0))
    assert np.all(rms < 1.5e-3), rms
    assert np.sqrt(np.mean((nominal[late] - truth[late]) ** 2, axis=0)).max() > 10 * rms.max()
    assert 0.9 < np.nanmean(track.nees_velocity) < 10.0


def test_a_sound_speed_error_shared_by_the_beams_is_held_by_a_correlated_scale_prior(
        dataset_of):
    """Every beam divided by the sound-speed ratio (the file's spread 1 %, here drawn at
    0.9907) besides each beam's own scale factor: the filter's scale-factor prior gains the
    shared part from the file (``common_scale_std``), and each beam's total scale, (1 + s_k)
    / ratio - 1, is estimated within 3 sigma; the velocity over the last 100 s is better
    than half as far from the truth along x as with independent priors, which take the
    shared scale for velocity: their mean NEES lies above 4 and twice the file's prior's
    (5.7 against 1.6), which lies within a factor 3.3 of a consistent filter's 3."""
    dvl = DvlConfig(noise_std=0.001, sound_speed_std=0.01)
    path = dataset_of(flat(zigzag(200.0, seed=47), imu=IMU_GRADES["navigation"], dvl=dvl),
                      "sound_speed")
    with open_dataset(path) as f:
        m = f.missions["zz"]
        total = ((1.0 + np.asarray(m.attrs["dvl_scale_factor"]))
                 / float(m.attrs["dvl_sound_speed_ratio"]) - 1.0)
        truth = np.asarray(m.dvl.velocity)
        shared = ins.run_mission(m, ins.FilterConfig(beam_states=True))
        apart = ins.run_mission(m, ins.FilterConfig(beam_states=True, common_scale_std=0.0))
    assert np.all(np.abs(shared.beam_scale[-1] - total) < 3 * shared.beam_scale_std[-1])
    late = shared.ping_time - shared.ping_time[0] >= 100.0
    rms = [np.sqrt(np.mean((t.velocity_dvl[late, 0] - truth[late, 0]) ** 2))
           for t in (shared, apart)]
    assert rms[0] < 0.5 * rms[1], rms
    nees = [np.nanmean(t.nees_velocity[late]) for t in (shared, apart)]
    assert 0.9 < nees[0] < 10.0 and nees[1] > max(4.0, 2.0 * nees[0]), nees


@pytest.mark.parametrize("beams, slow, gyro", [
    (False, False, False), (True, False, False), (True, True, False), (False, False, True),
    (True, False, True), (True, True, True)])
def test_each_optional_block_of_states_reports_in_its_own_columns(dataset_of, beams, slow,
                                                                  gyro):
    """Every layout of the state: the beam, slow-error and gyro-matrix blocks are each in
    their own columns of the track, NaN where off, and start at their own prior (the
    gyro matrix's, which one second of a zigzag does not move, to 1 %)."""
    dvl = DvlConfig(noise_std=0.002, slow_error_std=0.009, slow_error_time=19.0)
    path = dataset_of(flat(zigzag(30.0, seed=48), imu=IMU_GRADES["navigation"], dvl=dvl),
                      "layouts")
    config = ins.FilterConfig(beam_states=beams, slow_error_states=slow,
                              gyro_matrix_states=gyro, gyro_scale_factor_std=7e-6,
                              gyro_misalignment_std=1e-4)
    with open_dataset(path) as f:
        track = ins.run_mission(f.missions["zz"], config)
    for block, on in (("beam_scale", beams), ("slow_error", slow), ("gyro_matrix", gyro)):
        assert np.isfinite(getattr(track, f"{block}_std")).all() == on, block
        assert np.isnan(getattr(track, f"{block}_std")).all() == (not on), block
    if slow:
        assert np.all(track.slow_error_std[0] <= 0.009 + 1e-12)
        assert np.all(track.slow_error_std[0] > 0.003)
    if gyro:
        prior = np.where(np.eye(3).ravel() > 0, 7e-6, 1e-4)
        np.testing.assert_allclose(track.gyro_matrix_std[0], prior, rtol=0.01)
    if beams:
        assert np.all(track.beam_scale_std[0] <= 0.002 + 1e-12)


@pytest.fixture(scope="module")
def gyro_matrix(dataset_of):
    """The navigation-grade IMU with gyro scale factors (std 100 ppm) and misalignments
    (std 1 mrad, ten times the navigation-full grade's, so that 200 s show them), no
    accelerometer ones, on random waypoints: turns at up to 15 deg/s in every direction."""
    imu = dataclasses.replace(IMU_GRADES["navigation"], gyro_scale_factor_std=1e-4,
                              gyro_misalignment_std=1e-3)
    return dataset_of(flat(MissionConfig(name="rw", seed=12, scenario=ScenarioConfig(
        name="random_waypoints", duration=200.0)), imu=imu,
        dvl=DvlConfig(noise_std=PAPER_NOISE_CODE)), "gyro_matrix")


def test_the_gyros_scale_factors_and_misalignments_are_estimated_within_three_sigma(
        gyro_matrix):
    """With the gyro matrix's states (on by default where the IMU states the spreads) each
    element of K_g is estimated within 3 sigma, and the two a yaw rate excites (the x and y
    gyros' coupling to the z rate) to under a fifth of their prior. Without them the
    filter takes the tilt those couplings make in the turns for accelerometer bias:
    tens of sigma from the drawn bias along x or y, where with them it stays within 3, and
    its velocity NEES is further from 3."""
    with open_dataset(gyro_matrix) as f:
        m = f.missions["rw"]
        a = m.attrs
        drawn = (np.diag(np.asarray(a["imu_gyro_scale_factor"], dtype=float))
                 + np.asarray(a["imu_gyro_misalignment"], dtype=float).reshape(3, 3)).ravel()
        bias = np.asarray(a["imu_accel_turn_on_bias"], dtype=float)
        track = ins.run_mission(m)
        without = ins.run_mission(m, ins.FilterConfig(gyro_matrix_states=False))
    error, std = track.gyro_matrix[-1] - drawn, track.gyro_matrix_std[-1]
    assert np.all(np.abs(error) < 3 * std), error / std
    assert np.all(std[[2, 5]] < 0.2 * track.gyro_matrix_std[0][[2, 5]])
    assert np.all(np.abs(track.accel_bias[-1] - bias)[:2] < 3 * track.accel_bias_std[-1][:2])
    assert np.max(np.abs(without.accel_bias[-1] - bias)[:2]
                  / without.accel_bias_std[-1][:2]) > 10
    nees = [np.nanmean(t.nees_velocity) for t in (track, without)]
    assert abs(nees[0] - 3) < abs(nees[1] - 3), nees
    assert np.isnan(without.gyro_matrix).all()


def test_gyro_matrix_states_known_to_nothing_leave_the_filter_as_it_was(navigation):
    """The nine states with a prior of 1e-12 change nothing but the arithmetic's last
    digits: the track is the filter's without them to 1e-9 m and 1e-12 m/s."""
    with open_dataset(navigation) as f:
        m = f.missions["zz_0"]
        plain = ins.run_mission(m)
        known = ins.run_mission(m, ins.FilterConfig(
            gyro_matrix_states=True, gyro_scale_factor_std=1e-12, gyro_misalignment_std=1e-12))
    np.testing.assert_allclose(known.position_ned, plain.position_ned, rtol=0, atol=1e-9)
    np.testing.assert_allclose(known.velocity_dvl, plain.velocity_dvl, rtol=0, atol=1e-12)
    np.testing.assert_allclose(known.position_std, plain.position_std, rtol=1e-9)
    assert np.abs(known.gyro_matrix).max() < 1e-12


def test_gyro_matrix_states_without_a_spread_get_one_line_and_exit_2(navigation, tmp_path,
                                                                    capsys):
    settings = tmp_path / "filter.toml"
    settings.write_text("gyro_matrix_states = true\n")
    out = tmp_path / "out"
    assert main(["estimate", str(navigation), "--estimator", "INS/DVL", "--filter-config",
                 str(settings), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "its IMU states no gyro scale factor or misalignment" in err
    assert not out.exists()
    with pytest.raises(ValueError, match="^gyro_matrix_states: expected gyro_scale_factor_std"):
        ins.run_arrays(np.arange(3.0), np.tile([0.0, 0.0, -9.8], (3, 1)), np.zeros((3, 3)),
                       np.arange(2.0), velocity=np.zeros((2, 3)), start=ins.coarse_alignment(
                           np.arange(3.0), np.tile([0.0, 0.0, -9.8], (3, 1)), heading_deg=0.0),
                       instrument=ins.Instrument(1e-4, 1e-6, 1e-4, 1e-7, 0.0, 0.0,
                                                 np.full(3, 0.01)), gravity=9.8,
                       config=ins.FilterConfig(gyro_matrix_states=True))


@pytest.fixture(scope="module")
def two_beams(dataset_of):
    """Beams 2 and 3 dead all mission, and heavy-tailed outliers on 5 % of the rest."""
    dvl = DvlConfig(noise_std=PAPER_NOISE_CODE, beam_failures=((2, 0.0, 1e6), (3, 0.0, 1e6)),
                    outlier_rate=0.05, outlier_std=1.0)
    return dataset_of(flat(zigzag(120.0, seed=7), imu=IMU_GRADES["navigation"], dvl=dvl),
                      "two_beams")


def test_two_beams_give_a_velocity_at_every_ping_and_outliers_are_gated(two_beams):
    with open_dataset(two_beams) as f:
        m = f.missions["zz"]
        track = ins.run_mission(m)
        outlier = np.abs(m.dvl.beam_velocity - m.dvl.beam_velocity_true) > 0.1
        outlier &= m.dvl.valid
        error = track.velocity_dvl - m.dvl.velocity
        assert (m.dvl.mode == -1).all()  # no ping has an LS velocity
    assert np.isfinite(track.velocity_dvl).all()
    assert (track.beams_used + track.beams_rejected <= 2).all()
    assert outlier.sum() >= 5
    np.testing.assert_array_equal(track.beams_rejected[outlier.any(axis=1)] >= 1, True)
    assert track.beams_rejected.sum() <= outlier.sum() + 2  # a 0.1 % false alarm rate
    assert np.mean(np.abs(error) < 3 * track.velocity_std) > 0.95


def test_the_estimator_interface_predicts_every_sample_of_any_windows(navigation):
    """Each sample gets the track's velocity at its own ping, for the default windows,
    every ping (NaN beams among them) and a test split."""
    estimator = ins.InsDvlFilter(navigation).fit(split(load_windows(navigation))[0])
    for windows in (load_windows(navigation), load_windows(navigation, every_ping=True),
                    split(load_windows(navigation))[1]):
        v = estimator.predict(windows)
        p = estimator.positions(windows)
        tracks = estimator.tracks(windows)
        assert v.shape == p.shape == (len(windows.time), 3) and np.isfinite(v).all()
        for i, name in enumerate(windows.names):
            rows = windows.mission == i
            k = np.searchsorted(tracks[name].ping_time, windows.time[rows])
            np.testing.assert_array_equal(v[rows], tracks[name].velocity_dvl[k])
            np.testing.assert_array_equal(p[rows], tracks[name].position_ned[k])
    assert estimator.name == "INS/DVL"


def test_fit_learns_the_beams_scale_factor_that_the_imu_cannot_see(dataset_of):
    """A 1 % scale factor on every beam, no noise: on the steady legs the IMU cannot tell
    it from the velocity, so the raw-beam filter carries about 1 % of the velocity, while
    the filter on the beams corrected by the calibration fitted on the training split is
    exact to the mechanisation's error (1.2e-4 m/s, above)."""
    path = dataset_of(flat(zigzag(120.0), imu=IMU_GRADES["ideal"],
                           dvl=DvlConfig(scale_factor=0.01)), "scaled")
    train, test = split(load_windows(path))
    raw = ins.InsDvlFilter(path, calibrate=False).fit(train).predict(test)
    calibrated = ins.InsDvlFilter(path).fit(train).predict(test)
    speed = np.linalg.norm(test.target, axis=1)
    raw_error = np.linalg.norm(raw - test.target, axis=1)
    assert np.median(raw_error / speed) == pytest.approx(0.01, rel=0.3)
    assert np.abs(calibrated - test.target).max() < 2e-4


def test_a_mission_without_imu_raises_no_imu_error(tmp_path, capsys):
    source = tmp_path / "V.npy"
    np.save(source, np.tile([[1.0], [0.0], [0.0]], 20))
    path = tmp_path / "imported.h5"
    import_velocity([source], path, dvl=DvlConfig())
    with pytest.raises(ins.NoImuError, match=r"^mission V has no IMU record; [^\n]*skipped$"):
        ins.run(path, "V")
    # The command line names the file, not the --estimator flag as if it were wrong.
    assert main(["estimate", str(path), "--estimator", "INS/DVL",
                 "--out", str(tmp_path / "est")]) == 2
    assert capsys.readouterr().err == (
        f"beamsnet: error: {path}: mission V has no IMU record; the INS/DVL filter "
        "integrates the IMU, so it cannot run on it\n")


def test_a_ping_is_applied_at_the_imu_sample_nearest_its_time():
    """Known answers on a 100 Hz clock: a ping 4 ms after a sample is applied there and
    one 6 ms after at the next (at or before it, every ping would lag 5 ms on average);
    a ping more than half a sample before the first has none, nor, with a single sample,
    one before it."""
    t = np.arange(0.0, 1.0001, 0.01)
    pings = np.array([-0.02, -0.004, 0.0, 0.004, 0.006, 0.5, 1.0, 1.2])
    np.testing.assert_array_equal(ins.nearest_samples(t, pings),
                                  [-1, 0, 0, 0, 1, 50, 100, 100])
    lag = pings[2:6] - t[ins.nearest_samples(t, pings[2:6])]
    assert np.all(np.abs(lag) <= 0.005 + 1e-12)
    # One sample: every ping at or after it is its.
    np.testing.assert_array_equal(ins.nearest_samples(t[:1], pings), [-1, -1, 0, 0, 0, 0, 0, 0])


def _rest(n: int = 201):
    """A vehicle at rest for (n - 1) / 100 s, level, heading north: IMU at 100 Hz, a DVL
    reading zero at 1 Hz, and the start and instrument run_arrays takes."""
    t = np.arange(n) / 100.0
    f = np.tile([0.0, 0.0, -9.8], (n, 1))
    return dict(imu_time=t, specific_force=f, angular_rate=np.zeros((n, 3)),
                dvl_time=np.arange(0.0, t[-1] + 1e-9, 1.0),
                velocity=np.zeros((len(np.arange(0.0, t[-1] + 1e-9, 1.0)), 3)),
                start=ins.coarse_alignment(t, f, heading_deg=0.0),
                instrument=ins.Instrument(1e-4, 1e-6, 1e-4, 1e-7, 0.0, 0.0, np.full(3, 0.01)),
                gravity=9.8)


@pytest.mark.parametrize("change, said", [
    (lambda a: a["specific_force"].__setitem__((50, 0), np.nan),
     "specific_force: expected finite samples, got [nan, 0.0, -9.8] at sample 50 (t = 0.5 s);"),
    (lambda a: a.__setitem__("dvl_time", a["dvl_time"] + 300.0),
     "dvl_time: 3 ping(s) outside the IMU's span 0 to 2 s (the first at 300 s)"),
    (lambda a: a.__setitem__("dvl_time", a["dvl_time"] * 1000.0),
     "dvl_time: 2 ping(s) outside the IMU's span"),
    (lambda a: a.__setitem__("start", a["start"]._replace(time=5.0)),
     "start: its time 5 s is outside the IMU's span"),
    (lambda a: a.__setitem__("ping_row", np.arange(10)), "ping_row: expected (3,)"),
    (lambda a: a.__setitem__("valid", np.ones(5, bool)), "valid: expected shape (3,)"),
    (lambda a: a.__setitem__("mounting_rpy_deg", (0.0, 1.0)), "mounting_rpy_deg: expected 3"),
    (lambda a: a.__setitem__("start", a["start"]._replace(rotation=2 * np.eye(3))),
     "start.rotation: expected a 3 x 3 rotation matrix"),
    (lambda a: a.__setitem__("latitude_deg", 95.0), "latitude_deg: expected deg in [-90, 90]"),
    (lambda a: a.__setitem__("gravity", -9.8), "gravity: expected its magnitude in m/s^2"),
    # Gyros in deg/s, accelerometers in g: filtered, they had run to 651 m off.
    (lambda a: a["angular_rate"].__setitem__((slice(100, None), 2), 15.0),
     "angular_rate: reaches 15 rad/s at sample 100 (t = 1 s), beyond a full turn per "
     "second, as 50.2 % of the samples do; expected rad/s (in deg/s? np.radians them "
     "first)"),
    (lambda a: a.__setitem__("specific_force", a["specific_force"] / 9.80665),
     "specific_force: its median magnitude is 0.9993 m/s^2; expected about g"),
])
def test_run_arrays_names_a_bad_argument(change, said):
    """An argument the filter would take silently into a wrong answer (a NaN sample that
    made every later state NaN yet "accepted"; stamps in ms; a start outside the data) is
    refused, naming it and what is expected."""
    arrays = _rest()
    assert np.isfinite(ins.run_arrays(**arrays).position_ned).all()
    change(arrays)
    with pytest.raises(ValueError, match=re.escape(said)):
        ins.run_arrays(**arrays)


def test_ctrl_c_while_the_filter_runs_is_a_keyboard_interrupt():
    """From Python, with Python's own Ctrl-C handler: a signal that came while the
    compiled loop ran was handled as it handed back its arrays, inside numba's
    unpickling, and the call raised a chain of SystemErrors (or crashed). It is held
    until the loop has returned, and raised as the KeyboardInterrupt it is."""
    code = ("import os, signal, sys, threading, time\n"
            "import numpy as np\n"
            "from beamsnet.estimators import ins\n"
            "n = 100001\n"
            "t = np.arange(n) / 100.0\n"
            "f = np.tile([0.0, 0.0, -9.8], (n, 1))\n"
            "pings = np.arange(0.0, t[-1] + 1e-9, 1.0)\n"
            "arrays = dict(imu_time=t, specific_force=f, angular_rate=np.zeros((n, 3)),\n"
            "    dvl_time=pings, velocity=np.zeros((len(pings), 3)),\n"
            "    start=ins.coarse_alignment(t, f, heading_deg=0.0),\n"
            "    instrument=ins.Instrument(1e-4, 1e-6, 1e-4, 1e-7, 0.0, 0.0,\n"
            "                              np.full(3, 0.01)), gravity=9.8)\n"
            "ins.run_arrays(**arrays)  # compiled, or loaded from the cache\n"
            "started = time.perf_counter()\n"
            "ins.run_arrays(**arrays)\n"
            "took = time.perf_counter() - started\n"
            "threading.Timer(float(sys.argv[1]) * took, os.kill,\n"
            "                (os.getpid(), signal.SIGINT)).start()\n"
            "try:\n"
            "    for _ in range(20):\n"
            "        ins.run_arrays(**arrays)\n"
            "    print('ran to its end')\n"
            "except KeyboardInterrupt as e:\n"
            "    print('KeyboardInterrupt', type(e.__context__).__name__)\n")
    for share in (0.3, 0.7):  # into the first run of the loop
        done = subprocess.run([sys.executable, "-c", code, str(share)], capture_output=True,
                              text=True, timeout=300)
        assert (done.returncode, done.stdout) == (0, "KeyboardInterrupt NoneType\n"), \
            done.stderr[-2000:]


def test_run_arrays_filters_through_a_gyro_spike():
    """One sample beyond a turn per second is a glitch, not another unit: the run goes on."""
    arrays = _rest()
    arrays["angular_rate"][100, 2] = 15.0
    assert np.isfinite(ins.run_arrays(**arrays).position_ned).all()


def test_run_arrays_names_a_noise_of_the_wrong_length():
    """Three velocity-axis stds beside four beams was numpy's broadcasting traceback."""
    arrays = _rest()
    speed = arrays.pop("velocity")
    arrays["beams"] = speed @ beam_matrix(30.0).T
    arrays["beam_angle_deg"] = 30.0
    with pytest.raises(ValueError, match=re.escape(
            "instrument.measurement_std: expected one number or (4,), one per beam (the "
            "filter is given beams); got shape (3,)")):
        ins.run_arrays(**arrays)
    arrays["instrument"] = arrays["instrument"]._replace(measurement_std=0.01)
    assert np.isfinite(ins.run_arrays(**arrays).position_ned).all()
