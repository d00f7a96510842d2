"""Building the rig a session runs on: the DAQ simulator (--dry-run) or the real boards."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, cast

from ..errors import HardwareUnavailable
from ..hardware.calibration import CalibrationTable, load_calibration_table
from ..hardware.joint import JointConfig
from ..hardware.multi_rig import MultiRig
from ..hardware.rig import Rig
from ..hardware.watchdog import watchdog_limits
from ..protocol.loaded import LoadedProtocol
from ..protocol.schema import RigSpec
from ..protocol.settings import Settings
from ..protocol.step_ids import trial_of
from ..protocol.stream_check import safety_limits

if TYPE_CHECKING:
    from ..hardware.simulator.daq import SimulatedRig
    from ..hardware.simulator.multi import MultiSimulatedRig
    from ..hardware.simulator.params import SimulatorParams


def _table(base: Path, name: str | None) -> CalibrationTable | None:
    """The calibration table file `name` (relative to the protocol's folder), or None (identity) without one."""
    return load_calibration_table(base / name) if name else None


def joint_config(loaded: LoadedProtocol, rig: RigSpec | None = None) -> JointConfig:
    """The protocol's joint (or `rig`'s, one driven joint of a multi-joint protocol), channels, rates,
    look-up tables and safety envelope as a hardware JointConfig."""
    rig = rig or loaded.protocol.rig
    base = loaded.base_dir
    cal = rig.calibration
    watch = rig.watchdog.merged(loaded.protocol.watchdog)
    return JointConfig(
        name=rig.joint.name,
        range_deg=rig.joint.range_deg,
        torque_range_nm=rig.joint.torque_range_nm,
        output_channel=rig.output.channel,
        angle_input_channel=rig.input.angle_channel,
        torque_input_channel=rig.input.torque_channel,
        output_rate_hz=rig.output.rate_hz,
        input_rate_hz=rig.input.rate_hz,
        command_table=_table(base, cal.command_table),
        angle_table=_table(base, cal.angle_table),
        torque_table=_table(base, cal.torque_table),
        limits=safety_limits(rig),
        watchdog=watchdog_limits(
            rig.joint.torque_range_nm,
            torque_margin=watch.torque_margin,
            max_tracking_error_deg=watch.max_tracking_error_deg,
            max_tracking_error_s=watch.max_tracking_error_s,
            lag_s=rig.time_constant_s,
        ),
    )


class SimulatedBench:
    """The dry-run bench: the simulated rig (the joint's `simulator:` values from the rig file) plus the
    simulated operator's hands on the device."""

    def __init__(
        self,
        loaded: LoadedProtocol,
        *,
        seed: int,
        realtime: bool = False,
        params: SimulatorParams | None = None,
    ) -> None:
        from ..hardware.simulator.daq import SimulatedRig
        from ..hardware.simulator.params import SimulatorParams

        self.paced = realtime  # like the robot: runner.py then saves each unit before the next motion
        self.multi: MultiRig | None = None
        self.multi_sim: MultiSimulatedRig | None = None
        self.rig: Rig
        self.sim: SimulatedRig | MultiSimulatedRig
        p = loaded.protocol
        if p.multi_joint:
            from ..hardware.simulator.multi import MultiSimulatedRig

            self.multi_sim = MultiSimulatedRig(
                [joint_config(loaded, r) for r in p.rigs],
                [SimulatorParams(**dict(r.simulator)) for r in p.rigs],
                seed=seed,
                realtime=realtime,
            )
            self.multi = self.multi_sim.make_rig()
            self.sim = self.multi_sim  # its `clock` gives the simulated robot time (session/runner.py)
            # the session itself only parks through `rig` (`park(where=...)`), which MultiRig provides;
            # steps reach the joints through `multi` (steps/recording.py `drive`)
            self.rig = cast(Rig, self.multi)
            self.mode = "dry-run"
            return
        self.sim = SimulatedRig(
            joint_config(loaded),
            seed=seed,
            params=params or SimulatorParams(**dict(loaded.protocol.rig.simulator)),
            realtime=realtime,
        )
        self.rig = self.sim.make_rig()
        self.mode = "dry-run"

    def begin_step(self, step_id: str) -> None:
        """The simulated rig starts step `step_id`; a brace-off trial draws the same friction spread as
        its brace-on twin (the robot it subtracts is the one that ran the brace-on trial)."""
        trial = trial_of(step_id)
        if self.multi_sim is not None:
            self.multi_sim.begin_step(step_id, trial)
            return
        self.sim.begin_step(step_id, trial)

    def fit_brace(self, settings: Settings | None) -> None:
        """The simulated operator fits the configuration's device (its resolved elements), or removes it
        (every joint's, in a multi-joint protocol)."""
        if self.multi_sim is not None:
            for joint in self.multi_sim.joints:
                elements = settings.device_of(joint.name) if settings is not None else ()
                self.multi_sim.set_device(joint.name, elements or None)
            return
        cast("SimulatedRig", self.sim).set_device(None if settings is None else settings.device)

    def close(self) -> None:
        if self.multi_sim is not None:
            self.multi_sim.ao.close()
            self.multi_sim.ai.close()
            return
        self.sim.ao.close()
        self.sim.ai.close()


class HardwareBench:
    """The real rig: USB boards chosen by the protocol's rig section. The operator handles the brace."""

    def __init__(self, loaded: LoadedProtocol) -> None:
        from ..hardware.usb_common import realtime_priority

        self.mode = "hardware"
        self.paced = True
        self.rig: Rig
        self.multi: MultiRig | None = None
        if loaded.protocol.multi_joint:
            self.multi = open_hardware_multi_rig(loaded)
            self.multi.loop_context = realtime_priority
            self.rig = cast(Rig, self.multi)  # the session parks through `rig` (see SimulatedBench)
            return
        self.rig = open_hardware_rig(loaded)
        # the 100 Hz loop under SCHED_FIFO when allowed (tick jitter p99 < 1 ms needs it on a busy machine)
        self.rig.loop_context = realtime_priority

    def begin_step(self, step_id: str) -> None:
        return None

    def fit_brace(self, settings: Settings | None) -> None:
        return None  # done by hand, confirmed through the operator checklist

    def close(self) -> None:
        for dev in (self.rig.ao, self.rig.ai):
            close = getattr(dev, "close", None)
            if close is not None:
                close()


def refuse_unsupported_input(loaded: LoadedProtocol) -> None:
    """A protocol naming the DT9814 as its input board: say where, why, and what to do instead (exit 3)."""
    rig_spec = loaded.protocol.rig
    if rig_spec.input.board != "dt9814":
        return
    line = loaded.line_of(("rig", "input", "board"))
    where = f"{loaded.path}" + (f" line {line}" if line else "")
    raise HardwareUnavailable(
        f"{where}: rig.input.board is dt9814. protocol-runner cannot record with a DT9814 on Linux: the only "
        "known protocol for it (the DT9812's, UNVERIFIED for the DT9814) has no hardware-paced scan and reaches "
        "8 channels, so there is no opt-in to try it. To run on the rig: connect the inputs to three MCC "
        "USB-1608FS-Plus boards (board k gives channels 8k to 8k+7, so the channel numbers stay), copy the "
        "protocol's folder and set rig.input.board: usb1608fs in the copy (docs/hardware.md, \"Opening the "
        'rig from a protocol"); check the boards with run-protocol --hardware-check COPY. Or rehearse '
        "with --dry-run."
    )


def open_hardware_rig(loaded: LoadedProtocol) -> Rig:
    """Open the boards the protocol names; HardwareUnavailable (exit 3) with a plain message if absent."""
    refuse_unsupported_input(loaded)
    rig_spec = loaded.protocol.rig
    from ..hardware.rig_boards import open_rig_boards  # here: only a hardware run needs the USB drivers

    ao, ai, clock = open_rig_boards(rig_spec)
    return Rig(joint_config(loaded), ao, ai, clock)


def open_hardware_multi_rig(loaded: LoadedProtocol) -> MultiRig:
    """Open the boards once for every driven joint (one output board, one scan)."""
    refuse_unsupported_input(loaded)
    from ..hardware.rig_boards import open_rig_boards

    p = loaded.protocol
    ao, ai, clock = open_rig_boards(p.rig)
    for spec in p.rigs[1:]:  # the channels of the other joints exist on the boards opened
        n_in = getattr(ai, "n_channels", None)
        if n_in is not None and max(spec.input.angle_channel, spec.input.torque_channel) >= n_in:
            raise HardwareUnavailable(
                f"{spec.joint.name}: input channels {spec.input.angle_channel}, {spec.input.torque_channel} "
                f"are not on the {n_in} channels of the input boards attached"
            )
    return MultiRig([joint_config(loaded, r) for r in p.rigs], ao, ai, clock)
