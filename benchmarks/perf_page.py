"""Benchmark results as pages of the documentation: the figures live once, where a run put
them.

Each benchmark script takes ``--write [FILE]``: what it prints is also written, whole, as
a Markdown page (default ``docs/performance/results/<script>.md``), headed by the command
that made it and the date, which ``docs/performance/index.md`` includes. Prose elsewhere
cites that page instead of retyping its numbers.

In a script::

    perf_page.add_write_option(parser, "generation")   # beside its other options
    ...
    if __name__ == "__main__":
        sys.exit(perf_page.run(main))
"""

from __future__ import annotations

import argparse
import datetime
import io
import os
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "performance" / "results"

_target: Path | None = None  # set by --write while the arguments are parsed


class _Write(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        global _target
        _target = Path(values)
        setattr(namespace, self.dest, _target)


def add_write_option(parser: argparse.ArgumentParser, name: str) -> None:
    """Add ``--write [FILE]`` to a benchmark's parser (default file: ``<name>.md`` under
    ``docs/performance/results/``)."""
    default = RESULTS / f"{name}.md"
    parser.add_argument("--write", nargs="?", const=str(default), metavar="FILE",
                        action=_Write, help="also write the result as a Markdown page for "
                        f"the docs (default FILE: {default.relative_to(ROOT)})")


class _Tee(io.TextIOBase):
    def __init__(self, stream) -> None:
        self.stream = stream
        self.parts: list[str] = []

    def write(self, text: str) -> int:
        self.parts.append(text)
        return self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()


def page(output: str, argv: list[str], when: datetime.date) -> str:
    """The Markdown page of one run: the command that made it, the date, the output."""
    args: list[str] = []
    rest = argv[1:]
    while rest:  # the --write option itself is not part of the measurement
        a = rest.pop(0)
        if a == "--write":
            if rest and not rest[0].startswith("-"):
                rest.pop(0)
        elif not a.startswith("--write="):
            args.append(a)
    script = Path(argv[0])
    script = script.relative_to(ROOT) if script.is_absolute() and ROOT in script.parents \
        else script
    command = shlex.join([".venv/bin/python", str(script), *args])
    return (f"Made by `{command}` on {when.isoformat()} ({os.cpu_count()} cores; these "
            "machines are noisy: compare ratios within a run, not times across runs).\n\n"
            f"```text\n{output.rstrip()}\n```\n")


def run(main) -> int:
    """Run a benchmark's ``main``, and write its page if ``--write`` was given. The page is
    written under a temporary name and renamed, and only when ``main`` finished."""
    global _target
    _target = None
    tee = _Tee(sys.stdout)
    sys.stdout = tee
    try:
        code = main()
    finally:
        sys.stdout = tee.stream
    if _target is not None and not code:
        _target.parent.mkdir(parents=True, exist_ok=True)
        tmp = _target.with_name(f".{_target.name}.tmp")
        tmp.write_text(page("".join(tee.parts), sys.argv, datetime.date.today()))
        os.replace(tmp, _target)
        print(f"wrote {_target}")
    return code or 0
