"""`archive.h5util.put`: the storage rules of docs/archive.md (units attribute, standard gzip filter that
h5py, HDFView and MATLAB read without plug-ins, values stored exactly in the requested dtype)."""

from __future__ import annotations

import zlib
from pathlib import Path

import h5py
import numpy as np
from isal import isal_zlib

from protocol_runner.archive.h5util import CHUNK_BYTES, COMPRESS_ABOVE, DEFLATE_LEVEL, SIGNAL, put
from protocol_runner.hardware.conversions import ai12_code_to_volts, volts_to_angle


def _write_and_read(tmp_path: Path, arrays: dict[str, tuple[np.ndarray, np.dtype | None]]) -> Path:
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        for name, (arr, dtype) in arrays.items():
            put(f, name, arr, "1", dtype=dtype)
    return path


def test_large_datasets_use_only_standard_filters_and_round_trip_exactly(tmp_path: Path) -> None:
    """Every large dataset is gzip (deflate, HDF5 filter 1), optionally with shuffle (filter 2), nothing
    else; reading gives back exactly the values written in the requested dtype, with their units."""
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
            filters = set(ds.id.get_create_plist().get_nfilters() and _filter_ids(ds))
            assert filters <= {h5py.h5z.FILTER_DEFLATE, h5py.h5z.FILTER_SHUFFLE}
            expected = np.asarray(arr, dtype=dtype) if dtype is not None else arr
            assert ds.dtype == expected.dtype
            assert np.array_equal(ds[()], expected)
            assert ds.attrs["units"] == "1"
            if ds.ndim == 1:
                assert ds.chunks is not None and ds.chunks[0] * ds.dtype.itemsize <= CHUNK_BYTES


def _filter_ids(ds: h5py.Dataset) -> list[int]:
    plist = ds.id.get_create_plist()
    return [plist.get_filter(i)[0] for i in range(plist.get_nfilters())]


def test_shuffle_is_left_out_only_for_quantised_float_signals(tmp_path: Path) -> None:
    """A float32 signal converted from 12-bit codes (at most 4096 distinct values) deflates better
    unshuffled; integer codes, times and continuous signals keep the byte shuffle."""
    rng = np.random.default_rng(1)
    codes = rng.integers(-2048, 2048, 20_000).astype(np.int32)
    arrays: dict[str, tuple[np.ndarray, np.dtype | None]] = {
        "angle_deg": (volts_to_angle(ai12_code_to_volts(codes), (0.0, 130.0)), np.dtype(SIGNAL)),
        "codes": (codes, np.dtype(np.int32)),
        "smooth": (np.cumsum(rng.standard_normal(20_000)), np.dtype(SIGNAL)),
        "time_s": (np.arange(20_000) / 1000.0, None),
    }
    path = _write_and_read(tmp_path, arrays)
    with h5py.File(path, "r") as f:
        assert not f["angle_deg"].shuffle
        assert f["codes"].shuffle and f["smooth"].shuffle and f["time_s"].shuffle


def test_small_datasets_are_stored_contiguous(tmp_path: Path) -> None:
    """Up to COMPRESS_ABOVE elements a dataset is not worth a filter (or a chunk index)."""
    path = _write_and_read(tmp_path, {"small": (np.arange(COMPRESS_ABOVE, dtype=np.float64), None)})
    with h5py.File(path, "r") as f:
        assert f["small"].compression is None and f["small"].chunks is None


def test_chunks_compressed_here_read_back_through_hdf5s_own_filters(tmp_path: Path) -> None:
    """Multi-chunk datasets are compressed by `put` itself (shuffle, then ISA-L's zlib stream at
    DEFLATE_LEVEL) and written as raw chunks: HDF5 must decode them with its standard filters to exactly
    the written values, including the partial last chunk; every stored chunk is exactly that stream of its
    shuffled (zero-padded) values, and the dataset stays within 10 % of what HDF5's own zlib writes."""
    rng = np.random.default_rng(2)
    per_chunk = CHUNK_BYTES // 8
    n = 3 * per_chunk + 123  # three full float64 chunks and a partial one
    values = np.cumsum(rng.standard_normal(n))
    path = _write_and_read(tmp_path, {"x": (values, None)})
    with h5py.File(path, "r") as f:
        ds = f["x"]
        assert ds.chunks == (per_chunk,) and ds.shuffle and ds.compression == "gzip"
        assert np.array_equal(ds[()], values)
        assert np.array_equal(ds[n - 200 :], values[n - 200 :])  # a read of the partial chunk alone
        for k, raw in enumerate(_shuffled_chunks(values, per_chunk)):
            mask, stored = ds.id.read_direct_chunk((k * per_chunk,))
            assert mask == 0 and stored == isal_zlib.compress(raw, DEFLATE_LEVEL)
            assert zlib.decompress(stored) == raw  # the standard stream, as zlib itself reads it
        stored_size = ds.id.get_storage_size()
    assert stored_size <= 1.10 * _hdf5s_own_size(tmp_path, values, per_chunk)


def test_shuffled_integer_codes_are_deflated_here_and_read_by_hdf5s_own_filters(tmp_path: Path) -> None:
    """Multi-chunk integer datasets (the ADC codes) are shuffled, then deflated like every chunk: each
    stored chunk is ISA-L's stream of its shuffled values, which HDF5's own filter decodes to the written
    codes (partial last chunk included), within 10 % of what HDF5 itself writes at zlib's level 1."""
    rng = np.random.default_rng(3)
    per_chunk = CHUNK_BYTES // 4
    n = 3 * per_chunk + 77
    # a 12-bit ADC's codes of a slow sinusoid plus noise, as a trial records them
    codes = (1500 * np.sin(np.arange(n) / 900.0) + rng.normal(0.0, 3.0, n)).round().astype(np.int32)
    path = _write_and_read(tmp_path, {"codes": (codes, np.dtype(np.int32))})
    with h5py.File(path, "r") as f:
        ds = f["codes"]
        assert ds.shuffle and ds.compression == "gzip" and ds.chunks == (per_chunk,)
        assert np.array_equal(ds[()], codes) and np.array_equal(ds[n - 50 :], codes[n - 50 :])
        for k, raw in enumerate(_shuffled_chunks(codes, per_chunk)):
            mask, stored = ds.id.read_direct_chunk((k * per_chunk,))
            assert mask == 0 and stored == isal_zlib.compress(raw, DEFLATE_LEVEL)
        size = ds.id.get_storage_size()
    assert size <= 1.10 * _hdf5s_own_size(tmp_path, codes, per_chunk)


def _shuffled_chunks(values: np.ndarray, per_chunk: int) -> list[bytes]:
    """Each chunk's bytes as HDF5's shuffle filter hands them to deflate (the last padded with zeros)."""
    n_chunks = -(-values.size // per_chunk)
    padded = np.zeros(n_chunks * per_chunk, dtype=values.dtype)
    padded[: values.size] = values
    size = values.dtype.itemsize
    return [
        padded[k * per_chunk : (k + 1) * per_chunk].view(np.uint8).reshape(-1, size).T.tobytes()
        for k in range(n_chunks)
    ]


def _hdf5s_own_size(tmp_path: Path, values: np.ndarray, per_chunk: int) -> int:
    """The stored size of `values` as HDF5 itself writes them (shuffle, zlib level 1, the same chunks)."""
    with h5py.File(tmp_path / "ref.h5", "w") as f:
        f.create_dataset(
            "x", data=values, chunks=(per_chunk,), compression="gzip", compression_opts=1, shuffle=True
        )
        return int(f["x"].id.get_storage_size())
