"""Plan-time envelope checks of every motion the protocol commands (part of the preflight).

First, by field (`trajectory_limit_problems`): which FIELD of which trajectory breaks the joint's range, rate
or acceleration, so the test engineer knows what to change. Each kind says what to check (`check_limits` of
its model, protocol/trajectory_specs.py): a closed form where it has one (a sinusoid's peak speed and
acceleration, a ramp's, a range), else its samples at the output rate (`sampling.sample_trajectory`), first
and second differences as `hardware/safety.py` does.

Then the complete commanded stream (`check_streams`) of each configuration's trajectory and the calibration
step - approach from the park angle, the trajectory sampled at the output rate, exit to the park angle - and
a stop after any of its samples, against `rig.safety` and the joint's range (`hardware/stream.py`: range,
±10 V after the command table, rate and acceleration across the junctions). A protocol whose stream breaks
the envelope is refused before anything is created (exit 2), naming the configuration. Brace-off commands
come from brace-on measurements; the rig checks them before sending.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InvalidInput
from ..hardware.calibration import CalibrationTable, load_calibration_table
from ..hardware.safety import SafetyLimits, SafetyViolation, check_trajectory
from ..hardware.stream import build_stream, check_stream
from ..tables import parse_header_table, read_table_text
from .sampling import sample_trajectory, samples_problem
from .schema import RigSpec
from .trajectory_record import Trajectory
from .trajectory_specs import trajectory_kind

if TYPE_CHECKING:
    from .loaded import LoadedProtocol, Loc, Problem


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
            verdicts[key] = _problem(traj, loaded, limits, table)
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
) -> str | None:
    rate_hz = loaded.protocol.rig.output.rate_hz
    too_long = samples_problem(traj, rate_hz)
    if too_long:
        return too_long
    try:
        samples = sample_trajectory(traj, rate_hz, loaded.base_dir)
        check_trajectory(samples, rate_hz, limits, where="stream (trajectory)")
        stream = build_stream(samples, limits, rate_hz)
        check_stream(stream, limits, where="stream", command_table=table, volts_range_deg=limits.range_deg)
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


_REL_TOL = 1e-9  # a trajectory exactly at a limit passes (as in hardware/safety.py)


def trajectory_limit_problems(
    trajectory: Trajectory,
    limits: SafetyLimits,
    rate_hz: float,
    base_dir: Path,
    bindings: Mapping[str, str] | None = None,
) -> list[tuple[str, str]]:
    """(field, message) for every limit the trajectory breaks; empty if it is inside the envelope.
    `bindings` (field -> "factor.quantity") are named in the messages of bound fields."""
    kind = trajectory_kind(trajectory.profile)
    too_long = samples_problem(trajectory, rate_hz)
    if too_long:  # before anything is sampled: the work and memory of the checks below are bounded
        return [(kind.length_field, too_long)]
    check = LimitCheck(trajectory, limits, bindings or {}, rate_hz, base_dir)
    kind.check_limits(trajectory, check)
    return check.problems


@dataclasses.dataclass
class LimitCheck:
    """What a kind's `check_limits` reports to: each call names the protocol FIELD that sets the value, so
    that the message says what to change; each broken limit becomes a (field, message) in `problems`."""

    trajectory: Trajectory
    limits: SafetyLimits
    bindings: Mapping[str, str]  # field -> "factor.quantity", named in the messages of bound fields
    rate_hz: float
    base_dir: Path
    problems: list[tuple[str, str]] = dataclasses.field(default_factory=list)

    def _say(self, field: str, text: str) -> None:
        t = self.trajectory
        where = (
            f"trajectory{f' {t.name!r}' if t.name else ''} ({t.profile}{f' {t.source}' if t.source else ''})"
        )
        bound = f" (bound to {self.bindings[field]})" if field in self.bindings else ""
        self.problems.append((field, f"{where}: {field}{bound}: {text}"))

    def range(self, field: str, lo: float, hi: float, what: str = "") -> None:
        """[lo, hi] deg must lie inside the joint's range."""
        jlo, jhi = self.limits.range_deg
        tol = 1e-9
        if lo < jlo - tol or hi > jhi + tol:
            shown = what or (f"[{lo:g}, {hi:g}] deg" if hi > lo else f"{lo:g} deg")
            self._say(field, f"{shown} is outside the joint's range [{jlo:g}, {jhi:g}] deg")

    def rate(self, field: str, value: float, what: str) -> None:
        limit = self.limits.max_rate_deg_s
        if value > limit * (1.0 + _REL_TOL):
            self._say(
                field,
                f"{what} {value:.4g} deg/s is over the joint's rate limit max_rate_deg_s = {limit:g} deg/s",
            )

    def accel(self, field: str, value: float, what: str) -> None:
        limit = self.limits.max_accel_deg_s2
        if value > limit * (1.0 + _REL_TOL):
            self._say(
                field,
                f"{what} {value:.4g} deg/s² is over the joint's acceleration limit max_accel_deg_s2 = "
                f"{limit:g} deg/s²",
            )

    def samples(self, field: str) -> None:
        """The samples at the output rate (the very samples sent) inside the envelope, for a kind without a
        closed form: their range, rate and acceleration (first and second differences); for a file, the
        line and column of the file row nearest the worst sample."""
        rate_hz, base_dir = self.rate_hz, self.base_dir
        samples = sample_trajectory(self.trajectory, rate_hz, base_dir)
        try:
            check_trajectory(samples, rate_hz, self.limits, where="trajectory")
        except SafetyViolation as exc:
            self._say(
                field,
                f"its {exc.limit} reaches {exc.value:.4g} {exc.units} at t = {exc.time_s:.2f} s (sampled at "
                f"{rate_hz:g} Hz{self._file_row(exc.time_s, base_dir)}), the joint allows {allowed(exc)}",
            )

    def _file_row(self, time_s: float, base_dir: Path) -> str:
        """`, <file> line N column C` of the row nearest `time_s` (empty when not a readable CSV)."""
        source = self.trajectory.source
        if source is None or not source.lower().endswith((".csv", ".txt")):
            return ""
        try:
            table = parse_header_table(read_table_text(base_dir / source, "trajectory file"))
        except InvalidInput:
            return ""
        names = [c.lower() for c in table.header.cells] if table.header is not None else []
        col = next((names.index(n) for n in ("time_s", "t", "time") if n in names), 0)
        best: tuple[float, int] | None = None
        for row in table.rows:
            try:
                t = float(row.cells[col])
            except (ValueError, IndexError):
                continue
            if best is None or abs(t - time_s) < best[0]:
                best = (abs(t - time_s), row.line)
        if best is None:
            return ""
        column = dict(self.trajectory.params).get("column")
        return f"; {source} line {best[1]}" + (f" column {column}" if isinstance(column, str) else "")
