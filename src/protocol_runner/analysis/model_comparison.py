"""Model comparison of one configuration (and joint), side by side on the same trials (docs/analysis.md
§10): ``elements`` (the element model, `analysis.model_fit`), ``dahl`` (the elastic elements plus a plain
Dahl friction: what a two-parameter hysteresis adds to the springs) and ``bouc_wen`` (the fit step's
generalised Bouc-Wen model with its backbone; k counts its eight parameters and the backbone's
coefficients).

For each: k, RMSE, held-out RMSE with the trial as the unit (element-model refits start from the fit on
every trial and stop at HELDOUT_TOL; the Bouc-Wen one is the fit's own cross-validation), AIC = n_eff
ln(SSE / n) + 2k and BIC = n_eff ln(SSE / n) + k ln(n_eff) with the element model's n_eff for every model
(so that the differences compare), and the model's and data's loop energy per cycle (flagged beyond
ENERGY_FLAG). For the mostly unidentified Bouc-Wen parameters, what the loops do determine is reported
instead, each with a 95 % t-interval over the trials: the model's loop energy per cycle, its half-width
(energy over twice the angle span, N·m) and its backbone slope.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import stdtrit

from ..models.element_model import FloatArray, ModelLayout, Motion, layout, model_torque_nm
from ..models.elements import Element
from .branches import turning_points
from .energy import energy_per_cycle
from .model_fit import ElementModelFit, Problem, fit_element_model, mean_energy_j, sum_of_squares

ENERGY_FLAG = 0.03  # |model - data| / data above this: flagged
MODELS = ("elements", "dahl", "bouc_wen")
MOTION_STEP_DEG = 1.0  # the fit samples each trial at about this much travel (median step)
HELDOUT_TOL = 1e-3  # least_squares ftol and xtol of the held-out refits (module docstring)


@dataclass(frozen=True)
class ModelRow:
    """One model's line of the comparison (NaN where a number does not exist)."""

    model: str
    k: int
    rmse_nm: float
    heldout_rmse_nm: float
    aic: float
    bic: float
    energy_model_j: float
    energy_data_j: float

    @property
    def energy_error(self) -> float:
        return (
            (self.energy_model_j - self.energy_data_j) / self.energy_data_j
            if self.energy_data_j
            else math.nan
        )

    @property
    def energy_flag(self) -> bool:
        """The model's loop energy differs from the data's by more than ENERGY_FLAG."""
        return bool(math.isfinite(self.energy_error) and abs(self.energy_error) > ENERGY_FLAG)


@dataclass(frozen=True)
class Functional:
    """A quantity a fitted model determines well, with a 95 % interval over the trials."""

    name: str
    unit: str
    value: float
    ci95_low: float
    ci95_high: float


@dataclass(frozen=True)
class ModelComparison:
    """The comparison of one configuration (and joint)."""

    rows: tuple[ModelRow, ...]
    element_fit: ElementModelFit | None
    bouc_wen_functionals: tuple[Functional, ...] = ()
    motions: tuple[Motion, ...] = field(default=(), repr=False)
    bouc_wen_identified: tuple[bool, ...] = ()  # A, n, β1-β6: not named by the fit's weak reasons


def motions_of(trials: Sequence[tuple[FloatArray, FloatArray, FloatArray]]) -> tuple[Motion, ...]:
    """The fit's view of stored processed trials `(time_s, angle_deg, brace_torque_nm)`: sampled at
    about one degree of travel, the samples just after each turning point not compared
    (`Motion.from_samples`)."""
    return tuple(
        Motion.from_samples(t, a, y, max_step_deg=MOTION_STEP_DEG, turning_points=turning_points)
        for t, a, y in trials
    )


def reduced_layout(elements: Sequence[Element], angle_deg: FloatArray) -> ModelLayout:
    """The elastic elements and one plain Dahl friction (no stops, dampers or Stribeck excess)."""
    kept = [e for e in elements if e.kind == "elastic" or e.type in ("mass", "coulomb_brake")]
    lay = layout(kept, angle_deg=angle_deg)
    if not lay.friction_members:
        from ..models.elements import build_element

        brake = build_element("dry_friction", "coulomb_brake", {"torque_nm": 0.0})
        lay = layout([*kept, brake], angle_deg=angle_deg)
    return replace(lay, excess_ratio=0.0)


def heldout_rmse_nm(motions: Sequence[Motion], fit: ElementModelFit) -> float:
    """Leave one trial out: each trial predicted by the model refitted on the others (NaN for one trial).
    Each refit starts from the fit on every trial and stops at HELDOUT_TOL (module docstring)."""
    if len(motions) < 2:
        return math.nan
    lay = fit.layout
    x0 = np.array([fit.values[key] for key in lay.free])
    sq, count = 0.0, 0
    for i, m in enumerate(motions):
        x = x0
        if lay.free:
            x = np.asarray(
                Problem.of(lay, [o for j, o in enumerate(motions) if j != i]).solve(x0, HELDOUT_TOL).x
            )
        r = (model_torque_nm(lay, lay.values(x), m) - m.torque_nm)[m.compared]
        sq += float(r @ r)
        count += r.size
    return math.sqrt(sq / count) if count else math.nan


def _information(sse: float, n: int, n_eff: float, k: int) -> tuple[float, float]:
    if not (n and sse > 0 and n_eff > 0):
        return math.nan, math.nan
    fit_term = n_eff * math.log(sse / n)
    return fit_term + 2.0 * k, fit_term + k * math.log(n_eff)


