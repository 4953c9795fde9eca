"""BeamsNetV1/V2: shapes, the published parameter counts, dropout, the beams' path, build."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from beamsnet.estimators.networks import BeamsNetV1, BeamsNetV2, BeamsNetV2M, CorrectionNet, build


def n_params(model: torch.nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())  # a shared conv counts once


def v1_inputs(b: int, w: int = 100, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    return (torch.randn(b, 3, w, generator=g), torch.randn(b, 3, w, generator=g),
            torch.randn(b, 4, generator=g))


def v2_inputs(b: int, n_past: int = 3, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    return torch.randn(b, n_past, 4, generator=g), torch.randn(b, 4, generator=g)


@pytest.mark.parametrize("b", [1, 4])
def test_output_shapes(b):
    for shared in (False, True):
        assert BeamsNetV1(shared_imu_conv=shared)(*v1_inputs(b)).shape == (b, 3)
    assert BeamsNetV1(imu_window=20)(*v1_inputs(b, w=20)).shape == (b, 3)
    assert BeamsNetV2()(*v2_inputs(b)).shape == (b, 3)
    assert BeamsNetV2(n_past=5)(*v2_inputs(b, n_past=5)).shape == (b, 3)


def test_parameter_counts():
    # Published V1, one conv shared by both IMU windows:
    #   conv 3*6*2 + 6 = 42; fc 1188*512 + 512 = 608,768; 512*256 + 256 = 131,328;
    #   256*64 + 64 = 16,448; 64*2 + 2 = 130; output 6*3 + 3 = 21; total 756,737.
    assert n_params(BeamsNetV1(shared_imu_conv=True)) == 756_737
    # The paper's V1 has a second conv head (another 42): 756,737 + 42 = 756,779.
    assert n_params(BeamsNetV1()) == 756_779
    # V2: conv 3*6*2 + 6 = 42; fc 18*16 + 16 = 304; 16*2 + 2 = 34; output 6*3 + 3 = 21: 401.
    assert n_params(BeamsNetV2()) == 401
    assert n_params(BeamsNetV2(past_input="changes")) == 401  # the fixed V2: same layers
    # V2M: conv 6*6*2 + 6 = 78 (past changes and their masks); fc 304 + 34; output
    # 10*3 + 3 = 33: 449.
    assert n_params(BeamsNetV2M()) == 449
    # corr, n_past 3, no IMU: MLP 32*32 + 32 (16 values, 16 masks) = 1056, 32*32 + 32 =
    # 1056, 32*3 + 3 = 99; linear 3*3 + 3 = 12: 2223.
    assert n_params(CorrectionNet()) == 2223


def test_v1_dropout_is_off_in_eval_and_on_in_train():
    torch.manual_seed(0)
    model = BeamsNetV1(dropout=0.5)
    inputs = v1_inputs(8)
    with torch.no_grad():
        model.eval()
        assert torch.equal(model(*inputs), model(*inputs))
        model.train()
        assert not torch.equal(model(*inputs), model(*inputs))
    no_dropout = BeamsNetV1(dropout=0.0).train()
    with torch.no_grad():
        assert torch.equal(no_dropout(*inputs), no_dropout(*inputs))


def test_v1_heads_are_separate_unless_shared():
    two, one = BeamsNetV1(), BeamsNetV1(shared_imu_conv=True)
    assert len(two.imu_heads) == 2
    assert not torch.equal(two.imu_heads[0][0].weight, two.imu_heads[1][0].weight)
    assert len(one.imu_heads) == 1


def _zero_context(model: torch.nn.Module) -> None:
    """Zero every weight and bias except the output layer's."""
    with torch.no_grad():
        for name, p in model.named_parameters():
            if not name.startswith("out."):
                p.zero_()


def test_v2_output_layer_sees_the_current_beams_first():
    torch.manual_seed(1)
    model = BeamsNetV2().eval()
    past, beams = v2_inputs(4)
    with torch.no_grad():
        base = model(past, beams)
        nudged = beams.clone()
        nudged[:, 2] += 0.1
        assert not torch.allclose(model(past, nudged), base)
        # With the conv/FC branch at zero, tanh(0) = relu(0) = 0: the features are 0 and the
        # output is exactly the output layer applied to [beams, 0, 0] (published V2 order).
        _zero_context(model)
        w, b = model.out.weight, model.out.bias
        torch.testing.assert_close(model(past, beams), beams @ w[:, :4].T + b,
                                   rtol=0, atol=0)


