"""Several joints on one set of boards: every joint's output in the same output tick, every joint's angle
and torque in one input scan (thesis §2.3: the boards control "the 12 joints ... simultaneously").

`MultiRig.send` is `Rig.send` for a (ticks x joints) command: per tick one synchronous update of every
driven joint's channel (`AnalogOutput.write_volts_sync`: on the USB-3105 each channel's AOUT with the
"wait for sync" flag, then one AOUT_SYNC that latches them together), and one scan of
[angle_0, torque_0, angle_1, torque_1, ...] at the input rate. The recording is one `TrialRecording` per
joint, all on the SAME time base (the same command and input times, the same tick lateness).

`run_multi_motion` plans (`hardware/multi_stream.py`), checks every joint's stream against that joint's
envelope before any write, sends, and on a stop request (Ctrl-C, a violation) brakes and parks EVERY joint
in the same loop. `park` ramps every joint to its park angle together.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import ClassVar, cast

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock, LoopTap, ScanBlock
from protocol_runner.hardware.joint import JointConfig, StopRequested, TrialRecording
from protocol_runner.hardware.motion import trajectory_part
from protocol_runner.hardware.multi_stream import MultiStream, build_multi_stream, check_multi_stream
from protocol_runner.hardware.paced import Loop, PacedLoop, input_time_base_s
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import check_trajectory, parking_ramp_deg

FloatArray = npt.NDArray[np.float64]


class MultiRig(PacedLoop[tuple[TrialRecording, ...]]):
    """Binds one analog output, one analog input and a clock to several joints (channel order)."""

    def __init__(
        self, joints: Sequence[JointConfig], ao: AnalogOutput, ai: AnalogInput, clock: Clock
    ) -> None:
        if not joints:
            raise InvalidInput("a multi-joint rig needs at least one joint")
        rates = {(j.output_rate_hz, j.input_rate_hz) for j in joints}
        if len(rates) != 1:
            raise InvalidInput("the joints of one rig share its output and input rates")
        used: dict[int, str] = {}
        for j in joints:
            for ch in (j.angle_input_channel, j.torque_input_channel):
                if ch in used:
                    raise InvalidInput(f"input channel {ch} is both {used[ch]}'s and {j.name}'s")
                used[ch] = j.name
        if len({j.output_channel for j in joints}) != len(joints):
            raise InvalidInput("two joints of the rig share an output channel")
        self.joints = tuple(joints)
        self.ao, self.ai, self.clock = ao, ai, clock
        self.output_rate_hz, self.input_rate_hz = rates.pop()
        self._prepared = False
        self._last: list[float | None] = [None] * len(joints)
        self.loop_context: Callable[[], contextlib.AbstractContextManager[object]] = contextlib.nullcontext
        self.tap: LoopTap | None = None

    @property
    def joint(self) -> JointConfig:
        """The first driven joint: what the live monitor (`tap`) shows of a multi-joint loop."""
        return self.joints[0]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def scan_channels(self) -> tuple[int, ...]:
        return tuple(ch for j in self.joints for ch in (j.angle_input_channel, j.torque_input_channel))

    def last_command_deg(self) -> list[float | None]:
        return list(self._last)

    def prepare(self) -> None:
        """Configure every joint's output channel once (on a USB-3105 this drives it to 0 V)."""
        if not self._prepared:
            for j in self.joints:
                self.ao.configure_channel(j.output_channel)
            self._prepared = True

    def single(self, name: str) -> Rig:
        """A single-joint `Rig` on the same boards for one joint (its calibration check): the others hold
        their last output. Call `note_single` after using it."""
        k = self.names.index(name)
        rig = Rig(self.joints[k], self.ao, self.ai, self.clock)
        self.prepare()
        rig._prepared = True
        rig._last_command_deg = self._last[k]
        rig.loop_context = self.loop_context
        return rig

    def note_single(self, name: str, rig: Rig) -> None:
        self._last[self.names.index(name)] = rig.last_command_deg

    def plan(self, trajectories_deg: Sequence[npt.ArrayLike]) -> MultiStream:
        return build_multi_stream(
            self.names,
            trajectories_deg,
            [j.limits for j in self.joints],
            self.output_rate_hz,
            from_deg=self._last,
        )

    def check(self, stream: MultiStream, where: str) -> None:
        check_multi_stream(
            stream,
            [j.limits for j in self.joints],
            where=where,
            command_tables=[j.command_table for j in self.joints],
            volts_ranges_deg=[j.range_deg for j in self.joints],
        )
        for k, j in enumerate(self.joints):  # the junction with what each joint was sent before
            here = self._last[k]
            if here is not None:
                check_trajectory(
                    stream.streams[k].command_deg[:3],
                    stream.rate_hz,
                    j.limits,
                    where=f"{where} (start), joint {j.name}",
                    initial_deg=here,
                )

    def park(self, *, where: str = "park") -> tuple[TrialRecording, ...]:
        """Ramp every joint from its last command (else its measured angle) to its park angle, together."""
        starts = [
            s if s is not None else a for s, a in zip(self._last, self._measured_if_needed(), strict=True)
        ]
        ramps = [
            parking_ramp_deg(s, j.limits, self.output_rate_hz)
            for s, j in zip(starts, self.joints, strict=True)
        ]
        n = max(r.size for r in ramps)
        cmd = np.stack([np.concatenate([r, np.full(n - r.size, r[-1])]) for r in ramps], axis=1)
        for k, j in enumerate(self.joints):
            lo, hi = j.limits.range_deg
            widened = replace(
                j.limits,
                range_deg=(max(min(lo, starts[k]), j.range_deg[0]), min(max(hi, starts[k]), j.range_deg[1])),
            )
            cmd[:, k] = np.clip(cmd[:, k], *widened.range_deg)
            check_trajectory(
                cmd[:, k],
                self.output_rate_hz,
                widened,
                where=f"{where}, joint {j.name}",
                command_table=j.command_table,
                volts_range_deg=j.range_deg,
            )
        with self.loop_context():
            return self.send(cmd, where=where, stop_requested=None)

    def _measured_if_needed(self) -> list[float]:
        if all(s is not None for s in self._last):
            return [0.0] * len(self.joints)
        self.ai.start_scan(self.scan_channels, self.input_rate_hz)
        try:
            self.clock.sleep_until(self.clock.now_s() + 0.05)
        finally:
            block = self.ai.stop_scan()
        if block.n_samples == 0:
            raise InvalidInput("could not measure the joint angles: the input scan returned no samples")
        return [float(np.mean(j.angle_from_volts(block.volts[:, 2 * k]))) for k, j in enumerate(self.joints)]

    # ---- the paced loop (`PacedLoop.send`): per tick one synchronous write of every joint's channel -----
    UNWRITTEN: ClassVar[object] = None
    SHOWS_PARK: ClassVar[bool] = False

    @property
    def rates_hz(self) -> tuple[float, float]:
        return (self.output_rate_hz, self.input_rate_hz)

    def _command_volts(self, cmd: FloatArray) -> FloatArray:
        return np.stack([j.command_to_volts(cmd[:, k]) for k, j in enumerate(self.joints)], axis=1)

    def _tick_writer(self, volts: FloatArray) -> Callable[[int], object]:
        channels = [j.output_channel for j in self.joints]
        rows: list[dict[int, float]] = [dict(zip(channels, r, strict=True)) for r in volts.tolist()]
        write = self.ao.write_volts_sync
        return lambda k: write(rows[k])

    def _monitored_command(self, cmd: FloatArray) -> FloatArray:
        """The monitor sees the first joint (its angle and torque are scan columns 0 and 1)."""
        return np.ascontiguousarray(cmd[:, 0])

    def _monitored_scan(self, block: ScanBlock) -> ScanBlock:
        return ScanBlock(block.t_s, block.codes[:, :2], block.volts[:, :2])

    def _note_written(self, cmd: FloatArray, written: int) -> None:
        if written:
            self._last = [float(v) for v in cmd[written - 1]]

    def _recording(self, loop: Loop, where: str, *, partial: bool) -> tuple[TrialRecording, ...]:
        """Each joint's recording of the ticks written, all on the same time base."""
        n = loop.written(self.UNWRITTEN) if partial else loop.n
        dt = 1.0 / self.output_rate_hz
        scan = ScanBlock.concatenate(loop.blocks, 2 * len(self.joints))
        if scan.codes.ndim != 2 or scan.codes.shape[1] != 2 * len(self.joints):
            raise InvalidInput(f"{where}: the input board returned codes of shape {scan.codes.shape}")
        input_time_s = input_time_base_s(scan, loop.t0, self.input_rate_hz)
        t0 = loop.t0
        lateness = np.asarray(loop.actual[:n], dtype=np.float64) - (t0 + np.arange(n, dtype=np.float64) * dt)
        codes = cast("list[dict[int, int] | None]", loop.codes[:n])
        out = []
        for k, j in enumerate(self.joints):
            av = np.ascontiguousarray(scan.volts[:, 2 * k], dtype=np.float64)
            tv = np.ascontiguousarray(scan.volts[:, 2 * k + 1], dtype=np.float64)
            out.append(
                TrialRecording(
                    command_time_s=np.arange(n, dtype=np.float64) * dt,
                    command_deg=np.ascontiguousarray(loop.cmd[:n, k]),
                    command_volts=np.ascontiguousarray(loop.volts[:n, k]),
                    command_codes=np.asarray(
                        [c[j.output_channel] if c else -1 for c in codes], dtype=np.int32
                    ),
                    input_time_s=input_time_s,
                    angle_codes=np.ascontiguousarray(scan.codes[:, 2 * k], dtype=np.int32),
                    torque_codes=np.ascontiguousarray(scan.codes[:, 2 * k + 1], dtype=np.int32),
                    angle_volts=av,
                    torque_volts=tv,
                    angle_deg=j.angle_from_volts(av),
                    torque_nm=j.torque_from_volts(tv),
                    tick_lateness_s=lateness,
                    where=f"{where}, joint {j.name}",
                    t0_s=t0,
                    output_rate_hz=self.output_rate_hz,
                    input_rate_hz=self.input_rate_hz,
                )
            )
        return tuple(out)


