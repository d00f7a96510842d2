"""A SHA-256 checksum on every dataset of units and archives, and on every object's attributes
(docs/archive.md, "Checksums", gives the digest's bytes).

Each dataset carries an attribute `sha256`, the digest of its type, shape and values computed when they
are written: hashing them again proves that neither the stored bytes nor the type and shape changed, for
scalar, string and compressed datasets alike. Each object with attributes has one more, `attribute_sha256`,
a JSON object of the digests of its other attributes, recorded when a file is finished (`seal_attributes`)
and by `h5util.put_attrs` for attributes written into a finished file later (the verdicts).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt
from h5py import h5a, h5o, h5s, h5t

from .attrs import ATTRIBUTE_DIGESTS, ATTRIBUTE_MARKER, CHECKSUM_MARKER, DIGEST

MARKER_VALUE = "sha256"
NUMERIC_KINDS = "biuf"


def _header(kind: str, shape: tuple[int, ...]) -> bytes:
    return f"{kind}:{','.join(str(n) for n in shape)}\n".encode("ascii")


def numeric_digest(values: npt.NDArray[Any]) -> str:
    """The digest of a numeric array (values as stored: their dtype and shape)."""
    arr = np.asarray(values)
    if arr.dtype.kind not in NUMERIC_KINDS:
        raise TypeError(f"not a numeric array: {arr.dtype}")
    little = arr.dtype.newbyteorder("<") if arr.dtype.itemsize > 1 else arr.dtype
    data = np.ascontiguousarray(arr, dtype=little)
    h = hashlib.sha256(_header(f"{arr.dtype.kind}{arr.dtype.itemsize}", arr.shape))
    h.update(data.view(np.uint8).reshape(-1).data if data.size else b"")
    return h.hexdigest()


def text_digest(elements: list[bytes], shape: tuple[int, ...]) -> str:
    """The digest of a string dataset given its elements' UTF-8 bytes in C order."""
    h = hashlib.sha256(_header("s", shape))
    for item in elements:
        h.update(len(item).to_bytes(8, "little"))
        h.update(item)
    return h.hexdigest()


def seal_values(ds: h5py.Dataset, values: npt.NDArray[Any]) -> None:
    """Record on `ds` the digest of `values`, exactly what `ds` was created from (numbers, or the
    fixed-length byte strings of a text dataset): the digest needs neither `ds`'s type nor its shape read
    back."""
    if values.dtype.kind == "S":
        ds.attrs[DIGEST] = text_digest([bytes(v) for v in values.reshape(-1).tolist()], values.shape)
    else:
        ds.attrs[DIGEST] = numeric_digest(values)


def digest_of_stored(ds: h5py.Dataset) -> str:
    """Read `ds` and compute the digest of what is stored now (the caller has bounded its size).

    Raises TypeError for a type the archive never holds (compound, reference, opaque, ...)."""
    return attribute_digest(ds[()])  # h5py reads a dataset's values as it reads an attribute's


def recorded_digest(ds: h5py.Dataset) -> str | None:
    value = ds.attrs.get(DIGEST)
    if value is None:
        return None
    return value.decode("ascii", errors="replace") if isinstance(value, bytes) else str(value)


def seal_missing(f: h5py.File) -> int:
    """Record the digest of every dataset of `f` written without one (by code other than archive/h5util.py),
    from its stored values; the number sealed. Run before a file is marked, so the mark holds. Opens only
    the datasets without the attribute."""
    digest = DIGEST.encode("ascii")
    missing: list[bytes] = []

    def check(name: bytes, info: Any) -> None:
        if info.type == h5o.TYPE_DATASET and not h5a.exists(f.id, digest, obj_name=name):
            missing.append(name)

    h5o.visit(f.id, check, info=True)
    for name in missing:
        ds = f[name.decode("utf-8", errors="surrogateescape")]
        ds.attrs[DIGEST] = digest_of_stored(ds)
    return len(missing)


def mark(f: h5py.File) -> None:
    """Declare that every dataset of `f` carries a checksum."""
    f.attrs[CHECKSUM_MARKER] = MARKER_VALUE


def is_marked(f: h5py.File) -> bool:
    value = f.attrs.get(CHECKSUM_MARKER)
    return (value.decode() if isinstance(value, bytes) else value) == MARKER_VALUE


# ------------------------------------------------------------------------------------------- attributes

UNSUMMED_ATTRS = frozenset((DIGEST, ATTRIBUTE_DIGESTS))
"""Attributes no `attribute_sha256` covers: a dataset's checksum (its values check it) and the record itself."""
_UNSUMMED = frozenset(name.encode("ascii") for name in UNSUMMED_ATTRS)
_RECORD = ATTRIBUTE_DIGESTS.encode("ascii")
_EMPTY = hashlib.sha256(b"empty\n").hexdigest()
_MEMORY_TYPES: dict[bytes, tuple[np.dtype[Any], h5t.TypeID]] = {}  # HDF5 type's encoding -> `read_attr`'s

# Attributes are read and written on HDF5's identifiers, as consolidation merges them: an archive has about
# 10,000, and h5py's attribute managers cost several times the HDF5 calls they make.


