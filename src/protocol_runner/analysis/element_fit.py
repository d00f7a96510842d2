"""Fit of the device's elastic elements to a processed loop (thesis §6.1, generalised to any device;
docs/analysis.md "8. Element fit").

The model is the sum of the device's angle-only torques (elastic elements and the gravity of masses,
`models.element_torques`); its free parameters are each elastic element's `fit` list, estimated by bounded
least squares from several starts, every other parameter the configuration's value. The elements have no
friction, so the default target is the loop's *midline* (`target="branch_mean"`, a symmetric friction
cancels there) less `trim_deg` at each end; `"all_samples"` fits every sample. A device with nothing to fit
gives a "not applicable" result with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from protocol_runner.analysis.branches import branch_curves
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length
from protocol_runner.models.element_torques import has_static_torque, static_torque_nm
from protocol_runner.models.element_types import ELEMENT_TYPES
from protocol_runner.models.elements import Element, build_device

FitTarget = Literal["branch_mean", "all_samples"]


@dataclass(frozen=True)
class ElementFit:
    """Result of `fit_elements`. `fitted` lists (element, parameter, value); `elements` is the device's
    angle-only elements with the fitted values. Values are absent and errors NaN when not applicable."""

    applicable: bool
    reason: str  # why not applicable, or a one-line description of the fit
    target: FitTarget
    rmse_nm: float  # against the fitted target: the branch midline, or every sample (= rmse_all_samples_nm)
    rmse_all_samples_nm: float  # against every sample of the loop
    fitted: tuple[tuple[str, str, float], ...]
    elements: tuple[Element, ...]
    curve_angle_deg: FloatArray = field(repr=False)  # the fitted target's angles
    curve_torque_nm: FloatArray = field(repr=False)  # the fitted target's torques
    model_torque_nm: FloatArray = field(repr=False)  # the model at curve_angle_deg

    def value(self, element: str, param: str) -> float:
        """A fitted value (KeyError if that parameter was not fitted)."""
        for e, p, v in self.fitted:
            if (e, p) == (element, param):
                return v
        raise KeyError(f"{element}.{param}")


def not_applicable(reason: str, target: FitTarget, elements: Sequence[Element] = ()) -> ElementFit:
    """A fit that was not done, with the reason (starting "not applicable: ")."""
    nan = float("nan")
    empty = np.zeros(0, dtype=np.float64)
    return ElementFit(
        False, f"not applicable: {reason}", target, nan, nan, (), tuple(elements), empty, empty, empty
    )


def _fine_bins(
    angle: FloatArray, torque: FloatArray, width_deg: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Mean angle, mean torque and sample count of each occupied `width_deg` angle bin."""
    _, inverse, counts = np.unique(
        np.floor(angle / width_deg).astype(np.int64), return_inverse=True, return_counts=True
    )
    return (
        np.bincount(inverse, weights=angle) / counts,
        np.bincount(inverse, weights=torque) / counts,
        counts.astype(np.float64),
    )


def branch_midline(
    angle_deg: npt.ArrayLike,
    torque_nm: npt.ArrayLike,
    *,
    bin_width_deg: float = 1.0,
    reversal_deg: float = 1.0,
    trim_deg: float = 0.0,
) -> tuple[FloatArray, FloatArray]:
    """Mean of the loading and unloading torque at each angle both branches cover (grid `bin_width_deg`).

    `trim_deg` leaves out that many degrees at each end of the common range: just after a reversal the
    friction is still changing sign (rounded loop corners), so the midline there is biased towards the
    branch that has already turned.
    """
    if not trim_deg >= 0:
        raise AnalysisError(f"midline trim must be >= 0 deg, got {trim_deg}")
    curves = branch_curves(angle_deg, torque_nm, bin_width_deg=bin_width_deg, reversal_deg=reversal_deg)
    lo = max(curves.loading_angle_deg[0], curves.unloading_angle_deg[0]) + trim_deg
    hi = min(curves.loading_angle_deg[-1], curves.unloading_angle_deg[-1]) - trim_deg
    if not hi > lo:
        raise AnalysisError(
            f"the loading and unloading branches share no angle range (after trimming {trim_deg} deg at "
            "each end): no loop midline"
        )
    grid = np.arange(lo, hi + 0.5 * bin_width_deg, bin_width_deg)
    grid = grid[grid <= hi]
    mid = 0.5 * (
        np.interp(grid, curves.loading_angle_deg, curves.loading_torque_nm)
        + np.interp(grid, curves.unloading_angle_deg, curves.unloading_torque_nm)
    )
    return grid, mid


def model_torque_nm(elements: Sequence[Element], angle_deg: npt.ArrayLike) -> FloatArray:
    """The sum of the elements' angle-only torques (elastic elements, masses' gravity) at `angle_deg`."""
    total = np.zeros(np.shape(angle_deg), dtype=np.float64)
    for e in elements:
        if has_static_torque(e):
            total = total + static_torque_nm(e, angle_deg)
    return total


