"""Plan-time envelope check of every motion the protocol commands (part of the preflight).

For each configuration's trajectory and the calibration step, the complete commanded stream the rig will
send - approach from the park angle, the trajectory sampled at the output rate, exit to the park angle -
and a stop after any of its samples are checked against `rig.safety` and the joint's range
(`hardware/stream.py`: range, ±10 V after the command table, rate and acceleration across the junctions).
A protocol whose stream breaks the envelope is refused before anything is created (exit 2), naming the
configuration. Brace-off commands come from brace-on measurements; the rig checks them before sending.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from ..errors import InvalidInput
from ..hardware.calibration import CalibrationTable, load_calibration_table
from ..hardware.safety import SafetyLimits, SafetyViolation, check_trajectory
from ..hardware.stream import build_stream, check_stream
from .sampling import sample_trajectory, samples_problem
from .schema import RigSpec
from .trajectory_record import Trajectory

if TYPE_CHECKING:
    from .loaded import LoadedProtocol, Loc

Problem = tuple["Loc", str]


def safety_limits(rig: RigSpec) -> SafetyLimits:
    """The rig section's safety envelope: the joint's range and `rig.safety` (the one place that maps them)."""
    # `rig.safety` (SafetySpec) has the envelope's fields by name: rates, acceleration, park angle and rate
    return SafetyLimits(range_deg=rig.joint.range_deg, **rig.safety.model_dump())


def check_streams(
    loaded: LoadedProtocol, motions: list[tuple[Loc, str, Trajectory]], *, check_files: bool = True
) -> Iterator[Problem]:
    """(location, message) for every motion (location, what, trajectory) whose stream is unsafe."""
    p = loaded.protocol
    rig = p.rig
    limits = safety_limits(rig)
    table: CalibrationTable | None = None
    if check_files and rig.calibration.command_table is not None:
        try:
            table = load_calibration_table(loaded.base_dir / rig.calibration.command_table)
        except InvalidInput:
            return  # reported by the file checks
    verdicts: dict[str, str | None] = {}
    for loc, name, traj in motions:
        key = repr(traj.to_json())
        if key not in verdicts:
            verdicts[key] = _problem(traj, loaded, limits, table, rig.output.rate_hz, rig.joint.range_deg)
        message = verdicts[key]
        if message is not None:
            what = (
                f"{traj.profile} {traj.name or traj.source}" if (traj.name or traj.source) else traj.profile
            )
            yield loc, f"{name} ({what}): {message}"


def _problem(
    traj: Trajectory,
    loaded: LoadedProtocol,
    limits: SafetyLimits,
    table: CalibrationTable | None,
    rate_hz: float,
    volts_range_deg: tuple[float, float],
) -> str | None:
    too_long = samples_problem(traj, rate_hz)
    if too_long:
        return too_long
    try:
        samples = sample_trajectory(traj, rate_hz, loaded.base_dir)
        check_trajectory(samples, rate_hz, limits, where="stream (trajectory)")
        stream = build_stream(samples, limits, rate_hz)
        check_stream(stream, limits, where="stream", command_table=table, volts_range_deg=volts_range_deg)
    except SafetyViolation as exc:
        part = exc.where.removeprefix("stream").strip(" ()")
        return (
            f"its commanded stream ({part}) breaks rig.safety: {exc.limit} {exc.value:.4g} {exc.units} "
            f"at t = {exc.time_s:.2f} s from the trajectory's start, allowed {allowed(exc)}"
        )
    except InvalidInput as exc:
        return exc.message
    return None


def allowed(exc: SafetyViolation) -> str:
    """What the broken limit allows, with its unit."""
    if isinstance(exc.limit_value, tuple):
        return f"{exc.limit_value[0]:g} to {exc.limit_value[1]:g} {exc.units}"
    return f"±{exc.limit_value:g} {exc.units}"
