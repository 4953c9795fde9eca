"""Every module of both packages imports first and alone, in a fresh interpreter."""

from __future__ import annotations

import pkgutil
import subprocess
import sys

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


# A parent that holds the heavy third-party libraries (none of this project's modules) forks
# one child per module: each child imports its module first and alone, as a fresh
# interpreter would, without paying for torch, MuJoCo and numba again every time.
_FORKING_PARENT = """
import os, sys, traceback
import numpy, h5py, mujoco, numba, torch, gymnasium, tqdm, matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot
assert not any(m.split(".")[0] in ("auvsim", "beamsnet") for m in sys.modules)
for name in sys.argv[1:]:
    pid = os.fork()
    if pid == 0:
        try:
            __import__(name)
        except BaseException:
            print(name + ": " + traceback.format_exc().strip().splitlines()[-1], flush=True)
            os._exit(1)
        os._exit(0)
    _, status = os.waitpid(pid, 0)
    if status != 0:
        print(name + ": exit status " + str(status), flush=True)
"""


def test_every_module_imports_first_and_alone():
    modules = _modules()
    expected = {"auvsim.physics.maneuvers", "auvsim.sensors.dvl", "beamsnet.training.train"}
    assert expected <= set(modules)
    done = subprocess.run([sys.executable, "-c", _FORKING_PARENT, *modules],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    failed = sorted({line for line in done.stdout.splitlines() if line.strip()})
    assert not failed, failed


def test_beamsnet_evaluate_is_the_module_whatever_was_imported_first():
    """No top-level name shadows a submodule: ``beamsnet.evaluate`` had been the function
    ``evaluate`` or the module by the order of the imports."""
    code = ("import beamsnet\nfrom beamsnet import estimate\nimport beamsnet.evaluate\n"
            "import types\nassert isinstance(beamsnet.evaluate, types.ModuleType)\n"
            "assert callable(beamsnet.evaluate.evaluate) and estimate is "
            "beamsnet.evaluate.estimate\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    for package in (auvsim, beamsnet):
        assert not set(package.__all__) & {m.name for m in pkgutil.iter_modules(package.__path__)}


def test_dir_offers_the_public_names_not_the_submodules_an_import_loaded():
    """``dir(auvsim)`` (what tab completion offers) had listed ``lazy``, ``exports`` and
    any submodule an import had loaded (``checks``), which ``auvsim.checks`` then did not
    give until imported; it lists the public names."""
    import auvsim.checks  # noqa: F401  (loaded: still not offered)
    import auvsim.data

    for package in (auvsim, auvsim.data, beamsnet):
        offered = {n for n in dir(package) if not n.startswith("__")}
        public = {n for n in package.__all__ if not n.startswith("__")}
        assert offered == public, offered ^ public
