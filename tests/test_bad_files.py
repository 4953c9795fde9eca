"""Bad dataset files: ``auvsim inspect`` and ``auvsim plot`` refuse every one of them with
one line naming the file (and the mission and field, where there is one), exit 2, and
write nothing; good files, old format versions and odd but valid data still open.

Each fixture is a copy of a small good file made once per module, damaged with h5py or
plain file I/O (a flipped byte inside a checksummed chunk).
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import flat, mission, write

from auvsim.cli import main
from auvsim.config import DvlConfig
from auvsim.data.reader import open_dataset, require_usable_beams
from auvsim.errors import DatasetError

REPO = Path(__file__).resolve().parents[1]
CONFIG = flat(mission("m0", 3, speed=2.0, depth=20.0, duration=6.0),
              dvl=DvlConfig(beam_angle_deg=30.0, max_range=90.0))
M = "missions/m0"  # the simulated mission
R = "missions/rec"  # the imported mission


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> Path:
    return write(CONFIG, tmp_path_factory.mktemp("good") / "good.h5")


@pytest.fixture(scope="module")
def imported(tmp_path_factory) -> Path:
    """A dataset made by ``auvsim import-velocity`` from a small recording."""
    folder = tmp_path_factory.mktemp("imported")
    v = np.stack([np.full(20, 1.5), np.linspace(-0.2, 0.2, 20), np.full(20, 0.05)])
    np.save(folder / "rec.npy", v)  # (3, N), the paper's layout
    out = folder / "imported.h5"
    with contextlib.redirect_stdout(io.StringIO()):  # not into the first test's capsys
        assert main(["import-velocity", str(folder / "rec.npy"), "--out", str(out)]) == 0
    return out


# Damage ----------------------------------------------------------------------------------

def replace(f: h5py.File, key: str, data) -> None:
    del f[key]
    f[key] = data


def rows(f: h5py.File, key: str) -> int:
    return f[key].shape[0]


def flip_chunk_byte(path: Path, key: str) -> None:
    """Flip a byte in the middle of the first stored chunk of dataset ``key``."""
    with h5py.File(path, "r") as f:
        info = f[key].id.get_chunk_info(0)
    with open(path, "r+b") as fh:
        fh.seek(info.byte_offset + info.size // 2)
        byte = fh.read(1)[0]
        fh.seek(info.byte_offset + info.size // 2)
        fh.write(bytes([byte ^ 0xFF]))


def zero_rows(f: h5py.File, clock: str) -> None:
    """Every field of a clock of mission m0 emptied (kept its row shape and dtype)."""
    from auvsim.data.schema import schema

    for field in schema("simulated")[0]:
        if field.clock == clock:
            old = f[f"{M}/{field.path}"]
            replace(f, f"{M}/{field.path}", np.empty((0, *old.shape[1:]), dtype=old.dtype))


def delete_depth(f: h5py.File) -> None:
    """Make a schema-v2 file of a v3 one: no depth group, no depth attributes."""
    f.attrs["format_version"] = 2
    del f[f"{M}/depth"]
    for name in [a for a in f[M].attrs if a.startswith("depth_")]:
        del f[M].attrs[name]


# name -> (source file, how to damage a copy of it, what the message must name)
H5_EDITS = {
    "beams_m_by_3": ("good", lambda f: replace(f, f"{M}/dvl/beam_velocity",
                                                np.zeros((rows(f, f"{M}/dvl/time"), 3))),
                     "field dvl/beam_velocity has shape (6, 3); expected (N, 4)"),
    "beams_1d": ("good", lambda f: replace(f, f"{M}/dvl/beam_velocity", np.zeros(6)),
                 "field dvl/beam_velocity has shape (6,)"),
    "beams_scalar": ("good", lambda f: replace(f, f"{M}/dvl/beam_velocity", 1.0),
                     "field dvl/beam_velocity has shape ()"),
    "beams_3d": ("good", lambda f: replace(f, f"{M}/dvl/beam_velocity", np.zeros((6, 4, 1))),
                 "field dvl/beam_velocity has shape (6, 4, 1)"),
    "target_m_by_4": ("good", lambda f: replace(f, f"{M}/dvl/velocity", np.zeros((6, 4))),
                      "field dvl/velocity has shape (6, 4); expected (N, 3)"),
    "target_transposed": ("good", lambda f: replace(f, f"{M}/dvl/velocity", np.zeros((3, 6))),
                          "field dvl/velocity has shape (3, 6)"),
    "valid_float": ("good", lambda f: replace(f, f"{M}/dvl/valid", np.ones((6, 4))),
                    "field dvl/valid holds float64; expected bool values"),
    "valid_uint8": ("good", lambda f: replace(f, f"{M}/dvl/valid",
                                               np.ones((6, 4), dtype=np.uint8)),
                    "field dvl/valid holds uint8"),
    "index_out_of_range": ("good", lambda f: replace(
        f, f"{M}/imu/index_of_dvl", f[f"{M}/imu/index_of_dvl"][()] + rows(f, f"{M}/imu/time")),
        "field imu/index_of_dvl holds indices from"),
    "index_negative": ("good", lambda f: replace(
        f, f"{M}/imu/index_of_dvl", f[f"{M}/imu/index_of_dvl"][()] - 1),
        "field imu/index_of_dvl holds indices from -1"),
    "index_shifted": ("good", lambda f: replace(
        f, f"{M}/imu/index_of_dvl", f[f"{M}/imu/index_of_dvl"][()] + 1),
        "field imu/index_of_dvl row 0 is 1, the sample of truth/time at 0.01 s, but "
        "dvl/time is 0 s there"),
    "index_float": ("good", lambda f: replace(
        f, f"{M}/imu/index_of_dvl", f[f"{M}/imu/index_of_dvl"][()].astype(float)),
        "field imu/index_of_dvl holds float64; expected integer values"),
    "zero_truth_rows": ("good", lambda f: zero_rows(f, "imu"), "has no rows"),
    "zero_dvl_rows": ("good", lambda f: zero_rows(f, "dvl"), "field dvl/time has no rows"),
    "truth_unequal": ("good", lambda f: replace(f, f"{M}/truth/position_ned",
                                                 f[f"{M}/truth/position_ned"][:-1]),
                      "field truth/position_ned has 599 rows but truth/time has 600"),
    "dvl_unequal": ("good", lambda f: replace(f, f"{M}/dvl/velocity_ls",
                                               f[f"{M}/dvl/velocity_ls"][:-1]),
                    "field dvl/velocity_ls has 5 rows but dvl/time has 6"),
    "depth_unequal": ("good", lambda f: replace(f, f"{M}/depth/depth",
                                                 f[f"{M}/depth/depth"][1:]),
                      "field depth/depth has"),
    "time_as_strings": ("good", lambda f: replace(
        f, f"{M}/truth/time", np.array([b"0.0"] * rows(f, f"{M}/truth/time"))),
        "field truth/time holds"),
    "time_nan": ("good", lambda f: replace(f, f"{M}/dvl/time", np.where(
        np.arange(6) == 2, np.nan, f[f"{M}/dvl/time"][()])),
        "field dvl/time holds nan at row 2; expected finite sample times"),
    "time_backwards": ("good", lambda f: replace(f, f"{M}/truth/time",
                                                  f[f"{M}/truth/time"][()][::-1]),
                       "field truth/time goes from 5.99 s to 5.98 s at row 1; expected "
                       "increasing sample times"),
    "time_repeated": ("good", lambda f: replace(f, f"{M}/depth/time",
                                                 np.zeros(rows(f, f"{M}/depth/time"))),
                      "field depth/time goes from 0 s to 0 s at row 1"),
    "time_integer": ("good", lambda f: replace(f, f"{M}/dvl/time", np.arange(6)),
                     "field dvl/time holds int64; expected float values"),
    "beams_complex": ("good", lambda f: replace(f, f"{M}/dvl/beam_velocity",
                                                 np.zeros((6, 4), dtype=complex)),
                      "field dvl/beam_velocity holds complex128"),
    "field_is_a_group": ("good", lambda f: (f.__delitem__(f"{M}/dvl/valid"),
                                            f.create_group(f"{M}/dvl/valid")),
                         "lacks dvl/valid"),
    "group_is_a_dataset": ("good", lambda f: (f.__delitem__(f"{M}/control"),
                                              f.create_dataset(f"{M}/control", data=1.0)),
                           "lacks control/propeller_rpm"),
    "angle_string": ("good", lambda f: f[M].attrs.__setitem__("beam_angle_deg", "30"),
                     "attribute beam_angle_deg is '30'; expected a finite number"),
    "rate_string": ("good", lambda f: f[M].attrs.__setitem__("dvl_rate_hz", "1 Hz"),
                    "attribute dvl_rate_hz is '1 Hz'"),
    "seed_string": ("good", lambda f: f[M].attrs.__setitem__("seed", "three"),
                    "attribute seed is 'three'"),
    "config_json_broken": ("good", lambda f: f.attrs.__setitem__("config_json", "{not json"),
                           "its config_json is not a JSON dict ('{not json')"),
    "config_json_a_list": ("good", lambda f: f.attrs.__setitem__("config_json", "[1, 2]"),
                           "its config_json is not a JSON dict"),

    "rate_zero": ("good", lambda f: f[M].attrs.__setitem__("dvl_rate_hz", 0.0),
                  "attribute dvl_rate_hz is 0.0; expected a number above 0"),
    "seed_fraction": ("good", lambda f: f[M].attrs.__setitem__("seed", 1.5),
                      "attribute seed is 1.5; expected a whole number"),
    "noise_negative": ("good", lambda f: f[M].attrs.__setitem__("dvl_noise_std", -0.1),
                       "attribute dvl_noise_std is -0.1; expected a number of at least 0"),
    "seed_bytes": ("good", lambda f: f[M].attrs.__setitem__("seed", np.bytes_(b"3")),
                   "attribute seed is"),
    "scale_factor_of_3": ("good", lambda f: f[M].attrs.__setitem__("dvl_scale_factor",
                                                               np.zeros(3)),
                          "attribute dvl_scale_factor is [0. 0. 0.]; expected 4 finite"),
    "scale_factor_scalar": ("good", lambda f: f[M].attrs.__setitem__("dvl_scale_factor", 0.0),
                            "attribute dvl_scale_factor is 0.0; expected 4 finite numbers"),
    "long_vector_attr": ("good", lambda f: f[M].attrs.__setitem__("dvl_bias", np.zeros(400)),
                         "attribute dvl_bias is"),
    "nan_duration": ("good", lambda f: f[M].attrs.__setitem__("duration_s", np.nan),
                     "attribute duration_s is nan"),
    "inf_noise": ("good", lambda f: f[M].attrs.__setitem__("dvl_noise_std", np.inf),
                  "attribute dvl_noise_std is inf"),
    "nan_in_vector_attr": ("good", lambda f: f[M].attrs.__setitem__(
        "imu_position_body", np.array([0.5, np.nan, 0.0])), "attribute imu_position_body"),
    "vehicle_number": ("good", lambda f: f[M].attrs.__setitem__("vehicle", 5),
                       "attribute vehicle is 5; expected a string"),
    "missing_field": ("good", lambda f: f.__delitem__(f"{M}/dvl/beam_velocity"),
                      "lacks dvl/beam_velocity"),
    "missing_group": ("good", lambda f: f.__delitem__(f"{M}/truth"), "lacks truth/time"),
    "missing_depth_in_v7": ("good", lambda f: f.__delitem__(f"{M}/depth"),
                            "lacks depth/time, depth/depth (schema v7)"),
    "missing_attribute": ("good", lambda f: f[M].attrs.__delitem__("imu_rate_hz"),
                          "lacks attribute imu_rate_hz"),
    "missing_gravity_in_v7": ("good", lambda f: f[M].attrs.__delitem__("gravity"),
                              "lacks attribute gravity (schema v7)"),
    "negative_gravity": ("good", lambda f: f[M].attrs.__setitem__("gravity", -9.81),
                         "attribute gravity is -9.81; expected a number above 0"),
    "phases_not_json": ("good", lambda f: f[M].attrs.__setitem__("phases", "[[0.0, 5"),
                        "attribute phases is '[[0.0, 5'; expected a JSON list of [start s, "
                        "end s, label]"),
    "phases_backwards": ("good", lambda f: f[M].attrs.__setitem__(
        "phases", '[[5.0, 1.0, "straight"]]'), "attribute phases is"),
    "phases_a_number": ("good", lambda f: f[M].attrs.__setitem__("phases", "7"),
                        "expected a JSON list of [start s, end s, label] (expected a list"),
    "missions_missing": ("good", lambda f: f.__delitem__("missions"), "no missions group"),
    "missions_a_dataset": ("good", lambda f: (f.__delitem__("missions"),
                                              f.create_dataset("missions", data=[1, 2])),
                           "no missions group"),
    "mission_a_dataset": ("good", lambda f: f.create_dataset("missions/x", data=[1.0]),
                          "missions/x is not a mission group"),
    "unknown_origin": ("good", lambda f: f[M].attrs.__setitem__("origin", "dreamt"),
                       "mission m0 has origin 'dreamt'"),
    "origin_array": ("good", lambda f: f[M].attrs.__setitem__("origin", np.arange(3)),
                     "mission m0 has origin"),
    "origin_missing_v3": ("good", lambda f: f[M].attrs.__delitem__("origin"),
                          "mission m0 has no origin attribute"),
    "format_missing": ("good", lambda f: f.attrs.__delitem__("format"),
                       "not an auvsim dataset (no format attribute"),
    "format_foreign": ("good", lambda f: f.attrs.__setitem__("format", "netcdf4"),
                       "not an auvsim dataset (format attribute is 'netcdf4'"),
    "format_array": ("good", lambda f: f.attrs.__setitem__("format", np.arange(2)),
                     "not an auvsim dataset (format attribute is [0 1]"),
    "version_future": ("good", lambda f: f.attrs.__setitem__("format_version", 99),
                       "format_version 99; this auvsim reads versions 1, 2, 3, 4, 5, 6, 7"),
    "version_string": ("good", lambda f: f.attrs.__setitem__("format_version", "3"),
                       "format_version '3'"),
    "version_float": ("good", lambda f: f.attrs.__setitem__("format_version", 3.0),
                      "format_version 3.0"),
    "version_missing": ("good", lambda f: f.attrs.__delitem__("format_version"),
                        "no format_version attribute"),
    "version_zero": ("good", lambda f: f.attrs.__setitem__("format_version", 0),
                     "format_version 0"),
    "imported_beams_m_by_3": ("imported", lambda f: replace(f, f"{R}/dvl/beam_velocity",
                                                             np.zeros((20, 3))),
                              "mission rec (imported): field dvl/beam_velocity has shape "
                              "(20, 3); expected (N, 4)"),
    "imported_unequal": ("imported", lambda f: replace(f, f"{R}/dvl/valid",
                                                        f[f"{R}/dvl/valid"][:10]),
                         "mission rec (imported): field dvl/valid has 10 rows"),
    "imported_no_sha": ("imported", lambda f: f[R].attrs.__delitem__("source_sha256"),
                        "mission rec (imported) lacks attribute source_sha256"),
    "imported_zero_rows": ("imported", lambda f: [
        replace(f, f"{R}/{k}", np.empty((0, *f[f"{R}/{k}"].shape[1:]), f[f"{R}/{k}"].dtype))
        for k in [f"dvl/{n}" for n in f[f"{R}/dvl"]]], "has no rows"),
}

# name -> (source file, how to damage a copy of it (path -> None), what the message names)
RAW_EDITS = {
    "flipped_beams": ("good", lambda p: flip_chunk_byte(p, f"{M}/dvl/beam_velocity"),
                      "mission m0 (simulated): field dvl/beam_velocity fails its checksum"),
    "flipped_index": ("good", lambda p: flip_chunk_byte(p, f"{M}/imu/index_of_dvl"),
                      "field imu/index_of_dvl fails its checksum"),
    "flipped_truth_time": ("good", lambda p: flip_chunk_byte(p, f"{M}/truth/time"),
                           "field truth/time fails its checksum"),
    "flipped_imported": ("imported", lambda p: flip_chunk_byte(p, f"{R}/dvl/velocity"),
                         "mission rec (imported): field dvl/velocity fails its checksum"),
    "flipped_extra_field": ("good", lambda p: _extra_then_flip(p),
                            "field notes/log fails its checksum"),
    "empty_file": ("good", lambda p: p.write_bytes(b""), "not an HDF5 file"),
    "text_file": ("good", lambda p: p.write_text("time,velocity\n0,1\n"), "not an HDF5 file"),
    "truncated": ("good", lambda p: p.write_bytes(p.read_bytes()[:p.stat().st_size // 2]),
                  "not an HDF5 file"),
    "zeroed_superblock": ("good", lambda p: p.write_bytes(bytes(64) + p.read_bytes()[64:]),
                          "not an HDF5 file"),
    "someone_elses": ("good", lambda p: _foreign(p), "not an auvsim dataset"),
    "directory": ("good", lambda p: (p.unlink(), p.mkdir()), "is a directory"),
    "no_such_file": ("good", lambda p: p.unlink(), "no such file"),
}


def _extra_then_flip(path: Path) -> None:
    """A checksummed dataset of someone's own beside the schema's, then damaged: verifying
    reads every dataset, not only the schema's."""
    with h5py.File(path, "r+") as f:
        f.create_dataset(f"{M}/notes/log", data=np.arange(1000.0), chunks=(500,),
                         fletcher32=True)
    flip_chunk_byte(path, f"{M}/notes/log")


