"""Compare two archives (or two session directories) value by value.

    python tools/compare_archives.py A B [--ignore-attr NAME ...] [--rtol R] [--as-joints]

Walks every group and dataset of both archives and reports each path that exists in one only, each
dataset whose shape, dtype or values differ, and each attribute that differs. Wall-clock attributes
(names ending in `_utc`, the same keys inside JSON event rows, `wall_s`, the software version and durations measured on the machine) are
ignored, because a rerun of the same seeded campaign cannot reproduce them; so are the `sha256`
attributes of datasets whose values are equal (compression or chunking may legitimately differ).
Values are compared exactly (NaN equals NaN) unless `--rtol` is given.

With `--as-joints`, A is an archive of one joint written before every group was keyed by joint and B one
keyed by joint (docs/archive.md): each path of B is read as the path of A it keys (`joints/<joint>`
removed, `joints/<joint>/trials/<n>/processed` as `trials/<n>/processed`, `total_energy_*` as
`energy_*`), and groups and attributes that only name the joints (`joints`, `joint`) are layout keys; it
prints "same values apart from layout keys" when nothing else differs.

Exit 0 when the archives hold the same values, 1 when they differ, 2 on a usage error. Used to show
that a refactoring changes no recorded or computed number.
"""

from __future__ import annotations

import argparse
import json
import re
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


LAYOUT_ATTRS = {"joints", "joint"}
_PROCESSED = re.compile(r"^(configurations/[^/]+)/joints/[^/]+/trials/([^/]+)/processed")
_JOINT = re.compile(r"/joints/[^/]+(?=/|$)")
_TOTAL = re.compile(r"^(configurations/[^/]+)/total_(energy_loss_j|energy_cycle_trial)$")


def unkey(path: str) -> str:
    """The path of a single-joint archive written before every group was keyed by joint that the
    joint-keyed `path` holds (`joints/<joint>/` removed; a configuration's totals are its one joint's)."""
    path = _TOTAL.sub(r"\1/\2", path)
    path = _PROCESSED.sub(r"\1/trials/\2/processed", path)
    return _JOINT.sub("", path, count=1)


def compare_as_joints(a_path: Path, b_path: Path, ignore: set[str], rtol: float = 0.0) -> list[str]:
    """Every difference between a single-joint archive A of the former layout and B keyed by joint, each
    path of B read as the path of A it keys (`unkey`)."""
    out: list[str] = []
    with h5py.File(a_path, "r") as fa, h5py.File(b_path, "r") as fb:
        ia, ib = _collect(fa), _collect(fb)
        seen: set[str] = set()
        covered: set[tuple[str, str]] = set()
        for name in sorted(ib):
            ob, old = ib[name], unkey(name)
            if old not in ia:
                if not (isinstance(ob, h5py.Group) and name.endswith("/joints")):
                    out.append(f"only in B: {name}")
                continue
            seen.add(old)
            oa = ia[old]
            if isinstance(oa, h5py.Dataset) != isinstance(ob, h5py.Dataset):
                out.append(f"kind differs: {name} (A: {old})")
                continue
            if isinstance(oa, h5py.Dataset):
                assert isinstance(ob, h5py.Dataset)
                if oa.shape != ob.shape:
                    out.append(f"shape differs: {name} {ob.shape} vs A {old} {oa.shape}")
                elif not _equal(oa[()], ob[()], rtol):
                    out.append(f"values differ: {name} (A: {old})")
            for key in sorted(ob.attrs):
                if _ignored(key, ignore):
                    continue
                if key in oa.attrs:
                    covered.add((old, key))
                    if not _equal(oa.attrs[key], ob.attrs[key], rtol):
                        out.append(
                            f"attribute differs: {name} @{key}: {ob.attrs[key]!r} vs A {oa.attrs[key]!r}"
                        )
                elif key not in LAYOUT_ATTRS:
                    out.append(f"attribute only in B: {name} @{key}")
        for name in sorted(set(ia) - seen):
            out.append(f"only in A: {name}")
        for name in sorted(seen):
            for key in sorted(ia[name].attrs):
                if not _ignored(key, ignore) and (name, key) not in covered:
                    out.append(f"attribute only in A: {name} @{key}")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    parser.add_argument("--ignore-attr", action="append", default=[], help="an attribute name to ignore")
    parser.add_argument(
        "--rtol", type=float, default=0.0, help="relative tolerance for floats (default exact)"
    )
    parser.add_argument(
        "--as-joints",
        action="store_true",
        help="A is a single-joint archive of the former layout, B keyed by joint: compare apart from layout keys",
    )
    args = parser.parse_args(argv)
    a, b = _archive_path(args.a), _archive_path(args.b)
    for p in (a, b):
        if not p.is_file():
            print(f"error: {p} is not an archive", file=sys.stderr)
            return 2
    ignore = set(args.ignore_attr) | ({"attribute_sha256"} if args.as_joints else set())
    diffs = (compare_as_joints if args.as_joints else compare)(a, b, ignore, args.rtol)
    for line in diffs:
        print(line)
    same = "same values apart from layout keys" if args.as_joints else "same values"
    print(f"{len(diffs)} differences" if diffs else same)
    return 1 if diffs else 0


if __name__ == "__main__":
    raise SystemExit(main())
