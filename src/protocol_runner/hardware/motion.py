"""Sending a planned motion: approach + trajectory + exit in one paced loop, checked as a whole first.

`run_motion(rig, trajectory_deg, ...)` builds the stream (`hardware/stream.py`) from where the rig left
the joint, runs `check_stream` on it (exit 4 before any write if it leaves the envelope, the stop from every
sample included), sends it in one loop, and returns the recording of the trajectory part only, on the same
time base as a bare `Rig.run_trajectory` (time 0 = the first trajectory tick), with the whole commanded
stream attached (`stream_time_s`, `stream_deg`, `stream_segment`) for the archive.

A stop request during the approach or the trajectory sends the brake and the parking ramp from the last
written sample in the same loop, then raises `Interrupted`; during the exit the exit simply finishes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import numpy.typing as npt

from protocol_runner.hardware.joint import StopRequested, TrialRecording
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import check_trajectory
from protocol_runner.hardware.stream import TRAJECTORY, CommandStream, build_stream, check_stream

FloatArray = npt.NDArray[np.float64]


def plan_motion(rig: Rig, trajectory_deg: npt.ArrayLike) -> CommandStream:
    """The stream the rig will send for `trajectory_deg`: from the last commanded angle (the park angle if
    nothing was sent yet: every step starts and ends parked) at rest."""
    joint = rig.joint
    return build_stream(trajectory_deg, joint.limits, joint.output_rate_hz, from_deg=rig.last_command_deg)


def run_motion(
    rig: Rig,
    trajectory_deg: npt.ArrayLike,
    *,
    where: str,
    stop_requested: StopRequested | None = None,
) -> TrialRecording:
    """Plan, check and send one motion; return the trajectory part of its recording."""
    return run_stream(rig, plan_motion(rig, trajectory_deg), where=where, stop_requested=stop_requested)


def run_stream(
    rig: Rig,
    stream: CommandStream,
    *,
    where: str,
    stop_requested: StopRequested | None = None,
) -> TrialRecording:
    """Check the whole stream (and its first sample against where the joint was left), then send it."""
    joint = rig.joint
    table, volts_range = joint.command_table, joint.range_deg
    check_stream(stream, joint.limits, where=where, command_table=table, volts_range_deg=volts_range)
    here = rig.last_command_deg
    if here is not None:  # the junction with what was sent before
        check_trajectory(
            stream.command_deg[:3], stream.rate_hz, joint.limits, where=f"{where} (start)", initial_deg=here
        )
    segments: list[npt.NDArray[np.int8]] = [stream.segment]

    def on_stop(written: int) -> FloatArray:
        tail, codes = stream.stop_after(written, joint.limits)
        # defence in depth: check_stream has already checked the stop from every sample
        junction = stream.command_deg[max(0, written - 2) : written]
        check_trajectory(
            np.concatenate([junction, tail]),
            stream.rate_hz,
            joint.limits,
            where=where,
            command_table=table,
            volts_range_deg=volts_range,
        )
        segments[0] = np.concatenate([stream.segment[:written], codes])
        return tail

    try:
        with rig.loop_context():
            rec = rig.send(
                stream.command_deg.copy(), where=where, stop_requested=stop_requested, on_stop=on_stop
            )
    except BaseException as exc:
        partial = getattr(exc, "partial_recording", None)
        if isinstance(partial, TrialRecording):
            exc.partial_recording = trajectory_part(partial, segments[0], stream.first)  # type: ignore[attr-defined]
        raise
    return trajectory_part(rec, segments[0], stream.first)


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
