"""The complete commanded stream of one motion: approach, trajectory, exit - and a stop from any sample
(docs/hardware-model.md, "The complete commanded stream").

Everything sent during a trial or a calibration check is one stream in one paced loop (a pause would hold
the output, i.e. stop a moving joint at once). The **approach** runs from rest at the park angle to the
trajectory's first sample, arriving with its starting velocity; the **trajectory** is sent unchanged; the
**exit** brakes at the acceleration limit from the last sample's position and velocity, then follows the
parking ramp (`safety.parking_ramp_deg`) to the park angle. A **stop** requested at any sample replaces the
rest of the stream with the same exit from that sample. Braking at the full limit is the shortest stop, so
a brake never goes further than the trajectory itself could; the approach is the exit run backwards in time
(reversal keeps |rate| and |acceleration|), so one construction serves both junctions. `check_stream` runs
the envelope over the whole stream and over the stop from every sample before the exit; the plan-time
preflight (`protocol/stream_check.py`) and the rig's motions (`hardware/motion.py`) both call it.

A motion drives every joint of the rig: `build_motion_stream` aligns the joints' streams so that every first
trajectory sample falls on the same tick (a shorter approach waits at rest where it starts, a shorter exit
rests at its park angle). Resting repeats a sample and adds no rate or acceleration, so each aligned stream
is within its joint's envelope exactly when its own stream is (`check_motion_stream`). A stop after
`written` ticks stops EVERY joint, each braking from its own last position and velocity to its own park
angle, the tails padded to the longest at rest. With one joint all of this is that joint's own stream.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.safety import (
    SafetyLimits,
    SafetyViolation,
    check_trajectory,
    parking_ramp_deg,
)

FloatArray = npt.NDArray[np.float64]

APPROACH, TRAJECTORY, EXIT, STOP = 0, 1, 2, 3
SEGMENT_NAMES = {APPROACH: "approach", TRAJECTORY: "trajectory", EXIT: "exit", STOP: "stop"}
"""Segment codes, one per commanded sample (archived as `stream/segment`)."""

MAX_BRAKE_SAMPLES = 100_000
"""A brake longer than this (1000 s at 100 Hz) means limits that cannot stop the joint: refused."""


def _brake_step_deg(limits: SafetyLimits, rate_hz: float) -> float:
    return limits.max_accel_deg_s2 / (rate_hz * rate_hz)


def brake_deg(prev_deg: float, cur_deg: float, limits: SafetyLimits, rate_hz: float) -> FloatArray:
    """The samples after `cur_deg` that bring the velocity (cur - prev) * rate to zero, decreasing the
    per-tick step by the acceleration limit each tick; the last sample repeats the rest point (velocity 0).
    Empty when the joint is already at rest."""
    d = float(cur_deg) - float(prev_deg)
    if d == 0.0:
        return np.zeros(0, dtype=np.float64)
    step = _brake_step_deg(limits, rate_hz)
    n = max(0, math.ceil(abs(d) / step) - 1)  # ticks still moving
    if n > MAX_BRAKE_SAMPLES:
        raise InvalidInput(
            f"safety limits: braking from {abs(d) * rate_hz:g} deg/s at max_accel_deg_s2 = "
            f"{limits.max_accel_deg_s2:g} takes more than {MAX_BRAKE_SAMPLES} samples"
        )
    speeds = np.append(abs(d) - step * np.arange(1, n + 1, dtype=np.float64), 0.0)
    result: FloatArray = float(cur_deg) + math.copysign(1.0, d) * np.cumsum(speeds)
    return result


def brake_distance_deg(step_deg: npt.ArrayLike, limits: SafetyLimits, rate_hz: float) -> FloatArray:
    """How far `brake_deg` travels from a per-tick step of `step_deg` (vectorised; signed like the step)."""
    d = np.asarray(step_deg, dtype=np.float64)
    a = _brake_step_deg(limits, rate_hz)
    m = np.abs(d)
    n = np.maximum(np.ceil(m / a) - 1.0, 0.0)
    result: FloatArray = np.sign(d) * (n * m - a * n * (n + 1.0) / 2.0)
    return result


def stop_tail_deg(
    prev_deg: float, cur_deg: float, limits: SafetyLimits, rate_hz: float, *, to_deg: float | None = None
) -> FloatArray:
    """The samples after `cur_deg`: brake to rest, then the parking ramp to `to_deg` (default: the park
    angle). Empty when the joint is already at rest there."""
    brake = brake_deg(prev_deg, cur_deg, limits, rate_hz)
    rest = float(brake[-1]) if brake.size else float(cur_deg)
    target = limits.park_angle_deg if to_deg is None else float(to_deg)
    ramp = parking_ramp_deg(rest, replace(limits, park_angle_deg=target), rate_hz)
    return np.concatenate([brake, ramp[1:]])


def approach_deg(
    first_deg: float, second_deg: float, limits: SafetyLimits, rate_hz: float, *, from_deg: float
) -> FloatArray:
    """The samples before `first_deg`, starting at rest at `from_deg` and arriving with the velocity
    (second - first) * rate: the exit from (second, first) run backwards."""
    return stop_tail_deg(second_deg, first_deg, limits, rate_hz, to_deg=from_deg)[::-1].copy()


@dataclass(frozen=True)
class CommandStream:
    """Every sample one motion sends (real joint angles, one per output tick) and its segment code."""

    command_deg: FloatArray
    segment: npt.NDArray[np.int8]
    rate_hz: float

    @property
    def first(self) -> int:
        """Index of the trajectory's first sample."""
        return int(np.argmax(self.segment == TRAJECTORY))

    @property
    def exit_start(self) -> int:
        """Index of the first exit sample (the stream's length if there is none)."""
        after = np.flatnonzero(self.segment >= EXIT)
        return int(after[0]) if after.size else int(self.segment.size)

    def time_s(self) -> FloatArray:
        """Sample times from the trajectory's first sample (negative during the approach)."""
        result: FloatArray = (np.arange(self.segment.size, dtype=np.float64) - self.first) / self.rate_hz
        return result

    def stop_after(self, written: int, limits: SafetyLimits) -> tuple[FloatArray, npt.NDArray[np.int8]]:
        """What to send after the first `written` samples when a stop is requested: the rest of the exit if
        it has begun, else the brake and parking ramp from the last written sample's position and velocity.
        Returns the samples and their segment codes."""
        if written <= 0:  # nothing sent yet: the joint is still at rest where it was
            return np.zeros(0, dtype=np.float64), np.zeros(0, dtype=np.int8)
        if written >= self.exit_start:
            return self.command_deg[written:], self.segment[written:]
        cur = float(self.command_deg[written - 1])
        prev = float(self.command_deg[written - 2]) if written >= 2 else cur
        tail = stop_tail_deg(prev, cur, limits, self.rate_hz)
        return tail, np.full(tail.size, STOP, dtype=np.int8)


