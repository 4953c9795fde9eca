"""Our learned estimators (CorrectionNet, BeamsNetV2M) and the fixed V2 protocol, on tiny
synthetic samples built here and a 90 s simulated mission."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch
from conftest import flat, mission, write

from auvsim.config import DvlConfig
from auvsim.sensors.dvl import beam_matrix, least_squares
from beamsnet.data import load_windows, split
from beamsnet.estimators.networks import (
    BeamsNetV2,
    BeamsNetV2M,
    CorrectionNet,
    masked_least_squares,
)
from beamsnet.training.checkpoints import CheckpointError, load
from beamsnet.training.config import TrainConfig
from beamsnet.training.train import predict, train

H = torch.as_tensor(beam_matrix(math.radians(20.0)), dtype=torch.float32)
SCALE, BIAS = 0.007, 1e-4  # the published error model's scale factor and bias (m/s)


def measure(v: torch.Tensor, noise: float = 0.0, seed: int = 0) -> torch.Tensor:
    """(n, 4) beams of velocities v (n, 3) m/s under the published error model."""
    rng = np.random.default_rng(seed)
    n = torch.as_tensor(rng.normal(0.0, noise, (len(v), 4)), dtype=torch.float32)
    return (1 + SCALE) * v @ H.T + BIAS + n


def samples(n: int, low: float, high: float, *, seed: int = 0, n_past: int = 3,
            noise: float = 0.0):
    """(beams (n, 4), past beams (n, n_past, 4), true velocity (n, 3)): velocity components
    uniform in [low, high] m/s, constant over the past pings, beams with the published
    scale factor and bias and white noise of std ``noise`` m/s."""
    rng = np.random.default_rng(seed)
    v = torch.as_tensor(rng.uniform(low, high, (n, 3)), dtype=torch.float32)
    beams = measure(v, noise, seed)
    past = torch.stack([measure(v, noise, seed + 1 + j) for j in range(n_past)], dim=1)
    return beams, past, v


def fitted_corr(seed: int = 0) -> CorrectionNet:
    """A CorrectionNet fitted on velocities in [0.5, 2] m/s, its nonlinear term trained
    away from zero (full-batch Adam, so its output is not trivially the linear part)."""
    torch.manual_seed(seed)
    beams, past, v = samples(512, 0.5, 2.0, seed=seed, noise=1e-3)
    model = CorrectionNet(n_past=3)
    model.initialise([beams, past], v, H)
    optimizer = torch.optim.Adam(model.mlp.parameters(), lr=0.01)
    wobble = 1e-3 * torch.sin(3 * v)  # a smooth nonlinear target for the MLP to fit
    for _ in range(100):
        loss = torch.nn.functional.mse_loss(model(beams, past), v + wobble)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return model.eval()


def linear_part(model: CorrectionNet, beams: torch.Tensor) -> torch.Tensor:
    ls = masked_least_squares(beams, torch.isfinite(beams), model.h)
    return ls + model.linear(ls)


def test_masked_least_squares_matches_ls_and_needs_three_beams():
    beams, _, _ = samples(20, -2.0, 2.0)
    every = torch.ones_like(beams, dtype=torch.bool)
    np.testing.assert_allclose(masked_least_squares(beams, every, H).numpy(),
                               least_squares(beams.double().numpy(), H.double().numpy()),
                               atol=1e-5)
    three = every.clone()
    three[:, 1] = False
    holed = beams.double().numpy()
    holed[:, 1] = np.nan  # auvsim's LS solves the 3 valid beams exactly
    ref = least_squares(holed, H.double().numpy())
    np.testing.assert_allclose(masked_least_squares(beams, three, H).numpy(), ref, atol=1e-5)
    two = three.clone()
    two[:5, 2] = False
    out = masked_least_squares(beams, two, H)
    assert torch.isnan(out[:5]).all() and torch.isfinite(out[5:]).all()


def test_corr_starts_at_the_affine_fit_and_its_linear_part_is_exact_on_the_error_model():
    beams, past, v = samples(256, 0.5, 2.0)
    model = CorrectionNet(n_past=3)
    model.initialise([beams, past], v, H)
    # The nonlinear term's last layer is zero: the output is the linear part, and with a
    # scale factor and a bias (noise-free) that inverts the error model exactly.
    np.testing.assert_allclose(model(beams, past).detach().numpy(), v.numpy(), atol=2e-5)
    assert torch.all(model.bound < 1e-4)  # the linear fit's largest training residual


def test_corr_falls_back_to_the_linear_part_outside_the_training_range():
    model = fitted_corr()
    assert torch.any(model.mlp[-1].weight != 0)  # the nonlinear term did train
    _, _, v = samples(256, 0.5, 2.0, seed=1)
    # Velocities whose every beam, at 10 times the speed, is beyond the training beams
    # (|beam| <= 2.4 m/s for components up to 2 m/s): then every input is clipped.
    v = v[(measure(v).abs() > 0.3).all(dim=1)]
    n = len(v)
    assert n > 50
    with torch.no_grad():
        near = model(measure(v), measure(v)[:, None].repeat(1, 3, 1))
        assert torch.any((near - linear_part(model, measure(v))).abs() > 1e-5)
        out, nonlinear = [], []
        for k in (10.0, 20.0):  # 5 .. 40 m/s: every beam is beyond its training range
            beams = measure(k * v)
            out.append(model(beams, beams[:, None].repeat(1, 3, 1)))
            nonlinear.append(out[-1] - linear_part(model, beams))
    # Bounded by the bound, and constant once the inputs are clipped to the training range.
    assert torch.all(nonlinear[0].abs() <= model.bound)
    # (float32 rounding of 40 m/s values is 4e-6 m/s)
    np.testing.assert_allclose(nonlinear[0].numpy(), nonlinear[1].numpy(), atol=2e-5)
    # So the velocity follows the linear calibration, which holds at any speed: at 10 and
    # 20 times the training velocities the speed error stays under 0.1 % of the speed,
    # where LS's is the 0.7 % scale factor.
    for o, k in zip(out, (10.0, 20.0), strict=True):
        speed = torch.linalg.norm(k * v, dim=1)
        ls = masked_least_squares(measure(k * v), torch.ones(n, 4, dtype=torch.bool), H)
        assert torch.all((torch.linalg.norm(ls, dim=1) - speed).abs() > 0.006 * speed)
        assert torch.all((torch.linalg.norm(o, dim=1) - speed).abs() < 0.001 * speed)


@pytest.mark.parametrize("make", [lambda: fitted_corr(),
                                  lambda: _v2m()])
def test_a_masked_beam_does_not_change_the_output(make):
    model = make()
    beams, past, _ = samples(16, 0.5, 2.0, seed=2)
    mask = torch.ones_like(beams, dtype=torch.bool)
    mask[:, 2] = False
    past_mask = torch.ones_like(past, dtype=torch.bool)
    past_mask[:, 0, 1] = False
    args = (beams, past) if isinstance(model, CorrectionNet) else (past, beams)
    with torch.no_grad():
        ref = model(*args, mask=mask, past_mask=past_mask)
        other_beams, other_past = beams.clone(), past.clone()
        other_beams[:, 2] = torch.randn(16) * 100
        other_past[:, 0, 1] = torch.randn(16) * 100
        moved = (other_beams, other_past) if isinstance(model, CorrectionNet) else (
            other_past, other_beams)
        other = model(*moved, mask=mask, past_mask=past_mask)
        nan_beams, nan_past = beams.clone(), past.clone()
        nan_beams[:, 2] = float("nan")
        nan_past[:, 0, 1] = float("nan")
        by_nan = model(*((nan_beams, nan_past) if isinstance(model, CorrectionNet)
                         else (nan_past, nan_beams)))
        whole = model(*args)
    np.testing.assert_array_equal(ref.numpy(), other.numpy())
    np.testing.assert_array_equal(ref.numpy(), by_nan.numpy())
    assert torch.isfinite(ref).all() and not torch.equal(ref, whole)


def _v2m() -> BeamsNetV2M:
    torch.manual_seed(0)
    model = BeamsNetV2M(n_past=3)
    model.initialise([], torch.zeros(0, 3), H)
    return model.eval()


def test_v2m_fills_a_missing_current_beam_from_the_geometry_and_needs_three():
    model = _v2m()
    beams, past, _ = samples(8, 0.5, 2.0)
    beams = beams - BIAS  # in H's column space: the filled beam is exactly the true one
    missing = beams.clone()
    missing[:, 3] = float("nan")
    with torch.no_grad():
        # With the masks' and features' weights zero, the output layer sees only the
        # (filled) current beams: a filled beam gives what the true beam gives.
        model.out.weight[:, 4:] = 0
        np.testing.assert_allclose(model(past, missing).numpy(), model(past, beams).numpy(),
                                   atol=1e-5)
        two = missing.clone()
        two[:3, 0] = float("nan")
        out = model(past, two)
    assert torch.isnan(out[:3]).all() and torch.isfinite(out[3:]).all()
    assert sum(p.numel() for p in model.parameters()) == 449


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """One straight 90 s mission at 2 m/s, 20 deg beams with a 5 % scale factor."""
    return write(flat(mission("a", 1, speed=2.0, duration=90.0, start_speed=0.0),
                      dvl=DvlConfig(beam_angle_deg=20.0, scale_factor=0.05)),
                 tmp_path_factory.mktemp("data") / "line.h5")


@pytest.mark.parametrize("model", ["corr", "v2m"])
def test_checkpoint_round_trip_and_corrupt_files_are_refused(model, dataset, tmp_path):
    config = TrainConfig(model=model, epochs=1, lr=1e-3)
    assert config.drop_rate == 0.1  # the masked models train with beams dropped
    train(dataset, config, tmp_path / "run", progress=False)
    net, checkpoint = load(tmp_path / "run")
    again, _ = load(tmp_path / "run" / "model.pt")
    assert TrainConfig(**checkpoint["train_config"]).drop_rate == 0.1
    _, test = split(load_windows(dataset, n_past=3))
    np.testing.assert_array_equal(predict(net, test), predict(again, test))
    assert torch.equal(net.h, torch.as_tensor(test.h, dtype=torch.float32))
    # A ping that lost a beam still has an estimate; one that lost two has none.
    holes = test._replace(beams=test.beams.copy())
    holes.beams[0, 1] = np.nan
    holes.beams[1, :2] = np.nan
    out = predict(net, holes)
    assert np.isfinite(out[0]).all() and np.isnan(out[1]).all() and np.isfinite(out[2:]).all()
    data = (tmp_path / "run" / "model.pt").read_bytes()
    (tmp_path / "run" / "model.pt").write_bytes(data[:len(data) // 2])
    with pytest.raises(CheckpointError):
        load(tmp_path / "run")


def test_v2_protocol_is_recorded_and_the_paper_one_is_unchanged(dataset, tmp_path):
    for protocol in ("paper", "fixed"):
        train(dataset, TrainConfig(model="v2", epochs=1, protocol=protocol),
              tmp_path / protocol, progress=False)
    paper, paper_ckpt = load(tmp_path / "paper")
    fixed, fixed_ckpt = load(tmp_path / "fixed")
    assert paper_ckpt["train_config"]["protocol"] == "paper"
    assert fixed_ckpt["train_config"]["protocol"] == "fixed"
    assert (paper.past_input, fixed.past_input) == ("beams", "changes")
    assert sum(p.numel() for p in fixed.parameters()) == 401
    # A paper-protocol run is today's BeamsNetV2: a checkpoint without past_input (every
    # run written before the option) builds it, and the same weights give the same output.
    windows = load_windows(dataset, n_past=3)
    old = BeamsNetV2(n_past=3)
    old.load_state_dict(paper.state_dict())
    np.testing.assert_array_equal(predict(old, windows), predict(paper, windows))
    # The fixed V2 is the same network on the past beams' changes to the current ones.
    past, beams = old.inputs(windows)
    changes = BeamsNetV2(n_past=3, past_input="changes")
    changes.load_state_dict(paper.state_dict())
    with torch.no_grad():
        np.testing.assert_allclose(changes(past, beams).numpy(),
                                   old(past - beams[:, None, :], beams).numpy(), atol=1e-6)


def test_v1_and_v2_give_nan_rows_where_an_input_beam_is_nan(dataset, tmp_path):
    train(dataset, TrainConfig(model="v2", epochs=1), tmp_path / "v2", progress=False)
    net, _ = load(tmp_path / "v2")
    windows = load_windows(dataset, n_past=3)
    holes = windows._replace(past_beams=windows.past_beams.copy())
    holes.past_beams[0, 1, 2] = np.nan
    out = predict(net, holes)
    assert np.isnan(out[0]).all() and np.isfinite(out[1:]).all()


def test_cli_trains_corr_and_the_paper_v2(dataset, tmp_path, capsys):
    from beamsnet.cli import main

    assert main(["train", str(dataset), "--model", "corr", "--epochs", "1", "--out",
                 str(tmp_path / "corr"), "--quiet"]) == 0
    assert main(["train", str(dataset), "--model", "v2", "--protocol", "paper", "--epochs",
                 "1", "--out", str(tmp_path / "v2"), "--quiet"]) == 0
    assert "trained CorrectionNet" in capsys.readouterr().out
    corr, v2 = load(tmp_path / "corr")[1], load(tmp_path / "v2")[1]
    assert corr["model"] == "corr"
    assert TrainConfig(**corr["train_config"]).drop_rate == 0.1
    assert corr["kwargs"] == {"n_past": 3, "imu": False}
    assert (v2["train_config"]["protocol"], v2["kwargs"]["past_input"]) == ("paper", "beams")
    assert TrainConfig(**v2["train_config"]).drop_rate == 0.0
    # A profile's config given the masked model keeps the masked model's default rate.
    assert dataclasses.replace(TrainConfig(), model="v2m").drop_rate == 0.1
