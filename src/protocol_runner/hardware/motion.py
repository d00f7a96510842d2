"""Sending a planned motion: every joint's approach + trajectory + exit in one paced loop, checked first.

`run_motion(rig, commands_deg, ...)` builds each joint's stream (`hardware/stream.py`) from where the rig
left it, aligned on the first trajectory tick, runs the check of every joint's stream against that joint's
envelope (exit 4 before any write if one leaves it, the stop from every sample included), sends them in one
loop, and returns each joint's recording of the trajectory part only, on the same time base as a bare
`Rig.run_trajectory` (time 0 = the first trajectory tick), with its whole commanded stream attached
(`stream_time_s`, `stream_deg`, `stream_segment`) for the archive.

A stop request (Ctrl-C, the watchdog) during the approach or the trajectory sends every joint's brake and
parking ramp from its last written sample in the same loop, then raises `Interrupted`; during the exit the
exit simply finishes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from protocol_runner.hardware.joint import StopRequested, TrialRecording
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import check_trajectory
from protocol_runner.hardware.stream import (
    TRAJECTORY,
    MotionStream,
    build_motion_stream,
    check_motion_stream,
)

FloatArray = npt.NDArray[np.float64]


def plan_motion(rig: Rig, commands_deg: Sequence[npt.ArrayLike]) -> MotionStream:
    """The streams the rig will send for `commands_deg` (one trajectory per joint): each from its last
    commanded angle (its park angle if nothing was sent yet: every step starts and ends parked) at rest."""
    return build_motion_stream(
        rig.names,
        commands_deg,
        [j.limits for j in rig.joints],
        rig.output_rate_hz,
        from_deg=rig.last_command_deg,
    )


def run_motion(
    rig: Rig,
    commands_deg: Sequence[npt.ArrayLike],
    *,
    where: str,
    stop_requested: StopRequested | None = None,
) -> tuple[TrialRecording, ...]:
    """Plan one motion, check every joint's stream (and its first sample against where the joint was left),
    send it; return the trajectory part of each joint's recording."""
    stream = plan_motion(rig, commands_deg)
    joints = rig.joints
    limits = [j.limits for j in joints]
    check_motion_stream(
        stream,
        limits,
        where=where,
        command_tables=[j.command_table for j in joints],
        volts_ranges_deg=[j.range_deg for j in joints],
    )
    for k, (j, here) in enumerate(zip(joints, rig.last_command_deg, strict=True)):
        if here is not None:  # the junction with what was sent before
            check_trajectory(
                stream.streams[k].command_deg[:3],
                stream.rate_hz,
                j.limits,
                where=rig.where_of(f"{where} (start)", j),
                initial_deg=here,
            )
    segments = [stream.segment()]

    def on_stop(written: int) -> FloatArray:
        tail, codes = stream.stop_after(written, limits)
        for k in range(len(joints)):  # defence in depth: check_motion_stream checked every stop
            junction = stream.streams[k].command_deg[max(0, written - 2) : written]
            rig.check(k, np.concatenate([junction, tail[:, k]]), where)
        segments[0] = np.concatenate([segments[0][:written], codes])
        return tail

    def parts(recs: tuple[TrialRecording, ...]) -> tuple[TrialRecording, ...]:
        return tuple(trajectory_part(r, segments[0][:, k], stream.first) for k, r in enumerate(recs))

    try:
        with rig.loop_context():
            recs = rig.send(stream.command_deg(), where=where, stop_requested=stop_requested, on_stop=on_stop)
    except BaseException as exc:
        partial = getattr(exc, "partial_recording", None)
        if isinstance(partial, tuple):
            exc.partial_recording = parts(partial)  # type: ignore[attr-defined]
        raise
    return parts(recs)


def trajectory_part(rec: TrialRecording, segment: npt.NDArray[np.int8], first: int) -> TrialRecording:
    """The ticks of the trajectory segment and the input rows from its first tick to one tick after its
    last (what a bare run of the trajectory records), times from its first tick; the whole commanded stream
    (as far as it was written) is attached."""
    n = rec.n_ticks
    seg = segment[:n]
    ticks = np.flatnonzero(seg == TRAJECTORY)
    dt = 1.0 / rec.output_rate_hz
    t_first = first * dt
    lo, hi = (int(ticks[0]), int(ticks[-1]) + 1) if ticks.size else (min(first, n), min(first, n))
    half_row = 0.5 / rec.input_rate_hz
    rel = rec.input_time_s - t_first
    inside = (rel > -half_row) & (rel <= (hi - first) * dt + half_row)
    keep = np.flatnonzero(inside) if ticks.size else np.zeros(0, dtype=np.int64)
    rows = slice(int(keep[0]), int(keep[-1]) + 1) if keep.size else slice(0, 0)
    # the same form as a bare run's time base (offset to 1 us + index / rate): bit-identical across trials
    offset = round(float(rel[rows.start]) * 1e6) / 1e6 if keep.size else 0.0
    input_time_s = offset + np.arange(rows.stop - rows.start, dtype=np.float64) / rec.input_rate_hz
    return replace(
        rec,
        command_time_s=np.arange(hi - lo, dtype=np.float64) * dt,
        command_deg=rec.command_deg[lo:hi],
        command_volts=rec.command_volts[lo:hi],
        command_codes=rec.command_codes[lo:hi],
        tick_lateness_s=rec.tick_lateness_s[lo:hi],
        input_time_s=input_time_s,
        angle_codes=rec.angle_codes[rows],
        torque_codes=rec.torque_codes[rows],
        angle_volts=rec.angle_volts[rows],
        torque_volts=rec.torque_volts[rows],
        angle_deg=rec.angle_deg[rows],
        torque_nm=rec.torque_nm[rows],
        t0_s=rec.t0_s + t_first,
        stream_time_s=(np.arange(n, dtype=np.float64) - first) * dt,
        stream_deg=rec.command_deg,
        stream_segment=seg.astype(np.int8),
    )
