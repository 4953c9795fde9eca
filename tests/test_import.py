"""Recorded DVL velocity streams as datasets (``auvsim import-velocity``, schema v2
``imported`` missions) and the paper's sea-data protocol (``beamsnet reproduce snapir``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from auvsim.cli import main as auvsim_main
from auvsim.config import DvlConfig
from auvsim.data.importer import import_velocity
from auvsim.data.reader import open_dataset
from auvsim.data.schema import schema
from auvsim.sensors.dvl import beam_matrix
from beamsnet.cli import main as beamsnet_main
from beamsnet.data import load_windows


def stream(n: int, seed: int = 0) -> np.ndarray:
    """(3, n) a smooth, varying DVL velocity, m/s, the layout of the paper's V.npy."""
    t = np.arange(n)
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * np.pi, 3)
    return np.stack([1.2 + 0.5 * np.sin(t / 60 + phase[0]),
                     -1.1 + 0.5 * np.sin(t / 45 + phase[1]),
                     0.05 * np.sin(t / 20 + phase[2])])


@pytest.fixture
def npy(tmp_path):
    path = tmp_path / "V.npy"
    np.save(path, stream(500))
    return path


def test_noise_free_beams_equal_h_v_and_ls_the_velocity(npy, tmp_path):
    out = tmp_path / "ideal.h5"
    import_velocity([npy], out, dvl=DvlConfig(beam_angle_deg=20.0))
    h = beam_matrix(math.radians(20.0))
    with open_dataset(out) as f:
        m = f.missions["V"]
        assert m.attrs["origin"] == "imported" and m.groups == ["dvl"]
        v = np.load(npy).T
        np.testing.assert_array_equal(m.dvl.velocity, v)
        np.testing.assert_allclose(m.dvl.beam_velocity, v @ h.T, atol=1e-15)
        np.testing.assert_allclose(m.dvl.velocity_ls, v, atol=1e-12)
        np.testing.assert_array_equal(m.dvl.time, np.arange(500.0))


def test_error_model_is_eq_7_with_the_configured_noise(tmp_path):
    path = tmp_path / "long.npy"
    np.save(path, stream(40_000))
    dvl = DvlConfig(beam_angle_deg=20.0, scale_factor=0.007, bias=0.0001, noise_std=0.042)
    import_velocity([path], tmp_path / "noisy.h5", dvl=dvl, seed=3)
    with open_dataset(tmp_path / "noisy.h5") as f:
        m = f.missions["long"]
        s, b = m.attrs["dvl_scale_factor"], m.attrs["dvl_bias"]
        np.testing.assert_array_equal(s, 0.007)
        residual = m.dvl.beam_velocity - ((1 + s) * m.dvl.beam_velocity_true + b)
    assert abs(residual.std() / 0.042 - 1) < 0.01
    assert abs(residual.mean()) < 3 * 0.042 / math.sqrt(residual.size)


def test_csv_with_header_gives_the_same_dataset_as_npy(npy, tmp_path):
    csv = tmp_path / "V.csv"
    rows = "\n".join(",".join(repr(float(x)) for x in row) for row in np.load(npy).T)
    csv.write_text("vx,vy,vz\n" + rows + "\n")
    dvl = DvlConfig(beam_angle_deg=20.0, noise_std=0.01)
    import_velocity([npy], tmp_path / "a.h5", dvl=dvl)
    import_velocity([csv], tmp_path / "b.h5", dvl=dvl)
    with open_dataset(tmp_path / "a.h5") as a, \
            open_dataset(tmp_path / "b.h5") as b:
        for field in schema("imported")[0]:
            np.testing.assert_array_equal(a.missions["V"].read(field.path),
                                          b.missions["V"].read(field.path))


def test_a_dropout_row_is_a_ping_without_bottom_lock(tmp_path):
    v = stream(50)
    v[:, 7] = np.nan
    np.save(tmp_path / "gap.npy", v)
    import_velocity([tmp_path / "gap.npy"], tmp_path / "gap.h5", dvl=DvlConfig())
    with open_dataset(tmp_path / "gap.h5") as f:
        m = f.missions["gap"]
        assert not m.dvl.valid[7].any() and m.dvl.valid.sum() == 49 * 4
        assert np.isnan(m.dvl.velocity_ls[7]).all()
    w = load_windows(tmp_path / "gap.h5")  # pings 7..10 use ping 7: no samples there
    assert w.accel is None and not np.isin(w.time, [7.0, 8.0, 9.0, 10.0]).any()
    assert len(w.target) == 50 - 3 - 4


def test_cli_imports_several_files_as_missions_with_the_presets_dvl(npy, tmp_path, capsys):
    np.save(tmp_path / "V_test.npy", stream(200, seed=1))
    out = tmp_path / "snapir.h5"
    assert auvsim_main(["import-velocity", str(npy), str(tmp_path / "V_test.npy"),
                        "--out", str(out), "--seed", "4"]) == 0
    assert "V (500 pings), V_test (200 pings)" in capsys.readouterr().out
    with open_dataset(out) as f:
        assert list(f.missions) == ["V", "V_test"]
        a = f.missions["V_test"].attrs
        assert a["seed"] == 5 and a["beam_angle_deg"] == 20.0  # paper-sim's DVL
        assert a["dvl_noise_std"] == pytest.approx(0.042**2)
        # a recording of a DVL alone cannot know the gravity, and flew no scripted phases
        assert f.missions["V_test"].gravity is None and f.missions["V_test"].phases == []
    assert auvsim_main(["inspect", str(out)]) == 0
    assert "imported from" in capsys.readouterr().out


