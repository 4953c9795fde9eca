"""Teledyne RDI PD0 both ways (``auvsim.data.pd0``): our export read back by MHKiT's dolfyn
and by ``auvsim import --format pd0``, against the HDF5 arrays, within the format's
resolution (1 mm/s, 1 cm); corrupted ensembles skipped and counted, never read; files of
other instruments, or not PD0 at all, refused in one line with exit 2 and nothing
written."""

from __future__ import annotations

import contextlib
import io
import math
import struct
import sys
import warnings

import numpy as np
import pytest
from conftest import flat, mission

from auvsim.cli import main
from auvsim.config import DvlConfig
from auvsim.data.beams import beam_matrix
from auvsim.data.pd0 import RDI_BEAM, RDI_FROM_DVL, scan
from auvsim.data.reader import open_dataset

pytest.importorskip("mhkit.dolfyn")

MM = 0.0005 + 1e-9  # half of PD0's 1 mm/s: a value rounded to it
CM = 0.005 + 1e-9  # half of its 1 cm
DESCRIPTION = """\
[log]
origin = [32.8, 34.95, -5.0]
[dvl]
noise_std = 0.0026
velocity_accuracy = 0.02
"""


@pytest.fixture(scope="module")
def dataset(dataset_of):
    """20 s at 5 Hz over a 60 m flat floor, with beam dropouts, lost pings and a lost lock
    (beams without bottom lock, pings without velocity), and beam noise."""
    dvl = DvlConfig(rate_hz=5.0, noise_std=0.01, dropout_rate=0.15, ping_dropout_rate=0.05,
                    lock_loss_intervals=((8.0, 9.0),))
    return dataset_of(flat(mission(duration=20.0, speed=1.5), dvl=dvl), "pd0")


@pytest.fixture(scope="module")
def hdf5(dataset):
    with open_dataset(dataset) as ds:
        m = ds.missions["mission_000"]
        d = m.dvl
        out = {k: np.asarray(getattr(d, k)) for k in ("time", "beam_velocity", "beam_range",
                                                       "valid", "velocity_ls",
                                                       "error_velocity", "mode")}
        out["angle"] = float(m.attrs["beam_angle_deg"])
    out["measured"] = out["valid"] & np.isfinite(out["beam_velocity"]) \
        & (out["mode"] == 0)[:, None]
    assert out["measured"].any() and not out["measured"].all()  # the test sees both
    assert (out["mode"] != 0).any()
    return out


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def exported(dataset, tmp_path_factory):
    folder = tmp_path_factory.mktemp("pd0-out")
    files = {}
    for coordinates in ("beam", "instrument"):
        files[coordinates] = folder / f"{coordinates}.pd0"
        code, out, err = run("export", str(dataset), "--to", "pd0", "--coordinates",
                             coordinates, "--out", str(files[coordinates]))
        assert code == 0, err
        assert "PD0 ensembles" in out
    return files


def read_dolfyn(path):
    from mhkit.dolfyn.io.rdi import read_rdi

    with contextlib.redirect_stdout(io.StringIO()), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its note that the file states no ping interval
        return read_rdi(str(path), userdata=False)


def test_checksums_and_framing_of_our_export(exported, hdf5):
    for coordinates, path in exported.items():
        data = path.read_bytes()
        found = scan(data)
        assert (found.bad_checksum, found.truncated, found.skipped_bytes) == (0, 0, 0)
        assert len(found.ensembles) == len(hdf5["time"])
        assert found.coordinates == coordinates and found.beam_angle_deg == hdf5["angle"]
        for start, end in found.ensembles:  # RDI's checksum: the bytes' sum mod 65536
            assert sum(data[start:end - 2]) & 0xFFFF == struct.unpack("<H", data[end - 2:end])[0]


