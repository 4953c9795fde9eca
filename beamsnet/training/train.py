"""Training BeamsNetV1/V2 on an auvsim dataset, top to bottom.

The paper's protocol (../shared/reference/beamsnet-reference.md): MSE loss, RMSprop, batch
size 4, learning rate 0.01 (simulation) or 0.001 (sea data) divided by 10 every 15
epochs, 30 or 50 epochs, a sequential 75 / 25 split of each mission without shuffling
across it. Inputs and targets are not normalised, as in the paper. Mini-batches are
drawn in a seeded random order within the training part; the run is deterministic for a
given seed.

The checkpoint (``model.pt``) carries the model's name and constructor arguments, the
training config, and the dataset's identity (path, SHA-256, its ``config_json``), so
evaluation rebuilds exactly what was trained and can tell which data it came from
(``beamsnet.training.checkpoints``).

Two additions to the paper's protocol, off by default, measured on paper-sim (the report
of ``beamsnet reproduce paper-sim`` lists every seed):

* Polyak averaging (``average_epochs``): at batch 4 the last weights jitter about the
  minimum, and on the paper's straight lines that jitter was most of the error; averaging
  the weights over the steps of the last epochs removes it.
* Restarts (``beamsnet.training.runs.train_best``): which minimum RMSprop reaches
  depends on the seed, by as much as the gaps the paper reports between its models.
  ``train_best`` trains several seeds
  (in parallel processes, one thread each, or on a Dask cluster) and keeps the one
  whose final weights fit the TRAINING split best: the classic random-restart remedy for
  a non-convex fit, which looks at no test sample. Every seed's loss is kept in
  ``restarts.json``.

One correction of the paper, ON by default (``protocol="fixed"``; ``"paper"`` keeps
BeamsNetV2 exactly as published): V2's past beams enter as their changes to the current
beams. Trained on the Snapir stream, the published-input V2 scored from -55.8 % to +58.5 %
over LS on the separate test mission across seeds 0..2 (61.4 to 64.9 % on validation;
``reports/snapir.md``): its two ReLU
features were dead on the training split (or always on), so the output layer acted as an
affine calibration there, but their pre-activations grow with the velocity, and at the
test mission's velocities outside the training range they switched on with weights that
had never been trained. With the changes as input the features see no velocity level, and
every seed scores 56 to 61 % (``BeamsNetV2``'s docstring; the numbers in the report of
issue 11). Measured and not the cause: Polyak averaging (the last weights score within
0.5 % of the averaged ones), the number of epochs (15 is worse). Normalising inputs and
targets by the training statistics also gave 56 to 62 % on these seeds, but leaves the
pre-activations growing with the distance from the training mean velocity.

The masked models (v2m, corr) train with beams dropped at random (``mask_rate``, each
model's ``drop_beams``), so that their masked paths learn; ``predict`` runs them on pings
with missing beams. Each network cuts its own inputs from the windows (``inputs``) and
takes its constructor arguments from the config (``options``): nothing here knows one
network from another.

``TrainConfig``'s defaults (``beamsnet.training.config``) are the paper's simulation
settings, and the one place any training default is written: ``PROFILES`` names what
each use changes (the reports' averaging and seeds, the sea data's learning rate and
epochs), and the command line and the experiments read their defaults from there.

Training refuses windows holding NaN or inf before anything is written, and stops with
``DivergedError`` when the loss stops being finite: a run either trains or leaves nothing.
Under restarts a diverged seed is recorded and dropped, and the others go on.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from auvsim.data.files import check_out_dir, save_figure, staged_dir, write_text
from auvsim.errors import ConfigError, OutputError
from beamsnet.data import DataError, Windows, check_referenced, load_windows, split
from beamsnet.estimators import spec
from beamsnet.estimators.baselines import least_squares
from beamsnet.estimators.networks import build, training_threads
from beamsnet.plotstyle import legend_outside
from beamsnet.training.checkpoints import (
    CHECKPOINT_FORMAT,
    CHECKPOINT_VERSION,
    file_identity,
    sensor_setup,
)
from beamsnet.training.config import TrainConfig


@torch.no_grad()
def predict(model: torch.nn.Module, windows: Windows, *,
            allow_mismatch: bool = False) -> np.ndarray:
    """(S, 3) velocity estimates, m/s, of a network on the inputs it cuts from
    ``windows`` (its ``inputs``).

    Windows may hold NaN beams (``load_windows(every_ping=True)``). The masked models
    (v2m, corr) use the valid beams and give NaN rows only where fewer than 3 current
    beams are valid; the others take no masks, and give NaN rows wherever one of their
    input beams is NaN.

    Raises:
        ConfigError: the windows' beam angle is not one the model was trained on (a
            model from ``checkpoints.load`` knows them), unless ``allow_mismatch``: it
            learned one beam geometry, and on another its output is far off (a V2 of 20
            deg beams on 30 deg ones, 0.69 m/s in x where LS is 0.013 off).
    """
    trained = getattr(model, "trained_beam_angles_deg", ())
    if trained and not allow_mismatch:
        angle = math.degrees(math.acos(min(abs(float(windows.h[0, 2])), 1.0)))
        if not any(abs(angle - a) < 1e-6 for a in trained):
            raise ConfigError(f"the windows' beams are at {angle:g} deg and the model was "
                              f"trained on beams at {', '.join(f'{a:g}' for a in trained)} "
                              "deg; expected windows of its training data's geometry "
                              "(allow_mismatch runs it anyway)", argument="windows")
    model.eval()
    return model(*model.inputs(windows)).double().numpy()



@torch.no_grad()
def _mse(model: torch.nn.Module, x: list[torch.Tensor], y: torch.Tensor) -> float:
    """MSE of the model in evaluation mode (no dropout) on inputs ``x`` and targets ``y``;
    NaN when there are no samples."""
    model.eval()
    return torch.nn.functional.mse_loss(model(*x), y).item() if len(y) else math.nan


class DivergedError(ConfigError):
    """The training loss became NaN or inf: the learning rate (``argument``) is too large
    for this data, or the data's scale is. Nothing of the run is written."""



