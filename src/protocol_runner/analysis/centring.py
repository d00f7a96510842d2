"""Centring of a hysteresis loop on (0, 0) (thesis §6.2.3 note).

The knee's loops are not centred on the origin (there are no negative angles), so before the Bouc-Wen
fit "all the values were subtracted of the trial average". Centring is per trial: the trial's mean angle
and mean torque are subtracted and kept, so the loop can be put back in place.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy.typing as npt

from protocol_runner.analysis.validation import FloatArray, as_signal, same_length


@dataclass(frozen=True)
class CentredLoop:
    """A trial's angle and torque with their trial means removed (thesis §6.2.3)."""

    angle_deg: FloatArray
    torque_nm: FloatArray
    mean_angle_deg: float
    mean_torque_nm: float


def centre(angle_deg: npt.ArrayLike, torque_nm: npt.ArrayLike) -> CentredLoop:
    """Subtract the trial mean from angle and torque (thesis §6.2.3 note); both results have zero mean."""
    a = as_signal("angle_deg", angle_deg)
    t = as_signal("torque_nm", torque_nm)
    same_length(angle_deg=a, torque_nm=t)
    mean_a = float(a.mean())
    mean_t = float(t.mean())
    return CentredLoop(
        angle_deg=a - mean_a, torque_nm=t - mean_t, mean_angle_deg=mean_a, mean_torque_nm=mean_t
    )
