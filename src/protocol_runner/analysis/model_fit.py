"""Least-squares fit of the device's element model (`models.element_model`) to a configuration's processed
trials, with 95 % intervals that allow for correlated residuals, and the identification mark
(docs/analysis.md §10).

Fit: bounded least squares over every sample of every trial, from the declared values and a few other
starts, keeping the best. Intervals: the Gauss-Newton covariance ``s² (JᵀJ)⁻¹`` with ``s² = SSR / (n_eff -
k)``, scaled by ``n / n_eff`` (`effective_samples`: a filtered loop's residuals are strongly
autocorrelated); the 95 % interval is ``θ ± t(0.975, n_eff - k) σ``. A parameter is *unidentified* when its
interval covers more than `COVER_LIMIT` of its plausible range (`plausible_range`) or is not finite. Two
estimates correlated at `CONFOUNDED` or more in magnitude are noted as confounded, whatever their intervals:
the data determine their combined torque, not each (a damper on a motion of constant speed acts as a brake).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import OptimizeResult, least_squares
from scipy.special import stdtrit

from ..models.element_model import (
    FloatArray,
    Key,
    ModelLayout,
    Motion,
    Stacked,
    param_spec_key,
    stacked_torque_nm,
    torque_jacobian,
)
from ..models.element_types import ELEMENT_TYPES
from .energy import energy_per_cycle

COVER_LIMIT = 0.5  # an interval covering more of the plausible range than this: unidentified
CONFOUNDED = 0.99  # |correlation| of two estimates at or above this: the data barely tell them apart
DEFAULT_TRANSITION_BOUNDS = (0.01, 30.0)
FIT_TOL = 1e-7  # least_squares ftol and xtol of the fit


@dataclass(frozen=True)
class ParameterEstimate:
    """One free parameter: value, 95 % interval, plausible range, and whether the data identify it."""

    element: str
    parameter: str
    value: float
    ci95_low: float
    ci95_high: float
    plausible: tuple[float, float]
    identified: bool
    note: str = ""  # e.g. "sum of brake, hinge"

    def text(self) -> str:
        """The value with its interval; an unidentified one to two significant figures, marked."""
        if not self.identified:
            return f"{self.value:.2g} (unidentified)"
        return f"{self.value:.4g} [{self.ci95_low:.4g}, {self.ci95_high:.4g}]"


@dataclass(frozen=True)
class ElementModelFit:
    """A fit of an element model to a configuration's trials."""

    layout: ModelLayout
    values: Mapping[Key, float]  # every model value (the fitted ones and the declared others)
    estimates: tuple[ParameterEstimate, ...]
    covariance: FloatArray = field(repr=False)  # of the free parameters, in layout.free order
    correlation: FloatArray = field(repr=False)
    rmse_nm: float
    n_samples: int
    n_eff: float
    sse: float
    models: tuple[FloatArray, ...] = field(repr=False)  # the model torque on each trial

    @property
    def k(self) -> int:
        return len(self.layout.free)


def effective_samples(residuals: FloatArray, edges: np.ndarray) -> float:
    """n / τ with τ = 1 + 2 Σ ρ_k the residuals' integrated autocorrelation time (ρ_k pooled over the
    trials, `edges` their boundaries; the sum stops at the first lag where ρ_k is no longer positive)."""
    n = residuals.size
    if n < 3:
        return float(max(n, 1))
    longest = int(np.max(np.diff(edges)))
    acov = np.zeros(longest)
    for a, b in itertools.pairwise(edges):
        r = residuals[a:b] - np.mean(residuals[a:b])
        size = 1 << int(2 * r.size - 1).bit_length()
        spec = np.fft.rfft(r, size)
        acov[: r.size] += np.fft.irfft(spec * np.conj(spec), size)[: r.size]
    if acov[0] <= 0.0:
        return float(n)
    rho = acov / acov[0]
    stop = np.flatnonzero(rho[1:] <= 0.0)
    last = int(stop[0]) + 1 if stop.size else rho.size
    tau = max(1.0, 1.0 + 2.0 * float(np.sum(rho[1:last])))
    return max(2.0, n / tau)


def _bounds(lay: ModelLayout, key: Key) -> tuple[float, float]:
    etype, param = param_spec_key(lay, key)
    if param == "transition_deg":
        return DEFAULT_TRANSITION_BOUNDS
    spec = ELEMENT_TYPES[etype].parameters[param]
    return spec.bounds if spec.bounds is not None else (-math.inf, math.inf)


