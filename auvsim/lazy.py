"""Names a package offers from its modules, each loaded when first asked for (PEP 562), so
that importing the package stays light."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping


def exports(package: str, public: Mapping[str, str], namespace: MutableMapping[str, object]
            ) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of a package that offers ``public`` names.

    Args:
        package: the package's name (its ``__name__``).
        public: name -> the module that defines it.
        namespace: the package's ``globals()``; a name, once loaded, is kept there.
    """

    def __getattr__(name: str) -> object:
        if name not in public:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(public[name]), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        # The public names and the dunders; not the submodules an import has loaded
        # (``lazy``, ``checks``), which tab completion would offer as the package's own.
        return sorted(set(public) | {n for n in namespace if n.startswith("__")})

    return __getattr__, __dir__
