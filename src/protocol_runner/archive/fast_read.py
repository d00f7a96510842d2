"""Reading a whole 1-D dataset of the archive's own layout faster than HDF5's filter pipeline (issue 20).

The archive's long 1-D arrays (archive/h5util.py) are stored in chunks, byte-shuffled or not, then deflated:
HDF5's standard filters 2 and 1. HDF5 decodes each chunk with zlib's inflate; `read_values` instead takes
the stored chunks as they are (`read_direct_chunk`) and inflates them with Intel's ISA-L (the `isal`
package, about twice as fast as zlib on these streams), then undoes the shuffle with numpy. It is the same
decoding of the same standard format, so the values are exactly those `dataset[()]` gives; measured on the
knee dry run's 40 largest units (88 MB of arrays), reading them all takes 0.16 s of CPU instead of 0.26 s.

Only a dataset whose layout it fully understands is read this way: chunked, 1-D, a native little-endian
integer or float type, and a filter pipeline of exactly deflate or shuffle-then-deflate, with every chunk
stored and none of its filters skipped. Anything else (another writer's file, a missing chunk, a
checksum filter) is read by HDF5 itself, as is any chunk this reader cannot decode.

Within `reads_kept()` each dataset is decoded once: an analysis worker's task (`session/workers.py`)
processes a configuration, fits it and draws its figures, and the figures read the trials' recordings the
processing has just read (about 0.16 s of decoding per knee dry run). A dataset is known by its file (device,
inode, size and modification time: a unit is written anew under a new inode, never changed in place) and
its place in the file; each reader gets its own copy of the values.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt
from isal import isal_zlib

_SHUFFLE = h5py.h5z.FILTER_SHUFFLE
_DEFLATE = h5py.h5z.FILTER_DEFLATE


_Key = tuple[int, int, int, int, int]  # device, inode, size, modification time (ns), address in the file
_kept: dict[_Key, npt.NDArray[Any]] | None = None
_kept_bytes = 0
KEPT_BYTES = 256 * 2**20
"""The most `reads_kept` keeps (a knee configuration's task reads about 40 MB; a configuration of many
joints reads more): beyond it, values are decoded again rather than held."""


@contextlib.contextmanager
def reads_kept() -> Iterator[None]:
    """Within: a dataset read again is not decoded again (module notes). For files that do not change
    meanwhile (units); what was kept is let go at the end."""
    global _kept, _kept_bytes
    outer = _kept
    if outer is None:
        _kept, _kept_bytes = {}, 0
    try:
        yield
    finally:
        if outer is None:
            _kept, _kept_bytes = None, 0


def read_values(ds: h5py.Dataset) -> npt.NDArray[Any]:
    """Every value of `ds`, as `ds[()]` gives them (see the module notes for when it decodes itself)."""
    global _kept_bytes
    kept = _kept
    if kept is None:
        return _read(ds)
    key = _key(ds)
    values = kept.get(key) if key is not None else None
    if values is None:
        values = _read(ds)
        if key is None or _kept_bytes + values.nbytes > KEPT_BYTES:
            return values
        kept[key] = values
        _kept_bytes += values.nbytes
    return values.copy()


def _key(ds: h5py.Dataset) -> _Key | None:
    try:
        st = os.fstat(ds.file.id.get_vfd_handle())
        return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, h5py.h5o.get_info(ds.id).addr)
    except Exception:  # a file without a POSIX handle (in memory, another driver): not kept
        return None


def _read(ds: h5py.Dataset) -> npt.NDArray[Any]:
    shuffled = _decodable(ds)
    if shuffled is None:
        return np.asarray(ds[()])
    try:
        return _decoded(ds, shuffled)
    except Exception:  # a chunk this decoder cannot read (missing, damaged): HDF5 reads it, or says why not
        return np.asarray(ds[()])


def _decodable(ds: h5py.Dataset) -> bool | None:
    """Whether the chunks are shuffled (True) or not (False) when this module can decode `ds`; else None."""
    dtype = ds.dtype
    if ds.ndim != 1 or ds.chunks is None or dtype.kind not in "iuf" or not dtype.isnative:
        return None
    if sys.byteorder != "little" or ds.shape[0] == 0:
        return None
    plist = ds.id.get_create_plist()
    filters = [plist.get_filter(k)[0] for k in range(plist.get_nfilters())]
    if filters == [_DEFLATE]:
        return False
    if filters == [_SHUFFLE, _DEFLATE]:
        return True
    return None


def _decoded(ds: h5py.Dataset, shuffled: bool) -> npt.NDArray[Any]:
    n = ds.shape[0]
    per_chunk = ds.chunks[0]
    dtype = ds.dtype
    size = dtype.itemsize
    out = np.empty(n, dtype=dtype)
    out_bytes = out.view(np.uint8)
    for start in range(0, n, per_chunk):
        mask, stored = ds.id.read_direct_chunk((start,))
        if mask != 0:
            raise ValueError("a filter was skipped for this chunk")
        raw = isal_zlib.decompress(stored)
        if len(raw) != per_chunk * size:
            raise ValueError("a chunk of unexpected size")
        count = min(per_chunk, n - start)
        block = np.frombuffer(raw, dtype=np.uint8)
        target = out_bytes[start * size : (start + count) * size].reshape(count, size)
        if shuffled:
            target[:] = block.reshape(size, per_chunk).T[:count]
        else:
            target[:] = block[: count * size].reshape(count, size)
    return out
