"""Fit of the physical spring model to a processed brace loop (thesis §6.1).

The physical model (`models.spring.spring_torque_nm`, Eq 13-18) has two quantities the thesis could not
pin down: Max_Preload of Eq 17 (not given) and the zero-torque crossing, which "changes with the springs"
(§6.1.6). Both are fitted here by least squares (scipy `least_squares`, bounded, several starts), with the
spring constant and the screw position known from the configuration.

The model has no friction or hysteresis (§6.1.5: "all that can be compared is the general trend"), so it
is fitted to the loop's *midline*, the mean of the loading and unloading branches at each angle
(`target="branch_mean"`, the default): a symmetric friction torque cancels there, and the fit does not
depend on how long the joint dwelt at each angle (a stall at the robot's torque limit would otherwise
weigh heavily); `trim_deg` (5°) at each end of the loop are left out, because the friction is still
reversing there (rounded loop corners) and would tilt the fitted curve. `target="all_samples"` fits every
sample instead, for comparison. With no spring (K0) the
model is identically zero and there is nothing to fit: the result says "not applicable".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from protocol_runner.analysis.branches import branch_curves
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length
from protocol_runner.models.spring import SpringGeometry, spring_torque_nm

# INTERIM glue (helper PROTO): models.spring lost its knee default; the element fit (helper ELEM) replaces
# this module and reads the geometry from the protocol's lever_spring element.
THESIS_GEOMETRY = SpringGeometry(
    a_m=0.03, b_m=0.19, c_m=0.055, alpha_deg=20.0, preload_step_deg=2.73, n_springs=2
)

FitTarget = Literal["branch_mean", "all_samples"]

MAX_PRELOAD_BOUNDS_MM: tuple[float, float] = (0.0, 100.0)
ZERO_OFFSET_BOUNDS_DEG: tuple[float, float] = (-40.0, 40.0)
_STARTS: tuple[tuple[float, float], ...] = (
    (10.0, 0.0),
    (32.0, 0.0),
    (60.0, 0.0),
    (32.0, -15.0),
    (32.0, 15.0),
)


@dataclass(frozen=True)
class SpringFit:
    """Result of `fit_spring_model`. Parameters are NaN when `applicable` is False."""

    applicable: bool
    reason: str  # why not applicable, or a one-line description of the fit
    max_preload_mm: float
    zero_offset_deg: float
    rmse_nm: float  # against the fitted target: the branch midline, or every sample (= rmse_all_samples_nm)
    rmse_all_samples_nm: float  # against every sample of the loop
    stiffness_n_per_mm: float
    preload_position: int
    target: FitTarget
    curve_angle_deg: FloatArray = field(repr=False)  # the fitted target's angles
    curve_torque_nm: FloatArray = field(repr=False)  # the fitted target's torques
    model_torque_nm: FloatArray = field(repr=False)  # the model at curve_angle_deg


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


def fit_spring_model(
    angle_deg: npt.ArrayLike,
    brace_torque_nm: npt.ArrayLike,
    stiffness_n_per_mm: float,
    preload_position: int,
    *,
    geometry: SpringGeometry = THESIS_GEOMETRY,
    target: FitTarget = "branch_mean",
    bin_width_deg: float = 1.0,
    reversal_deg: float = 1.0,
    trim_deg: float = 5.0,
) -> SpringFit:
    """Fit Max_Preload (Eq 17) and the zero-torque offset of the spring model (Eq 13-18) to a brace loop.

    `angle_deg`, `brace_torque_nm`: the processed loop (brace torque after equal-angle subtraction), one
    or several trials concatenated. Minimises the squared difference between `spring_torque_nm(angle,
    stiffness_n_per_mm, preload_position, max_preload_mm=p, zero_offset_deg=o)` and the target (see the
    module docstring) over p in `MAX_PRELOAD_BOUNDS_MM`, o in `ZERO_OFFSET_BOUNDS_DEG`, from several
    starts, keeping the best. The midline leaves out `trim_deg` at each end of the loop (where friction is
    still reversing, see `branch_midline`). Stiffness 0 (K0, no spring) returns `applicable=False`.
    """
    a = as_signal("angle_deg", angle_deg, min_length=2)
    t = as_signal("brace_torque_nm", brace_torque_nm, min_length=2)
    same_length(angle_deg=a, brace_torque_nm=t)
    if not (math.isfinite(stiffness_n_per_mm) and stiffness_n_per_mm >= 0):
        raise AnalysisError(f"spring stiffness must be >= 0 N/mm, got {stiffness_n_per_mm}")
    if target not in ("branch_mean", "all_samples"):
        raise AnalysisError(f"unknown spring-fit target {target!r}: use 'branch_mean' or 'all_samples'")
    if stiffness_n_per_mm == 0:
        nan = float("nan")
        empty = np.zeros(0, dtype=np.float64)
        return SpringFit(
            applicable=False,
            reason="not applicable: no spring fitted (stiffness 0, K0), the spring model is zero",
            max_preload_mm=nan,
            zero_offset_deg=nan,
            rmse_nm=nan,
            rmse_all_samples_nm=nan,
            stiffness_n_per_mm=0.0,
            preload_position=int(preload_position),
            target=target,
            curve_angle_deg=empty,
            curve_torque_nm=empty,
            model_torque_nm=empty,
        )
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
    if xs.shape[0] < 3:
        raise AnalysisError(
            f"the loop gives only {xs.shape[0]} points to fit the spring model's 2 parameters"
        )

    def model(params: FloatArray, angles: FloatArray) -> FloatArray:
        return spring_torque_nm(
            angles,
            stiffness_n_per_mm,
            preload_position,
            max_preload_mm=float(params[0]),
            zero_offset_deg=float(params[1]),
            geometry=geometry,
        )

    def residual(params: FloatArray) -> FloatArray:
        return weights * (model(params, xs) - ys)

    model(np.array([_STARTS[0][0], 0.0]), xs[:1])  # validates the preload position (InvalidInput) up front
    lower = (MAX_PRELOAD_BOUNDS_MM[0], ZERO_OFFSET_BOUNDS_DEG[0])
    upper = (MAX_PRELOAD_BOUNDS_MM[1], ZERO_OFFSET_BOUNDS_DEG[1])
    best_x: FloatArray | None = None
    best_cost = math.inf
    for start in _STARTS:
        sol = least_squares(
            residual, np.array(start, dtype=np.float64), bounds=(lower, upper), x_scale=(10.0, 10.0)
        )
        if sol.cost < best_cost:
            best_cost, best_x = float(sol.cost), np.asarray(sol.x, dtype=np.float64)
    assert best_x is not None
    fitted = model(best_x, xs)
    # the model is smooth: evaluate it on a 0.05 deg grid and interpolate for every sample (fast on 1 kHz data)
    grid = np.linspace(a.min(), a.max(), max(2, int(np.ptp(a) / 0.05) + 2))
    rmse_all = float(np.sqrt(np.mean((np.interp(a, grid, model(best_x, grid)) - t) ** 2)))
    rmse = float(np.sqrt(np.mean((fitted - ys) ** 2))) if target == "branch_mean" else rmse_all
    return SpringFit(
        applicable=True,
        reason=f"least squares on the {'loop midline' if target == 'branch_mean' else 'samples'}",
        max_preload_mm=float(best_x[0]),
        zero_offset_deg=float(best_x[1]),
        rmse_nm=rmse,
        rmse_all_samples_nm=rmse_all,
        stiffness_n_per_mm=float(stiffness_n_per_mm),
        preload_position=int(preload_position),
        target=target,
        curve_angle_deg=xs,
        curve_torque_nm=ys,
        model_torque_nm=fitted,
    )
