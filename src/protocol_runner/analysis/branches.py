"""Loading and unloading branches of a cyclic angle signal (thesis §3.3 equal-angle subtraction).

"The same angle" means the same angle on the same branch: loading (angle increasing, +1) or unloading
(decreasing, -1). Turning points come from a zig-zag detector: an extremum is confirmed once the angle has
moved `reversal_deg` back from it, so noise below the threshold never splits a branch (docs/analysis.md
"4. Equal-angle subtraction").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length

LOADING = 1
UNLOADING = -1
Outside = Literal["clip", "nan"]


def turning_points(angle_deg: npt.ArrayLike, reversal_deg: float = 1.0) -> npt.NDArray[np.int64]:
    """Indices of the confirmed extrema of `angle_deg` (the angle later moves back `reversal_deg` from
    them), alternating maxima and minima in time order; never the first or last sample."""
    x = as_signal("angle_deg", angle_deg)
    if not reversal_deg > 0:
        raise AnalysisError(f"branch reversal threshold must be positive, got {reversal_deg} deg")
    n = x.shape[0]
    if n < 3:
        return np.zeros(0, dtype=np.int64)
    # Between consecutive local extrema the signal is monotone, so the zig-zag walk only needs to visit
    # local extrema (inclusive, so plateaus are kept) and the two end samples.
    inner = np.flatnonzero(
        ((x[1:-1] >= x[:-2]) & (x[1:-1] >= x[2:])) | ((x[1:-1] <= x[:-2]) & (x[1:-1] <= x[2:]))
    )
    candidates = np.concatenate(([0], inner + 1, [n - 1]))
    values = x[candidates].tolist()
    found: list[int] = []
    direction = 0  # +1 rising, -1 falling, 0 not yet known
    hi_i = lo_i = 0
    hi = lo = values[0]
    for k in range(1, len(values)):
        v = values[k]
        if direction >= 0 and v > hi:
            hi, hi_i = v, k
        if direction <= 0 and v < lo:
            lo, lo_i = v, k
        if direction >= 0 and hi - v >= reversal_deg:
            if direction == 1:
                found.append(int(candidates[hi_i]))
            direction = -1
            lo, lo_i = v, k
        elif direction <= 0 and v - lo >= reversal_deg:
            if direction == -1:
                found.append(int(candidates[lo_i]))
            direction = 1
            hi, hi_i = v, k
    return np.asarray(found, dtype=np.int64)


def branch_labels(angle_deg: npt.ArrayLike, reversal_deg: float = 1.0) -> npt.NDArray[np.int8]:
    """Per-sample branch: +1 loading (angle increasing), -1 unloading (decreasing).

    A turning point belongs to the branch that ends there. Samples before the first turning point take
    the opposite branch of that turning point (rising into a maximum is loading), samples after the last
    the branch leaving it. A signal with no reversal of at least `reversal_deg` is labelled by its net
    direction.
    """
    x = as_signal("angle_deg", angle_deg)
    turns = turning_points(x, reversal_deg)
    labels = np.empty(x.shape[0], dtype=np.int8)
    if turns.size == 0:
        labels[:] = LOADING if x[-1] >= x[0] else UNLOADING
        return labels
    # direction of the segment that ends at the first turning point
    first_is_max = x[turns[0]] >= x[0]
    current = LOADING if first_is_max else UNLOADING
    start = 0
    for t in turns.tolist():
        labels[start : t + 1] = current
        current = -current
        start = t + 1
    labels[start:] = current
    return labels


def complete_branches(angle_deg: npt.ArrayLike, reversal_deg: float = 1.0) -> slice:
    """The samples from a trial's first confirmed turning point to its last (all with fewer than two),
    leaving out the start-up and the stop. Label the branches on the whole trial before taking this part:
    labelled on its own, its first sample (a turning point) would change branch.
    """
    turns = turning_points(angle_deg, reversal_deg)
    if turns.size < 2:
        return slice(None)
    return slice(int(turns[0]), int(turns[-1]) + 1)


@dataclass(frozen=True)
class BranchCurves:
    """Angle -> torque relations of a cyclic trial, one per branch (binned means over all its cycles)."""

    loading_angle_deg: FloatArray
    loading_torque_nm: FloatArray
    unloading_angle_deg: FloatArray
    unloading_torque_nm: FloatArray

    def torque_at(
        self, angle_deg: npt.ArrayLike, branch: npt.ArrayLike, outside: Outside = "clip"
    ) -> FloatArray:
        """Torque at each (angle, branch) by linear interpolation along that branch's curve; outside its
        covered range, the torque at its nearest end (`outside="clip"`) or NaN (`"nan"`)."""
        a = as_signal("angle_deg", angle_deg)
        b = np.asarray(branch)
        if b.shape != a.shape:
            raise AnalysisError(f"branch labels ({b.shape}) must match the angles ({a.shape})")
        if outside not in ("clip", "nan"):
            raise AnalysisError(f"unknown out-of-range rule {outside!r}: use 'clip' or 'nan'")
        out = np.empty_like(a)
        for label, xs, ys in (
            (LOADING, self.loading_angle_deg, self.loading_torque_nm),
            (UNLOADING, self.unloading_angle_deg, self.unloading_torque_nm),
        ):
            mask = b == label
            if outside == "nan":
                out[mask] = np.interp(a[mask], xs, ys, left=np.nan, right=np.nan)
            else:
                out[mask] = np.interp(a[mask], xs, ys)
        return out

    def covers(self, angle_deg: npt.ArrayLike, branch: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """True where the angle lies inside the covered range of its branch's curve."""
        a = np.asarray(angle_deg, dtype=np.float64)
        b = np.asarray(branch)
        inside = np.zeros(a.shape, dtype=bool)
        for label, xs in ((LOADING, self.loading_angle_deg), (UNLOADING, self.unloading_angle_deg)):
            mask = b == label
            inside[mask] = (a[mask] >= xs[0]) & (a[mask] <= xs[-1])
        return inside


