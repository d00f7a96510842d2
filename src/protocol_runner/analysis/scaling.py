"""Brace-off input scaling (thesis §3.3.2, Eq 8, and a replacement for the lost Eq 9; docs/analysis.md §3).

The brace-off trial should sweep the brace-on trial's output angles, measured as cycle ranges
(`cycle_range`). Its input is an affine image of the original trajectory u(t): input_k = c_k + s_k ·
(u(t) - c_u), c_u the mid-range of u's cycles, s_0 = 1, c_0 = c_u. Each iteration runs the robot with
input_k, cuts the transition (§3.3.1: index 0 is the transition point) and measures the cycle range
[m_k, M_k] of the output. With the brace-on cycle range [m*, M*]:

    scale_k   = (M* - m*) / (M_k - m_k)                    (Eq 8, on the current brace-off output)
    s_{k+1}   = s_k · scale_k                              (amplitude correction)
    g_k       = (M_k - m_k) / (cycle range of input_k)     (the plant's observed range gain, in [0.2, 5])
    c_{k+1}   = c_k + ((M* + m*) - (M_k + m_k)) / (2 g_k)  (mid-range correction, a Newton step)

until both cycle levels are within `tolerance_deg` of the target or `max_iterations` runs were made; the
best iteration is kept. The input is clipped to `input_limits_deg` (the joint's safety range), so a target
that cannot be reached inside it ends without convergence (`converged=False`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.branches import turning_points
from protocol_runner.analysis.transition import transition_index
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length

_FLAT_DEG = 1e-9
"""A trajectory whose range is below this fraction of (1 + its mid-range) is flat to float precision."""


def range_scale(angle_on_deg: npt.ArrayLike, angle_off_deg: npt.ArrayLike) -> float:
    """Eq 8: brace-on output range divided by brace-off output range (both from the transition point on)."""
    on = as_signal("angle_on_deg", angle_on_deg)
    off = as_signal("angle_off_deg", angle_off_deg)
    span_off = float(off.max() - off.min())
    if span_off <= 0:
        raise AnalysisError("brace-off angle does not move: its range is zero, the Eq 8 scale is undefined")
    return float(on.max() - on.min()) / span_off


def cycle_range(angle_deg: npt.ArrayLike, reversal_deg: float = 1.0) -> tuple[float, float]:
    """(min, max) of a trial's cycles: the mean of its confirmed minima and of its confirmed maxima.

    Turning points are those of `branches.turning_points` (a reversal of at least `reversal_deg`), so the
    samples before the first reversal (the approach, the start-up) and after the last (the stop) set
    neither level. With fewer than one maximum and one minimum, the extremes of all samples.
    """
    x = as_signal("angle_deg", angle_deg)
    turns = turning_points(x, reversal_deg)
    if turns.size < 2:
        return float(x.min()), float(x.max())
    levels = x[turns]
    first_is_max = levels[0] > levels[1]
    maxima = levels[0 if first_is_max else 1 :: 2]
    minima = levels[1 if first_is_max else 0 :: 2]
    return float(minima.mean()), float(maxima.mean())


def lag_input(time_s: npt.ArrayLike, output_deg: npt.ArrayLike, time_constant_s: float) -> FloatArray:
    """The input u whose first-order-lag response is `output_deg`: u = y + tau * dy/dt (thesis §2.4.2).

    The servo follows its command as tau * dy/dt + y = u; feeding it the brace-on output y itself (what
    §3.3.2 prescribes) would return y lagged and attenuated once more, with its own speed profile.
    `output_deg` should be smooth (its derivative is taken by central differences).
    """
    t = as_signal("time_s", time_s, min_length=2)
    y = as_signal("output_deg", output_deg, min_length=2)
    same_length(time_s=t, output_deg=y)
    if not time_constant_s >= 0:
        raise AnalysisError(f"the servo time constant must not be negative, got {time_constant_s} s")
    return y + time_constant_s * np.gradient(y, t)


@dataclass(frozen=True)
class ScalingIteration:
    """One brace-off run of the scaling procedure."""

    iteration: int  # 0 = the unscaled input
    input_range_deg: tuple[float, float]  # (min, max) of the input that was run
    output_range_deg: tuple[float, float]  # cycle range (`cycle_range`) of its output after the transition
    scale: float  # Eq 8 scale of this output against the target
    range_error_deg: float  # max(|out_min - target_min|, |out_max - target_max|)
    transition_index: int


@dataclass(frozen=True)
class ScalingResult:
    """Outcome of `scale_brace_off_input` for one joint: the input to use, its output, and every iteration."""

    input_deg: FloatArray  # the input of the kept iteration
    output_deg: FloatArray  # what `run` returned for it
    converged: bool  # the kept iteration is within the tolerance
    history: tuple[ScalingIteration, ...]
    target_range_deg: tuple[float, float]
    kept: int  # the index in `history` of the kept iteration

    @property
    def best(self) -> ScalingIteration:
        """The kept iteration: for one joint the one with the smallest range error."""
        return self.history[self.kept]


def scale_brace_off_input(
    input_deg: npt.ArrayLike,
    target_range_deg: tuple[float, float],
    run: Callable[[FloatArray], FloatArray],
    *,
    tolerance_deg: float = 0.1,
    max_iterations: int = 6,
    transition_tolerance_deg: float = 5.0,
    transition_points: int = 3,
    input_limits_deg: tuple[float, float] | None = None,
    reversal_deg: float = 1.0,
) -> ScalingResult:
    """Iterate the brace-off input until its output's cycle range matches `target_range_deg`, the brace-on
    output's from its transition point on (§3.3.2, module docstring).

    `run(input_deg)` runs the robot without the brace and returns the measured angle on the time base of
    `input_deg` (see `rig_runner` for a rig). Each run's cycle range is measured from its own transition
    point, turning points confirmed by a reversal of `reversal_deg`.
    """
    (result,) = scale_brace_off_inputs(
        [input_deg],
        [target_range_deg],
        lambda inputs: [run(inputs[0])],
        tolerance_deg=tolerance_deg,
        max_iterations=max_iterations,
        transition_tolerance_deg=transition_tolerance_deg,
        transition_points=transition_points,
        input_limits_deg=[input_limits_deg],
        reversal_deg=reversal_deg,
    )
    return result


class _JointScaling:
    """One joint's state in the iteration: its input's shape, centre and amplitude, and its runs."""

    def __init__(
        self,
        input_deg: npt.ArrayLike,
        target_range_deg: tuple[float, float],
        limits_deg: tuple[float, float] | None,
        reversal_deg: float,
    ) -> None:
        u = as_signal("input_deg", input_deg, min_length=2)
        lo_t, hi_t = float(target_range_deg[0]), float(target_range_deg[1])
        if not (np.isfinite(lo_t) and np.isfinite(hi_t) and hi_t > lo_t):
            raise AnalysisError(f"target range must be (min, max) with max > min, got {target_range_deg}")
        if limits_deg is not None and not limits_deg[1] > limits_deg[0]:
            raise AnalysisError(f"input limits must be (min, max) with max > min, got {limits_deg}")
        u_mid = 0.5 * float(u.max() + u.min())
        if not float(u.max() - u.min()) > _FLAT_DEG * (1.0 + abs(u_mid)):
            raise AnalysisError(
                f"input_deg does not move (range {float(u.max() - u.min()):.3g} deg): a flat recording cannot "
                "be followed; check the brace-on recording it comes from"
            )
        self.u_lo, self.u_hi = cycle_range(u, reversal_deg)
        u_mid = 0.5 * (self.u_lo + self.u_hi)
        self.shape = u - u_mid
        self.centre, self.amplitude = u_mid, 1.0
        self.target = (lo_t, hi_t)
        self.limits = limits_deg
        self.history: list[ScalingIteration] = []
        self.runs: list[tuple[FloatArray, FloatArray]] = []

    def next_input(self, k: int) -> FloatArray:
        trial_input = self.centre + self.amplitude * self.shape
        if self.limits is not None:
            trial_input = np.clip(trial_input, self.limits[0], self.limits[1])
        if not float(trial_input.max() - trial_input.min()) > 0:  # the iteration lost the trajectory's shape
            lo_t, hi_t = self.target
            raise AnalysisError(
                f"scaling iteration {k}: the scaled brace-off input is constant at {float(trial_input[0]):.1f} "
                f"deg (clipped to the joint's limits, or the target range {lo_t:.1f}-{hi_t:.1f} deg is too "
                "small to follow); check the brace-on recording"
            )
        return trial_input

    def record(
        self,
        k: int,
        trial_input: FloatArray,
        returned: npt.ArrayLike,
        transition: tuple[float, int],
        reversal_deg: float,
    ) -> float:
        """Measure run `k`'s output cycle range; return its range error."""
        measured = as_signal("measured angle returned by run()", returned)
        same_length(input_deg=trial_input, measured_deg=measured)
        start = transition_index(trial_input, measured, *transition)
        lo_k, hi_k = cycle_range(measured[start:], reversal_deg)
        if not hi_k - lo_k > 0:
            raise AnalysisError(
                f"scaling iteration {k}: the brace-off output does not move after the transition"
            )
        lo_t, hi_t = self.target
        self.history.append(
            ScalingIteration(
                iteration=k,
                input_range_deg=(float(trial_input.min()), float(trial_input.max())),
                output_range_deg=(lo_k, hi_k),
                scale=(hi_t - lo_t) / (hi_k - lo_k),
                range_error_deg=max(abs(lo_k - lo_t), abs(hi_k - hi_t)),
                transition_index=start,
            )
        )
        self.runs.append((trial_input, measured))
        return self.history[-1].range_error_deg

    def correct(self) -> None:
        """The next input from the last run (module docstring): Eq 8 on the amplitude, a Newton step on the
        mid-range."""
        last = self.history[-1]
        (lo_t, hi_t), (lo_k, hi_k) = self.target, last.output_range_deg
        input_span = self.amplitude * (self.u_hi - self.u_lo)  # the run's input's cycle range (unclipped)
        gain = float(np.clip((hi_k - lo_k) / input_span, 0.2, 5.0))
        self.amplitude *= last.scale
        self.centre += 0.5 * ((hi_t + lo_t) - (hi_k + lo_k)) / gain

    def result(self, kept: int, tolerance_deg: float) -> ScalingResult:
        return ScalingResult(
            input_deg=self.runs[kept][0],
            output_deg=self.runs[kept][1],
            converged=self.history[kept].range_error_deg <= tolerance_deg,
            history=tuple(self.history),
            target_range_deg=self.target,
            kept=kept,
        )


