"""The rig: an analog output, an analog input scan and a clock bound to the joints they drive (channel
order), with each joint's channels and calibration. One joint (the knee campaign) is a rig of one joint.

`Rig.run_trajectory` is the acquisition loop (thesis §2.4-2.5); trials and checks send through
`hardware/motion.py`, which adds every joint's approach and exit in the same loop (`Rig.send`):

1. safety envelope (`hardware/safety.py`) on every joint's samples - a violation raises before any write;
2. command look-up table, real -> input angle (thesis §2.5.1); Eq 1, angle -> volts over the joint's
   range; clamp to ±10 V;
3. the paced loop (`Rig.send`): start the input scan ([angle_0, torque_0, angle_1, torque_1, ...] at
   the input rate), then for each output tick k sleep until t0 + k / output_rate_hz and write every joint's
   volts: one joint, one `write_volts`; several, one synchronous update (`write_volts_sync`: on the
   USB-3105 each channel's AOUT held, then one AOUT_SYNC latching them together, thesis §2.3: the boards
   control "the 12 joints ... simultaneously"). Read the scan (and poll the stop request) every
   `READ_EVERY_TICKS` ticks; after the last tick wait one more tick and stop the scan;
4. telemetry: the scan's volts -> Eq 2 (angle) and Eq 3 (torque) -> the angle and torque look-up tables
   (output -> real, thesis §2.5.1-2.5.2).

On a stop request `on_stop(written)`, if given, returns the samples to send next in the same loop (no
pause: the output would hold), then `Interrupted` is raised. The watchdog (`hardware/watchdog.py`) checks
every block as it is read: a measured signal beyond its limit stops the loop as a stop request does, then
its `WatchdogTripped` (exit 4) is raised instead; parking is not watched. An error or an interruption
carries what was recorded so far (`partial_recording`). The live monitor (`tap`) is started with every
joint's commands (restarted on the samples a stop sends, shown as parking) and shown every block read.
The DAQ simulator's boards satisfy the same interfaces (its clock jumps instead of sleeping), so a dry run
runs this same loop.

The recording is one `TrialRecording` per joint, all on the same time base. Times count from t0, the clock
reading just after the scan started (the first output tick is scheduled at t0); `tick_lateness_s[k]`, the
clock just before write k minus its schedule, is the output jitter recorded per trial.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import Interrupted, InvalidInput, WatchdogTripped
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.joint import JointConfig, OnStop, StopRequested, TrialRecording
from protocol_runner.hardware.safety import SafetyLimits, check_trajectory, parking_ramp_deg
from protocol_runner.hardware.watchdog import LoopWatch

FloatArray = npt.NDArray[np.float64]

READ_EVERY_TICKS = 10
"""Output ticks between two reads of the input scan (100 ms at 100 Hz: 100 rows per read at 1 kHz)."""


def schedule_s(t0: float, n: int, dt: float) -> list[float]:
    """The write times of ticks 0..n (tick n: one more tick, when the scan stops)."""
    times: list[float] = (t0 + np.arange(n + 1, dtype=np.float64) * dt).tolist()
    return times


def input_time_base_s(scan: ScanBlock, t0: float, input_rate_hz: float) -> FloatArray:
    """Input row times relative to t0 from sample indices (both boards are paced: output by the schedule,
    input by the scan clock), so they do not depend on where the clock stood: a trial recorded at another
    moment has bit-identical time bases. The scan's start offset is kept to 1 us."""
    n_in = int(scan.t_s.shape[0])
    offset = round((float(scan.t_s[0]) - t0) * 1e6) / 1e6 if n_in else 0.0
    times: FloatArray = offset + np.arange(n_in, dtype=np.float64) / input_rate_hz
    return times


@dataclass(eq=False)
class Loop:
    """One loop's samples as far as they go: the commands (ticks first), their volts and codes (None where
    not written yet), the write times, the schedule, the scan blocks read and t0."""

    cmd: FloatArray
    volts: FloatArray
    codes: list[object]
    actual: list[float]
    schedule: list[float]
    blocks: list[ScanBlock]
    t0: float

    def written(self) -> int:
        """How many ticks were written (the first unwritten code, else all)."""
        return self.codes.index(None) if None in self.codes else len(self.codes)


