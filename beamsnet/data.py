"""Samples for BeamsNet and its baselines, cut from an auvsim dataset.

One sample per DVL ping k (paper sec. 3, and the published code):

* ``beams``: the measured beam velocities of ping k (BeamsNet's "current beams");
* ``past_beams``: those of pings k - n_past .. k - 1, oldest first (BeamsNetV2's input);
* ``accel``, ``gyro``: the IMU samples of the interval before ping k,
  ``[index_of_dvl[k] - W, index_of_dvl[k])`` with W = IMU rate / DVL rate (BeamsNetV1's
  input: 100 samples at 100 Hz / 1 Hz);
* ``target``: the true DVL velocity of ping k, in the DVL frame.

A recorded mission (``origin`` ``"recorded"``, ``auvsim import``) has no truth: its target
is the REFERENCE velocity (a navigation solution, the mission's ``reference_source``) moved
to the DVL, ``M^T (C_ref^T v_ref + w x L)`` at the ping's time (``reference_velocity``),
and ``Windows.reference`` says so. Its beams are ``dvl/beam_velocity`` when the log has
them, else ``H v`` of the instrument's own velocity (``dvl_beams_derived``, listed in
``Windows.derived``): then the beams carry the instrument's velocity errors, mapped onto
the beams, but no error of one beam alone. Its IMU interval is found by the stamps
(``np.searchsorted``: a recorded mission keeps each stream's own clock), W the nearest
whole number of IMU samples per ping.

A ping is a sample only if it has n_past earlier pings and a full IMU interval in its own
mission (k >= max(n_past, 1); ping 0 has no interval before it) and all the beams it uses
(current and past) have bottom lock. So V1, V2 and every baseline see the SAME samples, and
no sample reaches across a mission boundary. ``split`` then cuts each mission sequentially,
as the paper does (75 % / 25 %, no shuffling).

A water-track ping (``dvl/mode`` 1, written when bottom lock is lost and the DVL config
allows it) measures the velocity relative to a water layer, not the velocity over ground
that is the target, so it is never a sample: training and ``evaluate`` see bottom-track
pings only. ``beamsnet estimate`` asks for ``every_ping=True`` instead: every ping with its
IMU interval, beams without bottom lock as NaN, and a water-track ping's beams NaN too
(``water_track=False``), as the INS/DVL filter leaves them; the fault stress test
(``beamsnet.experiments.faults``) keeps the water-track beams as the instrument reports
them, so that it can score what an estimator makes of a ping it cannot fully use.

The file is read only through ``auvsim.data.open_dataset``, the one reader that knows
the file format and checks it; its ``Mission`` views give the arrays by name.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import NamedTuple

import numpy as np

from auvsim.data.beams import DvlGeometry, beam_matrix, usable_beams
from auvsim.data.reader import open_dataset
from auvsim.errors import DatasetError


class DataError(DatasetError, ValueError):
    """A dataset cannot give the samples asked for (also raised for a file that is not an
    auvsim dataset, with ``open_dataset``'s message). An ``AuvsimError``, so the CLI
    boundary catches it with the others."""


# What a simulated mission's target is; an imported velocity stream's (``auvsim import
# --format velocity``: real velocities, synthetic beams) is that stream, the truth by the
# paper's protocol; a recorded mission's is its reference.
TRUTH = "the simulator's truth"
IMPORTED = "the imported velocity, the truth by the paper's protocol"
TRUTHS = (TRUTH, IMPORTED)  # targets that are the truth by construction
NO_REFERENCE = "nothing: the log has no reference"  # a recorded log's target, NaN


class Windows(NamedTuple):
    """Samples, one per usable DVL ping, missions one after the other in ``names`` order,
    pings in time order within each mission. Arrays are float64 except ``mission``.

    Attributes:
        beams: (S, 4) measured beam velocities of the ping, m/s.
        past_beams: (S, n_past, 4) measured beams of the n_past previous pings, oldest
            first, m/s.
        accel: (S, W, 3) measured specific force of the IMU interval before the ping,
            m/s^2, body axes; None when the file has no IMU group.
        gyro: (S, W, 3) measured angular rate of that interval, rad/s, body; or None.
        target: (S, 3) true DVL velocity in the DVL frame, m/s: the regression target.
        velocity_ls: (S, 3) the file's least-squares velocity of the ping (paper eq. 9), m/s.
        mission: (S,) int64 index into ``names``.
        time: (S,) ping time from the start of its mission, s.
        names: the mission names.
        h: (4, 3) beam matrix shared by every mission.
        reference: what ``target`` is: ``the simulator's truth`` (``TRUTH``), for an
            imported velocity stream that stream (``IMPORTED``), or for recorded missions
            ``the reference: <reference_source>``.
        derived: the missions whose beams are ``H v`` of the instrument's velocity
            (their log has no beams).
    """

    beams: np.ndarray
    past_beams: np.ndarray
    accel: np.ndarray | None
    gyro: np.ndarray | None
    target: np.ndarray
    velocity_ls: np.ndarray
    mission: np.ndarray
    time: np.ndarray
    names: tuple[str, ...]
    h: np.ndarray
    reference: str = TRUTH
    derived: tuple[str, ...] = ()


# Fields with one row per sample: what select() indexes.
_PER_SAMPLE = ("beams", "past_beams", "accel", "gyro", "target", "velocity_ls", "mission",
               "time")


def load_windows(path: str | os.PathLike, *, n_past: int = 3,
                 missions: Sequence[str] | None = None, every_ping: bool = False,
                 water_track: bool = True) -> Windows:
    """Cut the samples of every (or the named) mission of a dataset.

    Args:
        path: an auvsim dataset.
        n_past: number of past pings per sample (BeamsNetV2 uses 3), >= 1.
        missions: names of the missions to use, in this order; default all, in file order
            (h5py lists a group's members by name).
        every_ping: keep every ping that has n_past earlier pings and an IMU interval,
            whatever its beams: a beam without bottom lock is NaN (in ``beams`` and
            ``past_beams``), a water-track ping keeps its water-track beams (or, with
            ``water_track`` False, has NaN beams: it measured no velocity over ground, as
            a navigator that reads the instrument's mode takes it). Default: only pings
            whose current and past beams all have bottom lock.
        water_track: with ``every_ping``, keep a water-track ping's beams (the fault
            sweep's misuse of them) or make them NaN.

    Returns:
        The samples (see ``Windows``).

    Raises:
        DataError: the file is not an auvsim dataset; ``n_past`` < 1; a mission name is
            not in the file; a mission has too few pings for one sample; missions differ
            in beam angle or in IMU samples per ping; no ping has all its beams valid.
    """
    if isinstance(n_past, bool) or not isinstance(n_past, (int, np.integer)) or n_past < 1:
        raise DataError(f"n_past: expected an integer >= 1 (past pings per sample), "
                        f"got {n_past!r}")
    if isinstance(missions, str):
        raise DataError(f"missions: expected a sequence of mission names, got the string "
                        f"{missions!r} (write [{missions!r}])")
    try:
        f = open_dataset(path)
    except DatasetError as e:
        raise DataError(str(e)) from None
    with f:
        group = f.missions
        available = list(group)
        names = tuple(available if missions is None else missions)
        if not available:
            raise DataError(f"{path}: holds no missions; expected a dataset with at least "
                            "one (auvsim generate or auvsim import writes them)")
        if not names:
            raise DataError(f"missions: expected at least one mission name; {path} has "
                            f"{', '.join(available)}")
        unknown = [n for n in names if n not in group]
        if unknown:
            raise DataError(f"mission {', '.join(map(repr, unknown))}: not in {path}; "
                            f"expected one of its missions: {', '.join(available)}")
        if len(set(names)) != len(names):
            raise DataError(f"missions: each mission at most once, got {list(names)}")
        angles = {n: float(group[n].attrs["beam_angle_deg"]) for n in names}
        if len(set(angles.values())) > 1:
            raise DataError(f"{path}: missions have different beam angles "
                            f"({', '.join(f'{n} {a:g} deg' for n, a in angles.items())}); "
                            "one beam matrix is needed: pass missions= with one angle")
        with_imu = all(group[n].has("imu") for n in names)
        parts = [_mission_windows(group[n], n, i, n_past, with_imu, every_ping, water_track)
                 for i, n in enumerate(names)]
        _check_each_has_samples(path, group, names, parts, n_past)

    widths = {p["accel"].shape[1] for p in parts if p["accel"] is not None}
    if len(widths) > 1:
        raise DataError(f"{path}: missions have different IMU samples per DVL ping "
                        f"({sorted(widths)}); pass missions= with one IMU/DVL rate ratio")
    out = {k: (None if parts[0][k] is None else np.concatenate([p[k] for p in parts]))
           for k in _PER_SAMPLE}
    if len(out["target"]) == 0:
        raise DataError(f"{path}: no ping of {', '.join(names)} has all {n_past + 1} beam "
                        "epochs valid (bottom lock); no samples")
    return Windows(**out, names=names,
                   h=beam_matrix(math.radians(next(iter(angles.values())))),
                   reference=_reference_words(path, [p["reference"] for p in parts]),
                   derived=tuple(n for n, p in zip(names, parts, strict=True)
                                 if p["derived"]))


def _reference_words(path, references: list[str]) -> str:
    """``Windows.reference`` of missions whose targets are ``references``: one source.

    Raises:
        DataError: the missions mix the simulator's truth with a reference, or two
            references: their scores would not say against what.
    """
    kinds = list(dict.fromkeys(references))
    if len(kinds) > 1:
        raise DataError(f"{path}: the missions are scored against different things "
                        f"({'; '.join(kinds)}); pass missions= of one kind")
    return kinds[0]


def _check_each_has_samples(path, group, names: Sequence[str], parts: list[dict],
                            n_past: int) -> None:
    """Refuse a mission that gives no sample: trained or scored on the others alone, a
    run would say nothing of it and exit as if all were well.

    Raises:
        DataError: naming the first such mission and why (a recorded mission's pings all
            outside its reference's span, no beam velocity at all, or no ping with all its
            beam epochs valid).
    """
    for name, part in zip(names, parts, strict=True):
        if len(part["target"]):
            continue
        m = group[name]
        beams = recorded_beams(m)[0]
        t_ref = m.reference.time if m.has("reference") else None
        if t_ref is not None and not ((m.dvl.time >= t_ref[0]) & (m.dvl.time <= t_ref[-1])).any():
            why = "no ping lies within the reference's time span"
        elif not np.isfinite(beams).any():
            why = "every beam velocity is NaN (not one ping has a valid beam)"
        else:
            why = f"no ping has all {n_past + 1} beam epochs valid (bottom lock)"
        raise DataError(f"{path}: mission {name}: {why}, so it gives no samples; expected "
                        "DVL data to use (or leave the mission out)")


def check_dataset(path: str | os.PathLike, *, argument: str,
                  missions: Sequence[str] = (), truth: bool = False) -> Path:
    """Refuse ``path`` unless it is an auvsim dataset with ``missions`` (and, with
    ``truth``, a truth group in every mission): a check before any data is generated or
    model trained, so that a wrong file costs nothing.

    Raises:
        DataError: naming ``argument``, the file and what it lacks.
    """
    try:
        f = open_dataset(path)
    except DatasetError as e:
        raise DataError(f"{e}", argument=argument) from None
    with f:
        have = list(f.missions)
        lacking = [n for n in missions if n not in f.missions]
        if lacking:
            raise DataError(f"{str(path)!r}: has no mission {', '.join(lacking)} (it has "
                            f"{', '.join(have) or 'none'}); expected "
                            f"{', '.join(missions)}", argument=argument)
        imported = [n for n in have if truth and not f.missions[n].has("truth")]
        if imported:
            raise DataError(f"{str(path)!r}: mission {imported[0]} has no truth group (an "
                            "imported stream); expected a simulated dataset", argument=argument)
    return Path(path)


def check_referenced(windows: Windows, dataset: str | os.PathLike) -> None:
    """Refuse samples of a log without a reference (``NO_REFERENCE``): nothing to score
    or train against.

    Raises:
        DataError: in one line, saying what can be done with such a file.
    """
    if windows.reference == NO_REFERENCE:
        raise DataError(f"{dataset}: a log without a reference, so no velocity to score or "
                        "train against; expected a file with a reference or the truth "
                        "(beamsnet estimate runs an estimator on it, unscored)")


def check_truth(windows: Windows, dataset: str | os.PathLike) -> None:
    """Refuse samples whose true DVL velocity holds NaN or inf: no estimator can be scored
    against it.

    Raises:
        DataError: naming the dataset and where the first such sample is; or the file is
            a log without a reference (``NO_REFERENCE``), so nothing to score or train on.
    """
    check_referenced(windows, dataset)
    bad = ~np.isfinite(windows.target).all(axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        what = ("true" if windows.reference in TRUTHS else "reference")
        raise DataError(f"{dataset}: the {what} DVL velocity holds NaN or inf in "
                        f"{int(bad.sum())} of {len(bad)} samples (the first in mission "
                        f"{windows.names[windows.mission[first]]} at "
                        f"{windows.time[first]:g} s); expected finite {what} velocities "
                        "to score the estimators against")


def _mission_windows(m, name: str, index: int, n_past: int, with_imu: bool,
                     every_ping: bool = False, water_track: bool = True) -> dict:
    """The samples of one mission (an ``auvsim.data.reader.Mission``), as a dict of Windows
    fields (and ``reference``, ``derived``: what the target is, whether the beams are
    derived)."""
    recorded = m.origin == "recorded"
    beams, derived = recorded_beams(m)
    n_pings = len(beams)
    first = max(n_past, 1)  # the first ping with n_past pings and an IMU interval before it
    if n_pings <= first:
        raise DataError(f"mission {name}: {n_pings} DVL ping(s); a sample with n_past="
                        f"{n_past} needs at least {first + 1}")
    valid = usable_beams(m.dvl.valid if "valid" in m.dvl else np.isfinite(beams), beams)
    # Format v4 records the mode of each ping (0 bottom track, 1 water track, -1 none).
    mode = m.dvl.mode if "mode" in m.dvl else np.zeros(n_pings, dtype=np.int64)
    if every_ping:
        usable = np.ones(n_pings, dtype=bool)
        # A beam counts if it has bottom lock or measures the water layer; any other
        # beam is NaN, whatever the file holds there.
        keep = (valid | (mode == 1)[:, None] if water_track
                else valid & (mode != 1)[:, None])
        beams = np.where(keep, beams, np.nan)
    else:
        # A water-track ping does not measure the velocity over ground: no sample.
        usable = valid.all(axis=1) & np.isfinite(beams).all(axis=1) & (mode == 0)
    # ok[k]: pings k - n_past .. k all usable (a running count of usable pings).
    count = np.concatenate([[0], np.cumsum(usable)])
    ks = np.arange(first, n_pings)
    ok = count[ks + 1] - count[ks - n_past] == n_past + 1

    accel = gyro = None
    if with_imu:
        width = m.attrs["imu_rate_hz"] / m.attrs["dvl_rate_hz"]
        if recorded:  # stamped clocks: the IMU samples strictly before each ping
            width = max(round(width), 1)
            end = np.searchsorted(m.imu.time, m.dvl.time, side="left")
        else:
            if abs(width - round(width)) > 1e-9 or round(width) < 1:
                raise DataError(f"mission {name}: IMU rate {m.attrs['imu_rate_hz']:g} Hz is "
                                f"not a whole multiple of the DVL rate "
                                f"{m.attrs['dvl_rate_hz']:g} Hz")
            width = round(width)
            end = m.imu.index_of_dvl
        n_imu = m.imu.rows
        ok &= (end[ks] - width >= 0) & (end[ks] <= n_imu)
        ks = ks[ok]
        rows = end[ks][:, None] + np.arange(-width, 0)  # (S, W) IMU rows before each ping
        accel = m.imu.specific_force[rows]
        gyro = m.imu.angular_rate[rows]
    else:
        ks = ks[ok]
    if recorded and not m.has("reference"):  # estimates without a score
        target = np.full((len(ks), 3), np.nan)
        reference = NO_REFERENCE
    elif recorded:
        # Only the pings the reference covers are scored: beyond its span (a DVL clock
        # that check-log moved past the reference's last sample) nothing says where the
        # vehicle was.
        ref_time = m.reference.time
        inside = (m.dvl.time[ks] >= ref_time[0]) & (m.dvl.time[ks] <= ref_time[-1])
        ks = ks[inside]
        if accel is not None:
            accel, gyro = accel[inside], gyro[inside]
        target = reference_velocity(m, m.dvl.time[ks])
        reference = f"the reference: {m.attrs.get('reference_source', 'unnamed')}"
    else:
        target = m.dvl.velocity[ks]
        reference = TRUTH if m.origin == "simulated" else IMPORTED
    return dict(
        beams=beams[ks],
        past_beams=beams[ks[:, None] + np.arange(-n_past, 0)],
        accel=accel, gyro=gyro,
        target=target,
        velocity_ls=m.dvl.velocity_ls[ks],
        mission=np.full(len(ks), index, dtype=np.int64),
        time=m.dvl.time[ks],
        reference=reference, derived=derived,
    )


def recorded_beams(m) -> tuple[np.ndarray, bool]:
    """(P, 4) beam velocities of a mission, m/s, and whether they are derived: the file's
    ``dvl/beam_velocity``; for a recorded log without beams (``dvl_beams_derived``),
    ``H v`` of the instrument's own velocity ``dvl/velocity_ls``, which puts its velocity
    errors on the beams as LS would see them (LS of ``H v`` is ``v``, exactly)."""
    if "beam_velocity" in m.dvl:
        return np.asarray(m.dvl.beam_velocity, dtype=float), False
    h = beam_matrix(math.radians(float(m.attrs["beam_angle_deg"])))
    return np.asarray(m.dvl.velocity_ls, dtype=float) @ h.T, True


def reference_velocity(m, times: np.ndarray) -> np.ndarray:
    """(P, 3) velocity of the DVL over ground in its own frame, m/s, from a recorded
    mission's reference at ``times`` (s, on the DVL's clock):
    ``M^T (C_ref^T v_ref + w x L)``.

    ``C_ref^T v_ref`` (the reference's NED velocity in its body frame, with its attitude
    ``C_ref``, body -> NED) is formed at the reference's samples and interpolated linearly
    in time; ``w`` is the body rate (``recorded_body_rate``):
    the IMU's gyro interpolated at ``times`` where the mission has an IMU (the Earth's
    rate in it, 7e-5 rad/s, moves a 1 m lever by 0.07 mm/s), else the rate between the
    reference's attitudes. ``L`` is ``dvl_position_body``, the DVL's place from the
    reference point, and ``M`` the DVL mounting (DVL -> body).

    Raises:
        DataError: the mission has no reference, or its reference has no attitude (the
            velocity cannot be put in the DVL frame without it).
    """
    from auvsim.physics.frames import rotation_matrices, rotation_rpy

    if not m.has("reference"):
        raise DataError(f"mission {m.name}: a recorded mission without a reference group; "
                        "expected a reference to score against")
    ref = m.reference
    if "quaternion" not in ref:
        raise DataError(f"mission {m.name}: its reference has no attitude, so its velocity "
                        "cannot be put in the DVL frame; expected reference/quaternion")
    t = np.asarray(ref.time, dtype=float)
    times = np.asarray(times, dtype=float)
    # In the body frame, where a steady turn's velocity is constant (in NED it turns, and
    # a line between two samples 1 s apart cuts the circle's chord: 0.4 % slow at 0.2
    # rad/s).
    c = rotation_matrices(np.asarray(ref.quaternion, dtype=float))
    v_ref = np.einsum("rji,rj->ri", c, np.asarray(ref.velocity_ned, dtype=float))
    # NaN outside the reference's span: a ping it does not cover has no target.
    v_body = np.stack([np.interp(times, t, v_ref[:, i], left=np.nan, right=np.nan)
                       for i in range(3)], axis=1)
    geometry = DvlGeometry(beam_matrix(math.radians(float(m.attrs["beam_angle_deg"]))),
                           rotation_rpy(*np.radians(m.attrs["dvl_mounting_rpy_deg"])),
                           np.asarray(m.attrs["dvl_position_body"], dtype=float))
    return geometry.velocity(v_body, recorded_body_rate(m, times))


def recorded_body_rate(m, times: np.ndarray) -> np.ndarray:
    """(P, 3) body angular rate of a recorded mission at ``times`` (s), rad/s: its IMU's
    gyro interpolated where it has an IMU, else the rate between its reference's
    attitudes (``body_rate``)."""
    if m.has("imu"):
        return np.stack([np.interp(times, m.imu.time, m.imu.angular_rate[:, i])
                         for i in range(3)], axis=1)
    ref = m.reference
    return body_rate(np.asarray(ref.time, dtype=float), np.asarray(ref.quaternion, dtype=float),
                     times)


def quaternions_at(t: np.ndarray, q: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(P, 4) attitude quaternions [w, x, y, z] at ``times``: linear in each component
    between the two samples of ``q`` (R, 4) at ``t`` (R,) around it, on the first's
    hemisphere, then normalised (nlerp: within 1e-4 rad of slerp for steps under 10 deg);
    NaN outside ``t``'s span."""
    q = np.array(q, dtype=float)
    # q and -q are one attitude: flip each sample onto its predecessor's hemisphere.
    turn = np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0)
    q *= np.concatenate([[1.0], np.cumprod(turn)])[:, None]
    out = np.stack([np.interp(times, t, q[:, i], left=np.nan, right=np.nan)
                    for i in range(4)], axis=1)
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def body_rate(t: np.ndarray, q: np.ndarray, times: np.ndarray) -> np.ndarray:
    """(P, 3) body angular rate, rad/s, at ``times`` from attitude samples ``q`` (R, 4)
    at ``t`` (R,): each interval's rate (``auvsim.physics.frames.attitude_rates``),
    interpolated between the intervals' midpoints."""
    from auvsim.physics.frames import attitude_rates

    rate = attitude_rates(t, q)
    mid = 0.5 * (t[1:] + t[:-1])
    return np.stack([np.interp(times, mid, rate[:, i]) for i in range(3)], axis=1)


