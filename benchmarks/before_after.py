"""Before/after speed: each revision's own benchmarks/generation.py and datasets.py, alternating.

Each revision gets a git worktree of its own (the "after" side defaults to the working tree
this script sits in, uncommitted changes included) and runs its own benchmark scripts with
its own code (``PYTHONPATH=tree``, fresh temporary cwd). Per round: generation.py before and
after, then datasets.py before and after; the order of the two sides flips every round, so
slow drifts of a shared machine fall on both. The figures each script prints are parsed, and
the median over the rounds is tabled for each side with the after/before ratio; a figure
more than 10 % worse is flagged.

    .venv/bin/python benchmarks/before_after.py --before REV [--after REV] [--rounds 5]
        [--memory] [--generation-args "..."] [--datasets-args "..."] [--log DIR]

Default arguments of the benchmarks (one round of both sides in about 2-3 minutes on 2
busy cores): generation.py with its defaults (a 3600 s straight mission, median of 3
repeats, ~30-40 s); datasets.py ``--duration 1800 --repeats 1 --skip-memory`` (3 missions
of 1800 s, ~20-35 s). --memory drops
--skip-memory: the peak-memory part runs paper-sim for 1 h and 24 h per mission in
separate processes, about 4-5 minutes more per side per round.
Exit code: 0 nothing worse, 1 some figure more than 10 % worse, 2 could not run.
"""

from __future__ import annotations

import argparse
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import perf_page

REPO = Path(__file__).resolve().parent.parent
WORSE = 0.10
GENERATION_ARGS = ""
DATASETS_ARGS = "--duration 1800 --repeats 1 --skip-memory"
NUMBER = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"

# (script, regex, [(figure, higher is better) per group]); better None: not judged; figure
# None: not shown.
PATTERNS: list[tuple[str, str, list[tuple[str | None, bool | None]]]] = [
    *(("generation", rf"^{row}\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}\s+{NUMBER}\s*$",
       [(f"{row}: CPU s", False), (f"{row}: us/step", False),
        (f"{row}: x real time per core", True),
        (None if row == "bare" else f"{row}: x bare mj_step", False)])
      for row in ("bare", "simulate", "generate")),
    ("generation", rf"dataset size: {NUMBER} MB", [("dataset size, MB", None)]),
    ("datasets", rf"{NUMBER} MB written", [("paper-sim size, MB", None)]),
    ("datasets", rf"one core:\s+{NUMBER} s wall,\s+{NUMBER} s CPU ->\s+{NUMBER}x real time",
     [("one core: wall s", False), ("one core: CPU s", False),
      ("one core: x real time", True)]),
    ("datasets", rf"\d+ cores:\s+{NUMBER} s wall,\s+{NUMBER} s CPU ->\s+{NUMBER}x real time, "
     rf"{NUMBER}x per core, speed-up {NUMBER}x",
     [("all cores: wall s", False), ("all cores: CPU s", False),
      ("all cores: x real time", True), ("all cores: x real time per core", True),
      ("speed-up, all cores / one", True)]),
    ("datasets", rf"bare mj_step:\s+{NUMBER} s CPU -> generate costs {NUMBER}x bare stepping "
     rf"\({NUMBER}x pinned\)",
     [("bare mj_step: CPU s", False), ("generate: x bare mj_step", False),
      ("generate pinned: x bare mj_step", False)]),
    ("datasets", rf"peak memory:\s+1 h mission {NUMBER} MB, 24 h mission {NUMBER} MB -> "
     rf"ratio {NUMBER}",
     [("peak memory 1 h, MB", False), ("peak memory 24 h, MB", False),
      ("memory ratio 24 h / 1 h", False)]),
]
# The same plain MuJoCo loop on both sides: what these move by is the machine's noise.
CONTROLS = {("generation", "bare: CPU s"), ("generation", "bare: us/step"),
            ("generation", "bare: x real time per core"), ("datasets", "bare mj_step: CPU s")}


class RunError(Exception):
    """A side could not be set up or run."""


def git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=True).stdout.strip()


def parse(script: str, text: str) -> dict[tuple[str, str], float]:
    figures: dict[tuple[str, str], float] = {}
    for name, pattern, groups in PATTERNS:
        if name != script:
            continue
        match = re.search(pattern, text, re.MULTILINE)
        if match:
            figures.update(((script, label), float(value)) for (label, _), value in
                           zip(groups, match.groups(), strict=True) if label)
    return figures


