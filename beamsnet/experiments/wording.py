"""What the experiments' reports say about their rows: which estimators are worse than
least squares and why (each estimator's ``why`` in the registry), and how a network was
trained, in words, with the counts in their prose (``count``).

Rows are named as the tables name them (``LS``, ``BeamsNetV2 (v2)``); the registry
(``beamsnet.estimators``) tells a trained network's row from another estimator's by the
names it registers, not by a prefix.
"""

from __future__ import annotations

import math

from beamsnet.estimators import short_name, spec

# A row of no registered estimator (a variant made by hand, ``INS/DVL (raw beams)``).
UNKNOWN_WHY = "its model differs from LS's"


def why(row: str) -> str:
    """Why the estimator of a table row can be worse than LS on data unlike its
    training data."""
    try:
        return spec(row).why
    except KeyError:
        return UNKNOWN_WHY


# Why an estimator that has not learned the instrument is worse than LS (``unlearned``).
NOT_LEARNED = ("far off even on the calmest pings: it has not learned the instrument (too few "
               "epochs or too little training data: a smoke run)")


def why_worse(rows: dict[str, dict], key: str, *, availability: bool = False,
              unlearned: list[str] = ()) -> list[str]:
    """One line per estimator worse than LS by ``key`` (e.g. ``rmse_vector``) in some of
    ``rows`` (setting or mission -> estimator -> scores), saying where and why: fewer pings
    with an estimate than LS (gaps held through), what the estimator is, or, for one in
    ``unlearned``, that it has not learned the instrument at all."""
    names = [n for n in next(iter(rows.values())) if n != "LS"]
    lines = []
    for n in names:
        worse = [m for m, r in rows.items()
                 if math.isfinite(r[n][key]) and r[n][key] > r["LS"][key]]
        if not worse:
            continue
        reasons = [NOT_LEARNED if n in unlearned else why(n)]
        if availability and any(rows[m][n]["availability"] < rows[m]["LS"]["availability"]
                                for m in worse):
            reasons.insert(0, "it gives no estimate on pings where LS does, and a gap holds "
                           "its last estimate")
        lines.append(f"- {short_name(n)}, worse than LS on {len(worse)} of {len(rows)} ("
                     f"{', '.join(worse[:4])}{', ...' if len(worse) > 4 else ''}): "
                     + "; ".join(reasons) + ".")
    return lines or ["- None."]


def as_published(train_config: dict) -> str:
    """`` as published`` for a BeamsNetV2 trained with the paper's protocol (its raw past
    beams), else nothing."""
    if train_config.get("model") == "v2" and train_config.get("protocol") == "paper":
        return " as published"
    return ""


def count(n: int | float, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, plural (``plural``, default ``noun + "s"``) unless ``n`` is 1:
    ``count(1, "epoch")`` is "1 epoch", ``count(30, "epoch")`` "30 epochs"."""
    return f"{n:g} {noun if n == 1 else plural or noun + 's'}"
