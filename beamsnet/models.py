"""BeamsNetV1 and BeamsNetV2 (Cohen & Klein 2022): DVL velocity from raw beam velocities.

Both networks regress the DVL's velocity (m/s, DVL frame) from the four measured beam
velocities of the current epoch (m/s, along each beam), helped by the IMU window that ends
at that epoch (V1) or by the beams of the previous epochs (V2). Sizes follow the published
code (the authors' public BeamsNet repository) exactly; every input is raw SI, as there:
neither the published code nor this one normalises inputs or targets.

Where these models differ from the published code, and why:

* V1 has two IMU heads by default, one Conv1d for the accelerometer and one for the
  gyroscope, as the paper's text and figure describe. The published code applies ONE conv
  to both windows; ``shared_imu_conv=True`` reproduces that (756,737 parameters, 42 fewer).
* V1's dropout is an ``nn.Dropout`` module, so ``model.eval()`` turns it off. The published
  code calls ``F.dropout(x, p=0.2)``, whose ``training`` argument defaults to True, so its
  predictions stay random at evaluation: a slip we do not copy.
* The IMU window (100 samples in the code) and the number of past epochs (a global ``T = 3``
  in the code) are constructor arguments, stored in ``model.kwargs`` so that a checkpoint
  can rebuild the model with ``build(model.name, **model.kwargs)``.
* V2's ``forward`` takes ``(past_beams, beams)``: context first, current beams last, as in
  V1. The published ``forward(x, y)`` takes the current beams first.
* Inputs are checked: a wrong shape raises ValueError instead of a broadcasting surprise.
* Parameter names differ from the published ``state_dict`` keys (``conv_layer``,
  ``ConvToFc``, ``FC_output``), so the published ``.pkl`` weights need a key mapping.

The final concatenation is kept in each version's published order: V1 feeds
``[2 features, 4 beams]`` to its output layer, V2 ``[4 beams, 2 features]``. The order does
not change what the networks can learn, but it fixes which columns of the output layer's
weight act on the beams, so published weights only load into the published order.
"""

from __future__ import annotations

from typing import ClassVar

import torch
from torch import nn

N_BEAMS = 4  # Janus DVL
N_AXES = 3  # x, y, z of an accelerometer or gyroscope triad, and of the velocity
CONV_CHANNELS = 6  # "six filters of size 2 x 1" (paper, sec. 3.1)
CONV_KERNEL = 2  # the smallest kernel that sees a change between neighbouring samples
N_FEATURES = 2  # what the context branch hands to the output layer, next to the 4 beams


def _conv_head(in_channels: int) -> nn.Sequential:
    """Conv1d(in -> 6, kernel 2, stride 1) + Tanh: the published feature extractor."""
    return nn.Sequential(nn.Conv1d(in_channels, CONV_CHANNELS, CONV_KERNEL), nn.Tanh())


def _init_weights(module: nn.Module) -> None:
    """Kaiming-uniform weights of every conv and linear layer, biases left at PyTorch's.

    We pass ``nonlinearity="relu"`` (gain sqrt 2) to every layer. The published code calls
    ``kaiming_uniform_(weight)`` with its defaults, ``nonlinearity="leaky_relu", a=0``, whose
    gain is also sqrt 2: naming "relu" says the same thing plainly and keeps the published
    initial distribution. Most layers do feed a ReLU; the Tanh conv (gain 5/3) and the linear
    output layer (gain 1) would call for slightly different gains, but matching the published
    start keeps our results comparable with the paper's.
    """
    for m in module.modules():
        if isinstance(m, (nn.Conv1d, nn.Linear)):
            nn.init.kaiming_uniform_(m.weight, nonlinearity="relu")


def _check_shape(name: str, x: torch.Tensor, expected: tuple[int, ...]) -> None:
    """Raise ValueError naming ``name`` unless ``x.shape == expected``."""
    if tuple(x.shape) != expected:
        raise ValueError(f"{name} must have shape {expected}, got {tuple(x.shape)}")


