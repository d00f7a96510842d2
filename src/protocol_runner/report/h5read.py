"""Small readers of HDF5 attributes and datasets for the report: decoded, defaulted, read-only."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any, TypeVar

import h5py
import numpy as np

#: Most points drawn per line: the processed data is low-pass filtered (thesis §4.4), so ~250 points per
#: sinusoid cycle of a 65 s, 8-cycle trial still draw it exactly at report resolution.
MAX_PLOT_POINTS = 2000


def decimate_for_plot(values: np.ndarray, max_points: int = MAX_PLOT_POINTS) -> np.ndarray:
    """Every k-th sample so that at most `max_points` remain (k = ceil(n / max_points)); read-only."""
    arr = np.asarray(values)
    if arr.size <= max_points:
        return read_only(arr)
    stride = math.ceil(arr.size / max_points)
    return read_only(arr[::stride])


def subgroups(parent: h5py.Group, path: str = ".") -> list[tuple[str, h5py.Group]]:
    """(name, group) of every group directly under `parent[path]` (default: `parent` itself), in stored
    order; none when the path is absent (datasets beside them are passed over)."""
    if path not in parent:
        return []
    return [(name, obj) for name, obj in parent[path].items() if isinstance(obj, h5py.Group)]


def decode(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in ("S", "O"):
            return [decode(v) for v in value.tolist()]
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value


def attr_str(attrs: h5py.AttributeManager, name: str, default: str = "") -> str:
    if name not in attrs:
        return default
    value = decode(attrs[name])
    if isinstance(value, list):
        return ", ".join(str(v) for v in value)
    return str(value)


def attr_float(attrs: h5py.AttributeManager, name: str, default: float = float("nan")) -> float:
    values = attr_floats(attrs, name)  # an array's first value
    return values[0] if values else default


def attr_int(attrs: h5py.AttributeManager, name: str, default: int = 0) -> int:
    value = attr_float(attrs, name, float("nan"))
    return default if math.isnan(value) else int(value)


def attr_floats(attrs: h5py.AttributeManager, name: str) -> tuple[float, ...]:
    if name not in attrs:
        return ()
    value = decode(attrs[name])
    try:
        return tuple(float(v) for v in np.asarray(value, dtype=float).reshape(-1))
    except (TypeError, ValueError):
        return ()


def attr_bool(attrs: h5py.AttributeManager, name: str, default: bool = False) -> bool:
    if name not in attrs:
        return default
    value = decode(attrs[name])
    if isinstance(value, str):
        return value.strip().lower() in ("true", "1", "yes")
    return bool(value)


def scalar_str(ds: h5py.Dataset) -> str:
    value = decode(ds[()])
    if isinstance(value, list):
        return "\n".join(str(v) for v in value)
    return str(value)


def read_only(arr: np.ndarray) -> np.ndarray:
    out = np.asarray(arr)
    if out.flags.writeable:
        out = out.view()
        out.flags.writeable = False
    return out


def float_ds(group: h5py.Group, name: str) -> np.ndarray:
    if name not in group:
        return read_only(np.empty(0))
    return np.asarray(group[name][()], dtype=float).reshape(-1)


Record = TypeVar("Record")

#: How a record field is read from its group (given with its attributes, `group.attrs` taken once per
#: record), by the field's declared type: an attribute of that name, or (arrays) the dataset of that name
#: decimated for plotting. The last argument is the field's default.
_FIELD_READERS: dict[str, Callable[[h5py.Group, h5py.AttributeManager, str, Any], Any]] = {
    "float": lambda _, attrs, name, default: attr_float(attrs, name, default),
    "int": lambda _, attrs, name, default: attr_int(attrs, name, default),
    "bool": lambda _, attrs, name, default: attr_bool(attrs, name, default),
    "str": lambda _, attrs, name, default: attr_str(attrs, name, default),
    "tuple[float, ...]": lambda _, attrs, name, __: attr_floats(attrs, name),
    "FloatArray": lambda g, _, name, __: decimate_for_plot(float_ds(g, name)),
}
_NO_DEFAULT = {"float": float("nan"), "int": 0, "bool": False, "str": ""}


def read_record(record: type[Record], group: h5py.Group, **given: Any) -> Record:
    """A report record (a dataclass of the report model) from `group`: each field not `given` read under
    its own name by its type (`_FIELD_READERS`); a missing attribute takes the field's default, else NaN,
    0, False or ""."""
    values = dict(given)
    attrs = group.attrs
    for f in dataclasses.fields(record):  # type: ignore[arg-type]
        if f.name in values:
            continue
        kind = str(f.type)
        default = f.default if f.default is not dataclasses.MISSING else _NO_DEFAULT.get(kind)
        values[f.name] = _FIELD_READERS[kind](group, attrs, f.name, default)
    return record(**values)
