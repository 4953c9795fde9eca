"""Compile the numba kernels into their cache before the tests start (``make test`` runs
this beside the documentation build).

numba compiles a kernel at its first call and caches it beside the source (``cache=True``).
On a fresh clone every process that calls a kernel before some process has written its
cache compiles it too: the simulator's kernels take about 17 s, the INS/DVL filter's
about 38 s, and the two test workers, the commands the tests start and their worker
processes would each pay it at the start of the run. Here they are compiled once, through
the calls the tests make: a short ``navigator`` mission (every sensor effect on) and the
filter on it, on its beams and on its velocity.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from auvsim.data.reader import open_dataset
from auvsim.runs.generate import generate
from auvsim.runs.presets import preset
from beamsnet.estimators.ins import run_mission


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "kernels.h5"
        generate(preset("navigator").with_duration(20.0), path, workers=1, progress=False)
        with open_dataset(path) as f:
            for mission in f.missions.values():
                for measurements in ("auto", "velocity"):
                    run_mission(mission, measurements=measurements)


if __name__ == "__main__":
    main()
