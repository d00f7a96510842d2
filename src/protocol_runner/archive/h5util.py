"""Small helpers for writing the archive's HDF5 objects with units and plain-typed attributes."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt
from isal import isal_zlib

from ..analysis.validation import SIGNAL as STORED_SIGNAL
from .attrs import ATTRIBUTES, DYNAMIC, UNITS
from .checksums import seal_values
from .h5fast import create_dataset, remove_link, set_attr

SCHEMA_VERSION = 1
COMPRESS_ABOVE = 256
GZIP_LEVEL = 1
"""zlib level of the gzip filter. Level 1 writes ~1.5x faster than 4 and, with the chunks and shuffle rule
below, the archive is smaller than level 4 with HDF5's default chunks and shuffle everywhere."""
CHUNK_BYTES = 64 * 1024
"""Target chunk size of compressed 1-D datasets (HDF5's default guess makes ~8 KB chunks for a trial's
arrays: more per-chunk overhead and a worse ratio)."""
SHUFFLE_PROBE = 8192
"""Elements of a float32 dataset deflated both with and without the byte shuffle to choose the filter
chain: a signal converted from ADC codes (few distinct 4-byte patterns) deflates ~25 % smaller, and faster,
unshuffled; a smooth processed signal is smaller shuffled."""
DEFLATE_LEVEL = 1
"""ISA-L level (0-3) of the chunks this module deflates itself (`_write_chunks`) and of the shuffle probe.
Intel's ISA-L (the `isal` package) writes the same standard zlib stream format as zlib - HDF5's gzip filter,
h5py, HDFView, MATLAB and Octave read it unchanged - about 6 times faster than zlib's level 1 on the
archive's shuffled chunks (0.05 s of CPU instead of 0.33 s for the 60 MB of the knee dry run's 25 largest
units), for streams about 6 % larger (20.8 MB instead of 19.6 MB). Datasets HDF5 compresses itself (the
small and multi-dimensional ones) keep zlib at GZIP_LEVEL."""
SIGNAL = STORED_SIGNAL  # measured and processed signals (the analysis fits the stored precision)


