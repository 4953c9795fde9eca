"""BeamsNetV1 and BeamsNetV2 (Cohen & Klein 2022): DVL velocity from raw beam velocities;
and two models of ours that run on pings with missing beams: BeamsNetV2M (V2 with validity
masks, as MissBeamNet, Yona & Klein 2024, gives its network the missing beams) and
CorrectionNet (least squares on the valid beams plus a learned, bounded correction).

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
* ``BeamsNetV2(past_input="changes")`` feeds the past beams as their changes to the current
  ones (same layers): the fix of V2's extrapolation, see ``BeamsNetV2``. The default,
  ``"beams"``, is the published input, and what a checkpoint without the option builds.
* Parameter names differ from the published ``state_dict`` keys (``conv_layer``,
  ``ConvToFc``, ``FC_output``), so the published ``.pkl`` weights need a key mapping.

The final concatenation is kept in each version's published order: V1 feeds
``[2 features, 4 beams]`` to its output layer, V2 ``[4 beams, 2 features]``. The order does
not change what the networks can learn, but it fixes which columns of the output layer's
weight act on the beams, so published weights only load into the published order.
"""

from __future__ import annotations

import contextlib
from typing import TYPE_CHECKING, ClassVar

import torch
from torch import nn

from beamsnet.data import DataError
from beamsnet.estimators.registry import Needs, Spec

if TYPE_CHECKING:
    from beamsnet.data import Windows

N_BEAMS = 4  # Janus DVL
N_AXES = 3  # x, y, z of an accelerometer or gyroscope triad, and of the velocity
CONV_CHANNELS = 6  # "six filters of size 2 x 1" (paper, sec. 3.1)
CONV_KERNEL = 2  # the smallest kernel that sees a change between neighbouring samples
# The longest input window a network takes (IMU samples, past pings): its layers grow
# with it, and a checkpoint asking for more (n_past = 10**9: 48 GB) is not one of ours.
MAX_WINDOW = 10_000
N_FEATURES = 2  # what the context branch hands to the output layer, next to the 4 beams
PAST_INPUTS = ("beams", "changes")  # what V2's conv sees of the past epochs (see BeamsNetV2)
MIN_BEAMS = 3  # valid beams for a 3-D velocity: any 3 of a Janus DVL's 4 are independent
# Torch threads of every training (``training_threads``), on any machine and in any pool:
# the number of threads sets how torch splits its sums, so it changes the weights' last
# bits, and training grows those into other weights (a seed trained alone with two threads
# and in a pool with one gave different models). One, because reproduce, stress and
# restarts train several models at once, one process per core; a model trained alone at
# batch 4 loses little by it (``benchmarks/training.py`` prints the ratio).
TRAINING_THREADS = 1


@contextlib.contextmanager
def training_threads():
    """Run the block (or, as a decorator, the function) with ``TRAINING_THREADS`` torch
    threads, and give the process its own number back after."""
    previous = torch.get_num_threads()
    torch.set_num_threads(TRAINING_THREADS)
    try:
        yield
    finally:
        torch.set_num_threads(previous)


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


def _beams(windows: Windows) -> torch.Tensor:
    """(S, 4) current beams, float32."""
    return torch.as_tensor(windows.beams, dtype=torch.float32)


def _past(windows: Windows, n_past: int | None = None) -> torch.Tensor:
    """(S, n, 4) the last ``n_past`` (default: all) past pings' beams, float32."""
    n = windows.past_beams.shape[1] if n_past is None else n_past
    return torch.as_tensor(windows.past_beams[:, windows.past_beams.shape[1] - n:],
                           dtype=torch.float32)


def _imu(windows: Windows) -> list[torch.Tensor]:
    """[accel, gyro], each (S, 3, W) float32: the axes are the conv's channels, time runs
    along W."""
    if windows.accel is None:
        raise DataError("the windows have no IMU data, which BeamsNetV1 takes (an imported "
                        "DVL stream has none); expected a dataset with an IMU for it, or a "
                        "network that takes none (BeamsNetV2)")
    return [torch.as_tensor(x, dtype=torch.float32).transpose(1, 2).contiguous()
            for x in (windows.accel, windows.gyro)]


