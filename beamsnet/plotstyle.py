"""One look per estimator, the same in every beamsnet figure.

A figure holds twelve estimators and more, and matplotlib's colour cycle has ten: by
order alone, LS and BeamsNetV2M would both be blue. Each estimator gets a pair of its
own instead, a colour and a line style (with a marker and a bar hatch that go with the
style, for points and bars), chosen by its name: no two series of a figure look alike,
and an estimator looks the same in every figure. Legends go outside the axes, where
they cover no data.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from dataclasses import dataclass

# matplotlib's tab10, in its order.
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf")
# A style per round of the colours: the 11th estimator is the 1st colour, dashed.
LINESTYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D")
HATCHES = ("", "//", "..", "xx")
PAIRS = len(COLOURS) * len(LINESTYLES)
# The estimators in the order of their pairs: the model-based ones, the filter, the
# networks, then those added later (at the end, so that the others keep their pairs; a
# name here is its own, not a run of the name before its brackets). Names not here (a
# new estimator) take a free pair after these, by a hash of the name, so that they keep
# it from figure to figure too.
KNOWN = ("LS", "Affine", "Beam calibration", "LS scale+offset", "KF", "KF (beam calibration)",
         "Missing-beam LS", "INS/DVL", "BeamsNetV1", "BeamsNetV2", "BeamsNetV2M",
         "CorrectionNet", "INS/DVL (adaptive)", "INS/DVL (learned noise)")


@dataclass(frozen=True)
class Style:
    """An estimator's look: a colour and a line style, with the marker and the bar hatch
    that go with the style."""

    color: str
    linestyle: str
    marker: str
    hatch: str

    def line(self) -> dict:
        """Keywords of ``Axes.plot`` for a line."""
        return dict(color=self.color, linestyle=self.linestyle)

    def points(self) -> dict:
        """Keywords of ``Axes.plot`` for points without a line."""
        return dict(color=self.color, marker=self.marker, linestyle="none")

    def bar(self) -> dict:
        """Keywords of ``Axes.bar`` (edges in the colour, so the hatch shows)."""
        return dict(color=self.color, hatch=self.hatch, edgecolor="white")


def styles(names: Iterable[str]) -> dict[str, Style]:
    """A distinct ``Style`` for each of ``names``, by name.

    A name is known by itself or by what precedes its run in brackets ("BeamsNetV2 (v2)"
    is BeamsNetV2's); a second run of the same estimator, like an unknown name, takes the
    first free pair from one fixed by its name's hash. Up to ``PAIRS`` names are distinct.
    """
    taken: set[int] = set()
    out = {}
    for name in names:
        key = name if name in KNOWN else name.split(" (")[0]
        if key in KNOWN and KNOWN.index(key) not in taken:
            slot = KNOWN.index(key)
        else:
            digest = int(hashlib.sha256(name.encode()).hexdigest(), 16)
            slot = len(KNOWN) + digest % (PAIRS - len(KNOWN))
            for _ in range(PAIRS):
                if slot not in taken:
                    break
                slot = (slot + 1) % PAIRS
        taken.add(slot)
        round_ = slot // len(COLOURS) % len(LINESTYLES)
        out[name] = Style(COLOURS[slot % len(COLOURS)], LINESTYLES[round_], MARKERS[round_],
                          HATCHES[round_])
    return out


def legend_outside(ax, **kwargs) -> None:
    """The legend of ``ax`` to the right of it, outside the data."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **kwargs)


def figure_legend(fig, ax, **kwargs) -> None:
    """One legend for every panel of ``fig`` (the series of ``ax``), outside them all on
    the right: in the margin ``panel_grid`` keeps for it, or where ``layout="constrained"``
    makes room."""
    handles, labels = ax.get_legend_handles_labels()
    if fig.get_layout_engine() is None:  # a panel_grid: its margin's top left corner
        left = fig.subplotpars.right + 0.1 / fig.get_figwidth()  # 0.1 in from the panels
        fig.legend(handles, labels, loc="upper left",
                   bbox_to_anchor=(left, fig.subplotpars.top),
                   borderaxespad=0.0, **kwargs)
    else:
        fig.legend(handles, labels, loc="outside right upper", **kwargs)


def decades_only(ax) -> None:
    """``ax``'s log y axis with a tick at each decade and no minor ticks, which a panel an
    inch or two tall has no room to show. Ticks are most of the drawing of a figure of many
    small log panels (each is two lines and two texts): without the minor ones,
    ``beamsnet stress``'s figures draw in a half to two thirds of the time
    (``benchmarks/figures.py``). After the plotting: a new scale resets the ticks."""
    from matplotlib.ticker import NullLocator

    ax.yaxis.set_minor_locator(NullLocator())


def panel_grid(rows: int, cols: int, *, panel: tuple[float, float], legend: float = 0.0,
               left: float = 0.7, bottom: float = 0.5, top: float = 0.6, right: float = 0.15,
               wspace: float = 0.5, hspace: float = 0.75):
    """A figure of ``rows`` x ``cols`` panels of ``panel`` (width, height) inches, with
    margins and gaps fixed in inches: ``left`` for a y label and its tick labels,
    ``bottom`` for an x label, ``top`` for the title, ``wspace`` between panels for their
    tick labels, ``hspace`` for an x label above and a title below, and ``legend`` on
    the right for ``figure_legend``.

    For figures of many panels: matplotlib's constrained layout measures every tick label
    of every panel twice before a figure is drawn, about 40 % of the drawing time of
    twenty panels (``benchmarks/figures.py``). Returns ``(figure, axes)``, axes (rows, cols)."""
    import matplotlib.pyplot as plt

    w, h = panel
    width = left + cols * w + (cols - 1) * wspace + right + legend
    height = bottom + rows * h + (rows - 1) * hspace + top
    fig, axes = plt.subplots(rows, cols, figsize=(width, height), squeeze=False)
    fig.subplots_adjust(left=left / width, right=1 - (right + legend) / width,
                        bottom=bottom / height, top=1 - top / height,
                        wspace=wspace / w, hspace=hspace / h)
    return fig, axes