def plausible_range(lay: ModelLayout, key: Key, motions: Sequence[Motion]) -> tuple[float, float]:
    """The range a parameter could physically take here (module docstring)."""
    etype, param = param_spec_key(lay, key)
    spec = ELEMENT_TYPES[etype].parameters[param]
    if spec.plausible is not None:
        return spec.plausible
    if param == "transition_deg":
        return DEFAULT_TRANSITION_BOUNDS
    lo, hi = spec.bounds if spec.bounds is not None else (-math.inf, math.inf)
    if math.isfinite(lo) and math.isfinite(hi) and spec.unit != "_deg":
        return lo, hi
    torque = max(float(np.max(np.abs(m.torque_nm))) for m in motions)
    angle = np.concatenate([m.angle_deg for m in motions])
    span = max(float(np.ptp(angle)), 1e-9)
    speed = max(max(float(np.max(np.abs(m.speed_deg_s))) for m in motions), 1e-9)
    scale = {
        "_nm": 2.0 * torque,
        "_nm_per_deg": 2.0 * torque / span,
        "_nm_s_per_deg": 2.0 * torque / speed,
    }.get(spec.unit)
    if scale is not None:
        return max(lo, 0.0), scale
    return float(angle.min()) - span, float(angle.max()) + span


def _half_height_nm(motions: Sequence[Motion]) -> float:
    """Half the mean difference between the torque moving up and moving down near the middle angle."""
    heights = []
    for m in motions:
        mid = 0.5 * (m.angle_deg.min() + m.angle_deg.max())
        near = np.abs(m.angle_deg - mid) < 0.1 * np.ptp(m.angle_deg) + 1e-9
        up, down = near & (m.speed_deg_s > 0), near & (m.speed_deg_s < 0)
        if up.any() and down.any():
            heights.append(0.5 * (np.mean(m.torque_nm[up]) - np.mean(m.torque_nm[down])))
    return max(float(np.mean(heights)), 0.0) if heights else 0.0


def _starts(lay: ModelLayout, motions: Sequence[Motion]) -> list[FloatArray]:
    """The declared values; and, with a brake, the same with its torque at half the loops' mean height at
    mid-angle (the friction level of a Coulomb loop)."""
    bounds = [_bounds(lay, key) for key in lay.free]
    base = np.array(
        [min(max(lay.declared[key], lo), hi) for key, (lo, hi) in zip(lay.free, bounds, strict=True)]
    )
    brakes = [
        j for j, key in enumerate(lay.free) if param_spec_key(lay, key) == ("coulomb_brake", "torque_nm")
    ]
    if not brakes:
        return [base]
    other = base.copy()
    for j in brakes:
        other[j] = min(max(_half_height_nm(motions), bounds[j][0]), bounds[j][1])
    return [base, other]


@dataclass(frozen=True)
class Problem:
    """The least-squares problem of a layout on some trials: residuals and Jacobian over the compared
    samples, and the parameters' bounds."""

    lay: ModelLayout
    stacked: Stacked
    lower: FloatArray
    upper: FloatArray

    @staticmethod
    def of(lay: ModelLayout, motions: Sequence[Motion]) -> Problem:
        lower = np.array([_bounds(lay, key)[0] for key in lay.free])
        upper = np.array([_bounds(lay, key)[1] for key in lay.free])
        return Problem(lay, Stacked.of(motions), lower, upper)

    def residual(self, x: FloatArray) -> FloatArray:
        s = self.stacked
        return (stacked_torque_nm(self.lay, self.lay.values(x), s) - s.torque_nm)[s.compared]

    def jacobian(self, x: FloatArray) -> FloatArray:
        sign = np.where(x + 1e-6 * np.maximum(1.0, np.abs(x)) > self.upper, -1.0, 1.0)
        return torque_jacobian(self.lay, self.lay.values(x), self.stacked, sign)[self.stacked.compared]

    def solve(self, x0: FloatArray, tol: float, max_nfev: int | None = None) -> OptimizeResult:
        return least_squares(
            self.residual,
            np.clip(x0, self.lower, self.upper),
            jac=self.jacobian,
            bounds=(self.lower, self.upper),
            x_scale="jac",
            ftol=tol,
            xtol=tol,
            max_nfev=max_nfev,
        )


