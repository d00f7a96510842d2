"""The element model fit recovers a damper and a brake from a loop made by equal-angle subtraction of a
robot whose own friction is five times the brake's: the samples just after each turning point, where the
subtraction cannot follow the robot's friction reversal, are not compared."""

from __future__ import annotations

import numpy as np

from protocol_runner.analysis.branches import turning_points
from protocol_runner.analysis.model_fit import fit_element_model
from protocol_runner.analysis.subtraction import robot_torque_at_equal_angle
from protocol_runner.models.element_model import Motion, layout
from protocol_runner.models.element_torques import dahl_update
from protocol_runner.models.elements import build_element

RATE_HZ = 200.0
PERIOD_S = 2.0 * np.pi * 45.0 / 20.0  # 20..110 deg at 20 deg/s peak speed (elbow_example's slow sine)


def dahl_nm(angle_deg: np.ndarray, level_nm: float, transition_deg: float) -> np.ndarray:
    out = np.zeros_like(angle_deg)
    z = 0.0
    for i in range(1, angle_deg.size):
        z = dahl_update(z, level_nm, angle_deg[i] - angle_deg[i - 1], transition_deg)
        out[i] = z
    return out


def subtracted_trial(seed: int) -> Motion:
    """One trial: the robot (2.5 N·m Dahl friction over 1.5 deg, 0.03 N·m per deg/s) with and without a
    brace (0.5 N·m brake over 2 deg, 0.02 N·m·s/deg damper), the same motion both times, 0.05 N·m noise;
    the brace's loop by equal-angle subtraction, as the processing makes it."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 4.0 * PERIOD_S, 1.0 / RATE_HZ)
    angle = 65.0 - 45.0 * np.cos(2.0 * np.pi * t / PERIOD_S)
    speed = np.gradient(angle, t)
    robot = dahl_nm(angle, 2.5, 1.5) + 0.03 * speed
    device = dahl_nm(angle, 0.5, 2.0) + 0.02 * speed
    on = robot + device + 0.05 * rng.standard_normal(t.size)
    off = robot + 0.05 * rng.standard_normal(t.size)
    subtracted, _ = robot_torque_at_equal_angle(angle, angle, off)
    return Motion.from_samples(t, angle, on - subtracted, max_step_deg=1.0, turning_points=turning_points)


def test_damper_and_brake_recovered_through_the_subtraction() -> None:
    elements = [
        build_element("damper", "viscous_damper", {"damping_nm_s_per_deg": 0.02}),
        build_element("brake", "coulomb_brake", {"torque_nm": 0.5, "transition_deg": 2.0}),
    ]
    fit = fit_element_model([subtracted_trial(seed) for seed in range(3)], layout(elements))
    # comparing every sample gave 0.0166 and 0.554 N·m: the damper's torque moved into the brake
    assert abs(fit.values[("damper", "damping_nm_s_per_deg")] / 0.02 - 1.0) < 0.03
    assert abs(fit.values[("brake", "torque_nm")] / 0.5 - 1.0) < 0.03
    damper = next(e for e in fit.estimates if e.element == "damper")
    assert damper.ci95_low <= 0.02 <= damper.ci95_high


def test_the_first_degree_after_a_turning_point_is_not_compared() -> None:
    t = np.arange(0.0, 2.0 * PERIOD_S, 1.0 / RATE_HZ)
    angle = 65.0 - 45.0 * np.cos(2.0 * np.pi * t / PERIOD_S)
    m = Motion.from_samples(t, angle, np.zeros_like(t), turning_points=turning_points)
    top = int(np.argmax(np.where(t < PERIOD_S, angle, 0.0)))  # the first maximum
    travel = np.abs(angle - angle[top])
    after = (np.arange(angle.size) > top) & (t < PERIOD_S)  # down to the first minimum
    assert not m.compared[after & (travel < 1.0)].any()
    assert m.compared[after & (travel > 1.0) & (angle > 60.0)].all()
    before = (np.arange(angle.size) < top) & (angle > 100.0)  # after the first 5 deg of travel
    assert m.compared[before].all()  # the approach to a turning point is compared
