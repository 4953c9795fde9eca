"""Prove that two revisions' INS/DVL filter gives the same output, array by array: a change
to the filter's code that must not change its numbers (a refactor) shows that it does not.

The inputs are made once, with the AFTER side's code, in a temporary folder:

* a 500 s ``navigator`` mission and a 300 s ``navigator`` zigzag (beams, the DVL's slow
  error, dropouts, a dead beam, lost lock, water track; the rotating Earth);
* a noise model trained briefly on the zigzag (``beamsnet.estimators.noisenet``, 1 round
  of 5 epochs), so that both sides run the learned filter with the same weights (skipped
  without PyTorch);
* where the shared A-KIT logs are (``--akit``, default ``../shared/data/snapir-akit``),
  their first two segments, imported and corrected as ``beamsnet reproduce sea`` does
  them (``auvsim import --format akit``, ``auvsim check-log --apply``).

Each side then runs, with its own code (``PYTHONPATH=tree``, ``same_data.Side``), the
filter (``beamsnet.estimators.ins.run_mission``) on every mission at every setting of
``SETTINGS``, the simulated ones in both measurement forms (the beams, the DVL's
velocity), and the learned filter once per mission, and writes every array of every
``FilterTrack`` (and its events, as text) to an ``.npz``. The two are compared array by
array: the same names, dtypes, shapes and values, NaN equal to NaN, bit for bit.

    .venv/bin/python benchmarks/filter_same.py --before REV [--after REV] [--akit DIR]
        [--keep DIR]

Exit code: 0 the same, 1 different, 2 could not run.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from same_data import REPO, RunError, Side, Trees, git, resolve

# FilterConfig settings, by name: the filter's defaults, the model-based adaptive filter,
# the gyros' matrix states, the biases holding the slow error, the 15 core states alone,
# and a stated noise far too small with an eager watch (restarts).
SETTINGS = {
    "default": {},
    "adaptive": {"adaptive": "innovation"},
    "gyro": {"gyro_matrix_states": True, "gyro_scale_factor_std": 7e-6,
             "gyro_misalignment_std": 1e-4},
    "no-slow-states": {"slow_error_states": False, "beam_states": True},
    "core": {"beam_states": False},
    "watch": {"beam_noise_std": 0.0003, "watch_share": 0.1},
}
AKIT = next((up / "shared" / "data" / "snapir-akit" for up in REPO.parents
             if (up / "shared" / "data" / "snapir-akit").is_dir()),
            REPO.parent / "shared" / "data" / "snapir-akit")

# Made with the AFTER side's code: the simulated missions and the noise model.
PREPARE = """
import dataclasses, sys
from auvsim.config import MissionConfig, ScenarioConfig
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
nav = preset("navigator")
generate(nav.with_duration(500.0), "nav.h5", workers=1, progress=False)
zigzag = MissionConfig(name="zigzag", seed=3,
                       scenario=ScenarioConfig(name="zigzag", duration=300.0))
generate(dataclasses.replace(nav, missions=(zigzag,)), "zig.h5", workers=1, progress=False)
try:
    import torch  # noqa: F401
except ModuleNotFoundError:
    sys.exit(0)
from beamsnet.estimators.noisemodel import save_noise_model
from beamsnet.estimators.noisenet import train_noise_model
save_noise_model(train_noise_model("zig.h5", rounds=1, epochs=5), "noise-model.npz")
"""

# Run by each side: every track's arrays to an .npz.
RUN = """
import json, sys
from pathlib import Path
import numpy as np
from auvsim.data.reader import open_dataset
from beamsnet.estimators import ins
out, settings, files = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3:]
model = None
if Path("noise-model.npz").is_file():
    from beamsnet.estimators.noisemodel import load_noise_model
    model = load_noise_model("noise-model.npz")
arrays = {}
def keep(tag, track):
    for name in track._fields:
        value = getattr(track, name)
        if isinstance(value, np.ndarray):
            arrays[f"{tag}/{name}"] = value
        elif name == "events":
            arrays[f"{tag}/events"] = np.array([str(e) for e in value], dtype=str)
        elif isinstance(value, (bool, int, float)):
            arrays[f"{tag}/{name}"] = np.array(value)
