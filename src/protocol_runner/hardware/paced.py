"""The paced loop the rig runs (`hardware/rig.py`: one joint or several on one set of boards).

Start the input scan ([angle channel, torque channel] per joint at the input rate), then for each output
tick k sleep until t0 + k / output_rate_hz, write, record the write time; read the scan every
`READ_EVERY_TICKS` ticks and poll the stop request there; after the last tick wait one more tick and stop
the scan. On a stop request `on_stop(written)`, if given, returns the samples to send next in the same loop
(no pause: the output would hold), then `Interrupted` is raised. An error or an interruption carries what
was recorded so far (`partial_recording`). The live monitor (`tap`) is started with every joint's
commands (restarted on the samples a stop sends, shown as parking) and shown every block read, the one
`stop_scan` returns included, with every joint's columns.

The watchdog (`hardware/watchdog.py`) checks every block as it is read: a measured signal beyond its limit
stops the loop as a stop request does (`on_stop`'s brake and park in the same loop), then the watchdog's
`WatchdogTripped` (exit 4) is raised instead of `Interrupted`. Parking is not watched.

The hardware bench and a dry run run this same loop: the DAQ simulator's boards satisfy the same
interfaces, and its clock jumps instead of sleeping.

The loop does as little as possible per tick: conversions are done on whole arrays before and after, the
schedule is precomputed, and results go into preallocated lists.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Generic, TypeVar

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import Interrupted, WatchdogTripped
from protocol_runner.hardware.interfaces import AnalogInput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.joint import JointConfig, OnStop, StopRequested
from protocol_runner.hardware.watchdog import LoopWatch

FloatArray = npt.NDArray[np.float64]
RecordingT = TypeVar("RecordingT")

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


def _from_tick(write: Callable[[int], object], first: int) -> Callable[[int], object]:
    """`write` (of samples indexed from 0) for ticks numbered from `first`."""
    return lambda k: write(k - first)


@dataclass(eq=False)
class Loop:
    """One loop's samples as far as they go: the commands (ticks first), their volts and codes (`UNWRITTEN`
    where not written yet), the write times, the schedule, the scan blocks read and t0."""

    cmd: FloatArray
    volts: FloatArray
    codes: list[object]
    actual: list[float]
    schedule: list[float]
    blocks: list[ScanBlock]
    t0: float

    @property
    def n(self) -> int:
        return int(self.cmd.shape[0])

    def written(self, unwritten: object) -> int:
        """How many ticks were written (the first `unwritten` code, else all)."""
        return self.codes.index(unwritten) if unwritten in self.codes else len(self.codes)


class PacedLoop(Generic[RecordingT]):
    """`send`, the paced loop; a rig says how commands become volts and are written, what the live monitor
    (`tap`) is shown, and how the samples become its recording."""

    ai: AnalogInput
    clock: Clock
    tap: LoopTap | None
    UNWRITTEN: ClassVar[object]

    # ---- what a rig supplies ------------------------------------------------------------------------
    @property
    def rates_hz(self) -> tuple[float, float]:
        """(output tick rate, input row rate)."""
        raise NotImplementedError

    @property
    def scan_channels(self) -> tuple[int, ...]:
        raise NotImplementedError

    @property
    def watched_joints(self) -> tuple[JointConfig, ...]:
        """The joints in command column order (their angle and torque: scan columns 2k and 2k+1)."""
        raise NotImplementedError

    def prepare(self) -> None:
        raise NotImplementedError

    def _command_volts(self, cmd: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _tick_writer(self, volts: FloatArray) -> Callable[[int], object]:
        """Writes tick k of `volts` and returns its code(s)."""
        raise NotImplementedError

    def _note_written(self, cmd: FloatArray, written: int) -> None:
        """After an aborted loop: the first `written` commands were written."""
        raise NotImplementedError

    def _recording(self, loop: Loop, where: str, *, partial: bool) -> RecordingT:
        """The recording of the loop's samples (`partial`: of what an aborted loop wrote)."""
        raise NotImplementedError

    # ---- the loop -------------------------------------------------------------------------------------
    def send(
        self,
        cmd: FloatArray,
        *,
        where: str,
        stop_requested: StopRequested | None,
        on_stop: OnStop | None = None,
        watch: bool = True,
    ) -> RecordingT:
        """The paced loop over samples already checked (ticks x joints). On a stop request `on_stop(written)`,
        if given, returns the samples to send next in the same loop; then `Interrupted` carries the whole
        recording. `watch`: run the watchdog on the measured signals (a tripped watchdog stops the loop
        the same way, then raises its `WatchdogTripped`)."""
        cmd = np.asarray(cmd, dtype=np.float64)
        volts = self._command_volts(cmd)
        self.prepare()
        n = int(cmd.shape[0])
        rate, input_rate = self.rates_hz
        dt = 1.0 / rate
        write = self._tick_writer(volts)
        codes: list[object] = [self.UNWRITTEN] * n
        actual: list[float] = [0.0] * n
        blocks: list[ScanBlock] = []

        # Bind everything the loop touches to locals: attribute lookups cost more than the work itself.
        sleep_until = self.clock.sleep_until
        now = self.clock.now_s
        read = self.ai.read_available
        append = blocks.append

        self.ai.start_scan(self.scan_channels, input_rate)
        t0 = now()
        schedule = schedule_s(t0, n, dt)
        loop = Loop(cmd, volts, codes, actual, schedule, blocks, t0)
        stopped = ""
        watchdog = LoopWatch(self.watched_joints, t0, rate, where) if watch else None
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
                    write, n = _from_tick(self._tick_writer(tail_volts), end), int(cmd.shape[0])
                    codes[end:] = [self.UNWRITTEN] * (n - end)
                    actual[end:] = [0.0] * (n - end)
                    schedule = schedule_s(t0, n, dt)
                    loop.cmd, loop.volts, loop.schedule = cmd, volts, schedule
                    if tap is not None:
                        tap.start(f"{where} (park)", cmd, t0)
            sleep_until(schedule[n])  # one more tick: the scan covers the response to the last command
            if stopped:
                raise tripped or Interrupted(stopped)
        except BaseException as exc:
            written = loop.written(self.UNWRITTEN)
            self._note_written(cmd, written)
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
