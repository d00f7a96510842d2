"""The brace-off reference is built from its complete branches (branches.complete_branches): a trial starts
from rest, and the torque of that start (acceleration, static friction breaking away) must not be
subtracted from every brace-on cycle at the start angle. Found by a test engineer's ankle campaign: a
+3 N*m spike in every loop of a 0.5 N*m brake, and 0.14 J per cycle lost by no device at all."""

from __future__ import annotations

import numpy as np

from protocol_runner.analysis.branches import branch_curves, branch_labels, complete_branches
from protocol_runner.analysis.subtraction import subtract_equal_angle

RATE_HZ = 1000.0
PERIOD_S = 4.0
CYCLES = 5


def _trial(transient_nm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(time, angle, robot torque, branch) of a trial starting at rest at the sine's minimum (0 deg)."""
    t = np.arange(0.0, CYCLES * PERIOD_S, 1.0 / RATE_HZ)
    angle = 20.0 - 20.0 * np.cos(2.0 * np.pi * t / PERIOD_S)
    branch = branch_labels(angle)
    robot = 5.0 + 0.1 * angle + 2.0 * branch + transient_nm * np.exp(-t / 0.2)  # start-up: the first 0.5 s
    return t, angle, robot, branch


def test_the_start_up_torque_of_the_brace_off_trial_is_not_in_the_brace_loop() -> None:
    t, angle, robot_off, _ = _trial(transient_nm=4.0)
    _, _, robot_on, _ = _trial(transient_nm=0.0)
    brace = 0.2 * (angle - 20.0)  # the device's own torque
    got = subtract_equal_angle(angle, robot_on + brace, angle, robot_off)
    steady = t > PERIOD_S  # every cycle after the first
    assert np.max(np.abs(got[steady] - brace[steady])) < 0.02

    # what the reference was before: every brace-off sample averaged in, the start-up too
    curves = branch_curves(angle, robot_off)
    before = robot_on + brace - curves.torque_at(angle, branch_labels(angle))
    assert np.max(np.abs(before[steady] - brace[steady])) > 0.3  # at the start angle, in every cycle


def test_complete_branches_are_from_the_first_turning_point_to_the_last() -> None:
    _, angle, _, _ = _trial(transient_nm=0.0)
    kept = complete_branches(angle)
    first = round(PERIOD_S / 2 * RATE_HZ)  # the first maximum
    last = round((CYCLES - 0.5) * PERIOD_S * RATE_HZ)  # the last maximum (the trial ends at a minimum)
    assert abs(kept.start - first) <= 1 and abs(kept.stop - 1 - last) <= 1
    # under one cycle (one turning point): every sample is kept
    short = angle[: int(0.75 * PERIOD_S * RATE_HZ)]
    assert short[complete_branches(short)].size == short.size