def put(
    group: h5py.Group,
    name: str,
    data: npt.ArrayLike,
    units: str,
    *,
    dtype: npt.DTypeLike | None = None,
    compress: bool = True,
) -> h5py.Dataset:
    """Write a numeric dataset with its `units` attribute (docs/archive.md: every numeric dataset has one).

    Arrays of more than COMPRESS_ABOVE elements are gzip-compressed (HDF5's standard filters: h5py, HDFView
    and MATLAB read them without plug-ins), with the byte shuffle filter where `_shuffle_helps`; 1-D ones in
    chunks of about CHUNK_BYTES. The layout depends only on the data, never on when or where it is written.
    Like every dataset, it carries the sha256 checksum of its values (archive/checksums.py). The dataset
    and its attributes are created through archive/h5fast.py (the same HDF5 calls as h5py's `create_dataset`
    and `attrs`, with cached types and property lists)."""
    arr = np.asarray(data, dtype=dtype) if dtype is not None else np.asarray(data)
    remove_link(group, name)
    chunk = None
    shuffle = False
    level = None
    if compress and arr.size > COMPRESS_ABOVE:
        shuffle = _shuffle_helps(arr)
        level = GZIP_LEVEL
        if arr.ndim == 1:
            chunk = min(arr.shape[0], max(1, CHUNK_BYTES // max(1, arr.itemsize)))
    by_chunks = chunk is not None and arr.shape[0] > chunk and arr.dtype.kind in "fiu" and arr.dtype.isnative
    ds = create_dataset(group, name, arr, chunk=chunk, shuffle=shuffle, gzip_level=level, write=not by_chunks)
    if by_chunks:
        assert chunk is not None
        _write_chunks(ds, arr, chunk, shuffle)
    set_attr(ds, UNITS, units)
    seal_values(ds, arr)
    return ds


def _write_chunks(ds: h5py.Dataset, arr: npt.NDArray[Any], chunk: int, shuffle: bool) -> None:
    """Write a 1-D dataset chunk by chunk, each compressed here as HDF5's filter pipeline would (byte
    shuffle, then a zlib stream; the last chunk padded with the fill value 0) and stored as is
    (`write_direct_chunk`); the stream is ISA-L's at DEFLATE_LEVEL (the standard format every reader of the
    gzip filter reads). The chunks are compressed on COMPRESS_THREADS threads (ISA-L releases the GIL), so
    a trial's unit is written on two cores while they are free. The bytes do not depend on the threads:
    every chunk is compressed independently."""
    n_chunks = -(-arr.shape[0] // chunk)
    data = np.ascontiguousarray(arr)

    def compressed(k: int) -> bytes:
        block = data[k * chunk : (k + 1) * chunk]
        if block.shape[0] < chunk:
            padded = np.zeros(chunk, dtype=data.dtype)
            padded[: block.shape[0]] = block
            block = padded
        raw = block.view(np.uint8)
        if shuffle:
            raw = np.ascontiguousarray(raw.reshape(-1, data.itemsize).T)
        return isal_zlib.compress(raw.data, DEFLATE_LEVEL)

    for k, payload in enumerate(_compressor().map(compressed, range(n_chunks))):
        ds.id.write_direct_chunk((k * chunk,), payload, filter_mask=0)


COMPRESS_THREADS = 2
_POOL: tuple[int, ThreadPoolExecutor] | None = None


def _compressor() -> ThreadPoolExecutor:
    """This process's compression threads (a forked child gets its own: threads do not survive fork)."""
    global _POOL
    if _POOL is None or _POOL[0] != os.getpid():
        _POOL = (
            os.getpid(),
            ThreadPoolExecutor(max_workers=COMPRESS_THREADS, thread_name_prefix="h5-deflate"),
        )
    return _POOL[1]


def _shuffle_helps(arr: npt.NDArray[Any]) -> bool:
    """Whether the byte shuffle makes `arr` deflate smaller. Always for integers and float64 (codes, times:
    their high bytes barely change); for float32 it is decided on the first SHUFFLE_PROBE values, deflated
    both ways. Depends on the values only (deterministic)."""
    if arr.dtype != np.float32:
        return True
    head = np.ascontiguousarray(arr.reshape(-1)[:SHUFFLE_PROBE])
    plain = head.view(np.uint8)
    shuffled = np.ascontiguousarray(plain.reshape(-1, head.itemsize).T)
    return len(isal_zlib.compress(shuffled.tobytes(), DEFLATE_LEVEL)) < len(
        isal_zlib.compress(plain.tobytes(), DEFLATE_LEVEL)
    )


def fixed_text(text: str | list[str]) -> npt.NDArray[np.bytes_]:
    """`text` (one string, or a list of lines) as fixed-length byte strings of its UTF-8 encoding.

    The archive's text datasets use this type because GNU Octave's built-in `load` reads it: Octave
    cannot read variable-length strings nor the HDF5 UTF-8 character set, and one unreadable dataset
    stops its `load` for the rest of the file (docs/matlab.md). An empty list is stored as one empty
    line: Octave cannot read a string array of length 0."""
    if isinstance(text, str):
        return np.array(text.encode("utf-8"), dtype="S")
    encoded = [line.encode("utf-8") for line in text] or [b""]
    return np.array(encoded, dtype=f"S{max(1, *(len(b) for b in encoded))}")


def put_text(group: h5py.Group, name: str, text: str | list[str]) -> h5py.Dataset:
    """A text dataset (a scalar for a str, one element per line for a list), sealed with its checksum."""
    remove_link(group, name)
    data = fixed_text(text)
    ds = create_dataset(group, name, data)
    seal_values(ds, data)
    return ds


def put_lines(group: h5py.Group, name: str, lines: list[str]) -> h5py.Dataset:
    return put_text(group, name, lines)


def set_attrs(obj: h5py.HLObject, attrs: Mapping[str, Any]) -> None:
    """Attributes as HDF5/MATLAB-friendly types: str, int, float, bool, numeric arrays; dicts as JSON."""
    for key, value in attrs.items():
        if value is None:
            continue
        if isinstance(value, (dict, list)) and not _is_numeric_list(value):
            set_attr(obj, key, json.dumps(value))
        elif isinstance(value, (list, tuple)):
            set_attr(
                obj,
                key,
                np.asarray(value, dtype=np.float64 if any(isinstance(v, float) for v in value) else None),
            )
        else:
            set_attr(obj, key, value)


def put_attrs(
    obj: h5py.HLObject, kind: str, attrs: Mapping[str, Any], *, dynamic: Mapping[str, Any] | None = None
) -> None:
    """Set the attributes `attrs` of an object of `kind` (a key of `attrs.ATTRIBUTES`) and the per-campaign
    ones in `dynamic` (only for a kind of `attrs.DYNAMIC`); a name the layout does not give that kind of
    object is a bug, refused before anything is written."""
    unknown = sorted(set(attrs) - set(ATTRIBUTES[kind]))
    if unknown or (dynamic and kind not in DYNAMIC):
        raise ValueError(f"archive layout: a {kind} has no attribute {', '.join(unknown) or 'per campaign'}")
    set_attrs(obj, attrs)
    if dynamic:
        set_attrs(obj, dynamic)


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
