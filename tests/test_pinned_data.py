"""What must not move without a schema version and a word in the change: the realistic
presets' data and their missions' seeds.

A pin, not a known answer: the arrays below are what this code wrote for a 500 s
``navigator`` mission (every DVL failure and error on, among them a dead beam from 300 s
and lost lock, so water track, from 450 s; a navigation-grade IMU), kept in
``tests/data/pinned-navigator.npz``. A change that moves a random draw (a wider block in
``Dvl.effects``, a stream spawned in another order) changes them by the size of the noise;
the machine's floating point, by far less than the tolerance. A deliberate change of the
data rewrites the file, ``python tests/test_pinned_data.py --write``, and says so
(``benchmarks/same_data.py`` names the arrays that moved). The paper presets have their
own, stricter check against the code that first wrote them
(``tests/test_protocol_unchanged.py``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
from auvsim.sensors.dvl import Mode, Status

PINNED = Path(__file__).resolve().parent / "data" / "pinned-navigator.npz"
DURATION = 500.0  # s: long enough for every kind of loss, and water track
# Each field pinned, and the step it is kept at: the IMU and truth at 1 Hz (every 100th
# sample), depth at 1 Hz (every 10th), the DVL at every ping.
FIELDS = {"dvl/beam_velocity": 1, "dvl/beam_range": 1, "dvl/status": 1, "dvl/mode": 1,
          "imu/specific_force": 100, "imu/angular_rate": 100, "depth/depth": 10,
          "truth/position_ned": 100}

# The manoeuvre presets seed mission i of their list by position: appending a manoeuvre
# keeps these, inserting one reseeds every later mission (docs/ARCHITECTURE.md).
MANEUVERS = ("straight", "turning_circle", "zigzag_10_10", "zigzag_20_20", "lawnmower",
             "depth_steps", "yoyo", "speed_steps", "spiral_dive", "random_waypoints")
REALISTIC = [pair for i, name in enumerate(MANEUVERS)
             for pair in ((name, 200 + i), (f"{name}_slow", 300 + i))]
SEEDS = {"maneuvers": [(name, 100 + i) for i, name in enumerate(MANEUVERS)],
         "realistic-maneuvers": REALISTIC, "sim2real": REALISTIC}


def arrays(path: Path) -> dict[str, np.ndarray]:
    """``FIELDS`` of the file's one mission, each at its step."""
    with h5py.File(path, "r") as f:
        (mission,) = f["missions"].values()
        return {name: mission[name][::step] for name, step in FIELDS.items()}


def written(tmp: Path) -> dict[str, np.ndarray]:
    out = tmp / "navigator.h5"
    generate(preset("navigator").with_duration(DURATION), out, workers=1, progress=False)
    return arrays(out)


def test_the_navigator_preset_writes_the_pinned_data(tmp_path):
    pinned = np.load(PINNED)
    got = written(tmp_path)
    assert set(pinned.files) == set(got)
    assert set(np.unique(got["dvl/status"])) >= {Status.DROPOUT, Status.PING_DROPOUT,
                                                  Status.BEAM_FAILED, Status.LOCK_LOST}
    assert (got["dvl/mode"] == Mode.WATER_TRACK).any()
    for name, value in got.items():
        if value.dtype.kind == "f":
            np.testing.assert_allclose(value, pinned[name], rtol=1e-7, atol=1e-9,
                                       equal_nan=True, err_msg=name)
        else:
            np.testing.assert_array_equal(value, pinned[name], err_msg=name)


@pytest.mark.parametrize("name", sorted(SEEDS))
def test_the_manoeuvre_presets_keep_their_missions_seeds(name):
    assert [(m.name, m.seed) for m in preset(name).missions] == SEEDS[name]


if __name__ == "__main__" and sys.argv[1:] == ["--write"]:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        np.savez_compressed(PINNED, **written(Path(tmp)))
    print(f"wrote {PINNED}")
