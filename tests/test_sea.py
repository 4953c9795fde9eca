"""Scores against a reference (issue 24, item 4) and ``beamsnet reproduce sea`` (items 5, 9):
the scoring functions on known answers, the reference moved to the DVL, and the
estimators on recorded missions."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from auvsim.physics.frames import rotation_rpy
from beamsnet import metrics
from beamsnet.data import Windows, body_rate, quaternions_at, reference_velocity
from beamsnet.experiments.sea import DEFAULT_SEA, motion, watch_words
from beamsnet.navigation import earth_fixed_fit


def yawing(t: np.ndarray, rate: float) -> np.ndarray:
    """(T, 4) quaternions of a vehicle level and yawing at ``rate`` rad/s from north."""
    return np.stack([np.cos(rate * t / 2), 0 * t, 0 * t, np.sin(rate * t / 2)], axis=1)


def test_a_straight_track_with_a_known_drift_scores_its_known_errors():
    """North at 2 m/s for 400 s, the estimate drifting east at 1 cm/s: the error at t is
    0.01 t m, so final 4 m, RMSE 0.01 sqrt(mean t^2) over t = 0..400 s
    (mean t^2 = 400 x 801 / 6 s^2), and 4 m over 800 m travelled is 0.5 %."""
    t = np.arange(401.0)
    reference = np.stack([2.0 * t, 0 * t, 20 + 0 * t], axis=1)
    estimate = reference + np.stack([0 * t, 0.01 * t, 0.3 + 0 * t], axis=1)  # depth ignored
    scores = metrics.position_scores(estimate, reference)
    assert scores["final_m"] == pytest.approx(4.0, rel=1e-12)
    assert scores["rmse_m"] == pytest.approx(0.01 * math.sqrt(400 * 801 / 6), rel=1e-12)
    assert scores["distance_m"] == pytest.approx(800.0, rel=1e-12)
    assert scores["final_percent"] == pytest.approx(0.5, rel=1e-12)


def test_a_references_departure_from_its_own_velocities():
    """Positions that are the analytic integral of their velocities (north at a speed that
    grows linearly, east at a constant one: the trapezoids integrate both exactly) depart
    by 0; a fix that moves them 1.5 m east at 40 s departs by 1.5 m from there on."""
    from beamsnet.navigation import reference_departure

    t = np.arange(0.0, 80.0, 0.5)
    velocity = np.stack([1.0 + 0.01 * t, np.full_like(t, 0.3), 0 * t], axis=1)
    position = np.stack([t + 0.005 * t**2, 0.3 * t, 0 * t], axis=1) + [5.0, -2.0, 20.0]
    np.testing.assert_allclose(reference_departure(t, position, velocity), 0.0, atol=1e-12)
    fixed = position + np.where(t >= 40, 1.5, 0.0)[:, None] * [0.0, 1.0, 0.0]
    departure = reference_departure(t, fixed, velocity)
    np.testing.assert_allclose(departure[t < 40], 0.0, atol=1e-12)
    np.testing.assert_allclose(departure[t >= 40], 1.5, atol=1e-12)


def test_position_scores_refuse_mismatched_or_missing_rows():
    with pytest.raises(ValueError, match="shape of position"):
        metrics.position_scores(np.zeros((4, 3)), np.zeros((5, 3)))
    bad = np.zeros((4, 3))
    bad[2, 0] = np.nan
    with pytest.raises(ValueError, match="1 of 4 rows"):
        metrics.position_scores(bad, np.zeros((4, 3)))


def test_coverage_of_a_known_gaussian_error():
    """Errors drawn from N(0, sigma^2) and reported with that sigma lie within 3 sigma
    2 Phi(3) - 1 = 99.73 % of the time; two independent components both 99.73 %^2, their
    horizontal length within 3 sqrt(2) sigma 1 - e^-9; a filter that reports half its
    sigma covers 2 Phi(1.5) - 1 = 86.64 %."""
    rng = np.random.default_rng(0)
    n, sigma = 200_000, 0.7
    error = sigma * rng.standard_normal((n, 2))
    std = np.full((n, 2), sigma)
    within = 2 * 0.5 * (1 + math.erf(3 / math.sqrt(2))) - 1  # 0.99730
    tolerance = 5 * math.sqrt(within * (1 - within) / n)  # five binomial sd
    assert metrics.coverage(error[:, 0], std[:, 0]) == pytest.approx(within, abs=tolerance)
    assert metrics.coverage(error, std) == pytest.approx(within**2, abs=2 * tolerance)
    half = math.erf(1.5 / math.sqrt(2))
    assert metrics.coverage(error[:, 0], std[:, 0] / 2) == pytest.approx(
        half, abs=5 * math.sqrt(half * (1 - half) / n))
    # The horizontal radius (the filter's report): |e| <= 3 sqrt(sigma_N^2 + sigma_E^2),
    # |e|^2 / sigma^2 chi-square with 2 dof: 1 - exp(-18 / 2).
    radius = 1 - math.exp(-9)
    assert metrics.coverage(np.linalg.norm(error, axis=1), np.hypot(std[:, 0], std[:, 1])) \
        == pytest.approx(radius, abs=5 * math.sqrt(radius * (1 - radius) / n) + 1 / n)
    # Epochs without a sigma are not counted.
    std[: n // 2, 0] = np.nan
    assert metrics.coverage(error[:, 0], std[:, 0]) == pytest.approx(within, abs=2 * tolerance)


def test_the_body_rate_and_the_attitude_between_reference_samples():
    """A vehicle yawing at 0.3 rad/s (17 deg/s, the real segments' peaks), sampled at 1 Hz:
    the rate comes back exactly (every step is the same rotation), and the attitude half
    way between samples is the one at that time (nlerp of a 17 deg step: within 1e-4 rad
    of slerp, and slerp is exact here)."""
    t = np.arange(0.0, 30.0)
    q = yawing(t, 0.3)
    q[5:] *= -1  # the same attitudes, on the other hemisphere from sample 5 on
    mid = t[:-1] + 0.5
    np.testing.assert_allclose(body_rate(t, q, mid), np.tile([0, 0, 0.3], (len(mid), 1)),
                               atol=1e-12)
    got = quaternions_at(t, q, mid)
    want = yawing(mid, 0.3)
    angle = 2 * np.arccos(np.minimum(np.abs(np.sum(got * want, axis=1)), 1.0))
    assert angle.max() < 1e-4


class Fields(SimpleNamespace):
    """A group of a mission: its fields as attributes, ``in`` as the reader's."""

    def __contains__(self, name: str) -> bool:
        return name in vars(self)


def recorded_stub(t: np.ndarray, rate: float, speed: float, lever: np.ndarray,
                  mounting_yaw_deg: float, imu: bool) -> SimpleNamespace:
    """The parts of a recorded mission ``reference_velocity`` reads: a vehicle yawing at
    ``rate`` while flying forward at ``speed`` (body velocity (speed, 0, 0) at the
    reference point), its DVL at ``lever`` and yawed ``mounting_yaw_deg`` (30 deg beams)."""
    heading = rate * t
    imu_t = np.arange(0.0, t[-1], 0.01)
    groups = {"reference"} | ({"imu"} if imu else set())
    return SimpleNamespace(
        name="stub", has=groups.__contains__,
        reference=Fields(time=t, quaternion=yawing(t, rate), velocity_ned=np.stack(
            [speed * np.cos(heading), speed * np.sin(heading), 0 * t], axis=1)),
        imu=Fields(time=imu_t, angular_rate=np.tile([0, 0, rate], (len(imu_t), 1))),
        attrs={"dvl_position_body": lever,
               "dvl_mounting_rpy_deg": np.array([0.0, 0.0, mounting_yaw_deg]),
               "beam_angle_deg": 30.0})


@pytest.mark.parametrize("imu", [True, False])
def test_the_reference_velocity_at_the_dvl_is_the_body_velocity_plus_the_lever_arms(imu):
    """Forward at 2 m/s, yawing at 0.2 rad/s, the DVL 1.5 m aft and 0.3 m down, yawed
    45 deg: w x L = (0, 0, 0.2) x (-1.5, 0, 0.3) = (0, -0.3, 0) m/s in the body, so the
    body velocity at the DVL is (2, -0.3, 0), and the DVL frame sees it rotated by -45
    deg. The rate from the gyro or from the reference's attitudes gives the same."""
    t = np.arange(0.0, 20.0)
    lever = np.array([-1.5, 0.0, 0.3])
    m = recorded_stub(t, 0.2, 2.0, lever, 45.0, imu)
    pings = t[2:-2] + 0.25  # between the reference's samples
    got = reference_velocity(m, pings)
    c, s = math.cos(math.radians(45)), math.sin(math.radians(45))
    body = np.array([2.0, -0.3, 0.0])
    want = np.array([c * body[0] + s * body[1], -s * body[0] + c * body[1], 0.0])
    # Interpolated in the body frame, where a steady turn's velocity is constant: exact.
    np.testing.assert_allclose(got, np.tile(want, (len(pings), 1)), atol=1e-12)


LATITUDE, LONGITUDE, HEIGHT = 32.85, 34.95, -20.0  # deg, deg, m: off Haifa, 20 m down
SURGE, OMEGA = 0.3, 2 * math.pi / 60  # m/s and rad/s of the speed's swing


def write_akit(folder: Path, k: int, *, sway_bias: float = 0.01, scale: float = 0.0,
               surge: float = SURGE, weave_deg_s: float = 0.0, duration: int = 120) -> Path:
    """A segment in the A-KIT layout (``TrajectoryK/{IMU,DVL,GT}_trajectoryK.csv``): a
    level vehicle flying forward at 1.5 m/s, ``surge`` m/s up and down over a minute,
    heading north, or weaving about it at a yaw rate of ``weave_deg_s`` sin(2 pi t / 40
    s); its IMU reading that motion in the Earth's gravity (WGS-84 normal gravity there),
    its DVL the body velocity with a scale factor error ``scale`` forward and a bias of
    ``sway_bias`` m/s to starboard; the reference exact (positions integrated at 100 Hz).
    """
    from auvsim.physics.earth import earth_rate_ned, normal_gravity, radii

    segment = folder / f"Trajectory{k}"
    segment.mkdir(parents=True)
    t = np.arange(0, duration * 100) / 100.0
    zero = 0 * t
    u, du = 1.5 + surge * np.sin(OMEGA * t), surge * OMEGA * np.cos(OMEGA * t)
    r0, weave = math.radians(weave_deg_s), 2 * math.pi / 40
    rate = r0 * np.sin(weave * t)
    heading = r0 / weave * (1 - np.cos(weave * t))
    # The Earth's rate and the Coriolis term in NED (Groves eqs. 2.133 and 5.54; the
    # transport rate, v / R = 2e-7 rad/s, left out), seen in the level body yawed by
    # ``heading``: the gyro reads C^T w_ie + (0, 0, r), the accelerometers
    # C^T (2 w_ie x v) + (du, u r, -g).
    v_north, v_east = u * np.cos(heading), u * np.sin(heading)
    w_ie = earth_rate_ned(LATITUDE)
    coriolis = 2 * np.cross(w_ie, np.column_stack([v_north, v_east, zero]))
    c, s_ = np.cos(heading), np.sin(heading)

    def body(x):  # C^T x for a level body at ``heading``
        return np.column_stack([c * x[:, 0] + s_ * x[:, 1], -s_ * x[:, 0] + c * x[:, 1],
                                x[:, 2]])

    force = body(coriolis) + np.column_stack(
        [du, u * rate, zero - normal_gravity(LATITUDE, HEIGHT)])
    gyro = body(np.tile(w_ie, (len(t), 1))) + np.column_stack([zero, zero, rate])
    imu = np.column_stack([t, force, gyro])
    north, east = (np.concatenate([[0.0], np.cumsum((v[1:] + v[:-1]) / 2 * 0.01)])
                   for v in (v_north, v_east))
    i = np.arange(0, len(t), 100)  # the 1 Hz stamps
    meridian, transverse = radii(LATITUDE)
    lat = np.radians(LATITUDE) + north[i] / (meridian + HEIGHT)
    lon = np.radians(LONGITUDE) + east[i] / ((transverse + HEIGHT)
                                             * math.cos(math.radians(LATITUDE)))
    gt = np.column_stack([t[i], lon, lat, HEIGHT + zero[i], v_north[i], v_east[i], zero[i],
                          zero[i], zero[i], heading[i]])
    dvl = np.column_stack([t[i], (1 + scale) * u[i], sway_bias + zero[i], zero[i]])
    heads = {"IMU": "Time [s],ACC X [m/s^2],ACC Y [m/s^2],ACC Z [m/s^2],GYRO X [rad/s],"
                    "GYRO Y [rad/s],GYRO Z [rad/s]",
             "DVL": "Time [s],DVL X [m/s],DVL Y [m/s],DVL Z [m/s]",
             "GT": "Time [s],Longitude [rad],Latitude [rad],Altitude [m],V North [m/s],"
                   "V East [m/s],V Down [m/s],Roll [rad],Pitch [rad],Yaw [rad]"}
    for kind, table in (("IMU", imu), ("DVL", dvl), ("GT", gt)):
        np.savetxt(segment / f"{kind}_trajectory{k}.csv", table, delimiter=",",
                   header=heads[kind], comments="", fmt="%.17g")
    return segment


@pytest.fixture
def recorded(tmp_path) -> Path:
    """A dataset of one recorded mission, ``trajectory1``, imported as the user would."""
    from auvsim.data.recorded import import_logs

    logs = tmp_path / "logs"
    write_akit(logs, 1, surge=0.0)
    import_logs([logs], tmp_path / "sea.h5", format="akit")
    return tmp_path / "sea.h5"


def test_estimate_on_a_recorded_mission_scores_against_the_reference(recorded, tmp_path,
                                                                      capsys):
    """Due north at 1.5 m/s, the DVL 1 cm/s to starboard: LS's velocity error is 1 cm/s,
    and dead-reckoned with the reference's attitude from the fourth ping (t = 3 s) to the
    last (119 s) it ends 0.01 x 116 = 1.16 m east of the reference, 1.16 / (1.5 x 116)
    = 0.667 % of the distance."""
    from beamsnet.cli import main

    out = tmp_path / "ls"
    assert main(["estimate", str(recorded), "--estimator", "LS", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "scored against the reference: Delph INS" in said and "truth" not in said
    assert "derived as H v" in said
    summary = json.loads((out / "summary.json").read_text())
    assert summary["against"].startswith("the reference: ")
    assert summary["beams_derived"] == ["trajectory1"]
    row = summary["missions"]["trajectory1"]
    assert row["rmse_vector"] == pytest.approx(0.01, rel=1e-6)
    assert row["position"]["final_m"] == pytest.approx(1.16, abs=5e-3)
    assert row["position"]["distance_m"] == pytest.approx(1.5 * 116, rel=1e-6)
    assert row["position"]["final_percent"] == pytest.approx(100 * 0.01 / 1.5, rel=5e-3)
    # The error grows as 0.01 (t - 3): RMSE 0.01 sqrt(mean k^2) over k = 0..116 s.
    assert row["position"]["rmse_m"] == pytest.approx(0.01 * math.sqrt(116 * 233 / 6),
                                                      abs=5e-3)
    # LS's velocity is the DVL's own (LS of H v is v): its baseline scores the same.
    assert row["baselines"]["DR: DVL + reference attitude"] == pytest.approx(row["position"])
    header = (out / "estimates.csv").read_text().splitlines()[0].split(",")
    assert header == ["mission", "time", "vx", "vy", "vz", "reference_vx", "reference_vy",
                      "reference_vz"]  # LS has no position of its own


def reproduce_sea(data: Path, tmp_path: Path, monkeypatch) -> tuple[dict, str]:
    """``beamsnet reproduce sea`` on ``data`` at a tiny size (20 s per manoeuvre, one
    seed, one epoch); its sea.json and sea.md."""
    from beamsnet.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["reproduce", "sea", "--data", str(data), "--duration", "20", "--seeds", "1",
                 "--epochs", "1", "--out", "report", "--quiet"]) == 0
    assert (tmp_path / "report" / "sea.png").stat().st_size > 10_000
    return (json.loads((tmp_path / "report" / "sea.json").read_text()),
            (tmp_path / "report" / "sea.md").read_text())


@pytest.mark.slow
def test_reproduce_sea_scores_every_segment_against_its_reference(tmp_path, monkeypatch):
    """Three weaving segments the test writes, the DVL reading 0, 1 and 2 % fast (a scale
    factor check-log reports and leaves in the velocity): the dead-reckoning baseline's
    velocity error is that share of the speed, and its final error that share of the
    displacement, give or take what holding each velocity over its second costs (the
    exact DVL's final error); every estimator a row; the medians; no word of truth."""
    logs = tmp_path / "logs"
    for k, scale in enumerate((0.0, 0.01, 0.02), start=1):
        write_akit(logs, k, sway_bias=0.0, scale=scale, weave_deg_s=3.0)
    results, report = reproduce_sea(logs, tmp_path, monkeypatch)
    segments = results["segments"]
    assert list(segments) == ["trajectory1", "trajectory2", "trajectory3"]
    pings = np.arange(3.0, 120.0)
    speed = 1.5 + SURGE * np.sin(OMEGA * pings)
    held = segments["trajectory1"]["DR: DVL + reference attitude"]["final_m"]
    for name, scale in (("trajectory2", 0.01), ("trajectory3", 0.02)):
        baseline = segments[name]["DR: DVL + reference attitude"]
        assert baseline["velocity_rmse"] == pytest.approx(
            scale * math.sqrt(np.mean(speed**2)), rel=1e-3)
        # Displacement from 3 s to 119 s: weaving 2 x 3 deg/s / (2 pi / 40 s) = 38 deg
        # at most, the track is nearly straight: at most the distance, at least its
        # cosine of 19 deg.
        distance = baseline["distance_m"]
        assert (0.94 * scale * distance - held - 1e-3 <= baseline["final_m"]
                <= scale * distance + held + 1e-3)
        for label in ("LS", "Affine", "Robust LS", "CorrectionNet (seed_0)",
                      "Affine (other segments)"):
            assert np.isfinite(segments[name][label]["velocity_rmse"])
    assert held < 0.5
    for scores in segments.values():  # clean logs: every ping's measurement but the first's
        for label in ("INS/DVL", "INS/DVL (simulated instrument's noise)"):
            assert scores[label]["availability"] == pytest.approx(119 / 120)
            assert scores[label]["events"] == []
    assert "INS/DVL 99.2 % (lowest 99.2 %" in report and "restarted none of them" in report
    assert "Whether each filter's innovations are as large as it predicts" in report
    for scores in segments.values():
        assert scores["INS/DVL"]["windows"] == 12 and 0 < scores["INS/DVL"]["mean_nis"] < 2
    assert "| **median** |" in report
    ours = "\n".join(line for line in report.splitlines()  # not the errors it quotes
                      if not line.startswith("Filters that did not run"))
    assert "against the reference: Delph INS" in report and "truth" not in ours
    assert "derived** as `H v`" in report and "## Sim-to-real" in report
    assert "| auvsim, held out |" in report and "CorrectionNet: departure from LS" in report
    assert set(results["motion"]) == set(segments)


def _windows(beams: np.ndarray, past: np.ndarray) -> Windows:
    n = len(beams)
    return Windows(beams, past, None, None, np.zeros((n, 3)), np.tile([1.0, 0, 0], (n, 1)),
                   np.zeros(n, np.int64), np.arange(n, dtype=float), ("m",), np.eye(4, 3))


def test_motion_against_the_training_range_on_known_pings():
    """Training pings span beams 0..1 and changes from the past ping 0..0.1. Of four test
    pings (beams 0.5), one has a beam at 1.5, one changes by 0.2, one has a missing beam
    (never outside) and changes 0.05, one changes 0: half lie outside. The changes' RMS
    is over the 15 values there are: 0.05 on 4 + 3 beams, 0.2 on 4, 0 on 4."""
    rng = np.random.default_rng(0)
    beams = rng.uniform(0, 1, (200, 4))
    beams[0], beams[1] = 0.0, 1.0
    train = _windows(beams, beams[:, None, :] + np.linspace(0, 0.1, 200)[:, None, None])
    test_beams = np.full((4, 4), 0.5)
    past = test_beams[:, None, :] + np.array([0.05, 0.2, 0.05, 0.0])[:, None, None]
    test_beams[0, 2], past[0, 0, 2] = 1.5, 1.55  # a beam beyond the training's
    test_beams[2, 1] = np.nan  # a missing beam: no change there either
    m = motion(_windows(test_beams, past), train)
    assert m["pings"] == 4 and m["outside"] == 0.5  # pings 0 (a beam) and 1 (a change)
    assert m["change_rms"] == pytest.approx(math.sqrt((7 * 0.05**2 + 4 * 0.2**2) / 15))
    assert m["speed"] == 1.0


def test_the_reports_say_what_each_filters_divergence_watch_did():
    results = {"a": {"scores": {"F": {"availability": 0.5, "events": ["at 10 s: restarted"]},
                                "G": {"availability": 0.9}}},  # not a filter's: no events
               "b": {"scores": {"F": {"availability": 1.0, "events": []}}}}
    [words] = watch_words(results, ("F", "G"))
    assert "median over the 2 missions: F 75.0 % (lowest 50.0 %, a)." in words
    assert "G " not in words
    assert words.endswith("restarted them 1 time: F on a: at 10 s: restarted.")
    results["a"]["scores"]["F"]["events"] = []
    assert watch_words(results, ("F",))[0].endswith("restarted none of them.")
    assert watch_words(results, ("G",)) == []


SHARED = DEFAULT_SEA


@pytest.mark.slow
@pytest.mark.skipif(not SHARED.is_dir(), reason="the shared A-KIT segments are not here")
def test_reproduce_sea_on_the_shared_segments(tmp_path, monkeypatch):
    """The six Snapir segments: every one scored; the DVL dead-reckoned with the
    reference's attitude stays within 2 % of the distance travelled (a Navigator's
    velocity accuracy is 0.2 % of speed, its publication's 0.02 m/s std 1.3 % of 1.5 m/s)."""
    results, report = reproduce_sea(SHARED, tmp_path, monkeypatch)
    assert len(results["segments"]) == len(list(SHARED.glob("Trajectory*")))
    for scores in results["segments"].values():
        assert scores["DR: DVL + reference attitude"]["final_percent"] < 2.0
    assert "| **median** |" in report and "truth" not in report


def test_evaluate_on_a_recorded_mission_adds_the_position_scores(tmp_path, capsys):
    """The test split (the last 30 of 117 pings, 90 to 119 s): LS dead-reckoned with the
    reference's attitude drifts 0.01 m/s x 29 s = 0.29 m east (and north, holding each
    velocity over its second, (v(90 s) - v(119 s)) x 1 s / 2), as its baseline does, and
    the tables say what they are against."""
    from auvsim.data.recorded import import_logs
    from beamsnet.cli import main

    write_akit(tmp_path / "logs", 1)  # the speed swings: the calibrations have a fit
    recorded = tmp_path / "sea.h5"
    import_logs([tmp_path / "logs"], recorded, format="akit")
    run = tmp_path / "corr"
    assert main(["train", str(recorded), "--model", "corr", "--epochs", "1", "--out", str(run),
                 "--quiet"]) == 0
    assert main(["evaluate", str(run), str(recorded), "--out", str(tmp_path / "ev")]) == 0
    said = capsys.readouterr()
    assert "against the reference: Delph INS" in said.out and "truth" not in said.out
    result = json.loads((tmp_path / "ev" / "evaluation.json").read_text())[str(recorded)]
    rows = result["navigation"]["trajectory1"]
    north = (math.sin(OMEGA * 90) - math.sin(OMEGA * 119)) * SURGE / 2
    assert rows["LS"]["final_m"] == pytest.approx(math.hypot(0.29, north), abs=2e-3)
    assert rows["DR: DVL + reference attitude"] == pytest.approx(rows["LS"])
    assert np.isfinite(rows["CorrectionNet (corr)"]["final_m"])
    # The filter's own track, its 3 sigma, the baseline with its attitude, and its watch.
    assert rows["INS/DVL"]["coverage_3sigma"] == 1.0
    assert rows["DR: DVL + filter attitude (INS/DVL)"]["final_m"] == pytest.approx(
        rows["LS"]["final_m"], abs=0.01)  # its attitude all but the reference's
    watch = result["watch"]["INS/DVL"]["trajectory1"]
    assert watch["availability"] == 1.0 and watch["events"] == []
    assert watch["windows"] == 12 and watch["windows_above"] == 0  # 120 pings, exact logs
    assert ("INS/DVL, what its divergence watch saw (a restart when its gate keeps "
            "rejecting the measurements): trajectory1 100.0 % of the mission's pings "
            f"accepted, no restart, mean NIS {watch['mean_nis']:.2f} (1 where its covariance "
            f"is right; {watch['gated_nis']:.2f} with each capped at the gate, which an "
            "outlier moves little), 0 of 12 windows of 10 pings beyond the chi-square 99.9 % "
            "bound.") in (tmp_path / "ev" / "evaluation.md").read_text()


def test_estimate_on_a_log_without_a_reference_runs_unscored(tmp_path, capsys):
    """The weaving segment with its reference group taken out: the filter starts from a
    coarse alignment on the heading its settings give (north, the segment's own) and its
    track follows the one it makes from the reference's start; LS runs; neither is
    scored; an estimator fitted on a reference, and training, are refused in one line."""
    from auvsim.data.recorded import import_logs
    from beamsnet.cli import main

    write_akit(tmp_path / "logs", 1, weave_deg_s=3.0)
    recorded, blind = tmp_path / "sea.h5", tmp_path / "blind.h5"
    import_logs([tmp_path / "logs"], recorded, format="akit")
    shutil.copy(recorded, blind)
    with h5py.File(blind, "r+") as f:
        m = f["missions/trajectory1"]
        del m["reference"]
        m.attrs["groups"] = json.dumps(["imu", "dvl"])
    settings = tmp_path / "north.toml"
    settings.write_text("start_heading_deg = 0.0\nstart_heading_std_deg = 0.5\n")
    runs = {}
    for name, path, more in (("referenced", recorded, []),
                             ("blind", blind, ["--filter-config", str(settings)])):
        assert main(["estimate", str(path), "--estimator", "INS/DVL", "--out",
                     str(tmp_path / name), *more]) == 0
        runs[name] = np.loadtxt(tmp_path / name / "estimates.csv", delimiter=",",
                                skiprows=1, usecols=range(1, 8 if name == "blind" else 11))
    said = capsys.readouterr().out
    assert "INS/DVL on " + str(blind) + ", not scored: the log has no reference" in said
    assert "its beams are used as measured" in said
    assert (tmp_path / "blind" / "estimates.csv").read_text().startswith(
        "mission,time,vx,vy,vz,north_m,east_m,down_m\n")
    referenced, aligned = runs["referenced"], runs["blind"]
    np.testing.assert_array_equal(aligned[:, 0], referenced[:, 0])  # every ping's time
    # The reference's start is its first point, the alignment's the origin: the same.
    # Levelled less the acceleration the DVL shows (the vehicle speeds up and weaves as
    # the IMU is averaged: 3 to 5 mrad of tilt otherwise, and two restarts), the start
    # needs no restart; the velocities agree within 5 mm/s, the tracks within 0.2 m.
    drift = np.linalg.norm(aligned[:, 4:6] - referenced[:, 7:9], axis=1)
    assert drift.max() < 0.2, drift.max()
    np.testing.assert_allclose(aligned[:, 1:4], referenced[:, 1:4], atol=0.005)
    summary = json.loads((tmp_path / "blind" / "summary.json").read_text())
    assert summary["missions"]["trajectory1"]["events"] == []
    assert "position" not in summary["missions"]["trajectory1"]
    assert main(["estimate", str(blind), "--estimator", "LS", "--out",
                 str(tmp_path / "ls")]) == 0
    for args in (["estimate", str(blind), "--estimator", "Affine", "--out",
                  str(tmp_path / "affine")],
                 ["train", str(blind), "--model", "corr", "--out", str(tmp_path / "net")]):
        assert main(args) == 2
        assert "a log without a reference" in capsys.readouterr().err
        assert not (tmp_path / args[-1]).exists()


class OwnTrack:
    """An estimator with tracks of its own, as the INS/DVL filter has: its position the
    reference's plus 1 m east, its reported sigma ``sigma`` per axis, its attitude the
    reference's (so the baseline with its attitude is the one with the reference's)."""

    name = "own"

    def __init__(self, dataset: Path, sigma: float) -> None:
        from auvsim.data.reader import open_dataset
        from auvsim.physics.frames import rotation_matrices

        with open_dataset(dataset) as f:
            ref = f.missions["trajectory1"].reference
            self.track = SimpleNamespace(
                ping_time=ref.time, rotation=rotation_matrices(ref.quaternion),
                position_ned=ref.position_ned + [0.0, 1.0, 0.0],
                position_std=np.full((len(ref.time), 3), sigma))

    def tracks(self, windows):
        return {"trajectory1": self.track}


@pytest.mark.parametrize("sigma, covered", [(0.5, 1.0), (0.2, 0.0)])
def test_own_position_sigma_and_attitude_from_an_estimators_tracks(recorded, sigma, covered):
    """1 m off, reported 0.5 m per axis: within 3 sqrt(2) 0.5 = 2.1 m always; 0.2 m per
    axis: 0.85 m, never. The dead reckoning with its attitude (the reference's) scores as
    the one with the reference's."""
    from beamsnet.data import load_windows
    from beamsnet.evaluate import navigation_scores, own_rotations, reported_stds
    from beamsnet.navigation import truth_at_pings

    windows = load_windows(recorded)
    truth = truth_at_pings(recorded, windows)
    own = OwnTrack(recorded, sigma)
    position = own.track.position_ned[np.searchsorted(own.track.ping_time, windows.time)]
    rows = navigation_scores(windows, {"own": windows.velocity_ls}, truth,
                             positions={"own": position}, stds=reported_stds(own, windows),
                             rotations=own_rotations(own, windows))["trajectory1"]
    assert rows["own"]["final_m"] == pytest.approx(1.0, abs=1e-9)
    assert rows["own"]["rmse_m"] == pytest.approx(1.0, abs=1e-9)
    assert rows["own"]["coverage_3sigma"] == covered
    assert rows["DR: DVL + filter attitude"] == pytest.approx(
        rows["DR: DVL + reference attitude"], abs=1e-9)
    # Scored from its first sample, as the dead reckonings are (a test split starts
    # mid-mission): it moved exactly as the reference did, 0 m off; what its sigma covers
    # is still its own position's 1 m.
    since = navigation_scores(windows, {"own": windows.velocity_ls}, truth,
                              positions={"own": position}, stds=reported_stds(own, windows),
                              since_first=True)["trajectory1"]
    assert since["own"]["final_m"] == pytest.approx(0.0, abs=1e-9)
    assert since["own"]["rmse_m"] == pytest.approx(0.0, abs=1e-9)
    assert since["own"]["coverage_3sigma"] == covered
    assert since["DR: DVL + reference attitude"] == rows["DR: DVL + reference attitude"]


def test_the_filter_on_a_recorded_mission_writes_its_own_track(tmp_path, capsys):
    """The INS/DVL filter: ``estimates.csv`` carries its position in the mission's local
    frame (``north_m``, ``east_m``, ``down_m``), the summary its scores with the 3-sigma
    coverage and both dead-reckoning baselines, against the reference."""
    from auvsim.data.recorded import import_logs
    from beamsnet.cli import main

    write_akit(tmp_path / "logs", 1)  # the speed swings: its beam calibration has a fit
    recorded = tmp_path / "sea.h5"
    import_logs([tmp_path / "logs"], recorded, format="akit")
    out = tmp_path / "ins"
    assert main(["estimate", str(recorded), "--estimator", "INS/DVL", "--out", str(out)]) == 0
    assert "truth" not in capsys.readouterr().out
    rows = (out / "estimates.csv").read_text().splitlines()
    header = rows[0].split(",")
    assert header[:2] == ["mission", "time"] and header[-3:] == ["north_m", "east_m", "down_m"]
    first = dict(zip(header, rows[1].split(","), strict=True))
    # The fourth ping, 3 s after the start from the reference's first point:
    # 1.5 x 3 + (0.3 / OMEGA)(1 - cos(3 OMEGA)) m north.
    north = 1.5 * 3 + SURGE / OMEGA * (1 - math.cos(3 * OMEGA))
    assert float(first["north_m"]) == pytest.approx(north, abs=0.05)
    summary = json.loads((out / "summary.json").read_text())
    row = summary["missions"]["trajectory1"]
    # A right covariance holds the horizontal error within 3 sqrt(sigma_N^2 + sigma_E^2)
    # at least 98.9 % of the time; on this segment (an exact reference, a noise-free IMU,
    # the DVL off by a steady 1 cm/s to starboard) it holds at every one of the 117 pings
    # (measured): at most one may miss. (0 <= coverage <= 1 failed only on NaN.)
    assert row["position"]["coverage_3sigma"] >= 0.99
    assert set(row["baselines"]) == {"DR: DVL + reference attitude",
                                     "DR: DVL + filter attitude"}


def test_no_reference_velocity_beyond_the_references_span():
    """A ping after the reference's last sample (a DVL clock check-log moved past it) has
    no target: NaN, never the last sample held."""
    t = np.arange(0.0, 20.0)
    m = recorded_stub(t, 0.2, 2.0, np.zeros(3), 0.0, imu=False)
    got = reference_velocity(m, np.array([-0.5, 0.0, 19.0, 19.5]))
    assert np.isnan(got[[0, 3]]).all() and np.isfinite(got[[1, 2]]).all()


def _turning(n: int, rate: float):
    """A mission's windows of ``n`` pings at 1 Hz, turning at ``rate`` (rad/s) from
    heading 0: (windows, heading (n,) rad, body -> NED rotation (n, 3, 3))."""
    t = np.arange(float(n))
    heading = rate * t
    rotation = np.zeros((n, 3, 3))
    rotation[:, 0, 0], rotation[:, 0, 1] = np.cos(heading), -np.sin(heading)
    rotation[:, 1, 0], rotation[:, 1, 1] = np.sin(heading), np.cos(heading)
    rotation[:, 2, 2] = 1.0
    return SimpleNamespace(mission=np.zeros(n, dtype=int), time=t), heading, rotation


def test_dead_reckoning_moves_the_dvls_velocity_to_the_reference_point():
    """Turning at 0.1 rad/s at 1.5 m/s with the DVL 1.85 m aft: the DVL reads the
    origin's (1.5, 0, 0) plus w x L = (0, -0.185, 0) m/s. Moved back by M v - w x L, its
    track is the origin's, step for step, to round-off."""
    from beamsnet.navigation import dead_reckoning_positions

    n, rate = 60, 0.1
    windows, heading, rotation = _turning(n, rate)
    truth = dict(rotation=rotation, mounting=np.tile(np.eye(3), (n, 1, 1)),
                 position=np.zeros((n, 3)), body_rate=np.tile([0.0, 0.0, rate], (n, 1)),
                 lever=np.tile([-1.85, 0.0, 0.0], (n, 1)))
    at_origin = np.tile([1.5, 0.0, 0.0], (n, 1))
    at_dvl = at_origin + np.cross(truth["body_rate"], truth["lever"])
    np.testing.assert_allclose(at_dvl[0], [1.5, -0.185, 0.0])
    origin = dead_reckoning_positions(windows, at_origin, dict(truth, lever=0 * truth["lever"]),
                                      0)
    np.testing.assert_allclose(dead_reckoning_positions(windows, at_dvl, truth, 0), origin,
                               atol=1e-12)


def test_dead_reckoning_against_a_position_integrates_by_the_trapezoid_rule():
    """A circle at 2 m/s and 15 deg/s, 1 Hz pings: the trapezoid rule's track is the true
    one with each step's chord shortened by (theta/2) cot(theta/2), theta = 15 deg the turn
    over a step, to round-off. The rectangle rule (each velocity held to the next ping)
    lags half a ping and after the half turn stands over 1.9 m (about v dt) off."""
    from beamsnet.navigation import dead_reckoning_positions, dead_reckoning_track

    n, speed, rate = 13, 2.0, np.radians(15.0)
    windows, heading, rotation = _turning(n, rate)
    true = speed / rate * np.stack([np.sin(heading), 1 - np.cos(heading), 0 * heading],
                                   axis=1)
    truth = dict(rotation=rotation, mounting=np.tile(np.eye(3), (n, 1, 1)), position=true,
                 body_rate=np.zeros((n, 3)), lever=np.zeros((n, 3)))
    velocity = np.tile([speed, 0.0, 0.0], (n, 1))
    half = rate / 2  # theta / 2 over a 1 s step
    np.testing.assert_allclose(dead_reckoning_positions(windows, velocity, truth, 0),
                               true * half / np.tan(half), atol=1e-12)
    held = dead_reckoning_track(windows, velocity, truth, 0)
    assert np.linalg.norm(held[-1] - true[-1]) > 1.9
    assert np.linalg.norm(true[-1] * (1 - half / np.tan(half))) < 0.1


def test_the_imported_segments_are_made_again_when_the_built_in_description_changes(
        tmp_path, monkeypatch):
    """The cached import is keyed by the logs' digests and by the description that read
    them: new instrument specifications must reach the estimators."""
    import auvsim.data.recorded as recorded
    from auvsim.data.reader import open_dataset
    from beamsnet.experiments.sea import sea_dataset

    logs = tmp_path / "logs"
    write_akit(logs, 1, weave_deg_s=8.0)
    sea_dataset(logs, tmp_path)
    logged = tmp_path / "sea-logged.h5"
    made = logged.stat().st_mtime_ns
    sea_dataset(logs, tmp_path)
    assert logged.stat().st_mtime_ns == made  # same logs, same description: reused
    changed = recorded.AKIT_DESCRIPTION.replace("velocity_accuracy = 0.02",
                                                "velocity_accuracy = 0.03")
    assert changed != recorded.AKIT_DESCRIPTION
    monkeypatch.setattr(recorded, "AKIT_DESCRIPTION", changed)
    sea_dataset(logs, tmp_path)
    with open_dataset(logged) as f:
        assert f.missions["trajectory1"].attrs["log_description"] == changed.replace("{k}", "1")


def test_a_recorded_mission_whose_pings_miss_the_reference_is_refused_in_one_line(tmp_path):
    """Every ping outside the reference's span leaves nothing to score against: said so,
    not divided by zero further on."""
    import h5py

    from auvsim.data.recorded import import_logs
    from beamsnet.data import DataError, load_windows

    write_akit(tmp_path / "logs", 1)
    path = tmp_path / "late.h5"
    import_logs([tmp_path / "logs"], path, format="akit")
    with h5py.File(path, "r+") as f:
        f["missions/trajectory1/dvl/time"][...] += 1000.0  # a clock far off
    for every_ping in (False, True):
        with pytest.raises(DataError, match="no ping lies within the reference's time span"):
            load_windows(path, every_ping=every_ping)


def test_earth_fixed_fit_tells_a_current_from_an_instrument_error():
    """Known answer: a vehicle turning through two circles, its DVL (mounted 10 deg off in
    yaw) reading 12 mm/s north and 5 mm/s east that do not turn with it beside 7 mm/s
    along its x and -3 mm/s along its y that do, with 1 mm/s of white noise: the fit
    gives both back to 0.3 mm/s and leaves the noise; on a straight line the two cannot
    be told apart: each alone leaves what both do, and the split is not given."""
    rng = np.random.default_rng(3)
    heading = np.linspace(0.0, 4 * math.pi, 400)
    pitch = np.radians(5.0) * np.sin(heading / 3)  # diving and climbing as it turns
    body = np.stack([rotation_rpy(0.0, p, h) for p, h in zip(pitch, heading, strict=True)])
    turn = body @ rotation_rpy(0.0, 0.0, math.radians(10.0))  # DVL -> NED
    earth, own = np.array([0.012, 0.005, 0.0]), np.array([0.007, -0.003, 0.0])
    difference = (np.einsum("sji,j->si", turn, earth) + own
                  + 0.001 * rng.standard_normal((len(heading), 3)))
    fit = earth_fixed_fit(difference, turn)
    np.testing.assert_allclose([fit["north"], fit["east"], fit["x"], fit["y"]],
                               [0.012, 0.005, 0.007, -0.003], atol=3e-4)
    assert fit["rms_both"] == pytest.approx(0.001, rel=0.1)
    assert fit["rms_dvl"] > 9 * fit["rms_both"] and fit["rms_ned"] > 5 * fit["rms_both"]
    straight = earth_fixed_fit(difference[:50], np.repeat(turn[:1], 50, axis=0))
    assert straight["rms_ned"] == pytest.approx(straight["rms_both"], rel=1e-9)
    assert straight["rms_dvl"] == pytest.approx(straight["rms_both"], rel=1e-9)
    assert math.isnan(straight["north"]) and math.isnan(straight["y"])
    assert math.isnan(earth_fixed_fit(difference[:2], turn[:2])["rms"])


def test_dead_reckoning_turns_a_mounted_dvls_velocity_into_the_body():
    """Level, heading north, 1 m/s ahead, the DVL yawed 45 deg on the body: it reads
    M^T (1, 0, 0), and 10 s later the track is 10 m north."""
    from beamsnet.navigation import dead_reckoning_track

    n = 11
    m = rotation_rpy(0.0, 0.0, math.radians(45.0))  # DVL -> body
    truth = dict(rotation=np.tile(np.eye(3), (n, 1, 1)), mounting=np.tile(m, (n, 1, 1)))
    v_dvl = np.tile(m.T @ [1.0, 0.0, 0.0], (n, 1))
    track = dead_reckoning_track(_windows(np.zeros((n, 4)), np.zeros((n, 1, 4))), v_dvl,
                                 truth, 0)
    np.testing.assert_allclose(track[-1], [10.0, 0.0, 0.0], atol=1e-12)
