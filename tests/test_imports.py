"""Every module of both packages imports first and alone, in a fresh interpreter."""

from __future__ import annotations

import pkgutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

import auvsim
import beamsnet


def _modules() -> list[str]:
    names = []
    for package in (auvsim, beamsnet):
        names.append(package.__name__)
        names += [m.name for m in pkgutil.walk_packages(package.__path__,
                                                         prefix=f"{package.__name__}.")]
    # ``python -m auvsim`` runs the command line when imported: an entry point, not a module.
    return sorted(n for n in names if not n.endswith(".__main__"))


def _import_alone(name: str) -> tuple[str, int, str]:
    done = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True,
                          text=True, timeout=300)
    return name, done.returncode, done.stderr.strip().splitlines()[-1:] or [""]


def test_every_module_imports_first_and_alone():
    modules = _modules()
    expected = {"auvsim.physics.maneuvers", "auvsim.sensors.dvl", "beamsnet.training.train"}
    assert expected <= set(modules)
    with ThreadPoolExecutor(max_workers=2) as pool:  # the CI machine's two cores
        results = list(pool.map(_import_alone, modules))
    failed = [f"{name}: {last[0]}" for name, code, last in results if code != 0]
    assert not failed, failed