def run_multi_motion(
    rig: MultiRig,
    trajectories_deg: Sequence[npt.ArrayLike],
    *,
    where: str,
    stop_requested: StopRequested | None = None,
) -> tuple[TrialRecording, ...]:
    """Plan, check (every joint, before any write) and send one multi-joint motion; return each joint's
    trajectory part on the shared time base, its whole commanded stream attached. A stop request brakes and
    parks every joint in the same loop, then raises `Interrupted`."""
    stream = rig.plan(trajectories_deg)
    rig.check(stream, where)
    limits = [j.limits for j in rig.joints]
    segments = [stream.segment()]

    def on_stop(written: int) -> FloatArray:
        tail, codes = stream.stop_after(written, limits)
        for k, j in enumerate(rig.joints):  # defence in depth: check_multi_stream checked every stop
            junction = stream.streams[k].command_deg[max(0, written - 2) : written]
            check_trajectory(
                np.concatenate([junction, tail[:, k]]),
                stream.rate_hz,
                j.limits,
                where=f"{where}, joint {j.name}",
                command_table=j.command_table,
                volts_range_deg=j.range_deg,
            )
        segments[0] = np.concatenate([segments[0][:written], codes])
        return tail

    def parts(recs: tuple[TrialRecording, ...]) -> tuple[TrialRecording, ...]:
        return tuple(trajectory_part(r, segments[0][:, k], stream.first) for k, r in enumerate(recs))

    try:
        with rig.loop_context():
            recs = rig.send(stream.command_deg(), where=where, stop_requested=stop_requested, on_stop=on_stop)
    except BaseException as exc:
        partial = getattr(exc, "partial_recording", None)
        if isinstance(partial, tuple):
            exc.partial_recording = parts(partial)  # type: ignore[attr-defined]
        raise
    return parts(recs)