def _drop_beams(x: list[torch.Tensor], beams_at: int, past_at: int, rate: float,
                generator: torch.Generator) -> list[torch.Tensor]:
    """A batch of a masked model's inputs ``x`` with beams dropped (NaN) at random: with
    probability ``rate`` one current beam of a sample (``x[beams_at]``; so 3 stay: LS
    still has an estimate), and each past beam value (``x[past_at]``) with probability
    ``rate``."""
    beams, past = x[beams_at], x[past_at]
    b = len(beams)
    which = torch.randint(0, beams.shape[1], (b,), generator=generator)
    hit = torch.rand(b, generator=generator) < rate
    drop = torch.zeros_like(beams, dtype=torch.bool)
    drop[torch.arange(b)[hit], which[hit]] = True
    nan = torch.tensor(float("nan"))
    out = list(x)
    out[beams_at] = torch.where(drop, nan, beams)
    out[past_at] = torch.where(torch.rand(past.shape, generator=generator) < rate, nan, past)
    return out


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
    masked: ClassVar[bool] = False  # trains with beams dropped, runs on missing beams
    imu_option: ClassVar[bool] = False  # takes the IMU or not as its config says

    @classmethod
    def options(cls, config, windows: Windows) -> dict:
        """Constructor arguments from a ``TrainConfig`` and the training windows."""
        return dict(imu_window=windows.accel.shape[1], dropout=config.dropout,
                    shared_imu_conv=config.shared_imu_conv)

    def inputs(self, windows: Windows) -> list[torch.Tensor]:
        """What ``forward`` takes, float32, for every sample of ``windows``.

        Raises:
            DataError: the windows have no IMU data.
        """
        return [*_imu(windows), _beams(windows)]

    def __init__(self, *, imu_window: int = 100, dropout: float = 0.2,
                 shared_imu_conv: bool = False) -> None:
        super().__init__()
        if not (isinstance(imu_window, int) and CONV_KERNEL <= imu_window <= MAX_WINDOW):
            raise ValueError(f"imu_window must be an int in [{CONV_KERNEL}, {MAX_WINDOW}], "
                             f"got {imu_window!r}")
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

    ``past_input="changes"`` feeds the conv ``past_beams - beams`` (each past epoch's change
    to the current one) instead of the raw past beams; the architecture and the 401
    parameters are the same. Why (measured on the Snapir streams, ``reports/snapir.md``): the
    output layer is linear in the current beams plus the 2 ReLU features, and with raw past
    beams the features' pre-activations grow with the velocity itself, since the past beams
    are nearly the current ones. On the training split a feature ends up either off for
    every ping (the network is then exactly an affine calibration there) or on for every
    ping (linear: part of the calibration); at velocities outside the training range it
    switches, and an off feature comes on with weights that training never moved: the
    network extrapolates badly where an affine calibration does not (seed 2: -55.8 % against
    LS on the test mission in ``reports/snapir.md``; in an earlier run of that seed, -51 %,
    and +38 % with the features held at their training mean).
    The changes do not depend on the velocity level (a constant velocity gives zero changes,
    whatever it is), only on the accelerations between pings: the velocity then reaches the
    output through the linear path alone, and the network stays affine in the current beams
    at any velocity, with the features as a bounded-dynamics correction.

    Args:
        n_past: previous DVL epochs in the input (3: the best of 2..7 in the paper's fig. 9).
        past_input: ``"beams"`` (the paper and the published code) or ``"changes"``.
    """

    name: ClassVar[str] = "v2"
    masked: ClassVar[bool] = False
    imu_option: ClassVar[bool] = False

    @classmethod
    def options(cls, config, windows: Windows) -> dict:
        """Constructor arguments from a ``TrainConfig`` (its protocol: the published raw
        past beams, or their changes) and the training windows."""
        return dict(n_past=config.n_past,
                    past_input="beams" if config.protocol == "paper" else "changes")

    def inputs(self, windows: Windows) -> list[torch.Tensor]:
        """What ``forward`` takes, float32: every past ping of the windows (the caller
        trims them to ``n_past``, ``beamsnet.evaluate.trimmed``) and the current beams."""
        return [_past(windows), _beams(windows)]

    def __init__(self, *, n_past: int = 3, past_input: str = "beams") -> None:
        super().__init__()
        if not (isinstance(n_past, int) and 1 <= n_past <= MAX_WINDOW):
            raise ValueError(f"n_past must be an int in [1, {MAX_WINDOW}], got {n_past!r}")
        if past_input not in PAST_INPUTS:
            raise ValueError(f"past_input must be one of {PAST_INPUTS}, got {past_input!r}")
        self.kwargs = dict(n_past=n_past, past_input=past_input)
        self.n_past = n_past
        self.past_input = past_input
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
        if self.past_input == "changes":
            past_beams = past_beams - beams[:, None, :]
        x = self.fc(self.head(past_beams).flatten(1))  # (B, 2)
        return self.out(torch.cat([beams, x], dim=1))  # published order: beams, features


def _valid(x: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
    """The validity mask of beam values ``x``: ``mask`` (if given) and finite."""
    ok = torch.isfinite(x)
    return ok if mask is None else ok & mask.bool()


def masked_least_squares(beams: torch.Tensor, mask: torch.Tensor,
                         h: torch.Tensor) -> torch.Tensor:
    """Least squares on the valid beams of each sample, ``(H^T M H)^-1 H^T M y``.

    Args:
        beams: (B, 4) beam velocities, m/s; values where ``mask`` is False are ignored.
        mask: (B, 4) bool, the valid beams.
        h: (4, 3) beam matrix (unit beam directions, DVL frame).

    Returns:
        (B, 3) velocity, m/s; NaN where fewer than 3 beams are valid (no estimate).
    """
    m = mask.to(beams.dtype)
    y = torch.where(mask, beams, torch.zeros_like(beams))
    a = torch.einsum("bk,ki,kj->bij", m, h, h)
    rhs = torch.einsum("bk,ki->bi", m * y, h)
    ok = mask.sum(dim=1) >= MIN_BEAMS
    eye = torch.eye(N_AXES, dtype=beams.dtype).expand_as(a)
    v = torch.linalg.solve(torch.where(ok[:, None, None], a, eye), rhs)
    return torch.where(ok[:, None], v, torch.full_like(v, float("nan")))


class BeamsNetV2M(nn.Module):
    """BeamsNetV2 with validity masks: runs on pings where beams have no bottom lock.

    past changes (B, n, 4), zero where invalid, and their masks (B, n, 4)
    -> Conv1d(2n -> 6, kernel 2) over the 4 beams + Tanh -> (B, 6, 3)
    -> flatten (B, 18) -> FC 18 -> 16 -> 2, each ReLU
    -> concat [4 current beams, 4 current masks, 2 features] -> Linear(10, 3) -> velocity

    V2's layers, with each past epoch's mask as one more input channel of the conv and the
    current beams' masks as 4 more inputs of the output layer (449 parameters at n = 3,
    V2's 401 plus 48). A missing CURRENT beam is not zero-filled: a linear output layer
    cannot re-weight the other three beams when one is missing, and a zero would read as a
    velocity. It is filled with its value under the beam geometry, ``h_k . v`` with v the
    least squares of the other three (exact without noise, since 4 beams over-determine a
    3-D velocity by one), and its mask tells the output layer that it was filled. The past
    epochs enter as their changes to the current beams (``BeamsNetV2(past_input=
    "changes")``: no velocity scale in the features); a past value whose beam is missing
    then or now is zero and masked. So: NaN (no estimate) only where fewer than 3 current
    beams are valid; any past beams may be missing.

    Args:
        n_past: previous DVL epochs in the input.
    """

    name: ClassVar[str] = "v2m"
    masked: ClassVar[bool] = True
    imu_option: ClassVar[bool] = False

    @classmethod
    def options(cls, config, windows: Windows) -> dict:
        """Constructor arguments from a ``TrainConfig``."""
        return dict(n_past=config.n_past)

    def inputs(self, windows: Windows) -> list[torch.Tensor]:
        """What ``forward`` takes, float32: its ``n_past`` past pings, the current beams."""
        return [_past(windows, self.n_past), _beams(windows)]

    def drop_beams(self, batch: list[torch.Tensor], rate: float,
                   generator: torch.Generator) -> list[torch.Tensor]:
        """``batch`` (``inputs``) with beams dropped at random (``_drop_beams``)."""
        return _drop_beams(batch, 1, 0, rate, generator)

    def __init__(self, *, n_past: int = 3) -> None:
        super().__init__()
        if not (isinstance(n_past, int) and 1 <= n_past <= MAX_WINDOW):
            raise ValueError(f"n_past must be an int in [1, {MAX_WINDOW}], got {n_past!r}")
        self.kwargs = dict(n_past=n_past)
        self.n_past = n_past
        self.head = _conv_head(2 * n_past)
        self.fc = nn.Sequential(
            nn.Linear(CONV_CHANNELS * (N_BEAMS - CONV_KERNEL + 1), 16), nn.ReLU(),
            nn.Linear(16, N_FEATURES), nn.ReLU(),
        )
        self.out = nn.Linear(2 * N_BEAMS + N_FEATURES, N_AXES)
        _init_weights(self)
        # The training data's beam matrix (set by ``initialise``, saved with the weights).
        self.register_buffer("h", torch.zeros(N_BEAMS, N_AXES))

    def initialise(self, inputs: list[torch.Tensor], target: torch.Tensor,
                   h: torch.Tensor) -> None:
        """Take the beam matrix ``h`` (4, 3) of the training data; nothing else is fitted."""
        self.h.copy_(torch.as_tensor(h, dtype=self.h.dtype))

    def forward(self, past_beams: torch.Tensor, beams: torch.Tensor, *,
                past_mask: torch.Tensor | None = None,
                mask: torch.Tensor | None = None) -> torch.Tensor:
        """Estimate the DVL velocity of each sample.

        Args:
            past_beams: (B, n_past, 4) beam velocities of the previous epochs, oldest first,
                m/s; NaN (or ``past_mask`` False) where a beam had no bottom lock.
            beams: (B, 4) beam velocities of the current epoch, m/s; NaN where invalid.
            past_mask, mask: optional bool masks of the valid values (default: finite).

        Returns:
            (B, 3) DVL velocity, m/s; NaN rows where fewer than 3 current beams are valid.
        """
        b = beams.shape[0]
        _check_shape("beams", beams, (b, N_BEAMS))
        _check_shape("past_beams", past_beams, (b, self.n_past, N_BEAMS))
        ok = _valid(beams, mask)
        filled = torch.where(ok, beams, masked_least_squares(beams, ok, self.h) @ self.h.T)
        past_ok = _valid(past_beams, past_mask) & ok[:, None, :]
        changes = torch.where(past_ok, past_beams - filled[:, None, :],
                              torch.zeros_like(past_beams))
        x = self.head(torch.cat([changes, past_ok.to(beams.dtype)], dim=1))
        x = self.fc(x.flatten(1))
        return self.out(torch.cat([filled, ok.to(beams.dtype), x], dim=1))


class CorrectionNet(nn.Module):
    """Our estimator: least squares on the valid beams plus a learned, bounded correction.

    v = v_ls + (A v_ls + c) + bound * tanh(MLP(z))

    * v_ls: least squares on the valid current beams (3 of 4 suffice; fewer: NaN, no
      estimate), the model-based estimate (BeamsNet, Cohen & Klein 2022, eq. 9).
    * A v_ls + c: a linear correction, A (3, 3), c (3,) m/s, initialised at the closed-form
      least-squares fit of ``target - v_ls`` on the training split (``initialise``): an
      affine calibration of the DVL's scale factors and biases, which holds at any velocity.
    * bound * tanh(MLP(z)): a nonlinear correction of the normalised inputs z, at most
      ``bound`` (3,) m/s per axis, the largest residual of the linear fit on the training
      split: it may correct what the training data showed, never more. Its last layer starts
      at zero, so training starts from the affine fit. Each input is normalised by its
      training mean and standard deviation and clipped to its training range, so outside
      the training range the MLP sees the edge of that range: the nonlinear term stays
      bounded (and constant in the clipped inputs), and the velocity follows the linear
      part, as LS does, instead of a nonlinear fit's extrapolation.

    z holds, each value with its validity mask (missing: the training mean, i.e. 0 after
    normalising, and mask 0; as MissBeamNet, Yona & Klein 2024, feeds the network which
    beams are missing): the current beams; the changes of the ``n_past`` previous epochs'
    beams to the current ones (no velocity level in them, see ``BeamsNetV2``); and with
    ``imu`` the mean and standard deviation over the IMU window of the specific force and
    the angular rate (the average acceleration and turn rate between pings, and how much
    they vary: 12 numbers instead of 600 raw samples).

    The normalisation statistics, clipping ranges, bound and beam matrix are buffers, so the
    checkpoint carries them.

    Args:
        n_past: previous DVL epochs in the input (0: none).
        imu: take the IMU window (accelerometer and gyro) too.
        hidden: width of the MLP's two hidden layers (32: a few thousand weights, small
            beside the ~10^4 training pings of the Snapir stream).
    """

    name: ClassVar[str] = "corr"
    masked: ClassVar[bool] = True
    imu_option: ClassVar[bool] = True

    @classmethod
    def options(cls, config, windows: Windows) -> dict:
        """Constructor arguments from a ``TrainConfig`` (``imu``: take the IMU window)."""
        return dict(n_past=config.n_past, imu=config.imu)

    def inputs(self, windows: Windows) -> list[torch.Tensor]:
        """What ``forward`` takes, float32: the current beams, its ``n_past`` past pings,
        and with ``imu`` the IMU windows."""
        return [_beams(windows), _past(windows, self.n_past)] + (
            _imu(windows) if self.imu else [])

    def drop_beams(self, batch: list[torch.Tensor], rate: float,
                   generator: torch.Generator) -> list[torch.Tensor]:
        """``batch`` (``inputs``) with beams dropped at random (``_drop_beams``)."""
        return _drop_beams(batch, 0, 1, rate, generator)

    def __init__(self, *, n_past: int = 3, imu: bool = False, hidden: int = 32) -> None:
        super().__init__()
        if not (isinstance(n_past, int) and n_past >= 0):
            raise ValueError(f"n_past must be an int >= 0, got {n_past!r}")
        if not (isinstance(hidden, int) and hidden >= 1):
            raise ValueError(f"hidden must be an int >= 1, got {hidden!r}")
        self.kwargs = dict(n_past=n_past, imu=bool(imu), hidden=hidden)
        self.n_past, self.imu = n_past, bool(imu)
        n_values = N_BEAMS * (1 + n_past) + (4 * N_AXES if imu else 0)
        n_masks = N_BEAMS * (1 + n_past)
        self.linear = nn.Linear(N_AXES, N_AXES)
        self.mlp = nn.Sequential(nn.Linear(n_values + n_masks, hidden), nn.Tanh(),
                                 nn.Linear(hidden, hidden), nn.Tanh(),
                                 nn.Linear(hidden, N_AXES))
        for layer in (self.linear, self.mlp[-1]):
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)
        for key, size in (("h", (N_BEAMS, N_AXES)), ("mean", (n_values,)),
                          ("std", (n_values,)), ("low", (n_values,)), ("high", (n_values,)),
                          ("bound", (N_AXES,))):
            self.register_buffer(key, torch.ones(size) if key == "std" else torch.zeros(size))

    def _values(self, beams, past_beams, accel, gyro, mask, past_mask):
        """(B, n_values) raw inputs, (B, n_values) their validity, and the LS velocity."""
        b = beams.shape[0]
        _check_shape("beams", beams, (b, N_BEAMS))
        _check_shape("past_beams", past_beams, (b, self.n_past, N_BEAMS))
        ok = _valid(beams, mask)
        past_ok = _valid(past_beams, past_mask) & ok[:, None, :]
        zero = torch.zeros((), dtype=beams.dtype)
        values = [torch.where(ok, beams, zero),
                  torch.where(past_ok, past_beams - beams[:, None, :], zero).flatten(1)]
        valid = [ok, past_ok.flatten(1)]
        if self.imu:
            if accel is None or gyro is None:
                raise ValueError("accel and gyro are needed: this CorrectionNet takes the "
                                 "IMU window (imu=True)")
            for x in (accel, gyro):  # (B, 3, W), as BeamsNetV1 takes them
                stats = torch.cat([x.mean(dim=2), x.std(dim=2)], dim=1)
                values.append(stats)
                valid.append(torch.ones_like(stats, dtype=torch.bool))
        ls = masked_least_squares(beams, ok, self.h)
        return torch.cat(values, dim=1), torch.cat(valid, dim=1), ls

    @torch.no_grad()
    def initialise(self, inputs: list[torch.Tensor], target: torch.Tensor,
                   h: torch.Tensor) -> None:
        """Fit the buffers and the linear term on the training split.

        Args:
            inputs: what ``forward`` takes, for the training samples.
            target: (S, 3) true velocity, m/s.
            h: (4, 3) beam matrix of the training data.
        """
        self.h.copy_(torch.as_tensor(h, dtype=self.h.dtype))
        values, valid, ls = self._values(*self._split(inputs), None, None)
        v = values.double()
        for j in range(v.shape[1]):
            col = v[valid[:, j], j]
            if len(col) == 0:
                continue
            self.mean[j], self.low[j], self.high[j] = col.mean(), col.min(), col.max()
            spread = col.std() if len(col) > 1 else torch.zeros(())
            self.std[j] = spread if spread > 0 else 1.0  # a constant input: only centred
        self.low.sub_(self.mean).div_(self.std)
        self.high.sub_(self.mean).div_(self.std)
        rows = torch.isfinite(ls).all(dim=1)
        x = torch.cat([ls[rows], torch.ones(int(rows.sum()), 1)], dim=1).double()
        coef = torch.linalg.lstsq(x, (target[rows] - ls[rows]).double()).solution  # (4, 3)
        self.linear.weight.copy_(coef[:N_AXES].T)
        self.linear.bias.copy_(coef[N_AXES])
        residual = target[rows] - ls[rows] - self.linear(ls[rows])
        self.bound.copy_(residual.abs().amax(dim=0))

    def _split(self, inputs):
        beams, past_beams, *imu = inputs
        return beams, past_beams, *(imu if imu else (None, None))

    def forward(self, beams: torch.Tensor, past_beams: torch.Tensor,
                accel: torch.Tensor | None = None, gyro: torch.Tensor | None = None, *,
                mask: torch.Tensor | None = None,
                past_mask: torch.Tensor | None = None) -> torch.Tensor:
        """Estimate the DVL velocity of each sample.

        Args:
            beams: (B, 4) beam velocities of the current epoch, m/s; NaN where invalid.
            past_beams: (B, n_past, 4) those of the previous epochs, oldest first, m/s.
            accel: (B, 3, W) specific force, m/s^2 (with ``imu``).
            gyro: (B, 3, W) angular rate, rad/s (with ``imu``).
            mask, past_mask: optional bool masks of the valid beams (default: finite).

        Returns:
            (B, 3) DVL velocity, m/s; NaN rows where fewer than 3 current beams are valid.
        """
        values, valid, ls = self._values(beams, past_beams, accel, gyro, mask, past_mask)
        z = torch.maximum(torch.minimum((values - self.mean) / self.std, self.high), self.low)
        z = torch.where(valid, z, torch.zeros_like(z))
        masks = valid[:, :N_BEAMS * (1 + self.n_past)].to(z.dtype)
        correction = self.bound * torch.tanh(self.mlp(torch.cat([z, masks], dim=1)))
        return ls + self.linear(ls) + correction


# Why any network can be worse than LS on data unlike its training data.
NETWORK_WHY = ("a network fitted on the training data meets motions (sway, heave, turns, "
               "currents) its training data never showed")
ESTIMATORS = (
    Spec("v1", "BeamsNetV1 (beams + IMU)", "network", model=BeamsNetV1, short="BeamsNetV1",
         needs=Needs(beams=4, imu=True, text="needs 4 beams"), why=NETWORK_WHY, order=10),
    Spec("v2", "BeamsNetV2 (beams + past beams)", "network", model=BeamsNetV2,
         short="BeamsNetV2", needs=Needs(beams=4, history=3, all_past=True,
                                         text="needs 4 beams on 4 pings"),
         why=NETWORK_WHY, order=20),
    Spec("v2m", "BeamsNetV2M (V2 with validity masks)", "network", model=BeamsNetV2M,
         short="BeamsNetV2M", needs=Needs(history=3), why=NETWORK_WHY, order=30),
    Spec("corr", "CorrectionNet (LS plus a learned, bounded correction)", "network",
         model=CorrectionNet, short="CorrectionNet", needs=Needs(history=3), why=NETWORK_WHY,
         order=40),
)


def build(name: str, **kwargs) -> nn.Module:
    """Build a registered network by name, e.g. ``build(m.name, **m.kwargs)`` from a
    checkpoint.

    Args:
        name: a network's name in the registry (``beamsnet.estimators.registry``): "v1"
            (BeamsNetV1), "v2" (BeamsNetV2), "v2m" (BeamsNetV2M), "corr" (CorrectionNet).
        **kwargs: keyword arguments of that model's constructor.

    Raises:
        ValueError: ``name`` is not a known model.
    """
    from beamsnet.estimators.registry import models

    known = models()
    if name not in known:
        raise ValueError(f"name must be one of {sorted(known)}, got {name!r}")
    return known[name](**kwargs)