@pytest.mark.parametrize("coordinates", ["beam", "instrument"])
def test_dolfyn_reads_our_export(exported, hdf5, coordinates):
    ds = read_dolfyn(exported[coordinates])
    # dolfyn reads an ensemble only when another header follows it: all but the last.
    n = ds.sizes["time"]
    assert n == len(hdf5["time"]) - 1
    assert ds.attrs["coord_sys"] == {"beam": "beam", "instrument": "inst"}[coordinates]
    assert ds.attrs["beam_angle"] == hdf5["angle"]
    seconds = (ds["time"].values - np.datetime64("2000-01-01T00:00:00")) / np.timedelta64(1, "s")
    np.testing.assert_allclose(seconds, hdf5["time"][:n], atol=0.005 + 1e-6)
    rdi = RDI_BEAM  # RDI beam k + 1 is our beam RDI_BEAM[k]
    measured = hdf5["measured"][:n][:, rdi]
    good = ds["prcnt_gd_bt"].values.T
    np.testing.assert_array_equal(good, np.where(measured, 100, 0))
    vertical = ds["dist_bt"].values.T
    cos = math.cos(math.radians(hdf5["angle"]))
    expected = hdf5["beam_range"][:n][:, rdi] * cos
    assert np.all(np.abs(vertical - expected)[measured] <= CM)
    assert np.all(vertical[~measured] == 0)
    vel = ds["vel_bt"].values.T.astype(float)
    bad = np.isnan(vel) | (vel < -32.7675)  # -32768 mm/s, in float32 m/s
    if coordinates == "beam":
        beams = hdf5["beam_velocity"][:n][:, rdi]
        assert np.all(np.abs(vel - beams)[measured] <= MM)
        np.testing.assert_array_equal(bad, ~measured)
    else:
        bottom = hdf5["mode"][:n] == 0
        xyz = -(hdf5["velocity_ls"][:n] @ RDI_FROM_DVL.T)
        assert np.all(np.abs(vel[:, :3] - xyz)[bottom] <= MM)
        assert bad[~bottom, :3].all()
        e = -hdf5["error_velocity"][:n]
        has_e = bottom & np.isfinite(e)
        assert np.all(np.abs(vel[has_e, 3] - e[has_e]) <= MM)
        assert bad[~has_e, 3].all()


def test_beam_numbering_agrees_with_dolfyns_transformation(exported, hdf5):
    """dolfyn's own beam -> instrument matrix (RDI's) turns our beam-coordinate export into
    our instrument-coordinate one: the beams are numbered and signed as RDI's."""
    beam = read_dolfyn(exported["beam"])
    matrix = beam["beam2inst_orientmat"].values  # dolfyn's, from the fixed leader
    direct = read_dolfyn(exported["instrument"])
    vel = beam["vel_bt"].values.T.astype(float) @ matrix.T
    four = hdf5["measured"][:len(vel)].all(axis=1)
    assert four.sum() > 10
    # Each of the four rounded beams is within 0.5 mm/s: X, Y within a (2 MM), Z within
    # 4 b MM, e within 4 d MM, a = 1 / (2 sin 30) = 1, b = 1 / (4 cos 30), d = a / sqrt 2.
    np.testing.assert_allclose(vel[four], direct["vel_bt"].values.T[four], atol=3 * MM)


@pytest.mark.parametrize("motion, ahead", [((1.0, 0.0, 0.0), (1, 3)), ((0.0, 1.0, 0.0), (3, 2))])
def test_forward_lies_between_rdi_beams_3_and_1(tmp_path, motion, ahead):
    """A Navigator mounted with beam 3 45 deg to starboard of forward: moving forward, RDI
    beams 1 and 3 see the bottom come toward them (positive, RDI's sign), 2 and 4 recede;
    moving to starboard, beams 3 and 2 do. Read back by dolfyn, which numbers them as RDI."""
    from auvsim.data.pd0 import Pings, encode

    n, angle = 3, 30.0
    beams = np.tile(beam_matrix(math.radians(angle)) @ np.array(motion), (n, 1))
    pings = Pings(np.arange(n, dtype=float), beams, np.full((n, 4), 40.0),
                  np.tile(motion, (n, 1)), np.zeros(n), np.ones(n, dtype=bool), angle)
    path = tmp_path / "motion.pd0"
    path.write_bytes(encode(pings))
    vel = read_dolfyn(path)["vel_bt"].values.T.astype(float)  # (N, 4), RDI beams 1-4
    toward = math.sin(math.radians(angle)) * math.sqrt(0.5)  # m/s along each beam
    expected = [toward if b in ahead else -toward for b in (1, 2, 3, 4)]
    np.testing.assert_allclose(vel, np.tile(expected, (len(vel), 1)), atol=MM)


