"""Prove that two revisions generate the same data (and, with --reports, the same reports).

Each revision gets a git worktree of its own (the "after" side defaults to the working tree
this script sits in, uncommitted changes included) and runs, with that tree's code
(``PYTHONPATH=tree``) in a fresh directory, the same ``auvsim generate`` and
``auvsim import-velocity`` commands. The HDF5 files are then compared with h5py and numpy
alone (no auvsim import: the two sides may write different versions of the format):

* every dataset of BEFORE must be in AFTER with the same dtype, shape and values (NaN equal
  to NaN); filters and chunking may differ, hard links are followed under every name;
* every attribute of BEFORE (root, groups, datasets) must be in AFTER with an equal value
  and dtype, except the root's ``created_utc`` (ignored), ``auvsim_version`` and
  ``format_version`` (printed) and ``config_json`` (parsed; BEFORE's must be a recursive
  subset of AFTER's);
* datasets, groups, attributes and config keys only in AFTER are allowed and listed.

With --reports it also runs ``beamsnet reproduce paper-sim`` and ``beamsnet stress`` (a few
minutes each, with torch) and compares the Markdown tables of the reports and stress.json
text for text; differences in the prose around the tables are printed but do not fail.

    .venv/bin/python benchmarks/same_data.py --before REV [--after REV] [--reports]
        [--keep DIR] [--snapir DIR] [--new-estimator NAME ...]
    .venv/bin/python benchmarks/same_data.py --before-dir DIR [--after REV] [--reports]

--new-estimator NAME sets aside an estimator added since BEFORE (its table rows and
columns, its keys in stress.json): the rest of every table must still be equal.
--keep DIR keeps the runs in DIR/before and DIR/after (HDF5 files, reports, logs, and a
manifest.json). --before-dir DIR compares against such a kept DIR/before instead of running
--before again. Exit code: 0 same data, 1 different, 2 could not run.
"""

from __future__ import annotations

import argparse
import difflib
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

REPO = Path(__file__).resolve().parent.parent
IGNORED_ROOT_ATTRS = ("created_utc",)
VERSION_ROOT_ATTRS = ("auvsim_version", "format_version")
GENERATE = (
    ("navigator.h5", ["--preset", "navigator", "--duration", "120", "--seed", "3"]),
    ("paper-sim.h5", ["--preset", "paper-sim", "--duration", "300"]),
    ("paper-sim-text.h5", ["--preset", "paper-sim-text", "--duration", "300"]),
    ("maneuvers.h5", ["--preset", "maneuvers", "--duration", "300"]),
    ("maneuvers-w2.h5", ["--preset", "maneuvers", "--duration", "300", "--workers", "2"]),
    ("zigzag.h5", ["--scenario", "zigzag", "--duration", "200", "--seed", "5"]),
)
REPORTS = (
    ("reproduce", ["-m", "beamsnet.cli", "reproduce", "paper-sim", "--duration", "300",
                   "--epochs", "2", "--restarts", "1", "--out", "rep", "--quiet"],
     ("rep/paper-sim.md",)),
    ("stress", ["-m", "beamsnet.cli", "stress", "--train-duration", "300",
                "--maneuver-duration", "300", "--epochs", "2", "--out", "rep", "--quiet"],
     ("rep/stress.md", "rep/stress.json")),
)
MAX_LINES = 20  # differences printed per file


class RunError(Exception):
    """A side could not be set up or run."""


def git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(REPO), *args], capture_output=True, text=True,
                          check=True).stdout.strip()


def resolve(rev: str) -> str:
    try:
        return git("rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}")
    except subprocess.CalledProcessError:
        raise RunError(f"not a commit: {rev!r}") from None


class Trees:
    """Git worktrees in a temporary directory, removed on exit."""

    def __init__(self) -> None:
        self.root = Path(tempfile.mkdtemp(prefix="same_data-trees-"))
        self.made: list[Path] = []

    def add(self, name: str, sha: str) -> Path:
        path = self.root / name
        git("worktree", "add", "--detach", "--quiet", str(path), sha)
        self.made.append(path)
        return path

    def close(self) -> None:
        for path in self.made:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force",
                            str(path)], capture_output=True, check=False)
        subprocess.run(["git", "-C", str(REPO), "worktree", "prune"], capture_output=True,
                       check=False)
        shutil.rmtree(self.root, ignore_errors=True)


