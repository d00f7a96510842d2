"""Safety envelope for everything sent to the robot (docs/hardware-model.md §4).

`check_trajectory` checks a commanded trajectory as a whole *before* anything is written: every sample
finite and inside the protocol's joint range; rate (first difference × output rate) within
`max_rate_deg_s`; acceleration (second difference × rate²) within `max_accel_deg_s2`; optionally the volts
after the command look-up table (thesis §2.5.1) and Eq 1 within ±10 V. A violation raises `SafetyViolation`
(a `StoppedByCheck`, exit status 4) naming the step, the limit, the worst value, its sample index and time.
`clamp_volts` is the second line of defence at the output; `parking_ramp_deg` moves the joint to its rest
angle within the rate and acceleration limits. The move to the first sample is checked only with
`initial_deg`: trials and calibration checks send whole streams (`hardware/stream.py`), junctions included.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput, StoppedByCheck
from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.conversions import VOLTS_RANGE, angle_to_volts

FloatArray = npt.NDArray[np.float64]

# Tolerance for rounding in the limit comparisons (a ramp at exactly the limit must pass).
_REL_TOL = 1e-9
_RANGE_TOL_DEG = 1e-9  # rounding of a brake or ramp that ends exactly on a range limit
MAX_RAMP_SAMPLES = 1_000_000
"""A parking ramp longer than this (almost 3 h at 100 Hz) means limits that cannot move the joint."""


@dataclass(frozen=True)
class SafetyLimits:
    """The envelope a commanded trajectory must stay inside.

    range_deg: (min, max) joint angle allowed (from the protocol; may be narrower than the Eq 1 range).
    max_rate_deg_s: largest |angular rate| allowed between consecutive output samples.
    max_accel_deg_s2: largest |angular acceleration| (second difference) allowed.
    park_angle_deg: the rest angle the joint is parked at (inside range_deg).
    park_rate_deg_s: cruising rate of the parking ramp (<= max_rate_deg_s).
    """

    range_deg: tuple[float, float]
    max_rate_deg_s: float
    max_accel_deg_s2: float
    park_angle_deg: float
    park_rate_deg_s: float

    def __post_init__(self) -> None:
        lo, hi = (float(v) for v in self.range_deg)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise InvalidInput(
                f"safety limits: range_deg must be (min, max) with max > min, got {self.range_deg!r}"
            )
        object.__setattr__(self, "range_deg", (lo, hi))
        for name in ("max_rate_deg_s", "max_accel_deg_s2", "park_rate_deg_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise InvalidInput(f"safety limits: {name} must be a positive number, got {value!r}")
        if not lo <= self.park_angle_deg <= hi:
            raise InvalidInput(
                f"safety limits: park_angle_deg {self.park_angle_deg!r} is outside "
                f"range_deg {self.range_deg!r}"
            )
        if self.park_rate_deg_s > self.max_rate_deg_s:
            raise InvalidInput(
                f"safety limits: park_rate_deg_s {self.park_rate_deg_s!r} exceeds max_rate_deg_s "
                f"{self.max_rate_deg_s!r}"
            )


@dataclass(eq=False, kw_only=True)
class SafetyViolation(StoppedByCheck):
    """A commanded trajectory left the safety envelope; nothing was sent (exit status 4).

    Attributes: where (step id), limit (which limit), value (worst value), limit_value, index (sample) and
    time_s (index / rate), units.
    """

    where: str
    limit: str
    value: float
    limit_value: float | tuple[float, float]
    index: int
    time_s: float
    units: str

    def __post_init__(self) -> None:
        limit_value, units = self.limit_value, self.units
        if isinstance(limit_value, tuple):
            bound = f"allowed {limit_value[0]:g} to {limit_value[1]:g} {units}"
        else:
            bound = f"allowed ±{limit_value:g} {units}"
        super().__init__(
            f"{self.where}: the commanded trajectory breaks the safety envelope: {self.limit} is "
            f"{self.value:.6g} {units} at t = {self.time_s:.3f} s (sample {self.index}), {bound}. "
            "Nothing was sent to the robot."
        )


def check_trajectory(
    command_deg: npt.ArrayLike,
    rate_hz: float,
    limits: SafetyLimits,
    *,
    where: str,
    command_table: CalibrationTable | None = None,
    volts_range_deg: tuple[float, float] | None = None,
    initial_deg: float | None = None,
    derivatives: bool = True,
) -> None:
    """Raise `SafetyViolation` if the trajectory (real joint angles, one per output tick at `rate_hz`)
    leaves the envelope; return None if it is safe.

    `command_table` (real -> input angle, thesis §2.5.1) and `volts_range_deg` (the joint's Eq 1
    Minimum/Maximum_Position) enable the check that the volts sent stay within ±10 V. `initial_deg`, if
    given, is prepended for the rate and acceleration checks (times then count from that sample, at -1/rate).
    Checks run in the order range, volts, rate, acceleration; the first violated one is reported with its
    worst sample. `derivatives=False` checks range and volts only (for a set of points, not a sequence).
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InvalidInput(f"{where}: output rate must be a positive number of Hz, got {rate_hz!r}")
    cmd = np.asarray(command_deg, dtype=np.float64)
    if cmd.ndim != 1 or cmd.size == 0:
        raise InvalidInput(
            f"{where}: a trajectory must be a non-empty 1-D array of angles, got shape {cmd.shape}"
        )
    dt = 1.0 / rate_hz

    lo, hi = limits.range_deg
    # a non-finite sample is infinitely far out: the first one is the worst
    excess = np.where(np.isfinite(cmd), np.maximum(lo - cmd, cmd - hi), np.inf)
    i = int(np.argmax(excess))
    if excess[i] > _RANGE_TOL_DEG:
        raise SafetyViolation(
            where=where,
            limit="joint angle",
            value=float(cmd[i]),
            limit_value=limits.range_deg,
            index=i,
            time_s=i * dt,
            units="deg",
        )

    if volts_range_deg is not None:
        input_deg = command_table(cmd) if command_table is not None else cmd
        volts = angle_to_volts(input_deg, volts_range_deg)
        vlo, vhi = VOLTS_RANGE
        v_excess = np.maximum(vlo - volts, volts - vhi)
        i = int(np.argmax(v_excess))
        if v_excess[i] > 1e-9:
            raise SafetyViolation(
                where=where,
                limit="commanded output voltage (after the command look-up table and Eq 1)",
                value=float(volts[i]),
                limit_value=VOLTS_RANGE,
                index=i,
                time_s=i * dt,
                units="V",
            )

    if not derivatives:
        return
    offset = 0
    series = cmd
    if initial_deg is not None:
        series = np.concatenate([[float(initial_deg)], cmd])
        offset = -1
    # rate (first difference) and acceleration (second difference), each against its limit
    for order, limit_name, limit_value, units in (
        (1, "angular rate", limits.max_rate_deg_s, "deg/s"),
        (2, "angular acceleration", limits.max_accel_deg_s2, "deg/s²"),
    ):
        if series.size <= order:
            continue
        derivative = np.diff(series, order) * rate_hz**order
        i = int(np.argmax(np.abs(derivative)))
        if abs(derivative[i]) > limit_value * (1 + _REL_TOL):
            index = i + 1 + offset
            raise SafetyViolation(
                where=where,
                limit=limit_name,
                value=float(derivative[i]),
                limit_value=limit_value,
                index=index,
                time_s=index * dt,
                units=units,
            )


