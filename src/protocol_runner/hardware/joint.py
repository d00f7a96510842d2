"""What a rig is bound to and what it records: the joint's channels, rates, calibration and limits
(`JointConfig`), one run of the acquisition loop (`TrialRecording`), and how a caller stops that loop
(`StopRequested`, `OnStop`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.conversions import angle_to_volts, volts_to_angle, volts_to_torque
from protocol_runner.hardware.safety import SafetyLimits, clamp_volts
from protocol_runner.hardware.watchdog import WatchdogLimits

FloatArray = npt.NDArray[np.float64]

StopRequested = Callable[[], bool]
"""Polled by a paced loop as it reads: True asks it to stop (the operator's stop, a signal)."""
OnStop = Callable[[int], FloatArray]
"""Given the number of samples written when a stop was asked, the samples to send next (the parking)."""


@dataclass(frozen=True, kw_only=True)
class JointConfig:
    """One joint as the protocol defines it: Eq 1-3 ranges (thesis Tables 2-3: `range_deg` maps onto
    -10/+10 V, `torque_range_nm` is Eq 3's), channels, rates, calibration tables (thesis §2.5: `command_table`
    real -> input angle before Eq 1, `angle_table` and `torque_table` output -> real after Eq 2 / Eq 3; None =
    identity), the safety envelope and the watchdog (None = not watched)."""

    name: str
    range_deg: tuple[float, float]
    torque_range_nm: tuple[float, float]
    output_channel: int
    angle_input_channel: int
    torque_input_channel: int
    output_rate_hz: float = 100.0
    input_rate_hz: float = 1000.0
    command_table: CalibrationTable | None = None
    angle_table: CalibrationTable | None = None
    torque_table: CalibrationTable | None = None
    limits: SafetyLimits
    watchdog: WatchdogLimits | None = None

    def __post_init__(self) -> None:
        for label, pair in (("range_deg", self.range_deg), ("torque_range_nm", self.torque_range_nm)):
            lo, hi = (float(v) for v in pair)
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                raise InvalidInput(
                    f"joint {self.name}: {label} must be (min, max) with max > min, got {pair!r}"
                )
            object.__setattr__(self, label, (lo, hi))
        for label in ("output_channel", "angle_input_channel", "torque_input_channel"):
            value = getattr(self, label)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise InvalidInput(f"joint {self.name}: {label} must be a channel number >= 0, got {value!r}")
        if self.angle_input_channel == self.torque_input_channel:
            raise InvalidInput(
                f"joint {self.name}: angle and torque must be read on different input channels "
                f"(both are {self.angle_input_channel})"
            )
        for label in ("output_rate_hz", "input_rate_hz"):
            value = getattr(self, label)
            if not (math.isfinite(value) and value > 0):
                raise InvalidInput(f"joint {self.name}: {label} must be a positive number, got {value!r}")
        lo, hi = self.limits.range_deg
        if lo < self.range_deg[0] or hi > self.range_deg[1]:
            raise InvalidInput(
                f"joint {self.name}: the safety range {self.limits.range_deg} must lie inside the joint's "
                f"Eq 1 range {self.range_deg}"
            )

    def command_to_volts(self, command_deg: npt.ArrayLike) -> FloatArray:
        """Real angle wanted -> command look-up table -> Eq 1 -> clamp to ±10 V."""
        cmd = np.asarray(command_deg, dtype=np.float64)
        input_deg = self.command_table(cmd) if self.command_table is not None else cmd
        return clamp_volts(angle_to_volts(input_deg, self.range_deg))

    def angle_from_volts(self, volts: npt.ArrayLike) -> FloatArray:
        """Angle telemetry volts -> Eq 2 -> angle look-up table (output -> real degrees)."""
        shown = volts_to_angle(volts, self.range_deg)
        return self.angle_table(shown) if self.angle_table is not None else shown

    def torque_from_volts(self, volts: npt.ArrayLike) -> FloatArray:
        """Torque telemetry volts -> Eq 3 -> torque look-up table (output -> real N·m)."""
        shown = volts_to_torque(volts, self.torque_range_nm)
        return self.torque_table(shown) if self.torque_table is not None else shown


@dataclass(frozen=True)
class TrialRecording:
    """Everything one paced run produced. Times in seconds from t0 (the scan start).

    Output side, one entry per output tick: command_time_s (schedule), command_deg (real angle wanted),
    command_volts (after the LUT, Eq 1 and clamp), command_codes (the 16-bit codes the board reports it
    sent, as int32), tick_lateness_s (write time - scheduled time).
    Input side, one entry per scan row: input_time_s, angle_codes/torque_codes (raw board codes),
    angle_volts/torque_volts, angle_deg/torque_nm (after Eq 2/3 and the output look-up tables).
    """

    command_time_s: FloatArray
    command_deg: FloatArray
    command_volts: FloatArray
    command_codes: npt.NDArray[np.int32]
    input_time_s: FloatArray
    angle_codes: npt.NDArray[np.int32]
    torque_codes: npt.NDArray[np.int32]
    angle_volts: FloatArray
    torque_volts: FloatArray
    angle_deg: FloatArray
    torque_nm: FloatArray
    tick_lateness_s: FloatArray
    where: str = ""
    t0_s: float = 0.0
    output_rate_hz: float = 100.0
    input_rate_hz: float = 1000.0
    # a planned motion's whole commanded stream (hardware/motion.py); empty for a bare run_trajectory
    stream_time_s: FloatArray = field(default_factory=lambda: np.zeros(0, dtype=np.float64))
    stream_deg: FloatArray = field(default_factory=lambda: np.zeros(0, dtype=np.float64))
    stream_segment: npt.NDArray[np.int8] = field(default_factory=lambda: np.zeros(0, dtype=np.int8))

    @property
    def n_ticks(self) -> int:
        return int(self.command_time_s.shape[0])

    @property
    def n_samples(self) -> int:
        return int(self.input_time_s.shape[0])
