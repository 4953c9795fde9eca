"""Value checks shared by the config and the manoeuvres (a leaf: it imports nothing of
auvsim)."""

from __future__ import annotations

import math


def is_finite(value: object) -> bool:
    """A finite int or float, not a bool (an int too big for a float is not finite)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False
