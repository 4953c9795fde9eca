"""``benchmarks/same_data.py``, the check that a change keeps the presets' data array by
array: what it says of two arrays that differ."""

from __future__ import annotations

import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import same_data  # noqa: E402


def test_a_differing_array_is_named_by_its_first_row_and_its_largest_difference(tmp_path):
    """Rows are read in blocks; the first differing row is the first block's, the largest
    difference is over every block (a NaN on one side only counts as infinite)."""
    rows = 2_000_000  # rows per block at two columns (4e6 values a block)
    before = np.zeros((rows + 10, 2))
    after = before.copy()
    after[5, 0] = 1e-9
    after[rows + 3, 1] = 2e-6  # in the second block
    same, nan = tmp_path / "same.h5", tmp_path / "nan.h5"
    with h5py.File(tmp_path / "a.h5", "w") as f, h5py.File(tmp_path / "b.h5", "w") as g, \
            h5py.File(same, "w") as s, h5py.File(nan, "w") as n:
        f["x"], g["x"], s["x"] = before, after, before
        with_nan = before.copy()
        with_nan[7, 1] = np.nan
        n["x"] = with_nan
    with h5py.File(tmp_path / "a.h5") as f, h5py.File(tmp_path / "b.h5") as g, \
            h5py.File(same) as s, h5py.File(nan) as n:
        assert same_data.datasets_equal(f["x"], g["x"]) == \
            "values differ (first at row 5, max |diff| 2e-06)"
        assert same_data.datasets_equal(f["x"], s["x"]) is None
        assert same_data.datasets_equal(f["x"], n["x"]) == \
            "values differ (first at row 7, max |diff| inf)"
