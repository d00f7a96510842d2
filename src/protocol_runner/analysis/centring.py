"""Centring of a hysteresis loop on (0, 0) (thesis §6.2.3 note; docs/analysis.md "5. Centring").

Per trial, the mean angle and mean torque over its complete cycles (not the whole record, whose mean moves
with where the noise-dependent transition cut starts it) are subtracted and kept, so the loop can be put
back in place. A record with no complete cycle is centred on the mean of all its samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy.typing as npt

from protocol_runner.analysis.cycles import complete_cycles
from protocol_runner.analysis.validation import FloatArray, as_signal, same_length


@dataclass(frozen=True)
class CentredLoop:
    """A trial's angle and torque with their means over its complete cycles removed (thesis §6.2.3)."""

    angle_deg: FloatArray
    torque_nm: FloatArray
    mean_angle_deg: float
    mean_torque_nm: float


def complete_cycles_span(angle_deg: npt.ArrayLike) -> slice:
    """The samples from the start of a trial's first complete cycle to the end of its last (the whole
    trial when it has none)."""
    cycles = complete_cycles(angle_deg)
    if not cycles:
        return slice(None)
    return slice(cycles[0][0], cycles[-1][1])


def centre(angle_deg: npt.ArrayLike, torque_nm: npt.ArrayLike) -> CentredLoop:
    """Subtract the trial's mean angle and torque over its complete cycles (`complete_cycles_span`) from
    every sample (thesis §6.2.3 note); the loop keeps all its samples, only moved."""
    a = as_signal("angle_deg", angle_deg)
    t = as_signal("torque_nm", torque_nm)
    same_length(angle_deg=a, torque_nm=t)
    span = complete_cycles_span(a)
    mean_a = float(a[span].mean())
    mean_t = float(t[span].mean())
    return CentredLoop(
        angle_deg=a - mean_a, torque_nm=t - mean_t, mean_angle_deg=mean_a, mean_torque_nm=mean_t
    )
