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
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import Interrupted, InvalidInput
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.joint import JointConfig as JointConfig
from protocol_runner.hardware.joint import OnStop, StopRequested
from protocol_runner.hardware.joint import TrialRecording as TrialRecording
from protocol_runner.hardware.safety import SafetyLimits, check_trajectory, parking_ramp_deg

FloatArray = npt.NDArray[np.float64]

READ_EVERY_TICKS = 10
"""Output ticks between two reads of the input scan (100 ms at 100 Hz: 100 rows per read at 1 kHz)."""

BLOCK_S = 1.0
"""The most robot time one block of the simulator's block path covers: a stop request is seen within it."""

N_SCAN_CHANNELS = 2
"""Scan order: column 0 = angle channel, column 1 = torque channel."""


class ScheduledBlockIO(Protocol):
    """Boards that take a block of scheduled writes and read the scan at its last one in one call — the
    DAQ simulator in simulated time (`SimulatedRig.send_block`). Real boards are paced tick by tick."""

    @property
    def accepts_scheduled_blocks(self) -> bool: ...

    def drives(self, ao: object, ai: object) -> bool: ...

    def send_block(
        self, channel: int, times_s: FloatArray, volts: FloatArray
    ) -> tuple[npt.NDArray[np.int64], ScanBlock]: ...


def block_end(start: int, n: int, block_ticks: int, stop_requested: StopRequested | None) -> tuple[int, bool]:
    """The end of the block path's next block from tick `start` (of `n`) and whether a stop was requested
    there. `stop_requested` is polled, in order, at each READ_EVERY_TICKS boundary the per-tick loop polls
    (after ticks start + 10, start + 20, ...), up to `block_ticks` ahead, before the block is simulated; the
    block ends at the first boundary that asks for a stop. So a stop takes effect after the same sample as
    in the per-tick loop (for a request that depends on the polls, not on the samples), and a signal is
    seen within one block."""
    end = start
    limit = min(start + block_ticks, n)
    while end < limit:
        end = min(end + READ_EVERY_TICKS, n)
        if stop_requested is not None and stop_requested():
            return end, True
    return end, False


@dataclass(eq=False)
class Rig:
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
    # The simulator's block path (set by `SimulatedRig.make_rig`); None on the hardware bench.
    block_io: ScheduledBlockIO | None = field(default=None, init=False)

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

    def _block_output(self) -> ScheduledBlockIO | None:
        """The block path, when the boards offer one, take scheduled blocks now, and are the rig's boards
        (a board replaced or wrapped since, e.g. by fault injection, is driven tick by tick)."""
        io = self.block_io
        if io is not None and io.accepts_scheduled_blocks is True and io.drives(self.ao, self.ai):
            return io
        return None

    def send(
        self,
        cmd: FloatArray,
        *,
        where: str,
        stop_requested: StopRequested | None,
        on_stop: OnStop | None = None,
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
        block_out = self._block_output()
        block_ticks = max(READ_EVERY_TICKS, int(rate * BLOCK_S) // READ_EVERY_TICKS * READ_EVERY_TICKS)
        try:
            start = 0
            while start < n:
                if block_out is None:  # the paced loop, tick by tick (real boards, --realtime)
                    end = min(start + READ_EVERY_TICKS, n)
                    for k in range(start, end):
                        sleep_until(schedule[k])
                        actual[k] = now()
                        codes[k] = write(channel, volts_list[k])
                    append(read())
                    stop_now = not stopped and stop_requested is not None and stop_requested()
                else:  # simulated time: up to BLOCK_S of the same samples in one call (see block_end)
                    end, stop_now = block_end(start, n, block_ticks, None if stopped else stop_requested)
                    times = schedule[start:end]
                    block_codes, scan = block_out.send_block(channel, np.asarray(times), volts[start:end])
                    codes[start:end] = block_codes.tolist()
                    actual[start:end] = times  # each sample written at its time: what now() reads
                    append(scan)  # read at the block's last write, as the per-tick loop reads
                start = end
                if tap is not None:
                    tap.scan(blocks[-1])
                if stop_now:
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
        lateness_s = np.asarray(actual, dtype=np.float64) - schedule_arr
        return self._recording(cmd, volts, codes, lateness_s, scan, input_time_s, t0, where)

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
        input_time_s = np.arange(scan.t_s.shape[0], dtype=np.float64) / joint.input_rate_hz
        lateness_s = np.asarray(actual[:n], dtype=np.float64) - (t0 + np.arange(n) * dt)
        return self._recording(cmd[:n], volts[:n], codes[:n], lateness_s, scan, input_time_s, t0, where)

    def _recording(
        self,
        cmd: FloatArray,
        volts: FloatArray,
        codes: list[int],
        lateness_s: FloatArray,
        scan: ScanBlock,
        input_time_s: FloatArray,
        t0: float,
        where: str,
    ) -> TrialRecording:
        """The recording of the samples written (commands, their volts and codes, each tick's lateness)
        and the rows scanned (angle in column 0, torque in 1), in the joint's units."""
        joint = self.joint
        angle_volts = np.ascontiguousarray(scan.volts[:, 0], dtype=np.float64)
        torque_volts = np.ascontiguousarray(scan.volts[:, 1], dtype=np.float64)
        return TrialRecording(
            command_time_s=np.arange(cmd.shape[0], dtype=np.float64) * (1.0 / joint.output_rate_hz),
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
            tick_lateness_s=lateness_s,
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
