"""A mission's fields as xarray Datasets (``auvsim.data.reader.Mission.to_xarray``), one per
group, each on its group's own clock, with units and descriptions from the schema.

The reader reads the arrays; this module only labels them, from the schema's ``Field``
records (``auvsim.data.schema``): a field's unit and description, and its clock, whose
``time`` field becomes the Dataset's ``time`` coordinate. Component coordinates follow the
field names of the conventions (``auvsim`` package docstring): ``*_ned`` vectors are
``ned`` = N, E, D; ``quaternion`` is ``component`` = w, x, y, z; ``rpy_deg`` is ``angle``
= roll, pitch, yaw; other 3-vectors are ``axis`` = x, y, z (in the frame their
description names); 4-vectors are ``beam`` = 0 to 3, their columns, as settings and
reports name beams (``auvsim.sensors.dvl``).

xarray is optional (``pip install 'auvsim[io]'``), imported here when a view is made.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from auvsim.errors import AuvsimError
from auvsim.sensors import Field

if TYPE_CHECKING:
    import xarray

REFERENCE_NOTE = ("the recorded mission's reference: a navigation solution (see the "
                  "attribute reference_source), not the truth")


def group_datasets(fields: Sequence[Field], read: Callable[[str], np.ndarray],
                   attrs: Mapping[str, object], *, timedelta: bool = False
                   ) -> dict[str, xarray.Dataset]:
    """One ``xarray.Dataset`` per group of a mission.

    Each Dataset's ``time`` coordinate is the group's own ``time`` field (the truth's for
    ``control``, which has none), in s; every field of the group is a variable with dims
    ``(time, ...)``, attributes ``units`` and ``description`` (the schema's) and ``field``
    (its path in the file). A field on another group's clock moves to that group's
    Dataset, named ``<group>_<name>``: ``imu/index_of_dvl`` (the IMU sample of each ping)
    is ``imu_index_of_dvl`` in ``dvl``. Every Dataset carries ``attrs`` (the mission's),
    and a ``reference`` Dataset says in its ``description`` that it is a reference.

    Args:
        fields: the schema's fields the mission holds (``auvsim.data.schema``).
        read: reads a field whole by its path (``Mission.read``): (N, ...) values.
        attrs: attributes for every Dataset (the mission's, its name, the file).
        timedelta: make ``time`` a ``timedelta64[ns]`` index (the seconds rounded to the
            nanosecond), which pandas can ``resample``; default float seconds, exactly the
            file's.

    Raises:
        AuvsimError: xarray is not installed, in one line naming the extra that has it.
    """
    xr = _xarray()  # before reading anything
    known = {f.path: f for f in fields}
    times = {}  # clock -> the path of its time field, the first the schema lists
    for f in known.values():
        if f.path.endswith("/time"):
            times.setdefault(f.clock, f.path)
    placed: dict[str, dict[str, Field]] = {}  # Dataset -> variable name -> its field
    for f in known.values():
        group, name = f.path.split("/")
        own = times.get(f.clock)
        if own is None:
            continue  # no time to put it on (a field of a clock the file lacks)
        if f"{group}/time" in known and known[f"{group}/time"].clock != f.clock:
            group, name = own.split("/")[0], f"{group}_{name}"
        placed.setdefault(group, {})[name] = f
    out = {}
    for group, variables in sorted(placed.items()):
        clock = next(iter(variables.values())).clock
        time_field = known[f"{group}/time"] if f"{group}/time" in known \
            else known[times[clock]]
        data = {name: _variable(f, read(f.path)) for name, f in variables.items()
                if name != "time"}
        extra = {"group": group}
        if group == "reference":
            extra["description"] = REFERENCE_NOTE
        out[group] = xr.Dataset(data, coords={"time": _time(time_field, read, timedelta),
                                              **_components(variables.values())},
                                attrs={**attrs, **extra})
    return out


def _variable(f: Field, values: np.ndarray) -> tuple:
    dims = ("time", *(_component_dim(f, k) for k in range(len(f.shape))))
    return dims, values, {"units": f.unit, "description": f.doc, "field": f.path}


def _time(f: Field, read: Callable[[str], np.ndarray], timedelta: bool) -> tuple:
    seconds = read(f.path)
    attrs = {"description": f.doc, "field": f.path}
    if timedelta:
        # No units attribute: xarray encodes a timedelta's units itself when writing.
        return "time", np.rint(seconds * 1e9).astype(np.int64).view("timedelta64[ns]"), attrs
    return "time", seconds, {**attrs, "units": f.unit}


# Labels of a component axis by its dim (``_component_dim``). Beams by their column, 0 to 3,
# as settings and reports name them (``auvsim.sensors.dvl``, ``DvlConfig.beam_failures``).
LABELS = {"ned": ["N", "E", "D"], "component": ["w", "x", "y", "z"],
          "angle": ["roll", "pitch", "yaw"], "axis": ["x", "y", "z"], "beam": [0, 1, 2, 3]}


def _component_dim(f: Field, k: int) -> str:
    """The dim of axis ``k`` of a row of ``f``: named from the conventions' field names,
    or ``<name>_<k>`` for a shape they do not name."""
    name, n = f.path.split("/")[1], f.shape[k]
    if len(f.shape) == 1:
        if n == 4:
            return "component" if name == "quaternion" else "beam"
        if n == 3:
            return ("ned" if name.endswith("_ned") else "angle" if name.endswith("rpy_deg")
                    else "axis")
    return f"{name}_{k}"


def _components(fields: Sequence[Field]) -> dict[str, tuple]:
    dims = {_component_dim(f, k) for f in fields for k in range(len(f.shape))}
    return {d: (d, LABELS[d]) for d in sorted(dims) if d in LABELS}


def _xarray():
    try:
        import xarray
    except ImportError:
        raise AuvsimError("Mission.to_xarray needs xarray, which is not installed: expected "
                          "pip install 'auvsim[io]'") from None
    return xarray
