"""Zero-phase low-pass filtering of angle and torque (thesis §3.2, §4.4; docs/analysis.md "2. Filters").

Second-order sections (sound at order 10, where the transfer-function form is not), applied forward and
backward (`sosfiltfilt`, odd padding): no phase lag between angle and torque, which the equal-angle
subtraction and the loops depend on; the magnitude response is squared (-3 dB of one pass becomes -6 dB).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy import signal

from protocol_runner.analysis.processing_settings import FILTER_KINDS, FilterKind
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal


def design_lowpass(
    kind: FilterKind = "butterworth",
    order: int = 10,
    cutoff: float = 0.1,
    ripple_db: float = 0.5,
) -> FloatArray:
    """Second-order sections of a digital low-pass filter with unit DC gain (thesis §3.2).

    `cutoff` is a fraction of the Nyquist frequency in (0, 1) (thesis: 0.1); `ripple_db` is the Chebyshev
    type I pass-band ripple (ignored for Butterworth). Raises `AnalysisError` for an unknown kind, order < 1,
    a cut-off outside (0, 1) or a non-positive ripple. Each design is made once per process and handed out
    as a new array."""
    return np.array(_designed(kind, order, cutoff, ripple_db))


@functools.lru_cache(maxsize=64)
def _designed(kind: FilterKind, order: int, cutoff: float, ripple_db: float) -> FloatArray:
    """`design_lowpass`'s sections, made once per set of arguments and kept read-only."""
    if kind not in FILTER_KINDS:
        raise AnalysisError(f"unknown filter kind {kind!r}: use one of {', '.join(FILTER_KINDS)}")
    if isinstance(order, bool) or int(order) != order or order < 1:
        raise AnalysisError(f"filter order must be a whole number >= 1, got {order}")
    if not 0.0 < cutoff < 1.0:
        raise AnalysisError(
            f"filter cut-off must be a fraction of the Nyquist frequency strictly between 0 and 1 "
            f"(thesis: 0.1), got {cutoff}"
        )
    if kind == "butterworth":
        sos = signal.butter(int(order), cutoff, btype="lowpass", output="sos")
    else:
        if not ripple_db > 0:
            raise AnalysisError(f"Chebyshev pass-band ripple must be positive (dB), got {ripple_db}")
        sos = signal.cheby1(int(order), ripple_db, cutoff, btype="lowpass", output="sos")
    sections = np.array(sos, dtype=np.float64)
    # Unit DC gain: an even-order Chebyshev type I sits at the bottom of its ripple at DC (gain
    # 10^(-ripple/20)); a constant torque must pass unchanged, so the first section is rescaled.
    dc_gain = float(np.prod(sections[:, :3].sum(axis=1) / sections[:, 3:].sum(axis=1)))
    sections[0, :3] /= dc_gain
    sections.flags.writeable = False
    return sections


def padding_length(sos: npt.ArrayLike) -> int:
    """Samples of odd extension added at each end by the zero-phase filter (3 x (2 x sections + 1)); a
    signal must be longer than this to be filtered."""
    return 3 * (2 * np.atleast_2d(np.asarray(sos)).shape[0] + 1)


def filter_zero_phase(values: npt.ArrayLike, sos: npt.ArrayLike, *, name: str = "signal") -> FloatArray:
    """Apply the filter `sos` forward and backward: zero phase lag, unit DC gain (thesis §3.2)."""
    return filter_zero_phase_together([values], sos, names=[name])[0]


def filter_zero_phase_together(
    signals: Sequence[npt.ArrayLike], sos: npt.ArrayLike, *, names: Sequence[str]
) -> list[FloatArray]:
    """`filter_zero_phase` of several signals of one length (a trial's angle and torque), each checked
    before any is filtered; each result is C-contiguous float64."""
    xs = [as_signal(name, values) for name, values in zip(names, signals, strict=True)]
    sections = np.ascontiguousarray(np.atleast_2d(np.asarray(sos, dtype=np.float64)))
    if sections.ndim != 2 or sections.shape[1] != 6:
        raise AnalysisError(
            f"a filter must be second-order sections (rows b0 b1 b2 1 a1 a2), got shape {sections.shape}"
        )
    if not np.all(sections[:, 3] == 1.0):
        k = int(np.flatnonzero(sections[:, 3] != 1.0)[0])
        raise AnalysisError(
            f"a filter's sections must have a0 = 1 (rows b0 b1 b2 1 a1 a2); section {k} has {sections[k, 3]}"
        )
    pad = padding_length(sections)
    for name, x in zip(names, xs, strict=True):
        if x.shape[0] <= pad:
            raise AnalysisError(
                f"{name}: {x.shape[0]} samples are too few for this filter (it pads {pad} samples at each "
                "end); use a lower filter order or a longer trial"
            )
    if len({x.shape[0] for x in xs}) > 1:
        raise AnalysisError(f"{', '.join(names)} must have the same length to be filtered together")
    return [np.ascontiguousarray(signal.sosfiltfilt(sections, x, padtype="odd", padlen=pad)) for x in xs]


def lowpass(
    values: npt.ArrayLike,
    *,
    kind: FilterKind = "butterworth",
    order: int = 10,
    cutoff: float = 0.1,
    ripple_db: float = 0.5,
    name: str = "signal",
) -> FloatArray:
    """Design (`design_lowpass`) and apply (`filter_zero_phase`) a zero-phase low-pass filter."""
    return filter_zero_phase(values, design_lowpass(kind, order, cutoff, ripple_db), name=name)
