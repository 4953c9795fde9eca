"""``python -m auvsim``: the ``auvsim`` program, as its console script runs it."""

from auvsim.cli import run

run()