def read_attr(attr: h5a.AttrID) -> tuple[npt.NDArray[Any], h5t.TypeID]:
    """An attribute's values as h5py's `attrs[name]` reads them (into the numpy type h5py gives its HDF5
    type, an array of the attribute's shape), and the memory type read with; both types made once per HDF5
    type (its encoding)."""
    key = attr.get_type().encode()
    types = _MEMORY_TYPES.get(key)
    if types is None:
        types = _MEMORY_TYPES[key] = (attr.dtype, h5t.py_create(attr.dtype))
    values = np.empty(attr.shape, dtype=types[0])
    if values.size:
        attr.read(values, mtype=types[1])
    return values, types[1]


def attribute_digest(value: Any) -> str:
    """The digest of an attribute's value as h5py reads it: numbers (scalar or array) as a numeric dataset's
    values, text (str or UTF-8 bytes, one or an array) as a text dataset's, an empty attribute as no value."""
    if isinstance(value, h5py.Empty):
        return _EMPTY
    if isinstance(value, str | bytes):
        return text_digest([value.encode("utf-8") if isinstance(value, str) else value], ())
    arr = np.asarray(value)
    if arr.dtype.kind in "OSU":
        items = arr.reshape(-1).tolist()
        return text_digest([v.encode("utf-8") if isinstance(v, str) else bytes(v) for v in items], arr.shape)
    return numeric_digest(arr)


def _stored_digest(oid: h5o.ObjectID, name: bytes) -> str:
    attr = h5a.open(oid, name)
    if attr.get_space().get_simple_extent_type() == h5s.NULL:
        return _EMPTY
    return attribute_digest(read_attr(attr)[0])


def attribute_names(oid: h5o.ObjectID) -> list[bytes]:
    names: list[bytes] = []
    h5a.iterate(oid, names.append)  # append returns None: iteration goes on
    return names


def _digests(oid: h5o.ObjectID) -> dict[str, str]:
    return {k.decode("utf-8"): _stored_digest(oid, k) for k in attribute_names(oid) if k not in _UNSUMMED}


def stored_attribute_digests(obj: h5py.HLObject) -> dict[str, str]:
    """The digest of each attribute of `obj` that `attribute_sha256` covers, from its stored value."""
    return _digests(obj.id)


def recorded_attribute_digests(obj: h5py.HLObject) -> dict[str, str] | None:
    """`obj`'s recorded attribute digests, or None when it has none; ValueError when unreadable."""
    if not h5a.exists(obj.id, _RECORD):
        return None
    raw = read_attr(h5a.open(obj.id, _RECORD))[0].reshape(-1)
    text = raw[0] if raw.size == 1 else b""
    doc = json.loads(text.decode("utf-8") if isinstance(text, bytes) else str(text))
    if not isinstance(doc, dict) or not all(isinstance(v, str) for v in doc.values()):
        raise ValueError(f"{ATTRIBUTE_DIGESTS} is not a JSON object of digests")
    return doc


_TEXT = h5py.string_dtype()
_TEXT_TYPE = h5t.py_create(_TEXT, logical=True)  # a UTF-8 variable-length string, as `attrs[k] = str` stores


def _record(oid: h5o.ObjectID, digests: dict[str, str]) -> None:
    """Write `digests` as the object's `attribute_sha256` (none when it has no attribute to cover)."""
    if h5a.exists(oid, _RECORD):
        h5a.delete(oid, _RECORD)
    if digests:
        attr = h5a.create(oid, _RECORD, _TEXT_TYPE, h5s.create(h5s.SCALAR))
        text = json.dumps(dict(sorted(digests.items())), separators=(",", ":"))
        attr.write(np.array(text, dtype=_TEXT))


def seal_attributes_of(obj: h5py.HLObject, names: Iterable[str] | None = None) -> None:
    """Record the digests of `obj`'s attributes `names` (default: all of them, replacing the record), from
    the values just stored; digests of attributes that no longer exist are dropped."""
    if names is None:
        _record(obj.id, stored_attribute_digests(obj))
        return
    present = {name.decode("utf-8") for name in attribute_names(obj.id)}
    digests = {k: v for k, v in (recorded_attribute_digests(obj) or {}).items() if k in present}
    for name in names:
        if name not in UNSUMMED_ATTRS:
            digests[name] = _stored_digest(obj.id, name.encode("utf-8"))
    _record(obj.id, digests)


def seal_attributes(f: h5py.File) -> int:
    """Record the digests of every attribute of every object of `f` from the values stored now, and mark
    `f` as carrying them; the number of attributes sealed. Called by the writer of a unit, an archive or a
    reprocessed archive as it finishes the file (what it reads back is what it has just written)."""
    f.attrs[ATTRIBUTE_MARKER] = MARKER_VALUE
    names: list[bytes] = [b"."]
    h5o.visit(f.id, names.append)  # every object once, by one of its paths
    count = 0
    for name in names:
        obj = h5o.open(f.id, name)
        digests = _digests(obj)
        count += len(digests)
        _record(obj, digests)
    return count


def attributes_marked(f: h5py.File) -> bool:
    """Whether `f` declares a digest for every attribute (written after attribute checksums existed)."""
    value = f.attrs.get(ATTRIBUTE_MARKER)
    return (value.decode() if isinstance(value, bytes) else value) == MARKER_VALUE
