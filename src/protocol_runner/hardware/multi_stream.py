"""The commanded streams of a multi-joint motion: one stream per joint, aligned on a shared time base.

Each driven joint gets the stream a single joint would (`hardware/stream.py`: approach from its park angle
or where it rests, its trajectory samples, exit to its park angle), then the streams are aligned so that
every joint's first trajectory sample falls on the same output tick: a joint whose approach is shorter
waits at rest where it is (samples repeated before its approach), a joint whose exit is shorter rests at
its park angle (samples repeated after its exit). Resting repeats a sample, so it adds no rate or
acceleration: every joint's aligned stream stays within that joint's envelope exactly when its own stream
does, which `check_multi_stream` verifies joint by joint (range, ±10 V after the joint's command table,
rate, acceleration, and the stop from every sample).

A stop requested after `written` ticks stops EVERY joint: each joint brakes from its own last position and
velocity at its own acceleration limit and ramps to its own park angle; the tails are padded to the longest
with each joint resting where its tail ends, so all joints are sent together until the last one is parked.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.safety import SafetyLimits, SafetyViolation
from protocol_runner.hardware.stream import (
    APPROACH,
    EXIT,
    STOP,
    TRAJECTORY,
    CommandStream,
    build_stream,
    check_stream,
)

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class MultiStream:
    """Aligned streams (equal length, same first trajectory tick), one per joint in channel order."""

    joints: tuple[str, ...]
    streams: tuple[CommandStream, ...]

    @property
    def rate_hz(self) -> float:
        return self.streams[0].rate_hz

    @property
    def first(self) -> int:
        return self.streams[0].first

    @property
    def n_ticks(self) -> int:
        return int(self.streams[0].segment.size)

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
        cols, codes = [], []
        for s, (tail, code) in zip(self.streams, tails, strict=True):
            rest = float(tail[-1]) if tail.size else float(s.command_deg[max(written, 1) - 1])
            pad = n - tail.size
            cols.append(np.concatenate([tail, np.full(pad, rest)]))
            last = int(code[-1]) if code.size else STOP
            codes.append(np.concatenate([code, np.full(pad, last, dtype=np.int8)]).astype(np.int8))
        if n == 0:
            return np.zeros((0, len(self.streams))), np.zeros((0, len(self.streams)), dtype=np.int8)
        return np.stack(cols, axis=1), np.stack(codes, axis=1)


def build_multi_stream(
    joints: Sequence[str],
    trajectories_deg: Sequence[npt.ArrayLike],
    limits: Sequence[SafetyLimits],
    rate_hz: float,
    *,
    from_deg: Sequence[float | None] | None = None,
) -> MultiStream:
    """Each joint's stream (`build_stream`) aligned on the first trajectory tick. The trajectories must
    have the same number of samples (the joints share the trial's time)."""
    arrays = [np.asarray(t, dtype=np.float64) for t in trajectories_deg]
    sizes = {a.size for a in arrays}
    if len(sizes) != 1:
        shown = ", ".join(f"{j} {a.size}" for j, a in zip(joints, arrays, strict=True))
        raise ValueError(f"the joints of a motion must have as many samples each, got {shown}")
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
    assert len({int(np.argmax(a.segment == TRAJECTORY)) for a in aligned}) == 1
    return MultiStream(tuple(joints), tuple(aligned))


def check_multi_stream(
    stream: MultiStream,
    limits: Sequence[SafetyLimits],
    *,
    where: str,
    command_tables: Sequence[CalibrationTable | None],
    volts_ranges_deg: Sequence[tuple[float, float]],
) -> None:
    """`check_stream` for every joint against its own envelope; the violation names the joint."""
    for joint, s, lim, table, vr in zip(
        stream.joints, stream.streams, limits, command_tables, volts_ranges_deg, strict=True
    ):
        try:
            check_stream(s, lim, where=where, command_table=table, volts_range_deg=vr)
        except SafetyViolation as exc:
            raise SafetyViolation(
                where=f"{exc.where}, joint {joint}",
                limit=exc.limit,
                value=exc.value,
                limit_value=exc.limit_value,
                index=exc.index,
                time_s=exc.time_s,
                units=exc.units,
            ) from None
