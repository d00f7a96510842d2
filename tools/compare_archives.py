"""Compare two archives (or two session directories) value by value.

    python tools/compare_archives.py A B [--ignore-attr NAME ...] [--rtol R]

Walks every group and dataset of both archives and reports each path that exists in one only, each
dataset whose shape, dtype or values differ, and each attribute that differs. Wall-clock attributes
(names ending in `_utc`, the same keys inside JSON event rows, `wall_s`, the software version and durations measured on the machine) are
ignored, because a rerun of the same seeded campaign cannot reproduce them; so are the `sha256`
attributes of datasets whose values are equal (compression or chunking may legitimately differ).
Values are compared exactly (NaN equals NaN) unless `--rtol` is given.

Exit 0 when the archives hold the same values, 1 when they differ, 2 on a usage error. Used to show
that a refactoring changes no recorded or computed number.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import h5py
import numpy as np

WALL_CLOCK_SUFFIXES = ("_utc", "wall_s", "_wall_s", "elapsed_s")
WALL_CLOCK_NAMES = {"software_version", "sha256"}


def _archive_path(path: Path) -> Path:
    return path / "archive.h5" if path.is_dir() else path


def _collect(f: h5py.File) -> dict[str, h5py.Dataset | h5py.Group]:
    items: dict[str, Any] = {"/": f}
    f.visititems(lambda name, obj: items.__setitem__(name, obj))
    return items


def _ignored(name: str, extra: set[str]) -> bool:
    return name in extra or name in WALL_CLOCK_NAMES or name.endswith(WALL_CLOCK_SUFFIXES)


def _without_wall_clock(value: Any) -> Any:
    """A JSON-object string with its wall-clock keys removed (event rows carry their time)."""
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if isinstance(value, str) and value.startswith("{"):
        try:
            obj = json.loads(value)
        except ValueError:
            return value
        if isinstance(obj, dict):
            return json.dumps({k: v for k, v in obj.items() if not k.endswith(WALL_CLOCK_SUFFIXES)})
    return value


def _equal(a: Any, b: Any, rtol: float) -> bool:
    if isinstance(a, np.ndarray) and a.dtype.kind in "SOU":
        a = np.array([_without_wall_clock(v) for v in a.ravel()]).reshape(a.shape)
    if isinstance(b, np.ndarray) and b.dtype.kind in "SOU":
        b = np.array([_without_wall_clock(v) for v in b.ravel()]).reshape(b.shape)
    if isinstance(a, bytes):
        a = a.decode("utf-8", "replace")
    if isinstance(b, bytes):
        b = b.decode("utf-8", "replace")
    a_arr, b_arr = np.asarray(a), np.asarray(b)
    if a_arr.shape != b_arr.shape:
        return False
    if a_arr.dtype.kind in "fc" and b_arr.dtype.kind in "fc":
        if rtol > 0:
            return bool(np.allclose(a_arr, b_arr, rtol=rtol, atol=0.0, equal_nan=True))
        return bool(np.array_equal(a_arr, b_arr, equal_nan=True))
    if a_arr.dtype.kind in "iub" and b_arr.dtype.kind in "iubfc":
        return bool(np.array_equal(a_arr, b_arr))
    return bool(np.array_equal(a_arr.astype(str), b_arr.astype(str)))


def compare(a_path: Path, b_path: Path, ignore: set[str], rtol: float = 0.0) -> list[str]:
    """Every difference between the two archives, one line each (empty when they agree)."""
    out: list[str] = []
    with h5py.File(a_path, "r") as fa, h5py.File(b_path, "r") as fb:
        ia, ib = _collect(fa), _collect(fb)
        for name in sorted(set(ia) - set(ib)):
            out.append(f"only in A: {name}")
        for name in sorted(set(ib) - set(ia)):
            out.append(f"only in B: {name}")
        for name in sorted(set(ia) & set(ib)):
            oa, ob = ia[name], ib[name]
            if isinstance(oa, h5py.Dataset) != isinstance(ob, h5py.Dataset):
                out.append(f"kind differs: {name}")
                continue
            if isinstance(oa, h5py.Dataset):
                assert isinstance(ob, h5py.Dataset)
                if oa.shape != ob.shape:
                    out.append(f"shape differs: {name} {oa.shape} vs {ob.shape}")
                elif not _equal(oa[()], ob[()], rtol):
                    out.append(f"values differ: {name}")
            for key in sorted(set(oa.attrs) | set(ob.attrs)):
                if _ignored(key, ignore):
                    continue
                if key not in oa.attrs or key not in ob.attrs:
                    side = "A" if key in oa.attrs else "B"
                    out.append(f"attribute only in {side}: {name} @{key}")
                elif not _equal(oa.attrs[key], ob.attrs[key], rtol):
                    out.append(f"attribute differs: {name} @{key}: {oa.attrs[key]!r} vs {ob.attrs[key]!r}")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    parser.add_argument("--ignore-attr", action="append", default=[], help="an attribute name to ignore")
    parser.add_argument("--rtol", type=float, default=0.0, help="relative tolerance for floats (default exact)")
    args = parser.parse_args(argv)
    a, b = _archive_path(args.a), _archive_path(args.b)
    for p in (a, b):
        if not p.is_file():
            print(f"error: {p} is not an archive", file=sys.stderr)
            return 2
    diffs = compare(a, b, set(args.ignore_attr), args.rtol)
    for line in diffs:
        print(line)
    print(f"{len(diffs)} differences" if diffs else "same values")
    return 1 if diffs else 0


if __name__ == "__main__":
    raise SystemExit(main())