def test_v1_on_a_file_without_imu_gives_one_line_and_exit_2(npy, tmp_path, capsys):
    out = tmp_path / "v.h5"
    import_velocity([npy], out, dvl=DvlConfig(beam_angle_deg=20.0))
    assert beamsnet_main(["train", str(out), "--model", "v1", "--out",
                          str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no IMU data" in err and "--model v2" in err
    assert not (tmp_path / "run").exists()
    # A V1 run evaluated on it: no --model flag named (evaluate has none), the data blamed.
    sim = tmp_path / "sim.h5"
    assert auvsim_main(["generate", "--preset", "paper-sim", "--duration", "40", "--out",
                        str(sim), "--quiet"]) == 0
    assert beamsnet_main(["train", str(sim), "--model", "v1", "--epochs", "1", "--out",
                          str(tmp_path / "v1"), "--quiet"]) == 0
    capsys.readouterr()
    assert beamsnet_main(["evaluate", str(tmp_path / "v1"), str(out), "--out",
                          str(tmp_path / "ev"), "--quiet"]) == 2
    err = capsys.readouterr().err
    error = [line for line in err.splitlines() if line.startswith("beamsnet: error")]
    assert len(error) == 1 and "no IMU data, which BeamsNetV1 takes" in error[0], err
    assert "--model" not in error[0] and not (tmp_path / "ev").exists()


def test_an_imported_stream_is_scored_against_itself_not_a_simulator(npy, tmp_path, capsys):
    """An imported velocity stream is the truth by the paper's protocol, and scores say
    so: not "the simulator's truth", which it never had."""
    out = tmp_path / "v.h5"
    import_velocity([npy], out, dvl=DvlConfig(beam_angle_deg=20.0))
    assert beamsnet_main(["estimate", str(out), "--estimator", "LS", "--out",
                          str(tmp_path / "est")]) == 0
    said = capsys.readouterr().out
    assert "scored against the imported velocity, the truth by the paper's protocol" in said
    assert "simulator" not in said


@pytest.mark.parametrize("name,content,message", [
    ("wide.npy", np.zeros((500, 3)), "expected a numeric array of shape (3, N)"),
    ("bad.csv", "1,2,3\n4,5\n", "line 2: expected three columns"),
    ("words.csv", "vx,vy,vz\n1,2,3\na,b,c\n", "line 3: expected three numbers"),
    ("empty.npy", np.full((3, 4), np.nan), "no finite velocity row"),
    ("v.txt", "1,2,3\n", "expected a .npy (3 x N) or .csv"),
    ("missing.npy", None, "no such file"),
])
def test_bad_input_gives_one_line_exit_2_and_no_file(tmp_path, capsys, name, content,
                                                     message):
    path = tmp_path / name
    if isinstance(content, str):
        path.write_text(content)
    elif content is not None:
        np.save(path, content)
    out = tmp_path / "out.h5"
    assert auvsim_main(["import-velocity", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
    assert not out.exists() and list(tmp_path.glob(".*tmp")) == []


def test_reproduce_snapir_end_to_end_small(tmp_path, monkeypatch, capsys):
    data = tmp_path / "snapir"
    data.mkdir()
    np.save(data / "V.npy", stream(400))
    np.save(data / "V_test.npy", stream(120, seed=1))
    monkeypatch.chdir(tmp_path)
    assert beamsnet_main(["reproduce", "snapir", "--data", str(data), "--epochs", "2",
                          "--seeds", "2", "--out", "reports", "--quiet"]) == 0
    report = (tmp_path / "reports" / "snapir.md").read_text()
    for text in ("| validation", "| test (V_test.npy)", "62.86", "| Affine |", "| KF |",
                 "| BeamsNetV2 (seed_0) |", "| BeamsNetV2 (paper) (seed_1) |",
                 "| CorrectionNet (seed_0) |", "test mission: V_test.npy, 117 pings",
                 "| CorrectionNet | test | "):
        assert text in report
    assert (tmp_path / "reports" / "snapir.png").exists()
    # A second run reuses the imported file and the trained models.
    model = tmp_path / "runs" / "snapir" / "v2" / "seed_1" / "model.pt"
    stamp = model.stat().st_mtime_ns
    assert beamsnet_main(["reproduce", "snapir", "--data", str(data), "--epochs", "2",
                          "--seeds", "2", "--out", "reports", "--quiet"]) == 0
    assert model.stat().st_mtime_ns == stamp


def test_reproduce_snapir_without_the_data_says_where_it_comes_from(tmp_path, capsys):
    assert beamsnet_main(["reproduce", "snapir", "--data", str(tmp_path / "nowhere"),
                          "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "V.npy" in err and "BeamsNet paper" in err
