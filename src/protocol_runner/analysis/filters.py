"""Zero-phase low-pass filtering of angle and torque (thesis §3.2, §4.4).

The thesis offers a Butterworth or a Chebyshev (type I) filter, with user-chosen order and cut-off; the
campaign used a 10th-order Butterworth with a cut-off of 10 % of the Nyquist frequency ("the ratio of the
real cut-off frequency and the maximum frequency of the signal, ½ the sampling frequency", §3.2 note).

Here the filter is designed as second-order sections (numerically sound at order 10, where the
transfer-function form is not) and applied forward and backward (scipy's `sosfiltfilt`, odd padding), so
the filtered signal has no phase lag: angle and torque stay synchronised, which the equal-angle subtraction
and the hysteresis loops depend on. The forward-backward pass squares the magnitude response (the effective
order doubles; the -3 dB point of one pass becomes the -6 dB point).
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
    """Second-order sections of a digital low-pass filter (thesis §3.2).

    `cutoff` is the normalised cut-off: a fraction of the Nyquist frequency, strictly between 0 and 1
    (thesis: 10 % = 0.1). `ripple_db` is the pass-band ripple of the Chebyshev type I filter (ignored for
    Butterworth). The sections are normalised to unit gain at DC. Raises `AnalysisError` for an unknown
    kind, order < 1, a cut-off outside (0, 1) or a non-positive ripple. Each design is made once per
    process (every trial of a campaign uses the same few) and handed out as a new array."""
    return np.array(_designed(kind, order, cutoff, ripple_db))


@functools.lru_cache(maxsize=64)
def _designed(kind: FilterKind, order: int, cutoff: float, ripple_db: float) -> FloatArray:
    """`design_lowpass`'s sections, made once per set of arguments and kept read-only. The DC rescaling
    matters for an even-order Chebyshev, whose DC gain is otherwise the bottom of the ripple."""
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
    """Samples of odd extension added at each end by the zero-phase filter (3 x (2 x sections + 1)).

    A signal must be longer than this to be filtered.
    """
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