def clamp_volts(volts: npt.ArrayLike, volts_range: tuple[float, float] = VOLTS_RANGE) -> FloatArray:
    """Clip volts to the ±10 V output range (the second line of defence after `check_trajectory`)."""
    result: FloatArray = np.clip(np.asarray(volts, dtype=np.float64), volts_range[0], volts_range[1])
    return result


def parking_ramp_deg(from_deg: float, limits: SafetyLimits, rate_hz: float) -> FloatArray:
    """Samples (one per output tick at `rate_hz`) moving the joint from `from_deg` to the park angle.

    A trapezoidal velocity profile: cruising at `park_rate_deg_s`, accelerating and braking at half of
    `max_accel_deg_s2`, so the ramp passes `check_trajectory` with margin. The first sample is `from_deg`
    (where the joint is), the last is exactly `park_angle_deg`. A `from_deg` outside the range is allowed
    (parking is how a joint gets back in); the samples move monotonically towards the park angle.
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InvalidInput(f"parking ramp: output rate must be a positive number of Hz, got {rate_hz!r}")
    if not math.isfinite(from_deg):
        raise InvalidInput(f"parking ramp: the current angle must be finite, got {from_deg!r}")
    target = limits.park_angle_deg
    distance = abs(target - from_deg)
    if distance == 0.0:
        return np.array([target], dtype=np.float64)
    v = limits.park_rate_deg_s
    a = 0.5 * limits.max_accel_deg_s2
    if distance <= v * v / a:  # triangle profile: never reaches cruising rate
        t_acc = math.sqrt(distance / a)
        v = a * t_acc
        t_cruise = 0.0
    else:
        t_acc = v / a
        t_cruise = (distance - v * t_acc) / v
    total = 2.0 * t_acc + t_cruise
    if total * rate_hz > MAX_RAMP_SAMPLES:  # bounded work whatever the limits say
        raise InvalidInput(
            f"parking ramp: moving {distance:g} deg at park_rate_deg_s = {limits.park_rate_deg_s:g} and "
            f"max_accel_deg_s2 = {limits.max_accel_deg_s2:g} would take {total:.0f} s; raise the limits"
        )
    n = max(1, math.ceil(total * rate_hz - 1e-9))  # at least one step: the last sample is the target
    t = np.arange(n + 1, dtype=np.float64) / rate_hz
    s = np.where(
        t < t_acc,
        0.5 * a * t * t,
        np.where(
            t < t_acc + t_cruise,
            0.5 * a * t_acc * t_acc + v * (t - t_acc),
            distance - 0.5 * a * np.square(np.maximum(total - t, 0.0)),
        ),
    )
    s = np.clip(s, 0.0, distance)
    s[-1] = distance
    result: FloatArray = from_deg + math.copysign(1.0, target - from_deg) * s
    result[-1] = target  # exactly, whatever the rounding of from + (target - from)
    return result
