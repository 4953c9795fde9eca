"""``auvsim plot``: a mission at a glance, as a PNG per mission.

A simulated mission gets six panels: the track in plan view, the depth profile over the
seafloor, speed (over ground, and through the water where the file has it), attitude, the
DVL velocity (true and least squares, water-track segments shaded) and the beams' bottom
lock, with the reason each beam lost it where the file says (``dvl/status``, schema v4). A
v4 mission adds two more: the current at the vehicle (speed, and the direction it flows
toward, 0 to 360 deg from north, as ``auvsim inspect`` says it) and the DVL's error
velocity. An imported mission (a recorded DVL stream, no trajectory) gets the DVL panels
only. A recorded mission (a real vehicle's logs) gets its reference's track, depth, speed
and attitude, labelled as a reference (a navigation solution, not the truth), and each
stream it holds with its rate: the DVL's velocity beside the reference's, the IMU's
rates and specific force. Legends sit beside their panels, outside the data.
"""

from __future__ import annotations

import io
import os
import warnings
from pathlib import Path

import numpy as np

from auvsim.data.files import all_or_nothing, check_out_dir, make_out_dir, write_bytes
from auvsim.data.reader import Mission, open_dataset, require_usable_beams
from auvsim.errors import ConfigError, DatasetError
from auvsim.physics.frames import euler_angles
from auvsim.sensors.dvl import Mode, Status


def plot(path: str | os.PathLike, *, missions: list[str] | None = None,
         out: str | os.PathLike | None = None) -> list[Path]:
    """Draw each (or each named) mission of a dataset.

    Only checked data is drawn: the file is opened with every checksum verified, and
    nothing is written (not even the ``out`` directory) until every figure is drawn.

    Args:
        path: an auvsim dataset.
        missions: names of the missions to draw (default: all).
        out: directory for the PNGs (default: beside the file); one
            ``<file stem>_<mission>.png`` per mission.

    Returns:
        The paths written.

    Raises:
        DatasetError: the file is not a readable, consistent auvsim dataset, has no
            missions, or a mission's values cannot be drawn.
        ConfigError: a mission name is not in the file; ``out`` is not a directory.
        OutputError: a figure cannot be written (none is left then).
    """
    path = Path(path)
    out = check_out_dir(path.parent if out is None else out)
    with open_dataset(path, verify=True) as f:
        group = f.missions
        names = list(group) if missions is None else list(missions)
        unknown = [n for n in names if n not in group]
        if unknown:
            raise ConfigError(f"{', '.join(unknown)}: not in {path}; it has "
                              f"{', '.join(group) or 'no missions'}", argument="missions")
        if not names:
            raise DatasetError(f"{path}: no missions to draw")
        for name in names:
            if group[name].origin != "recorded":  # a real log may have no beams at all
                require_usable_beams(group[name])
        pngs = {out / f"{path.stem}_{name}.png": _render(group[name], path)
                for name in names}
    with all_or_nothing():  # a full disk at the third figure leaves none
        make_out_dir(out)  # only now: every input has been checked
        for target, png in pngs.items():
            write_bytes(target, png)
    return list(pngs)


# No offset on an axis: a steady depth reads 20.0005 m, not 5e-4 + 2e1.
NO_OFFSET = {"axes.formatter.useoffset": False}