class Rig:
    """Binds one analog output, one analog input and a clock to one or several joints (channel order)."""

    def __init__(
        self, joints: Sequence[JointConfig], ao: AnalogOutput, ai: AnalogInput, clock: Clock
    ) -> None:
        if not joints:
            raise InvalidInput("a rig needs at least one joint")
        rates = {(j.output_rate_hz, j.input_rate_hz) for j in joints}
        if len(rates) != 1:
            shown = ", ".join(f"{j.name} {j.output_rate_hz:g}/{j.input_rate_hz:g} Hz" for j in joints)
            raise InvalidInput(f"the joints of one rig share its output and input rates, got {shown}")
        used: dict[tuple[str, int], str] = {}
        for j in joints:
            for kind, ch in (
                ("input", j.angle_input_channel),
                ("input", j.torque_input_channel),
                ("output", j.output_channel),
            ):
                if (kind, ch) in used:
                    raise InvalidInput(f"{kind} channel {ch} is both {used[kind, ch]}'s and {j.name}'s")
                used[kind, ch] = j.name
        self.joints = tuple(joints)
        self.ao, self.ai, self.clock = ao, ai, clock
        self.output_rate_hz, self.input_rate_hz = rates.pop()
        self._prepared = False
        self._last: list[float | None] = [None] * len(self.joints)
        # Entered around every paced loop; the hardware bench sets it to real-time scheduling.
        self.loop_context: Callable[[], contextlib.AbstractContextManager[object]] = contextlib.nullcontext
        # The live monitor's sampler (--monitor): shown each scan block as it is read; None costs nothing.
        self.tap: LoopTap | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def scan_channels(self) -> tuple[int, ...]:
        return tuple(ch for j in self.joints for ch in (j.angle_input_channel, j.torque_input_channel))

    @property
    def last_command_deg(self) -> tuple[float | None, ...]:
        """The last real angle written to each joint (None before any write)."""
        return tuple(self._last)

    def prepare(self) -> None:
        """Configure every joint's output channel (±10 V) once per rig: on a USB-3105 this also drives it to
        0 V, i.e. the middle of the joint's Eq 1 range. `send` calls it if needed."""
        if not self._prepared:
            for j in self.joints:
                self.ao.configure_channel(j.output_channel)
            self._prepared = True

    def single(self, name: str) -> Rig:
        """A rig of joint `name` alone on the same boards (its calibration check): the others hold their last
        output. Call `note_single` after using it."""
        k = self.names.index(name)
        rig = Rig((self.joints[k],), self.ao, self.ai, self.clock)
        self.prepare()
        rig._prepared = True
        rig._last = [self._last[k]]
        rig.loop_context = self.loop_context
        return rig

    def note_single(self, name: str, rig: Rig) -> None:
        """Take over where the rig `single(name)` left its joint."""
        self._last[self.names.index(name)] = rig._last[0]

    def run_trajectory(
        self,
        commands_deg: Sequence[npt.ArrayLike],
        *,
        where: str,
        stop_requested: StopRequested | None = None,
    ) -> tuple[TrialRecording, ...]:
        """Send `commands_deg` (one array of real joint angles per joint, one per output tick, as many each)
        and record the telemetry.

        Raises SafetyViolation (exit 4) before any write if a joint's samples leave its envelope.
        `stop_requested`, polled at every scan read (~10 ticks), lets a signal handler stop the trial at a
        safe point: the scan is stopped and `Interrupted` raised (the caller then parks the joints).
        """
        cmd = self._columns(commands_deg)
        for k in range(len(self.joints)):
            self.check(k, cmd[:, k], where)
        with self.loop_context():
            return self.send(cmd, where=where, stop_requested=stop_requested)

    def park(
        self, *, from_deg: Sequence[float | None] | None = None, where: str = "park"
    ) -> tuple[TrialRecording, ...]:
        """Ramp every joint to its `limits.park_angle_deg` at its `limits.park_rate_deg_s` (trapezoidal,
        within the acceleration limit), together. Each starts from `from_deg`, else its last commanded angle,
        else its measured one."""
        given = list(from_deg) if from_deg is not None else [None] * len(self.joints)
        known = [f if f is not None else last for f, last in zip(given, self._last, strict=True)]
        measured = self.read_angles_deg() if None in known else (0.0,) * len(known)
        starts = [float(m if s is None else s) for s, m in zip(known, measured, strict=True)]
        ramps = [
            parking_ramp_deg(s, j.limits, self.output_rate_hz)
            for s, j in zip(starts, self.joints, strict=True)
        ]
        n = max(r.size for r in ramps)
        cmd = np.stack([np.concatenate([r, np.full(n - r.size, r[-1])]) for r in ramps], axis=1)
        for k, j in enumerate(self.joints):
            # a joint found outside the range must still be parkable: widen the range to the start point only
            lo, hi = j.limits.range_deg
            widened = replace(
                j.limits,
                range_deg=(max(min(lo, starts[k]), j.range_deg[0]), min(max(hi, starts[k]), j.range_deg[1])),
            )
            cmd[:, k] = np.clip(cmd[:, k], *widened.range_deg)
            self.check(k, cmd[:, k], where, widened)
        with self.loop_context():
            return self.send(cmd, where=where, stop_requested=None, watch=False)

    def read_angles_deg(self, duration_s: float = 0.05) -> tuple[float, ...]:
        """Measure every joint's current real angle: a short scan, averaged (Eq 2 + angle look-up table)."""
        self.ai.start_scan(self.scan_channels, self.input_rate_hz)
        try:
            self.clock.sleep_until(self.clock.now_s() + duration_s)
        finally:
            block = self.ai.stop_scan()
        if block.n_samples == 0:
            raise InvalidInput("could not measure the joint angles: the input scan returned no samples")
        return tuple(
            float(np.mean(j.angle_from_volts(block.volts[:, 2 * k]))) for k, j in enumerate(self.joints)
        )

    def _columns(self, commands_deg: Sequence[npt.ArrayLike]) -> FloatArray:
        """(ticks, joints) from one array per joint."""
        arrays = [np.asarray(c, dtype=np.float64) for c in commands_deg]
        if len(arrays) != len(self.joints) or len({a.shape for a in arrays}) != 1 or arrays[0].ndim != 1:
            shown = ", ".join(str(a.shape) for a in arrays)
            raise InvalidInput(
                f"the rig drives {len(self.joints)} joint(s) ({', '.join(self.names)}): give one 1-D array "
                f"of angles per joint, as many samples each; got shapes {shown or 'none'}"
            )
        return np.stack(arrays, axis=1)

    def where_of(self, where: str, joint: JointConfig) -> str:
        """`where`, naming the joint when the rig drives several."""
        return where if len(self.joints) == 1 else f"{where}, joint {joint.name}"

    def check(self, k: int, command_deg: FloatArray, where: str, limits: SafetyLimits | None = None) -> None:
        """`check_trajectory` of joint k's samples against its envelope (or `limits`), its command table
        and Eq 1 range included."""
        j = self.joints[k]
        check_trajectory(
            command_deg,
            self.output_rate_hz,
            limits or j.limits,
            where=self.where_of(where, j),
            command_table=j.command_table,
            volts_range_deg=j.range_deg,
        )

    def send(
        self,
        cmd: FloatArray,
        *,
        where: str,
        stop_requested: StopRequested | None,
        on_stop: OnStop | None = None,
        watch: bool = True,
    ) -> tuple[TrialRecording, ...]:
        """The paced loop over samples already checked (ticks x joints). On a stop request `on_stop(written)`,
        if given, returns the samples to send next in the same loop; then `Interrupted` carries the whole
        recording. `watch`: run the watchdog on the measured signals (a tripped watchdog stops the loop
        the same way, then raises its `WatchdogTripped`)."""
        cmd = np.asarray(cmd, dtype=np.float64)
        volts = self._command_volts(cmd)
        self.prepare()
        n = int(cmd.shape[0])
        dt = 1.0 / self.output_rate_hz
        write = self._tick_writer(volts)
        codes: list[object] = [None] * n
        actual: list[float] = [0.0] * n
        blocks: list[ScanBlock] = []

        # Bind everything the loop touches to locals: attribute lookups cost more than the work itself.
        sleep_until = self.clock.sleep_until
        now = self.clock.now_s
        read = self.ai.read_available
        append = blocks.append

        self.ai.start_scan(self.scan_channels, self.input_rate_hz)
        t0 = now()
        schedule = schedule_s(t0, n, dt)
        loop = Loop(cmd, volts, codes, actual, schedule, blocks, t0)
        stopped = ""
        watchdog = LoopWatch(self.joints, t0, self.output_rate_hz, where) if watch else None
        tripped: WatchdogTripped | None = None
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
                    codes[k] = write(k)
                append(read())
                if watchdog is not None and not stopped:
                    tripped = watchdog.check(blocks[-1], cmd, end)
                stop_now = not stopped and (
                    tripped is not None or (stop_requested is not None and stop_requested())
                )
                start = end
                if tap is not None:
                    tap.scan(blocks[-1])
                if stop_now:
                    stopped = f"{where}: stopped on request at t = {schedule[end - 1] - t0:.2f} s"
                    if on_stop is None:
                        raise tripped or Interrupted(stopped)
                    # continue in the same loop with what the stop sends (no pause: the output would hold)
                    tail = on_stop(end)
                    tail_volts = self._command_volts(tail)
                    cmd = np.concatenate([cmd[:end], tail])
                    volts = np.concatenate([volts[:end], tail_volts])
                    # only the tail is prepared for writing (between two ticks, while the robot moves)
                    write, n = self._tick_writer(tail_volts, first=end), int(cmd.shape[0])
                    codes[end:] = [None] * (n - end)
                    actual[end:] = [0.0] * (n - end)
                    schedule = schedule_s(t0, n, dt)
                    loop.cmd, loop.volts, loop.schedule = cmd, volts, schedule
                    if tap is not None:
                        tap.start(f"{where} (park)", cmd, t0)
            sleep_until(schedule[n])  # one more tick: the scan covers the response to the last command
            if stopped:
                raise tripped or Interrupted(stopped)
        except BaseException as exc:
            self._note_written(cmd, loop.written())
            with contextlib.suppress(Exception):  # the original error matters more than a failing stop
                append(self.ai.stop_scan())
                if tap is not None:
                    tap.scan(blocks[-1])
            # keep the data recorded so far with the error (a board that vanished mid-trial: the session
            # archives it as a failed trial)
            with contextlib.suppress(Exception):
                exc.partial_recording = self._recording(loop, where, partial=True)  # type: ignore[attr-defined]
            raise
        append(self.ai.stop_scan())
        if tap is not None:  # the rows a board hands over when it stops (the simulator's last transfer)
            tap.scan(blocks[-1])
        self._note_written(cmd, n)
        return self._recording(loop, where, partial=False)

    def _command_volts(self, cmd: FloatArray) -> FloatArray:
        return np.stack([j.command_to_volts(cmd[:, k]) for k, j in enumerate(self.joints)], axis=1)

    def _tick_writer(self, volts: FloatArray, first: int = 0) -> Callable[[int], object]:
        """Writes tick k (row k - `first` of `volts`) and returns its code(s)."""
        if len(self.joints) == 1:  # one board write per tick: nothing to latch together
            write, channel, column = self.ao.write_volts, self.joints[0].output_channel, volts[:, 0].tolist()
            return lambda k: write(channel, column[k - first])
        channels = [j.output_channel for j in self.joints]
        rows: list[dict[int, float]] = [dict(zip(channels, r, strict=True)) for r in volts.tolist()]
        write_sync = self.ao.write_volts_sync
        return lambda k: write_sync(rows[k - first])

    def _note_written(self, cmd: FloatArray, written: int) -> None:
        if written:
            self._last = [float(v) for v in cmd[written - 1]]

    def _command_codes(self, codes: list[object], k: int) -> npt.NDArray[np.int32]:
        """Joint k's output codes of the ticks written."""
        if len(self.joints) == 1:
            return np.asarray(codes, dtype=np.int32)
        channel = self.joints[k].output_channel
        return np.asarray([c[channel] for c in codes], dtype=np.int32)  # type: ignore[index]

    def _recording(self, loop: Loop, where: str, *, partial: bool) -> tuple[TrialRecording, ...]:
        """Each joint's recording of the samples written (commands, their volts and codes, each tick's
        lateness) and of its scan columns (angle 2k, torque 2k+1), in its units, all on the same time base;
        `partial`: what an aborted loop recorded before it stopped."""
        n = loop.written() if partial else int(loop.cmd.shape[0])
        n_columns = 2 * len(self.joints)
        scan = ScanBlock.concatenate(loop.blocks, n_columns)
        if scan.codes.ndim != 2 or scan.codes.shape[1] != n_columns:
            raise InvalidInput(
                f"{where}: the input board returned codes of shape {scan.codes.shape}, "
                f"expected {n_columns} columns"
            )
        input_time_s = input_time_base_s(scan, loop.t0, self.input_rate_hz)
        dt = 1.0 / self.output_rate_hz
        lateness_s = np.asarray(loop.actual[:n], dtype=np.float64) - np.asarray(
            loop.schedule[:n], dtype=np.float64
        )
        command_time_s = np.arange(n, dtype=np.float64) * dt
        out = []
        for k, j in enumerate(self.joints):
            angle_volts = np.ascontiguousarray(scan.volts[:, 2 * k], dtype=np.float64)
            torque_volts = np.ascontiguousarray(scan.volts[:, 2 * k + 1], dtype=np.float64)
            out.append(
                TrialRecording(
                    command_time_s=command_time_s,
                    command_deg=np.ascontiguousarray(loop.cmd[:n, k]),
                    command_volts=np.ascontiguousarray(loop.volts[:n, k]),
                    command_codes=self._command_codes(loop.codes[:n], k),
                    input_time_s=input_time_s,
                    angle_codes=np.ascontiguousarray(scan.codes[:, 2 * k], dtype=np.int32),
                    torque_codes=np.ascontiguousarray(scan.codes[:, 2 * k + 1], dtype=np.int32),
                    angle_volts=angle_volts,
                    torque_volts=torque_volts,
                    angle_deg=j.angle_from_volts(angle_volts),
                    torque_nm=j.torque_from_volts(torque_volts),
                    tick_lateness_s=lateness_s,
                    where=self.where_of(where, j),
                    t0_s=loop.t0,
                    output_rate_hz=self.output_rate_hz,
                    input_rate_hz=self.input_rate_hz,
                )
            )
        return tuple(out)
