"""``Mission.to_xarray``: every group an xarray Dataset on its own clock.

Checked against the file itself, read with h5py (not through the reader): every field of a
small simulated mission, of a recorded one (a CSV log of ``test_recorded``) and of an
imported DVL stream comes back bit for bit on its own group's time, with the schema's
units and descriptions; slicing by time and resampling give what numpy gives on the
file's arrays.
"""

from __future__ import annotations

import sys

import h5py
import numpy as np
import pytest
from conftest import flat
from test_recorded import csv_log, run_csv

from auvsim.config import DvlConfig, MissionConfig, ScenarioConfig
from auvsim.data.importer import import_velocity
from auvsim.data.reader import open_dataset
from auvsim.data.schema import recorded_schema, schema
from auvsim.errors import AuvsimError

pytest.importorskip("xarray")


@pytest.fixture(scope="module")
def simulated(dataset_of):
    turning = MissionConfig(name="mission_000", seed=3,
                            scenario=ScenarioConfig(name="zigzag", duration=10.0))
    return dataset_of(flat(turning), "xarray_sim")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("xarray_rec")
    csv_log(folder / "dive")
    out = folder / "dive.h5"
    assert run_csv(folder / "dive", out) == (0, "")
    return out


def file_fields(path, name: str) -> tuple[dict[str, np.ndarray], dict]:
    """Every dataset of mission ``name`` by path, and its attributes, read with h5py."""
    with h5py.File(path, "r") as f:
        group = f["missions"][name]
        # By name: truth/time and imu/time are one dataset (a hard link), listed twice.
        arrays = {f"{g}/{k}": group[g][k][()] for g in group for k in group[g]}
        return arrays, dict(group.attrs)


def assert_views_are_the_file(views: dict, arrays: dict, attrs: dict, fields) -> None:
    """Every variable and time coordinate is the file's field its ``field`` attribute
    names, exactly (values and dtype), with the schema's units and description; every
    field of the file is in a view; the mission's attributes are on every Dataset."""
    by_path = {f.path: f for f in fields}
    seen = set()
    for group, ds in views.items():
        assert ds.attrs["group"] == group
        for key, value in attrs.items():
            np.testing.assert_array_equal(ds.attrs[key], value)
        time = ds["time"]
        # Its own clock: the group's time field, or the truth's for the controls.
        assert time.attrs["field"] == (f"{group}/time" if f"{group}/time" in arrays
                                       else "truth/time")
        assert time.attrs["units"] == "s" and time.dtype == np.float64
        for var in [time, *ds.data_vars.values()]:
            path = var.attrs["field"]
            values = arrays[path]
            assert var.dtype == values.dtype and var.shape == values.shape, path
            assert np.array_equal(var.values, values, equal_nan=values.dtype.kind == "f"), path
            assert var.dims[0] == "time"
            assert var.attrs["description"] == by_path[path].doc
            assert var.attrs.get("units", "s") == by_path[path].unit
            seen.add(path)
    assert seen == set(arrays)


def test_every_field_of_a_simulated_mission(simulated):
    arrays, attrs = file_fields(simulated, "mission_000")
    with open_dataset(simulated) as f:
        views = f.missions["mission_000"].to_xarray()
    assert sorted(views) == ["control", "depth", "dvl", "imu", "truth"]
    assert_views_are_the_file(views, arrays, attrs, schema("simulated")[0])
    dvl, truth = views["dvl"], views["truth"]
    # The IMU sample of each ping is the DVL's, on the ping's time.
    np.testing.assert_array_equal(dvl.imu_index_of_dvl, arrays["imu/index_of_dvl"])
    assert dvl.imu_index_of_dvl.attrs["field"] == "imu/index_of_dvl"
    # Components are labelled as the conventions name them.
    assert list(truth.ned.values) == ["N", "E", "D"]
    assert list(truth.component.values) == ["w", "x", "y", "z"]
    assert list(truth.axis.values) == ["x", "y", "z"] and list(dvl.beam.values) == [0, 1, 2, 3]
    np.testing.assert_array_equal(truth.position_ned.sel(ned="D"),
                                  arrays["truth/position_ned"][:, 2])
    np.testing.assert_array_equal(truth.quaternion.sel(component="w"),
                                  arrays["truth/quaternion"][:, 0])
    np.testing.assert_array_equal(truth.angular_rate.sel(axis="z"),
                                  arrays["truth/angular_rate"][:, 2])
    for k in range(4):  # beam k is column k, as dvl.beam_failures names it
        np.testing.assert_array_equal(dvl.beam_velocity.sel(beam=k),
                                      arrays["dvl/beam_velocity"][:, k])
    assert truth.position_ned.attrs["units"] == "m" and dvl.valid.attrs["units"] == "-"
    assert views["control"].thrust.attrs["units"] == "N"