def build_stream(
    trajectory_deg: npt.ArrayLike, limits: SafetyLimits, rate_hz: float, *, from_deg: float | None = None
) -> CommandStream:
    """Approach (from rest at `from_deg`, default the park angle) + trajectory + exit to the park angle."""
    cmd = np.asarray(trajectory_deg, dtype=np.float64)
    if cmd.ndim != 1 or cmd.size == 0:
        raise InvalidInput(f"a trajectory must be a non-empty 1-D array of angles, got shape {cmd.shape}")
    if not np.all(np.isfinite(cmd)):
        raise InvalidInput("a trajectory must contain finite angles only")
    start = limits.park_angle_deg if from_deg is None else float(from_deg)
    second = float(cmd[1]) if cmd.size > 1 else float(cmd[0])
    before_last = float(cmd[-2]) if cmd.size > 1 else float(cmd[-1])
    try:
        approach = approach_deg(float(cmd[0]), second, limits, rate_hz, from_deg=start)
        exit_ = stop_tail_deg(before_last, float(cmd[-1]), limits, rate_hz)
    except InvalidInput:
        # a junction that cannot be built (a brake or ramp too long) comes from samples far outside the
        # envelope: name what the trajectory itself breaks (SafetyViolation) when it does
        check_trajectory(cmd, rate_hz, limits, where="trajectory")
        raise
    segment = np.concatenate(
        [
            np.full(approach.size, APPROACH, dtype=np.int8),
            np.full(cmd.size, TRAJECTORY, dtype=np.int8),
            np.full(exit_.size, EXIT, dtype=np.int8),
        ]
    )
    return CommandStream(np.concatenate([approach, cmd, exit_]), segment, float(rate_hz))


def stop_points_deg(stream: CommandStream, limits: SafetyLimits) -> FloatArray:
    """Where the joint comes to rest if a stop is requested after sample k, for every k before the exit
    (k = 0 is at rest already). The brake is monotonic and the parking ramp runs between two in-range
    angles, so these points are the only new extremes a stop can reach."""
    cmd = stream.command_deg[: max(stream.exit_start, 1)]
    steps = np.diff(cmd, prepend=cmd[0])
    result: FloatArray = cmd + brake_distance_deg(steps, limits, stream.rate_hz)
    return result


def check_stream(
    stream: CommandStream,
    limits: SafetyLimits,
    *,
    where: str,
    command_table: CalibrationTable | None = None,
    volts_range_deg: tuple[float, float] | None = None,
) -> None:
    """Raise `SafetyViolation` if any sample of the stream, or the rest point of a stop after any sample
    before the exit, leaves the envelope (range, volts, rate, acceleration). The message names the segment
    and the time from the trajectory's first sample."""
    times = stream.time_s()
    try:
        check_trajectory(
            stream.command_deg,
            stream.rate_hz,
            limits,
            where=where,
            command_table=command_table,
            volts_range_deg=volts_range_deg,
        )
    except SafetyViolation as exc:
        i = min(exc.index, stream.segment.size - 1)
        where_ = f"{where} ({SEGMENT_NAMES[int(stream.segment[i])]})"
        raise replace(exc, where=where_, index=exc.index - stream.first, time_s=float(times[i])) from None
    stops = stop_points_deg(stream, limits)
    try:
        check_trajectory(
            stops,
            stream.rate_hz,
            limits,
            where=where,
            command_table=command_table,
            volts_range_deg=volts_range_deg,
            derivatives=False,
        )
    except SafetyViolation as exc:
        i = exc.index
        segment = SEGMENT_NAMES[int(stream.segment[i])]
        where_ = f"{where} (a stop requested during the {segment} brakes to {exc.value:.6g} {exc.units})"
        raise replace(exc, where=where_, index=i - stream.first, time_s=float(times[i])) from None