def select(windows: Windows, which: np.ndarray | Sequence[int] | slice) -> Windows:
    """The samples picked by a boolean mask (S,), integer indices or a slice; ``names``
    and ``h`` are kept, so mission indices keep their meaning."""
    if not isinstance(which, slice):
        which = np.asarray(which)
        n = len(windows.target)
        if which.dtype == bool and which.shape != (n,):
            raise ValueError(f"select: a mask must have shape ({n},), got "
                             f"{which.shape}")
    return windows._replace(**{k: None if getattr(windows, k) is None
                               else getattr(windows, k)[which] for k in _PER_SAMPLE})


def split(windows: Windows, train_fraction: float = 0.75) -> tuple[Windows, Windows]:
    """Sequential train/test split of each mission, no shuffling (paper: 75 % / 25 %).

    The first ``floor(train_fraction * n)`` samples of each mission (of n) train, the
    rest test; both keep the order of ``windows``.

    Raises:
        DataError: ``train_fraction`` is not in (0, 1), or either part is empty (a
            ``ValueError`` too, and an ``AuvsimError``, so the command lines catch it).
    """
    if not (isinstance(train_fraction, (int, float)) and 0 < train_fraction < 1):
        raise DataError(f"train_fraction: expected a fraction in (0, 1), got "
                         f"{train_fraction!r}")
    train = np.zeros(len(windows.target), dtype=bool)
    for m in np.unique(windows.mission):
        rows = np.flatnonzero(windows.mission == m)
        rows = rows[np.argsort(windows.time[rows], kind="stable")]
        train[rows[:int(train_fraction * len(rows))]] = True
    if train.all() or not train.any():
        raise DataError(f"split: train_fraction {train_fraction:g} of {len(train)} "
                         f"samples leaves the {'test' if train.all() else 'training'} "
                         "part empty")
    return select(windows, train), select(windows, ~train)