class Side:
    def __init__(self, label: str, tree: Path, describe: str) -> None:
        self.label, self.tree, self.describe = label, tree, describe
        self.env = {**os.environ, "PYTHONPATH": str(tree)}
        self.figures: dict[tuple[str, str], list[float]] = {}

    def run(self, args: list[str], cwd: Path) -> str:
        result = subprocess.run([sys.executable, *args], cwd=cwd, env=self.env,
                                capture_output=True, text=True, check=False)
        if result.returncode:
            tail = (result.stdout + result.stderr).strip().splitlines()[-8:]
            raise RunError(f"{self.label}: `{' '.join(args)}` exited {result.returncode}"
                           + "".join(f"\n    {line}" for line in tail))
        return result.stdout

    def check_imports(self, cwd: Path) -> None:
        out = self.run(["-c", "import auvsim; print(auvsim.__file__)"], cwd).strip()
        if not Path(out).resolve().is_relative_to(self.tree.resolve()):
            raise RunError(f"{self.label}: auvsim imports from {out}, not {self.tree}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, help="git revision of the reference")
    parser.add_argument("--after", help="git revision to measure (default: the working tree "
                        "of this repository, uncommitted changes included)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--memory", action="store_true",
                        help="also measure peak memory (datasets.py without --skip-memory)")
    parser.add_argument("--generation-args", default=GENERATION_ARGS,
                        help=f"arguments of generation.py (default: {GENERATION_ARGS!r})")
    parser.add_argument("--datasets-args", default=DATASETS_ARGS,
                        help=f"arguments of datasets.py (default: {DATASETS_ARGS!r})")
    parser.add_argument("--log", type=Path, help="write every run's output to DIR")
    perf_page.add_write_option(parser, "before_after")
    args = parser.parse_args()
    datasets_args = shlex.split(args.datasets_args)
    if args.memory:
        datasets_args = [a for a in datasets_args if a != "--skip-memory"]
    scripts = {"generation": shlex.split(args.generation_args), "datasets": datasets_args}
    if args.log:
        args.log.mkdir(parents=True, exist_ok=True)

    tmp = Path(tempfile.mkdtemp(prefix="before_after-"))
    made: list[Path] = []
    start = time.perf_counter()
    try:
        sides = []
        for label, rev in (("before", args.before), ("after", args.after)):
            if rev is None:
                dirty = len(git("status", "--porcelain").splitlines())
                sides.append(Side(label, REPO, f"working tree {REPO} (HEAD "
                                  f"{git('rev-parse', '--short', 'HEAD')}, {dirty} changed "
                                  "or untracked paths)"))
                continue
            try:
                sha = git("rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}")
            except subprocess.CalledProcessError:
                raise RunError(f"not a commit: {rev!r}") from None
            tree = tmp / label
            git("worktree", "add", "--detach", "--quiet", str(tree), sha)
            made.append(tree)
            sides.append(Side(label, tree, f"{rev} = {sha[:12]}"))
        for side in sides:
            print(f"{side.label}: {side.describe}")
            side.check_imports(tmp)
        for name, extra in scripts.items():
            print(f"{name}.py {' '.join(extra) or '(its defaults)'}")
        for r in range(args.rounds):
            for name, extra in scripts.items():
                for side in sides if r % 2 == 0 else sides[::-1]:
                    cwd = Path(tempfile.mkdtemp(dir=tmp))
                    t = time.perf_counter()
                    out = side.run([str(side.tree / "benchmarks" / f"{name}.py"), *extra],
                                   cwd)
                    shutil.rmtree(cwd, ignore_errors=True)
                    figures = parse(name, out)
                    print(f"round {r + 1}/{args.rounds}: {name}.py {side.label}: "
                          f"{time.perf_counter() - t:.0f} s, {len(figures)} figures", flush=True)
                    if not figures:
                        print("    nothing parsed from:\n" + out)
                    if args.log:
                        (args.log / f"{r + 1}-{name}-{side.label}.txt").write_text(out)
                    for key, value in figures.items():
                        side.figures.setdefault(key, []).append(value)
    except RunError as e:
        print(f"could not run: {e}", file=sys.stderr)
        return 2
    finally:
        for tree in made:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force",
                            str(tree)], capture_output=True, check=False)
        subprocess.run(["git", "-C", str(REPO), "worktree", "prune"], capture_output=True,
                       check=False)
        shutil.rmtree(tmp, ignore_errors=True)

    before, after = sides
    worse: list[str] = []
    print(f"\nmedians of {args.rounds} round(s); spread = (max - min) / median")
    print(f"{'figure':36s} {'before':>10s} {'spread':>7s} {'after':>10s} {'spread':>7s} "
          f"{'after/before':>12s}")

    def spread(values: list[float]) -> str:
        med = statistics.median(values)
        return f"{(max(values) - min(values)) / med:6.1%}" if len(values) > 1 and med else ""

    header = None
    for script, _, groups in PATTERNS:
        for label, higher_better in groups:
            key = (script, label)
            b, a = before.figures.get(key), after.figures.get(key)
            if not b and not a:
                continue
            if script != header:
                header = script
                print(f"{script}.py {' '.join(scripts[script]) or '(its defaults)'}")
            mb = statistics.median(b) if b else None
            ma = statistics.median(a) if a else None
            ratio = ma / mb if mb and ma is not None else None
            flag = ""
            if ratio is None:
                flag = "  not parsed on one side"
            elif higher_better is not None and (
                    ratio < 1 - WORSE if higher_better else ratio > 1 + WORSE):
                flag = f"  WORSE (>{WORSE:.0%})"
                if key not in CONTROLS:
                    worse.append(f"{script}.py {label}")
                else:
                    flag += " (control: same MuJoCo loop, machine noise)"
            print(f"  {label:34s} {'' if mb is None else f'{mb:10.4g}':>10s} "
                  f"{spread(b) if b else '':>7s} {'' if ma is None else f'{ma:10.4g}':>10s} "
                  f"{spread(a) if a else '':>7s} "
                  f"{'' if ratio is None else f'{ratio:12.3f}':>12s}{flag}")
    print(f"({time.perf_counter() - start:.0f} s)")
    print(f"WORSE: {', '.join(worse)}" if worse else "nothing more than 10 % worse")
    return 1 if worse else 0


if __name__ == "__main__":
    sys.exit(perf_page.run(main))