# What each network input is, in the dataset's words, for the messages about bad values.
_FIELDS = {"target": "the true DVL velocity", "accel": "the measured specific force",
           "gyro": "the measured angular rate"}


def check_finite(windows: Windows, model: str, dataset: str | Path, *,
                 imu: bool = False) -> None:
    """Refuse samples whose target or ``model``'s inputs hold NaN or inf: the loss of a
    single such sample is NaN, and so is every weight after one step.

    Args:
        windows: the samples (``beamsnet.data.Windows``).
        model: a network's name; one that needs the IMU (``v1``) has its IMU windows
            checked too. The beams need no check: ``load_windows`` keeps only pings whose
            beams are all valid and finite.
        dataset: the file they came from, for the message.
        imu: check the IMU windows whatever the model (CorrectionNet with ``imu``).

    Raises:
        DataError: naming the dataset, the field, and where the first such sample is.
    """
    imu = imu or spec(model).needs.imu
    for key in ("target", "accel", "gyro") if imu else ("target",):
        values = getattr(windows, key)
        bad = ~np.isfinite(values.reshape(len(values), -1)).all(axis=1)
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise DataError(
                f"{dataset}: {_FIELDS[key]} holds NaN or inf in {int(bad.sum())} of "
                f"{len(values)} samples (the first in mission "
                f"{windows.names[windows.mission[first]]} at {windows.time[first]:g} s); "
                "expected finite values to train on")


