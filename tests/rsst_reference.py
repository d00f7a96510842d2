"""The thesis's reference data the tests check the code against: the 12 actuated RSST joints (Tables
1-3) and the DT9814's 12-bit ±10 V code of a voltage (what the simulator's scan kernel computes)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware import conversions


@dataclass(frozen=True)
class RsstJoint:
    """One actuated RSST joint (thesis Tables 1-3): its number, name, Eq 1-2 angle range and Eq 3
    torque range."""

    number: int
    name: str
    range_deg: tuple[float, float]
    torque_range_nm: tuple[float, float]


RSST_JOINTS: dict[int, RsstJoint] = {
    j.number: j
    for j in (
        RsstJoint(1, "Shoulder Flexion", (-15.0, 180.0), (-45.2, 39.6)),
        RsstJoint(2, "Shoulder Abduction", (0.0, 90.0), (-45.2, 39.6)),
        RsstJoint(3, "Humerus Rotation", (-90.0, 90.0), (-28.3, 28.3)),
        RsstJoint(4, "Elbow Flexion", (0.0, 130.0), (-39.6, 31.0)),
        RsstJoint(5, "Wrist Rotation", (-90.0, 90.0), (-102.0, 56.5)),
        RsstJoint(6, "Hip Flexion", (0.0, 100.0), (-147.0, 147.0)),
        RsstJoint(7, "Hip Abduction", (0.0, 45.0), (-45.2, 226.0)),
        RsstJoint(8, "Thigh rotation", (-22.0, 22.0), (-56.5, 56.5)),
        RsstJoint(9, "Knee Flexion", (0.0, 130.0), (-84.8, 84.8)),
        RsstJoint(10, "Ankle Rotation", (-20.0, 20.0), (-56.5, 56.5)),
        RsstJoint(11, "Ankle Flexion", (-45.0, 30.0), (-79.1, 79.1)),
        RsstJoint(12, "Ankle Inversion", (-20.0, 20.0), (-56.5, 56.5)),
    )
}
"""The 12 actuated RSST joints by number (thesis Tables 1, 2 and 3)."""


def volts_to_ai12_code(volts: npt.ArrayLike) -> npt.NDArray[np.int32]:
    """DT9814 12-bit ±10 V two's-complement code: round(V * 4096 / 20), clamped to -2048..2047."""
    v = np.asarray(volts, dtype=np.float64)
    if np.isnan(v).any():
        raise InvalidInput("cannot convert NaN volts to an analog input code")
    k = np.rint(v / conversions.AI12_VOLTS_PER_CODE)
    result: npt.NDArray[np.int32] = np.clip(k, conversions.AI12_MIN_CODE, conversions.AI12_MAX_CODE).astype(
        np.int32
    )
    return result
