"""Removal of the robot's own torque: brace-on minus brace-off torque (thesis §3.3, §5.6).

The brace's torque is the brace-on torque minus the bare robot's torque *at the same angle, moving the same
way*: `subtract_equal_angle`. Subtracting at equal times (`subtract_equal_time`, what §5.6 criticises) is
kept for comparison only; docs/analysis.md "4. Equal-angle subtraction" explains why it is wrong.
"""

from __future__ import annotations

from typing import TypedDict, Unpack

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.branches import (
    BranchCurves,
    Outside,
    branch_curves,
    branch_labels,
    complete_branches,
)
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, signal_pair


def robot_torque_at_equal_angle(
    angle_on_deg: npt.ArrayLike,
    angle_off_deg: npt.ArrayLike,
    torque_off_nm: npt.ArrayLike,
    *,
    bin_width_deg: float = 0.5,
    reversal_deg: float = 1.0,
    outside: Outside = "clip",
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """The bare robot's torque at each brace-on sample's angle and branch, and where that was covered.

    The brace-off trial's complete branches (`complete_branches`: the start from rest and the stop left
    out, so their transient is not subtracted from every brace-on cycle) become one binned curve per branch
    (`branch_curves`); each brace-on sample, labelled by `branch_labels`, interpolates its branch's curve.
    Angles outside a branch's range take its nearest end value (`outside="clip"`) or NaN (`"nan"`); the
    second array is True where the angle was inside the range.
    """
    a_on = as_signal("angle_on_deg", angle_on_deg)
    a_off, t_off = signal_pair("angle_off_deg", angle_off_deg, "torque_off_nm", torque_off_nm)
    keep = complete_branches(a_off, reversal_deg)
    curves: BranchCurves = branch_curves(
        a_off[keep], t_off[keep], bin_width_deg=bin_width_deg, labels=branch_labels(a_off, reversal_deg)[keep]
    )
    labels = branch_labels(a_on, reversal_deg)
    return curves.torque_at(a_on, labels, outside), curves.covers(a_on, labels)


class EqualAngleOptions(TypedDict, total=False):
    """The keyword options of `robot_torque_at_equal_angle` (their defaults are there)."""

    bin_width_deg: float
    reversal_deg: float
    outside: Outside


def subtract_equal_angle(
    angle_on_deg: npt.ArrayLike,
    torque_on_nm: npt.ArrayLike,
    angle_off_deg: npt.ArrayLike,
    torque_off_nm: npt.ArrayLike,
    **options: Unpack[EqualAngleOptions],
) -> FloatArray:
    """Brace torque = brace-on torque - brace-off torque at the same angle on the same branch (thesis §3.3),
    one value per brace-on sample (`robot_torque_at_equal_angle` gives the branch and `outside` rules)."""
    a_on, t_on = signal_pair("angle_on_deg", angle_on_deg, "torque_on_nm", torque_on_nm)
    a_off, t_off = signal_pair("angle_off_deg", angle_off_deg, "torque_off_nm", torque_off_nm)
    robot, _ = robot_torque_at_equal_angle(a_on, a_off, t_off, **options)
    return t_on - robot


def subtract_equal_time(
    time_on_s: npt.ArrayLike,
    torque_on_nm: npt.ArrayLike,
    time_off_s: npt.ArrayLike,
    torque_off_nm: npt.ArrayLike,
) -> FloatArray:
    """Brace-on minus brace-off torque at equal time since each trial's first sample (§5.6; comparison
    only: wrong whenever the two angle histories differ). The brace-off torque is linearly interpolated at
    the brace-on times and held at its ends."""
    t_on, q_on = signal_pair("time_on_s", time_on_s, "torque_on_nm", torque_on_nm)
    t_off, q_off = signal_pair("time_off_s", time_off_s, "torque_off_nm", torque_off_nm)
    if t_off.shape[0] > 1 and not np.all(np.diff(t_off) > 0):
        raise AnalysisError("time_off_s must be strictly increasing")
    return q_on - np.interp(t_on - t_on[0], t_off - t_off[0], q_off)
