"""Navigation from velocity estimates: the truth at each ping, dead reckoning, position
errors, and holding an estimate through the pings an estimator gives none for.

The lowest floor of beamsnet's scoring: ``evaluate``, ``estimate`` and the experiments
score dead reckoning with these, and they depend on nothing of beamsnet's but its
windows (``beamsnet.data``). Positions are m NED, velocities m/s in the DVL frame, times
s; a mission is an index into ``windows.names``.
"""

from __future__ import annotations

import os

import numpy as np

from auvsim.data.checklog import cumulative
from auvsim.data.reader import open_dataset, require_attitude
from auvsim.physics.frames import rotation_matrices, rotation_rpy
from beamsnet import metrics
from beamsnet.data import DataError, Windows, quaternions_at, recorded_body_rate


def truth_at_pings(path: str | os.PathLike, windows: Windows) -> dict[str, np.ndarray]:
    """Per sample of ``windows``: the true body->NED rotation (S, 3, 3), DVL->body mounting
    (S, 3, 3), yaw rate (S, deg/s), the rate of change of the true DVL-frame velocity since
    the previous ping (S,), the true position (S, 3, m NED), and for moving a DVL velocity
    to the body origin the body rate (``body_rate``, S, 3, rad/s) and the DVL's lever arm
    (``lever``, S, 3, m, body).

    For a recorded mission the same from its reference (``reference_source``), at the
    pings' times: attitude and position interpolated (``beamsnet.data.quaternions_at``),
    the yaw rate from the gyro (or the reference's attitude), the velocity's change from
    the reference DVL velocity of ``windows.target``. Nothing here calls it truth but the
    caller's words: ``windows.reference`` says what it is.
    """
    parts = {k: [] for k in ("rotation", "mounting", "yaw_rate", "acceleration", "position",
                             "body_rate", "lever")}
    with open_dataset(path) as f:
        for i, name in enumerate(windows.names):
            m = f.missions[name]
            mine = windows.mission == i
            if m.origin == "recorded":
                for key, value in _reference_at(m, windows.time[mine],
                                                windows.target[mine]).items():
                    parts[key].append(value)
                continue
            if not m.has("truth"):
                raise DataError(f"{path}: mission {name} has no truth group (an imported "
                                "stream); dead reckoning is scored against a simulated truth "
                                "or a recorded reference")
            ping = np.searchsorted(m.dvl.time, windows.time[mine])
            rows = m.imu.index_of_dvl[ping]
            rate = float(m.attrs["dvl_rate_hz"])
            v_dvl = m.dvl.velocity
            parts["rotation"].append(rotation_matrices(m.truth.quaternion[rows]))
            mounting = rotation_rpy(*np.radians(m.attrs["dvl_mounting_rpy_deg"]))
            parts["mounting"].append(np.broadcast_to(mounting, (len(rows), 3, 3)))
            parts["yaw_rate"].append(np.abs(np.degrees(m.truth.angular_rate[rows, 2])))
            parts["body_rate"].append(m.truth.angular_rate[rows])
            parts["lever"].append(np.broadcast_to(
                np.asarray(m.attrs["dvl_position_body"], dtype=float), (len(rows), 3)))
            parts["position"].append(m.truth.position_ned[rows])
            parts["acceleration"].append(
                np.linalg.norm(v_dvl[ping] - v_dvl[np.maximum(ping - 1, 0)], axis=1) * rate)
    return {k: np.concatenate(v) for k, v in parts.items()}


