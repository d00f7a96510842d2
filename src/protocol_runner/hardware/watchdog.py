"""The watchdog on MEASURED signals (docs/hardware.md, "The watchdog on measured signals"): the safety
envelope (`hardware/safety.py`) checks what is commanded before anything is written; the watchdog checks,
row by row of every scan block the paced loop reads, what the joint does while it moves: the measured
torque within `torque_limits_nm`, and the measured angle within `max_tracking_error_deg` of the command
delayed by the servo lag (`lag_s`: a first-order lag follows a ramp by exactly rate x tau) for at most
`max_tracking_error_s`. The first row that breaks a check is returned as `WatchdogTripped` (exit 4): the loop
then stops the trial through the stop path a stop request takes (brake and park in the same loop).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput, WatchdogTripped
from protocol_runner.hardware.interfaces import ScanBlock

FloatArray = npt.NDArray[np.float64]
TORQUE_ROUNDING = 1e-6  # a fraction of the torque range: single-precision rounding of a reading at an end


@dataclass(frozen=True)
class WatchdogLimits:
    """What the watchdog allows one joint while it moves: the measured torque within `torque_limits_nm`;
    |measured angle - command delayed by `lag_s`| beyond `max_tracking_error_deg` for at most
    `max_tracking_error_s`."""

    torque_limits_nm: tuple[float, float]
    max_tracking_error_deg: float
    max_tracking_error_s: float
    lag_s: float

    def __post_init__(self) -> None:
        lo, hi = (float(v) for v in self.torque_limits_nm)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise InvalidInput(f"watchdog: torque limits must be (min, max) with max > min, got {(lo, hi)!r}")
        object.__setattr__(self, "torque_limits_nm", (lo, hi))
        for name in ("max_tracking_error_deg", "max_tracking_error_s", "lag_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0 and (value > 0 or name == "lag_s")):
                raise InvalidInput(f"watchdog: {name} must be a positive number, got {value!r}")


def watchdog_limits(
    torque_range_nm: tuple[float, float],
    *,
    torque_margin: float,
    max_tracking_error_deg: float,
    max_tracking_error_s: float,
    lag_s: float,
) -> WatchdogLimits:
    """The limits of a joint of torque range `torque_range_nm`: `torque_margin` times each end of it."""
    lo, hi = torque_range_nm
    return WatchdogLimits(
        torque_limits_nm=(torque_margin * lo, torque_margin * hi),
        max_tracking_error_deg=max_tracking_error_deg,
        max_tracking_error_s=max_tracking_error_s,
        lag_s=lag_s,
    )


class WatchedJoint(Protocol):
    """What the watchdog reads of a joint (`hardware.joint.JointConfig`)."""

    @property
    def name(self) -> str: ...

    @property
    def watchdog(self) -> WatchdogLimits | None: ...

    def angle_from_volts(self, volts: npt.ArrayLike) -> FloatArray: ...

    def torque_from_volts(self, volts: npt.ArrayLike) -> FloatArray: ...


class LoopWatch:
    """One paced loop's watchdog: `check` each scan block as it is read. Joint k's angle and torque are
    scan columns 2k and 2k+1, its command column k of the loop's (ticks x joints) commands."""

    def __init__(self, joints: Sequence[WatchedJoint], t0: float, output_rate_hz: float, where: str) -> None:
        self.watched = [(k, j, j.watchdog) for k, j in enumerate(joints) if j.watchdog is not None]
        self.t0 = t0
        self.rate_hz = output_rate_hz
        self.where = where
        # per joint: the time the tracking error has been beyond its limit since (None: it is not)
        self.onset_s: list[float | None] = [None] * len(joints)

    def check(self, block: ScanBlock, cmd: FloatArray, written: int) -> WatchdogTripped | None:
        """The first breach in `block` (rows on the loop's clock), None if there is none. `cmd`: the loop's
        commands, the first `written` of them written."""
        if not self.watched or block.t_s.shape[0] == 0 or written == 0:
            return None
        t = np.asarray(block.t_s, dtype=np.float64) - self.t0
        found: list[tuple[float, str, str, float, str, str]] = []  # (time_s, joint, quantity, value, ...)
        for k, joint, limits in self.watched:
            column = cmd[:, k]
            torque = joint.torque_from_volts(block.volts[:, 2 * k + 1])
            lo, hi = limits.torque_limits_nm
            # the telemetry saturates at the range's ends (Eq 3 maps +-10 V onto it): a reading AT an end,
            # up to the single-precision rounding of the stored codes, is the joint at its limit, not beyond
            slack = TORQUE_ROUNDING * (hi - lo)
            out = np.flatnonzero((torque < lo - slack) | (torque > hi + slack))
            if out.size:
                i = int(out[0])
                limit = f"{lo:g} to {hi:g} N·m"
                found.append((float(t[i]), joint.name, "torque", float(torque[i]), limit, "N·m"))
            angle = joint.angle_from_volts(block.volts[:, 2 * k])
            tick = np.clip(np.floor((t - limits.lag_s) * self.rate_hz), 0, written - 1).astype(np.int64)
            error = angle - column[tick]
            exceed = np.abs(error) > limits.max_tracking_error_deg
            # the start time of the run of exceeding rows each row belongs to (carried over from the block
            # before); a row trips once its run has lasted max_tracking_error_s
            starts = np.where(
                exceed & ~np.concatenate([[self.onset_s[k] is not None], exceed[:-1]]), t, -np.inf
            )
            carried = self.onset_s[k]
            if carried is not None and exceed[0]:
                starts[0] = carried
            onset = np.maximum.accumulate(starts)
            self.onset_s[k] = float(onset[-1]) if exceed[-1] else None
            late = np.flatnonzero(exceed & (t - onset >= limits.max_tracking_error_s))
            if late.size:
                i = int(late[0])
                limit = (
                    f"±{limits.max_tracking_error_deg:g} deg for at most {limits.max_tracking_error_s:g} s"
                )
                found.append((float(t[i]), joint.name, "tracking error", float(error[i]), limit, "deg"))
        if not found:
            return None
        when, who, what, value, limit, units = min(found, key=lambda f: f[0])
        return WatchdogTripped(
            where=self.where, joint=who, quantity=what, value=value, limit=limit, units=units, time_s=when
        )