def _render(m: Mission, path: Path) -> bytes:
    """One mission's figure as PNG bytes; values matplotlib cannot draw (limits beyond
    float range) are refused with a ``DatasetError`` naming the mission."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if m.origin == "recorded":
        rows = 3
    else:
        rows = (4 if "current_ned" in m.truth else 3) if m.has("truth") else 1
    with plt.rc_context(NO_OFFSET):
        fig, axes = plt.subplots(rows, 2, figsize=(15, 3.2 * rows), squeeze=False,
                                 layout="constrained")
    buffer = io.BytesIO()
    try:
        # NaN and huge values are valid data (no bottom lock, a diverged filter): numpy's
        # and matplotlib's warnings about them would only clutter the command's output.
        with warnings.catch_warnings(), np.errstate(all="ignore"), plt.rc_context(NO_OFFSET):
            warnings.simplefilter("ignore")
            (_draw_recorded if m.origin == "recorded" else _draw)(m, axes)
            fig.suptitle(f"{path.name}: {m.name}")
            fig.savefig(buffer, format="png", dpi=100)
    except (ValueError, OverflowError, FloatingPointError) as e:
        reason = " ".join(str(e).split()) or type(e).__name__
        raise DatasetError(f"{path}: mission {m.name} ({m.origin}): cannot be drawn "
                           f"({reason})") from None
    finally:
        plt.close(fig)
    return buffer.getvalue()


def _draw(m: Mission, axes: np.ndarray) -> None:
    """Draw one mission on a (3, 2) or (4, 2) grid of axes (simulated) or a (1, 2) one
    (imported)."""
    simulated = m.has("truth")
    t_dvl = m.dvl.time
    if simulated:
        truth = m.truth
        t = truth.time
        pos = truth.position_ned
        ax = axes[0, 0]
        ax.plot(pos[:, 1], pos[:, 0], lw=1)
        ax.plot(pos[0, 1], pos[0, 0], "go", label="start")
        ax.plot(pos[-1, 1], pos[-1, 0], "rs", label="end")
        ax.set_xlabel("east, m")
        ax.set_ylabel("north, m")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title("track, plan view")
        _legend_beside(ax)

        ax = axes[0, 1]
        floor = pos[:, 2] + truth.altitude
        ax.plot(t, pos[:, 2], label="vehicle")
        ax.fill_between(t, floor, floor.max() + 5, color="tan", alpha=0.6, label="seafloor")
        ax.invert_yaxis()
        ax.set_xlabel("time, s")
        ax.set_ylabel("depth, m")
        ax.set_title("depth profile")
        _legend_beside(ax)

        ax = axes[1, 0]
        v = truth.velocity_body
        ax.plot(t, np.linalg.norm(v, axis=1), label="over ground")
        ax.plot(t, v[:, 0], "--", lw=0.8, label="surge u, over ground")
        title = "speed over ground"
        if "velocity_water_body" in truth:  # what the speed set point holds, in a current
            water = truth.velocity_water_body
            ax.plot(t, np.linalg.norm(water, axis=1), lw=1, label="through the water")
            title += " and through the water"
        ax.set_xlabel("time, s")
        ax.set_ylabel("m/s")
        ax.set_title(title)
        ax.ticklabel_format(axis="y", useOffset=False)
        _legend_beside(ax)

        ax = axes[1, 1]
        roll, pitch, yaw = euler_angles(truth.quaternion).T
        yaw = np.unwrap(yaw)
        for angle, label in ((roll, "roll"), (pitch, "pitch")):
            ax.plot(t, np.degrees(angle), label=label)
        ax.set_ylabel("roll, pitch, deg")
        twin = ax.twinx()
        twin.plot(t, np.degrees(yaw), "k", lw=0.8, label="yaw")
        twin.set_ylabel("yaw, deg")
        twin.ticklabel_format(axis="y", useOffset=False)
        ax.set_xlabel("time, s")
        ax.set_title("attitude")
        _legend_beside(ax, twin)

    dvl_row = 2 if simulated else 0
    ax = axes[dvl_row, 0]
    true, ls = m.dvl.velocity, m.dvl.velocity_ls
    for k, axis in enumerate("xyz"):
        line, = ax.plot(t_dvl, true[:, k], lw=1, label=f"v{axis} true")
        ax.plot(t_dvl, ls[:, k], ".", ms=1.5, color=line.get_color(), label=f"v{axis} LS")
    title = "DVL velocity"
    if "mode" in m.dvl:
        water = m.dvl.mode == Mode.WATER_TRACK
        if water.any():
            ax.fill_between(t_dvl, 0, 1, where=water, step="mid", color="tab:cyan", alpha=0.3,
                            transform=ax.get_xaxis_transform(), label="water track")
            title += f", water track in {100 * water.mean():.1f} % of pings (shaded)"
    ax.set_xlabel("time, s")
    ax.set_ylabel("m/s, DVL frame")
    ax.set_title(title)
    _legend_beside(ax)

    ax = axes[dvl_row, 1]
    valid = m.dvl.valid
    # Beams by their array index, 0 to 3, as dvl.beam_failures and the reports name them.
    extent = (t_dvl[0], t_dvl[-1] if len(t_dvl) > 1 else t_dvl[0] + 1, 3.5, -0.5)
    if "status" in m.dvl:
        _draw_status(ax, m.dvl.status, extent)
    else:
        ax.imshow(valid.T, aspect="auto", interpolation="nearest", cmap="RdYlGn", vmin=0,
                  vmax=1, extent=extent)
        ax.set_title(f"bottom lock (green), {100 * valid.mean():.1f} % of beam pings")
    ax.set_yticks([0, 1, 2, 3])
    ax.set_ylabel("beam (index)")
    ax.set_xlabel("time, s")

    if axes.shape[0] == 4:
        _draw_water(m, axes[3, 0], axes[3, 1])


def _draw_recorded(m: Mission, axes: np.ndarray) -> None:
    """A recorded mission on a (3, 2) grid: the reference (track, depth, speed, attitude),
    then the DVL's velocity and the IMU's rates, each stream with its rate."""
    a = m.attrs
    rate = {g: a.get(f"{g}_rate_hz", float("nan")) for g in ("imu", "dvl", "depth",
                                                              "reference")}
    ref = m.reference if m.has("reference") else None
    ax = axes[0, 0]
    if ref is not None:
        pos = ref.position_ned
        ax.plot(pos[:, 1], pos[:, 0], lw=1, label="reference")
        ax.plot(pos[0, 1], pos[0, 0], "go", label="start (origin)")
        ax.plot(pos[-1, 1], pos[-1, 0], "rs", label="end")
        ax.set_aspect("equal", adjustable="datalim")
        _legend_beside(ax)
    ax.set_xlabel("east, m")
    ax.set_ylabel("north, m")
    ax.set_title(f"reference track (a navigation solution, not the truth), "
                 f"{rate['reference']:.3g} Hz" if ref is not None else "no reference in the log")

    ax = axes[0, 1]
    if ref is not None:
        ax.plot(ref.time, ref.position_ned[:, 2] - a["height_m"], label="reference")
    if m.has("depth"):
        ax.plot(m.depth.time, m.depth.depth, lw=0.8, label=f"depth sensor, {rate['depth']:.3g} Hz")
    ax.invert_yaxis()
    ax.set_xlabel("time, s")
    ax.set_ylabel("depth, m")
    ax.set_title("depth (reference: -height)")
    _legend_beside(ax)

    ax = axes[1, 0]
    if ref is not None:
        ax.plot(ref.time, np.linalg.norm(ref.velocity_ned, axis=1), label="reference |v|")
    if m.has("dvl"):
        ax.plot(m.dvl.time, np.linalg.norm(m.dvl.velocity_ls, axis=1), ".", ms=2,
                label=f"DVL |v|, {rate['dvl']:.3g} Hz")
    ax.set_xlabel("time, s")
    ax.set_ylabel("m/s")
    ax.set_title("speed over ground")
    _legend_beside(ax)

    ax = axes[1, 1]
    if ref is not None and "rpy_deg" in ref:
        rpy = ref.rpy_deg
        ax.plot(ref.time, rpy[:, 0], label="roll")
        ax.plot(ref.time, rpy[:, 1], label="pitch")
        twin = ax.twinx()
        twin.plot(ref.time, np.degrees(np.unwrap(np.radians(rpy[:, 2]))), "k", lw=0.8,
                  label="yaw")
        twin.set_ylabel("yaw, deg")
        ax.set_title("reference attitude")
        _legend_beside(ax, twin)
    else:
        ax.set_title("no attitude in the reference")
    ax.set_ylabel("roll, pitch, deg")
    ax.set_xlabel("time, s")

    ax = axes[2, 0]
    if m.has("dvl"):
        v = m.dvl.velocity_ls
        for k, axis in enumerate("xyz"):
            ax.plot(m.dvl.time, v[:, k], ".", ms=2, label=f"v{axis}")
        ax.set_title(f"DVL velocity (its own output, DVL frame), {rate['dvl']:.3g} Hz")
        _legend_beside(ax)
    else:
        ax.set_title("no DVL in the log")
    ax.set_xlabel("time, s")
    ax.set_ylabel("m/s")

    ax = axes[2, 1]
    if m.has("imu"):
        t, w = m.imu.time, np.degrees(m.imu.angular_rate)
        for k, axis in enumerate("xyz"):
            ax.plot(t, w[:, k], lw=0.5, label=f"gyro {axis}")
        twin = ax.twinx()
        twin.plot(t, np.linalg.norm(m.imu.specific_force, axis=1), color="0.6", lw=0.3,
                  label="|specific force|")
        twin.set_ylabel("m/s^2")
        ax.set_zorder(twin.get_zorder() + 1)  # the gyros over the grey |f|, not under it
        ax.patch.set_visible(False)
        ax.set_title(f"IMU (body FRD), {rate['imu']:.4g} Hz")
        _legend_beside(ax, twin)
    else:
        ax.set_title("no IMU in the log")
    ax.set_xlabel("time, s")
    ax.set_ylabel("deg/s")


# The colours of the first status codes (``Status``), chosen to read: ok green, the
# geometry's greys, faults warm.
STATUS_COLOURS = ("tab:green", "lightgrey", "dimgrey", "tab:orange", "tab:brown", "tab:red",
                  "black", "tab:purple", "tab:blue", "gold")


def status_colours(n: int) -> list:
    """A colour for each of ``n`` status codes (``len(Status)``): ``STATUS_COLOURS`` first,
    then hues spread by the golden ratio, distinct for any number of codes."""
    from matplotlib.colors import hsv_to_rgb

    extra = [tuple(hsv_to_rgb(((k * 0.618033988749895) % 1.0, 0.65, 0.85)))
             for k in range(max(0, n - len(STATUS_COLOURS)))]
    return [*STATUS_COLOURS[:n], *extra]


def _draw_status(ax, status: np.ndarray, extent) -> None:
    """The beams' reason codes (``Status``) over time, one colour per code, with a legend
    of the codes that occur and their shares."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    colours = status_colours(len(Status))
    cmap = ListedColormap(colours)
    ax.imshow(status.T, aspect="auto", interpolation="nearest", cmap=cmap, vmin=-0.5,
              vmax=len(Status) - 0.5, extent=extent)
    counts = np.bincount(status.ravel().clip(0, len(Status) - 1), minlength=len(Status))
    handles = [Patch(color=colours[code], label=f"{Status(code).name.lower()} "
                     f"{100 * n / status.size:.1f} %")
               for code, n in enumerate(counts) if n]
    _legend_beside(ax, handles=handles)
    ax.set_title(f"beam status (dvl/status): ok in {100 * counts[Status.OK] / status.size:.1f}"
                 " % of beam pings")