def _foreign(path: Path) -> None:
    path.unlink()
    with h5py.File(path, "w") as f:
        f.attrs["title"] = "ocean model output"
        f["temperature"] = np.zeros((4, 5))
        f.create_group("missions")  # even with a group of the same name


CASES = {**{k: ("h5",) + v for k, v in H5_EDITS.items()},
         **{k: ("raw",) + v for k, v in RAW_EDITS.items()}}


def make(case: str, tmp_path: Path, sources: dict[str, Path]) -> Path:
    how, source, edit, _ = CASES[case]
    path = tmp_path / f"{case}.h5"
    shutil.copy(sources[source], path)
    if how == "h5":
        with h5py.File(path, "r+") as f:
            edit(f)
    else:
        edit(path)
    return path


@pytest.fixture
def sources(good, imported) -> dict[str, Path]:
    return {"good": good, "imported": imported}


def test_there_are_at_least_35_bad_files():
    assert len(CASES) >= 35


def one_error_line(capsys, path: Path) -> str:
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("auvsim: error: "), lines[0]
    assert str(path) in lines[0]
    assert "Traceback" not in captured.err and captured.out == ""
    return lines[0]


@pytest.mark.parametrize("case", CASES)
def test_inspect_refuses_with_one_line_naming_file_and_field(case, tmp_path, sources,
                                                             capsys):
    path = make(case, tmp_path, sources)
    assert main(["inspect", str(path)]) == 2
    line = one_error_line(capsys, path)
    assert CASES[case][3] in line