@training_threads()
def train(dataset: str | Path, config: TrainConfig, out: str | Path, *,
          progress: bool = True, on_epoch: Callable[[], object] | None = None) -> dict:
    """Train one model on ``dataset`` and save it under the directory ``out``;
    ``on_epoch`` is called after each epoch (another process's progress bar). It trains
    with ``networks.TRAINING_THREADS`` torch threads, so a config and seed give the same
    weights wherever they train.

    Every input is checked before the training starts, and nothing is written unless it
    ends with finite weights.

    Returns:
        A summary: the per-epoch losses and where the checkpoint and the plot went.

    Raises:
        ConfigError: ``out`` cannot be a directory; BeamsNetV1 on a file without IMU data.
        DataError: the dataset cannot give the samples, or they hold NaN or inf.
        DivergedError: the training loss became NaN or inf.
    """
    out = check_out_dir(out)
    windows = load_windows(dataset, n_past=config.n_past, missions=config.missions)
    network = spec(config.model)
    if network.needs.imu and windows.accel is None:
        raise ConfigError(f"v2 is needed: {dataset} has no IMU data (an imported DVL stream "
                          f"has none), and {network.short} takes the IMU samples between "
                          "pings", argument="model")
    if config.imu and windows.accel is None:
        raise ConfigError(f"False is needed: {dataset} has no IMU data (an imported DVL "
                          "stream has none) for CorrectionNet's IMU input", argument="imu")
    check_referenced(windows, dataset)
    check_finite(windows, config.model, dataset, imu=config.imu)
    try:
        train_w, test_w = split(windows, config.train_fraction)
    except ValueError as e:
        raise DataError(f"{dataset}: {e}") from None
    # RMSprop's running mean of squared gradients decays geometrically for units whose
    # gradient is zero (dead ReLUs) and reaches float32's subnormal range within a few
    # thousand steps, where x86 arithmetic is tens of times slower: flush them to zero.
    torch.set_flush_denormal(True)
    torch.manual_seed(config.seed)
    order = torch.Generator().manual_seed(config.seed)
    kwargs = spec(config.model).model.options(config, windows)
    model = build(config.model, **kwargs)
    x_train, y_train = model.inputs(train_w), torch.as_tensor(train_w.target,
                                                              dtype=torch.float32)
    x_test, y_test = model.inputs(test_w), torch.as_tensor(test_w.target, dtype=torch.float32)
    if hasattr(model, "initialise"):  # v2m, corr: the beam matrix, statistics, linear fit
        model.initialise(x_train, y_train, torch.as_tensor(windows.h, dtype=torch.float32))
    optimizer = torch.optim.RMSprop(model.parameters(), lr=config.lr, foreach=True)
    schedule = torch.optim.lr_scheduler.StepLR(optimizer, config.lr_step, config.lr_gamma)
    n = len(y_train)
    steps = math.ceil(n / config.batch_size)
    loss_fn = torch.nn.MSELoss()
    averaged = torch.optim.swa_utils.AveragedModel(model) if config.average_epochs else None
    history = {"train": [], "test": []}
    started = time.perf_counter()
    bar = tqdm(total=config.epochs * steps, disable=None if progress else True, leave=False,
               unit=" steps", desc=spec(config.model).short)
    with bar:
        for epoch in range(config.epochs):
            averaging = averaged is not None and epoch >= config.epochs - config.average_epochs
            model.train()
            perm = torch.randperm(n, generator=order)
            total = 0.0
            for i in range(0, n, config.batch_size):
                idx = perm[i:i + config.batch_size]
                batch = [x[idx] for x in x_train]
                if config.drop_rate:
                    batch = model.drop_beams(batch, config.drop_rate, order)
                loss = loss_fn(model(*batch), y_train[idx])
                value = loss.item()
                if not math.isfinite(value):
                    # One non-finite step makes every weight NaN: stop before writing.
                    raise _diverged(config, value, f"at epoch {epoch + 1}, step "
                                    f"{i // config.batch_size + 1} of {steps}")
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                optimizer.step()
                if averaging:
                    averaged.update_parameters(model)
                total += value * len(idx)
            schedule.step()
            test_loss = _mse(model, x_test, y_test)
            history["train"].append(total / n)
            history["test"].append(test_loss)
            bar.update(steps)
            bar.set_postfix(train=f"{total / n:.3g}", test=f"{test_loss:.3g}")
            if on_epoch is not None:
                on_epoch()
    seconds = time.perf_counter() - started
    if averaged is not None:
        model = averaged.module
    # The saved weights' losses (the history's are the last weights', before averaging).
    final_train_loss = _mse(model, x_train, y_train)  # what train_best compares seeds by
    final_test_loss = _mse(model, x_test, y_test)
    if not math.isfinite(final_train_loss):  # the last step's update overflowed
        raise _diverged(config, final_train_loss, "after the last step")
    # The same loss of the beams' own least-squares solution (paper eq. 9): what a network
    # that learned nothing useful still has to beat.
    ls_test_loss = float(np.nanmean((least_squares(test_w.beams, test_w.h)
                                     - test_w.target) ** 2))

    checkpoint = dict(format=CHECKPOINT_FORMAT, format_version=CHECKPOINT_VERSION,
                      model=config.model, kwargs=kwargs, state_dict=model.state_dict(),
                      train_config=dataclasses.asdict(config), dataset=file_identity(dataset),
                      sensors=sensor_setup(dataset, windows.names),
                      history=history, samples=dict(train=n, test=len(y_test)),
                      final_train_loss=final_train_loss, final_test_loss=final_test_loss)
    with staged_dir(out) as stage:  # the whole run or nothing (a full disk, Ctrl-C)
        try:
            torch.save(checkpoint, stage / "model.pt")
        except RuntimeError as e:  # torch's writer says a failed write so, without errno
            raise OutputError(f"{str(Path(out) / 'model.pt')!r}: cannot be written "
                              f"({str(e).splitlines()[0][:200]}); expected room for it "
                              "there and a folder that can be written") from None
        write_text(stage / "history.json", json.dumps(history, indent=1))
        _plot_losses(history, stage / "losses.png", config,
                     final=(final_train_loss, final_test_loss))
    return dict(checkpoint=str(out / "model.pt"), plot=str(out / "losses.png"),
                history=history,
                seconds=seconds, samples_per_second=config.epochs * n / seconds,
                final_train_loss=final_train_loss, final_test_loss=final_test_loss,
                ls_test_loss=ls_test_loss)


