"""The ``beamsnet`` program's entry point, light on purpose: ``beamsnet.cli`` loads torch
and every estimator (some 2 s), and a Ctrl-C while it does is then one line and exit
status 130, as one during a command is, where it had been a traceback."""

from __future__ import annotations

from auvsim.cli_support import exit_with


def _main() -> int:
    from beamsnet.cli import main  # the heavy imports, inside exit_with's catch

    return main()


def run() -> None:
    """The ``beamsnet`` program (``beamsnet.cli.main`` under ``exit_with``)."""
    exit_with("beamsnet", _main)