@pytest.mark.parametrize("case", CASES)
def test_plot_refuses_with_one_line_and_writes_nothing(case, tmp_path, sources, capsys):
    path = make(case, tmp_path, sources)
    out = tmp_path / "png"
    before = sorted(tmp_path.iterdir())
    assert main(["plot", str(path), "--out", str(out)]) == 2
    line = one_error_line(capsys, path)
    assert CASES[case][3] in line
    assert not out.exists()
    assert sorted(tmp_path.iterdir()) == before  # nothing beside the file either


@pytest.mark.parametrize("case", ["beams_m_by_3", "flipped_beams", "version_future",
                                  "imported_beams_m_by_3"])
def test_the_reader_raises_dataset_error(case, tmp_path, sources):
    path = make(case, tmp_path, sources)
    with pytest.raises(DatasetError, match=CASES[case][3].replace("(", r"\(")
                       .replace(")", r"\)")):
        with open_dataset(path, verify=True):
            pass


def test_a_flipped_byte_is_refused_when_read_not_read_as_data(tmp_path, sources):
    """Without ``verify`` the file opens (only indices are read on open); the corrupt
    field is refused by the Mission view's ``read``, and by ``load_windows``."""
    from beamsnet.data import load_windows

    path = make("flipped_beams", tmp_path, sources)
    with open_dataset(path) as f:
        m = f.missions["m0"]
        assert m.dvl.velocity.shape == (6, 3)  # an intact field of the same file reads
        with pytest.raises(DatasetError) as error:
            m.read("dvl/beam_velocity")
    message = str(error.value)
    assert "\n" not in message and str(path) in message
    assert "mission m0 (simulated): field dvl/beam_velocity fails its checksum" in message
    with pytest.raises(DatasetError, match="field dvl/beam_velocity fails its checksum"):
        load_windows(path, n_past=1)