def _binned_curve(
    angle: FloatArray, torque: FloatArray, bin_width_deg: float
) -> tuple[FloatArray, FloatArray]:
    """Mean angle and torque of the samples in each occupied angle bin, in increasing angle order."""
    bins = np.floor(angle / bin_width_deg).astype(np.int64)
    _, inverse, counts = np.unique(bins, return_inverse=True, return_counts=True)
    mean_angle = np.bincount(inverse, weights=angle) / counts
    mean_torque = np.bincount(inverse, weights=torque) / counts
    return mean_angle, mean_torque


def branch_curves(
    angle_deg: npt.ArrayLike,
    torque_nm: npt.ArrayLike,
    *,
    bin_width_deg: float = 0.5,
    reversal_deg: float = 1.0,
    labels: npt.ArrayLike | None = None,
) -> BranchCurves:
    """Per-branch angle -> torque curves of a multi-cycle trial: samples split by branch (`branch_labels`
    or the given `labels`), one point per `bin_width_deg` angle bin (mean angle and mean torque over all
    cycles). Raises `AnalysisError` when a branch has fewer than two bins.
    """
    a = as_signal("angle_deg", angle_deg)
    t = as_signal("torque_nm", torque_nm)
    same_length(angle_deg=a, torque_nm=t)
    if not bin_width_deg > 0:
        raise AnalysisError(f"angle bin width must be positive, got {bin_width_deg} deg")
    lab = branch_labels(a, reversal_deg) if labels is None else np.asarray(labels)
    curves: list[tuple[FloatArray, FloatArray]] = []
    for label, name in ((LOADING, "loading"), (UNLOADING, "unloading")):
        mask = lab == label
        xs, ys = _binned_curve(a[mask], t[mask], bin_width_deg)
        if xs.shape[0] < 2:
            raise AnalysisError(
                f"the trial has no usable {name} branch (angle {'increasing' if label > 0 else 'decreasing'}"
                f" over at least two {bin_width_deg} deg bins): it cannot serve as a reference"
            )
        curves.append((xs, ys))
    return BranchCurves(curves[0][0], curves[0][1], curves[1][0], curves[1][1])