for path in files:
    with open_dataset(path) as ds:
        for name, m in ds.missions.items():
            recorded = m.attrs.get("origin") == "recorded"
            for label, setting in settings.items():
                for form in (("auto",) if recorded else ("auto", "velocity")):
                    track = ins.run_mission(m, ins.FilterConfig(**setting), measurements=form)
                    keep(f"{path}/{name}/{label}/{form}", track)
            if model is not None:
                track = ins.run_mission(m, ins.FilterConfig(adaptive="learned"),
                                        noise_model=model)
                keep(f"{path}/{name}/learned", track)
np.savez(out, **arrays)
print(len(arrays), "arrays")
"""


def compare(before: Path, after: Path) -> list[str]:
    """What differs between two sides' arrays: names, dtypes, shapes or values."""
    a, b = np.load(before), np.load(after)
    differ = [f"only in BEFORE: {k}" for k in sorted(set(a.files) - set(b.files))]
    differ += [f"only in AFTER: {k}" for k in sorted(set(b.files) - set(a.files))]
    for key in sorted(set(a.files) & set(b.files)):
        x, y = a[key], b[key]
        if x.dtype != y.dtype or x.shape != y.shape:
            differ.append(f"{key}: {x.dtype}{x.shape} against {y.dtype}{y.shape}")
        elif not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
            worst = np.nanmax(np.abs(x.astype(float) - y.astype(float))) \
                if x.dtype.kind in "fiub" else "text"
            differ.append(f"{key}: values differ (largest difference {worst})")
    return differ


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, metavar="REV")
    parser.add_argument("--after", metavar="REV",
                        help="default: this working tree, uncommitted changes included")
    parser.add_argument("--akit", type=Path, default=AKIT,
                        help="the shared A-KIT logs (their segments skipped if absent)")
    parser.add_argument("--keep", type=Path, metavar="DIR",
                        help="keep the inputs and both sides' arrays in DIR")
    args = parser.parse_args()
    trees = Trees()
    work = Path(tempfile.mkdtemp(prefix="filter_same-"))
    try:
        before_sha = resolve(args.before)
        before = Side("before", trees.add("before", before_sha), before_sha[:10],
                      work / "before")
        if args.after is None:
            after = Side("after", REPO, f"{git('rev-parse', '--short', 'HEAD')} + working "
                         "tree", work / "after")
        else:
            sha = resolve(args.after)
            after = Side("after", trees.add("after", sha), sha[:10], work / "after")
        for side in (before, after):
            side.check_imports()
        inputs = work / "inputs"
        print(f"making the inputs with AFTER's code ({after.describe}) ...", flush=True)
        after.run(inputs, ["-c", PREPARE], "prepare")
        files = ["nav.h5", "zig.h5"]
        if (args.akit / "Trajectory1").is_dir():
            logs = inputs / "akit"
            logs.mkdir()
            for k in (1, 2):  # the first two segments suffice to cover the recorded path
                (logs / f"Trajectory{k}").symlink_to(args.akit / f"Trajectory{k}")
            after.run(inputs, ["-m", "auvsim", "import", str(logs), "--format", "akit",
                               "--out", "logged.h5"], "import")
            after.run(inputs, ["-m", "auvsim", "check-log", "logged.h5", "--apply",
                               "sea.h5"], "check-log")
            files.append("sea.h5")
        else:
            print(f"{args.akit}: no A-KIT logs; the recorded path is not compared")
        for side in (before, after):
            print(f"running the filter with {side.label}'s code ({side.describe}) ...",
                  flush=True)
            side.run(inputs, ["-c", RUN, str(side.out / "tracks.npz"),
                              json.dumps(SETTINGS), *files], f"run-{side.label}")
        differ = compare(before.out / "tracks.npz", after.out / "tracks.npz")
        count = len(np.load(after.out / "tracks.npz").files)
        if args.keep is not None:
            shutil.copytree(work, args.keep, dirs_exist_ok=True)
        if differ:
            print(f"DIFFERENT: {len(differ)} of {count} arrays")
            for line in differ[:40]:
                print(f"    {line}")
            return 1
        print(f"SAME: {count} arrays of the filter's tracks ({', '.join(files)}; settings "
              f"{', '.join(SETTINGS)}, and the learned noise where PyTorch is) are equal, bit "
              "for bit")
        return 0
    except RunError as e:
        print(f"could not run: {e}", file=sys.stderr)
        return 2
    finally:
        trees.close()
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
