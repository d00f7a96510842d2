"""A zero-phase Butterworth low-pass without scipy, for the session process (issue 20).

The session smooths each brace-on recording before it becomes a brace-off command (`steps/trial.py`,
4th order at `COMMAND_SMOOTHING_HZ`). Everything else the session does needs no scipy, and importing it
(with scipy.optimize, .stats and .linalg, which scipy.signal brings along) was a quarter of a second of the
session's start, before anything else could start. So this module computes the same filter from its
definition, with numpy only; the analysis workers keep scipy's designs (`filters.py`: every order,
Chebyshev too) and filter with this module's pass (`zero_phase_pass`, scipy's `sosfiltfilt` bit for bit
for any of them):

- the design (`butterworth_sos`): the analog prototype's poles ``-exp(i pi m / 2N)``, m = -N+1, -N+3,
  ..., N-1, at the pre-warped cut-off ``4 tan(pi Wn / 2)``; the bilinear transform
  ``z = (4 + s) / (4 - s)`` (all N zeros at z = -1); one section per conjugate pair of poles, the pair
  farthest from the unit circle first (the sharpest resonance last), numerator ``(1 + z^-1)^2`` with the
  overall gain ``wo^N / prod(4 - s_k)`` on the first section, then divided by the cascade's gain at DC
  (as `filters.design_lowpass` makes every design);
- the start-up state of each section for a unit step (`sections_zi`): the steady state of its
  transposed direct form II, ``(I - A^T) zi = B``, scaled by the DC gain of the sections before it;
- the pass (`zero_phase`): an odd extension of 3 (2 n_sections + 1) samples at each end, the cascade
  forward from the state scaled by the first sample, then backward from the state scaled by the last
  output, the extension cut off.

Each number is computed with the numpy operations, in the order, that give exactly what `filters.lowpass`
gives with scipy (`design_lowpass` for a Butterworth, `sosfilt_zi`, `sosfiltfilt` with odd padding):
tests/analysis/test_butterworth.py compares them bit for bit over orders, cut-offs and signals, so a
brace-off command is the same whichever computed it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal

FS = 2.0  # the design's sampling rate: frequencies are fractions of the Nyquist frequency (= 1)


def butterworth_sos(order: int, cutoff: float) -> FloatArray:
    """Second-order sections (rows b0 b1 b2 1 a1 a2) of the digital Butterworth low-pass of even `order`
    with cut-off `cutoff` (a fraction of the Nyquist frequency, strictly between 0 and 1)."""
    if isinstance(order, bool) or int(order) != order or order < 2 or order % 2:
        raise AnalysisError(f"the session's Butterworth filter takes an even order >= 2, got {order}")
    if not 0.0 < cutoff < 1.0:
        raise AnalysisError(
            f"filter cut-off must be a fraction of the Nyquist frequency in (0, 1), got {cutoff}"
        )
    n = int(order)
    m = np.arange(-n + 1, n, 2)
    prototype = -np.exp(1j * np.pi * m / (2 * n))  # analog poles for a cut-off of 1 rad/s
    wo = float(2 * FS * np.tan(np.pi * cutoff / FS))  # the cut-off, pre-warped for the bilinear transform
    poles_s = wo * prototype
    fs2 = 2.0 * FS
    poles_z = (fs2 + poles_s) / (fs2 - poles_s)
    gain_z = wo**n * np.real(1.0 / np.prod(fs2 - poles_s))  # no finite zeros: 1 over the poles' product
    upper = poles_z[poles_z.imag > 0]  # one pole of each conjugate pair
    order_of = np.argsort(-np.abs(1 - np.abs(upper)), kind="stable")  # farthest from the unit circle first
    numerator = np.real(np.poly(np.array([-1.0 + 0j, -1.0 + 0j])))  # both zeros at z = -1: 1, 2, 1
    sos = np.zeros((n // 2, 6))
    for row, k in enumerate(order_of):
        pole = upper[k]
        sos[row, :3] = (gain_z if row == 0 else 1.0) * numerator
        sos[row, 3:] = np.real(np.poly(np.array([pole, pole.conj()])))
    # unit DC gain, as `filters.design_lowpass` makes every design: the first numerator divided by the
    # cascade's gain at z = 1 (within rounding of 1 for a Butterworth)
    sos[0, :3] /= float(np.prod(sos[:, :3].sum(axis=1) / sos[:, 3:].sum(axis=1)))
    return sos


def sections_zi(sos: npt.ArrayLike) -> FloatArray:
    """Each section's state (2 values) in the steady state of a unit step through the cascade."""
    sections = np.asarray(sos, dtype=np.float64)
    zi = np.empty((sections.shape[0], 2))
    scale = 1.0
    for k in range(sections.shape[0]):
        b = sections[k, :3] / sections[k, 3]
        a = sections[k, 3:] / sections[k, 3]
        # I - A^T for A the companion matrix of a (first row -a1, -a2; ones below the diagonal)
        i_minus_at = np.array([[1.0 + a[1], -1.0], [a[2], 1.0]])
        zi[k] = scale * np.linalg.solve(i_minus_at, b[1:] - a[1:] * b[0])
        scale *= np.sum(b) / np.sum(a)
    return zi


