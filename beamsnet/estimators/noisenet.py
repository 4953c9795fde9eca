"""The INS/DVL filter with a learned DVL noise (``FilterConfig.adaptive = "learned"``, the
estimator ``INS/DVL (learned noise)``): a small network reads a window of the recent
pings' IMU and innovation features and scales the DVL's noise, its white part and its slow
part's drive together.

**Which noise, and why.** The DVL's, as a whole: one scale lambda multiplies the
measurements' white variances (R = lambda R_stated, one lambda for the beams or the DVL's
axes, for the reasons the model-based adaptive filter gives in ``ins``) and the driving
PSD of the measurement biases c_k, the Gauss-Markov states that hold the instrument's
slow error (a process noise of the filter's augmented state). Not the IMU's Q: between
two pings of a 1 Hz DVL, a navigation-grade IMU's white noise adds h Q h^T of order
(0.0002 m/s^2/sqrt(Hz))^2 x 1 s = 4e-8 (m/s)^2 to an innovation's variance, against 1e-6
to 1e-5 (m/s)^2 for the beams' white noise (1.2 to 3.6 mm/s): the innovations, all a
filter at sea sees of its own errors, cannot tell a Q ten times larger from the stated.
And not R alone: the slow error's drive, into the states that hold it, is the DVL's
other noise, and a noise mis-stated in both parts needs both scaled; with the real
Navigator's slow error (9 mm/s over 19 s) the two together make most of the innovation
variance (the "scaled noise share" of ``reports/adaptive.md``'s inputs table, median 0.83
on auvsim's missions and 0.73 at sea). A-KIT (Cohen & Klein 2025, "Adaptive
Kalman-informed transformer", EAAI) adapts the IMU's process noise instead, trained on
real segments with a reference. At sea a constant Q hardly moves this filter's median:
``beamsnet reproduce adaptive`` runs the fixed filter with the IMU's Q std times 0.5 to 10
(``FilterConfig.process_noise_scale``); the best one scale for every segment ends 3.9 %
below the stated Q's median final, though single segments move by tens of per cent
either way, and each segment's own best, chosen in hindsight against the reference, 6.7 %
(its DVL scale: 11.7 %). A choice per segment in hindsight gains much of its figure by
picking the least of noisy finals: on the held-out simulated missions, where the filter
is told the DVL noise the simulator drew, it adds 27.3 points to the best one DVL scale
for all (the report's "How much of a choice in hindsight is chance").

**Features** (``FEATURES``; the loop computes them at every ping, after its updates, from
the IMU samples since the previous ping and the ping's own innovations; ratios and
logarithms, so that neither the IMU's rate nor the instrument's stated noise sets their
scale): the log mean rotation rate, the log r.m.s. of |f| - g, the log speed, the log
scale the ping's innovations imply (lambda times their mean nu^2 / S, winsorised at the
gate: the true scale, whatever lambda the filter used), the share of S that the scaled
noise makes (lambda (r + q) / S, q the drive since the last ping) and the share of the
measurements offered. The network reads the last ``WINDOW`` pings' features (the first
ping's fill the window at the start), normalised by the training data's mean and std; a
feature that never varies in the training data gets zero weights, so that an input the
network never saw move cannot steer it.

No feature is the network's own output, or moves with it: the filter's runs with the
learned scale are the next round's training data, and an input that follows the output
(the scale in use, the share the gate rejected, the plain nu^2 / S) made the rounds a
feedback loop that did not converge. On a 200 s zigzag told half its beams' noise (true
scale 4), five seeds learned 2.9 to 5.9 with those inputs; with them and the loss's
scaled S below, 1.6 to 2.5 after one round and 1.0 to 10.3 after three; with these
inputs and the loss below, 3.0 to 4.5 after two rounds (``tests/test_learned_noise.py``
checks each seed within 30 % of 4).

**Network.** W F inputs, ``HIDDEN`` tanh units, one output z; log lambda =
(log a + log b) / 2 + (log b - log a) / 2 tanh(z) for the variance bounds (a, b) =
(floor^2, ceiling^2) of ``BOUNDS`` (std 0.5 to 10 times the stated, as the model-based
filter's ``adaptive_range``). So R is diagonal with every variance in [a r, b r] and the
drive in [a q, b q]: positive definite and bounded by construction, the
bounded-exponential form of AI-IMU's learned covariances (Brossard, Barrau & Bonnabel
2020, "AI-IMU dead-reckoning", IEEE T-IV 5(4), 585-595). The filter stays the Kalman
filter: every measurement is gated against its innovation variance and counted, and the
divergence watch is unchanged. lambda is used from the next ping on, as the model-based
one.

**Loss.** The negative log-likelihood of the innovations, the likelihood of a Kalman
filter's output (Schweppe 1965, "Evaluation of likelihood functions for Gaussian
signals", IEEE Trans. Inf. Theory 11(1), 61-70; used to identify noise variances by Mehra
1970, "On the identification of variances and adaptive Kalman filtering", IEEE TAC 15(2),
175-184): per measurement, 0.5 (log S + nu^2 / S) with S(lambda) = (lambda / lambda_0)
S_0, where S_0 (h P h^T with the timing term, plus lambda_0 r) and the scale lambda_0 are
a recorded run's. A Kalman filter told every noise and its prior lambda times larger
has lambda times the covariance and the same gain; here the scale multiplies the DVL's
white noise and its slow error's drive, which make most of S (above), so S scales with
it. The loss is so in closed form and needs no differentiable filter; as the scale
changes P beyond what that says, the network is trained again (from its seeded start,
with its inputs normalised afresh) on the filter's run with the learned scale
(``ROUNDS``: first on the fixed filter's run, then on the learned one's). An innovation
beyond the gate (nu^2 >= gate S_0) counts by the probability of being there,
-log P(|nu| > sqrt(gate S_0)) under S(lambda), not by its size: the censored normal
likelihood (Tobin 1958, "Estimation of relationships for limited dependent variables",
Econometrica 26(1), 24-36). So an outlier weighs no more than an innovation at the
gate, and a filter told too little noise, whose gate cuts many good innovations, is not
read as less noisy than it is (winsorising them at the gate instead, told half the noise,
learned 16 to 24 % under the true scale: of N(0, 4 S_0), min(nu^2, gate S_0) keeps 0.83
of the variance).
The loss needs no truth: what the network is fitted to is what the filter sees.

**Training data** (``training_records``): auvsim missions only. Each runs in both of the
filter's measurement forms (the beams, and the DVL's LS velocity, the form a log without
beams gives) and with the stated noise multiplied by each of ``STATED_FACTORS``: a real
instrument's stated noise is not the simulated one's, so the network must read the scale
from the innovations rather than learn the simulated instrument's (domain randomisation,
Tobin et al. 2017, "Domain randomization for transferring deep neural networks from
simulation to the real world", IROS).

The model itself (its features' names, arrays, bounds and file) is
``beamsnet.estimators.noisemodel``, which the filter's loop reads without this module.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch  # it trains its network; without PyTorch the registry leaves it out

from beamsnet.data import Windows
from beamsnet.estimators.ins import FilterConfig, InsDvlFilter
from beamsnet.estimators.noisemodel import (
    BOUNDS,
    HIDDEN,
    WINDOW,
    NoiseModel,
    NoiseModelError,
    load_noise_model,
    windows,
)
from beamsnet.estimators.registry import Needs, Spec

ROUNDS = 2  # training on the fixed filter's run, then on the learned filter's
STATED_FACTORS = (0.5, 1.0, 2.0)  # the stated noise's multiples in the training runs
FORMS = ("auto", "velocity")  # the measurement forms of the training runs
EPOCHS = 300
LR = 0.01


@dataclass(frozen=True)
class Records:
    """What a training run of the filter gives the loss, one row per ping with a
    previous ping: the network's input after the previous ping, and this ping's
    measurements (up to 4; ``mask`` says which were offered)."""

    inputs: np.ndarray  # (N, WINDOW F)
    nu2: np.ndarray  # (N, 4) squared innovations, at most gate S_0, (m/s)^2
    s0: np.ndarray  # (N, 4) their variances S_0 in the recorded run, (m/s)^2
    log_scale0: np.ndarray  # (N,) log lambda_0, the scale the recorded run used
    censored: np.ndarray  # (N, 4) bool: beyond the gate (nu2 is then gate S_0)
    mask: np.ndarray  # (N, 4) bool
    group: np.ndarray  # (N,) int, the mission each row is from (for the validation split)

    @staticmethod
    def concatenate(parts: Sequence[Records]) -> Records:
        return Records(*(np.concatenate([getattr(p, f.name) for p in parts])
                         for f in dataclasses.fields(Records)))


def records(track, gate: float, group: int = 0, *, until: float = math.inf,
            window: int = WINDOW) -> Records:
    """The loss's rows of one filter ``track`` (``ins.FilterTrack``) with the gate
    ``gate`` (chi-square threshold), from pings up to time ``until``."""
    started = np.flatnonzero(np.isfinite(track.features).all(axis=1)
                             & (track.ping_time <= until))
    x = windows(track.features[started], window)
    k = track.innovation.shape[1]
    now = started[1:]
    r_stated = np.asarray(track.stated_std, dtype=float)[now] ** 2
    scale = track.noise_scale[now]
    nu = track.innovation[now]
    mask = np.isfinite(nu) & np.isfinite(track.innovation_hph[now])
    s0 = np.nan_to_num(track.innovation_hph[now]) + scale[:, None] * r_stated
    nu2 = np.nan_to_num(nu) ** 2
    censored = mask & (nu2 >= gate * s0)
    pad = ((0, 0), (0, 4 - k))
    return Records(inputs=x[:-1], nu2=np.pad(np.minimum(nu2, gate * s0), pad),
                   s0=np.pad(s0, pad, constant_values=1.0), log_scale0=np.log(scale),
                   censored=np.pad(censored, pad), mask=np.pad(mask, pad),
                   group=np.full(len(now), group))


def training_records(dataset, missions: Sequence[str], config=None, model=None, *,
                     until: dict[str, float] | None = None, beam_correction=None,
                     progress: Callable[[int], None] | None = None) -> Records:
    """The loss's rows of every mission of ``dataset`` in both measurement forms and at
    every stated-noise factor (the module docstring's "Training data"), run with the
    fixed filter (``model`` None) or the learned one; ``until``: the last time of each
    mission to use (the training split's), default all; ``beam_correction``: the beams'
    calibration (``ins.run_mission``)."""
    from auvsim.data.reader import open_dataset
    from beamsnet.estimators.ins import chi2_1dof, run_mission

    config = config if config is not None else FilterConfig()
    gate = chi2_1dof(config.gate_probability)
    parts = []
    with open_dataset(dataset) as f:
        for g, name in enumerate(missions):
            m = f.missions[name]
            for form in FORMS:
                for factor in STATED_FACTORS:
                    cfg = dataclasses.replace(
                        config, noise_scale=factor,
                        adaptive="none" if model is None else "learned")
                    track = run_mission(m, cfg, noise_model=model, measurements=form,
                                        beam_correction=beam_correction)
                    parts.append(records(track, gate, g, until=(until or {}).get(
                        name, math.inf)))
                    if progress is not None:
                        progress(1)
    return Records.concatenate(parts)


def _nll(net, bounds, rec):
    lo, hi = (2 * math.log(b) for b in bounds)
    z = net(rec["inputs"])[:, 0]
    log_scale = 0.5 * (lo + hi) + 0.5 * (hi - lo) * torch.tanh(z)
    s = torch.exp(log_scale - rec["log_scale0"])[:, None] * rec["s0"]
    # Beyond the gate: -log P(|nu| > sqrt(gate S_0)) = -log 2 Phi(-sqrt(gate S_0 / S)); the
    # ratio is 1 elsewhere, so that the branch not taken has a finite gradient.
    ratio = torch.where(rec["censored"], rec["nu2"] / s, torch.ones_like(s))
    tail = -(math.log(2.0) + torch.special.log_ndtr(-torch.sqrt(ratio)))
    terms = torch.where(rec["censored"], tail, 0.5 * (torch.log(s) + rec["nu2"] / s))
    return (terms * rec["mask"]).sum() / rec["mask"].sum()


def fit(rec: Records, *, seed: int = 0, epochs: int = EPOCHS, lr: float = LR,
        bounds: tuple[float, float] = BOUNDS, trained_on: dict | None = None) -> NoiseModel:
    """Fit the network to ``rec`` by the innovations' negative log-likelihood (full
    batch, Adam, from a seeded start). Every fifth mission (``group``) is held out to
    choose the epoch (with fewer than two missions, every fifth block of 2 ``WINDOW``
    rows: a held-out row's window then barely overlaps a training row's, where rows taken
    one in five shared most of theirs and the epoch chosen fitted the pings' noise); the
    inputs are normalised by the training rows' mean and std (a constant input by 1, its
    weights zero). It trains with ``networks.TRAINING_THREADS`` torch threads, so a seed
    gives the same model on any machine."""
    from beamsnet.estimators.networks import training_threads

    with training_threads():
        return _fit(rec, seed, epochs, lr, bounds, trained_on)


def _fit(rec: Records, seed: int, epochs: int, lr: float, bounds: tuple[float, float],
         trained_on: dict | None) -> NoiseModel:
    """``fit``'s work, in the torch threads it sets."""
    torch.manual_seed(seed)
    held = rec.group % 5 == 4
    if held.all() or not held.any():
        held = (np.arange(len(rec.group)) // (2 * WINDOW)) % 5 == 4
    train, valid = ~held, held
    if not (rec.mask[valid].any() and rec.mask[train].any()):
        # The first held-out block is the fifth: 4 blocks of 2 WINDOW rows before it.
        need = 8 * WINDOW + 1
        runs = len(FORMS) * len(STATED_FACTORS)
        raise NoiseModelError(
            f"the learned noise has {len(rec.group)} rows of innovations to fit on, too "
            f"few to hold any out to choose its epoch; expected at least {need} (longer or "
            f"more training missions: one mission gives {runs} rows a ping after its first "
            f"{WINDOW + 1}, so about {WINDOW + 1 + -(-need // runs)} training pings)")
    mean = rec.inputs[train].mean(axis=0)
    std = rec.inputs[train].std(axis=0)
    constant = std < 1e-6
    std[constant] = 1.0
    d = rec.inputs.shape[1]
    net = torch.nn.Sequential(torch.nn.Linear(d, HIDDEN, dtype=torch.float64), torch.nn.Tanh(),
                              torch.nn.Linear(HIDDEN, 1, dtype=torch.float64))
    with torch.no_grad():  # an input that never varied here gets no weight (its gradient
        net[0].weight[:, torch.from_numpy(constant)] = 0.0  # is 0, so it stays 0)

    def tensors(rows):
        return {"inputs": torch.from_numpy((rec.inputs[rows] - mean) / std),
                "nu2": torch.from_numpy(rec.nu2[rows]), "s0": torch.from_numpy(rec.s0[rows]),
                "log_scale0": torch.from_numpy(rec.log_scale0[rows]),
                "censored": torch.from_numpy(rec.censored[rows]),
                "mask": torch.from_numpy(rec.mask[rows].astype(float))}

    t, v = tensors(train), tensors(valid)
    opt = torch.optim.Adam(net.parameters(), lr=lr)
    best, best_state = math.inf, None
    for _ in range(epochs):
        opt.zero_grad()
        loss = _nll(net, bounds, t)
        loss.backward()
        opt.step()
        with torch.no_grad():
            score = float(_nll(net, bounds, v))
        if score < best:
            best, best_state = score, [p.detach().clone() for p in net.parameters()]
    w1, b1, w2, b2 = (p.numpy() for p in best_state)
    return NoiseModel(w1=w1.copy(), b1=b1.copy(), w2=w2[0].copy(), b2=float(b2[0]),
                      mean=np.asarray(mean, dtype=float), std=np.asarray(std, dtype=float),
                      bounds=bounds, trained_on=dict(trained_on or {}, validation_nll=best))


def train_noise_model(dataset, missions: Sequence[str] | None = None, *, seed: int = 0,
                      rounds: int = ROUNDS, epochs: int = EPOCHS, config=None,
                      until: dict[str, float] | None = None, beam_correction=None,
                      progress: bool = False) -> NoiseModel:
    """Train the noise network on the missions of an auvsim ``dataset`` (default all):
    ``rounds`` fits, each on the filter's runs with the previous round's model (the first
    on the fixed filter's). The model records what it was trained on."""
    return train_noise_models(dataset, missions, seeds=(seed,), rounds=rounds, epochs=epochs,
                              config=config, until=until, beam_correction=beam_correction,
                              progress=progress)[0]


def train_noise_models(dataset, missions: Sequence[str] | None = None, *,
                       seeds: Sequence[int] = (0,), rounds: int = ROUNDS,
                       epochs: int = EPOCHS, config=None,
                       until: dict[str, float] | None = None, beam_correction=None,
                       progress: bool = False) -> list[NoiseModel]:
    """``train_noise_model`` for each of ``seeds``, the same models as one call each: the
    first round's runs (the fixed filter's, which no seed changes) are made once."""
    from auvsim.data.reader import open_dataset

    seeds = list(seeds)  # a generator would pass the check empty-handed
    if rounds < 1 or epochs < 1 or not seeds:
        raise ValueError(f"expected at least one round, epoch and seed, got rounds={rounds}, "
                         f"epochs={epochs}, seeds={seeds}")
    with open_dataset(dataset) as f:
        if missions is None:
            missions = list(f.missions)
    _refuse_recorded(dataset, missions)
    bar = None
    if progress:
        from tqdm import tqdm

        runs = (1 + len(seeds) * (rounds - 1)) * len(missions) * len(FORMS)
        bar = tqdm(total=runs * len(STATED_FACTORS), desc="noise model", unit="run")

    def records_with(model):
        return training_records(dataset, missions, config, model, until=until,
                                beam_correction=beam_correction,
                                progress=None if bar is None else bar.update)

    models = []
    try:
        first = records_with(None)
        for seed in seeds:
            model, rec = None, first
            for k in range(rounds):
                if k > 0:
                    rec = records_with(model)
                size = dict(dataset=str(dataset), missions=len(missions),
                            pings=len(rec.group), measurements=int(rec.mask.sum()),
                            rounds=rounds, epochs=epochs, seed=seed, forms=list(FORMS),
                            stated_factors=list(STATED_FACTORS))
                model = fit(rec, seed=seed, epochs=epochs, trained_on=size)
            models.append(model)
    finally:
        if bar is not None:
            bar.close()
    return models


class LearnedInsDvlFilter(InsDvlFilter):
    """The INS/DVL filter with the learned noise as a beamsnet estimator: ``fit`` calibrates
    the beams as ``InsDvlFilter`` does and, unless a model was given (``model``, or the
    settings' ``noise_model`` file), trains one on the training split's pings of the
    file's own missions, which must be simulated (``train_noise_model``)."""

    name = "INS/DVL (learned noise)"

    def __init__(self, dataset, config: FilterConfig | None = None, *,
                 calibrate: bool = True, model: NoiseModel | None = None) -> None:
        config = dataclasses.replace(config if config is not None else FilterConfig(),
                                     adaptive="learned")
        super().__init__(dataset, config, calibrate=calibrate)
        if not calibrate:
            self.name = "INS/DVL (learned noise, raw beams)"
        self.given = model is not None or config.noise_model is not None
        self.noise_model = (model if model is not None or config.noise_model is None
                            else load_noise_model(config.noise_model))

    def fit(self, train: Windows) -> LearnedInsDvlFilter:
        """Calibrate the beams and, unless a model was given, train one on the
        training split's pings.

        Raises:
            NoiseModelError: the training windows are not of this filter's file (their
                missions, times or beams differ), so it has no training run of its own.
        """
        if not self.given:
            _refuse_recorded(self.dataset, [train.names[i] for i in np.unique(train.mission)])
        super().fit(train)
        if not self.given:
            _check_windows_of(self.dataset, train)
            missions = np.unique(train.mission)
            self.noise_model = train_noise_model(
                self.dataset, [train.names[i] for i in missions],
                until={train.names[i]: float(train.time[train.mission == i].max())
                       for i in missions},
                beam_correction=self.correction)
        return self


def _refuse_recorded(dataset, missions: Sequence[str]) -> None:
    """Refuse to train on a recorded mission of ``dataset`` (a log has no truth to learn
    the noise from, nor measured beams); a name the file does not hold is
    ``_check_windows_of``'s to refuse.

    Raises:
        NoiseModelError: naming the first recorded mission and what to give instead.
    """
    from auvsim.data.reader import open_dataset

    with open_dataset(dataset) as f:
        recorded = [n for n in missions
                    if n in f.missions and f.missions[n].origin == "recorded"]
    if recorded:
        raise NoiseModelError(f"{dataset}: mission {recorded[0]!r} is recorded, and the "
                              "noise model trains on simulated data only; on a recorded "
                              "log, give a trained one (noise_model in the filter's "
                              "settings, --filter-config; beamsnet reproduce adaptive "
                              "writes one)")


def _check_windows_of(dataset, windows: Windows) -> None:
    """Refuse windows that are not of ``dataset``: each of their missions must be there
    with a ping at each of their times, beams equal where both are finite."""
    from auvsim.data.reader import open_dataset

    with open_dataset(dataset) as f:
        for i in np.unique(windows.mission):
            name, rows = windows.names[i], windows.mission == i
            same = name in f.missions
            if same:
                dvl = f.missions[name].dvl
                t = np.asarray(dvl.time, dtype=float)
                k = np.minimum(np.searchsorted(t, windows.time[rows]), len(t) - 1)
                theirs = np.asarray(dvl.beam_velocity, dtype=float)[k]
                both = np.isfinite(theirs) & np.isfinite(windows.beams[rows])
                same = (np.allclose(t[k], windows.time[rows], rtol=1e-9, atol=1e-9)
                        and np.allclose(theirs[both], windows.beams[rows][both], rtol=1e-6,
                                        atol=1e-9))
            if not same:
                which = "differs from the file's" if name in f.missions else "is not in it"
                raise NoiseModelError(
                    f"the learned noise trains on the filter's own file ({dataset}), and the "
                    f"training windows are of another (their mission {name!r} {which}); "
                    "expected training windows of that file, or a trained model "
                    "(noise_model in the filter's settings: --filter-config of beamsnet "
                    "estimate and evaluate)")


ESTIMATORS = (
    Spec("INS/DVL (learned noise)", "INS/DVL filter whose beam noise a small network sets "
         "from the recent IMU samples and innovations, trained on auvsim data", "filter",
         make=LearnedInsDvlFilter, order=12,
         needs=Needs(beams=0, imu=True, text="needs the IMU record"),
         why="its noise network learned auvsim's instrument and manoeuvres; where the real "
             "ones differ, its scale is an extrapolation"),
)
