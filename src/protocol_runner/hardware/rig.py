"""The rig: one joint's analog output, analog input scan and clock, bound to its channels and calibration.

`Rig.run_trajectory` is the acquisition loop (thesis §2.4-2.5, DESIGN.md "Data flow"); trials and checks
send through `hardware/motion.py`, which adds the approach and the exit in the same loop (`Rig.send`):

1. safety envelope (`hardware/safety.py`) on the whole trajectory — a violation raises before any write;
2. command look-up table, real -> input angle (thesis §2.5.1);
3. Eq 1, angle -> volts over the joint's range; clamp to ±10 V;
4. the paced loop: start the input scan ([angle channel, torque channel] at `input_rate_hz`), then for each
   output tick k sleep until t0 + k / output_rate_hz, write the volts, record the write time; read the scan
   every `READ_EVERY_TICKS` ticks; after the last tick wait one more tick and stop the scan;
5. telemetry: the scan's volts -> Eq 2 (angle) and Eq 3 (torque) -> the angle and torque look-up tables
   (output -> real, thesis §2.5.1-2.5.2).

Times in a `TrialRecording` count from t0, the clock reading just after the scan started (the first output
tick is scheduled at t0). `tick_lateness_s[k]` is the clock reading just before write k minus its schedule:
the output jitter DESIGN.md asks to record per trial.

The loop does as little as possible per tick: all conversions are done on whole arrays before and after,
the schedule is precomputed, and results go into preallocated lists.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import Interrupted, InvalidInput
from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.conversions import angle_to_volts, volts_to_angle, volts_to_torque
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.safety import SafetyLimits, check_trajectory, clamp_volts, parking_ramp_deg

FloatArray = npt.NDArray[np.float64]

READ_EVERY_TICKS = 10
"""Output ticks between two reads of the input scan (100 ms at 100 Hz: 100 rows per read at 1 kHz)."""

N_SCAN_CHANNELS = 2
"""Scan order: column 0 = angle channel, column 1 = torque channel."""


@dataclass(frozen=True, kw_only=True)
class JointConfig:
    """One joint as the protocol defines it: Eq 1-3 ranges (thesis Tables 2-3), channels, rates,
    calibration tables (thesis §2.5) and the safety envelope.

    range_deg: Eq 1-2 Minimum/Maximum_Position (the angle that maps to -10/+10 V).
    torque_range_nm: Eq 3 Minimum/Maximum_Torque.
    output_channel: analog output channel commanding the joint.
    angle_input_channel, torque_input_channel: analog input channels of the joint's telemetry.
    command_table: real_deg -> input_deg, applied before Eq 1 (None = identity).
    angle_table: output_deg -> real_deg, applied after Eq 2 (None = identity).
    torque_table: output_nm -> real_nm, applied after Eq 3 (None = identity).
    """

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


class Rig:
    """Binds an analog output, an analog input and a clock to one joint (`JointConfig`)."""

    def __init__(self, joint: JointConfig, ao: AnalogOutput, ai: AnalogInput, clock: Clock) -> None:
        self.joint = joint
        self.ao = ao
        self.ai = ai
        self.clock = clock
        self._prepared = False
        self._last_command_deg: float | None = None
        # Entered around every paced loop; the hardware bench sets it to real-time scheduling.
        self.loop_context: Callable[[], contextlib.AbstractContextManager[object]] = contextlib.nullcontext
        # The live monitor's sampler (--monitor): shown each scan block as it is read; None costs nothing.
        self.tap: LoopTap | None = None

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
        stop_requested: Callable[[], bool] | None = None,
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

    def send(
        self,
        cmd: FloatArray,
        *,
        where: str,
        stop_requested: Callable[[], bool] | None,
        on_stop: Callable[[int], FloatArray] | None = None,
    ) -> TrialRecording:
        """The paced loop over samples already checked. On a stop request `on_stop(written)`, if given,
        returns the samples to send next in the same loop; then `Interrupted` carries the whole recording."""
        joint = self.joint
        volts = joint.command_to_volts(cmd)
        self.prepare()
        n = int(cmd.shape[0])
        rate = joint.output_rate_hz
        dt = 1.0 / rate
        volts_list: list[float] = volts.tolist()
        codes: list[int] = [-1] * n
        actual: list[float] = [0.0] * n
        blocks: list[ScanBlock] = []

        # Bind everything the loop touches to locals: attribute lookups cost more than the work itself.
        write = self.ao.write_volts
        sleep_until = self.clock.sleep_until
        now = self.clock.now_s
        read = self.ai.read_available
        append = blocks.append
        channel = joint.output_channel

        self.ai.start_scan(self.scan_channels, joint.input_rate_hz)
        t0 = now()
        schedule: list[float] = (t0 + np.arange(n + 1, dtype=np.float64) * dt).tolist()
        stopped = ""
        tap = self.tap
        if tap is not None:
            tap.start(where, cmd, t0)
        try:
            start = 0
            while start < n:
                end = min(start + READ_EVERY_TICKS, n)
                for k in range(start, end):
                    sleep_until(schedule[k])
                    actual[k] = now()
                    codes[k] = write(channel, volts_list[k])
                append(read())
                start = end
                if tap is not None:
                    tap.scan(blocks[-1])
                if not stopped and stop_requested is not None and stop_requested():
                    stopped = f"{where}: stopped on request at t = {schedule[end - 1] - t0:.2f} s"
                    if on_stop is None:
                        raise Interrupted(stopped)
                    # continue in the same loop with what the stop sends (no pause: the output would hold)
                    cmd = np.concatenate([cmd[:end], on_stop(end)])
                    volts = np.concatenate([volts[:end], joint.command_to_volts(cmd[end:])])
                    volts_list, n = volts.tolist(), int(cmd.size)
                    codes, actual = codes[:end] + [-1] * (n - end), actual[:end] + [0.0] * (n - end)
                    schedule = (t0 + np.arange(n + 1, dtype=np.float64) * dt).tolist()
                    if tap is not None:
                        tap.start(f"{where} (park)", cmd, t0)  # the stop's samples, shown as parking
            sleep_until(schedule[n])  # one more tick: the scan covers the response to the last command
            if stopped:
                raise Interrupted(stopped)
        except BaseException as exc:
            self._note_last_written(cmd, codes)
            with contextlib.suppress(Exception):  # the original error matters more than a failing stop
                append(self.ai.stop_scan())
            # keep the data recorded so far with the error (a board that vanished mid-trial: the session
            # archives it as a failed trial)
            with contextlib.suppress(Exception):
                exc.partial_recording = self._partial(cmd, volts, codes, actual, blocks, t0, where)  # type: ignore[attr-defined]
            raise
        append(self.ai.stop_scan())
        self._last_command_deg = float(cmd[-1])

        scan = ScanBlock.concatenate(blocks, N_SCAN_CHANNELS)
        if scan.codes.ndim != 2 or scan.codes.shape[1] != N_SCAN_CHANNELS:
            raise InvalidInput(
                f"{where}: the input board returned codes of shape {scan.codes.shape}, "
                f"expected {N_SCAN_CHANNELS} columns"
            )
        schedule_arr = np.asarray(schedule[:n], dtype=np.float64)
        # Times relative to the trial start from sample indices (both boards are paced: output by the
        # schedule, input by the scan clock), so they do not depend on where the clock stood: a trial
        # recorded at another moment has bit-identical time bases. The scan's start offset is kept to 1 us.
        n_in = int(scan.t_s.shape[0])
        offset = round((float(scan.t_s[0]) - t0) * 1e6) / 1e6 if n_in else 0.0
        input_time_s = offset + np.arange(n_in, dtype=np.float64) / joint.input_rate_hz
        angle_volts = np.ascontiguousarray(scan.volts[:, 0], dtype=np.float64)
        torque_volts = np.ascontiguousarray(scan.volts[:, 1], dtype=np.float64)
        return TrialRecording(
            command_time_s=np.arange(n, dtype=np.float64) * dt,
            command_deg=cmd,
            command_volts=volts,
            command_codes=np.asarray(codes, dtype=np.int32),
            input_time_s=input_time_s,
            angle_codes=np.ascontiguousarray(scan.codes[:, 0], dtype=np.int32),
            torque_codes=np.ascontiguousarray(scan.codes[:, 1], dtype=np.int32),
            angle_volts=angle_volts,
            torque_volts=torque_volts,
            angle_deg=joint.angle_from_volts(angle_volts),
            torque_nm=joint.torque_from_volts(torque_volts),
            tick_lateness_s=np.asarray(actual, dtype=np.float64) - schedule_arr,
            where=where,
            t0_s=t0,
            output_rate_hz=rate,
            input_rate_hz=joint.input_rate_hz,
        )

    def _partial(
        self,
        cmd: FloatArray,
        volts: FloatArray,
        codes: list[int],
        actual: list[float],
        blocks: list[ScanBlock],
        t0: float,
        where: str,
    ) -> TrialRecording:
        """What an aborted trial recorded before it stopped: the ticks written and the rows scanned."""
        joint = self.joint
        n = codes.index(-1) if -1 in codes else len(codes)
        scan = ScanBlock.concatenate(blocks, N_SCAN_CHANNELS)
        dt = 1.0 / joint.output_rate_hz
        angle_volts = np.ascontiguousarray(scan.volts[:, 0], dtype=np.float64)
        torque_volts = np.ascontiguousarray(scan.volts[:, 1], dtype=np.float64)
        return TrialRecording(
            command_time_s=np.arange(n, dtype=np.float64) * dt,
            command_deg=cmd[:n],
            command_volts=volts[:n],
            command_codes=np.asarray(codes[:n], dtype=np.int32),
            input_time_s=np.arange(scan.t_s.shape[0], dtype=np.float64) / joint.input_rate_hz,
            angle_codes=np.ascontiguousarray(scan.codes[:, 0], dtype=np.int32),
            torque_codes=np.ascontiguousarray(scan.codes[:, 1], dtype=np.int32),
            angle_volts=angle_volts,
            torque_volts=torque_volts,
            angle_deg=joint.angle_from_volts(angle_volts),
            torque_nm=joint.torque_from_volts(torque_volts),
            tick_lateness_s=np.asarray(actual[:n], dtype=np.float64) - (t0 + np.arange(n) * dt),
            where=where,
            t0_s=t0,
            output_rate_hz=joint.output_rate_hz,
            input_rate_hz=joint.input_rate_hz,
        )

    def _note_last_written(self, cmd: FloatArray, codes: list[int]) -> None:
        """After an aborted loop, remember the last angle actually written (for parking)."""
        written = codes.index(-1) if -1 in codes else len(codes)
        if written > 0:
            self._last_command_deg = float(cmd[written - 1])