def _diverged(config: TrainConfig, loss: float, where: str) -> DivergedError:
    return DivergedError(f"{config.lr:g}: {spec(config.model).short} (seed {config.seed}) "
                         f"diverged, its training loss became {loss} {where}; expected a "
                         "finite loss, with a smaller learning rate", argument="lr")



def _plot_losses(history: dict, path: Path, config: TrainConfig, *,
                 final: tuple[float, float] | None = None) -> Path:
    """The losses per epoch: training as its steps saw it (each batch's loss as the
    weights moved, with dropout and masks), the test split's at the epoch's last weights,
    and, at the last epoch, the saved weights' on both (``final``: averaged over the last
    epochs where ``average_epochs``; what ``train`` prints)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, ax = plt.subplots(figsize=(7.5, 4), layout="constrained")
    epochs = np.arange(1, len(history["train"]) + 1)
    ax.semilogy(epochs, history["train"], label="training, over the epoch's steps")
    ax.semilogy(epochs, history["test"], label="test split, at the epoch's end")
    if final is not None:
        for loss, marker, what in zip(final, "os", ("training", "test split"), strict=True):
            ax.semilogy([epochs[-1]], [loss], marker, color="k", fillstyle="none",
                        label=f"the saved weights: {what}")
    ax.set_xlabel("epoch")
    ax.set_ylabel("MSE loss, (m/s)^2")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # epochs are whole
    ax.set_title(f"{spec(config.model).short}, lr {config.lr:g}, batch {config.batch_size}")
    legend_outside(ax)
    ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path, dpi=120)
    return path

