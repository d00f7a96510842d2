"""A SHA-256 checksum on every dataset of units and archives (docs/archive.md, "Checksums").

Each dataset carries an attribute `sha256`: the hex SHA-256 of its type, shape and values, computed from
the values when they are written. Reading the values back and hashing them again proves that neither the
stored bytes (raw or compressed chunks) nor the dataset's type and shape changed since: one flipped bit
anywhere in them changes the digest. This works the same for scalar, tiny, string and compressed
datasets, unlike HDF5's fletcher32 filter (chunked datasets only; it leaves strings unprotected).

The digest of a dataset is SHA-256 over a header line and the values:

    numeric (bool, int, uint, float):  b"<kind><itemsize>:<shape>\\n" then the values in C order as
                                       little-endian bytes; kind is one of b, i, u, f
    strings (UTF-8 text):              b"s:<shape>\\n" then per element its UTF-8 byte length as an
                                       8-byte little-endian integer followed by the bytes

where <shape> is the dimensions joined by "," (empty for a scalar), e.g. b"f4:65000\\n".
"""

from __future__ import annotations

import hashlib
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt
from h5py import h5a, h5o

from .attrs import CHECKSUM_MARKER, DIGEST

DIGEST_ATTR = DIGEST
MARKER_ATTR = CHECKSUM_MARKER
"""Root attribute of units and archives whose every dataset has a `sha256` attribute (value "sha256")."""
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


def seal(ds: h5py.Dataset, values: npt.ArrayLike | str | list[str]) -> None:
    """Record the digest of `values`, the content just written to `ds`, on `ds`."""
    if h5py.check_string_dtype(ds.dtype) is not None:
        items = [values] if isinstance(values, str) else list(np.asarray(values, dtype=object).reshape(-1))
        encoded = [v.encode("utf-8") if isinstance(v, str) else bytes(v) for v in items]
        ds.attrs[DIGEST_ATTR] = text_digest(encoded, ds.shape)
    else:
        ds.attrs[DIGEST_ATTR] = numeric_digest(np.asarray(values, dtype=ds.dtype).reshape(ds.shape))


def seal_values(ds: h5py.Dataset, values: npt.NDArray[Any]) -> None:
    """`seal` for `values` that are exactly what `ds` was created from (numbers, or the fixed-length byte
    strings of a text dataset): the digest needs neither `ds`'s type nor its shape read back."""
    if values.dtype.kind == "S":
        ds.attrs[DIGEST_ATTR] = text_digest([bytes(v) for v in values.reshape(-1).tolist()], values.shape)
    else:
        ds.attrs[DIGEST_ATTR] = numeric_digest(values)


def digest_of_stored(ds: h5py.Dataset) -> str:
    """Read `ds` and compute the digest of what is stored now (the caller has bounded its size).

    Raises TypeError for a type the archive never holds (compound, reference, opaque, ...)."""
    if h5py.check_string_dtype(ds.dtype) is not None or ds.dtype.kind == "S":
        raw = ds[()]
        items = [raw] if ds.shape == () else list(np.asarray(raw, dtype=object).reshape(-1))
        return text_digest([v if isinstance(v, bytes) else str(v).encode("utf-8") for v in items], ds.shape)
    if ds.dtype.kind not in NUMERIC_KINDS:
        raise TypeError(f"unexpected type {ds.dtype}")
    return numeric_digest(np.asarray(ds[()]))


def recorded_digest(ds: h5py.Dataset) -> str | None:
    value = ds.attrs.get(DIGEST_ATTR)
    if value is None:
        return None
    return value.decode("ascii", errors="replace") if isinstance(value, bytes) else str(value)


def seal_missing(f: h5py.File) -> int:
    """Record the digest of every dataset of `f` written without one (by code other than archive/h5util.py),
    from its stored values; the number sealed. Run before a file is marked, so the mark holds.

    Walks the file with HDF5's own visit and asks HDF5 whether each dataset has the attribute, so a unit
    whose datasets were all sealed when written opens none of them here."""
    digest = DIGEST_ATTR.encode("ascii")
    missing: list[bytes] = []

    def check(name: bytes, info: Any) -> None:
        if info.type == h5o.TYPE_DATASET and not h5a.exists(f.id, digest, obj_name=name):
            missing.append(name)

    h5o.visit(f.id, check, info=True)
    for name in missing:
        ds = f[name.decode("utf-8", errors="surrogateescape")]
        ds.attrs[DIGEST_ATTR] = digest_of_stored(ds)
    return len(missing)


def mark(f: h5py.File) -> None:
    """Declare that every dataset of `f` carries a checksum."""
    f.attrs[MARKER_ATTR] = MARKER_VALUE


def is_marked(f: h5py.File) -> bool:
    value = f.attrs.get(MARKER_ATTR)
    return (value.decode() if isinstance(value, bytes) else value) == MARKER_VALUE