def _starts(
    free: list[tuple[int, str]], elements: Sequence[Element], angle: FloatArray
) -> tuple[list[FloatArray], FloatArray, FloatArray, FloatArray]:
    """Starting points, bounds and scales: the declared values, then each parameter alone moved to each of
    its type's `fit_starts` (an angle without them: the quartiles of the data's angles), deduplicated."""
    base, lower, upper, scale, options = [], [], [], [], []
    for i, name in free:
        spec = ELEMENT_TYPES[elements[i].type].parameters[name]
        lo, hi = spec.bounds if spec.bounds is not None else (-math.inf, math.inf)
        lower.append(lo)
        upper.append(hi)
        scale.append(spec.fit_scale)
        base.append(min(max(elements[i].number(name), lo), hi))
        extra = spec.fit_starts or (
            tuple(np.percentile(angle, (25.0, 50.0, 75.0))) if spec.unit == "_deg" else ()
        )
        options.append(sorted({base[-1], *(min(max(float(s), lo), hi) for s in extra)}))
    starts: list[FloatArray] = []
    seen: set[tuple[float, ...]] = set()
    for j, values in enumerate(options):
        for v in values:
            x = list(base)
            x[j] = v
            if tuple(x) not in seen:
                seen.add(tuple(x))
                starts.append(np.array(x, dtype=np.float64))
    return starts, np.array(lower), np.array(upper), np.array(scale)


def fit_elements(
    angle_deg: npt.ArrayLike,
    brace_torque_nm: npt.ArrayLike,
    device: Sequence[object],
    *,
    target: FitTarget = "branch_mean",
    bin_width_deg: float = 1.0,
    reversal_deg: float = 1.0,
    trim_deg: float = 5.0,
) -> ElementFit:
    """Fit the free parameters of `device`'s elastic elements to a processed loop (module docstring).

    `angle_deg`, `brace_torque_nm`: the processed loop (the device's torque after equal-angle
    subtraction), one or several trials concatenated. `device`: `models.elements.Element`s or
    ElementSetting-like objects. Raises AnalysisError when the loop cannot support a fit.
    """
    a = as_signal("angle_deg", angle_deg, min_length=2)
    t = as_signal("brace_torque_nm", brace_torque_nm, min_length=2)
    same_length(angle_deg=a, brace_torque_nm=t)
    if target not in ("branch_mean", "all_samples"):
        raise AnalysisError(f"unknown element-fit target {target!r}: use 'branch_mean' or 'all_samples'")
    elements = tuple(e for e in device if isinstance(e, Element))
    if len(elements) != len(device):
        elements = build_device(device)
    static = [e for e in elements if has_static_torque(e)]
    if not any(e.kind == "elastic" for e in static):
        return not_applicable("the device has no elastic element to fit", target, static)
    if not np.any(model_torque_nm(static, np.linspace(a.min(), a.max(), 64)) != 0.0):
        return not_applicable(
            "the elastic elements give no torque (stiffness 0): nothing to fit", target, static
        )
    free = [(i, name) for i, e in enumerate(static) for name in e.fit]
    if target == "branch_mean":
        xs, ys = branch_midline(
            a, t, bin_width_deg=bin_width_deg, reversal_deg=reversal_deg, trim_deg=trim_deg
        )
        weights = np.ones_like(xs)
    else:
        # Every sample, condensed: the model depends on the angle only, so the sum of squares over the
        # samples equals the count-weighted sum over fine angle bins (0.05 deg) of their means, plus a
        # constant. The fit is the same, thousands of times cheaper on 1 kHz data.
        xs, ys, counts = _fine_bins(a, t, 0.05)
        weights = np.sqrt(counts)
    if xs.shape[0] < max(3, len(free) + 1):
        raise AnalysisError(f"the loop gives only {xs.shape[0]} points to fit {len(free)} element parameters")

    def with_values(x: FloatArray) -> list[Element]:
        changed: dict[int, dict[str, float]] = {}
        for (i, name), v in zip(free, x, strict=True):
            changed.setdefault(i, {})[name] = float(v)
        out = list(static)
        for i, values in changed.items():
            out[i] = out[i].replace(**values)  # one copy per element, whatever its number of free parameters
        return out

    def residual(x: FloatArray) -> FloatArray:
        return weights * (model_torque_nm(with_values(x), xs) - ys)

    best = np.zeros(0, dtype=np.float64)
    if free:
        starts, lower, upper, scale = _starts(free, static, a)
        best_cost = math.inf
        for x0 in starts:
            sol = least_squares(residual, x0, bounds=(lower, upper), x_scale=scale)
            if sol.cost < best_cost:
                best_cost, best = float(sol.cost), np.asarray(sol.x, dtype=np.float64)
    fitted_elements = with_values(best)
    fitted = model_torque_nm(fitted_elements, xs)
    # the model is smooth: evaluate it on a 0.05 deg grid and interpolate for every sample (fast on 1 kHz data)
    grid = np.linspace(a.min(), a.max(), max(2, int(np.ptp(a) / 0.05) + 2))
    rmse_all = float(np.sqrt(np.mean((np.interp(a, grid, model_torque_nm(fitted_elements, grid)) - t) ** 2)))
    rmse = float(np.sqrt(np.mean((fitted - ys) ** 2))) if target == "branch_mean" else rmse_all
    return ElementFit(
        applicable=True,
        reason=f"least squares on the {'loop midline' if target == 'branch_mean' else 'samples'}",
        target=target,
        rmse_nm=rmse,
        rmse_all_samples_nm=rmse_all,
        fitted=tuple((static[i].name, name, float(v)) for (i, name), v in zip(free, best, strict=True)),
        elements=tuple(fitted_elements),
        curve_angle_deg=xs,
        curve_torque_nm=ys,
        model_torque_nm=fitted,
    )
