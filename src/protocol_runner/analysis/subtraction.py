"""Removal of the robot's own torque: brace-on torque minus brace-off torque (thesis §3.3, §5.6).

The robot's weight, friction and hysteresis are present in every trial. The brace's own torque is the
brace-on torque minus the torque the bare robot needs *at the same angle, moving the same way*. The two
trials do not reach the same angles at the same times — with the brace fitted the joint lags more and
stalls at the robot's torque limit (±84.8 N·m, thesis §5) — so subtracting at equal times (what Schmidt did,
§5.6) compares the robot's torque at one angle with the brace-on torque at another, and mixes the robot's
gravity torque into the "brace" loop. `subtract_equal_angle` is the thesis's method; `subtract_equal_time`
is kept for comparison only.
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

    The brace-off trial (many cycles) is reduced to one angle -> torque curve per branch (`branch_curves`:
    mean torque per `bin_width_deg` angle bin over its complete branches, `complete_branches`: the partial
    branch of its start from rest and of its stop are left out, so that their transient torque is not
    subtracted from every brace-on cycle at those angles); each brace-on sample is labelled
    loading/unloading (`branch_labels`, reversal threshold `reversal_deg`, best on filtered data) and
    looks up its branch's curve by linear interpolation. Brace-on angles outside the brace-off branch's
    range take the nearest end value (`outside="clip"`, the default) or NaN (`outside="nan"`); the second
    returned array is True where the angle was inside the range.
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
    """Brace torque = brace-on torque - brace-off torque at the same angle on the same branch (thesis §3.3).

    Returns one value per brace-on sample (same length as `angle_on_deg`). See
    `robot_torque_at_equal_angle` for the branch logic and the `outside` rule (default: clip to the
    nearest covered angle; "nan" marks such samples NaN instead).
    """
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
    """Brace-on minus brace-off torque at equal time since each trial's start (§5.6; comparison only).

    Times are taken relative to each trial's first sample (pass both trials from their transition point
    on); the brace-off torque is linearly interpolated at the brace-on times and held at its ends. This
    is the method the thesis criticises in §5.6: the two trials are not at the same angle at the same
    time, so it is wrong whenever their angle histories differ.
    """
    t_on, q_on = signal_pair("time_on_s", time_on_s, "torque_on_nm", torque_on_nm)
    t_off, q_off = signal_pair("time_off_s", time_off_s, "torque_off_nm", torque_off_nm)
    if t_off.shape[0] > 1 and not np.all(np.diff(t_off) > 0):
        raise AnalysisError("time_off_s must be strictly increasing")
    return q_on - np.interp(t_on - t_on[0], t_off - t_off[0], q_off)
