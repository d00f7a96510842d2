"""Attributes and datasets created through h5py's low-level API, with their HDF5 types, dataspaces and
creation property lists made once and reused (issue 20).

A session writes about 10,000 attributes and 2,000 datasets, most of them tiny: h5py's high-level
`obj.attrs[name] = value` and `group.create_dataset(...)` rebuild a datatype, a dataspace and a property
list for each, which costs more than writing the values. The functions here make exactly the HDF5 calls
h5py's high-level API makes for the same value (the same datatype from `h5py.h5t.py_create`, the same
dataspace, the same dataset creation properties: chunk shape, then the shuffle and deflate filters, no
object times, no attribute creation order), so the file holds the same bytes; a value they do not cover
goes through h5py's high-level API unchanged. tests/archive/test_h5fast.py compares both byte for byte.
"""

from __future__ import annotations

from typing import Any

import h5py
import numpy as np
import numpy.typing as npt
from h5py import h5a, h5d, h5p, h5s, h5t

ATTR_KINDS = "biuf"
"""numpy kinds of the array attributes written here (bool, integers, floats); others go through h5py."""
DATASET_KINDS = "biufS"
"""numpy kinds of the datasets created here: numbers and fixed-length byte strings (the text datasets)."""
_STR = h5py.string_dtype()  # what h5py stores a Python str attribute as: variable-length UTF-8
_INT64_MIN, _INT64_MAX = -(2**63), 2**63 - 1

_attr_types: dict[str, tuple[h5t.TypeID, h5t.TypeID]] = {}
_dataset_types: dict[str, h5t.TypeID] = {}
_spaces: dict[tuple[int, ...], h5s.SpaceID] = {}
_dcpls: dict[tuple[object, ...], h5p.PropDCID] = {}


def set_attr(obj: h5py.HLObject, name: str, value: Any) -> None:
    """`obj.attrs[name] = value` (replacing an attribute of that name), for str, bool, int, float and
    numeric arrays through the cached objects; any other value through h5py."""
    data, key = _attr_data(value)
    if data is None or not name.isascii():
        obj.attrs[name] = value
        return
    types = _attr_types.get(key)
    if types is None:
        # h5py's attrs.create: the logical type for the file, the exact memory type for the write
        types = _attr_types[key] = (h5t.py_create(data.dtype, logical=True), h5t.py_create(data.dtype))
    oid = obj.id
    encoded = name.encode("ascii")
    if h5a.exists(oid, encoded):
        h5a.delete(oid, encoded)
    attr = h5a.create(oid, encoded, types[0], _space(data.shape))
    try:
        attr.write(data, mtype=types[1])
    except BaseException:
        attr.close()
        h5a.delete(oid, encoded)
        raise
    attr.close()


def _attr_data(value: Any) -> tuple[npt.NDArray[Any] | None, str]:
    """The array h5py would write for `value` and the key of its cached types; (None, "") for a value
    left to h5py (bytes, object arrays, integers beyond int64, ...)."""
    if isinstance(value, str):
        return np.array(value, dtype=_STR), "str"
    if isinstance(value, int) and not isinstance(value, bool) and not _INT64_MIN <= value <= _INT64_MAX:
        return None, ""
    if isinstance(value, (bool, int, float, np.bool_, np.integer, np.floating)):
        data = np.asarray(value)
    elif isinstance(value, np.ndarray) and value.dtype.kind in ATTR_KINDS:
        data = np.asarray(value, order="C")
    else:
        return None, ""
    return data, data.dtype.str


def remove_link(group: h5py.Group, name: str) -> None:
    """`del group[name]` if `group` has a member `name` (a plain name asked of HDF5 directly)."""
    if "/" in name or not name.isascii():
        if name in group:
            del group[name]
    elif group.id.links.exists(name.encode("ascii")):
        group.id.unlink(name.encode("ascii"))


def _space(shape: tuple[int, ...]) -> h5s.SpaceID:
    space = _spaces.get(shape)
    if space is None:
        space = _spaces[shape] = h5s.create_simple(shape)
    return space


def create_dataset(
    group: h5py.Group,
    name: str,
    arr: npt.NDArray[Any],
    *,
    chunk: int | None = None,
    shuffle: bool = False,
    gzip_level: int | None = None,
    write: bool = True,
) -> h5py.Dataset:
    """`group.create_dataset(name, data=arr, ...)` (with `write=False`: `shape=arr.shape, dtype=arr.dtype`,
    the values to be written by the caller) for a 1-D chunk of `chunk` elements with the shuffle filter
    (`shuffle`) and deflate at `gzip_level`, or contiguous when `chunk` is None. A dtype or name outside
    what is cached here, or compression without a 1-D chunk (h5py's guessed chunks), goes through h5py's
    `create_dataset`."""
    track_order = h5py.get_config().track_order
    by_h5py = gzip_level is not None and (chunk is None or arr.ndim != 1)  # h5py guesses the chunks
    if by_h5py or arr.dtype.kind not in DATASET_KINDS or not name.isascii() or "/" in name:
        return _create_by_h5py(group, name, arr, chunk, shuffle, gzip_level, write)
    tid = _dataset_types.get(arr.dtype.str)
    if tid is None:
        tid = _dataset_types[arr.dtype.str] = h5t.py_create(arr.dtype, logical=True)
    key = (chunk, shuffle, gzip_level, track_order)
    dcpl = _dcpls.get(key)
    if dcpl is None:
        dcpl = _dcpls[key] = _make_dcpl(chunk, shuffle, gzip_level, track_order)
    dsid = h5d.create(group.id, name.encode("ascii"), tid, h5s.create_simple(arr.shape), dcpl=dcpl)
    if write:
        dsid.write(h5s.ALL, h5s.ALL, np.asarray(arr, order="C"))
    return h5py.Dataset(dsid)


def _make_dcpl(chunk: int | None, shuffle: bool, gzip_level: int | None, track_order: bool | None) -> Any:
    """The dataset creation properties h5py's `make_new_dset` sets, in its order."""
    dcpl = h5p.create(h5p.DATASET_CREATE)
    if chunk is not None:
        dcpl.set_chunk((chunk,))
        if shuffle:
            dcpl.set_shuffle()
        if gzip_level is not None:
            dcpl.set_deflate(gzip_level)
    dcpl.set_obj_track_times(False)
    if track_order is True:
        dcpl.set_attr_creation_order(h5p.CRT_ORDER_TRACKED | h5p.CRT_ORDER_INDEXED)
    elif track_order is False:
        dcpl.set_attr_creation_order(0)
    return dcpl


def _create_by_h5py(
    group: h5py.Group,
    name: str,
    arr: npt.NDArray[Any],
    chunk: int | None,
    shuffle: bool,
    gzip_level: int | None,
    write: bool,
) -> h5py.Dataset:
    kwargs: dict[str, Any] = {}
    if gzip_level is not None:
        kwargs = {"compression": "gzip", "compression_opts": gzip_level, "shuffle": shuffle}
    if chunk is not None:
        kwargs["chunks"] = (chunk,)
    if write:
        return group.create_dataset(name, data=arr, **kwargs)
    return group.create_dataset(name, shape=arr.shape, dtype=arr.dtype, **kwargs)
