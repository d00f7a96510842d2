"""Identification of complete cycles in a multi-cycle trial (thesis §5.7.1; docs/analysis.md "6. Cycles").

A complete cycle runs from one *upward* crossing of the reference level (the trial's mean angle, or its
linear trend) to the next, counted with hysteresis (a Schmitt trigger) so that noise around the reference
never creates extra cycles; the partial first and last cycles are left out.
"""

from __future__ import annotations

import itertools
from typing import Literal

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal

Reference = Literal["mean", "linear"]

DEFAULT_HYSTERESIS_FRACTION = 0.1


def reference_level(angle_deg: npt.ArrayLike, reference: Reference = "mean") -> FloatArray:
    """The level crossings are counted against: the mean angle, or a least-squares line over the samples."""
    x = as_signal("angle_deg", angle_deg)
    if reference == "mean":
        return np.full_like(x, x.mean())
    if reference == "linear":
        k = np.arange(x.shape[0], dtype=np.float64)
        slope, intercept = np.polyfit(k, x, 1)
        return np.asarray(intercept + slope * k, dtype=np.float64)
    raise AnalysisError(f"unknown cycle reference {reference!r}: use 'mean' or 'linear'")


def upward_crossings(
    angle_deg: npt.ArrayLike,
    *,
    hysteresis_deg: float | None = None,
    reference: Reference = "mean",
) -> npt.NDArray[np.int64]:
    """Per upward crossing (below `reference - hysteresis_deg`, then above `reference + hysteresis_deg`),
    the sample where the angle last passed the reference itself on the way up. `hysteresis_deg=None`: 10 %
    of the 1st-99th percentile range of the angle about the reference (a drift does not inflate it).
    """
    x = as_signal("angle_deg", angle_deg)
    ref = reference_level(x, reference)
    d = x - ref
    if hysteresis_deg is None:
        p1, p99 = np.percentile(d, [1.0, 99.0])
        hysteresis_deg = DEFAULT_HYSTERESIS_FRACTION * float(p99 - p1)
    if hysteresis_deg < 0:
        raise AnalysisError(f"cycle hysteresis must not be negative, got {hysteresis_deg} deg")
    # Schmitt trigger: state -1 (low) once d < -h, +1 (high) once d > +h (d >= 0 when h = 0).
    low = d < -hysteresis_deg if hysteresis_deg > 0 else d < 0
    high = d > hysteresis_deg if hysteresis_deg > 0 else d >= 0
    event = np.zeros(x.shape[0], dtype=np.int8)
    event[low] = -1
    event[high] = 1
    marks = np.flatnonzero(event)
    if marks.size == 0:
        return np.zeros(0, dtype=np.int64)
    states = event[marks]
    # state switches: a high mark right after a low mark is an upward crossing
    switch_up = np.flatnonzero((states[1:] == 1) & (states[:-1] == -1)) + 1
    found: list[int] = []
    for m in switch_up.tolist():
        lo_idx = int(marks[m - 1])
        hi_idx = int(marks[m])
        # last sample in (lo_idx, hi_idx] where the angle passed from below the reference to at/above it
        segment = d[lo_idx : hi_idx + 1]
        up = np.flatnonzero((segment[1:] >= 0) & (segment[:-1] < 0))
        found.append(lo_idx + 1 + int(up[-1]))
    return np.asarray(found, dtype=np.int64)


def complete_cycles(
    angle_deg: npt.ArrayLike,
    *,
    hysteresis_deg: float | None = None,
    reference: Reference = "mean",
) -> list[tuple[int, int]]:
    """(start, stop) of every complete cycle, from one `upward_crossings` index to the next (thesis
    §5.7.1): `angle_deg[start:stop + 1]` holds the cycle, both ends at or just above the reference."""
    ups = upward_crossings(angle_deg, hysteresis_deg=hysteresis_deg, reference=reference)
    return [(int(a), int(b)) for a, b in itertools.pairwise(ups.tolist())]
