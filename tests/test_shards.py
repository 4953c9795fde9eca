"""Sharded datasets (issue 12): a shard per mission and an index that reads as one file,
the same data as one file, resume by config hash and data digest, and clear refusals."""

from __future__ import annotations

import dataclasses
import json
import shutil

import h5py
import numpy as np
import pytest
from conftest import flat, mission

from auvsim import cli as auvsim_cli
from auvsim.data.reader import dataset_paths, open_dataset
from auvsim.data.schema import INDEX, SHARDS
from auvsim.data.shards import data_files
from auvsim.errors import DatasetError
from auvsim.runs.generate import generate
from beamsnet import cli as beamsnet_cli

CONFIG = flat(mission("a", 1, duration=40.0), mission("b", 2, duration=30.0, speed=1.5),
              mission("c", 3, duration=20.0, heading_deg=90.0))


def arrays(path) -> dict:
    """Every mission's attributes and fields, read through ``open_dataset``."""
    out = {}
    with open_dataset(path) as f:
        for name, m in f.missions.items():
            out[name, "attrs"] = json.dumps({k: np.asarray(v).tolist()
                                             for k, v in sorted(m.attrs.items())})
            for key in dataset_paths(m._group):
                out[name, key] = m.read(key)
    return out


def assert_same_data(a, b) -> None:
    a, b = arrays(a), arrays(b)
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=str(key))


@pytest.fixture(scope="module")
def single(tmp_path_factory):
    path = tmp_path_factory.mktemp("one") / "one.h5"
    generate(CONFIG, path, workers=1, progress=False)
    return path


@pytest.fixture
def sharded(tmp_path):
    out = tmp_path / "rm"
    summary = generate(CONFIG, f"{out}/", workers=1, progress=False)
    assert (summary["shards"], summary["kept"]) == (3, 0)
    return out


def test_a_sharded_dataset_holds_the_single_files_data(single, sharded):
    assert sorted(p.name for p in sharded.iterdir()) == [INDEX, SHARDS]
    assert sorted(p.name for p in (sharded / SHARDS).iterdir()) == [
        "part-00000.h5", "part-00001.h5", "part-00002.h5"]
    assert_same_data(single, sharded)
    assert_same_data(single, sharded / INDEX)  # the index itself reads the same
    with open_dataset(sharded) as f:
        assert list(f.missions) == ["a", "b", "c"]
        assert f.config_json == CONFIG.to_json()
        assert f.shards == [sharded / SHARDS / f"part-0000{k}.h5" for k in range(3)]
    assert data_files(sharded) == [sharded / SHARDS / f"part-0000{k}.h5" for k in range(3)]
    assert data_files(single) == [single]


def test_the_index_links_and_copies_nothing(sharded):
    with h5py.File(sharded / INDEX) as f:
        assert f.attrs["layout"] == "index"
        links = {n: f["missions"].get(n, getlink=True) for n in f["missions"]}
    assert all(isinstance(link, h5py.ExternalLink) for link in links.values())
    assert (sharded / INDEX).stat().st_size < 64_000


def test_shards_of_several_missions_and_other_processes_give_the_same_data(single, tmp_path):
    two = generate(CONFIG, tmp_path / "two", shards=2, workers=2, progress=False)
    assert (two["shards"], two["kept"]) == (2, 0)
    assert_same_data(single, tmp_path / "two")


def test_a_finished_dataset_is_kept_and_a_lost_or_changed_shard_made_again(sharded,
                                                                          single):
    shards = sharded / SHARDS
    stamps = {p.name: p.stat().st_mtime_ns for p in shards.iterdir()}
    again = generate(CONFIG, f"{sharded}/", workers=1, progress=False)
    assert again["kept"] == 3
    assert {p.name: p.stat().st_mtime_ns for p in shards.iterdir()} == stamps

    (shards / "part-00001.h5").write_bytes(b"\0" * 100)  # damaged: not even HDF5
    with h5py.File(shards / "part-00002.h5", "r+") as f:  # data changed, checksums kept
        ds = f["missions/c/truth/position_ned"]
        ds[5, 0] = ds[5, 0] + 1.0
    other = sharded.parent / "other"  # another config's shard 0
    generate(dataclasses.replace(CONFIG, missions=(
        dataclasses.replace(CONFIG.missions[0], seed=99),)), f"{other}/", workers=1,
        progress=False)
    shutil.copy(other / SHARDS / "part-00000.h5", shards / "part-00000.h5")
    assert generate(CONFIG, f"{sharded}/", workers=1, progress=False)["kept"] == 0
    assert_same_data(single, sharded)


