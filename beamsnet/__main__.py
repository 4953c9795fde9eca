"""``python -m beamsnet``: the ``beamsnet`` program, as its console script runs it."""

from beamsnet.console import run

run()
