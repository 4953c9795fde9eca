"""Writing outputs whole or not at all: each file is written under a temporary name beside
its final one and renamed when complete, so an interrupted run leaves no half-written
report, table or figure."""

from __future__ import annotations

import os
from pathlib import Path


def temporary(path: Path, *, suffix: str = "") -> Path:
    """The temporary name an output is written under, beside ``path``."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp{suffix}")


def write_text(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` to ``path`` atomically."""
    path = Path(path)
    tmp = temporary(path, suffix=path.suffix)
    try:
        tmp.write_text(text)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def save_figure(fig, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Save a matplotlib figure to ``path`` atomically and close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    tmp = temporary(path, suffix=path.suffix)
    try:
        fig.savefig(tmp, dpi=dpi)
        tmp.replace(path)
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return path