@pytest.mark.parametrize("case", ["beams_m_by_3", "flipped_beams", "directory"])
def test_command_line_exit_code_and_no_traceback(case, tmp_path, sources):
    path = make(case, tmp_path, sources)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    for command in (["inspect", str(path)], ["plot", str(path), "--out", str(tmp_path / "o")]):
        run = subprocess.run([sys.executable, "-m", "auvsim", *command], env=env,
                             capture_output=True, text=True, timeout=120)
        assert run.returncode == 2, run.stderr
        lines = run.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("auvsim: error: "), run.stderr
        assert str(path) in lines[0] and CASES[case][3] in lines[0]
        assert run.stdout == ""
    assert not (tmp_path / "o").exists()


# Good files still open -------------------------------------------------------------------

def inspect_and_plot(path: Path, tmp_path: Path, capsys) -> list[Path]:
    assert main(["inspect", str(path)]) == 0, capsys.readouterr().err
    assert str(path) in capsys.readouterr().out
    out = tmp_path / "png"
    assert main(["plot", str(path), "--out", str(out)]) == 0, capsys.readouterr().err
    assert capsys.readouterr().err == ""
    pngs = sorted(out.glob("*.png"))
    assert pngs and all(p.stat().st_size > 0 for p in pngs)
    return pngs


