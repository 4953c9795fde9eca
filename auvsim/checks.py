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


def loose_key(text: str) -> str:
    """What of a name a loose match compares: its letters and digits, lower case
    (``paper_sim`` and ``Paper-Sim`` alike; ``INS/DVL (adaptive)`` and
    ``ins-dvl-adaptive``)."""
    return "".join(c for c in text.lower() if c.isalnum())


def did_you_mean(word: object, choices) -> str:
    """`` (did you mean 'paper-sim'?)`` for the choice ``word`` was meant as, if one is
    near enough: the same letters and digits (``paper_sim``, ``Paper-Sim``), or a close
    spelling (``watch_ping``); else ``""``."""
    import difflib

    if not isinstance(word, str):
        return ""
    choices = [c for c in choices if isinstance(c, str)]
    same = [c for c in choices if loose_key(c) == loose_key(word)]
    near = same or difflib.get_close_matches(word, choices, n=1, cutoff=0.75)
    return f" (did you mean {near[0]!r}?)" if near else ""
