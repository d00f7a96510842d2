"""The paced loop both rigs run (`Rig`: one joint; `MultiRig`: several joints on one set of boards).

Start the input scan ([angle channel, torque channel] per joint at the input rate), then for each output
tick k sleep until t0 + k / output_rate_hz, write, record the write time; read the scan every
`READ_EVERY_TICKS` ticks and poll the stop request there; after the last tick wait one more tick and stop
the scan. On a stop request `on_stop(written)`, if given, returns the samples to send next in the same loop
(no pause: the output would hold), then `Interrupted` is raised. An error or an interruption carries what
was recorded so far (`partial_recording`).

In simulated time (`ScheduledBlockIO`, the DAQ simulator's block path) up to `BLOCK_S` of the same samples
go in one call, read at the block's last write as the per-tick loop reads (`block_end`).

The loop does as little as possible per tick: conversions are done on whole arrays before and after, the
schedule is precomputed, and results go into preallocated lists.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar, Generic, Protocol, TypeVar

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import Interrupted
from protocol_runner.hardware.interfaces import AnalogInput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.joint import OnStop, StopRequested

FloatArray = npt.NDArray[np.float64]
RecordingT = TypeVar("RecordingT")

READ_EVERY_TICKS = 10
"""Output ticks between two reads of the input scan (100 ms at 100 Hz: 100 rows per read at 1 kHz)."""

BLOCK_S = 10.0
"""The most robot time one block of the simulator's block path covers: a stop request is seen within it
(about 10 ms of wall time in a dry run). The data do not depend on it (the rows are read as the per-tick loop
reads them); a longer block only means fewer calls: 1 s blocks cost ~9,000 calls of ~0.15 ms of Python
around the compiled one for the knee campaign."""


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
    seen within one block.

    A flag whose answer does not depend on how often it is asked (`POLLED_AS_FLAG` true, as the session's
    `StopFlag`: an event that a signal sets) is asked once, at the block's first boundary: asking it again
    microseconds later at the next boundaries could only see a signal that arrived meanwhile, which the next
    block sees as well. That saves ~90,000 polls in a knee dry run."""
    end = start
    limit = min(start + block_ticks, n)
    if stop_requested is not None and getattr(stop_requested, "POLLED_AS_FLAG", False) and end < limit:
        if stop_requested():
            return min(end + READ_EVERY_TICKS, n), True
        return limit, False
    while end < limit:
        end = min(end + READ_EVERY_TICKS, n)
        if stop_requested is not None and stop_requested():
            return end, True
    return end, False


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
    SHOWS_PARK: ClassVar[bool]
    """Whether the monitor is restarted on the samples a stop sends (shown as parking)."""

    # ---- what a rig supplies ------------------------------------------------------------------------
    @property
    def rates_hz(self) -> tuple[float, float]:
        """(output tick rate, input row rate)."""
        raise NotImplementedError

    @property
    def scan_channels(self) -> tuple[int, ...]:
        raise NotImplementedError

    def prepare(self) -> None:
        raise NotImplementedError

    def _command_volts(self, cmd: FloatArray) -> FloatArray:
        raise NotImplementedError

    def _tick_writer(self, volts: FloatArray) -> Callable[[int], object]:
        """Writes tick k of `volts` and returns its code(s)."""
        raise NotImplementedError

    def _monitored_command(self, cmd: FloatArray) -> FloatArray:
        """What the monitor shows of the commands."""
        return cmd

    def _monitored_scan(self, block: ScanBlock) -> ScanBlock:
        """What the monitor shows of a scan block."""
        return block

    def _block_output(self) -> tuple[ScheduledBlockIO, int] | None:
        """The block path and the channel it drives, when it may be used now (never by default)."""
        return None

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
    ) -> RecordingT:
        """The paced loop over samples already checked (ticks first). On a stop request `on_stop(written)`,
        if given, returns the samples to send next in the same loop; then `Interrupted` carries the whole
        recording."""
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
        tap = self.tap
        if tap is not None:
            tap.start(where, self._monitored_command(cmd), t0)
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
                        codes[k] = write(k)
                    append(read())
                    stop_now = not stopped and stop_requested is not None and stop_requested()
                else:  # simulated time: up to BLOCK_S of the same samples in one call (see block_end)
                    io, channel = block_out
                    end, stop_now = block_end(start, n, block_ticks, None if stopped else stop_requested)
                    times = schedule[start:end]
                    block_codes, scan = io.send_block(channel, np.asarray(times), volts[start:end])
                    codes[start:end] = block_codes.tolist()
                    actual[start:end] = times  # each sample written at its time: what now() reads
                    append(scan)  # read at the block's last write, as the per-tick loop reads
                start = end
                if tap is not None:
                    tap.scan(self._monitored_scan(blocks[-1]))
                if stop_now:
                    stopped = f"{where}: stopped on request at t = {schedule[end - 1] - t0:.2f} s"
                    if on_stop is None:
                        raise Interrupted(stopped)
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
                    if tap is not None and self.SHOWS_PARK:
                        tap.start(f"{where} (park)", self._monitored_command(cmd), t0)
            sleep_until(schedule[n])  # one more tick: the scan covers the response to the last command
            if stopped:
                raise Interrupted(stopped)
        except BaseException as exc:
            written = loop.written(self.UNWRITTEN)
            self._note_written(cmd, written)
            with contextlib.suppress(Exception):  # the original error matters more than a failing stop
                append(self.ai.stop_scan())
            # keep the data recorded so far with the error (a board that vanished mid-trial: the session
            # archives it as a failed trial)
            with contextlib.suppress(Exception):
                exc.partial_recording = self._recording(loop, where, partial=True)  # type: ignore[attr-defined]
            raise
        append(self.ai.stop_scan())
        self._note_written(cmd, n)
        return self._recording(loop, where, partial=False)