def test_the_good_files_inspect_and_plot(good, imported, tmp_path, capsys):
    assert [p.name for p in inspect_and_plot(good, tmp_path / "a", capsys)] == ["good_m0.png"]
    assert [p.name for p in inspect_and_plot(imported, tmp_path / "b", capsys)] == [
        "imported_rec.png"]


def edited(good: Path, tmp_path: Path, edit) -> Path:
    path = tmp_path / "edited.h5"
    shutil.copy(good, path)
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


def test_a_v2_file_without_the_depth_sensor_still_opens(good, tmp_path, capsys):
    path = edited(good, tmp_path, delete_depth)
    with open_dataset(path, verify=True) as f:
        assert f.version == 2 and not f.missions["m0"].has("depth")
    inspect_and_plot(path, tmp_path, capsys)


def test_a_v1_file_without_origin_still_opens(good, tmp_path, capsys):
    def v1(f):
        delete_depth(f)
        f.attrs["format_version"] = 1
        del f[M].attrs["origin"]

    path = edited(good, tmp_path, v1)
    with open_dataset(path) as f:
        assert f.missions["m0"].origin == "simulated"
    inspect_and_plot(path, tmp_path, capsys)


def test_valid_but_unusual_data_is_not_refused(good, tmp_path, capsys):
    """NaN DVL velocity on all but the last ping (no bottom lock), extra fields, groups
    and attributes, unsigned indices: valid, so inspected and drawn."""
    def odd(f):
        n = rows(f, f"{M}/dvl/time")
        for key in ("dvl/velocity", "dvl/velocity_ls", "dvl/beam_velocity",
                    "dvl/beam_velocity_true", "dvl/beam_range"):
            values = f[f"{M}/{key}"][()]
            values[:-1] = np.nan
            replace(f, f"{M}/{key}", values)
        valid = np.zeros((n, 4), dtype=bool)
        valid[-1] = True
        replace(f, f"{M}/dvl/valid", valid)
        replace(f, f"{M}/imu/index_of_dvl", f[f"{M}/imu/index_of_dvl"][()].astype(np.uint32))
        f[f"{M}/notes"] = np.arange(3)  # a dataset beside the groups
        f[f"{M}/extra/thing"] = np.zeros(2)  # a group of someone's own
        f[f"{M}/dvl/extra_field"] = np.zeros(7)
        f[M].attrs["comment"] = "made by hand"
        f.attrs["site"] = "lab"

    path = edited(good, tmp_path, odd)
    pngs = inspect_and_plot(path, tmp_path, capsys)
    assert [p.name for p in pngs] == ["edited_m0.png"]


