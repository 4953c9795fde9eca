"""The packages' import structure, read from the source with ``ast``: no import circle
(imports inside functions and under ``if TYPE_CHECKING:`` count too), no private name
imported from another module, and beamsnet reads the simulator's facts from the dataset
API, not from the simulator."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("auvsim", "beamsnet")
# What beamsnet may import of auvsim: its lazy top-level exports, the dataset API (beam
# geometry included), frames, the Earth (WGS-84), the error vocabulary, the value checks
# (a leaf) and the command-line boundary both CLIs share, and, for the experiment runner,
# the presets, generation, the cluster helpers its Dask options share with auvsim and the
# worker processes its training pool shares.
BEAMSNET_MAY_IMPORT = ("auvsim.lazy", "auvsim.data", "auvsim.physics.frames",
                       "auvsim.physics.earth", "auvsim.errors", "auvsim.checks",
                       "auvsim.cli_support", "auvsim.runs.presets", "auvsim.runs.generate",
                       "auvsim.runs.cluster", "auvsim.processes")


def _modules() -> dict[str, Path]:
    """Module name -> file, for every module of both packages (a package by its
    ``__init__``)."""
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports(name: str) -> list[tuple[str, list[str]]]:
    """(module imported, names taken from it) for every import of module ``name``, at any
    depth (inside functions too), relative imports resolved."""
    path = MODULES[name]
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, []) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            found.append((base, [alias.name for alias in node.names]))
    return found


def _target(module: str, names: list[str]) -> list[str]:
    """The modules of ours an import reaches: ``from a.b import c`` is ``a.b.c`` when that
    is a module, else ``a.b``."""
    if module not in MODULES and not module.startswith(PACKAGES):
        return []
    out = [f"{module}.{n}" for n in names if f"{module}.{n}" in MODULES]
    if len(out) < len(names) or not names:
        out.append(module)
    return [m for m in out if m in MODULES]


def _graph() -> dict[str, set[str]]:
    graph = {}
    for name in MODULES:
        graph[name] = {t for module, names in _imports(name) for t in _target(module, names)
                       if t != name}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _parents(name: str) -> set[str]:
    """A module's packages (importing ``a.b.c`` runs ``a`` and ``a.b`` first), which an
    import of it does not make a circle with."""
    parts = name.split(".")
    return {".".join(parts[:k]) for k in range(1, len(parts))}


def test_the_module_graph_has_no_circle():
    graph = _graph()
    # A package's ``__init__`` re-exporting its own modules is not a circle: Python runs
    # the package first whatever is imported from it.
    graph = {v: {w for w in ws if v not in _parents(w)} for v, ws in graph.items()}
    assert "beamsnet.evaluate" in graph and graph["beamsnet.experiments.stress"]
    assert _cycles(graph) == []


def test_the_circle_finder_finds_one():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_private_name_is_imported_from_another_module():
    private = [f"{name}: from {module} import {n}" for name in MODULES
               for module, names in _imports(name) if module.startswith(PACKAGES)
               for n in names if n.startswith("_") and not n.startswith("__")]
    assert private == []


def _private_uses(path: Path, ours: set[str]) -> list[str]:
    """A script's private names taken from modules of ``ours`` (module names): imported
    (``from m import _x``) or reached through an imported module (``import m``, ``m._x``)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    aliases, found = {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            aliases.update({(a.asname or a.name): a.name for a in node.names
                            if a.name.split(".")[0] in ours})
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            if node.module.split(".")[0] not in ours:
                continue
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    found.append(f"from {node.module} import {a.name}")
                elif f"{node.module}.{a.name}" in MODULES:
                    aliases[a.asname or a.name] = f"{node.module}.{a.name}"
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            found.append(f"{aliases[node.value.id]}.{node.attr}")
    return [f"{path.relative_to(ROOT)}: {use}" for use in found]


def test_tests_and_benchmarks_share_no_private_name():
    # A helper one test module (or benchmark) lends another is public, named without the
    # underscore; a benchmark times auvsim through its public functions. (A test of a
    # module may call that module's private helpers: it tests them.)
    scripts = {folder: sorted((ROOT / folder).glob("*.py")) for folder in ("tests", "benchmarks")}
    siblings = {p.stem for paths in scripts.values() for p in paths}
    private = [use for folder, paths in scripts.items() for path in paths
               for use in _private_uses(path, siblings | ({"auvsim"} if folder == "benchmarks"
                                                          else set()))]
    assert private == []


def test_beamsnet_imports_only_the_dataset_api_and_the_runners_of_auvsim():
    taken = sorted({f"{name} -> {module}" for name in MODULES if name.startswith("beamsnet")
                    for module, _ in _imports(name)
                    if module.split(".")[0] == "auvsim" and not any(
                        module == allowed or module.startswith(f"{allowed}.")
                        for allowed in BEAMSNET_MAY_IMPORT)})
    assert taken == []


def test_auvsim_never_imports_beamsnet():
    assert not [name for name in MODULES if name.startswith("auvsim")
                for module, _ in _imports(name) if module.split(".")[0] == "beamsnet"]


def test_scipy_is_installed_with_the_package_where_numba_does_linear_algebra():
    """numba compiles np.linalg into calls of SciPy's LAPACK: a compiled function that
    uses it aborts the process where SciPy is not installed. Every module whose source
    holds ``np.linalg`` in a numba-compiled function needs SciPy in the package's own
    dependencies, not in an extra (the INS/DVL filter's loop had it only in ``test``)."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    compiled = []
    for path in sorted((ROOT / "auvsim").rglob("*.py")) + sorted((ROOT / "beamsnet").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and any(
                    "njit" in ast.unparse(d) for d in node.decorator_list) and \
                    "np.linalg" in ast.unparse(node):
                compiled.append(f"{path.relative_to(ROOT)}:{node.name}")
    assert compiled  # the INS/DVL filter's loop, at least
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert any(d.split(">")[0].split("=")[0].strip() == "scipy"
               for d in project["dependencies"]), compiled
