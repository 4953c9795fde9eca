"""The learned DVL noise model of the INS/DVL filter: its inputs (``FEATURES``), its
network's arrays and bounds (``NoiseModel``, whose ``arrays`` the filter's compiled loop
runs at every ping and whose ``scale`` is the same arithmetic in numpy), and its file
(``save_noise_model``, ``load_noise_model``). What the features are, why the network
scales the DVL's noise, and how it is trained: ``beamsnet.estimators.noisenet``.

The file is an ``.npz`` of the arrays and a JSON header with ``NOISE_MODEL_FORMAT``, the
features, window, bounds and what the model was trained on; any other file is refused in
one line (``NoiseModelError``).
"""

from __future__ import annotations

import dataclasses
import io
import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from auvsim.errors import AuvsimError

FEATURES = ("log rotation rate", "log rms |f| - g", "log speed", "log implied scale",
            "scaled noise share", "offered share")
WINDOW = 30  # pings of features the network reads (the model-based filter's window)
HIDDEN = 16  # tanh units
BOUNDS = (0.5, 10.0)  # the scaled std's bounds, multiples of the stated one
NOISE_MODEL_FORMAT = "beamsnet-noise-model"
NOISE_MODEL_VERSION = 2  # 2: the implied scale, no scale in use or rejected share


class NoiseModelError(AuvsimError):
    """A file that is not a beamsnet noise model, or one that cannot be read."""


@dataclass(frozen=True)
class NoiseModel:
    """A trained noise network: its layers, inputs' normalisation, bounds and provenance."""

    w1: np.ndarray  # (HIDDEN, WINDOW F)
    b1: np.ndarray  # (HIDDEN,)
    w2: np.ndarray  # (HIDDEN,)
    b2: float
    mean: np.ndarray  # (WINDOW F,)
    std: np.ndarray  # (WINDOW F,)
    window: int = WINDOW
    bounds: tuple[float, float] = BOUNDS
    trained_on: dict = dataclasses.field(default_factory=dict)

    def arrays(self) -> tuple:
        """The filter loop's arguments (``ins._filter``'s ``net_window`` to ``feat_std``)."""
        return (self.window, *(np.ascontiguousarray(a, dtype=float) for a in (
            self.w1, self.b1, self.w2, np.array([self.b2]), self.mean, self.std)))

    def scale(self, inputs: np.ndarray) -> np.ndarray:
        """(N,) lambda, the variance scale, for (N, WINDOW F) inputs (``windows``): the
        loop's arithmetic in numpy."""
        hidden = np.tanh(((inputs - self.mean) / self.std) @ self.w1.T + self.b1)
        lo, hi = (2 * math.log(b) for b in self.bounds)
        return np.exp(0.5 * (lo + hi) + 0.5 * (hi - lo) * np.tanh(hidden @ self.w2 + self.b2))


def constant_model(scale: float, bounds: tuple[float, float] = BOUNDS,
                   window: int = WINDOW) -> NoiseModel:
    """A model whose output is the variance scale ``scale`` at every ping (its weights are
    zero): in the learned filter, the fixed filter with the DVL's noise, its white part and
    its slow error's drive, multiplied by ``scale``. ``beamsnet reproduce adaptive`` runs it
    to show how far any constant scale moves the filter.

    Raises:
        ValueError: ``scale`` not strictly inside the variance bounds (the std bounds
            squared), which the bounded output only approaches.
    """
    lo, hi = (2 * math.log(b) for b in bounds)
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0
            and lo < math.log(scale) < hi):
        raise ValueError(f"scale: expected a variance scale strictly between "
                         f"{bounds[0] ** 2:g} and {bounds[1] ** 2:g}, got {scale!r}")
    d = len(FEATURES) * window
    return NoiseModel(w1=np.zeros((HIDDEN, d)), b1=np.zeros(HIDDEN), w2=np.zeros(HIDDEN),
                      b2=math.atanh((2 * math.log(scale) - lo - hi) / (hi - lo)),
                      mean=np.zeros(d), std=np.ones(d), window=window, bounds=bounds,
                      trained_on=dict(constant_scale=float(scale)))


def windows(features: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """(P, window F) the network's input after each ping: its features and the previous
    pings', newest first, the first ping's repeated before the start (as the loop fills
    its window). ``features``: (P, F), the started pings only."""
    p = len(features)
    rows = np.arange(p)[:, None] - np.arange(window)[None, :]
    return features[np.maximum(rows, 0)].reshape(p, -1)


def save_noise_model(model: NoiseModel, path) -> None:
    """Write ``model`` to ``path`` (``.npz``) whole or not at all."""
    from auvsim.data.files import write_bytes

    header = dict(format=NOISE_MODEL_FORMAT, version=NOISE_MODEL_VERSION,
                  features=list(FEATURES), window=model.window, bounds=list(model.bounds),
                  b2=model.b2, trained_on=model.trained_on)
    buffer = io.BytesIO()
    np.savez(buffer, header=np.array(json.dumps(header, default=float)), w1=model.w1,
             b1=model.b1, w2=model.w2, mean=model.mean, std=model.std)
    write_bytes(path, buffer.getvalue())


def load_noise_model(path) -> NoiseModel:
    """The model in ``path``.

    Raises:
        NoiseModelError: the file cannot be read, or is not a beamsnet noise model of this
            version whose arrays fit its features and window (one line).
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            header = json.loads(str(z["header"]))
            arrays = {k: np.asarray(z[k], dtype=float) for k in ("w1", "b1", "w2", "mean", "std")}
    except OSError as e:
        raise NoiseModelError(f"noise_model: cannot read {str(path)!r} "
                              f"({e.strerror or e})") from None
    except (ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError, EOFError):
        raise NoiseModelError(f"noise_model: {str(path)!r} is not a beamsnet noise model "
                              "(expected the .npz that beamsnet reproduce adaptive "
                              "writes)") from None
    if not isinstance(header, dict) or header.get("format") != NOISE_MODEL_FORMAT:
        raise NoiseModelError(f"noise_model: {str(path)!r} is not a beamsnet noise model "
                              "(expected the .npz that beamsnet reproduce adaptive writes)")
    if header.get("version") != NOISE_MODEL_VERSION or header.get("features") != list(FEATURES):
        raise NoiseModelError(f"noise_model: {str(path)!r} is a noise model of another "
                              f"version ({header.get('version')!r}); expected version "
                              f"{NOISE_MODEL_VERSION} with features {', '.join(FEATURES)}")
    window = header.get("window")
    d = len(FEATURES) * window if isinstance(window, int) else -1
    shapes_ok = (arrays["w1"].ndim == 2 and arrays["w1"].shape[1] == d
                 and arrays["b1"].shape == arrays["w2"].shape == (arrays["w1"].shape[0],)
                 and arrays["mean"].shape == arrays["std"].shape == (d,)
                 and (arrays["std"] > 0).all()
                 and all(np.isfinite(a).all() for a in arrays.values()))
    bounds = header.get("bounds")
    if not (shapes_ok and isinstance(bounds, list) and len(bounds) == 2
            and 0 < bounds[0] <= 1 <= bounds[1]):
        raise NoiseModelError(f"noise_model: {str(path)!r} has arrays or bounds that do not "
                              "fit its features and window; expected a file written by "
                              "beamsnet reproduce adaptive")
    return NoiseModel(**arrays, b2=float(header["b2"]), window=window,
                      bounds=(float(bounds[0]), float(bounds[1])),
                      trained_on=header.get("trained_on", {}))