@pytest.mark.parametrize("flagged", [True, False])
def test_a_mission_without_one_usable_beam_is_described_so_and_not_drawn(
        good, tmp_path, capsys, flagged):
    """Every beam velocity NaN, flagged valid (an edited file, a recording) or not: no
    beam counts as valid, and a consumer that needs beams refuses the mission."""
    def no_beams(f):
        replace(f, f"{M}/dvl/beam_velocity", np.full(f[f"{M}/dvl/beam_velocity"].shape, np.nan))
        replace(f, f"{M}/dvl/valid", np.full(f[f"{M}/dvl/valid"].shape, flagged))

    path = edited(good, tmp_path, no_beams)
    assert main(["inspect", str(path)]) == 0
    assert "0.0 % of beams valid, 0.0 % of pings solvable" in capsys.readouterr().out
    with open_dataset(path) as f, pytest.raises(DatasetError, match=(
            r"mission m0 \(simulated\): no usable beam in its 6 pings \(every beam is "
            r"flagged invalid or its velocity is NaN\)")):
        require_usable_beams(f.missions["m0"])
    out = tmp_path / "png"
    assert main(["plot", str(path), "--out", str(out)]) == 2
    assert "no usable beam" in one_error_line(capsys, path)
    assert not out.exists()


def test_inspect_sweeps_what_ended_runs_left_and_names_the_rest(good, tmp_path, capsys):
    """After kill -9 a run's temporaries stay beside its output: readers ignore them,
    inspect removes those of ended runs (their lock is free) and names the others in one
    line with the command that removes them."""
    from auvsim.data import files

    folder = tmp_path / "out"
    folder.mkdir()
    path = folder / "good.h5"
    shutil.copy(good, path)
    dead = folder / f".good.h5.{files.TAG}.{files.HOST}.999999999"
    for made in (dead, dead.with_name(dead.name + ".lock")):
        made.write_bytes(b"half a file")  # nobody holds its lock: its run ended
    dead.with_name(dead.name + ".parts").mkdir()
    elsewhere = folder / f".good.h5.{files.TAG}.another-host.7"
    elsewhere.write_bytes(b"")
    other_output = folder / f".other.h5.{files.TAG}.another-host.7"
    other_output.write_bytes(b"")
    with open_dataset(path) as f:
        assert list(f.missions) == ["m0"]
    with files.Claim(path) as live:  # a run writing there now
        assert main(["inspect", str(path)]) == 0
        text = capsys.readouterr().out
        assert sorted(folder.iterdir()) == sorted(
            [path, elsewhere, other_output, live.file.with_name(live.file.name + ".lock")])
        note = text.splitlines()[-1]
        assert note.startswith("note: 2 temporary file(s) of another auvsim run")
        assert note.endswith(f"rm -rf {folder}/.*.{files.TAG}.*")
    elsewhere.unlink()
    assert main(["inspect", str(path)]) == 0
    assert "note:" not in capsys.readouterr().out