def _row(name: str, motions: Sequence[Motion], fit: ElementModelFit, n_eff: float, e_data: float) -> ModelRow:
    aic, bic = _information(fit.sse, fit.n_samples, n_eff, fit.k)
    return ModelRow(
        name,
        fit.k,
        fit.rmse_nm,
        heldout_rmse_nm(motions, fit),
        aic,
        bic,
        mean_energy_j(motions, fit.models),
        e_data,
    )


def _interval(values: Sequence[float]) -> tuple[float, float, float]:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=np.float64)
    if v.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(np.mean(v))
    if v.size < 2:
        return mean, math.nan, math.nan
    half = float(stdtrit(v.size - 1, 0.975)) * float(np.std(v, ddof=1)) / math.sqrt(v.size)
    return mean, mean - half, mean + half


def bouc_wen_functionals(
    segments: Sequence[tuple[FloatArray, FloatArray]], models: Sequence[FloatArray]
) -> tuple[Functional, ...]:
    """Loop energy, half-width and backbone slope of the fitted Bouc-Wen model, per trial, with their
    95 % intervals over the trials (module docstring)."""
    energy, half, slope = [], [], []
    for (x, _), z in zip(segments, models, strict=True):
        if not np.all(np.isfinite(z)) or x.size < 3:
            continue
        cycles = energy_per_cycle(x, z)
        e = float(np.mean(cycles)) if cycles.size else math.nan
        energy.append(e)
        span_rad = math.radians(float(np.ptp(x)))
        half.append(e / (2.0 * span_rad) if span_rad > 0 else math.nan)
        slope.append(float(np.polyfit(x, z, 1)[0]))
    out = []
    for name, unit, values in (
        ("loop energy per cycle", "J", energy),
        ("loop half-width", "N*m", half),
        ("backbone slope", "N*m/deg", slope),
    ):
        out.append(Functional(name, unit, *_interval(values)))
    return tuple(out)


def compare_models(
    trials: Sequence[tuple[FloatArray, FloatArray, FloatArray]],
    elements: Sequence[Element],
    bouc_wen: object | None = None,
) -> ModelComparison:
    """The comparison of one configuration: `trials` its stored processed trials (time_s, angle_deg,
    brace_torque_nm), `elements` its declared device, `bouc_wen` its `analysis.service.BoucWenResult`
    (None when the Bouc-Wen fit did not run)."""
    motions = motions_of(trials)
    angles = np.concatenate([m.angle_deg for m in motions])
    e_data = mean_energy_j(motions, [m.torque_nm for m in motions])
    full = fit_element_model(motions, layout(elements, angle_deg=angles))
    reduced = fit_element_model(motions, reduced_layout(elements, angles))
    rows = [
        _row("elements", motions, full, full.n_eff, e_data),
        _row("dahl", motions, reduced, full.n_eff, e_data),
    ]
    functionals: tuple[Functional, ...] = ()
    identified: tuple[bool, ...] = ()
    if bouc_wen is not None:
        rows.append(_bouc_wen_row(bouc_wen, full.n_eff))
        functionals = bouc_wen_functionals(bouc_wen.segments, bouc_wen.model_torque_nm)  # type: ignore[attr-defined]
        identified = bouc_wen_identified(bouc_wen.fit.weak_reasons)  # type: ignore[attr-defined]
    return ModelComparison(tuple(rows), full, functionals, motions, identified)


def bouc_wen_identified(weak_reasons: Sequence[str]) -> tuple[bool, ...]:
    """Per Bouc-Wen parameter (A, n, β1-β6), whether the fit's identification check leaves it out of its
    weak reasons (each reason starts with the parameter's dimensionless name: `a` for A, `psi'k` for βk)."""
    from ..models.bouc_wen.identifiability import DIMENSIONLESS_NAMES

    return tuple(not any(r.startswith(f"{name}:") for r in weak_reasons) for name in DIMENSIONLESS_NAMES)


def _bouc_wen_row(result: object, n_eff: float) -> ModelRow:
    fit = result.fit  # type: ignore[attr-defined]
    segments = result.segments  # type: ignore[attr-defined]
    models = result.model_torque_nm  # type: ignore[attr-defined]
    backbone = fit.backbone
    coef = getattr(backbone, "coef", ()) if backbone is not None else ()
    k = 8 + len(coef)
    r = np.concatenate([z - y for (_, y), z in zip(segments, models, strict=True)])
    n = r.size
    sse = sum_of_squares(r) if np.all(np.isfinite(r)) else math.nan
    cv = [float(v) for v in result.cv_rmse_nm]  # type: ignore[attr-defined]
    heldout = math.sqrt(float(np.mean(np.square(cv)))) if cv else math.nan
    aic, bic = _information(sse, n, n_eff, k)
    energy = result.energy  # type: ignore[attr-defined]
    return ModelRow(
        "bouc_wen", k, float(fit.rmse_nm), heldout, aic, bic, float(energy.model_j), float(energy.data_j)
    )


def compare_stored(
    trials: Sequence[tuple[FloatArray, FloatArray, FloatArray]],
    device: Sequence[object],
    bouc_wen: object | None = None,
) -> ModelComparison:
    """`compare_models` for a device given as ElementSetting-like objects (the protocol's)."""
    from ..models.elements import build_device

    return compare_models(trials, build_device(list(device)), bouc_wen)
