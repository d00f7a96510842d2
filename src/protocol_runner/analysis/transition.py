"""Start-up transition detection and removal (thesis §3.3.1, §4.4; docs/analysis.md "1. Transition").

Recording starts while the joint still moves from where it was parked to the trajectory's first point; the
transition point is the first where the measured angle is within five degrees of the command for three
consecutive points. The command (100 Hz output ticks) is first brought onto the input time base (1 kHz).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length

Resampling = Literal["hold", "linear"]


def command_on_input_base(
    command_time_s: npt.ArrayLike,
    command_deg: npt.ArrayLike,
    input_time_s: npt.ArrayLike,
    method: Resampling = "hold",
) -> FloatArray:
    """Resample the commanded angle (output ticks, strictly increasing) onto the input sample times.

    `"hold"`: zero-order hold, the last tick at or before t (what the analog output holds; the first tick
    before it). `"linear"`: linear interpolation, end values held outside the ticks.
    """
    t_cmd = as_signal("command_time_s", command_time_s)
    cmd = as_signal("command_deg", command_deg)
    t_in = as_signal("input_time_s", input_time_s)
    same_length(command_time_s=t_cmd, command_deg=cmd)
    if t_cmd.shape[0] > 1 and not np.all(np.diff(t_cmd) > 0):
        raise AnalysisError("command_time_s: output tick times must be strictly increasing")
    if method == "hold":
        index = np.searchsorted(t_cmd, t_in, side="right") - 1
        return cmd[np.clip(index, 0, cmd.shape[0] - 1)]
    if method == "linear":
        return np.interp(t_in, t_cmd, cmd)
    raise AnalysisError(f"unknown command resampling method {method!r}: use 'hold' or 'linear'")


def transition_index(
    command_deg: npt.ArrayLike,
    measured_deg: npt.ArrayLike,
    tolerance_deg: float = 5.0,
    points: int = 3,
) -> int:
    """The first index i with |measured - command| <= `tolerance_deg` at samples i ... i+points-1 (thesis
    §3.3.1: five degrees, three points), both on one time base. Raises `AnalysisError` when there is none.
    """
    cmd = as_signal("command_deg", command_deg)
    meas = as_signal("measured_deg", measured_deg)
    n = same_length(command_deg=cmd, measured_deg=meas)
    if not tolerance_deg > 0:
        raise AnalysisError(f"transition tolerance must be positive, got {tolerance_deg} deg")
    if points < 1:
        raise AnalysisError(f"transition points must be at least 1, got {points}")
    within = np.abs(meas - cmd) <= tolerance_deg
    if n >= points:
        # run[i] = number of within-tolerance samples in [i, i + points)
        cumulative = np.concatenate(([0], np.cumsum(within, dtype=np.int64)))
        run = cumulative[points:] - cumulative[:-points]
        hits = np.flatnonzero(run == points)
        if hits.size:
            return int(hits[0])
    closest = float(np.min(np.abs(meas - cmd)))
    raise AnalysisError(
        f"transition never ends: the measured angle is never within {tolerance_deg} deg of the command for "
        f"{points} consecutive samples (closest approach {closest:.2f} deg over {n} samples); "
        "check the trial data or raise the transition tolerance"
    )


@dataclass(frozen=True)
class TrialSegment:
    """A trial from its transition point on (index 0 = transition point, thesis §3.3.2 note)."""

    time_s: FloatArray
    command_deg: FloatArray
    angle_deg: FloatArray
    torque_nm: FloatArray
    start_index: int  # index of the transition point in the original recording


def remove_transition(
    time_s: npt.ArrayLike,
    command_deg: npt.ArrayLike,
    angle_deg: npt.ArrayLike,
    torque_nm: npt.ArrayLike,
    *,
    tolerance_deg: float = 5.0,
    points: int = 3,
) -> TrialSegment:
    """The trial (all four arrays on the input time base) from its `transition_index` on; `time_s` keeps
    the original clock."""
    t = as_signal("time_s", time_s)
    cmd = as_signal("command_deg", command_deg)
    angle = as_signal("angle_deg", angle_deg)
    torque = as_signal("torque_nm", torque_nm)
    same_length(time_s=t, command_deg=cmd, angle_deg=angle, torque_nm=torque)
    start = transition_index(cmd, angle, tolerance_deg, points)
    return TrialSegment(
        time_s=t[start:].copy(),
        command_deg=cmd[start:].copy(),
        angle_deg=angle[start:].copy(),
        torque_nm=torque[start:].copy(),
        start_index=start,
    )
