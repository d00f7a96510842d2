"""Energy lost per cycle of the brace (thesis §5.7, Eq 10-12; docs/analysis.md "7. Energy per cycle").

E = ∮ T dθ (Eq 10) over one complete cycle, by the trapezoid rule over the samples (Eq 11), degrees
converted by π/180 to give joules (Eq 12). Positive values are energy dissipated: a clockwise loop in the
(angle, torque) plane, loading torque above unloading. The sum is closed by the segment from the last
sample back to the first, which makes it exactly the area of the sampled loop (the shoelace formula),
independent of a constant torque offset and of an angle shift.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.cycles import Reference, complete_cycles
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length

DEG_TO_RAD = np.pi / 180.0


def loop_integral_deg_nm(angle_deg: npt.ArrayLike, torque_nm: npt.ArrayLike) -> float:
    """Eq 11: Σ (T[i+1] + T[i]) / 2 · (θ[i+1] - θ[i]) over the samples, closed back to the first sample.

    Units deg·N·m. Positive for a clockwise (dissipative) loop in the (angle, torque) plane.
    """
    a = as_signal("angle_deg", angle_deg, min_length=2)
    t = as_signal("torque_nm", torque_nm, min_length=2)
    same_length(angle_deg=a, torque_nm=t)
    a_closed = np.append(a, a[0])
    t_closed = np.append(t, t[0])
    return float(np.sum(0.5 * (t_closed[1:] + t_closed[:-1]) * np.diff(a_closed)))


def cycle_energy_j(angle_deg: npt.ArrayLike, torque_nm: npt.ArrayLike) -> float:
    """Energy lost over one closed cycle, in joules (Eq 11 times π/180, Eq 12)."""
    return loop_integral_deg_nm(angle_deg, torque_nm) * DEG_TO_RAD


def energy_per_cycle(
    angle_deg: npt.ArrayLike,
    torque_nm: npt.ArrayLike,
    *,
    hysteresis_deg: float | None = None,
    reference: Reference = "mean",
) -> FloatArray:
    """Energy lost in each complete cycle (`cycles.complete_cycles`) of a trial, in joules (thesis §5.7,
    Eq 10-12); empty when the trial holds no complete cycle."""
    a = as_signal("angle_deg", angle_deg)
    t = as_signal("torque_nm", torque_nm)
    same_length(angle_deg=a, torque_nm=t)
    bounds = complete_cycles(a, hysteresis_deg=hysteresis_deg, reference=reference)
    return np.array([cycle_energy_j(a[s : e + 1], t[s : e + 1]) for s, e in bounds], dtype=np.float64)


@dataclass(frozen=True)
class EnergySummary:
    """Mean, sample standard deviation (ddof=1; NaN for fewer than two cycles) and count of cycles."""

    mean_j: float
    std_j: float
    n: int


def summarize_energy(energies_j: npt.ArrayLike | Sequence[npt.ArrayLike]) -> EnergySummary:
    """Mean, standard deviation and count of per-cycle energies, pooled over one or several trials."""
    if isinstance(energies_j, Sequence) and not isinstance(energies_j, np.ndarray):
        parts = [np.asarray(e, dtype=np.float64).ravel() for e in energies_j]
        values = np.concatenate(parts) if parts else np.zeros(0)
    else:
        values = np.asarray(energies_j, dtype=np.float64).ravel()
    if values.size and not np.all(np.isfinite(values)):
        raise AnalysisError("energy per cycle: every value must be a finite number")
    n = int(values.size)
    if n == 0:
        return EnergySummary(mean_j=float("nan"), std_j=float("nan"), n=0)
    std = float(np.std(values, ddof=1)) if n > 1 else float("nan")
    return EnergySummary(mean_j=float(values.mean()), std_j=std, n=n)