def import_file(path, tmp_path, name="out.h5"):
    description = tmp_path / "log.toml"
    description.write_text(DESCRIPTION)
    out = tmp_path / name
    result = run("import", str(path), "--format", "pd0", "--description", str(description),
                 "--out", str(out))
    return result, out


def read_dvl(path):
    with open_dataset(path) as ds:
        (m,) = ds.missions.values()
        assert m.origin == "recorded" and m.groups == ["dvl"]
        return {k: np.asarray(getattr(m.dvl, k)) for k in m.dvl}, m.attrs


def test_import_our_beam_export(exported, hdf5, tmp_path):
    (code, out, err), h5 = import_file(exported["beam"], tmp_path)
    assert code == 0, err
    assert "skipped: 0 ensemble(s) failing their checksum, 0 cut off" in out
    dvl, attrs = read_dvl(h5)
    assert attrs["dvl_beams_derived"] == 0 and attrs["beam_angle_deg"] == hdf5["angle"]
    assert attrs["latitude_deg"] == 32.8 and attrs["height_m"] == -5.0
    np.testing.assert_allclose(dvl["time"], hdf5["time"] - hdf5["time"][0], atol=0.01)
    measured = hdf5["measured"]
    np.testing.assert_array_equal(dvl["valid"], measured)
    assert np.all(np.abs(dvl["beam_velocity"] - hdf5["beam_velocity"])[measured] <= MM)
    assert np.isnan(dvl["beam_velocity"][~measured]).all()
    # A vertical range rounded to 1 cm, divided by cos(beam angle): the slant's resolution.
    slant = CM / math.cos(math.radians(hdf5["angle"]))
    assert np.all(np.abs(dvl["beam_range"] - hdf5["beam_range"])[measured] <= slant)
    # The LS velocity of beams each within MM: within MM times pinv's largest row sum.
    bound = MM * np.abs(np.linalg.pinv(beam_matrix(math.radians(hdf5["angle"])))).sum(1).max()
    three = measured.sum(axis=1) >= 3
    np.testing.assert_array_equal(np.isfinite(dvl["velocity_ls"]).all(axis=1), three)
    four = measured.all(axis=1)
    assert np.all(np.abs(dvl["velocity_ls"] - hdf5["velocity_ls"])[four] <= bound)
    assert np.all(np.abs(dvl["error_velocity"] - hdf5["error_velocity"])[four] <= 2 * bound)


def test_import_our_instrument_export(exported, hdf5, tmp_path):
    (code, out, err), h5 = import_file(exported["instrument"], tmp_path)
    assert code == 0, err
    dvl, attrs = read_dvl(h5)
    assert attrs["dvl_beams_derived"] == 1 and "beam_velocity" not in dvl
    bottom = hdf5["mode"] == 0
    assert np.all(np.abs(dvl["velocity_ls"] - hdf5["velocity_ls"])[bottom] <= MM * math.sqrt(2))
    assert np.isnan(dvl["velocity_ls"][~bottom]).all()
    np.testing.assert_array_equal(dvl["mode"], np.where(bottom, 0, -1))


def corrupt_and_import(exported, hdf5, tmp_path, edit):
    data = bytearray(exported["beam"].read_bytes())
    spans = scan(bytes(data)).ensembles
    edit(data, spans)
    bad = tmp_path / "bad.pd0"
    bad.write_bytes(bytes(data))
    return import_file(bad, tmp_path), spans