def padding(sos: npt.ArrayLike) -> int:
    """Samples of odd extension at each end: 3 (2 n_sections + 1)."""
    return 3 * (2 * np.atleast_2d(np.asarray(sos)).shape[0] + 1)


def zero_phase(values: npt.ArrayLike, sos: npt.ArrayLike, *, name: str = "signal") -> FloatArray:
    """`values` filtered forward and backward by the cascade `sos` (zero phase, unit DC gain)."""
    x = as_signal(name, values)
    sections = np.ascontiguousarray(sos, dtype=np.float64)
    pad = padding(sections)
    if x.shape[0] <= pad:
        raise AnalysisError(
            f"{name}: {x.shape[0]} samples are too few for this filter (it pads {pad} samples at each end)"
        )
    return zero_phase_pass(x, sections, sections_zi(sections), pad)


def zero_phase_pass(x: FloatArray, sections: FloatArray, zi: FloatArray, pad: int) -> FloatArray:
    """The forward-backward pass of `zero_phase` over a validated float64 `x` longer than `pad`, with the
    cascade's unit-step state `zi` (`sections_zi`) and C-contiguous float64 `sections` (rows with a0 = 1, as
    every scipy design has): what `scipy.signal.sosfiltfilt(sections, x, padtype="odd", padlen=pad)` gives,
    bit for bit, for any such sections (tests/analysis/test_butterworth.py), 2-3 times faster. Also the
    analysis's pass (`filters.filter_zero_phase_together`)."""
    ext = np.concatenate((2 * x[0] - x[pad:0:-1], x, 2 * x[-1] - x[-2 : -(pad + 2) : -1]))
    forward = _cascade(sections, ext, zi * ext[0])
    backward = _cascade(sections, np.ascontiguousarray(forward[::-1]), zi * forward[-1])
    return np.ascontiguousarray(backward[::-1][pad:-pad])


@njit(cache=True, nogil=True)
def _cascade(sos: FloatArray, x: FloatArray, zi: FloatArray) -> FloatArray:  # pragma: no cover - compiled
    """The sections in cascade over `x` from the states `zi` (a copy is updated), transposed direct form II:
    ``y = b0 x + z0; z0 = b1 x - a1 y + z1; z1 = b2 x - a2 y``."""
    state = zi.copy()
    y = np.empty_like(x)
    for i in range(x.shape[0]):
        v = x[i]
        for s in range(sos.shape[0]):
            out = sos[s, 0] * v + state[s, 0]
            state[s, 0] = sos[s, 1] * v - sos[s, 4] * out + state[s, 1]
            state[s, 1] = sos[s, 2] * v - sos[s, 5] * out
            v = out
        y[i] = v
    return y
