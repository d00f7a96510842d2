"""Bounds on what a dataset of an archive or unit may declare, checked before any of it is read
(docs/archive.md, "Bounds"): a damaged or hostile file can declare a dataset of 10^12 elements (chunked,
nothing stored: HDF5 fills it in on reading) and make a reader allocate terabytes.
"""

from __future__ import annotations

import json
import math
from typing import Any

import h5py

from ..errors import InvalidInput

MAX_INPUT_RATE_HZ = 50_000
"""The highest input sample rate a protocol may declare (protocol/schema.py, InputSpec.rate_hz)."""
MARGIN_S = 600.0
"""Recording time allowed beyond a step's planned duration: approach, park, transition, settling."""
HARD_CAP = int(3600 * MAX_INPUT_RATE_HZ)
MAX_RANK = 2


def element_cap(f: h5py.File) -> int:
    """The most elements any dataset of `f` may hold, from its `/plan` (MARGIN_S alone without one)."""
    longest = 0.0
    plan = f.get("plan")
    if isinstance(plan, h5py.Dataset) and plan.shape == () and h5py.check_string_dtype(plan.dtype):
        try:
            raw = plan[()]
            steps = json.loads(raw.decode("utf-8") if isinstance(raw, bytes) else str(raw)).get("steps", [])
            longest = max((_duration(s) for s in steps), default=0.0)
        except (ValueError, TypeError, AttributeError, OSError):
            longest = 0.0
    return min(HARD_CAP, math.ceil((longest + MARGIN_S) * MAX_INPUT_RATE_HZ))


def _duration(step: Any) -> float:
    trajectory = step.get("trajectory") if isinstance(step, dict) else None
    if not isinstance(trajectory, dict):
        return 0.0
    value = trajectory.get("duration_s", 0.0)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return 0.0
    return max(0.0, float(value))


def check_layout(ds: h5py.Dataset, cap: int, where: str) -> None:
    """Raise `InvalidInput` naming `where` (file and dataset path) unless `ds` is within the bounds."""
    kind = ds.dtype.kind
    text = h5py.check_string_dtype(ds.dtype) is not None or kind == "S"
    if not text and kind not in "biuf":
        raise InvalidInput(f"{where}: unexpected data type {ds.dtype} (the archive holds numbers and text)")
    shape = ds.shape
    if shape is None or len(shape) > MAX_RANK:
        raise InvalidInput(
            f"{where}: unexpected shape {shape} (the archive holds scalars, 1-D and 2-D arrays)"
        )
    n = math.prod(shape)
    if n > cap:
        raise InvalidInput(
            f"{where}: declares {n} elements, more than the {cap} any step of this archive can record "
            "(damaged or not written by protocol-runner); not read"
        )
    chunks = ds.chunks
    if chunks is not None and math.prod(chunks) > cap:
        raise InvalidInput(
            f"{where}: declares chunks of {math.prod(chunks)} elements, more than {cap}; not read"
        )
