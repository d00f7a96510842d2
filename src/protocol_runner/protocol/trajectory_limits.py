"""Plan-time check of a trajectory against its joint's range, rate and acceleration limits, by field.

`protocol/stream_check.py` checks the complete commanded stream (approach, samples, exit, a stop from any
sample); this check comes first and says which FIELD of which trajectory breaks which limit, so the test
engineer knows what to change. Where a kind has a closed form it is used:

- sinusoid (Eq 24-25): its range inside the joint's; peak speed `speed_deg_s` = 2*pi*A/p under the rate
  limit; peak acceleration A*(2*pi/p)^2 = speed^2/A under the acceleration limit;
- triangle: range; `speed_deg_s` (its peak speed) under the rate limit; `corner_accel_deg_s2` (its peak
  acceleration) under the acceleration limit;
- ramped step: `from_deg` and `from_deg + step_deg` inside the range; the raised cosine's peak speed
  pi/2*step/ramp and peak acceleration pi^2/2*step/ramp^2 within the limits (else `ramp_s` is too short);
- hold: `angle_deg` inside the range.

The identification motion (Eq 4-7) and files have none: their samples at the output rate (the very samples
sent, `sampling.sample_trajectory`) are checked, first and second differences as `hardware/safety.py` does.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

from ..errors import InvalidInput
from ..hardware.safety import SafetyLimits, SafetyViolation, check_trajectory
from ..tables import parse_header_table, read_table_text
from .plan_trajectory import Trajectory
from .sampling import FloatArray, sample_trajectory, samples_problem
from .trajectories import (
    calibration_step_peak_accel_deg_s2,
    calibration_step_peak_speed_deg_s,
    sinusoid_peak_accel_deg_s2,
)

_REL_TOL = 1e-9  # a trajectory exactly at a limit passes (as in hardware/safety.py)

Problem = tuple[str, str]  # (field, message)


def trajectory_limit_problems(
    trajectory: Trajectory,
    limits: SafetyLimits,
    rate_hz: float,
    base_dir: Path,
    bindings: Mapping[str, str] | None = None,
) -> list[Problem]:
    """(field, message) for every limit the trajectory breaks; empty if it is inside the envelope.
    `bindings` (field -> "factor.quantity") are named in the messages of bound fields."""
    check = _Checker(trajectory, limits, dict(bindings or {}))
    kind = trajectory.profile
    p = dict(trajectory.params)
    too_long = samples_problem(trajectory, rate_hz)
    if too_long:  # before anything is sampled: the work and memory of the checks below are bounded
        field = {"file": "file", "human": "file", "sinusoid": "periods", "triangle": "cycles"}.get(
            kind, "duration_s"
        )
        return [(field, too_long)]
    if kind == "sinusoid":
        assert trajectory.mean_deg is not None and trajectory.amplitude_deg is not None
        assert trajectory.period_s is not None
        a, mean = trajectory.amplitude_deg, trajectory.mean_deg
        speed = 2.0 * math.pi * a / trajectory.period_s  # Eq 25
        check.range("range_deg", mean - a, mean + a)
        check.rate("speed_deg_s", speed, "its peak speed (Eq 25)")
        check.accel(
            "speed_deg_s", sinusoid_peak_accel_deg_s2(a, speed), "its peak acceleration speed²/amplitude"
        )
    elif kind == "triangle":
        lo, hi = _pair(p["range_deg"])
        check.range("range_deg", lo, hi)
        check.rate("speed_deg_s", _num(p["speed_deg_s"]), "its constant speed")
        check.accel("corner_accel_deg_s2", _num(p["corner_accel_deg_s2"]), "its corners' acceleration")
    elif kind in ("ramped_step", "step"):
        start, step, ramp = _num(p["from_deg"]), _num(p["step_deg"]), _num(p["ramp_s"])
        check.range("from_deg", start, start)
        check.range(
            "step_deg", start + step, start + step, f"the step's end from_deg + step_deg = {start + step:g}"
        )
        check.rate(
            "ramp_s", calibration_step_peak_speed_deg_s(step, ramp), "the ramp's peak speed pi/2*step/ramp"
        )
        check.accel(
            "ramp_s",
            calibration_step_peak_accel_deg_s2(step, ramp),
            "the ramp's peak acceleration pi²/2*step/ramp²",
        )
    elif kind == "hold":
        angle = _num(p["angle_deg"])
        check.range("angle_deg", angle, angle)
    elif kind == "identification":
        check.range("range_deg", _num(p["min_deg"]), _num(p["max_deg"]))
        if not check.problems:
            check.samples("final_period_s", sample_trajectory(trajectory, rate_hz, base_dir), rate_hz)
    elif kind in ("file", "human"):
        check.samples("file", sample_trajectory(trajectory, rate_hz, base_dir), rate_hz, base_dir)
    else:
        raise ValueError(f"unknown trajectory profile {kind!r}")
    return check.problems


class _Checker:
    def __init__(self, trajectory: Trajectory, limits: SafetyLimits, bindings: dict[str, str]) -> None:
        self.limits = limits
        self.bindings = bindings
        name = f" {trajectory.name!r}" if trajectory.name else ""
        what = f" {trajectory.source}" if trajectory.source else ""
        self.where = f"trajectory{name} ({trajectory.profile}{what})"
        self.source = trajectory.source
        column = dict(trajectory.params).get("column")
        self.column = column if isinstance(column, str) else None
        self.problems: list[Problem] = []

    def _say(self, field: str, text: str) -> None:
        bound = f" (bound to {self.bindings[field]})" if field in self.bindings else ""
        self.problems.append((field, f"{self.where}: {field}{bound}: {text}"))

    def range(self, field: str, lo: float, hi: float, what: str = "") -> None:
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

    def samples(self, field: str, samples: FloatArray, rate_hz: float, base_dir: Path | None = None) -> None:
        """The sampled trajectory's range, rate and acceleration (first and second differences); for a
        file, the line and column of the file row nearest the worst sample."""
        try:
            check_trajectory(samples, rate_hz, self.limits, where="trajectory")
        except SafetyViolation as exc:
            bound = (
                f"{exc.limit_value[0]:g} to {exc.limit_value[1]:g}"
                if isinstance(exc.limit_value, tuple)
                else f"±{exc.limit_value:g}"
            )
            self._say(
                field,
                f"its {exc.limit} reaches {exc.value:.4g} {exc.units} at t = {exc.time_s:.2f} s (sampled at "
                f"{rate_hz:g} Hz{self._file_row(exc.time_s, base_dir)}), the joint allows {bound} {exc.units}",
            )

    def _file_row(self, time_s: float, base_dir: Path | None) -> str:
        """`, <file> line N column C` of the row nearest `time_s` (empty when not a readable CSV)."""
        if base_dir is None or self.source is None or not self.source.lower().endswith((".csv", ".txt")):
            return ""
        try:
            table = parse_header_table(read_table_text(base_dir / self.source, "trajectory file"))
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
        column = f" column {self.column}" if self.column else ""
        return f"; {self.source} line {best[1]}{column}"


def _pair(value: object) -> tuple[float, float]:
    assert isinstance(value, tuple) and len(value) == 2
    return float(value[0]), float(value[1])


def _num(value: object) -> float:
    assert isinstance(value, float | int)
    return float(value)
