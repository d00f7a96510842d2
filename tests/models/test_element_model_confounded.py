"""A damper on a motion of constant speed gives a constant torque along each stroke, as a brake does: the
fit's estimates of the two are then nearly perfectly correlated, and each is noted as confounded with the
other. On a sinusoid, whose speed varies along each stroke, the two are told apart and no note is made."""

from __future__ import annotations

import numpy as np

from protocol_runner.analysis.branches import turning_points
from protocol_runner.analysis.model_fit import fit_element_model
from protocol_runner.models.element_model import Motion, layout
from protocol_runner.models.element_torques import dahl_update
from protocol_runner.models.elements import build_element

RATE_HZ = 100.0
ELEMENTS = [
    build_element("damper", "viscous_damper", {"damping_nm_s_per_deg": 0.02}),
    build_element("brake", "coulomb_brake", {"torque_nm": 0.5, "transition_deg": 2.0}),
]


def trial(angle_deg: np.ndarray, t: np.ndarray, seed: int) -> Motion:
    """The brace's torque (a 0.5 N·m brake over 2 deg and a 0.02 N·m·s/deg damper) with 0.02 N·m noise."""
    z, brake = 0.0, np.zeros_like(angle_deg)
    for i in range(1, angle_deg.size):
        z = dahl_update(z, 0.5, angle_deg[i] - angle_deg[i - 1], 2.0)
        brake[i] = z
    torque = brake + 0.02 * np.gradient(angle_deg, t)
    torque += 0.02 * np.random.default_rng(seed).standard_normal(t.size)
    return Motion.from_samples(t, angle_deg, torque, max_step_deg=1.0, turning_points=turning_points)


def fit_notes(shape: str) -> dict[str, str]:
    period_s = 9.0
    t = np.arange(0.0, 3.0 * period_s, 1.0 / RATE_HZ)
    phase = (t / period_s) % 1.0
    if shape == "triangle":  # 20..110 deg at a constant 20 deg/s, turning at the ends
        angle = 20.0 + 90.0 * (1.0 - np.abs(2.0 * phase - 1.0))
    else:
        angle = 65.0 - 45.0 * np.cos(2.0 * np.pi * phase)
    fit = fit_element_model([trial(angle, t, seed) for seed in range(3)], layout(ELEMENTS))
    return {f"{e.element}.{e.parameter}": e.note for e in fit.estimates}


def test_a_damper_on_constant_speed_is_noted_as_confounded_with_the_brake() -> None:
    notes = fit_notes("triangle")
    assert "confounded with brake.torque_nm" in notes["damper.damping_nm_s_per_deg"]
    assert "confounded with damper.damping_nm_s_per_deg" in notes["brake.torque_nm"]
    assert "combined torque" in notes["brake.torque_nm"]


def test_a_damper_on_a_sinusoid_is_told_apart_from_the_brake() -> None:
    notes = fit_notes("sinusoid")
    assert set(notes) >= {"damper.damping_nm_s_per_deg", "brake.torque_nm"}
    assert all("confounded" not in note for note in notes.values())
