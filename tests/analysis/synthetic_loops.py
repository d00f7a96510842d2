"""A known joint for the loop and service fact tests: a 0.3 N*m/deg spring (neutral 40 deg) plus a Bouc-Wen loop
that saturates at 4 N*m, swept +-45 deg about 65 deg; and a device that declares a torsion spring, whose
stiffness and neutral angle the element fit finds."""

from __future__ import annotations

import numpy as np

from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate

HYSTERESIS = BoucWenParams(A=2.0, n=1.0, beta=(0.5, 0.0, 0.0, 0.0, 0.0, 0.0))  # saturates at 4 N*m
SPRING = [("torsion", "torsion_spring", {"stiffness_nm_per_deg": 0.1, "neutral_deg": 0.0})]


def spring_and_loop_trials() -> list[tuple[np.ndarray, np.ndarray]]:
    """Two uncentred trials (angle, torque) of two cycles each, the second offset by 0.05 N*m."""
    t = np.arange(0.0, 12.0, 0.05)
    centred = -45.0 * np.cos(2.0 * np.pi * t / 6.0)
    angle = 65.0 + centred
    torque = 0.3 * (angle - 40.0) + simulate(centred, HYSTERESIS, z0=-4.0)
    return [(angle, torque), (angle, torque + 0.05)]
