"""What ``auvsim inspect`` prints: a dataset summarised in words and numbers."""

from __future__ import annotations

import os

import numpy as np

from auvsim.data.reader import Group, Mission, open_dataset
from auvsim.data.schema import SHARDS


def _describe_v4(m: Mission, a: dict, fmt) -> list[str]:
    """The lines of what schema v4 added, where the mission has it: the DVL's realised
    calibration, its beams' status codes, modes and error velocity, and the current."""
    from auvsim.sensors.dvl import Mode, Status

    lines = []
    if "dvl_sound_speed_ratio" in a:
        lines.append(f"    DVL calibration: sound-speed ratio {a['dvl_sound_speed_ratio']:.6f}, "
                     f"misalignment {fmt(a['dvl_misalignment_rpy_deg'])} deg (roll, pitch, "
                     "yaw)")
    dvl = m.dvl
    if "status" in dvl:
        status = dvl.status
        counts = np.bincount(status.ravel().clip(0, len(Status) - 1), minlength=len(Status))
        shares = ", ".join(f"{Status(code).name.lower()} {100 * n / status.size:.1f} %"
                           for code, n in enumerate(counts) if n)
        lines.append(f"    DVL beam status: {shares}")
    if "mode" in dvl:
        mode = dvl.mode
        shares = ", ".join(f"{x.name.lower().replace('_', ' ')} "
                           f"{100 * np.mean(mode == x):.1f} %" for x in Mode)
        error = dvl.error_velocity
        finite = error[np.isfinite(error)]
        rms = f"{np.sqrt(np.mean(finite**2)):.3g} m/s" if finite.size else "none"
        lines.append(f"    DVL modes: {shares}; error velocity rms {rms} over "
                     f"{finite.size} four-beam pings")
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


def describe(path: str | os.PathLike) -> str:
    """A human-readable summary of a dataset: missions, durations, rates, DVL validity,
    the realised error parameters and the fields. Every field is read, so a corrupt one
    is refused here (``DatasetError``)."""
    def fmt(values) -> str:
        return np.array2string(np.asarray(values), precision=6, separator=", ")

    with open_dataset(path, verify=True) as f:
        sharded = f" in {len(f.shards)} shard(s) of {f.path.parent / SHARDS}" if f.shards \
            else ""
        lines = [f"{path}: auvsim dataset v{f.version} "
                 f"(auvsim {f.attrs.get('auvsim_version', '?')}, created "
                 f"{f.attrs.get('created_utc', '?')}), {len(f.missions)} mission(s)"
                 + sharded]
        for name, m in f.missions.items():
            a = m.attrs
            valid = m.dvl.valid
            solvable = (f"{100 * valid.mean():.1f} % of beams valid, "
                        f"{100 * (valid.sum(axis=1) >= 3).mean():.1f} % of pings solvable")
            if m.origin == "imported":
                lines += [
                    f"  {name}: imported from {a['source_file']} (sha256 "
                    f"{a['source_sha256'][:12]}...), seed {a['seed']}, {a['duration_s']:g} s",
                    f"    DVL {a['dvl_rate_hz']:g} Hz ({len(valid)} pings), beams at "
                    f"{a['beam_angle_deg']:g} deg, {solvable}; no truth, IMU or controls",
                ]
            else:
                lines += [
                    f"  {name}: {a['scenario']}, seed {a['seed']}, {a['duration_s']:g} s, "
                    f"vehicle {a['vehicle']}",
                    f"    IMU {a['imu_rate_hz']:g} Hz ({m.imu.rows} samples); DVL "
                    f"{a['dvl_rate_hz']:g} Hz ({len(valid)} pings), beams at "
                    f"{a['beam_angle_deg']:g} deg, {solvable}",
                ]
            lines.append(f"    DVL errors: scale factor {fmt(a['dvl_scale_factor'])}, bias "
                         f"{fmt(a['dvl_bias'])} m/s, noise std {a['dvl_noise_std']:g} m/s")
            lines += _describe_v4(m, a, fmt)
            if "imu_accel_turn_on_bias" in a:
                lines.append(
                    f"    IMU errors: accel turn-on bias {fmt(a['imu_accel_turn_on_bias'])} "
                    f"m/s^2, gyro {fmt(a['imu_gyro_turn_on_bias'])} rad/s; noise densities "
                    f"{a['imu_accel_noise_density']:.3g} m/s^2/rtHz, "
                    f"{a['imu_gyro_noise_density']:.3g} rad/s/rtHz")
            if "imu_accel_scale_factor" in a:  # v4
                largest = {k: f"{np.max(np.abs(a[f'imu_{k}'])):.3g}" for k in (
                    "accel_misalignment", "gyro_misalignment", "gyro_g_sensitivity")}
                lines.append(
                    f"    IMU calibration: scale factors accel "
                    f"{fmt(a['imu_accel_scale_factor'])}, gyro {fmt(a['imu_gyro_scale_factor'])};"
                    f" largest misalignment accel {largest['accel_misalignment']}, gyro "
                    f"{largest['gyro_misalignment']} rad; largest g-sensitivity "
                    f"{largest['gyro_g_sensitivity']} rad/s per m/s^2; bias correlation "
                    f"times accel {a['imu_accel_bias_correlation_time']:g} s, gyro "
                    f"{a['imu_gyro_bias_correlation_time']:g} s")
            if "depth_rate_hz" in a:
                lines.append(
                    f"    depth sensor {a['depth_rate_hz']:g} Hz ({m.depth.rows} samples): "
                    f"offset {a['depth_bias']:.4g} m, noise std {a['depth_noise_std']:g} m, "
                    f"resolution {a['depth_resolution']:g} m")
        first = next(iter(f.missions.values()), None)
        if first is not None:
            lines.append("  fields of each mission:")
            for group in first.groups:
                lines.append(f"    {group}: " + ", ".join(sorted(Group(first, group))))
        return "\n".join(lines)
