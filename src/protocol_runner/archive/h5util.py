"""Small helpers for writing the archive's HDF5 objects with units and plain-typed attributes."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt

from ..analysis.validation import SIGNAL as STORED_SIGNAL
from .attrs import ATTRIBUTES, DYNAMIC, UNITS
from .checksums import attributes_marked, seal_attributes_of, seal_values

SCHEMA_VERSION = 1
COMPRESS_ABOVE = 256
GZIP_LEVEL = 1
"""zlib level of the gzip filter: level 1 writes ~1.5x faster than 4 for an archive a few % larger."""
CHUNK_BYTES = 64 * 1024
"""Target chunk size of compressed 1-D datasets (HDF5's default guess makes ~8 KB chunks for a trial's
arrays: more per-chunk overhead and a worse ratio)."""
SIGNAL = STORED_SIGNAL  # measured and processed signals (the analysis fits the stored precision)


def put(
    group: h5py.Group, name: str, data: npt.ArrayLike, units: str, *, dtype: npt.DTypeLike | None = None
) -> h5py.Dataset:
    """Write a numeric dataset with its `units` attribute and its checksum, replacing one of that name.
    Arrays of more than COMPRESS_ABOVE elements are stored with HDF5's standard byte-shuffle and gzip
    filters (read without plug-ins); 1-D ones in chunks of about CHUNK_BYTES."""
    arr = np.asarray(data, dtype=dtype) if dtype is not None else np.asarray(data)
    if name in group:
        del group[name]
    filters: dict[str, Any] = {}
    if arr.size > COMPRESS_ABOVE:
        filters = {"compression": "gzip", "compression_opts": GZIP_LEVEL, "shuffle": True}
        if arr.ndim == 1:
            filters["chunks"] = (min(arr.shape[0], max(1, CHUNK_BYTES // max(1, arr.itemsize))),)
    ds = group.create_dataset(name, data=arr, **filters)
    ds.attrs[UNITS] = units
    seal_values(ds, arr)
    return ds


def put_text(group: h5py.Group, name: str, text: str | list[str]) -> h5py.Dataset:
    """A text dataset (a scalar for a str, one element per line for a list), sealed with its checksum, as
    fixed-length byte strings of its UTF-8 encoding: the type GNU Octave's `load` reads (not variable-length
    strings nor the UTF-8 character set, docs/matlab.md). An empty list is one empty line: Octave cannot read
    a string array of length 0."""
    if name in group:
        del group[name]
    if isinstance(text, str):
        data = np.array(text.encode("utf-8"), dtype="S")
    else:
        encoded = [line.encode("utf-8") for line in text] or [b""]
        data = np.array(encoded, dtype=f"S{max(1, *(len(b) for b in encoded))}")
    ds = group.create_dataset(name, data=data)
    seal_values(ds, data)
    return ds


def set_attrs(obj: h5py.HLObject, attrs: Mapping[str, Any]) -> None:
    """Attributes as HDF5/MATLAB-friendly types: str, int, float, bool, numeric arrays; dicts as JSON."""
    for key, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, (dict, list)) and not _is_numeric_list(value):
            obj.attrs[key] = json.dumps(value)
        elif isinstance(value, (list, tuple)):
            obj.attrs[key] = np.asarray(
                value, dtype=np.float64 if any(isinstance(v, float) for v in value) else None
            )
        else:
            obj.attrs[key] = value


def put_attrs(
    obj: h5py.HLObject, kind: str, attrs: Mapping[str, Any], *, dynamic: Mapping[str, Any] | None = None
) -> None:
    """Set the attributes `attrs` of an object of `kind` (a key of `attrs.ATTRIBUTES`) and the per-campaign
    ones in `dynamic` (only for a kind of `attrs.DYNAMIC`); a name the layout does not give that kind of
    object is a bug, refused before anything is written. In a file already finished with attribute
    checksums, their digests are recorded at once."""
    unknown = sorted(set(attrs) - set(ATTRIBUTES[kind]))
    if unknown or (dynamic and kind not in DYNAMIC):
        raise ValueError(f"archive layout: a {kind} has no attribute {', '.join(unknown) or 'per campaign'}")
    set_attrs(obj, attrs)
    if dynamic:
        set_attrs(obj, dynamic)
    if attributes_marked(obj.file):
        written = [k for k, v in {**attrs, **(dynamic or {})}.items() if v is not None]
        seal_attributes_of(obj, written)


def _is_numeric_list(value: object) -> bool:
    return isinstance(value, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
    )


def text_of(ds: h5py.Dataset) -> str:
    value = ds[()]
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def attr_str(obj: h5py.HLObject, key: str, default: str = "") -> str:
    value = obj.attrs.get(key, default)
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def attr_strs(obj: h5py.HLObject, key: str) -> list[str]:
    """A string-array attribute (or a single string) as a list of str; empty when absent."""
    if key not in obj.attrs:
        return []
    return [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in np.atleast_1d(obj.attrs[key])]


def group_name(step_id: str) -> str:
    """Step ids as HDF5 names and file names: ':' -> '__' (docs/archive.md)."""
    return step_id.replace(":", "__").replace("/", "_")
