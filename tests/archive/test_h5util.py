"""`archive.h5util.put`: the storage rules of docs/archive.md (units attribute, standard gzip filter that
h5py, HDFView and MATLAB read without plug-ins, values stored exactly in the requested dtype)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from protocol_runner.archive.h5util import CHUNK_BYTES, COMPRESS_ABOVE, SIGNAL, put
from protocol_runner.hardware.conversions import ai12_code_to_volts, volts_to_angle


def _write_and_read(tmp_path: Path, arrays: dict[str, tuple[np.ndarray, np.dtype | None]]) -> Path:
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        for name, (arr, dtype) in arrays.items():
            put(f, name, arr, "1", dtype=dtype)
    return path


def test_large_datasets_use_only_standard_filters_and_round_trip_exactly(tmp_path: Path) -> None:
    """Every large dataset is byte-shuffled then gzip-compressed (HDF5 filters 2 and 1), nothing else;
    reading gives back exactly the values written in the requested dtype, with their units."""
    rng = np.random.default_rng(0)
    codes = rng.integers(-2048, 2048, 65_000).astype(np.int32)
    angle_deg = volts_to_angle(ai12_code_to_volts(codes), (0.0, 130.0))  # a converted 12-bit signal
    smooth = np.cumsum(rng.standard_normal(65_000))  # a filtered, continuous signal
    time_s = 0.0005 + np.arange(65_000) / 1000.0
    arrays: dict[str, tuple[np.ndarray, np.dtype | None]] = {
        "codes": (codes, np.dtype(np.int32)),
        "angle_deg": (angle_deg, np.dtype(SIGNAL)),
        "smooth": (smooth, np.dtype(SIGNAL)),
        "time_s": (time_s, None),
        "table": (rng.standard_normal((400, 3)), None),
    }
    path = _write_and_read(tmp_path, arrays)
    with h5py.File(path, "r") as f:
        for name, (arr, dtype) in arrays.items():
            ds = f[name]
            assert ds.compression == "gzip"
            assert _filter_ids(ds) == [h5py.h5z.FILTER_SHUFFLE, h5py.h5z.FILTER_DEFLATE]
            expected = np.asarray(arr, dtype=dtype) if dtype is not None else arr
            assert ds.dtype == expected.dtype
            assert np.array_equal(ds[()], expected)
            assert ds.attrs["units"] == "1"
            if ds.ndim == 1:
                assert ds.chunks is not None and ds.chunks[0] * ds.dtype.itemsize <= CHUNK_BYTES


def _filter_ids(ds: h5py.Dataset) -> list[int]:
    plist = ds.id.get_create_plist()
    return [plist.get_filter(i)[0] for i in range(plist.get_nfilters())]


def test_small_datasets_are_stored_contiguous(tmp_path: Path) -> None:
    """Up to COMPRESS_ABOVE elements a dataset is not worth a filter (or a chunk index)."""
    path = _write_and_read(tmp_path, {"small": (np.arange(COMPRESS_ABOVE, dtype=np.float64), None)})
    with h5py.File(path, "r") as f:
        assert f["small"].compression is None and f["small"].chunks is None
