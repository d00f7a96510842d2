"""Parameter intervals of a Bouc-Wen fit and the "weakly identified" mark (docs/analysis.md §9,
"Intervals and identifiability", gives the reasons and the tests).

* n is profiled from the fitted n toward each bound (`PROFILE_STEPS`), the other seven parameters refitted
  with n fixed; its 95 % interval is where ``m_eff ln(SSE(n) / SSE_min) <= 3.84`` (chi-square, one degree
  of freedom). A refit ending above that limit is continued (``CROSSING_NFEV``) before it ends the interval.
* The others get Wald intervals ``theta +- 1.96 sigma``, sigma from the Jacobian at the optimum; that sigma
  becomes the fit's ``param_std``.
* Filtered residuals are correlated: ``m_eff = m (1 - rho) / (1 + rho)`` (rho their lag-1
  autocorrelation, the AR(1) effective sample size) sets the profile threshold and scales sigma by
  ``sqrt(m / m_eff)``.

Weak: each parameter is judged in the dimensionless form whose bounds are its plausible range
(:class:`.problem.BoucWenBounds`: ``a = A X / Z``, n and the six Table 4 phase values ``psi'_k``, Eq 24);
a fit is weak when some 95 % interval covers more than ``COVER_LIMIT`` of that range, or is not finite.
A value at a bound with a narrow interval is not weak.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from .backbone import hysteretic_part
from .copies import decimate
from .fitting import _validate_segments, blas_single_threaded
from .params import FloatArray
from .problem import FitScale, Problem, Samples, jacobian_std, param_std
from .records import BoucWenFit
from .schemes import REFINED

CHI2_1_95 = 3.841458820694124  # 95 % quantile of chi-square with one degree of freedom
PROFILE_SAMPLES = 400  # samples per trial of the copy on which n is profiled
PROFILE_STEP_DEG = 0.5  # substep of the refined integration while profiling
PROFILE_STEPS = np.array([0.02, 0.1, 0.3, 0.6, 1.0])  # grid from the fitted n to each bound
PROFILE_NFEV = 6  # residual evaluations of each fixed-n refit (as close to converged refits as 10 were,
# given the continuation at the crossing: docs/analysis.md)
CROSSING_NFEV = 30  # further evaluations of a refit that ends above the interval's limit (see _n_profile)
COVER_LIMIT = 0.5  # a 95 % interval covering more of the plausible range than this: weakly identified
DIMENSIONLESS_NAMES: tuple[str, ...] = (
    "a = A X/Z",
    "n",
    *(f"psi'{k} (Table 4 phase {k})" for k in range(1, 7)),
)


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


def _fixed_n_refit(problem: Problem, u0: FloatArray, max_nfev: int | None = None) -> tuple[FloatArray, float]:
    """Refit every parameter except n (held at ``u0[1]``), with at most ``max_nfev`` residual evaluations
    (``PROFILE_NFEV`` by default); the parameters and the SSE."""
    keep = [0, *range(2, 8)]
    n = float(u0[1])

    def full(v: FloatArray) -> FloatArray:
        u = np.insert(v, 1, n)
        return u

    problem.fused = True  # each evaluation gives the Jacobian too (see Problem.solve)
    try:
        res = least_squares(
            lambda v: problem.residuals(full(v)),
            np.clip(u0[keep], problem.lower[keep], problem.upper[keep]),
            jac=lambda v: problem.jacobian(full(v))[:, keep],
            bounds=(problem.lower[keep], problem.upper[keep]),
            x_scale="jac",
            method="trf",
            tr_solver="exact",
            max_nfev=PROFILE_NFEV if max_nfev is None else max_nfev,
        )
    finally:
        problem.fused = False
    # the solver's cost is half the sum of squares of its residuals at the point it returns
    return full(np.asarray(res.x, dtype=np.float64)), 2.0 * float(res.cost)


def _crossing(n_in: float, s_in: float, n_out: float, s_out: float, sse0: float, limit: float) -> float:
    """n where the profile crosses ``limit`` between a point inside and one outside, interpolating
    ``sqrt(SSE - SSE_min)`` linearly (exact for a profile quadratic about its minimum)."""
    q_in = math.sqrt(max(s_in - sse0, 0.0))
    q_out = math.sqrt(max(s_out - sse0, 0.0))
    if q_out <= q_in:
        return n_out
    return n_in + (math.sqrt(limit - sse0) - q_in) / (q_out - q_in) * (n_out - n_in)


def _n_profile(problem: Problem, u_best: FloatArray, sse0: float, m_eff: float) -> tuple[float, float]:
    """The 95 % profile-likelihood interval of n (ends at n's bounds where the profile stays inside)."""
    limit = sse0 * math.exp(CHI2_1_95 / m_eff)
    n_best = float(u_best[1])
    ends: list[float] = []
    for bound in (problem.bounds.n_min, problem.bounds.n_max):
        u_prev, s_prev, n_prev, end = u_best, sse0, n_best, bound
        for n in n_best + (bound - n_best) * PROFILE_STEPS:
            start = u_prev.copy()
            start[1] = n
            u, s = _fixed_n_refit(problem, start)
            if s > limit:  # outside, or a refit not yet converged: continued before it ends the interval
                u, s = _fixed_n_refit(problem, u, CROSSING_NFEV)
            if s > limit:
                end = _crossing(n_prev, s_prev, float(n), s, sse0, limit)
                break
            u_prev, s_prev, n_prev = u, s, float(n)
            if s < sse0:  # a better optimum at this n: the profile is measured from it
                sse0, limit = s, s * math.exp(CHI2_1_95 / m_eff)
        ends.append(end)
    return ends[0], ends[1]


def weak_reasons(
    u: FloatArray, std_u: FloatArray, n_interval: tuple[float, float], problem: Problem
) -> list[str]:
    """The parameters (dimensionless, see the module notes) whose 95 % interval covers more than
    ``COVER_LIMIT`` of their plausible range, or that have no finite interval, each with the reason."""
    reasons: list[str] = []
    lower, upper = problem.lower, problem.upper
    for k, name in enumerate(DIMENSIONLESS_NAMES):
        if k == 1:
            lo, hi = n_interval
        elif not math.isfinite(std_u[k]):
            reasons.append(f"{name}: not determined by the data (no finite interval)")
            continue
        else:
            lo = max(float(u[k] - 1.96 * std_u[k]), float(lower[k]))
            hi = min(float(u[k] + 1.96 * std_u[k]), float(upper[k]))
        cover = (hi - lo) / float(upper[k] - lower[k])
        if cover > COVER_LIMIT:
            reasons.append(
                f"{name}: the 95 % interval {lo:.3g} to {hi:.3g} covers {100 * cover:.0f} % of its "
                f"plausible range {lower[k]:g} to {upper[k]:g}"
            )
    return reasons


@blas_single_threaded
def identify(segments: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]], result: BoucWenFit) -> BoucWenFit:
    """``result`` with n's profile interval, every parameter's interval and the weak-identification mark."""
    checked = _validate_segments(segments)
    if result.backbone is not None:
        checked = hysteretic_part(checked, result.backbone)
    x, y, seg, _ = decimate(checked, PROFILE_SAMPLES)
    step = PROFILE_STEP_DEG if result.scheme == REFINED else None
    scale = FitScale(result.angle_scale_deg, result.torque_scale_nm)
    problem = Problem(Samples(x, y, seg), result.bounds, scale, result.scheme, step)
    u_best = problem.to_u(result.params)
    problem.fused = True  # the residuals come with the Jacobian, which std_u needs at the same point
    try:
        r = problem.residuals(u_best)
    finally:
        problem.fused = False
    sse0 = float(r @ r)
    m_eff = effective_samples(r, seg)
    inflate = math.sqrt(r.size / m_eff)
    std_u = jacobian_std(problem.jacobian(u_best), sse0) * inflate
    std = param_std(problem, result.params) * inflate
    n_low, n_high = _n_profile(problem, u_best, sse0, m_eff)
    theta = result.params.as_array()
    low = theta - 1.96 * std
    high = theta + 1.96 * std
    low[1], high[1] = n_low, n_high
    reasons = weak_reasons(u_best, std_u, (n_low, n_high), problem)
    return replace(
        result,
        param_std=std,  # the sigma of the intervals: residuals' correlation allowed for (the fit's is not)
        n_interval=(float(n_low), float(n_high)),
        param_interval_low=tuple(float(v) for v in low),
        param_interval_high=tuple(float(v) for v in high),
        weakly_identified=bool(reasons),
        weak_reasons=tuple(reasons),
    )