STILL = 1e-3  # m/s: a current slower than this horizontally flows toward nowhere


def toward_deg(current_ned: np.ndarray) -> np.ndarray:
    """(N,) the direction a current flows toward, deg from north in [0, 360), as
    ``auvsim inspect`` gives it, of its (N, 3) NED velocity, m/s; NaN where its horizontal
    speed is under ``STILL`` (still water has no direction: arctan2 would say 0)."""
    toward = np.degrees(np.arctan2(current_ned[:, 1], current_ned[:, 0])) % 360
    return np.where(np.hypot(current_ned[:, 0], current_ned[:, 1]) < STILL, np.nan, toward)


def _legend_beside(ax, *more, handles=None) -> None:
    """The legend of ``ax`` (and of its twin axes ``more``) to the right of the panel,
    where it hides no data."""
    if handles is None:
        handles = [h for a in (ax, *more) for h in a.get_legend_handles_labels()[0]]
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0),
              borderaxespad=0.0, frameon=False)
    if more:  # beside the twin's tick labels, not over them
        ax.get_legend().set_bbox_to_anchor((1.12, 1.0))


def _draw_water(m: Mission, ax_current, ax_error) -> None:
    """The current at the vehicle (horizontal speed and the direction it flows toward)
    and the DVL's error velocity."""
    t, current = m.truth.time, m.truth.current_ned
    ax_current.plot(t, np.hypot(current[:, 0], current[:, 1]), label="horizontal speed")
    ax_current.plot(t, current[:, 2], lw=0.8, label="down")
    ax_current.set_xlabel("time, s")
    ax_current.set_ylabel("m/s")
    twin = ax_current.twinx()
    # The direction in its own colour, with the right axis it reads on: in black it
    # looked like a third speed on the left axis.
    twin.plot(t, toward_deg(current), ".", color="tab:green", ms=1.5,
              label="toward (right axis)")
    twin.set_ylim(0, 360)
    twin.set_yticks([0, 90, 180, 270, 360])
    twin.set_ylabel("flowing toward, deg from north", color="tab:green")
    twin.tick_params(axis="y", colors="tab:green")
    ax_current.set_title("current at the vehicle (truth/current_ned)")
    _legend_beside(ax_current, twin)

    t_dvl = m.dvl.time
    if "error_velocity" in m.dvl:
        error = m.dvl.error_velocity
        ax_error.plot(t_dvl, error, ".", ms=2)
        finite = error[np.isfinite(error)]
        rms = float(np.sqrt(np.mean(finite**2))) if finite.size else float("nan")
        ax_error.set_title(f"DVL error velocity (dvl/error_velocity), rms {rms:.3g} m/s")
    else:
        ax_error.set_title("no error velocity in this file")
    ax_error.set_xlabel("time, s")
    ax_error.set_ylabel("m/s")