class Side:
    """One revision's code (a tree) and the directory its runs go to."""

    def __init__(self, label: str, tree: Path, describe: str, out: Path) -> None:
        self.label, self.tree, self.describe, self.out = label, tree, describe, out
        self.env = {**os.environ, "PYTHONPATH": str(tree)}

    def check_imports(self) -> None:
        """PYTHONPATH must beat the editable install's finder, for both packages."""
        self.out.mkdir(parents=True, exist_ok=True)
        code = "import auvsim, beamsnet; print(auvsim.__file__); print(beamsnet.__file__)"
        result = subprocess.run([sys.executable, "-c", code], cwd=self.out, env=self.env,
                                capture_output=True, text=True, check=False)
        files = result.stdout.split()
        tree = self.tree.resolve()
        if result.returncode or len(files) != 2 or not all(
                Path(f).resolve().is_relative_to(tree) for f in files):
            raise RunError(f"{self.label}: the packages do not import from {tree}: "
                           f"{result.stdout.strip()} {result.stderr.strip()[-500:]}")

    def run(self, cwd: Path, args: list[str], log: str) -> float:
        """Run ``python ARGS`` in ``cwd`` with this side's code; wall seconds."""
        cwd.mkdir(parents=True, exist_ok=True)
        start = time.perf_counter()
        with open(cwd / f"{log}.log", "w") as f:
            result = subprocess.run([sys.executable, *args], cwd=cwd, env=self.env,
                                    stdout=f, stderr=subprocess.STDOUT, check=False)
        wall = time.perf_counter() - start
        if result.returncode:
            tail = (cwd / f"{log}.log").read_text().strip().splitlines()[-5:]
            raise RunError(f"{self.label}: `{' '.join(args)}` exited {result.returncode}"
                           + "".join(f"\n    {line}" for line in tail))
        return wall


def commands(snapir: Path) -> list[tuple[str, list[str]]]:
    out = [(name, ["-m", "auvsim.cli", "generate", *args, "--out", name, "--quiet"])
           for name, args in GENERATE]
    out.append(("snapir.h5", ["-m", "auvsim.cli", "import-velocity", str(snapir / "V.npy"),
                              str(snapir / "V_test.npy"), "--out", "snapir.h5"]))
    return out


# ---- HDF5 comparison -------------------------------------------------------------------


def walk(group: h5py.Group, prefix: str = "") -> dict[str, object]:
    """Every object under ``group`` by path, following each hard link under its own name
    (``visititems`` visits a hard-linked dataset only once); soft links by their target."""
    found: dict[str, object] = {}
    for name in group:
        path = f"{prefix}{name}"
        link = group.get(name, getlink=True)
        if isinstance(link, h5py.SoftLink | h5py.ExternalLink):
            found[path] = link
            continue
        obj = group[name]
        found[path] = obj
        if isinstance(obj, h5py.Group):
            found.update(walk(obj, f"{path}/"))
    return found


def kind(obj: object) -> str:
    if isinstance(obj, h5py.Dataset):
        return "dataset"
    if isinstance(obj, h5py.Group):
        return "group"
    return type(obj).__name__


def type_info(dtype: np.dtype) -> tuple:
    return (dtype, h5py.check_string_dtype(dtype), h5py.check_vlen_dtype(dtype))


def arrays_equal(a: np.ndarray, b: np.ndarray) -> bool:
    if a.dtype.names:
        return a.dtype.names == b.dtype.names and all(
            arrays_equal(a[n], b[n]) for n in a.dtype.names)
    if a.dtype.kind in "fc":
        return bool(np.array_equal(a, b, equal_nan=True))
    if a.dtype.kind == "O":  # variable length: compare element by element
        return a.shape == b.shape and all(
            arrays_equal(np.asarray(x), np.asarray(y)) if isinstance(x, np.ndarray)
            else x == y for x, y in zip(a.ravel(), b.ravel(), strict=True))
    return bool(np.array_equal(a, b))