def scale_brace_off_inputs(
    inputs_deg: Sequence[npt.ArrayLike],
    target_ranges_deg: Sequence[tuple[float, float]],
    run: Callable[[list[FloatArray]], Sequence[npt.ArrayLike]],
    *,
    tolerance_deg: float = 0.1,
    max_iterations: int = 6,
    transition_tolerance_deg: float = 5.0,
    transition_points: int = 3,
    input_limits_deg: Sequence[tuple[float, float] | None] | None = None,
    reversal_deg: float = 1.0,
) -> tuple[ScalingResult, ...]:
    """`scale_brace_off_input` for several joints moved together: `run(inputs)` runs them in one robot
    motion and returns each joint's measured angle. A joint once matched keeps its input while the others
    are corrected; the run kept for every joint is the one whose largest range error is smallest."""
    if not tolerance_deg > 0:
        raise AnalysisError(f"scaling tolerance must be positive, got {tolerance_deg} deg")
    if max_iterations < 1:
        raise AnalysisError(f"scaling needs at least one iteration, got {max_iterations}")
    limits = list(input_limits_deg) if input_limits_deg is not None else [None] * len(inputs_deg)
    joints = [
        _JointScaling(u, target, lim, reversal_deg)
        for u, target, lim in zip(inputs_deg, target_ranges_deg, limits, strict=True)
    ]
    matched = [False] * len(joints)
    for k in range(max_iterations):
        trial_inputs = [j.next_input(k) for j in joints]
        measured = run([x.copy() for x in trial_inputs])
        for n, (j, x, m) in enumerate(zip(joints, trial_inputs, measured, strict=True)):
            error = j.record(k, x, m, (transition_tolerance_deg, transition_points), reversal_deg)
            matched[n] = matched[n] or error <= tolerance_deg
        if all(matched):
            break
        for j, done in zip(joints, matched, strict=True):
            if not done:
                j.correct()
    kept = min(range(len(joints[0].history)), key=lambda i: max(j.history[i].range_error_deg for j in joints))
    return tuple(j.result(kept, tolerance_deg) for j in joints)


class RecordingLike(Protocol):
    """What `rig_runner` needs of a trial recording (hardware.rig.TrialRecording satisfies it)."""

    @property
    def command_time_s(self) -> npt.NDArray[np.float64]: ...
    @property
    def input_time_s(self) -> npt.NDArray[np.float64]: ...
    @property
    def angle_deg(self) -> npt.NDArray[np.float64]: ...


def rig_runner(run_trajectory: Callable[[FloatArray], RecordingLike]) -> Callable[[FloatArray], FloatArray]:
    """Adapt a one-joint rig (`lambda cmd: rig.run_trajectory([cmd], where=...)[0]`) to the `run` of
    `scale_brace_off_input`: the recording's angle linearly interpolated onto the command ticks."""

    def run(input_deg: FloatArray) -> FloatArray:
        rec = run_trajectory(input_deg)
        return np.interp(
            np.asarray(rec.command_time_s, dtype=np.float64),
            np.asarray(rec.input_time_s, dtype=np.float64),
            np.asarray(rec.angle_deg, dtype=np.float64),
        )

    return run
