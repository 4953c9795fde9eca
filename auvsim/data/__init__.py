"""Files: the HDF5 schema (``schema``), its reader (``reader``) and writer (``writer``),
sharded datasets (``shards``), ``auvsim inspect``'s summary (``describe``), the random
streams (``streams``), atomic outputs (``files``) and imported logs (``importer``).

``open_dataset`` is importable from here (and from ``auvsim``), with
``require_usable_beams``, which refuses a mission with no usable DVL beam in one line;
they are loaded when first asked for, so that importing ``auvsim.data.files`` stays
light.
"""

_PUBLIC = {"open_dataset": "auvsim.data.reader", "Dataset": "auvsim.data.reader",
           "Mission": "auvsim.data.reader", "require_usable_beams": "auvsim.data.reader"}
__all__ = list(_PUBLIC)


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'auvsim.data' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_PUBLIC[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
