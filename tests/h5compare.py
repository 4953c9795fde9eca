"""Compare two HDF5 files' contents (tests only)."""

from __future__ import annotations

import h5py
import numpy as np


def contents(path) -> dict:
    """Every dataset's values and every group's attributes, except the creation time."""
    out = {}
    with h5py.File(path, "r") as f:
        out["/"] = {k: v for k, v in f.attrs.items() if k != "created_utc"}
        f.visititems(lambda name, obj: out.__setitem__(
            name, obj[()] if isinstance(obj, h5py.Dataset) else dict(obj.attrs)))
    return out


def assert_same_contents(path_a, path_b) -> None:
    a, b = contents(path_a), contents(path_b)
    assert a.keys() == b.keys()
    for key in a:
        if isinstance(a[key], dict):
            assert a[key].keys() == b[key].keys(), key
            for k in a[key]:
                np.testing.assert_array_equal(a[key][k], b[key][k], err_msg=f"{key}:{k}")
        else:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
