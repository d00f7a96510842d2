"""Driving the campaign's joints and writing a rig recording (raw codes and converted values) into a unit:
shared by trials and checks."""

from __future__ import annotations

import json
from collections.abc import Sequence

import h5py
import numpy as np
import numpy.typing as npt

from ..archive.h5util import SIGNAL, put, put_attrs
from ..archive.paths import put_dataset
from ..hardware.joint import TrialRecording
from ..hardware.motion import run_motion
from ..hardware.stream import SEGMENT_NAMES
from ..protocol.plan_steps import CalibrationCheckStep, TrialStep
from ..protocol.trajectory_record import Trajectory
from .context import StepContext


def joint_trajectories(
    step: TrialStep | CalibrationCheckStep, ctx: StepContext
) -> tuple[tuple[str, Trajectory], ...]:
    """Each driven joint's trajectory of a step, in channel order (one joint: the step's trajectory)."""
    if step.joint_trajectories:
        return step.joint_trajectories
    return ((ctx.loaded.protocol.driven_joints[0], step.trajectory),)


def drive(ctx: StepContext, commands: Sequence[npt.ArrayLike], where: str) -> tuple[TrialRecording, ...]:
    """One motion of every driven joint (`commands` in channel order, as many samples each): each joint's
    recording on the shared time base. A board failure's partial recording is a tuple likewise."""
    return run_motion(ctx.bench.rig, commands, where=where, stop_requested=ctx.stop_requested)


def drive_joint(ctx: StepContext, joint: str, command: npt.ArrayLike, where: str) -> TrialRecording:
    """A motion of `joint` alone (its calibration step); any other driven joint holds its last output."""
    rig = ctx.bench.rig
    if len(rig.joints) == 1:
        return run_motion(rig, [command], where=where, stop_requested=ctx.stop_requested)[0]
    single = rig.single(joint)
    try:
        return run_motion(single, [command], where=where, stop_requested=ctx.stop_requested)[0]
    finally:
        rig.note_single(joint, single)


def put_scan(g: h5py.Group, rec: TrialRecording) -> None:
    """The input scan (1 kHz): times, angle and torque, and the raw ADC codes.

    Codes are stored as int32 whatever the board: the DT9814's are signed 12-bit, the USB-1608FS-Plus's
    unsigned 16-bit; the byte-shuffle filter makes the unused high bytes cost almost nothing."""
    put_dataset(g, "recording", "time_s", rec.input_time_s)
    put_dataset(g, "recording", "angle_deg", rec.angle_deg, dtype=SIGNAL)
    put_dataset(g, "recording", "torque_nm", rec.torque_nm, dtype=SIGNAL)
    put_dataset(g, "recording", "angle_codes", rec.angle_codes, dtype=np.int32)
    put_dataset(g, "recording", "torque_codes", rec.torque_codes, dtype=np.int32)


def put_commands(g: h5py.Group, rec: TrialRecording, *, full: bool) -> None:
    """The output ticks (100 Hz): times and commanded angles; with `full`, volts, DAC codes and timing."""
    put_dataset(g, "recording", "command_time_s", rec.command_time_s)
    put_dataset(g, "recording", "command_deg", rec.command_deg)
    if full:
        put_dataset(g, "recording", "command_volts", rec.command_volts, dtype=SIGNAL)
        put_dataset(g, "recording", "command_codes", rec.command_codes, dtype=np.uint16)
        put_dataset(g, "recording", "tick_lateness_s", rec.tick_lateness_s)
    if rec.stream_deg.size:
        put_stream(g.create_group("stream"), rec)


def put_stream(g: h5py.Group, rec: TrialRecording) -> None:
    """Every sample the motion commanded (approach, trajectory, exit or stop), its time from the first
    trajectory tick (negative during the approach) and its segment code (`hardware/stream.py`)."""
    put(g, "command_time_s", rec.stream_time_s, "s")
    put(g, "command_deg", rec.stream_deg, "deg")
    put(g, "segment", rec.stream_segment, "1", dtype=np.int8)
    put_attrs(g, "stream", {"segments": json.dumps({str(k): v for k, v in SEGMENT_NAMES.items()})})