def _reference_at(m, times: np.ndarray, v_dvl: np.ndarray) -> dict[str, np.ndarray]:
    """``truth_at_pings``'s fields for a recorded mission ``m`` at ``times`` (s), whose
    reference velocity at the DVL (``v_dvl``, (P, 3) m/s DVL frame) ``load_windows``
    made the target."""
    ref = m.reference
    t = np.asarray(ref.time, dtype=float)
    rotation = rotation_matrices(quaternions_at(t, require_attitude(m), times))
    rate = recorded_body_rate(m, times)
    step = np.diff(times, prepend=times[:1])
    change = np.linalg.norm(np.diff(v_dvl, axis=0, prepend=v_dvl[:1]), axis=1)
    mounting = rotation_rpy(*np.radians(m.attrs["dvl_mounting_rpy_deg"]))
    return dict(rotation=rotation,
                mounting=np.broadcast_to(mounting, (len(times), 3, 3)),
                yaw_rate=np.abs(np.degrees(rate[:, 2])), body_rate=rate,
                lever=np.broadcast_to(np.asarray(m.attrs["dvl_position_body"], dtype=float),
                                      (len(times), 3)),
                acceleration=np.divide(change, step, out=np.zeros_like(change),
                                       where=step > 0),
                position=np.stack([np.interp(times, t, ref.position_ned[:, i], left=np.nan,
                                             right=np.nan)
                                   for i in range(3)], axis=1))


def dead_reckoning_track(windows: Windows, velocity: np.ndarray,
                         truth: dict[str, np.ndarray], mission: int, *,
                         trapezoid: bool = False) -> np.ndarray:
    """(S_m, 3) NED displacement from the mission's first sample to each of its pings, m,
    from integrating ``velocity`` (S, 3, DVL frame) with the true attitude (the first row
    is zero, and the span is that of a position solution's from the first ping to the
    last).

    By default each NED velocity holds until the next ping (the rectangle rule): the
    track lags the vehicle by half a ping, which cancels in the difference of two such
    tracks (``dead_reckoning_error``, ``beamsnet stress``). Against a position
    (``dead_reckoning_positions``) it does not: after a half turn at 2 m/s and 1 Hz the
    held track stands v dt = 2 m from where it should. ``trapezoid`` averages each
    interval's two NED velocities instead (second order: on a circle, each step's chord
    shortened by (theta/2) cot(theta/2), theta the turn over the step)."""
    mine = windows.mission == mission
    dt = np.diff(windows.time[mine])[:, None]
    to_ned = truth["rotation"][mine] @ truth["mounting"][mine]  # DVL -> NED
    ned = np.einsum("sij,sj->si", to_ned, velocity[mine])
    mean = 0.5 * (ned[:-1] + ned[1:]) if trapezoid else ned[:-1]
    return np.concatenate([np.zeros((1, 3)), np.cumsum(mean * dt, axis=0)])


def dead_reckoning_error(windows: Windows, velocity: np.ndarray,
                         truth: dict[str, np.ndarray], mission: int) -> tuple[float, float]:
    """Horizontal position error (m) at the end of a mission from integrating
    ``velocity`` (S, 3, DVL frame) instead of the true DVL velocity, with the true attitude,
    over the pings of ``windows``; and the distance travelled over them (m)."""
    mine = windows.mission == mission
    error = (dead_reckoning_track(windows, velocity, truth, mission)
             - dead_reckoning_track(windows, windows.target, truth, mission))[-1]
    travelled = np.linalg.norm(windows.target[mine][:-1], axis=1) @ np.diff(
        windows.time[mine])
    return float(np.linalg.norm(error[:2])), float(travelled)


def own_position_error(windows: Windows, position: np.ndarray, truth: dict[str, np.ndarray],
                       mission: int) -> float:
    """Horizontal error (m) of an estimator's own position solution (``position``, (S, 3)
    m NED at each sample's ping, such as the INS/DVL filter's) after the mission: its
    displacement from the mission's first sample to its last against the truth's."""
    mine = np.flatnonzero(windows.mission == mission)
    first, last = mine[0], mine[-1]
    error = (position[last] - position[first]) - (truth["position"][last]
                                                  - truth["position"][first])
    return float(np.linalg.norm(error[:2]))


