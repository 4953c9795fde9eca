"""The error vocabulary, shared by the library and both command lines.

One base class, a few precise subclasses, caught once at each CLI boundary. A library
error names the *argument* that was wrong (``out``, ``seed``), never a command-line flag:
``AuvsimError.for_cli`` renders it with the flag a CLI gave that argument.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping


class AuvsimError(Exception):
    """Base class of every error auvsim and beamsnet raise on purpose.

    Args:
        message: what was wrong and what is expected, in one line.
        argument: the function argument the error is about, if one is; ``str(error)``
            then starts with it (``out 'x.h5': ...``).
        mentions: other arguments the message names (``allow_mismatch`` in "... allow_mismatch
            evaluates anyway"), which ``for_cli`` renders as their flags too.
    """

    def __init__(self, message: str, *, argument: str | None = None,
                 mentions: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.message = message
        self.argument = argument
        self.mentions = mentions

    def __str__(self) -> str:
        return self._named(self.argument)

    def for_cli(self, flags: Mapping[str, str]) -> str:
        """The message with the argument, and the arguments it mentions, named by their
        command-line flags (``--out``)."""
        text = self._named(flags.get(self.argument, self.argument))
        for name in self.mentions:
            if name in flags:
                text = text.replace(name, flags[name])
        return text

    def _named(self, name: str | None) -> str:
        if name is None:
            return self.message
        return f"{name}{'' if self.message.startswith(':') else ' '}{self.message}"


class ConfigError(AuvsimError, ValueError):
    """A configuration value or argument is invalid."""


class DatasetError(AuvsimError):
    """A file is not an auvsim dataset, is corrupt, or has another format version."""


class MissingFieldError(DatasetError, AttributeError):
    """A dataset group has no field of the name asked for as an attribute
    (``mission.dvl.beam_velocity`` of a log without beams): one line at a command line, as
    any ``DatasetError``, and an ``AttributeError`` to ``hasattr`` and ``getattr``'s
    default."""


class OutputError(AuvsimError):
    """An output cannot be written: a full disk, a quota, a read-only or vanished folder."""


class SimulationError(AuvsimError):
    """A mission cannot go on as configured (for example the vehicle reached the seafloor)."""


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser that reports a usage error on one line and exits with status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message}\n")