def test_slicing_by_time_is_the_file_s_rows(simulated):
    arrays, _ = file_fields(simulated, "mission_000")
    with open_dataset(simulated) as f:
        views = f.missions["mission_000"].to_xarray()
    a, b = 2.5, 6.0
    t = arrays["truth/time"]
    rows = (t >= a) & (t <= b)
    part = views["truth"].sel(time=slice(a, b))
    np.testing.assert_array_equal(part.time, t[rows])
    np.testing.assert_array_equal(part.velocity_body, arrays["truth/velocity_body"][rows])
    td = arrays["dvl/time"]
    np.testing.assert_array_equal(views["dvl"].sel(time=slice(a, b)).beam_range,
                                  arrays["dvl/beam_range"][(td >= a) & (td <= b)])


def test_resampling_on_a_timedelta_time(simulated):
    arrays, _ = file_fields(simulated, "mission_000")
    with open_dataset(simulated) as f:
        truth = f.missions["mission_000"].to_xarray(timedelta=True)["truth"]
    t = arrays["truth/time"]
    # The index is the file's seconds to the nanosecond.
    ns = truth.time.values.astype(np.int64)
    assert np.abs(ns * 1e-9 - t).max() <= 0.5e-9 + 1e-15 * t.max()
    means = truth.velocity_ned.resample(time="2s").mean()
    second = np.floor(t / 2.0)
    expected = np.array([arrays["truth/velocity_ned"][second == k].mean(axis=0)
                         for k in np.unique(second)])
    np.testing.assert_allclose(means, expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(means.time.values.astype(np.int64),
                                  np.unique(second) * 2_000_000_000)
    assert means.ned.values.tolist() == ["N", "E", "D"]


def test_a_recorded_mission_has_its_reference(recorded):
    arrays, attrs = file_fields(recorded, "dive")
    with open_dataset(recorded) as f:
        m = f.missions["dive"]
        views = m.to_xarray()
        groups = m.groups
    assert sorted(views) == groups == ["depth", "dvl", "imu", "reference"]
    required, optional, _ = recorded_schema(groups)
    assert_views_are_the_file(views, arrays, attrs, required + optional)
    reference = views["reference"]
    assert "reference" in reference.attrs["description"]
    assert "not the truth" in reference.attrs["description"]
    assert reference.attrs["reference_source"] == attrs["reference_source"]
    assert list(reference.angle.values) == ["roll", "pitch", "yaw"]
    # Each stream on its own clock: the IMU at 100 Hz, the DVL at 2 Hz.
    assert len(views["imu"].time) == 200 and len(views["dvl"].time) == 4


def test_an_imported_dvl_stream(tmp_path):
    velocity = np.column_stack([np.linspace(1.0, 1.5, 50), np.full(50, -0.2), np.zeros(50)])
    np.save(tmp_path / "V.npy", velocity.T)  # (3, n), the paper's layout
    out = tmp_path / "imported.h5"
    import_velocity([tmp_path / "V.npy"], out, dvl=DvlConfig())
    arrays, attrs = file_fields(out, "V")
    with open_dataset(out) as f:
        views = f.missions["V"].to_xarray()
    assert list(views) == ["dvl"]
    assert_views_are_the_file(views, arrays, attrs, schema("imported")[0])
    np.testing.assert_array_equal(views["dvl"].velocity.sel(axis="x"), velocity[:, 0])


def test_the_beam_dvl_beam_failures_names_is_the_beam_of_that_label(dataset_of):
    dead = MissionConfig(name="mission_000", seed=3,
                         scenario=ScenarioConfig(name="straight", duration=5.0))
    path = dataset_of(flat(dead, dvl=DvlConfig(beam_failures=((2, 0.0, 10.0),))), "dead")
    with open_dataset(path) as f:
        dvl = f.missions["mission_000"].to_xarray()["dvl"]
    assert not dvl.valid.sel(beam=2).any()
    assert dvl.valid.drop_sel(beam=2).all()


def test_without_xarray_one_line_names_the_extra(simulated, monkeypatch):
    monkeypatch.setitem(sys.modules, "xarray", None)  # import fails
    with open_dataset(simulated) as f, pytest.raises(AuvsimError) as e:
        f.missions["mission_000"].to_xarray()
    assert str(e.value) == ("Mission.to_xarray needs xarray, which is not installed: "
                            "expected pip install 'auvsim[io]'")
