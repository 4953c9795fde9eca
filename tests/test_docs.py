"""Every code example in README.md and the documentation site runs, as written.

Each page is a tutorial: its fenced blocks run in order in one fresh folder, so a block
may use the files an earlier block of the same page made. Fences:

* ```` ```sh ````: run with bash (``-e``: any failing command fails the block), the venv's
  ``bin`` first on ``PATH``;
* ```` ```python ````: run with this interpreter in a subprocess;
* ```` ```text ````: what a command printed; never run;
* anything else (``toml``, ...) needs a directive: written to a file, or skipped.

Directives are HTML comments right above a fence (blank lines and other directives may
sit between), invisible on the page but visible in its source:

* ``<!-- test: skip (why) -->``: not run, and the reason is required (counted below);
* ``<!-- test: replace "OLD" "NEW" -->``: run with OLD replaced by NEW, to keep a long
  example small (OLD must occur, so a stale rule fails);
* ``<!-- test: exit N -->``: the block must exit with status N (a refused input: 2);
* ``<!-- test: expect "TEXT" -->``: its output (stdout and stderr) must contain TEXT;
* ``<!-- test: file NAME -->``: not run; written to NAME in the page's folder, for the
  blocks after it (a TOML config, a script).

A page whose source holds ``<!-- test-page: slow -->`` runs under ``pytest.mark.slow``.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUN = {"sh", "python"}
OUTPUT = {"text"}
DIRECTIVE = re.compile(r"^<!--\s*test:\s*(.*?)\s*-->\s*$")
FENCE = re.compile(r"^(?P<indent> {0,3})(?P<fence>```+)(?P<lang>[^\s`]*)\s*$")
INCLUDE = re.compile(r'^--8<--\s+"([^"]+)"\s*$', re.M)
BLOCK_TIMEOUT_S = 300


@dataclass
class Block:
    """One fenced block of a page and the directives above it."""

    page: str
    line: int
    lang: str
    code: str
    directives: list[str] = field(default_factory=list)

    def where(self) -> str:
        return f"{self.page}:{self.line} ({self.lang or 'no language'})"

    def options(self) -> dict:
        """The directives, parsed: skip, exit, file, expect and replace."""
        out: dict = {"skip": None, "exit": 0, "file": None, "expect": [], "replace": []}
        for d in self.directives:
            word, _, rest = d.partition(" ")
            if word == "skip":
                reason = rest.strip()
                if not (reason.startswith("(") and reason.endswith(")") and len(reason) > 2):
                    raise ValueError(f"{self.where()}: 'skip' needs a reason: "
                                     f"<!-- test: skip (why) -->, got {d!r}")
                out["skip"] = reason[1:-1]
            elif word == "exit":
                out["exit"] = int(rest)
            elif word == "file":
                out["file"] = rest.strip()
            elif word == "expect":
                out["expect"] += shlex.split(rest)
            elif word == "replace":
                args = shlex.split(rest)
                if len(args) != 2:
                    raise ValueError(f"{self.where()}: expected replace \"OLD\" \"NEW\", "
                                     f"got {d!r}")
                out["replace"].append(tuple(args))
            else:
                raise ValueError(f"{self.where()}: unknown directive {d!r}; expected skip, "
                                 "replace, exit, expect or file")
        return out

    def source(self) -> str:
        code = self.code
        for old, new in self.options()["replace"]:
            if old not in code:
                raise ValueError(f"{self.where()}: replace {old!r}: not in the block")
            code = code.replace(old, new)
        return code


def blocks(text: str, page: str) -> list[Block]:
    """The fenced blocks of a Markdown text, each with the directives right above it."""
    out: list[Block] = []
    pending: list[str] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        directive = DIRECTIVE.match(line.strip())
        fence = FENCE.match(line)
        if directive:
            pending.append(directive.group(1))
        elif fence:
            close = re.compile(rf"^ {{0,3}}{fence.group('fence')}`*\s*$")
            j = i + 1
            while j < len(lines) and not close.match(lines[j]):
                j += 1
            indent = len(fence.group("indent"))
            body = [s[indent:] if s[:indent].isspace() else s for s in lines[i + 1:j]]
            out.append(Block(page, i + 1, fence.group("lang"), "\n".join(body) + "\n",
                             pending))
            pending = []
            i = j
        elif line.strip():
            pending = []
        i += 1
    return out


def site_pages() -> list[Path]:
    """README.md, every page under docs/, and every file a page includes."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    included = []
    for page in pages:
        included += [ROOT / p for p in INCLUDE.findall(page.read_text())]
    return pages + sorted(set(included) - set(pages))


def page_id(path: Path) -> str:
    return str(path.relative_to(ROOT))


PAGES = site_pages()


def _params():
    for path in PAGES:
        text = path.read_text()
        if not any(b.options()["skip"] is None and (b.lang in RUN or b.options()["file"])
                   for b in blocks(text, page_id(path))):
            continue
        marks = [pytest.mark.slow] if "<!-- test-page: slow -->" in text else []
        yield pytest.param(path, id=page_id(path), marks=marks)


