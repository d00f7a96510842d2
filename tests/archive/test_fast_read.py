"""`archive.fast_read.read_values`: the archive's chunked arrays decoded by ISA-L give exactly what HDF5's own
filter pipeline gives; every layout it does not fully understand is left to HDF5."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive import fast_read
from protocol_runner.archive.fast_read import read_values
from protocol_runner.archive.h5util import CHUNK_BYTES, SIGNAL, put


def _same(ds: h5py.Dataset) -> None:
    expected = ds[()]
    got = read_values(ds)
    assert got.dtype == expected.dtype and got.shape == expected.shape
    assert np.array_equal(got, expected, equal_nan=True)


def test_the_archives_own_chunks_are_decoded_here_to_exactly_hdf5s_values(tmp_path: Path) -> None:
    """Shuffled and unshuffled chunks of every stored type, a partial last chunk included, whether `put`
    deflated them (ISA-L) or HDF5 did (zlib): decoded by this module (not handed to HDF5), to the same
    values and dtype."""
    rng = np.random.default_rng(4)
    n = 3 * (CHUNK_BYTES // 4) + 321
    codes = (1500 * np.sin(np.arange(n) / 700.0) + rng.normal(0.0, 3.0, n)).round().astype(np.int32)
    arrays = {
        "codes": (codes, np.dtype(np.int32)),
        "converted": (codes * (20.0 / 4096), np.dtype(SIGNAL)),  # unshuffled when that deflates smaller
        "smooth": (np.cumsum(rng.standard_normal(n)), np.dtype(SIGNAL)),
        "time_s": (0.0005 + np.arange(n) / 1000.0, None),
        "segment": (np.repeat(np.arange(5, dtype=np.int8), n // 5 + 1)[:n], np.dtype(np.int8)),
    }
    path = tmp_path / "u.h5"
    with h5py.File(path, "w") as f:
        for name, (values, dtype) in arrays.items():
            put(f, name, values, "1", dtype=dtype)
        for shuffle in (False, True):
            f.create_dataset(
                f"hdf5_{shuffle}",
                data=arrays["smooth"][0],
                chunks=(1000,),
                compression="gzip",
                shuffle=shuffle,
            )
    with h5py.File(path, "r") as f:
        shuffled = {name: fast_read._decodable(f[name]) for name in f}
        assert all(v is not None for v in shuffled.values())  # every one decoded here
        assert shuffled["hdf5_True"] and not shuffled["hdf5_False"] and shuffled["codes"]
        for name in f:
            _same(f[name])


def test_layouts_it_does_not_fully_understand_are_read_by_hdf5(tmp_path: Path) -> None:
    """Contiguous, uncompressed chunks, a checksum filter, big-endian, 2-D, empty and never-written chunks:
    not decoded here, and still exactly what HDF5 reads."""
    values = np.linspace(-3.0, 7.0, 20_000)
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("contiguous", data=values)
        f.create_dataset("plain_chunks", data=values, chunks=(1000,))
        f.create_dataset("fletcher", data=values, chunks=(1000,), compression="gzip", fletcher32=True)
        f.create_dataset("big_endian", data=values.astype(">f8"), chunks=(1000,), compression="gzip")
        f.create_dataset("two_d", data=values.reshape(200, 100), chunks=(50, 100), compression="gzip")
        f.create_dataset("empty", shape=(0,), maxshape=(None,), dtype="f8", chunks=(10,), compression="gzip")
        holes = f.create_dataset("holes", shape=(5000,), dtype="f8", chunks=(1000,), compression="gzip")
        holes[2000:3000] = 1.5  # the other chunks are never written: they read as the fill value
    with h5py.File(path, "r") as f:
        for name in ("contiguous", "plain_chunks", "fletcher", "big_endian", "two_d", "empty"):
            assert fast_read._decodable(f[name]) is None, name
            _same(f[name])
        assert fast_read._decodable(f["holes"]) is False  # readable in principle, but a chunk is missing
        _same(f["holes"])


def test_a_damaged_chunk_fails_as_hdf5_fails(tmp_path: Path) -> None:
    """A chunk whose stream is not deflate: the reader does not make up values; HDF5's own error stands."""
    path = tmp_path / "bad.h5"
    with h5py.File(path, "w") as f:
        ds = f.create_dataset("x", shape=(2000,), dtype="f8", chunks=(1000,), compression="gzip")
        ds[:] = 1.0
        ds.id.write_direct_chunk((1000,), b"not a deflate stream", filter_mask=0)
    with h5py.File(path, "r") as f, pytest.raises(OSError):
        read_values(f["x"])


def _unit(path: Path, values: np.ndarray) -> None:
    """A unit's way of writing: a new file renamed over the old one (a new inode)."""
    tmp = path.with_suffix(".tmp")
    with h5py.File(tmp, "w") as f:
        put(f, "angle_deg", values, "deg")
        put(f, "torque_nm", -values, "N*m")
    tmp.replace(path)


def test_within_reads_kept_a_dataset_is_decoded_once_and_each_reader_gets_its_own_copy(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    decoded: list[str] = []
    read = fast_read._read
    monkeypatch.setattr(fast_read, "_read", lambda ds: (decoded.append(ds.name), read(ds))[1])
    values = np.cumsum(np.random.default_rng(5).standard_normal(50_000))
    path = tmp_path / "unit.h5"
    _unit(path, values)
    with fast_read.reads_kept():
        with h5py.File(path, "r") as f:
            first = read_values(f["angle_deg"])
            first[:] = 0.0  # a reader changing its values changes no one else's
            torque = read_values(f["torque_nm"])
        with h5py.File(path, "r") as f:  # opened again, as the figures open the units again
            again = read_values(f["angle_deg"])
        assert decoded == ["/angle_deg", "/torque_nm"]
        assert np.array_equal(again, values) and np.array_equal(torque, -values)
        _unit(path, 2.0 * values)  # rewritten: another file, read anew
        with h5py.File(path, "r") as f:
            assert np.array_equal(read_values(f["angle_deg"]), 2.0 * values)
        assert decoded == ["/angle_deg", "/torque_nm", "/angle_deg"]
    with h5py.File(path, "r") as f:  # outside: nothing kept
        read_values(f["angle_deg"])
        read_values(f["angle_deg"])
    assert decoded.count("/angle_deg") == 4


def test_reads_kept_hold_at_most_their_budget(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Values beyond `KEPT_BYTES` are decoded again rather than held."""
    decoded: list[str] = []
    read = fast_read._read
    monkeypatch.setattr(fast_read, "_read", lambda ds: (decoded.append(ds.name), read(ds))[1])
    values = np.arange(50_000, dtype=np.float64)
    monkeypatch.setattr(fast_read, "KEPT_BYTES", values.nbytes + 1)  # room for one of the two arrays
    path = tmp_path / "unit.h5"
    _unit(path, values)
    with fast_read.reads_kept(), h5py.File(path, "r") as f:
        for _ in range(3):
            assert np.array_equal(read_values(f["angle_deg"]), values)
            assert np.array_equal(read_values(f["torque_nm"]), -values)
    assert decoded == ["/angle_deg", "/torque_nm", "/torque_nm", "/torque_nm"]