def test_bad_checksum_is_skipped_and_counted(exported, hdf5, tmp_path):
    k = 7

    def flip(data, spans):  # a velocity byte of ensemble k: its checksum no longer adds up
        start = spans[k][0]
        data[start + 12 + 59 + 65 + 26] ^= 0x5A

    ((code, out, err), h5), spans = corrupt_and_import(exported, hdf5, tmp_path, flip)
    assert code == 0, err
    assert "skipped: 1 ensemble(s) failing their checksum, 0 cut off" in out
    dvl, _ = read_dvl(h5)
    keep = np.arange(len(hdf5["time"])) != k
    assert len(dvl["time"]) == keep.sum()
    np.testing.assert_allclose(dvl["time"], hdf5["time"][keep] - hdf5["time"][0], atol=0.01)
    measured = hdf5["measured"][keep]
    np.testing.assert_array_equal(dvl["valid"], measured)
    assert np.all(np.abs(dvl["beam_velocity"] - hdf5["beam_velocity"][keep])[measured] <= MM)


@pytest.mark.parametrize("length_msb, where", [(0xFF, "past the end of the file"),
                                                (0x02, "inside the file")])
def test_a_corrupt_length_loses_only_its_ensemble(exported, hdf5, tmp_path, length_msb, where):
    """An ensemble whose length is corrupt is counted bad, and framing resumes at the next
    header that frames a whole ensemble: every later ensemble is read, none is cut off."""
    k = 5

    def lengthen(data, spans):
        start = spans[k][0]
        assert data[start + 3] == 0
        data[start + 3] = length_msb  # the length, 223 B, becomes 65 kB or 735 B
        end = start + int.from_bytes(data[start + 2:start + 4], "little") + 2
        assert (end > len(data)) == (where == "past the end of the file")

    ((code, out, err), h5), spans = corrupt_and_import(exported, hdf5, tmp_path, lengthen)
    assert code == 0, err
    assert "skipped: 1 ensemble(s) failing their checksum, 0 cut off" in out
    found = scan((tmp_path / "bad.pd0").read_bytes())
    assert found.ensembles == spans[:k] + spans[k + 1:]
    assert (found.bad_checksum, found.truncated) == (1, 0)
    dvl, _ = read_dvl(h5)
    keep = np.arange(len(hdf5["time"])) != k
    np.testing.assert_allclose(dvl["time"], hdf5["time"][keep] - hdf5["time"][0], atol=0.01)
    measured = hdf5["measured"][keep]
    np.testing.assert_array_equal(dvl["valid"], measured)
    assert np.all(np.abs(dvl["beam_velocity"] - hdf5["beam_velocity"][keep])[measured] <= MM)


def test_failures_are_counted_each_and_a_cut_off_tail_once(exported):
    data = bytearray(exported["beam"].read_bytes())
    spans = scan(bytes(data)).ensembles
    data[spans[5][0] + 3] = 0xFF  # a length past the end of the file
    data[spans[6][0] + 100] ^= 0x5A  # a checksum that fails
    found = scan(bytes(data))
    assert (found.bad_checksum, found.truncated) == (2, 0)
    assert found.ensembles == spans[:5] + spans[7:]
    cut = bytes(data[:spans[-1][0] + 100])  # and the file ends inside the last
    found = scan(cut)
    assert (found.bad_checksum, found.truncated) == (2, 1)
    assert found.ensembles == spans[:5] + spans[7:-1]


def test_lengths_all_corrupt_and_a_clock_that_goes_back_are_said_so(exported, tmp_path):
    """Every ensemble's length field corrupt: not a file cut off, but headers that frame
    nothing whole. Two exports joined: the ensemble where the clock goes back is named,
    not the count of them all."""
    data = bytearray(exported["beam"].read_bytes())
    spans = scan(bytes(data)).ensembles
    for start, _ in spans:
        data[start + 3] = 0xFF
    path = tmp_path / "lengths.pd0"
    path.write_bytes(bytes(data))
    (code, out, err), h5 = import_file(path, tmp_path, name="lengths.h5")
    assert code == 2 and err.count("\n") == 1, err
    assert f"none of its {len(spans)} headers frames one with a good checksum" in err, err
    joined = tmp_path / "joined.pd0"
    joined.write_bytes(exported["beam"].read_bytes() * 2)
    (code, out, err), h5 = import_file(joined, tmp_path, name="joined.h5")
    assert code == 2 and err.count("\n") == 1 and not h5.exists(), err
    assert f"ensemble {len(spans) + 1} of {2 * len(spans)} is stamped" in err, err


