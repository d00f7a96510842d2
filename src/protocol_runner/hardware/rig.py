"""The rig: one joint's analog output, analog input scan and clock, bound to its channels and calibration.

`Rig.run_trajectory` is the acquisition loop (thesis §2.4-2.5); trials and checks
send through `hardware/motion.py`, which adds the approach and the exit in the same loop (`Rig.send`):

1. safety envelope (`hardware/safety.py`) on the whole trajectory — a violation raises before any write;
2. command look-up table, real -> input angle (thesis §2.5.1);
3. Eq 1, angle -> volts over the joint's range; clamp to ±10 V;
4. the paced loop (`hardware/paced.py`, shared with `MultiRig`): start the input scan ([angle channel,
   torque channel] at `input_rate_hz`), then for each output tick k sleep until t0 + k / output_rate_hz,
   write the volts, record the write time; read the scan every `READ_EVERY_TICKS` ticks; after the last
   tick wait one more tick and stop the scan;
5. telemetry: the scan's volts -> Eq 2 (angle) and Eq 3 (torque) -> the angle and torque look-up tables
   (output -> real, thesis §2.5.1-2.5.2).

Times in a `TrialRecording` count from t0, the clock reading just after the scan started (the first output
tick is scheduled at t0). `tick_lateness_s[k]` is the clock reading just before write k minus its schedule:
the output jitter recorded per trial.

The loop does as little as possible per tick: all conversions are done on whole arrays before and after,
the schedule is precomputed, and results go into preallocated lists.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.joint import JointConfig, StopRequested, TrialRecording
from protocol_runner.hardware.paced import Loop, PacedLoop, input_time_base_s
from protocol_runner.hardware.safety import SafetyLimits, check_trajectory, parking_ramp_deg

FloatArray = npt.NDArray[np.float64]

N_SCAN_CHANNELS = 2
"""Scan order: column 0 = angle channel, column 1 = torque channel."""


@dataclass(eq=False)
class Rig(PacedLoop[TrialRecording]):
    """Binds an analog output, an analog input and a clock to one joint (`JointConfig`)."""

    joint: JointConfig
    ao: AnalogOutput
    ai: AnalogInput
    clock: Clock
    _prepared: bool = field(default=False, init=False)
    _last_command_deg: float | None = field(default=None, init=False)
    # Entered around every paced loop; the hardware bench sets it to real-time scheduling.
    loop_context: Callable[[], contextlib.AbstractContextManager[object]] = field(
        default=contextlib.nullcontext, init=False
    )
    # The live monitor's sampler (--monitor): shown each scan block as it is read; None costs nothing.
    tap: LoopTap | None = field(default=None, init=False)

    @property
    def scan_channels(self) -> tuple[int, int]:
        return (self.joint.angle_input_channel, self.joint.torque_input_channel)

    @property
    def last_command_deg(self) -> float | None:
        """The last real angle written to the joint (None before any write)."""
        return self._last_command_deg

    def prepare(self) -> None:
        """Configure the output channel (±10 V). Once per rig: on a USB-3105 this also drives the output
        to 0 V, i.e. the middle of the joint's Eq 1 range. `run_trajectory` calls it if needed."""
        if not self._prepared:
            self.ao.configure_channel(self.joint.output_channel)
            self._prepared = True

    def run_trajectory(
        self,
        command_deg: npt.ArrayLike,
        *,
        where: str,
        stop_requested: StopRequested | None = None,
    ) -> TrialRecording:
        """Send `command_deg` (real joint angles, one per output tick) and record the telemetry.

        Raises SafetyViolation (exit 4) before any write if the trajectory leaves the envelope.
        `stop_requested`, polled at every scan read (~10 ticks), lets a signal handler stop the trial at a
        safe point: the scan is stopped and `Interrupted` raised (the caller then parks the joint).
        """
        joint = self.joint
        cmd = np.array(command_deg, dtype=np.float64)
        check_trajectory(
            cmd,
            joint.output_rate_hz,
            joint.limits,
            where=where,
            command_table=joint.command_table,
            volts_range_deg=joint.range_deg,
        )
        with self.loop_context():
            return self.send(cmd, where=where, stop_requested=stop_requested)

    def park(self, *, from_deg: float | None = None, where: str = "park") -> TrialRecording:
        """Ramp the joint to `limits.park_angle_deg` at `limits.park_rate_deg_s` (trapezoidal, within the
        acceleration limit). Starts from `from_deg`, else the last commanded angle, else the measured one.
        """
        limits = self.joint.limits
        start = from_deg if from_deg is not None else self._last_command_deg
        if start is None:
            start = self.read_angle_deg()
        ramp = parking_ramp_deg(start, limits, self.joint.output_rate_hz)
        # A joint found outside the range must still be parkable: widen the range to the start point only.
        lo, hi = limits.range_deg
        eq1_lo, eq1_hi = self.joint.range_deg
        widened = SafetyLimits(
            range_deg=(max(min(lo, start), eq1_lo), min(max(hi, start), eq1_hi)),
            max_rate_deg_s=limits.max_rate_deg_s,
            max_accel_deg_s2=limits.max_accel_deg_s2,
            park_angle_deg=limits.park_angle_deg,
            park_rate_deg_s=limits.park_rate_deg_s,
        )
        ramp = np.clip(ramp, widened.range_deg[0], widened.range_deg[1])
        check_trajectory(
            ramp,
            self.joint.output_rate_hz,
            widened,
            where=where,
            command_table=self.joint.command_table,
            volts_range_deg=self.joint.range_deg,
        )
        with self.loop_context():
            return self.send(ramp, where=where, stop_requested=None)

    def read_angle_deg(self, duration_s: float = 0.05) -> float:
        """Measure the joint's current real angle: a short scan, averaged (Eq 2 + angle look-up table)."""
        self.ai.start_scan(self.scan_channels, self.joint.input_rate_hz)
        try:
            self.clock.sleep_until(self.clock.now_s() + duration_s)
        finally:
            block = self.ai.stop_scan()
        if block.n_samples == 0:
            raise InvalidInput("could not measure the joint angle: the input scan returned no samples")
        return float(np.mean(self.joint.angle_from_volts(block.volts[:, 0])))

    # ---- the paced loop (`PacedLoop.send`) for one joint ------------------------------------------------
    UNWRITTEN: ClassVar[object] = -1
    SHOWS_PARK: ClassVar[bool] = True

    @property
    def rates_hz(self) -> tuple[float, float]:
        return (self.joint.output_rate_hz, self.joint.input_rate_hz)

    def _command_volts(self, cmd: FloatArray) -> FloatArray:
        return self.joint.command_to_volts(cmd)

    def _tick_writer(self, volts: FloatArray) -> Callable[[int], object]:
        write, channel, volts_list = self.ao.write_volts, self.joint.output_channel, volts.tolist()
        return lambda k: write(channel, volts_list[k])

    def _note_written(self, cmd: FloatArray, written: int) -> None:
        if written > 0:
            self._last_command_deg = float(cmd[written - 1])

    def _recording(self, loop: Loop, where: str, *, partial: bool) -> TrialRecording:
        """The recording of the samples written (commands, their volts and codes, each tick's lateness)
        and the rows scanned (angle in column 0, torque in 1), in the joint's units; `partial`: what an
        aborted trial recorded before it stopped."""
        joint = self.joint
        scan = ScanBlock.concatenate(loop.blocks, N_SCAN_CHANNELS)
        if partial:
            n = loop.written(self.UNWRITTEN)
            input_time_s = np.arange(scan.t_s.shape[0], dtype=np.float64) / joint.input_rate_hz
            dt = 1.0 / joint.output_rate_hz
            lateness_s = np.asarray(loop.actual[:n], dtype=np.float64) - (loop.t0 + np.arange(n) * dt)
        else:
            n = loop.n
            if scan.codes.ndim != 2 or scan.codes.shape[1] != N_SCAN_CHANNELS:
                raise InvalidInput(
                    f"{where}: the input board returned codes of shape {scan.codes.shape}, "
                    f"expected {N_SCAN_CHANNELS} columns"
                )
            input_time_s = input_time_base_s(scan, loop.t0, joint.input_rate_hz)
            schedule = np.asarray(loop.schedule[:n], dtype=np.float64)
            lateness_s = np.asarray(loop.actual, dtype=np.float64) - schedule
        angle_volts = np.ascontiguousarray(scan.volts[:, 0], dtype=np.float64)
        torque_volts = np.ascontiguousarray(scan.volts[:, 1], dtype=np.float64)
        return TrialRecording(
            command_time_s=np.arange(n, dtype=np.float64) * (1.0 / joint.output_rate_hz),
            command_deg=loop.cmd[:n],
            command_volts=loop.volts[:n],
            command_codes=np.asarray(loop.codes[:n], dtype=np.int32),
            input_time_s=input_time_s,
            angle_codes=np.ascontiguousarray(scan.codes[:, 0], dtype=np.int32),
            torque_codes=np.ascontiguousarray(scan.codes[:, 1], dtype=np.int32),
            angle_volts=angle_volts,
            torque_volts=torque_volts,
            angle_deg=joint.angle_from_volts(angle_volts),
            torque_nm=joint.torque_from_volts(torque_volts),
            tick_lateness_s=lateness_s,
            where=where,
            t0_s=loop.t0,
            output_rate_hz=joint.output_rate_hz,
            input_rate_hz=joint.input_rate_hz,
        )
