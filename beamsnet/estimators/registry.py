"""Every estimator of beamsnet, declared once: its name, kind, what it needs of a ping,
why it can be worse than least squares, and how to make it.

An estimator's module declares its own ``ESTIMATORS``, a tuple of ``Spec``; this module
finds them in every module of ``beamsnet.estimators`` (no list of modules to keep), so a
new model-based estimator is one file there, and a new network its model class plus its
spec. Everything that runs or reports estimators (``evaluate``, ``estimate``, the
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

KINDS = ("model-based", "filter", "network")


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


@cache
def _all() -> tuple[Spec, ...]:
    """Every ``ESTIMATORS`` of the modules of ``beamsnet.estimators``, by kind then order."""
    import beamsnet.estimators as package

    found: list[Spec] = []
    for module in pkgutil.iter_modules(package.__path__):
        found += getattr(importlib.import_module(f"{package.__name__}.{module.name}"),
                         "ESTIMATORS", ())
    names = [s.name for s in found]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise RuntimeError(f"estimators declared twice: {', '.join(twice)}")
    return tuple(sorted(found, key=lambda s: (KINDS.index(s.kind), s.order, s.name)))


def specs(kind: str | None = None) -> tuple[Spec, ...]:
    """Every estimator (of ``kind``, if given), model-based first, then filters, then
    networks, each kind in its declared order."""
    if kind is not None and kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    return tuple(s for s in _all() if kind is None or s.kind == kind)


def estimator_key(name: str) -> str:
    """What of an estimator's name a loose match compares: its letters and digits, lower
    case (``INS/DVL (adaptive)`` and ``ins-dvl-adaptive`` alike)."""
    return "".join(c for c in name.lower() if c.isalnum())


class UnknownEstimator(KeyError):
    """No estimator has the name asked for; the message lists those there are."""

    def __str__(self) -> str:  # KeyError's own quotes its argument, message and all
        return str(self.args[0])


def spec(name: str) -> Spec:
    """The estimator called ``name``: a spec's ``name`` or ``short``, a table row's (such
    as ``BeamsNetV2 (seed_0)``), or either matched on its letters and digits alone
    (``estimator_key``: ``ls``, ``robust-ls``, ``ins-dvl``), as the command line matches.

    Raises:
        UnknownEstimator (a KeyError): no estimator has that name.
    """
    for s in _all():
        if name in (s.name, s.short) or _is_run_of(name, s):
            return s
    key = estimator_key(name)
    for s in _all():
        if key in (estimator_key(s.name), estimator_key(s.short)):
            return s
    raise UnknownEstimator(f"no estimator {name!r}; expected one of "
                           + ", ".join(s.name for s in _all()))


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
