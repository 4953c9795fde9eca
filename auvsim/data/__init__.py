"""Files: the HDF5 schema (``schema``), its reader (``reader``) and writer (``writer``),
sharded datasets (``shards``), ``auvsim inspect``'s summary (``describe``), the random
streams (``streams``), atomic outputs (``files``), imported velocity streams
(``importer``), recorded logs (``recorded``) and what they leave out, found against
their reference (``checklog``, ``auvsim check-log``).

``open_dataset`` is importable from here (and from ``auvsim``), with
``require_usable_beams``, which refuses a mission with no usable DVL beam in one line,
and ``require_attitude``, which refuses a mission without attitude; they are loaded when
first asked for, so that importing ``auvsim.data.files`` stays light.
"""

from auvsim.lazy import exports

_PUBLIC = {"open_dataset": "auvsim.data.reader", "Dataset": "auvsim.data.reader",
           "Mission": "auvsim.data.reader", "require_usable_beams": "auvsim.data.reader",
           "require_attitude": "auvsim.data.reader"}
__all__ = list(_PUBLIC)

__getattr__, __dir__ = exports(__name__, _PUBLIC, globals())
