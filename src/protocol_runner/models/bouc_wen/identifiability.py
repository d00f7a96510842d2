"""Parameter intervals of a Bouc-Wen fit and the "weakly identified" mark (issue 15 item 3).

* The exponent n is profiled over its whole range: on a grid of n values from the fitted n outward to
  each bound (2, 10, 30, 60 and 100 % of the way, substeps of 0.5 deg, stopping where the profile leaves the interval), the other seven parameters are refitted with n held fixed, giving the profile ``SSE(n)``.
  The 95 % profile-likelihood interval is where ``m_eff ln(SSE(n) / SSE_min) <= 3.84`` (chi-square, one
  degree of freedom, Gaussian errors of unknown variance).
* The other parameters get Wald intervals, ``theta +- 1.96 sigma``, with sigma from the Jacobian at the
  optimum (:func:`.problem.param_std`).
* Filtered data have strongly correlated residuals, so ``m`` samples carry far less than ``m`` independent
  errors.  ``m_eff = m (1 - rho) / (1 + rho)`` with ``rho`` the residuals' lag-1 autocorrelation (the
  AR(1) effective sample size) is used in both: the profile threshold and sigma scaled by
  ``sqrt(m / m_eff)``.
* A fit is *weakly identified* when n's interval reaches a bound of n (the data cannot tell n from the
  bound, including a fitted n at its bound), A's interval reaches 0 or its upper bound, or a parameter has
  an infinite sigma (a direction the data do not determine, e.g. a Table 4 phase never visited).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from .backbone import hysteretic_part
from .fitting import _validate_segments, decimate
from .params import PARAM_NAMES, FloatArray
from .problem import BoucWenFit, Problem, param_std

CHI2_1_95 = 3.841458820694124  # 95 % quantile of chi-square with one degree of freedom
PROFILE_SAMPLES = 400  # samples per trial of the copy on which n is profiled
PROFILE_STEP_DEG = 0.5  # substep of the refined integration while profiling
PROFILE_STEPS = np.array([0.02, 0.1, 0.3, 0.6, 1.0])  # grid from the fitted n to each bound
PROFILE_NFEV = 10  # residual evaluations of each fixed-n refit


def effective_samples(residuals: FloatArray, seg: npt.NDArray[np.int64]) -> float:
    """AR(1) effective number of independent residuals, ``m (1 - rho) / (1 + rho)`` (at least 2)."""
    num = 0.0
    den = 0.0
    for k in range(seg.size - 1):
        r = residuals[seg[k] : seg[k + 1]]
        r = r - np.mean(r)
        num += float(np.dot(r[1:], r[:-1]))
        den += float(np.dot(r, r))
    rho = min(max(num / den, 0.0), 0.999) if den > 0.0 else 0.0
    return max(2.0, residuals.size * (1.0 - rho) / (1.0 + rho))


def _fixed_n_refit(problem: Problem, u0: FloatArray) -> tuple[FloatArray, float]:
    """Refit every parameter except n (held at ``u0[1]``); the parameters and the SSE."""
    keep = [0, *range(2, 8)]
    n = float(u0[1])

    def full(v: FloatArray) -> FloatArray:
        u = np.insert(v, 1, n)
        return u

    res = least_squares(
        lambda v: problem.residuals(full(v)),
        np.clip(u0[keep], problem.lower[keep], problem.upper[keep]),
        jac=lambda v: problem.jacobian(full(v))[:, keep],
        bounds=(problem.lower[keep], problem.upper[keep]),
        x_scale="jac",
        method="trf",
        tr_solver="exact",
        max_nfev=PROFILE_NFEV,
    )
    u = full(np.asarray(res.x, dtype=np.float64))
    r = problem.residuals(u)
    return u, float(r @ r)


def _crossing(n_in: float, s_in: float, n_out: float, s_out: float, sse0: float, limit: float) -> float:
    """n where the profile crosses ``limit`` between a point inside and one outside, interpolating
    ``sqrt(SSE - SSE_min)`` linearly (exact for a profile quadratic about its minimum)."""
    q_in = math.sqrt(max(s_in - sse0, 0.0))
    q_out = math.sqrt(max(s_out - sse0, 0.0))
    if q_out <= q_in:
        return n_out
    return n_in + (math.sqrt(limit - sse0) - q_in) / (q_out - q_in) * (n_out - n_in)


def identify(segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]], result: BoucWenFit) -> BoucWenFit:
    """``result`` with n's profile interval, every parameter's interval and the weak-identification mark."""
    checked = _validate_segments(segments)
    if result.backbone is not None:
        checked = hysteretic_part(checked, result.backbone)
    x, y, seg, _ = decimate(checked, PROFILE_SAMPLES)
    problem = Problem(x, y, seg, result.bounds, result.angle_scale_deg, result.torque_scale_nm, result.scheme)
    u_best = problem.to_u(result.params)
    r = problem.residuals(u_best)
    sse0 = float(r @ r)
    m_eff = effective_samples(r, seg)
    limit = sse0 * math.exp(CHI2_1_95 / m_eff)
    n_min, n_max = result.bounds.n_min, result.bounds.n_max
    n_best = float(u_best[1])
    ends: list[float] = []
    for bound in (n_min, n_max):
        u_prev, s_prev, n_prev, end = u_best, sse0, n_best, bound
        for n in n_best + (bound - n_best) * PROFILE_STEPS:
            start = u_prev.copy()
            start[1] = n
            u, s = _fixed_n_refit(problem, start)
            if s > limit:
                end = _crossing(n_prev, s_prev, float(n), s, sse0, limit)
                break
            u_prev, s_prev, n_prev = u, s, float(n)
            if s < sse0:  # a better optimum at this n: the profile is measured from it
                sse0, limit = s, s * math.exp(CHI2_1_95 / m_eff)
        ends.append(end)
    std = param_std(problem, result.params) * math.sqrt(r.size / m_eff)
    theta = result.params.as_array()
    low = theta - 1.96 * std
    high = theta + 1.96 * std
    low[1], high[1] = ends[0], ends[1]
    reasons: list[str] = []
    tol = 1e-6 * (n_max - n_min)
    if low[1] <= n_min + tol or high[1] >= n_max - tol:
        reasons.append(f"n's interval reaches its bound ({low[1]:.3g}-{high[1]:.3g}, range {n_min}-{n_max})")
    a_max = result.bounds.a_max * result.torque_scale_nm / result.angle_scale_deg
    if low[0] <= 0.0 or high[0] >= a_max:
        reasons.append(f"A's interval reaches its bound (0 or {a_max:.3g} N*m/deg)")
    unknown = [PARAM_NAMES[k] for k in range(8) if k != 1 and not math.isfinite(std[k])]
    if unknown:
        reasons.append("not determined by the data: " + ", ".join(unknown))
    return replace(
        result,
        n_interval=(float(low[1]), float(high[1])),
        param_interval_low=tuple(float(v) for v in low),
        param_interval_high=tuple(float(v) for v in high),
        weakly_identified=bool(reasons),
        weak_reasons=tuple(reasons),
    )
