"""Every estimator of beamsnet, declared once: its name, kind, what it needs of a ping,
why it can be worse than least squares, and how to make it.

An estimator's module declares its own ``ESTIMATORS``, a tuple of ``Spec``; this module
finds them in every module of ``beamsnet.estimators`` (no list of modules to keep), so a
new model-based estimator is one file there, and a new network its model class plus its
spec. A model-based estimator of a user's own package joins them through ``register``
(in a process) or an entry point of the group ``beamsnet.estimators`` (for the command
lines as well). Everything that runs or reports estimators (``evaluate``, ``estimate``, the
experiments, both command lines' choices, the report tables' columns and texts) iterates
over ``specs()`` or looks a name up with ``spec()``.

Three kinds:

* ``model-based``: ``make()`` gives it unfitted; ``fit(train_windows)`` then
  ``predict(windows)`` (LS fits nothing and ignores the training split);
* ``filter``: runs on the dataset file itself (it integrates a record a window holds only
  in part): ``make(dataset)``, then ``fit``/``predict``/``positions`` as the others;
* ``network``: ``model`` is its ``torch.nn.Module`` class, which declares its own inputs
  (``options``, ``inputs`` and, for a masked model, ``drop_beams``); ``name`` is its key
  on the command line and in checkpoints (``v2``), ``short`` its table name.

A row of a table is named by the spec's ``short`` name; a trained network's row carries
its run too (``BeamsNetV2 (seed_0)``), which ``short_name`` strips by the registered
names, never by a prefix.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from auvsim.checks import loose_key
from auvsim.errors import ConfigError

KINDS = ("model-based", "filter", "network")
# Where PyTorch is not installed (the package's ``learn`` extra, which a plain install
# leaves out), the estimators whose modules need it (the networks, the learned-noise
# filter) are not there; the model-based estimators and the other filters are.
NO_TORCH = ("PyTorch is not installed, and the networks and the learned-noise filter need "
            "it: install the package's learn extra, pip install 'auvsim[learn]' (the CPU "
            "build of torch first, to keep pip from pulling CUDA: pip install torch "
            "--index-url https://download.pytorch.org/whl/cpu)")
# What an unknown name's error adds where they are left out: the name may be a typo too.
WITHOUT_TORCH = ("without PyTorch, which is not installed, the networks and the "
                 "learned-noise filter are not among them: pip install 'auvsim[learn]'")


@dataclass(frozen=True)
class Needs:
    """What an estimator needs of a ping to give an estimate.

    Attributes:
        beams: valid current beams (3: LS's exact solution; 4: all of a Janus DVL's).
        history: past pings it takes (their beams, 0: none); ``all_past``: all of their
            beams valid, too.
        imu: the IMU record (a window of it, or the whole file's for a filter).
        training: a training split to fit on.
        text: the table's words for it where it gives no estimate (``n/a: needs ...``).
    """

    beams: int = 3
    history: int = 0
    all_past: bool = False
    imu: bool = False
    training: bool = True
    text: str = "needs 3 beams"


@dataclass(frozen=True)
class Spec:
    """One estimator.

    Attributes:
        name: its key: the table name of a model-based estimator or filter (``LS``), the
            command line's and checkpoint's name of a network (``v2``).
        title: what it is, in words, for help texts.
        kind: one of ``KINDS``.
        needs: what it needs of a ping (``Needs``).
        why: why it can be worse than LS on data unlike its training data, for the
            reports' "worse than LS, and why".
        short: its name in report tables (default ``name``).
        make: model-based: ``make()`` -> the estimator, unfitted; filter:
            ``make(dataset, filter_config)`` (None: its defaults); network: None. What it
            makes is called ``name`` (its ``name`` attribute): the tables, the command
            line and ``beamsnet estimate`` find it by that.
        model: a network's ``torch.nn.Module`` class (its ``name`` is ``name``).
        order: where its row goes among those of its kind (tables keep one order).
    """

    name: str
    title: str
    kind: str
    needs: Needs
    why: str
    short: str = ""
    make: Callable | None = None
    model: type | None = None
    order: int = 0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"Spec {self.name!r}: kind must be one of {KINDS}, got "
                             f"{self.kind!r}")
        if (self.model is None) == (self.kind == "network"):
            raise ValueError(f"Spec {self.name!r}: a network has a model class, and only "
                             "a network")
        if (self.make is None) != (self.kind == "network"):
            raise ValueError(f"Spec {self.name!r}: a model-based estimator or filter has "
                             "make, a network does not")
        if not self.short:
            object.__setattr__(self, "short", self.name)


ENTRY_POINTS = "beamsnet.estimators"  # the group of other packages' estimators
_added: dict[str, Spec] = {}  # register()'s
_without_torch: set[str] = set()  # the modules of estimators left out: no PyTorch here


@cache
def _all() -> tuple[Spec, ...]:
    """Every ``ESTIMATORS`` of the modules of ``beamsnet.estimators``, every spec of the
    installed packages' ``ENTRY_POINTS`` and every registered one, by kind then order."""
    import beamsnet.estimators as package

    found: list[Spec] = []
    _without_torch.clear()  # found again on every load (``register`` clears the cache)
    for module in pkgutil.iter_modules(package.__path__):
        try:
            loaded = importlib.import_module(f"{package.__name__}.{module.name}")
        except ModuleNotFoundError as e:
            if e.name != "torch":
                raise
            _without_torch.add(module.name)
            continue
        found += getattr(loaded, "ESTIMATORS", ())
    found += _plugged_in()
    found += _added.values()
    keys = [loose_key(s.name) for s in found]
    twice = sorted({s.name for s, k in zip(found, keys, strict=True) if keys.count(k) > 1})
    if twice:
        raise ConfigError(f"estimators declared twice (names alike once case and punctuation "
                         f"are set aside): {', '.join(twice)}; expected one name each")
    return tuple(sorted(found, key=lambda s: (KINDS.index(s.kind), s.order, s.name)))


def _plugged_in() -> list[Spec]:
    """The specs of the installed packages' entry points in ``ENTRY_POINTS``: each names a
    ``Spec`` or a tuple of them (a module's ``ESTIMATORS``)."""
    from importlib.metadata import entry_points

    found: list[Spec] = []
    for point in entry_points(group=ENTRY_POINTS):
        try:
            loaded = point.load()
        except Exception as e:  # whatever it is, it is that package's, named here
            raise ConfigError(f"estimator entry point {point.name!r} ({point.value}) could "
                             f"not be loaded: {type(e).__name__}: {e}") from None
        for s in loaded if isinstance(loaded, (tuple, list)) else (loaded,):
            _check_plugged(s, f"entry point {point.name!r} ({point.value})")
            found.append(s)
    return found


def _check_plugged(s: object, where: str) -> None:
    """An estimator from outside beamsnet: a ``Spec`` of a model-based estimator (a filter
    or a network needs more of beamsnet than a spec says)."""
    if not isinstance(s, Spec):
        raise ConfigError(f"{where}: expected a beamsnet.estimators.Spec, got "
                         f"{type(s).__name__}")
    if s.kind != "model-based":
        raise ConfigError(f"{where}: estimator {s.name!r} is a {s.kind}; expected a "
                         "model-based one (make() -> an object with name, fit and predict)")


def register(s: Spec) -> Spec:
    """Add a model-based estimator defined outside beamsnet, by its ``Spec``: from then on
    ``estimate``, ``evaluate``, ``stress`` and the reports run it beside the others (in
    this process; for the command lines, declare it as an entry point of the group
    ``ENTRY_POINTS`` of the package that defines it).

    Raises:
        ConfigError (a ValueError): not a model-based ``Spec``, or its name is taken
            (letters and digits compared, as the command line matches names).
    """
    _check_plugged(s, "register")
    taken = [t.name for t in _all() if loose_key(t.name) == loose_key(s.name)]
    if taken:
        raise ConfigError(f"register: {s.name!r} is the name of the estimator {taken[0]!r} "
                          "(names compare on their letters and digits); expected a new name")
    _added[s.name] = s
    _all.cache_clear()
    return s


def unregister(name: str) -> None:
    """Remove an estimator that ``register`` added (nothing if none is called ``name``)."""
    if _added.pop(name, None) is not None:
        _all.cache_clear()


def specs(kind: str | None = None) -> tuple[Spec, ...]:
    """Every estimator (of ``kind``, if given), model-based first, then filters, then
    networks, each kind in its declared order."""
    if kind is not None and kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    return tuple(s for s in _all() if kind is None or s.kind == kind)


class UnknownEstimator(KeyError):
    """No estimator has the name asked for; the message lists those there are."""

    def __str__(self) -> str:  # KeyError's own quotes its argument, message and all
        return str(self.args[0])


def spec(name: str) -> Spec:
    """The estimator called ``name``: a spec's ``name`` or ``short``, a table row's (such
    as ``BeamsNetV2 (seed_0)``), or either matched on its letters and digits alone
    (``loose_key``: ``ls``, ``robust-ls``, ``ins-dvl``), as the command line matches.

    Raises:
        UnknownEstimator (a KeyError): no estimator has that name.
    """
    for s in _all():
        if name in (s.name, s.short) or _is_run_of(name, s):
            return s
    key = loose_key(name)
    for s in _all():
        if key in (loose_key(s.name), loose_key(s.short)):
            return s
    raise UnknownEstimator(f"no estimator {name!r}; expected one of "
                           + ", ".join(s.name for s in _all())
                           + (f" ({WITHOUT_TORCH})" if torch_missing() else ""))


def torch_missing() -> bool:
    """Whether estimators were left out for want of PyTorch (``NO_TORCH``)."""
    _all()
    return bool(_without_torch)


def short_name(row: str) -> str:
    """A table row's estimator: ``BeamsNetV2 (seed_0)`` -> ``BeamsNetV2``; a row of no
    registered network (``KF (beam calibration)``) as it is."""
    for s in specs("network"):
        if row == s.short or _is_run_of(row, s):
            return s.short
    return row


def network_names() -> tuple[str, ...]:
    """The networks' names (``v1``, ``v2``, ...): the command line's ``--model``."""
    return tuple(s.name for s in specs("network"))


def models() -> dict[str, type]:
    """Network name -> its model class."""
    return {s.name: s.model for s in specs("network")}


def _is_run_of(row: str, s: Spec) -> bool:
    """Whether ``row`` is a trained network's row, ``<short> (<run>)``."""
    return s.kind == "network" and row.startswith(f"{s.short} (") and row.endswith(")")


def predicted(estimator, windows) -> np.ndarray:
    """``estimator.predict(windows)``, checked to be what every caller reads: (S, 3)
    velocities, one per sample (m/s, DVL frame; NaN where it gives none).

    Raises:
        ConfigError: it returned anything else (a user's estimator, say), naming it.
    """
    return checked(estimator, estimator.predict(windows), windows)


def checked(estimator, out, windows) -> np.ndarray:
    """``out``, what ``estimator`` predicted on ``windows``, checked as ``predicted`` does.

    Raises:
        ConfigError: it is not (S, 3), naming the estimator.
    """
    shape = np.shape(out)
    if shape != (len(windows.beams), 3):
        raise ConfigError(f"estimator {estimator.name!r}: its predict returned shape {shape}; "
                          f"expected ({len(windows.beams)}, 3), a velocity (m/s, DVL frame) "
                          "per sample")
    return np.asarray(out, dtype=float)