def run_block(block: Block, folder: Path) -> None:
    opts = block.options()
    code = block.source()
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    env["REPO"] = str(ROOT)  # for a replace rule that runs a script of the repository
    if block.lang == "sh":
        argv = ["bash", "-e", "-o", "pipefail", "-c", code]
    else:
        argv = [sys.executable, "-c", code]
    done = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True,
                          timeout=BLOCK_TIMEOUT_S, stdin=subprocess.DEVNULL)
    output = done.stdout + done.stderr
    assert done.returncode == opts["exit"], (
        f"{block.where()} exited {done.returncode}, expected {opts['exit']}:\n{code}\n"
        f"--- output ---\n{output[-4000:]}")
    for text in opts["expect"]:
        assert text in output, f"{block.where()}: expected {text!r} in:\n{output[-4000:]}"


@pytest.mark.parametrize("path", list(_params()))
def test_page_runs(path: Path, tmp_path: Path) -> None:
    """The page's blocks run in order, as a reader would type them, in one folder."""
    ran = 0
    for block in blocks(path.read_text(), page_id(path)):
        opts = block.options()
        if opts["skip"] is not None or block.lang in OUTPUT:
            continue
        if opts["file"]:
            target = tmp_path / opts["file"]
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(block.source())
            continue
        run_block(block, tmp_path)
        ran += 1
    assert ran or any(b.options()["file"] for b in blocks(path.read_text(), page_id(path)))


def test_every_block_runs_or_says_why() -> None:
    """No code block is left out silently: each runs, is written to a file, is output, or
    is skipped with a reason; the skips are counted and listed."""
    counts = {"run": 0, "file": 0, "output": 0, "skip": 0}
    problems, skips = [], []
    for path in PAGES:
        for block in blocks(path.read_text(), page_id(path)):
            try:
                opts = block.options()
                block.source()
            except ValueError as e:
                problems.append(str(e))
                continue
            if opts["skip"] is not None:
                counts["skip"] += 1
                skips.append(f"{block.where()}: {opts['skip']}")
            elif opts["file"]:
                counts["file"] += 1
            elif block.lang in RUN:
                counts["run"] += 1
            elif block.lang in OUTPUT:
                counts["output"] += 1
            else:
                problems.append(f"{block.where()}: a ```{block.lang} block with no directive: "
                                "expected sh, python or text, or a file/skip directive")
    print(f"code blocks: {counts}; skipped:\n  " + "\n  ".join(skips))
    assert not problems, "\n".join(problems)
    assert counts["run"] > 0
    # Skips are for what cannot run here (an SSH cluster, Slurm, the Snapir data, a ROS 2
    # installation); if this grows, prefer a smaller example that runs.
    assert counts["skip"] <= 11, skips


def test_pages_stay_inside_the_repository() -> None:
    """Nothing points to the issue tracker or to folders outside the repository."""
    bad = re.compile(r"\bissues? \d+|\.\./shared|/work/")
    hits = [f"{page_id(p)}:{n}: {line.strip()}" for p in PAGES
            for n, line in enumerate(p.read_text().splitlines(), 1) if bad.search(line)]
    assert not hits, "\n".join(hits)


def test_readme_is_short() -> None:
    """The README is the front door: two screens, the rest lives in the site."""
    size = (ROOT / "README.md").stat().st_size
    assert size <= 15_000, f"README.md is {size} bytes; expected at most 15,000"


def test_directives_are_parsed() -> None:
    """The extractor itself: directives bind to the next fence only, skips need a reason,
    a stale replace is an error."""
    text = "\n".join([
        "<!-- test: replace \"600\" \"20\" -->", "<!-- test: exit 2 -->", "",
        "```sh", "auvsim generate --duration 600", "```",
        "text between", "```python", "print(1)", "```",
        "<!-- test: skip -->", "```sh", "x", "```",
        "<!-- test: replace \"nope\" \"x\" -->", "```sh", "y", "```"])
    found = blocks(text, "t.md")
    assert [b.lang for b in found] == ["sh", "python", "sh", "sh"]
    assert found[0].source() == "auvsim generate --duration 20\n"
    assert found[0].options()["exit"] == 2
    assert found[1].directives == []
    with pytest.raises(ValueError, match="needs a reason"):
        found[2].options()
    with pytest.raises(ValueError, match="not in the block"):
        found[3].source()


def test_benchmark_pages_name_their_command() -> None:
    """A benchmark's page starts with the command that made it (without --write) and the
    date, and holds its output verbatim."""
    import datetime

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import perf_page
    finally:
        sys.path.pop(0)
    argv = [str(ROOT / "benchmarks" / "generation.py"), "--duration", "5", "--write",
            "out.md", "--repeats", "1"]
    text = perf_page.page("line 1\nline 2\n", argv, datetime.date(2026, 12, 3))
    assert text.startswith("Made by `.venv/bin/python benchmarks/generation.py --duration 5 "
                           "--repeats 1` on 2026-12-03")
    assert "```text\nline 1\nline 2\n```" in text
    for path in sorted((ROOT / "docs" / "performance" / "results").glob("*.md")):
        assert path.read_text().startswith("Made by `.venv/bin/python benchmarks/"), path
