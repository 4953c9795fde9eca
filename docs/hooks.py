"""MkDocs hooks: files the site shows that live outside ``docs/``, and the API pages.

* The reports (``reports/*.md``) and the model card (``models/README.md``) are included
  into pages with ``pymdownx.snippets``; the figures they link to sit beside them in the
  repository, so they are added to the site at the same relative place, not copied.
* The API reference pages are written at build time from each package's public names
  (``_PUBLIC`` in ``auvsim/__init__.py`` and ``beamsnet/__init__.py``) and from the modules
  of ``auvsim.data`` and ``auvsim.sensors``, so a name added to the API is documented
  without editing a page, and a name that no longer resolves fails the strict build.
"""

from __future__ import annotations

import ast
import pkgutil
from pathlib import Path

from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]


def _public_names(package: str) -> dict[str, str]:
    """The ``_PUBLIC`` mapping (name -> module) of a package's ``__init__.py``, read
    without importing the package."""
    tree = ast.parse((ROOT / package / "__init__.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "_PUBLIC" for t in node.targets):
            return ast.literal_eval(node.value)
    raise ValueError(f"{package}/__init__.py: expected a _PUBLIC dict of the names users import")


def _modules(package: str) -> list[str]:
    """The public modules of a package folder, by name."""
    path = ROOT / package.replace(".", "/")
    return [f"{package}.{m.name}" for m in pkgutil.iter_modules([str(path)])
            if not m.name.startswith("_")]


def _top_level_page(package: str, intro: str) -> str:
    lines = [f"# {package}", "", intro, "",
             f"::: {package}", "    options:", "      members: false",
             "      show_root_heading: false", ""]
    for name, module in _public_names(package).items():
        lines += [f"::: {module}.{name}", "    options:", "      show_root_full_path: false",
                  "      heading_level: 2", ""]
    return "\n".join(lines)


def _package_page(package: str, intro: str) -> str:
    lines = [f"# {package}", "", intro, "",
             f"::: {package}", "    options:", "      members: false",
             "      show_root_heading: false", ""]
    for module in _modules(package):
        lines += [f"::: {module}", "    options:", "      heading_level: 2",
                  "      show_submodules: false", ""]
    return "\n".join(lines)


PAGES = {
    "api/auvsim.md": lambda: _top_level_page(
        "auvsim", "The names users import from `auvsim` itself (`from auvsim import "
        "open_dataset`); each is shown at the module that defines it."),
    "api/beamsnet.md": lambda: _top_level_page(
        "beamsnet", "The names users import from `beamsnet` itself (`from beamsnet import "
        "load_windows`); each is shown at the module that defines it."),
    "api/auvsim-data.md": lambda: _package_page(
        "auvsim.data", "The file format, its reader and writer, shards, and imported logs."),
    "api/auvsim-sensors.md": lambda: _package_page(
        "auvsim.sensors", "The sensor plugins and their interface."),
}


def on_files(files: Files, config) -> Files:
    for path in sorted((ROOT / "reports").glob("*.png")):
        files.append(File(str(path.relative_to(ROOT)), str(ROOT), config["site_dir"],
                          config["use_directory_urls"]))
    for uri, page in PAGES.items():
        files.append(File.generated(config, uri, content=page()))
    return files
