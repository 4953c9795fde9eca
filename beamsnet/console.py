"""The ``beamsnet`` program's entry point, light on purpose: ``beamsnet.cli`` loads every
estimator (some 2 s, PyTorch's among them where it is installed), and a Ctrl-C while it
does is then one line and exit status 130, as one during a command is, where it had been a
traceback; so is an error found as it loads (another package's estimator that cannot be
loaded), and so is a command that needs PyTorch where it is not installed (the package's
``learn`` extra, which a plain install leaves out: the model-based estimators and the
filters run without it)."""

from __future__ import annotations

import sys

from auvsim.cli_support import ERROR, exit_with
from auvsim.errors import AuvsimError


def _main() -> int:
    try:
        from beamsnet.cli import main  # the heavy imports, inside exit_with's catch

        return main()
    except AuvsimError as e:  # as it loads; a command's own are main's to report
        print(f"beamsnet: error: {e}", file=sys.stderr)
        return ERROR
    except ModuleNotFoundError as e:
        if e.name != "torch":
            raise
        from beamsnet.estimators.registry import NO_TORCH

        print(f"beamsnet: error: {NO_TORCH}", file=sys.stderr)
        return ERROR


def run() -> None:
    """The ``beamsnet`` program (``beamsnet.cli.main`` under ``exit_with``)."""
    exit_with("beamsnet", _main)
