"""The experiments' sizes and default data folders, which the command line shows in its
help and uses where a flag is not given: here, apart from the experiments (which train,
and so load PyTorch), so that the command line loads without PyTorch and its model-based
commands run there (``beamsnet.estimators.registry.NO_TORCH``). Each experiment's module
reads its own from here."""

from __future__ import annotations

from pathlib import Path

from auvsim.runs.presets import PAPER_NOISE_CODE, PAPER_NOISE_TEXT

SHARED_DATA = Path(__file__).resolve().parents[3] / "shared" / "data"

# ``reproduce snapir`` and ``sim2real``: the Snapir's DVL velocity streams.
DEFAULT_SNAPIR = SHARED_DATA / "snapir"
# Seeds per network. Each costs minutes of a core (10,000 pings x 50 epochs at batch 4),
# so: on the sea data (``reproduce snapir``, whose runs the V.npy column reuses) 5 for
# BeamsNetV2, whose seed spread is part of the question, 3 for the others; 3 on the
# auvsim set flown with the Snapir's mounting (the spread, and whether any seed is worse
# than LS), 1 on the set with the DVL along the body (what the frame costs).
SIM2REAL_SEEDS = {"v2": 5, "v2-paper": 3, "corr": 3}
SIM_SEEDS = 3
BODY_SEEDS = 1
SIM2REAL_DURATION = 300.0  # s per manoeuvre of the generated training sets: 4,500 pings

# ``sea`` and ``adaptive``: a folder of A-KIT logs.
DEFAULT_SEA = SHARED_DATA / "snapir-akit"
# s per manoeuvre of the auvsim training set: 20 missions (10 manoeuvres at 2 and 0.8
# m/s), 4,897 samples, generated in 11 s; 3,668 of them train, and CorrectionNet takes
# 3,668 x 50 epochs / 816 samples/s = 3.7 min of a core per seed (measured: ``beamsnet
# train`` at 3 epochs, 18 s), so 3 seeds on 2 cores (two rounds) and the import,
# check-log and the filters (about a minute) make 9-10 min on 2 free cores.
SEA_DURATION = 300.0
SEA_SEEDS = 3  # CorrectionNet seeds, every one scored

ADAPTIVE_DURATION = 300.0  # s per manoeuvre of the training and held-out sets
# Noise models trained, each from its own seed, every one scored: at sea their median
# gains over the fixed filter spread several times wider over nine seeds than over the
# first three (reports/adaptive.md, "Every seed"); nine show the spread that three hid.
ADAPTIVE_SEEDS = 9

# ``stress``: the beam noise of the generated data: the straight-line preset trained on,
# the manoeuvres' noise (m/s) and their file's suffix.
NOISE = {"code": ("paper-sim", PAPER_NOISE_CODE, ""),
         "text": ("paper-sim-text", PAPER_NOISE_TEXT, "-text")}
# The generated datasets' sizes: s per speed of paper-sim, s per manoeuvre.
TRAIN_DURATION = 1800.0
MANEUVER_DURATION = 600.0
# ``stress --faults``: the default test set: s per manoeuvre, and which manoeuvres of the
# maneuvers preset (a straight line, a steady turn, a hard zigzag and random waypoints
# span the stress test's range of intensity). 16 datasets of 4 x 300 s take about 3
# minutes to generate on 2 cores.
FAULT_DURATION = 300.0
FAULT_MISSIONS = ("straight", "turning_circle", "zigzag_20_20", "random_waypoints")
