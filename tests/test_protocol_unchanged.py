"""The paper's presets keep the paper's protocol (issue 10, item 6).

``paper-sim``, ``paper-sim-text`` and ``maneuvers`` change only through the corrected
vehicle models. With the models switched back to the old values (the model files of the
commit before the change, kept in ``tests/data/models-v3``), today's code must write
exactly the arrays the old code wrote: no current, no disturbance, no new DVL or IMU
effect may leak into them. The old code is the commit's own tree (``git archive``), run in
a subprocess with the same interpreter.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
from pathlib import Path

import h5py
import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
OLD_COMMIT = "eaebb92"  # the last commit before the realism of issue 10
OLD_MODELS = Path(__file__).resolve().parent / "data" / "models-v3"
CASES = {  # preset -> the generate flags both sides run
    "paper-sim": ["--preset", "paper-sim", "--duration", "30"],
    "paper-sim-text": ["--preset", "paper-sim-text", "--duration", "30"],
    "maneuvers": ["--preset", "maneuvers", "--duration", "30"],
}


def _old_tree(tmp: Path) -> Path:
    """The old commit's package, unpacked into ``tmp`` (skips without git history)."""
    archive = tmp / "old.tar"
    try:
        subprocess.run(["git", "-C", str(REPO), "archive", "-o", str(archive), OLD_COMMIT,
                        "auvsim", "models"], check=True, capture_output=True)
    except (OSError, subprocess.CalledProcessError) as e:
        pytest.skip(f"needs the git history of commit {OLD_COMMIT}: {e}")
    tree = tmp / "old"
    with tarfile.open(archive) as tar:
        tar.extractall(tree, filter="data")
    return tree


def _generate(tree: Path, flags: list[str], out: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(tree))
    subprocess.run([sys.executable, "-m", "auvsim.cli", "generate", *flags, "--workers", "1",
                    "--out", str(out), "--quiet"], check=True, env=env, cwd=out.parent,
                   capture_output=True)


def _arrays(path: Path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()])
                     if isinstance(obj, h5py.Dataset) else None)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("preset", CASES)
def test_paper_presets_with_the_old_models_write_the_old_arrays(preset, tmp_path_factory):
    tmp = tmp_path_factory.getbasetemp() / "protocol"
    tmp.mkdir(exist_ok=True)
    old_tree = tmp / "old"
    if not old_tree.exists():
        _old_tree(tmp)
    old, new = tmp / f"{preset}-old.h5", tmp / f"{preset}-new.h5"
    vehicle = str(OLD_MODELS / "auv.xml")
    _generate(old_tree, CASES[preset], old)
    _generate(REPO, [*CASES[preset], "--vehicle", vehicle], new)
    before, after = _arrays(old), _arrays(new)
    assert set(before) <= set(after), "the new file lacks fields of the old one"
    for name, value in before.items():
        np.testing.assert_array_equal(after[name], value, err_msg=name)
    assert len(before) >= 23  # every mission's truth, controls, IMU and DVL fields