def test_a_shard_not_sealed_by_this_config_is_refused_by_the_index(sharded):
    shard = sharded / SHARDS / "part-00001.h5"
    with h5py.File(shard, "r+") as f:
        f.attrs["config_sha256"] = "0" * 64
    with pytest.raises(DatasetError, match="part-00001.h5: not the shard the index"):
        open_dataset(sharded)


def test_a_shard_changed_after_its_index_was_checked_is_checked_again(sharded, monkeypatch):
    """An index that was checked whole (its shards quiet) is known while it and every
    shard stay as they were: a shard changed since is checked again (reader._CHECKED)."""
    import time

    from auvsim.data import reader

    monkeypatch.setattr(reader, "QUIET_S", 0.05)
    time.sleep(0.1)
    open_dataset(sharded).close()  # checked whole, and kept
    assert any(key[0] == str((sharded / INDEX).resolve()) for key in reader._CHECKED)
    with h5py.File(sharded / SHARDS / "part-00002.h5", "r+") as f:
        del f["missions/c/dvl/velocity"]
    with pytest.raises(DatasetError, match="lacks dvl/velocity"):
        open_dataset(sharded)


def test_values_edited_through_hdf5_are_refused_not_read_as_data(sharded, capsys, tmp_path):
    """HDF5 recomputes a field's Fletcher-32 when a value is edited through it: the shard's
    seal (its data digest) is what tells, at the first read from that shard."""
    with h5py.File(sharded / SHARDS / "part-00001.h5", "r+") as f:
        ds = f["missions/b/dvl/beam_velocity"]
        ds[3, 0] = ds[3, 0] + 0.5
    with open_dataset(sharded) as f:  # opening stays cheap: no shard is read whole
        assert f.missions["a"].dvl.beam_velocity.shape == (40, 4)  # another shard reads
        with pytest.raises(DatasetError, match="part-00001.h5: its data differ from the "
                           "digest it was sealed with"):
            f.missions["b"].read("truth/time")  # any field of the edited shard is refused
    assert auvsim_cli.main(["inspect", str(sharded)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "its data differ from the digest" in err
    assert auvsim_cli.main(["plot", str(sharded), "--mission", "b", "--out",
                            str(tmp_path / "png")]) == 2
    assert not (tmp_path / "png").exists()


def test_a_shard_resealed_after_an_edit_is_refused_by_the_index(sharded):
    from auvsim.data.schema import data_digest

    with h5py.File(sharded / SHARDS / "part-00001.h5", "r+") as f:
        ds = f["missions/b/dvl/beam_velocity"]
        ds[3, 0] = ds[3, 0] + 0.5
        f.attrs["data_sha256"] = data_digest(f)
    with pytest.raises(DatasetError, match="part-00001.h5: not the shard the index"):
        open_dataset(sharded)


def test_a_missing_shard_or_index_is_refused_in_one_line(sharded, capsys):
    (sharded / SHARDS / "part-00002.h5").unlink()
    with pytest.raises(DatasetError, match=r"mission c's shard shards/part-00002.h5 is "
                       "missing"):
        open_dataset(sharded)
    (sharded / INDEX).unlink()
    assert auvsim_cli.main(["inspect", str(sharded)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"is a directory with no {INDEX}" in err
    assert "run it again to finish the dataset" in err  # its shards are there
    run = sharded.parent / "run"  # a training run's folder given as a dataset
    run.mkdir()
    (run / "model.pt").write_bytes(b"")
    with pytest.raises(DatasetError, match="is a training run .model.pt., not a dataset"):
        open_dataset(run)
    empty = sharded.parent / "empty"  # any other folder: no hint of a rerun
    empty.mkdir()
    with pytest.raises(DatasetError) as other:
        open_dataset(empty)
    assert f"is a directory with no {INDEX}" in str(other.value)
    assert "run it again" not in str(other.value)


def test_a_corrupt_shard_names_the_shard_and_the_field(sharded, capsys):
    shard = sharded / SHARDS / "part-00000.h5"
    data = bytearray(shard.read_bytes())
    with h5py.File(shard) as f:
        offset = f["missions/a/truth/velocity_ned"].id.get_chunk_info(0).byte_offset
    data[offset + 100] ^= 0xFF
    shard.write_bytes(bytes(data))
    assert auvsim_cli.main(["inspect", str(sharded)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "part-00000.h5: mission a (simulated): field truth/velocity_ned fails its checksum" \
        in err


def test_inspect_and_plot_read_the_folder(sharded, capsys, tmp_path):
    assert auvsim_cli.main(["inspect", str(sharded)]) == 0
    text = capsys.readouterr().out
    assert "3 mission(s) in 3 shard(s)" in text
    assert auvsim_cli.main(["plot", str(sharded), "--mission", "b", "--out",
                            str(tmp_path / "png")]) == 0
    assert [p.name for p in (tmp_path / "png").iterdir()] == ["rm_b.png"]


def test_inspect_gives_one_data_digest_for_the_same_data_however_written(single, sharded,
                                                                       tmp_path, capsys):
    """A repeated run writes the same data but not the same bytes (the time it was made,
    and HDF5's layout of several missions): inspect's digest is the same for the file,
    the sharded folder and a pool's file, and another seed changes it."""
    pool = tmp_path / "pool.h5"
    generate(CONFIG, pool, workers=2, progress=False)
    other = tmp_path / "other.h5"
    generate(dataclasses.replace(CONFIG, missions=tuple(
        dataclasses.replace(m, seed=m.seed + 100) for m in CONFIG.missions)), other,
        workers=1, progress=False)

    def digest(path) -> str:
        assert auvsim_cli.main(["inspect", str(path)]) == 0
        line = [t for t in capsys.readouterr().out.splitlines() if "data SHA-256" in t]
        assert len(line) == 1
        return line[0].split()[2]

    assert digest(single) == digest(sharded) == digest(pool) != digest(other)
    assert len(digest(single)) == 64


def test_inspect_sweeps_a_folder_whose_run_was_killed_before_its_index(tmp_path, capsys):
    """A run killed before it wrote ``index.h5`` leaves its shards' temporaries; inspect
    (which the clusters guide says removes them) refused the folder and left them."""
    from auvsim.data import files

    folder = tmp_path / "rm"
    (folder / SHARDS).mkdir(parents=True)
    dead = folder / SHARDS / f".part-00000.h5.{files.TAG}.{files.HOST}.999999999"
    dead.write_bytes(b"x" * 100)
    dead.with_name(dead.name + ".lock").write_bytes(b"")  # nobody holds it
    assert auvsim_cli.main(["inspect", str(folder)]) == 2
    assert "no index.h5" in capsys.readouterr().err
    assert list((folder / SHARDS).iterdir()) == []


def test_beamsnet_reads_an_index_as_a_file(single, sharded, tmp_path):
    for name, path in (("one", single), ("sharded", sharded)):
        assert beamsnet_cli.main(["estimate", str(path), "--estimator", "LS", "--out",
                                  str(tmp_path / name)]) == 0
    assert (tmp_path / "one" / "estimates.csv").read_bytes() == \
        (tmp_path / "sharded" / "estimates.csv").read_bytes()


def test_a_bad_shards_count_is_refused(tmp_path, capsys):
    assert auvsim_cli.main(["generate", "--duration", "5", "--shards", "0", "--out",
                            str(tmp_path / "x")]) == 2
    assert "--shards: expected a whole number >= 1, got 0" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_a_shards_count_with_a_file_name_is_refused(tmp_path, capsys):
    assert auvsim_cli.main(["generate", "--duration", "5", "--shards", "2", "--out",
                            str(tmp_path / "x.h5")]) == 2
    assert "a sharded dataset is a folder" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_one_run_at_a_time_writes_a_folder(sharded):
    import fcntl
    import os

    from auvsim.errors import ConfigError

    fd = os.open(sharded, os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)  # another run holds it
    try:
        with pytest.raises(ConfigError, match="another auvsim generate is writing"):
            generate(CONFIG, f"{sharded}/", workers=1, progress=False)
    finally:
        os.close(fd)
    assert (sharded / INDEX).exists()  # the finished dataset is left as it was


def test_the_shards_of_an_earlier_plan_go(sharded, single):
    generate(CONFIG, f"{sharded}/", shards=2, workers=1, progress=False)
    assert sorted(p.name for p in (sharded / SHARDS).iterdir()) == [
        "part-00000.h5", "part-00001.h5"]
    assert_same_data(single, sharded)


def test_closing_the_dataset_closes_its_shards(sharded):
    generate(CONFIG, f"{sharded}/", shards=2, workers=1, progress=False)  # two in one shard
    with open_dataset(sharded) as f:
        mission = f.missions["b"]
    with pytest.raises((ValueError, RuntimeError, KeyError, DatasetError)):
        mission.read("truth/time")


def test_an_index_with_malformed_records_is_refused(sharded):
    with h5py.File(sharded / INDEX, "r+") as f:
        records = json.loads(f.attrs["shards"])
        records[0]["missions"] = "a"
        f.attrs["shards"] = json.dumps(records)
    with pytest.raises(DatasetError, match="corrupt auvsim index"):
        open_dataset(sharded)