def test_v1_output_layer_sees_the_current_beams_last():
    torch.manual_seed(2)
    model = BeamsNetV1().eval()
    accel, gyro, beams = v1_inputs(4)
    with torch.no_grad():
        _zero_context(model)
        w, b = model.out.weight, model.out.bias
        # Published V1 order: [2 features, 4 beams].
        torch.testing.assert_close(model(accel, gyro, beams), beams @ w[:, 2:].T + b,
                                   rtol=0, atol=0)


def test_wrong_input_shapes_are_named():
    accel, gyro, beams = v1_inputs(2, w=50)
    with pytest.raises(ValueError, match=r"accel must have shape \(2, 3, 100\), got \(2, 3, 50\)"):
        BeamsNetV1()(accel, gyro, beams)
    past, beams = v2_inputs(2, n_past=4)
    with pytest.raises(ValueError, match="past_beams must have shape"):
        BeamsNetV2()(past, beams)
    with pytest.raises(ValueError, match="beams must have shape"):
        BeamsNetV2()(*v2_inputs(2)[:1], torch.zeros(2, 3))


def test_bad_constructor_arguments_are_named():
    with pytest.raises(ValueError, match="imu_window"):
        BeamsNetV1(imu_window=1)
    with pytest.raises(ValueError, match="dropout"):
        BeamsNetV1(dropout=1.0)
    with pytest.raises(ValueError, match="n_past"):
        BeamsNetV2(n_past=0)
    with pytest.raises(ValueError, match="past_input"):
        BeamsNetV2(past_input="raw")
    with pytest.raises(ValueError, match="hidden"):
        CorrectionNet(hidden=0)


def test_build_rejects_unknown_names():
    with pytest.raises(ValueError, match=r"name must be one of \['corr', 'v1', 'v2', 'v2m'\], "
                       "got 'v3'"):
        build("v3")


@pytest.mark.parametrize("name, kwargs", [
    ("v1", dict(imu_window=40, dropout=0.1, shared_imu_conv=True)),
    ("v1", {}),
    ("v2", dict(n_past=5)),
    ("v2", dict(n_past=2, past_input="changes")),
    ("v2m", dict(n_past=4)),
    ("corr", dict(n_past=0, imu=True, hidden=8)),
])
def test_kwargs_round_trip(name, kwargs):
    model = build(name, **kwargs)
    assert model.name == name
    rebuilt = build(model.name, **model.kwargs)
    assert type(rebuilt) is type(model)
    assert rebuilt.kwargs == model.kwargs
    shapes = {k: v.shape for k, v in model.state_dict().items()}
    assert {k: v.shape for k, v in rebuilt.state_dict().items()} == shapes
    rebuilt.load_state_dict(model.state_dict())  # strict: same keys, same shapes


def test_v1_takes_the_imu_axes_as_channels_and_time_along_the_window():
    import numpy as np

    from beamsnet.estimators.networks import _imu

    accel = np.random.default_rng(0).normal(size=(2, 100, 3))  # (samples, window, axes)
    accel_t, gyro_t = _imu(SimpleNamespace(accel=accel, gyro=-accel))
    assert accel_t.shape == (2, 3, 100)
    for sample, k, axis in ((0, 5, 2), (1, 99, 0), (1, 0, 1)):
        assert accel_t[sample, axis, k].item() == pytest.approx(accel[sample, k, axis],
                                                                rel=1e-6)
        assert gyro_t[sample, axis, k].item() == pytest.approx(-accel[sample, k, axis],
                                                               rel=1e-6)


def test_a_model_of_fewer_past_pings_gets_the_newest():
    """Windows hold the past pings oldest first; a model trained on fewer (a checkpoint's
    ``n_past``, or V2's own) takes the last of them."""
    import numpy as np

    from beamsnet.data import Windows
    from beamsnet.estimators.networks import _past
    from beamsnet.evaluate import trimmed

    n = 5
    past = np.broadcast_to(np.arange(3.0)[None, :, None], (n, 3, 4)).copy()  # 2: newest
    windows = Windows(beams=np.zeros((n, 4)), past_beams=past, accel=None, gyro=None,
                      target=np.zeros((n, 3)), velocity_ls=np.zeros((n, 3)),
                      mission=np.zeros(n, dtype=np.int64), time=np.arange(float(n)),
                      names=("m",), h=np.eye(4, 3))
    np.testing.assert_array_equal(
        trimmed(windows, {"train_config": {"n_past": 1}}).past_beams, past[:, 2:])
    np.testing.assert_array_equal(_past(windows, 2).numpy(), past[:, 1:])