def fit_element_model(motions: Sequence[Motion], lay: ModelLayout) -> ElementModelFit:
    """Fit `lay`'s free parameters to every sample of `motions` (the configuration's trials)."""
    problem = Problem.of(lay, motions)
    s = problem.stacked
    y = s.torque_nm[s.compared]
    edges = np.concatenate([[0], np.cumsum([np.count_nonzero(m.compared) for m in motions])]).astype(np.int64)

    def predict(x: FloatArray) -> list[FloatArray]:
        return s.split(stacked_torque_nm(lay, lay.values(x), s))

    residual = problem.residual
    k = len(lay.free)
    x_best = np.zeros(0)
    jac = np.zeros((y.size, 0))
    if k:
        best_cost = math.inf
        for x0 in _starts(lay, motions):
            sol = problem.solve(x0, FIT_TOL)
            if sol.cost < best_cost:
                best_cost, x_best, jac = float(sol.cost), np.asarray(sol.x), np.asarray(sol.jac)
    models = tuple(predict(x_best))
    r = residual(x_best)
    sse = sum_of_squares(r)
    n = y.size
    n_eff = effective_samples(r, edges)
    dof = max(n_eff - k, 1.0)
    cov = np.full((k, k), math.nan)
    if k:
        jtj = jac.T @ jac
        if np.all(np.isfinite(jtj)) and np.linalg.matrix_rank(jtj) == k:
            cov = np.linalg.inv(jtj) * (sse / dof) * (n / n_eff)
    std = np.sqrt(np.abs(np.diag(cov))) if k else np.zeros(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(std, std) if k else np.zeros((0, 0))
    q = float(stdtrit(dof, 0.975))
    estimates = []
    for j, key in enumerate(lay.free):
        lo_p, hi_p = plausible_range(lay, key, motions)
        lo, hi = x_best[j] - q * std[j], x_best[j] + q * std[j]
        width = hi_p - lo_p
        covered = (min(hi, hi_p) - max(lo, lo_p)) / width if width > 0 else math.inf
        identified = bool(math.isfinite(lo) and math.isfinite(hi) and covered <= COVER_LIMIT)
        note = ""
        if key[0] == lay.friction_name and len(lay.friction_members) > 1:
            members = ", ".join(lay.friction_members)
            note = (
                f"sum of {members} (they act together: only the sum is identifiable)"
                if key[1] == "torque_nm"
                else f"shared by {members}"
            )
        elif key[0] == lay.damper_name and len(lay.damper_members) > 1:
            note = f"sum of {', '.join(lay.damper_members)}"
        confounded = [
            f"{other[0]}.{other[1]} (r = {corr[j, m]:+.3f})"
            for m, other in enumerate(lay.free)
            if m != j and abs(corr[j, m]) >= CONFOUNDED
        ]
        if confounded:
            said = f"confounded with {', '.join(confounded)}: only their combined torque is determined"
            note = f"{note}; {said}" if note else said
        estimates.append(
            ParameterEstimate(
                key[0], key[1], float(x_best[j]), float(lo), float(hi), (lo_p, hi_p), identified, note
            )
        )
    return ElementModelFit(
        layout=lay,
        values=lay.values(x_best),
        estimates=tuple(estimates),
        covariance=cov,
        correlation=corr,
        rmse_nm=math.sqrt(sse / n) if n else math.nan,
        n_samples=n,
        n_eff=n_eff,
        sse=sse,
        models=models,
    )


def sum_of_squares(r: FloatArray) -> float:
    """Σ r², correctly rounded (math.fsum): the same bits for the same values wherever the array lies in
    memory (a BLAS dot product's last bits may depend on the alignment), so that the fit step and
    `--reprocess` store the same AIC and BIC."""
    return math.fsum(np.square(np.asarray(r, dtype=np.float64)).tolist())


def mean_energy_j(motions: Sequence[Motion], torques: Sequence[FloatArray]) -> float:
    """Mean energy per complete cycle (Eq 10-12) of `torques` along the motions' angles."""
    cycles = [energy_per_cycle(m.angle_deg, t) for m, t in zip(motions, torques, strict=True)]
    pooled = np.concatenate(cycles) if cycles else np.zeros(0)
    return float(np.mean(pooled)) if pooled.size else math.nan