def held(windows: Windows, pred: np.ndarray) -> np.ndarray:
    """``pred`` (S, 3) with each NaN row replaced by the mission's last estimate before
    it, and before its first by the velocity the navigator started with: the target's
    (the truth's, or a recorded mission's reference's) at the mission's first sample, as
    the INS/DVL filter starts from the truth's (or the reference's) state. A gap at the
    start then costs what a gap anywhere does, the velocity's change over it, not the
    whole distance flown before the first estimate (which had made an estimator that
    starts three pings late on a turn look as if gaps ruined it)."""
    out = np.empty_like(pred)
    have = np.isfinite(pred).all(axis=1)
    for m in np.unique(windows.mission):
        rows = np.flatnonzero(windows.mission == m)  # in time order (``load_windows``)
        last = np.maximum.accumulate(np.where(have[rows], np.arange(len(rows)), -1))
        out[rows] = pred[rows][np.maximum(last, 0)]
        if last[0] < 0:  # pings before its first estimate
            out[rows[last < 0]] = windows.target[rows[0]]
    return out


def dead_reckoning_positions(windows: Windows, velocity: np.ndarray,
                             truth: dict[str, np.ndarray], mission: int) -> np.ndarray:
    """(S_m, 3) NED positions of the body origin (a recorded mission's reference point) at
    the mission's pings, m: ``velocity`` (S, 3, DVL frame; NaN rows held, ``held``) moved
    to the origin, ``M v - w x L`` (``truth``'s mounting, body rate and the DVL's lever
    arm), rotated by ``truth["rotation"]`` (the reference's attitude, or another's put in
    its place), integrated by the trapezoid rule from ``truth["position"]`` at the
    mission's first sample (``dead_reckoning_track`` of the origin's velocity in the DVL
    frame, ``v - M^T (w x L)``): a position solution in the frame of the reference's.

    Without the lever arm, the DVL's own track would stand L from the origin's, turned
    with the heading: 3.7 m apart after a half turn with the Snapir's DVL 1.85 m aft."""
    origin = held(windows, velocity) - np.einsum(
        "sji,sj->si", truth["mounting"], np.cross(truth["body_rate"], truth["lever"]))
    start = truth["position"][windows.mission == mission][0]
    return start + dead_reckoning_track(windows, origin, truth, mission, trapezoid=True)


def position_report(windows: Windows, position: np.ndarray, truth: dict[str, np.ndarray],
                    mission: int, position_std: np.ndarray | None = None, *,
                    since_first: bool = False) -> dict[str, float]:
    """``beamsnet.metrics.position_scores`` of the mission's positions (``position``, (S_m,
    3) or the whole (S, 3), m NED) against ``truth["position"]`` (the truth, or the
    reference), and with ``position_std`` (same shape, the estimator's reported 1 sigma
    per axis) ``coverage_3sigma``: the share of pings whose horizontal error lies within
    the radius 3 sqrt(sigma_N^2 + sigma_E^2) (``beamsnet.metrics.coverage``), 1 - e^-9 =
    99.99 % for a right covariance with equal north and east sigmas.

    ``since_first``: score how far the positions moved from the mission's first sample,
    put at the truth there, as a dead reckoning from that sample is (a scored interval
    that starts mid-mission, such as a test split); the coverage stays that of the
    positions themselves, which is what their sigma is of."""
    mine = windows.mission == mission
    if len(position) == len(windows.time):
        position = position[mine]
        position_std = None if position_std is None else position_std[mine]
    reference = truth["position"][mine]
    scored = position - position[0] + reference[0] if since_first else position
    out = metrics.position_scores(scored, reference)
    if position_std is not None:
        out["coverage_3sigma"] = metrics.coverage(
            np.linalg.norm(position[:, :2] - reference[:, :2], axis=1),
            np.hypot(position_std[:, 0], position_std[:, 1]))
    return out


