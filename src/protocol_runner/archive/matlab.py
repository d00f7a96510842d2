"""Archive groups as MATLAB structs for the `.mat` export, by the rules docs/matlab.md states for users
(valid MATLAB names, numbers as double, 1-D arrays as columns, 1-based indices, text as char or a cell
column, one flat `units` struct).
"""

from __future__ import annotations

import re
from typing import Any

import h5py
import numpy as np

from ..errors import InvalidInput
from .attrs import ATTRIBUTE_DIGESTS, UNITS

NAMELENGTHMAX = 63  # MATLAB's namelengthmax
_EXACT_INT = 2**53  # larger integers lose digits as double
_LEGACY_INDEX0 = {
    "transition_index_on": "transition_index0_on",
    "transition_index_off": "transition_index0_off",
}


def matlab_name(name: str, prefix: str = "x") -> str:
    """`name` as a valid MATLAB identifier: `config_12` stays, `1` -> `{prefix}_1`, `brace-off` -> `brace_off`,
    `speed.speed_deg_s` -> `speed__speed_deg_s`."""
    clean = re.sub(r"[^A-Za-z0-9_]", "_", name.replace(".", "__"))
    if not clean[:1].isalpha():
        clean = prefix + clean if clean.startswith("_") else f"{prefix}_{clean}"
    return clean[:NAMELENGTHMAX]


def put_field(struct: dict[str, Any], name: str, value: Any, prefix: str = "x") -> str:
    """Set `struct[matlab_name(name)] = value`, with `_2`, `_3`... when that name is taken; returns the name."""
    base = matlab_name(name, prefix)
    key, n = base, 2
    while key in struct:
        suffix = f"_{n}"
        key = base[: NAMELENGTHMAX - len(suffix)] + suffix
        n += 1
    struct[key] = value
    return key


def index_base(name: str, value: Any) -> tuple[str, Any]:
    """A 0-based index attribute as its 1-based MATLAB form (`x_index0_on` 962 -> `x_index1_on` 963)."""
    name = _LEGACY_INDEX0.get(name, name)
    if "index0" in name:
        return name.replace("index0", "index1"), np.asarray(value) + 1
    return name, value


class Units:
    """The units of the exported datasets, by MATLAB field name; a name with two units is an error."""

    def __init__(self, archive: str) -> None:
        self.archive = archive
        self._units: dict[str, tuple[str, str]] = {}

    def add(self, field: str, ds: h5py.Dataset) -> None:
        if UNITS not in ds.attrs:
            return
        unit = text(ds.attrs[UNITS])
        seen = self._units.setdefault(field, (unit, ds.name or field))
        if seen[0] != unit:
            raise InvalidInput(
                f"{self.archive}: {ds.name} has units '{unit}' but {seen[1]} has '{seen[0]}'; "
                "a name has one unit throughout an archive (docs/archive.md)"
            )

    def struct(self) -> dict[str, str]:
        return {name: unit for name, (unit, _) in sorted(self._units.items())}


def text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray) and value.shape == ():
        return text(value[()])
    return str(value)


def matlab_value(value: Any, where: str) -> Any:
    """An attribute's or dataset's value in the types of the module docstring; `where` names it in errors."""
    if isinstance(value, (bytes, str)):
        return text(value)
    arr = np.asarray(value)
    kind = arr.dtype.kind
    if kind == "b":
        return arr
    if kind in "SUO":
        items = [text(v) for v in arr.reshape(-1).tolist()]
        if arr.shape == ():
            return items[0]
        cell = np.empty((len(items), 1), dtype=object)
        for i, item in enumerate(items):
            cell[i, 0] = item
        return cell
    if kind in "iu":
        if arr.size and int(np.max(np.abs(arr.astype(np.int64)))) >= _EXACT_INT:
            return arr.astype(np.int64)
        return arr.astype(np.float64)
    if kind == "f":
        return arr.astype(np.float64)
    if kind == "c":
        return arr.astype(np.complex128)
    raise InvalidInput(f"{where}: values of HDF5 type {arr.dtype} have no MATLAB equivalent; cannot export")


def attrs_struct(obj: h5py.HLObject, where: str) -> dict[str, Any]:
    """An HDF5 object's attributes as struct fields (indices made 1-based; see `index_base`)."""
    out: dict[str, Any] = {}
    for key, value in obj.attrs.items():
        if key == ATTRIBUTE_DIGESTS:  # the archive's own integrity record, checked before
            continue
        name, value = index_base(key, value)
        put_field(out, name, matlab_value(value, f"{where}: {obj.name}@{key}"))
    return out


def group_struct(group: h5py.Group, units: Units, where: str, skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """A group as a struct: its attributes, its datasets (as arrays) and its subgroups (as structs), but
    the members named in `skip`. `where` names the archive in error messages."""
    out = attrs_struct(group, where)
    for name, obj in group.items():
        if name in skip:
            continue
        if isinstance(obj, h5py.Dataset):
            field = put_field(out, name, dataset_value(obj, where))
            units.add(field, obj)
        elif isinstance(obj, h5py.Group):
            put_field(out, name, group_struct(obj, units, where))
    return out


def dataset_value(ds: h5py.Dataset, where: str) -> Any:
    return matlab_value(ds[()], f"{where}: {ds.name}")
