"""archive/h5fast.py writes the same bytes as h5py's high-level API (issue 20: a faster writer must not change
what is stored): every attribute and dataset written through it, in a file of its own, against the same
objects written with `obj.attrs[...] = ...` and `create_dataset` in another file, compared byte for byte."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from protocol_runner.archive.h5fast import create_dataset, remove_link, set_attr

ATTRIBUTE_VALUES: dict[str, Any] = {
    "text": "knee_flexion",
    "non_ascii_text": "40 °/s, Δθ",
    "empty_text": "",
    "json": '{"kind": "butterworth", "order": 4}',
    "true": True,
    "numpy_false": np.bool_(False),
    "int": 7,
    "negative_int": -3,
    "int64_max": 2**63 - 1,
    "float": 0.1,
    "nan": float("nan"),
    "float32": np.float32(1.5),
    "int32": np.int32(-12),
    "float_array": np.array([0.0, 130.0]),
    "int_array": np.array([1, 2, 3]),
    "matrix": np.arange(6.0).reshape(2, 3),
    "empty_array": np.zeros(0),
    "bool_array": np.array([True, False]),
    "bytes": b"raw",  # left to h5py
    "string_array": np.array(["a", "bc"], dtype=h5py.string_dtype()),  # left to h5py
    "nonascii_name_é": 1.0,  # left to h5py
}


def _write_both(tmp_path: Path, write_reference: Any, write_fast: Any) -> tuple[bytes, bytes]:
    paths = tmp_path / "reference.h5", tmp_path / "fast.h5"
    for path, write in zip(paths, (write_reference, write_fast), strict=True):
        with h5py.File(path, "w") as f:
            write(f)
    return paths[0].read_bytes(), paths[1].read_bytes()


def test_attributes_are_the_bytes_h5py_writes(tmp_path: Path) -> None:
    def reference(f: h5py.File) -> None:
        g = f.create_group("g")
        for name, value in ATTRIBUTE_VALUES.items():
            g.attrs[name] = value
        g.attrs["text"] = "replaced"  # an attribute written again replaces the first

    def fast(f: h5py.File) -> None:
        g = f.create_group("g")
        for name, value in ATTRIBUTE_VALUES.items():
            set_attr(g, name, value)
        set_attr(g, "text", "replaced")

    ref, new = _write_both(tmp_path, reference, fast)
    assert new == ref
    with h5py.File(tmp_path / "fast.h5", "r") as f:
        attrs = f["g"].attrs
        assert attrs["text"] == "replaced"
        assert attrs["non_ascii_text"] == "40 °/s, Δθ"
        assert attrs["true"].dtype == np.bool_ and bool(attrs["true"])
        assert attrs["int"].dtype == np.int64 and attrs["int"] == 7
        assert attrs["float32"].dtype == np.float32
        assert attrs["matrix"].shape == (2, 3)


DATASETS: list[tuple[str, Any, dict[str, Any]]] = [
    ("contiguous_f8", np.linspace(0.0, 1.0, 200), {}),
    ("scalar", np.float64(2.5), {}),
    ("int8", np.array([0, 1, 2, 3], dtype=np.int8), {}),
    ("bools", np.array([True, False, True]), {}),
    ("matrix", np.arange(12.0).reshape(6, 2), {}),
    ("empty", np.zeros(0, dtype=np.float32), {}),
    ("text", np.array("protocol: 40 °/s\n".encode(), dtype="S"), {}),
    ("lines", np.array([b"a", b"line two"], dtype="S8"), {}),
    ("gzip_shuffled", np.sin(np.arange(5000) / 50.0).astype(np.float32), {"chunk": 3000, "shuffle": True}),
    ("gzip_plain", np.arange(4000, dtype=np.int32) % 97, {"chunk": 4000, "shuffle": False}),
    ("gzip_2d_guessed_chunks", np.ones((300, 2)), {"shuffle": True}),  # left to h5py
    ("unicode_object", np.array(["x"], dtype=h5py.string_dtype()), {}),  # left to h5py
]


@pytest.mark.parametrize("name, data, layout", DATASETS, ids=[d[0] for d in DATASETS])
def test_datasets_are_the_bytes_h5py_writes(
    tmp_path: Path, name: str, data: Any, layout: dict[str, Any]
) -> None:
    arr = np.asarray(data)
    compressed = "shuffle" in layout
    kwargs: dict[str, Any] = {}
    if compressed:
        kwargs = {"compression": "gzip", "compression_opts": 1, "shuffle": layout["shuffle"]}
    if "chunk" in layout:
        kwargs["chunks"] = (layout["chunk"],)

    def reference(f: h5py.File) -> None:
        f.create_group("g").create_dataset(name, data=arr, **kwargs)

    def fast(f: h5py.File) -> None:
        create_dataset(
            f.create_group("g"),
            name,
            arr,
            chunk=layout.get("chunk"),
            shuffle=layout.get("shuffle", False),
            gzip_level=1 if compressed else None,
        )

    ref, new = _write_both(tmp_path, reference, fast)
    assert new == ref
    with h5py.File(tmp_path / "fast.h5", "r") as f:
        ds = f["g"][name]
        assert ds.dtype == arr.dtype and ds.shape == arr.shape
        assert np.array_equal(ds.asstr()[()] if arr.dtype.kind == "O" else ds[()], arr)
        assert ds.compression == ("gzip" if compressed else None)
        assert ds.shuffle == layout.get("shuffle", False)


def test_a_dataset_created_empty_takes_the_values_written_later(tmp_path: Path) -> None:
    arr = np.arange(1000, dtype=np.float64)
    with h5py.File(tmp_path / "late.h5", "w") as f:
        ds = create_dataset(f, "late", arr, chunk=250, shuffle=True, gzip_level=1, write=False)
        assert ds.chunks == (250,) and ds.compression_opts == 1
        assert not ds[()].any()  # nothing written yet: the fill value
        ds[...] = arr
    with h5py.File(tmp_path / "late.h5", "r") as f:
        assert np.array_equal(f["late"][()], arr)


def test_remove_link_removes_a_member_and_ignores_an_absent_one(tmp_path: Path) -> None:
    with h5py.File(tmp_path / "links.h5", "w") as f:
        f.create_dataset("g/x", data=[1.0])
        f.create_dataset("y", data=[2.0])
        remove_link(f["g"], "x")
        remove_link(f, "g/absent")
        remove_link(f, "absent")
        remove_link(f, "y")
        assert "g/x" not in f and "y" not in f and "g" in f