def test_truncated_file_skips_the_cut_ensemble(exported, hdf5, tmp_path):
    def cut(data, spans):
        del data[spans[-1][0] + 100:]

    ((code, out, err), h5), _ = corrupt_and_import(exported, hdf5, tmp_path, cut)
    assert code == 0, err
    assert "skipped: 0 ensemble(s) failing their checksum, 1 cut off" in out
    dvl, _ = read_dvl(h5)
    n = len(hdf5["time"]) - 1
    assert len(dvl["time"]) == n
    assert np.all(np.abs(dvl["beam_velocity"] - hdf5["beam_velocity"][:n])[
        hdf5["measured"][:n]] <= MM)


def rechecksum(data: bytearray, spans) -> None:
    for start, end in spans:
        data[end - 2:end] = struct.pack("<H", sum(data[start:end - 2]) & 0xFFFF)


def other_instrument(kind):
    def edit(data, spans):
        for start, _ in spans:
            fixed = start + 12
            if kind == "no bottom track":  # the third data type is a water profile's ID
                data[start + 12 + 59 + 65:start + 12 + 59 + 65 + 2] = b"\x00\x01"
            elif kind == "sentinel v":
                data[fixed + 2] = 66
            elif kind == "up-looking":
                data[fixed + 4] |= 0x80
            elif kind == "earth":
                data[fixed + 25] = 0b11111
            elif kind == "5 beams":
                data[fixed + 5] = (0b0101 << 4) | (data[fixed + 5] & 0x0F)
        rechecksum(data, spans)
    return edit


@pytest.mark.parametrize("kind, words", [
    ("no bottom track", "no bottom track (0600)"),
    ("sentinel v", "firmware 66.41 is not a Workhorse's"),
    ("up-looking", "head faces up"),
    ("earth", "earth coordinates"),
    ("5 beams", "Janus code 0101"),
])
def test_another_instrument_is_refused(exported, hdf5, tmp_path, kind, words):
    ((code, out, err), h5), _ = corrupt_and_import(exported, hdf5, tmp_path,
                                                   other_instrument(kind))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and words in err and "Traceback" not in err
    assert not h5.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["bad.pd0",
                                                                             "log.toml"]


def test_not_pd0_at_all_is_refused(dataset, tmp_path):
    for name, data in (("hdf5.pd0", dataset.read_bytes()[:4096]), ("empty.pd0", b""),
                       ("garbled.pd0", b"\x7f\x7f" + bytes(range(256)) * 4)):
        path = tmp_path / name
        path.write_bytes(data)
        (code, out, err), h5 = import_file(path, tmp_path, name=f"{name}.h5")
        assert code == 2 and out == "" and err.count("\n") == 1, err
        assert "PD0" in err and not h5.exists()


def test_export_refuses_and_writes_nothing(dataset, tmp_path):
    out = tmp_path / "x.pd0"
    code, _, err = run("export", str(dataset), "--to", "pd0", "--mission", "nope",
                       "--out", str(out))
    assert code == 2 and "--mission 'nope': no such mission" in err
    code, _, err = run("export", str(dataset), "--to", "pd0", "--mission", "nope", "--out",
                       str(tmp_path / "nowhere" / "x.pd0"))  # no folder made for nothing
    assert code == 2 and "--mission 'nope': no such mission" in err
    (tmp_path / "afile").write_text("")
    code, _, err = run("export", str(dataset), "--to", "pd0", "--out",
                       str(tmp_path / "afile" / "x.pd0"))
    assert code == 2 and "is a file, not a folder" in err, err
    (tmp_path / "afile").unlink()
    code, _, err = run("import", str(dataset), "--format", "pd0", "--out",
                       str(tmp_path / "y.h5"))
    assert code == 2 and "--description" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("to, other, own", [("pd0", "x.mcap", "x.pd0"),
                                             ("mcap", "x.pd0", "x.mcap")])