@dataclass(frozen=True)
class MotionStream:
    """Aligned streams (equal length, same first trajectory tick), one per joint in channel order."""

    joints: tuple[str, ...]
    streams: tuple[CommandStream, ...]

    @property
    def rate_hz(self) -> float:
        return self.streams[0].rate_hz

    @property
    def first(self) -> int:
        return self.streams[0].first

    def command_deg(self) -> FloatArray:
        """(ticks, joints): every joint's angle per output tick."""
        return np.stack([s.command_deg for s in self.streams], axis=1)

    def segment(self) -> npt.NDArray[np.int8]:
        """(ticks, joints): every joint's segment code per tick."""
        return np.stack([s.segment for s in self.streams], axis=1)

    def stop_after(
        self, written: int, limits: Sequence[SafetyLimits]
    ) -> tuple[FloatArray, npt.NDArray[np.int8]]:
        """(ticks, joints) samples and segment codes that stop every joint after `written` ticks: each
        joint's own brake and parking ramp (`CommandStream.stop_after`), padded to the longest at rest."""
        tails = [s.stop_after(written, lim) for s, lim in zip(self.streams, limits, strict=True)]
        n = max(t.size for t, _ in tails)
        if n == 0:
            return np.zeros((0, len(self.streams))), np.zeros((0, len(self.streams)), dtype=np.int8)
        cols, codes = [], []
        for s, (tail, code) in zip(self.streams, tails, strict=True):
            rest = float(tail[-1]) if tail.size else float(s.command_deg[max(written, 1) - 1])
            pad = n - tail.size
            cols.append(np.concatenate([tail, np.full(pad, rest)]))
            last = int(code[-1]) if code.size else STOP
            codes.append(np.concatenate([code, np.full(pad, last, dtype=np.int8)]).astype(np.int8))
        return np.stack(cols, axis=1), np.stack(codes, axis=1)


def build_motion_stream(
    joints: Sequence[str],
    trajectories_deg: Sequence[npt.ArrayLike],
    limits: Sequence[SafetyLimits],
    rate_hz: float,
    *,
    from_deg: Sequence[float | None] | None = None,
) -> MotionStream:
    """Each joint's stream (`build_stream`) aligned on the first trajectory tick. The trajectories must
    have the same number of samples (the joints share the trial's time)."""
    arrays = [np.asarray(t, dtype=np.float64) for t in trajectories_deg]
    if len(arrays) != len(joints):
        raise InvalidInput(
            f"a motion of {len(joints)} joint(s) ({', '.join(joints)}) needs one trajectory per joint, "
            f"got {len(arrays)}"
        )
    if len({a.size for a in arrays}) != 1:
        shown = ", ".join(f"{j} {a.size}" for j, a in zip(joints, arrays, strict=True))
        raise InvalidInput(f"the joints of a motion must have as many samples each, got {shown}")
    starts = list(from_deg) if from_deg is not None else [None] * len(arrays)
    own = [
        build_stream(a, lim, rate_hz, from_deg=f) for a, lim, f in zip(arrays, limits, starts, strict=True)
    ]
    lead = max(s.first for s in own)
    tail = max(s.segment.size - s.exit_start for s in own)
    aligned = []
    for s in own:
        before = lead - s.first
        after = tail - (s.segment.size - s.exit_start)
        cmd = np.concatenate(
            [np.full(before, s.command_deg[0]), s.command_deg, np.full(after, s.command_deg[-1])]
        )
        seg = np.concatenate(
            [np.full(before, APPROACH, dtype=np.int8), s.segment, np.full(after, EXIT, dtype=np.int8)]
        )
        aligned.append(CommandStream(cmd, seg.astype(np.int8), float(rate_hz)))
    return MotionStream(tuple(joints), tuple(aligned))


def check_motion_stream(
    stream: MotionStream,
    limits: Sequence[SafetyLimits],
    *,
    where: str,
    command_tables: Sequence[CalibrationTable | None],
    volts_ranges_deg: Sequence[tuple[float, float]],
) -> None:
    """`check_stream` for every joint against its own envelope; with several joints the violation names
    the joint."""
    several = len(stream.streams) > 1
    for joint, s, lim, table, vr in zip(
        stream.joints, stream.streams, limits, command_tables, volts_ranges_deg, strict=True
    ):
        try:
            check_stream(s, lim, where=where, command_table=table, volts_range_deg=vr)
        except SafetyViolation as exc:
            if not several:
                raise
            raise replace(exc, where=f"{exc.where}, joint {joint}") from None
