"""A run remembers its training data's sensors; evaluating it on other sensors is refused
(geometry, rates) or said (error model), on one line."""

from __future__ import annotations

import copy
import warnings

import pytest
import torch
from conftest import flat, mission, write

from auvsim.config import DvlConfig
from auvsim.errors import ConfigError
from beamsnet.cli import main
from beamsnet.evaluate import SensorSetupWarning, check_sensors
from beamsnet.training.checkpoints import load, sensor_setup
from beamsnet.training.config import TrainConfig
from beamsnet.training.train import train


def line(path, **dvl):
    """One straight 90 s mission "a" at 2 m/s; the DVL is 20 deg beams with a 5 % scale
    factor unless ``dvl`` says otherwise."""
    return write(flat(mission("a", 1, speed=2.0, duration=90.0, start_speed=0.0),
                      dvl=DvlConfig(**{"beam_angle_deg": 20.0, "scale_factor": 0.05, **dvl})),
                 path)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("sensors")
    return dict(trained=line(d / "trained.h5"), wide=line(d / "wide.h5", beam_angle_deg=30.0),
                noisier=line(d / "noisier.h5", scale_factor=0.02, noise_std=0.01))


@pytest.fixture(scope="module")
def run(data, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "v2"
    train(data["trained"], TrainConfig(model="v2", epochs=1), out, progress=False)
    return out


def test_the_checkpoint_stores_the_training_datas_sensors(run):
    _, checkpoint = load(run)
    assert checkpoint["sensors"] == {"a": {
        "beam_angle_deg": 20.0, "dvl_mounting_rpy_deg": [0.0, 0.0, 0.0], "dvl_rate_hz": 1.0,
        "imu_rate_hz": 100.0, "dvl_scale_factor": [0.05] * 4, "dvl_bias": [0.0] * 4,
        "dvl_noise_std": 0.0}}


def test_the_same_sensors_evaluate_without_a_word(run, data, tmp_path, capsys):
    assert main(["evaluate", str(run), str(data["trained"]), "--out", str(tmp_path / "r")]) == 0
    assert capsys.readouterr().err == ""


def test_other_beams_are_refused_unless_allowed(run, data, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["evaluate", str(run), str(data["wide"]), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"beamsnet: error: DATASET "
                                                   f"'{data['wide']}': its sensors differ")
    assert f"run '{run}'" in err and "beam_angle_deg 30 (mission a) against 20;" in err
    # Named by its flag, as the user can give it.
    assert "(--allow-mismatch evaluates anyway)" in err and "allow_mismatch" not in err
    assert not out.exists()

    assert main(["evaluate", str(run), str(data["wide"]), "--out", str(out),
                 "--allow-mismatch"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("beamsnet: warning: ")
    assert "beam_angle_deg 30 (mission a) against 20; evaluated anyway, as allowed" in err
    assert (out / "evaluation.md").exists()


def test_another_error_model_is_a_robustness_test_said_in_one_line(run, data, tmp_path,
                                                                  capsys):
    assert main(["evaluate", str(run), str(data["noisier"]), "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("beamsnet: warning: ")
    assert ("dvl_scale_factor [0.02, 0.02, 0.02, 0.02] (mission a) against "
            "[0.05, 0.05, 0.05, 0.05]; dvl_noise_std 0.01 (mission a) against 0;") in err
    assert "beam_angle" not in err and "robustness" in err


def test_other_draws_of_one_error_model_are_held_out_seeds_said_nothing(tmp_path):
    """Trained on one seed of a DVL whose scale factors and biases are drawn per mission,
    evaluated on another seed of the same config: the realised values differ, the model
    they were drawn from does not, so no warning; a file of another model still warns."""
    spread = dict(scale_factor=0.0, scale_factor_std=0.003, bias_std=0.001, noise_std=0.002)
    files = {}
    for name, seed, dvl in (("train", 1, spread), ("seed", 2, spread),
                            ("other", 2, {**spread, "scale_factor_std": 0.01})):
        files[name] = write(flat(mission("a", seed, speed=2.0, duration=90.0, start_speed=0.0),
                                 dvl=DvlConfig(beam_angle_deg=20.0, **dvl)),
                            tmp_path / f"{name}.h5")
    run = tmp_path / "run"
    train(files["train"], TrainConfig(model="v2", epochs=1), run, progress=False)
    _, checkpoint = load(run)
    assert sensor_setup(files["seed"])["a"]["dvl_scale_factor"] != \
        checkpoint["sensors"]["a"]["dvl_scale_factor"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", SensorSetupWarning)
        check_sensors(run, checkpoint, files["seed"])
    with pytest.warns(SensorSetupWarning, match="its DVL error model differs"):
        check_sensors(run, checkpoint, files["other"])


def test_a_run_from_before_the_sensor_record_is_evaluated_with_a_warning(
        run, data, tmp_path, capsys):
    old = tmp_path / "old"
    old.mkdir()
    checkpoint = torch.load(run / "model.pt", weights_only=True)
    del checkpoint["sensors"]
    torch.save(checkpoint, old / "model.pt")
    assert main(["evaluate", str(old), str(data["wide"]), "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"beamsnet: warning: run '{old}': ")
    assert "cannot be checked" in err


def test_rates_and_mounting_are_geometry(run, data):
    """A network learned one ping spacing, one IMU window and one mounting: other values
    are refused, naming both; an attribute one side lacks (an imported stream has no IMU
    rate) is not compared."""
    _, checkpoint = load(run)
    other = copy.deepcopy(checkpoint)
    other["sensors"]["a"].update(dvl_rate_hz=2.0, dvl_mounting_rpy_deg=[0.0, 0.0, 45.0])
    with pytest.raises(ConfigError) as refused:
        check_sensors(run, other, data["trained"])
    assert refused.value.argument == "datasets"
    assert ("dvl_mounting_rpy_deg [0, 0, 0] (mission a) against [0, 0, 45]; "
            "dvl_rate_hz 1 (mission a) against 2;") in str(refused.value)
    with pytest.warns(SensorSetupWarning, match="dvl_rate_hz 1 .mission a. against 2"):
        check_sensors(run, other, data["trained"], allow_mismatch=True)
    imported = copy.deepcopy(checkpoint)
    del imported["sensors"]["a"]["imu_rate_hz"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", SensorSetupWarning)  # no error, no warning
        check_sensors(run, imported, data["trained"])
    assert sensor_setup(data["trained"]) == checkpoint["sensors"]
    # A calibration's residual mounting and a clock's rate error are the same setup:
    # within a degree and 1 %; just beyond either is refused.
    near = copy.deepcopy(checkpoint)
    near["sensors"]["a"].update(dvl_rate_hz=0.9975, imu_rate_hz=100.9,
                                dvl_mounting_rpy_deg=[0.27, -0.07, -0.99])
    with warnings.catch_warnings():
        warnings.simplefilter("error", SensorSetupWarning)
        check_sensors(run, near, data["trained"])
    for change in (dict(dvl_rate_hz=0.985), dict(dvl_mounting_rpy_deg=[0.0, 0.0, 1.02])):
        beyond = copy.deepcopy(checkpoint)
        beyond["sensors"]["a"].update(change)
        with pytest.raises(ConfigError, match=next(iter(change))):
            check_sensors(run, beyond, data["trained"])


def test_a_mismatch_over_many_missions_names_a_few():
    """A file of 20 missions had each difference list all 20 names."""
    from beamsnet.evaluate import _missions

    assert _missions(["a"], 1) == "mission a"
    assert _missions(list("abcde"), 20) == "missions a, b, c and 2 more"
    assert _missions(list("ab"), 2) == "every mission"