def reference_departure(time: np.ndarray, position_ned: np.ndarray,
                        velocity_ned: np.ndarray) -> np.ndarray:
    """(R,) m, how far a navigation solution's horizontal positions (``position_ned``, (R,
    3) m, at ``time`` (R,) s) have moved from the integral of its own NED velocities
    (``velocity_ned``, (R, 3) m/s; trapezoids between its samples) since its first sample.

    0 throughout for a solution whose positions are its velocities' integral; one whose
    positions were corrected by something its velocities do not hold (a position fix, a
    smoother's) departs by that. Scores against such a reference cannot be trusted to
    better than it: two estimators that differ by less are not told apart by it."""
    p = np.asarray(position_ned, dtype=float)[:, :2]
    moved = cumulative(np.asarray(time, dtype=float),
                       np.asarray(velocity_ned, dtype=float)[:, :2])
    return np.linalg.norm(p - p[0] - moved, axis=1)


def dvl_against_reference(windows: Windows, truth: dict[str, np.ndarray]
                          ) -> tuple[np.ndarray, np.ndarray]:
    """At the samples of ``windows``: the DVL's own velocity less the target (the truth's
    or the reference's velocity at the DVL), (S, 3) m/s in the DVL frame, and the DVL ->
    NED rotation ``truth``'s attitude and mounting give, (S, 3, 3): what
    ``earth_fixed_fit`` takes."""
    return windows.velocity_ls - windows.target, truth["rotation"] @ truth["mounting"]


def earth_fixed_fit(difference: np.ndarray, turn: np.ndarray) -> dict[str, float]:
    """Whether a velocity difference turns with the vehicle: ``difference`` (S, 3) m/s in
    the DVL frame (a DVL's velocity less a reference's), put in NED by ``turn`` (S, 3, 3)
    DVL -> NED, and its horizontal part fitted by least squares as a constant in NED
    (``north``, ``east``) plus a constant in the DVL frame (``x``, ``y``; its z barely
    reaches the horizontal). An error of the instrument (scale, bias, mounting, lever
    arm, clock) turns with the vehicle; an Earth-fixed difference (a current one of the
    two took for motion, a fix spread over a reference's velocities) does not. Where the
    headings vary the two are told apart; on a straight line they are not (both fits
    then leave the same, and the split is NaN).

    Returns:
        ``north``, ``east``, ``x``, ``y`` (m/s) of the joint fit (NaN where the headings
        cannot tell them apart), and the rms per axis (m/s; N and E together) of the
        horizontal difference left by no fit (``rms``), by the NED constant alone
        (``rms_ned``), by the DVL-frame one alone (``rms_dvl``) and by both
        (``rms_both``). All NaN with fewer than three finite samples.
    """
    difference, turn = np.asarray(difference, float), np.asarray(turn, float)
    ok = np.isfinite(difference).all(axis=1) & np.isfinite(turn).all(axis=(1, 2))
    keys = ("north", "east", "x", "y", "rms", "rms_ned", "rms_dvl", "rms_both")
    if ok.sum() < 3:
        return dict.fromkeys(keys, float("nan"))
    horizontal = turn[ok, :2, :]  # (S, 2, 3)
    y = np.einsum("sij,sj->si", horizontal, difference[ok]).ravel()
    design = np.concatenate([np.broadcast_to(np.eye(2), (len(horizontal), 2, 2)),
                             horizontal[:, :, :2]], axis=2).reshape(-1, 4)

    def fit(columns: list[int]) -> tuple[np.ndarray, float]:
        x = np.linalg.lstsq(design[:, columns], y, rcond=None)[0]
        return x, float(np.sqrt(np.mean((y - design[:, columns] @ x) ** 2)))

    both, left = fit([0, 1, 2, 3])
    if np.linalg.matrix_rank(design) < 4:  # one heading: the split is arbitrary
        both = np.full(4, np.nan)
    return dict(zip(keys, (*map(float, both), float(np.sqrt(np.mean(y**2))),
                           fit([0, 1])[1], fit([2, 3])[1], left), strict=True))
