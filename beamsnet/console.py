"""The ``beamsnet`` program's entry point, light on purpose: ``beamsnet.cli`` loads torch
and every estimator (some 2 s), and a Ctrl-C while it does is then one line and exit
status 130, as one during a command is, where it had been a traceback; so is an error
found as it loads (another package's estimator that cannot be loaded), and so is a
missing PyTorch: the package's ``learn`` extra, which a plain install leaves out."""

from __future__ import annotations

import sys

from auvsim.cli_support import ERROR, exit_with
from auvsim.errors import AuvsimError

NO_TORCH = ("PyTorch is not installed, and beamsnet needs it: install the package's learn "
            "extra, pip install 'auvsim[learn]' (the CPU build of torch first, to keep pip "
            "from pulling CUDA: pip install torch --index-url "
            "https://download.pytorch.org/whl/cpu)")


def _main() -> int:
    try:
        from beamsnet.cli import main  # the heavy imports, inside exit_with's catch
    except AuvsimError as e:
        print(f"beamsnet: error: {e}", file=sys.stderr)
        return ERROR
    except ModuleNotFoundError as e:
        if e.name != "torch":
            raise
        print(f"beamsnet: error: {NO_TORCH}", file=sys.stderr)
        return ERROR
    return main()


def run() -> None:
    """The ``beamsnet`` program (``beamsnet.cli.main`` under ``exit_with``)."""
    exit_with("beamsnet", _main)