class BeamsNetV1(nn.Module):
    """IMU + DVL BeamsNet: current beams and the IMU window that ends at this DVL epoch.

    accel (B, 3, W) -> Conv1d + Tanh -> (B, 6, W-1) -\\
                                                     flatten, concat -> (B, 12 (W-1))
    gyro  (B, 3, W) -> Conv1d + Tanh -> (B, 6, W-1) -/
    -> Dropout -> FC 12 (W-1) -> 512 -> 256 -> 64 -> 2, each ReLU
    -> concat [2 features, 4 beams] -> Linear(6, 3) -> velocity (B, 3)

    Args:
        imu_window: IMU samples per DVL epoch, W (100 = a 100 Hz IMU and a 1 Hz DVL).
        dropout: probability of zeroing a conv feature, in training only.
        shared_imu_conv: one conv for both IMU windows, as in the published code (True), or
            one conv per sensor, as in the paper's text (False).
    """

    name: ClassVar[str] = "v1"

    def __init__(self, *, imu_window: int = 100, dropout: float = 0.2,
                 shared_imu_conv: bool = False) -> None:
        super().__init__()
        if not (isinstance(imu_window, int) and imu_window >= CONV_KERNEL):
            raise ValueError(f"imu_window must be an int >= {CONV_KERNEL}, got {imu_window!r}")
        if not 0.0 <= dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {dropout!r}")
        self.kwargs = dict(imu_window=imu_window, dropout=dropout,
                           shared_imu_conv=bool(shared_imu_conv))
        self.imu_window = imu_window
        # One head, used twice, or an accelerometer head and a gyro head; forward takes the
        # first for the accelerometer and the last for the gyro either way.
        self.imu_heads = nn.ModuleList(
            [_conv_head(N_AXES)] if shared_imu_conv else [_conv_head(N_AXES), _conv_head(N_AXES)]
        )
        # 2 sensors x 6 channels x (W - 1) positions of a kernel-2, stride-1 conv: 1188 at W=100.
        n_conv = 2 * CONV_CHANNELS * (imu_window - CONV_KERNEL + 1)
        self.dropout = nn.Dropout(dropout)
        # The published funnel: 1188 -> 512 -> 256 -> 64 -> 2, roughly halving to quartering
        # per layer; the 608k weights of the first layer are 80 % of the model.
        self.fc = nn.Sequential(
            nn.Linear(n_conv, 512), nn.ReLU(),
            nn.Linear(512, 256), nn.ReLU(),
            nn.Linear(256, 64), nn.ReLU(),
            nn.Linear(64, N_FEATURES), nn.ReLU(),
        )
        # No activation: a velocity can be negative. The beams reach this layer directly, so
        # the network can learn least squares (a linear map of the beams) plus a correction.
        self.out = nn.Linear(N_FEATURES + N_BEAMS, N_AXES)
        _init_weights(self)

    def forward(self, accel: torch.Tensor, gyro: torch.Tensor,
                beams: torch.Tensor) -> torch.Tensor:
        """Estimate the DVL velocity of each sample.

        Args:
            accel: (B, 3, W) specific force, m/s^2, axes along dim 1, time along dim 2.
            gyro: (B, 3, W) angular rate, rad/s, same layout.
            beams: (B, 4) measured beam velocities of the current epoch, m/s.

        Returns:
            (B, 3) DVL velocity, m/s.
        """
        b = beams.shape[0]
        _check_shape("beams", beams, (b, N_BEAMS))
        _check_shape("accel", accel, (b, N_AXES, self.imu_window))
        _check_shape("gyro", gyro, (b, N_AXES, self.imu_window))
        accel_head, gyro_head = self.imu_heads[0], self.imu_heads[-1]
        x = torch.cat([accel_head(accel).flatten(1), gyro_head(gyro).flatten(1)], dim=1)
        x = self.fc(self.dropout(x))  # (B, 2)
        return self.out(torch.cat([x, beams], dim=1))  # published order: features, beams


class BeamsNetV2(nn.Module):
    """DVL-only BeamsNet: current beams and the beams of the ``n_past`` previous epochs.

    past_beams (B, n, 4) -> Conv1d(n -> 6, kernel 2) over the 4 beams + Tanh -> (B, 6, 3)
    -> flatten (B, 18) -> FC 18 -> 16 -> 2, each ReLU
    -> concat [4 beams, 2 features] -> Linear(6, 3) -> velocity (B, 3)

    The epochs are the conv's input channels and the kernel slides over neighbouring beams
    (1-2, 2-3, 3-4), as in the published code.

    Args:
        n_past: previous DVL epochs in the input (3: the best of 2..7 in the paper's fig. 9).
    """

    name: ClassVar[str] = "v2"

    def __init__(self, *, n_past: int = 3) -> None:
        super().__init__()
        if not (isinstance(n_past, int) and n_past >= 1):
            raise ValueError(f"n_past must be an int >= 1, got {n_past!r}")
        self.kwargs = dict(n_past=n_past)
        self.n_past = n_past
        self.head = _conv_head(n_past)
        # 6 channels x (4 - 1) beam pairs = 18 features, then a small funnel: the whole
        # model has 401 parameters at n_past = 3, so it trains on a few thousand epochs.
        self.fc = nn.Sequential(
            nn.Linear(CONV_CHANNELS * (N_BEAMS - CONV_KERNEL + 1), 16), nn.ReLU(),
            nn.Linear(16, N_FEATURES), nn.ReLU(),
        )
        self.out = nn.Linear(N_BEAMS + N_FEATURES, N_AXES)  # no activation, as in V1
        _init_weights(self)

    def forward(self, past_beams: torch.Tensor, beams: torch.Tensor) -> torch.Tensor:
        """Estimate the DVL velocity of each sample.

        Args:
            past_beams: (B, n_past, 4) measured beam velocities of the previous epochs,
                oldest first, m/s.
            beams: (B, 4) measured beam velocities of the current epoch, m/s.

        Returns:
            (B, 3) DVL velocity, m/s.
        """
        b = beams.shape[0]
        _check_shape("beams", beams, (b, N_BEAMS))
        _check_shape("past_beams", past_beams, (b, self.n_past, N_BEAMS))
        x = self.fc(self.head(past_beams).flatten(1))  # (B, 2)
        return self.out(torch.cat([beams, x], dim=1))  # published order: beams, features


MODELS: dict[str, type[nn.Module]] = {"v1": BeamsNetV1, "v2": BeamsNetV2}


def build(name: str, **kwargs) -> nn.Module:
    """Build a model by name, e.g. ``build(m.name, **m.kwargs)`` from a checkpoint.

    Args:
        name: "v1" (BeamsNetV1) or "v2" (BeamsNetV2).
        **kwargs: keyword arguments of that model's constructor.

    Raises:
        ValueError: ``name`` is not a known model.
    """
    if name not in MODELS:
        raise ValueError(f"name must be one of {sorted(MODELS)}, got {name!r}")
    return MODELS[name](**kwargs)