def test_a_one_ping_mission_draws(good, tmp_path, capsys):
    def one(f):
        for key in list(f[f"{M}/dvl"]):
            replace(f, f"{M}/dvl/{key}", f[f"{M}/dvl/{key}"][:1])
        replace(f, f"{M}/imu/index_of_dvl", f[f"{M}/imu/index_of_dvl"][:1])

    inspect_and_plot(edited(good, tmp_path, one), tmp_path, capsys)


def test_values_near_the_float_limit_are_valid_data_and_drawn(good, tmp_path, capsys):
    """1e308 m/s is finite: inspect accepts it, and plot draws it on its own axis scale
    (the speed over ground overflows to inf and is left out), with nothing on stderr."""
    path = edited(good, tmp_path, lambda f: replace(
        f, f"{M}/truth/velocity_body", np.full(f[f"{M}/truth/velocity_body"].shape, 1e308)))
    assert main(["inspect", str(path)]) == 0  # finite values: valid data
    capsys.readouterr()
    out = tmp_path / "png"
    assert main(["plot", str(path), "--out", str(out)]) == 0
    assert capsys.readouterr().err == ""
    assert [p.name for p in out.iterdir()] == ["edited_m0.png"]


def test_plot_of_a_file_without_missions_says_so(good, tmp_path, capsys):
    path = edited(good, tmp_path, lambda f: f.__delitem__(M))
    assert main(["inspect", str(path)]) == 0 and "0 mission(s)" in capsys.readouterr().out
    assert main(["plot", str(path), "--out", str(tmp_path / "png")]) == 2
    assert "no missions to draw" in one_error_line(capsys, path)
    assert not (tmp_path / "png").exists()


def test_plot_out_that_is_a_file_is_refused(good, tmp_path, capsys):
    (tmp_path / "png").write_text("")
    assert main(["plot", str(good), "--out", str(tmp_path / "png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and "not a directory" in err


def test_a_file_with_a_v7_attribute_out_of_range_is_refused(tmp_path):
    """``dvl_slow_error_time`` (format 7) must be above 0: the filter divides by it."""
    path = write(flat(mission(duration=5.0)), tmp_path / "d.h5")
    with h5py.File(path, "r+") as f:
        name = next(iter(f["missions"]))
        f["missions"][name].attrs["dvl_slow_error_time"] = 0.0
    with pytest.raises(DatasetError, match="dvl_slow_error_time"):
        open_dataset(path)
