"""What the realism costs: ``generate`` with every effect of issue 10 on, against the same
command with every new effect off, and against a bare MuJoCo stepping loop.

Side by side and alternating, in one run (these machines are noisy), for the same missions:

* ``bare``: a plain Python loop of ``mujoco.mj_step`` on the same model for the same number
  of physics steps (no forces, no recording, no gravity);
* ``off``: ``generate`` of the preset with every setting added since schema v3 at its
  default: still water, no disturbance, and the DVL and IMU error models of v3 (the
  preset's own v3 settings kept: rates, beam angle, ranges, eq. 7 errors, IMU noise and
  biases, the terrain);
* ``on``: ``generate`` of the preset as it is: currents, disturbances, every DVL failure
  and error, the IMU's scale factors, misalignments and g-sensitivity.

CPU seconds of this process, one worker (the physics thread included). Targets (issue 10,
item 9): on <= 3x bare, on <= 1.25x off.

    .venv/bin/python benchmarks/realism.py [--preset navigator] [--duration 1800]
        [--repeats 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
from pathlib import Path

import mujoco
import perf_page
from generation import cpu_seconds  # the sibling script (its directory is on sys.path)

from auvsim.config import Config
from auvsim.physics.vehicle import model_path
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset

# The settings each section had in schema v3 (auvsim before issue 10): ``off`` keeps
# these from the preset and puts every other field at its default.
V3_FIELDS = {
    "vehicle": ("model", "net_buoyancy", "current_ned"),
    "seafloor": ("kind", "depth", "roughness", "correlation_length", "slope_deg",
                 "slope_heading_deg", "heightmap", "cell_size"),
    "dvl": ("rate_hz", "beam_angle_deg", "mounting_rpy_deg", "min_range", "max_range",
            "scale_factor", "scale_factor_std", "bias", "bias_std", "noise_std"),
    "imu": ("rate_hz", "accel_noise_density", "gyro_noise_density", "accel_turn_on_bias",
            "gyro_turn_on_bias", "accel_bias_instability", "gyro_bias_instability",
            "bias_correlation_time"),
    "depth": ("rate_hz", "noise_std", "bias_std", "resolution"),
}


def effects_off(config: Config) -> Config:
    """``config`` with every section reduced to its v3 settings (the rest at defaults)."""
    changes = {}
    for f in dataclasses.fields(config):
        section = getattr(config, f.name)
        if not dataclasses.is_dataclass(section):
            continue
        keep = V3_FIELDS.get(f.name, ())
        changes[f.name] = type(section)(**{k: getattr(section, k) for k in keep})
    return dataclasses.replace(config, **changes)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="navigator")
    parser.add_argument("--duration", type=float, default=1800.0, help="s per mission")
    parser.add_argument("--repeats", type=int, default=3, help="alternating runs; medians")
    perf_page.add_write_option(parser, "realism")
    args = parser.parse_args()

    on = preset(args.preset).with_duration(args.duration)
    off = effects_off(on)
    simulated = sum(m.scenario.duration for m in on.missions)
    model = mujoco.MjModel.from_xml_path(str(model_path(on.vehicle.model)))
    model.opt.gravity[:] = 0.0  # the bare body floats instead of falling
    data = mujoco.MjData(model)
    steps = round(simulated / model.opt.timestep)

    def bare() -> None:
        mujoco.mj_resetData(model, data)
        for _ in range(steps):
            mujoco.mj_step(model, data)

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.h5"
        runs = {"bare": bare,
                "off": lambda: generate(off, out, workers=1, progress=False),
                "on": lambda: generate(on, out, workers=1, progress=False)}
        runs["off"]()  # loads the compiled kernels from numba's cache once
        runs["on"]()
        times: dict[str, list[float]] = {name: [] for name in runs}
        for _ in range(args.repeats):
            for name, fn in runs.items():
                times[name].append(cpu_seconds(fn))

    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"preset {args.preset}, {len(on.missions)} mission(s) of {args.duration:g} s, "
          f"{steps} physics steps, median of {args.repeats} alternated runs (CPU seconds)")
    print(f"{'':6s} {'CPU s':>8s} {'x real time':>12s} {'x bare':>8s} {'x off':>8s}")
    for name, t in med.items():
        print(f"{name:6s} {t:8.3f} {simulated / t:12.0f} {t / med['bare']:8.2f} "
              f"{t / med['off']:8.2f}")
    on_bare, on_off = med["on"] / med["bare"], med["on"] / med["off"]
    print(f"targets: on <= 3x bare -> {on_bare:.2f}, {'met' if on_bare <= 3 else 'MISSED'}; "
          f"on <= 1.25x off -> {on_off:.2f}, {'met' if on_off <= 1.25 else 'MISSED'}")


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
