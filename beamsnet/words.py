"""Numbers in report prose: ``count(1, "epoch")`` is "1 epoch", ``count(30, "epoch")``
"30 epochs"."""

from __future__ import annotations


def count(n: int | float, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, plural (``plural``, default ``noun + "s"``) unless ``n`` is 1."""
    return f"{n:g} {noun if n == 1 else plural or noun + 's'}"
