"""What ``auvsim inspect`` prints: a dataset summarised in words and numbers.

Each mission gets its own lines (scenario, seed, gravity, manoeuvre phases), each sensor
plugin's (``auvsim.sensors.Sensor.describe``, for the sensors whose group it holds) and
the water's; then the fields of the first mission. A recorded mission (a real vehicle's
logs) gets its origin, its reference (named as one) and each stream with its rate.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from auvsim.data.files import leftovers, leftovers_note, sweep
from auvsim.data.reader import Group, Mission, open_dataset
from auvsim.data.schema import SHARDS
from auvsim.sensors import registry

MAX_PHASES = 6  # phases listed per mission; a lawnmower's legs would fill the screen


def describe(path: str | os.PathLike) -> str:
    """A human-readable summary of a dataset: missions, durations, each sensor's rate,
    usable data and realised error parameters, the current, and the fields. Every field
    is read (and every shard's seal checked), so a corrupt one is refused here
    (``DatasetError``). Temporaries that ended runs left beside the data are removed
    (``auvsim.data.files.leftovers``); any others are named in a last line, with the
    command that removes them. A sharded run's folder is swept before it is opened, so
    the temporaries of a run killed before it wrote its index go too."""
    if Path(path).is_dir():
        sweep(path)
        sweep(Path(path) / SHARDS)
    with open_dataset(path, verify=True) as f:
        sharded = f" in {len(f.shards)} shard(s) of {f.path.parent / SHARDS}" if f.shards \
            else ""
        lines = [f"{path}: auvsim dataset v{f.version} "
                 f"(auvsim {f.attrs.get('auvsim_version', '?')}, created "
                 f"{f.attrs.get('created_utc', '?')}), {len(f.missions)} mission(s)"
                 + sharded]
        commanded = _commanded(f.config_json)
        # In the config's order (a preset's), where the file has one; else the file's.
        names = [n for n in commanded if n in f.missions]
        names += [n for n in f.missions if n not in commanded]
        for name in names:
            m = f.missions[name]
            if m.origin == "recorded":
                lines += _recorded(name, m)
                continue
            lines += _mission(name, m, commanded.get(name, ""))
            for sensor in registry().values():
                if m.has(sensor.name):
                    lines += sensor.describe(m)
            lines += _water(m)
        first = next(iter(f.missions.values()), None)
        if first is not None:
            lines.append("  fields of each mission:")
            for group in first.groups:
                lines.append(f"    {group}: " + ", ".join(sorted(Group(first, group))))
        lines.append(f"  data SHA-256: {f.digest()} (every mission's attributes and fields: "
                     "the same for the same data, however and wherever written; the file's "
                     "bytes also hold when it was made)")
        if f.shards:
            left = leftovers(f.path.parent) + leftovers(f.path.parent / SHARDS)
        else:
            left = leftovers(f.path.parent, name=f.path.name)
        if left:
            lines.append(leftovers_note(left))
        return "\n".join(lines)


def _commanded(config_json: str) -> dict[str, str]:
    """Mission name -> what its scenario commands, in words (``at 2 m/s, heading 30 deg,
    20 m deep``), from a dataset's stored config, in its order ({} without one)."""
    try:
        missions = json.loads(config_json)["missions"] if config_json else []
        return {m["name"]: f"at {m['scenario']['speed']:g} m/s, heading "
                           f"{m['scenario']['heading_deg']:g} deg, {m['scenario']['depth']:g} m "
                           "deep" for m in missions}
    except (ValueError, KeyError, TypeError):  # a config of another shape: not said
        return {}


def _mission(name: str, m: Mission, commanded: str = "") -> list[str]:
    a = m.attrs
    if m.origin == "imported":
        return [f"  {name}: imported from {a['source_file']} (sha256 "
                f"{a['source_sha256'][:12]}...), seed {a['seed']}, {a['duration_s']:g} s; no "
                "truth, IMU or controls"]
    gravity = m.gravity
    place = ""
    if "latitude_deg" in a:  # a geographic origin (schema v7)
        lat, lon = float(a["latitude_deg"]), float(a["longitude_deg"])
        place = (f", at {abs(lat):g} deg {'N' if lat >= 0 else 'S'}, {abs(lon):g} deg "
                 f"{'E' if lon >= 0 else 'W'} (the rotating Earth)")
    lines = [f"  {name}: {a['scenario']}" + (f" {commanded}" if commanded else "")
             + f", seed {a['seed']}, {a['duration_s']:g} s, vehicle "
             f"{a['vehicle']}" + (f", gravity {gravity:g} m/s^2" if gravity else "") + place]
    phases = m.phases
    if phases:
        listed = ", ".join(f"{label} {start:g}-{end:g} s"
                           for start, end, label in phases[:MAX_PHASES])
        more = f" (and {len(phases) - MAX_PHASES} more)" if len(phases) > MAX_PHASES else ""
        lines.append(f"    phases: {listed}{more}")
    return lines


def _recorded(name: str, m: Mission) -> list[str]:
    """A recorded mission: where it was, what its reference is, and each stream's rows,
    rate, span and what the import applied to it."""
    a = m.attrs
    files = json.loads(a["source_files"])
    lines = [f"  {name}: recorded, {a['duration_s']:g} s, from {len(files)} file(s) "
             f"({', '.join(Path(p).name for p in files)}); origin {a['latitude_deg']:.6f} deg "
             f"N, {a['longitude_deg']:.6f} deg E, height {a['height_m']:.2f} m; WGS-84 gravity "
             f"there {a['gravity']:.5f} m/s^2"]
    for group in json.loads(a["groups"]):
        t = getattr(m, group).time
        head = (f"    {group}: {len(t)} samples at {a[f'{group}_rate_hz']:.4g} Hz, {t[0]:g} to "
                f"{t[-1]:g} s, time offset {a[f'{group}_time_offset_s']:g} s")
        if group == "imu":
            head += (f", at {_vec(a['imu_position_body'])} m (body); spec: accelerometer "
                     f"noise {a['imu_accel_noise_density']:.3g} m/s^2/sqrt(Hz), gyro noise "
                     f"{a['imu_gyro_noise_density']:.3g} rad/s/sqrt(Hz)")
        elif group == "dvl":
            v = m.dvl.velocity_ls
            lock = 100 * np.isfinite(v).all(axis=1).mean()
            beams = ("no beams in the log (derived beams would be H v)"
                     if a["dvl_beams_derived"] else "beams as logged")
            head += (f", at {_vec(a['dvl_position_body'])} m (body); velocity in {lock:.1f} % "
                     f"of pings; {beams}; spec: beam noise {a['dvl_noise_std']:g} m/s, "
                     f"velocity accuracy {a['dvl_velocity_accuracy']:g} m/s")
        elif group == "reference":
            ref = m.reference
            pos = ref.position_ned
            track = float(np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1).sum())
            attitude = "with attitude" if "quaternion" in ref else "WITHOUT attitude"
            head = (f"    reference (a navigation solution, not the truth): "
                    f"{a['reference_source']}; " + head.split(": ", 1)[1]
                    + f"; track {track:.0f} m, ends {pos[-1, 0]:.1f} m N, {pos[-1, 1]:.1f} m E,"
                    f" {pos[-1, 2]:.1f} m down of the origin; {attitude}")
        lines.append(head)
    return lines


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:g}" for x in np.asarray(v)) + ")"


def _water(m: Mission) -> list[str]:
    """The current the mission was drawn (schema v4) and met at the vehicle."""
    a, lines = m.attrs, []
    if "water_surface_speed" in a:
        lines.append(f"    water: surface current {a['water_surface_speed']:.3f} m/s toward "
                     f"{a['water_direction_deg'] % 360:.0f} deg (drawn for the mission)")
    if m.has("truth") and "current_ned" in m.truth:
        current = m.truth.current_ned
        speed = np.hypot(current[:, 0], current[:, 1])
        mean = current.mean(axis=0)
        toward = np.degrees(np.arctan2(mean[1], mean[0])) % 360
        lines.append(f"    current at the vehicle: {speed.min():.3f} to {speed.max():.3f} m/s "
                     f"(mean {np.hypot(mean[0], mean[1]):.3f} m/s toward {toward:.0f} deg)")
    return lines