def test_export_never_replaces_a_users_other_file(dataset, tmp_path, to, other, own):
    """An export had replaced whatever was at --out (a user's script, a bag with a PD0
    export's bytes); now a file of another kind is refused, and so is another of
    auvsim's formats' names; a file of its own kind is replaced, as a dataset is."""
    pytest.importorskip("mcap") if to == "mcap" else None
    script = tmp_path / "reader.py"
    script.write_text("print(1)\n")
    code, _, err = run("export", str(dataset), "--to", to, "--out", str(script))
    assert code == 2 and err.count("\n") == 1, err
    assert f"a file that is not {to.upper()} is there" in err, err
    assert script.read_text() == "print(1)\n"
    code, _, err = run("export", str(dataset), "--to", to, "--out", str(tmp_path / other))
    assert code == 2 and f"name for a {to.upper()} file; expected a .{to} name" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reader.py"]
    for _ in range(2):  # new, in a new folder as generate makes one, then replaced
        code, _, err = run("export", str(dataset), "--to", to, "--out",
                           str(tmp_path / "new" / own))
        assert code == 0, err


def test_export_of_a_log_without_beams_says_what_it_has(tmp_path):
    """A recorded log holds its DVL's velocity, not its beams: refused in one line naming
    the file and what the log has, nothing written."""
    from test_sea import write_akit

    from auvsim.data.recorded import import_logs

    write_akit(tmp_path / "logs", 1)
    log = tmp_path / "sea.h5"
    import_logs([tmp_path / "logs"], log, format="akit")
    out = tmp_path / "x.pd0"
    code, stdout, err = run("export", str(log), "--to", "pd0", "--out", str(out))
    assert code == 2 and stdout == "" and err.count("\n") == 1, err
    assert f"{log}: mission 'trajectory1' has its DVL's velocity only; expected" in err
    assert not out.exists()


def test_a_description_nested_too_deeply_is_refused_in_one_line(exported, tmp_path):
    description = tmp_path / "deep.toml"
    description.write_text("[log]\norigin = " + "[" * 3000 + "]" * 3000 + "\n")
    out = tmp_path / "x.h5"
    code, stdout, err = run("import", str(exported["beam"]), "--format", "pd0",
                            "--description", str(description), "--out", str(out))
    assert code == 2 and stdout == "" and err.count("\n") == 1, err
    assert "not valid TOML (arrays or tables nested too deeply to read)" in err
    assert not out.exists()


def test_export_refuses_to_write_over_its_dataset(dataset, tmp_path):
    """--out naming the dataset, or a link to it, is refused before anything is written:
    the dataset is left as it was."""
    before = dataset.read_bytes()
    copy = tmp_path / "copy.h5"  # the module's dataset stays whole if the export is not refused
    copy.write_bytes(before)
    link = tmp_path / "link.h5"
    link.symlink_to(copy)
    for out in (copy, link):
        code, stdout, err = run("export", str(copy), "--to", "pd0", "--out", str(out))
        assert code == 2 and stdout == "" and err.count("\n") == 1, err
        assert f"--out {str(out)!r}: is the dataset itself; expected another file" in err
    assert copy.read_bytes() == before and link.is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy.h5", "link.h5"]


def test_ranges_beyond_655_m_use_the_msb_byte(tmp_path):
    from auvsim.data.pd0 import Pings, encode, read_pd0

    n = 3
    slant = np.array([[700.0, 12.34, 1000.0, 655.36]] * n)  # m: 606 m, 866 m vertical...
    beams = np.tile([0.5, -0.5, 0.5, -0.5], (n, 1))
    pings = Pings(np.arange(n, dtype=float), beams, slant, np.zeros((n, 3)), np.zeros(n),
                  np.ones(n, dtype=bool), 30.0, 0.0)
    path = tmp_path / "deep.pd0"
    path.write_bytes(encode(pings))
    log = read_pd0(path)
    assert np.all(np.abs(log.beam_range - slant) <= CM / math.cos(math.radians(30)))
    assert np.all(np.abs(log.beam_velocity - beams) <= MM)


def test_without_mhkit_the_import_says_what_to_install(exported, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "mhkit.dolfyn.io.rdi", None)  # its import fails
    (code, out, err), h5 = import_file(exported["beam"], tmp_path)
    assert code == 2 and err.count("\n") == 1
    assert "MHKiT" in err and "pip install 'auvsim[io]'" in err and not h5.exists()