def datasets_equal(a: h5py.Dataset, b: h5py.Dataset) -> str | None:
    """None when equal, else what differs."""
    if type_info(a.dtype) != type_info(b.dtype):
        return f"dtype {a.dtype} -> {b.dtype}"
    if a.shape != b.shape:
        return f"shape {a.shape} -> {b.shape}"
    if a.shape is None or a.size == 0:
        return None
    if not a.shape:
        return None if arrays_equal(np.asarray(a[()]), np.asarray(b[()])) else "value differs"
    step = max(1, 4_000_000 // max(1, a.size // a.shape[0]))  # rows per read, bounded memory
    first, largest = None, 0.0  # the first row that differs; the largest |diff| of all
    for start in range(0, a.shape[0], step):
        x, y = a[start:start + step], b[start:start + step]
        if not arrays_equal(x, y):
            if x.dtype.kind not in "biuf":
                return f"values differ (rows {start}..{start + len(x) - 1})"
            bad = (x != y) & ~(np.isnan(x) & np.isnan(y)) if x.dtype.kind == "f" else x != y
            if first is None:
                first = start + np.flatnonzero(bad.reshape(len(x), -1).any(axis=1))[0]
            if x.dtype.kind == "f":  # NaN on one side only: an infinite difference
                gap = np.nan_to_num(np.abs(x[bad] - y[bad]), nan=np.inf)
                largest = max(largest, float(np.max(gap)))
    if first is None:
        return None
    size = f", max |diff| {largest:.3g}" if a.dtype.kind == "f" else ""
    return f"values differ (first at row {first}{size})"


def attr_equal(a: object, b: object) -> bool:
    if isinstance(a, str | bytes) or isinstance(b, str | bytes):
        return type(a) is type(b) and a == b
    x, y = np.asarray(a), np.asarray(b)
    return type_info(x.dtype) == type_info(y.dtype) and x.shape == y.shape and \
        arrays_equal(x, y)


def json_subset(before: object, after: object, path: str, diffs: list[str],
                added: list[str]) -> None:
    """Every key/value of ``before`` must be in ``after``; keys only in ``after`` go to
    ``added``."""
    if isinstance(before, dict) and isinstance(after, dict):
        for key, value in before.items():
            if key not in after:
                diffs.append(f"{path}.{key} missing")
            else:
                json_subset(value, after[key], f"{path}.{key}", diffs, added)
        added += [f"{path}.{key}" for key in after if key not in before]
    elif isinstance(before, list) and isinstance(after, list) and len(before) == len(after):
        for i, (x, y) in enumerate(zip(before, after, strict=True)):
            json_subset(x, y, f"{path}[{i}]", diffs, added)
    elif not (before == after and type(before) is type(after) or (
            isinstance(before, float) and isinstance(after, float)
            and math.isnan(before) and math.isnan(after))):
        diffs.append(f"{path}: {json.dumps(before)[:80]} -> {json.dumps(after)[:80]}")


def collapse(names: list[str]) -> list[str]:
    """``missions/<m>/x`` for several missions -> ``missions/*/x (n missions)``."""
    groups: dict[str, list[str]] = {}
    for name in names:
        groups.setdefault(re.sub(r"^missions/[^/@]+", "missions/*", name), []).append(name)
    return [v[0] if len(v) == 1 else f"{k} ({len(v)} missions)" for k, v in groups.items()]


def compare_h5(before: Path, after: Path) -> tuple[str, list[str]]:
    """(summary line, differences)."""
    diffs: list[str] = []
    added: list[str] = []
    versions: list[str] = []
    n_data = n_attrs = 0
    with h5py.File(before, "r") as fb, h5py.File(after, "r") as fa:
        objs_b, objs_a = walk(fb), walk(fa)
        objs_b[""], objs_a[""] = fb, fa
        for path, ob in objs_b.items():
            oa = objs_a.get(path)
            if oa is None:
                diffs.append(f"{path}: {kind(ob)} missing")
                continue
            if kind(ob) != kind(oa):
                diffs.append(f"{path}: {kind(ob)} -> {kind(oa)}")
                continue
            if isinstance(ob, h5py.SoftLink | h5py.ExternalLink):
                if vars(ob) != vars(oa):
                    diffs.append(f"{path}: link {vars(ob)} -> {vars(oa)}")
                continue
            if isinstance(ob, h5py.Dataset):
                problem = datasets_equal(ob, oa)
                if problem:
                    diffs.append(f"{path}: {problem}")
                else:
                    n_data += 1
            where = path or "/"
            for key in ob.attrs:
                if path == "" and key in IGNORED_ROOT_ATTRS:
                    continue
                if key not in oa.attrs:
                    diffs.append(f"{where}@{key}: attribute missing")
                    continue
                vb, va = ob.attrs[key], oa.attrs[key]
                if path == "" and key in VERSION_ROOT_ATTRS:
                    versions.append(f"{key} {vb} -> {va}")
                elif path == "" and key == "config_json":
                    bad: list[str] = []
                    new: list[str] = []
                    json_subset(json.loads(vb), json.loads(va), "config_json", bad, new)
                    diffs += bad
                    added += new
                    n_attrs += not bad
                elif attr_equal(vb, va):
                    n_attrs += 1
                else:
                    diffs.append(f"{where}@{key}: {repr(vb)[:60]} -> {repr(va)[:60]}")
            added += [f"{where}@{key}" for key in oa.attrs if key not in ob.attrs]
        added += [f"{p}{'/' if kind(o) == 'group' else ''}" for p, o in objs_a.items()
                  if p not in objs_b]
    line = (f"{n_data} datasets equal, {n_attrs} attributes equal; {'; '.join(versions)}; "
            f"added: {', '.join(collapse(added)) or 'none'}")
    return line, diffs


# ---- reports ---------------------------------------------------------------------------


def without(lines: list[str], new: tuple[str, ...]) -> list[str]:
    """Report lines with the rows and columns of the estimators ``new`` (added since BEFORE)
    taken out of every Markdown table."""
    out, drop = [], set()
    for line in lines:
        if not line.lstrip().startswith("|"):
            out.append(line)
            drop = set()
            continue
        cells = line.strip().strip("|").split("|")
        if not drop and any(c.strip() in new for c in cells[1:]):  # a header naming them
            drop = {i for i, c in enumerate(cells) if c.strip() in new}
        if cells[0].strip() in new:
            continue
        out.append("|" + "|".join(c for i, c in enumerate(cells) if i not in drop) + "|")
    return out


def without_keys(value: object, new: tuple[str, ...]) -> object:
    """JSON ``value`` with every key in ``new`` taken out, at any depth."""
    if isinstance(value, dict):
        return {k: without_keys(v, new) for k, v in value.items() if k not in new}
    if isinstance(value, list):
        return [without_keys(v, new) for v in value]
    return value


def compare_text(before: Path, after: Path, new: tuple[str, ...] = ()
                 ) -> tuple[list[str], list[str]]:
    """(differing table lines, differing prose lines) of two reports; .json: all lines.
    The estimators ``new`` (added since BEFORE) are set aside in AFTER's tables and JSON."""
    if not after.exists():
        return [f"{after.name} missing"], []
    a, b = before.read_text().splitlines(), after.read_text().splitlines()
    if new and after.suffix == ".json":
        b = json.dumps(without_keys(json.loads(after.read_text()), new), indent=1).splitlines()
        a = json.dumps(json.loads(before.read_text()), indent=1).splitlines()
    elif new:
        b = without(b, new)

    def delta(x: list[str], y: list[str]) -> list[str]:
        return [d for d in difflib.unified_diff(x, y, "before", "after", n=0, lineterm="")
                if d[:1] in "+-" and d[:3] not in ("---", "+++")]

    if before.suffix != ".md":
        return delta(a, b), []

    def table(lines: list[str], want: bool) -> list[str]:
        return [line for line in lines if line.lstrip().startswith("|") == want]

    return delta(table(a, True), table(b, True)), delta(table(a, False), table(b, False))


def show(lines: list[str], indent: str = "    ") -> None:
    for line in lines[:MAX_LINES]:
        print(f"{indent}{line[:300]}")
    if len(lines) > MAX_LINES:
        print(f"{indent}... {len(lines) - MAX_LINES} more")


# ---- main ------------------------------------------------------------------------------


def side_for(label: str, rev: str | None, trees: Trees, out: Path) -> Side:
    if rev is None:
        head = git("rev-parse", "--short", "HEAD")
        dirty = len(git("status", "--porcelain").splitlines())
        return Side(label, REPO, f"working tree {REPO} (HEAD {head}, {dirty} changed or "
                    "untracked paths)", out)
    sha = resolve(rev)
    return Side(label, trees.add(label, sha), f"{rev} = {sha[:12]}", out)


def run_pair(before: Side | None, after: Side, cwd: str, cmd: list[str], log: str,
             different: list[str]) -> str | None:
    """Run ``cmd`` on both sides (BEFORE only if not kept); their wall times, or None when
    AFTER failed (recorded in ``different``). BEFORE failing raises RunError."""
    walls = [before.run(before.out / cwd, cmd, log)] if before else []
    try:
        walls.append(after.run(after.out / cwd, cmd, log))
    except RunError as e:
        print(f"{log}: {e}", flush=True)
        different.append(f"{log} (after failed)")
        return None
    return ", ".join(f"{w:.1f} s" for w in walls)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--before", help="git revision of the reference")
    which.add_argument("--before-dir", type=Path,
                       help="use DIR/before, kept by an earlier --keep DIR, as the reference")
    parser.add_argument("--after", help="git revision to check (default: the working tree "
                        "of this repository, uncommitted changes included)")
    parser.add_argument("--reports", action="store_true",
                        help="also compare beamsnet reproduce paper-sim / stress reports")
    parser.add_argument("--keep", type=Path, help="keep the runs in DIR/before, DIR/after")
    parser.add_argument("--new-estimator", action="append", default=[], metavar="NAME",
                        help="an estimator added since BEFORE: its rows and columns of the "
                        "reports' tables (and its keys in stress.json) are set aside, the "
                        "rest must be equal (repeatable)")
    parser.add_argument("--snapir", type=Path, default=REPO.parent / "shared/data/snapir",
                        help="directory with V.npy and V_test.npy (default: %(default)s)")
    args = parser.parse_args()
    snapir = args.snapir.resolve()
    cmds = commands(snapir)
    reports = REPORTS if args.reports else ()
    if args.keep:
        args.keep = args.keep.resolve()
        for label in ("before", "after"):
            if (args.keep / label).exists() and not (label == "before" and args.before_dir):
                print(f"--keep: {args.keep / label} exists; give a new directory",
                      file=sys.stderr)
                return 2
    runs = args.keep or Path(tempfile.mkdtemp(prefix="same_data-runs-"))
    trees = Trees()
    start = time.perf_counter()
    try:
        if args.before_dir:
            kept = args.before_dir.resolve() / "before"
            manifest = json.loads((kept / "manifest.json").read_text())
            if manifest["commands"] != [c for _, c in cmds]:
                print("warning: the kept run's commands differ from this script's")
            missing = [r for r, _, _ in reports if r not in manifest["reports"]]
            if missing:
                raise RunError(f"{kept} has no kept report runs: {', '.join(missing)}")
            before = None
            print(f"before: kept run {kept} ({manifest['describe']})")
        else:
            before = side_for("before", args.before, trees, runs / "before")
            kept = before.out
            print(f"before: {before.describe}")
        after = side_for("after", args.after, trees, runs / "after")
        print(f"after:  {after.describe}")
        for side in (before, after):
            if side:
                side.check_imports()
        different: list[str] = []
        for name, cmd in cmds:
            took = run_pair(before, after, "generate", cmd, name.removesuffix(".h5"),
                            different)
            if took is None:
                continue
            line, diffs = compare_h5(kept / "generate" / name, after.out / "generate" / name)
            print(f"{name}: {line}  [{took}]", flush=True)
            show(diffs)
            if diffs:
                different.append(f"{name} ({len(diffs)} differences)")
        for run, cmd, files in reports:
            took = run_pair(before, after, run, cmd, run, different)
            if took is None:
                continue
            for file in files:
                tables, prose = compare_text(kept / run / file, after.out / run / file,
                                             tuple(args.new_estimator))
                what = "tables" if file.endswith(".md") else "text"
                print(f"{Path(file).name}: {what} {'DIFFER' if tables else 'equal'}"
                      f"{f', {len(prose)} prose lines differ (not checked)' if prose else ''}"
                      f"  [{took}]", flush=True)
                show(tables)
                show(prose, "    (prose) ")
                if tables:
                    different.append(f"{Path(file).name} ({len(tables)} lines)")
        for side in (before, after):
            if side:
                record = dict(describe=side.describe, tree=str(side.tree),
                              commands=[c for _, c in cmds], reports=[r for r, _, _ in reports])
                (side.out / "manifest.json").write_text(json.dumps(record, indent=1))
    except RunError as e:
        print(f"could not run: {e}", file=sys.stderr)
        return 2
    finally:
        trees.close()
        if not args.keep:
            shutil.rmtree(runs, ignore_errors=True)
    print(f"({time.perf_counter() - start:.0f} s; outputs kept in {runs})" if args.keep else
          f"({time.perf_counter() - start:.0f} s)")
    print("SAME DATA" if not different else f"DIFFERENT: {', '.join(different)}")
    return 1 if different else 0


if __name__ == "__main__":
    sys.exit(main())
