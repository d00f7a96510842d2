"""The smaller copies of a configuration's trials that the Bouc-Wen fit solves on (thesis §6.2.3): every
``stride``-th sample; the full angle path with residuals at every ``stride``-th sample; and the angle's
turning points with residuals at every ``stride``-th sample."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from .params import FloatArray
from .problem import FitScale, Problem, Samples
from .records import BoucWenBounds
from .schemes import REFINED, segment_starts


def decimate(
    segments: list[tuple[FloatArray, FloatArray]], max_samples_per_trial: int | None
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64], tuple[int, ...]]:
    xs: list[FloatArray] = []
    ys: list[FloatArray] = []
    strides: list[int] = []
    for x, y in segments:
        stride = 1 if max_samples_per_trial is None else max(1, math.ceil(x.size / max_samples_per_trial))
        xs.append(x[::stride])
        ys.append(y[::stride])
        strides.append(stride)
    x_all, y_all, seg = _joined(xs, ys)
    return x_all, y_all, seg, tuple(strides)


def _joined(
    xs: list[FloatArray], ys: list[FloatArray]
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int64]]:
    """The trials' samples concatenated, with the segment starts (one more than the trials)."""
    return np.concatenate(xs), np.concatenate(ys), segment_starts(xs)


def _path_problem(
    segments: list[tuple[FloatArray, FloatArray]],
    strides: tuple[int, ...],
    bounds: BoucWenBounds,
    scale: FitScale,
    max_step_deg: float | None,
) -> Problem:
    """Refined-scheme problem on every sample's angle path, residuals at every ``stride``-th sample."""
    x, y, seg, _ = decimate(segments, None)
    rows = np.concatenate(
        [np.arange(seg[k], seg[k + 1], stride, dtype=np.int64) for k, stride in enumerate(strides)]
    )
    return Problem(Samples(x, y, seg, rows), bounds, scale, REFINED, max_step_deg)


def turning_point_copy(segments: list[tuple[FloatArray, FloatArray]], max_samples_per_trial: int) -> Samples:
    """A smaller copy of the trials that integrates along the same angle path: each trial's every
    ``stride``-th sample (as :func:`decimate`), compared with the data, plus every turning point of its
    angle (a sample where the angle stops or changes direction) and its last sample, integrated along only.

    Between turning points the angle is monotonic, so the piecewise-linear path through the kept samples
    visits the same angles in the same directions as the path through every sample: Eq 20's state
    ``dz/dx`` depends on the angle travelled, not on when, so the copy differs from the full path only by
    where the substeps fall.  A copy of every ``stride``-th sample alone cuts the small reversals of a
    noisy angle, each of which switches Psi (Eq 22), and its optimum can lie far from the full one."""
    xs: list[FloatArray] = []
    ys: list[FloatArray] = []
    rows: list[npt.NDArray[np.int64]] = []
    offset = 0
    for x, y in segments:
        stride = max(1, math.ceil(x.size / max_samples_per_trial))
        keep = np.zeros(x.size, dtype=bool)
        keep[::stride] = True
        keep[-1] = True
        d = np.diff(x)
        keep[1:-1] |= d[:-1] * d[1:] <= 0.0
        kept = np.flatnonzero(keep)
        xs.append(x[kept])
        ys.append(y[kept])
        rows.append(offset + np.flatnonzero(kept % stride == 0))
        offset += kept.size
    x_all, y_all, seg = _joined(xs, ys)
    return Samples(x_all, y_all, seg, np.concatenate(rows))
