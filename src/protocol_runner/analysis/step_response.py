"""The calibration check's first-order model (thesis §2.4.2: the joint answers a step as a first-order lag,
tau = 0.2 s) and the search for its time constant, without scipy (issue 20: the session process, which
runs the checks, imports no scipy; see analysis/butterworth.py).

- `first_order_response`: the exact zero-order-hold discretisation of ``tau dy/dt = c - y``,
  ``y[i+1] = a y[i] + (1 - a) c[i]`` with ``a = exp(-dt / tau)``, from ``y[0] = y0``. Computed in the
  order scipy's ``lfilter([1 - a], [1, -a], c, zi=[a y0])`` computes it (``v = (1 - a) c[i] + z;
  z = a v``), so the same bits (tests/analysis/test_step_response.py).
- `golden_section_min`: the minimum of a unimodal function on an interval by golden-section search, to
  a given width of the bracket. It replaces scipy's bounded Brent search (``minimize_scalar(...,
  method="bounded")``), which took 1e-4 s as its tolerance on tau: searched to 1e-5 s here, the time
  constants of the seeded knee dry run's checks are within 1e-4 s of the former ones
  (docs/analysis.md, "Calibration check").
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numba import njit

from protocol_runner.analysis.validation import FloatArray

INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0  # 1 / golden ratio: the bracket shrinks by this factor per step


def first_order_response(command_deg: FloatArray, dt_s: float, tau_s: float, y0_deg: float) -> FloatArray:
    """The first-order lag's output at each sample of `command_deg` (held over each `dt_s`), from `y0_deg`:
    ``y[0] = y0`` and ``y[i+1] = a y[i] + (1 - a) c[i]``, ``a = exp(-dt / tau)``."""
    a = math.exp(-dt_s / tau_s)
    return _lag(np.ascontiguousarray(command_deg, dtype=np.float64), a, y0_deg)


@njit(cache=True, nogil=True)
def _lag(command: FloatArray, a: float, y0: float) -> FloatArray:  # pragma: no cover - compiled
    out = np.empty(command.shape[0])
    if command.shape[0] == 0:
        return out
    out[0] = y0
    b = 1.0 - a
    z = a * y0
    for i in range(command.shape[0] - 1):
        v = b * command[i] + z
        out[i + 1] = v
        z = a * v
    return out


def golden_section_min(f: Callable[[float], float], lo: float, hi: float, width: float) -> float:
    """The point of [lo, hi] where `f` (assumed unimodal there) is least, to within `width`: the middle of
    the last bracket, which halves the error bound."""
    if not (lo < hi and width > 0.0):
        raise ValueError(f"need lo < hi and a positive width, got [{lo}, {hi}], {width}")
    c = hi - INV_PHI * (hi - lo)
    d = lo + INV_PHI * (hi - lo)
    fc, fd = f(c), f(d)
    while hi - lo > width:
        if fc <= fd:  # the minimum lies in [lo, d]
            hi, d, fd = d, c, fc
            c = hi - INV_PHI * (hi - lo)
            fc = f(c)
        else:  # in [c, hi]
            lo, c, fc = c, d, fd
            d = lo + INV_PHI * (hi - lo)
            fd = f(d)
    return 0.5 * (lo + hi)
