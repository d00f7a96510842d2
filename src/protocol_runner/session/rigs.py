"""Building the rig a session runs on: the DAQ simulator (--dry-run) or the real boards."""

from __future__ import annotations

from pathlib import Path

from ..errors import HardwareUnavailable, InvalidInput
from ..hardware.calibration import CalibrationTable, load_calibration_table
from ..hardware.joint import JointConfig
from ..hardware.rig import Rig
from ..hardware.watchdog import watchdog_limits
from ..protocol.loaded import LoadedProtocol, line_for
from ..protocol.schema import RigSpec
from ..protocol.settings import Settings
from ..protocol.step_ids import trial_of
from ..protocol.stream_check import safety_limits


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


def joint_configs(loaded: LoadedProtocol) -> list[JointConfig]:
    """Every joint the protocol drives, in channel order (the protocol's own joint without `joints:`)."""
    p = loaded.protocol
    return [joint_config(loaded, r) for r in p.rigs] if p.multi_joint else [joint_config(loaded)]


class SimulatedBench:
    """The dry-run bench: the simulated rig (each joint's `simulator:` values from its rig file) plus the
    simulated operator's hands on the device."""

    def __init__(self, loaded: LoadedProtocol, *, seed: int, realtime: bool = False) -> None:
        from ..hardware.simulator.daq import SimulatedRig
        from ..hardware.simulator.params import SimulatorParams

        p = loaded.protocol
        specs = p.rigs if p.multi_joint else [p.rig]
        self.sim = SimulatedRig(
            joint_configs(loaded),
            seed=seed,
            params=[SimulatorParams(**dict(r.simulator)) for r in specs],
            realtime=realtime,
        )
        self.rig: Rig = self.sim.make_rig()
        self.mode = "dry-run"

    def begin_step(self, step_id: str) -> None:
        """The simulated rig starts step `step_id`; a brace-off trial draws the same friction spread as
        its brace-on twin (the robot it subtracts is the one that ran the brace-on trial)."""
        self.sim.begin_step(step_id, trial_of(step_id))

    def fit_brace(self, settings: Settings | None) -> None:
        """The simulated operator fits the configuration's device (its resolved elements) to every joint, or
        removes it."""
        for joint in self.sim.joints:
            elements = settings.device_of(joint.name) if settings is not None else None
            self.sim.set_device(elements, joint=joint.name)

    def close(self) -> None:
        self.sim.ao.close()
        self.sim.ai.close()


class HardwareBench:
    """The real rig: USB boards chosen by the protocol's rig section. The operator handles the brace."""

    def __init__(self, loaded: LoadedProtocol) -> None:
        """Open the boards the protocol names once for every driven joint (one output board, one scan);
        HardwareUnavailable (exit 3) with a plain message if absent, naming the rig file for a vendor
        library it selects that is not installed."""
        # here: only a hardware run needs the USB drivers (and a vendor library only when selected)
        from ..hardware.rig_boards import open_rig_boards
        from ..hardware.usb_common import realtime_priority
        from ..hardware.vendor_common import VendorLibraryMissing

        refuse_unsupported_input(loaded)
        p = loaded.protocol
        try:
            ao, ai, clock = open_rig_boards(p.rig)
        except VendorLibraryMissing as exc:
            raise VendorLibraryMissing(f"{loaded.rig_source.shown}: {exc.message}") from None
        for spec in p.rigs[1:] if p.multi_joint else []:  # the other joints' channels exist on the boards
            n_in = getattr(ai, "n_channels", None)
            if n_in is not None and max(spec.input.angle_channel, spec.input.torque_channel) >= n_in:
                raise HardwareUnavailable(
                    f"{spec.joint.name}: input channels {spec.input.angle_channel}, "
                    f"{spec.input.torque_channel} are not on the {n_in} channels of the input boards attached"
                )
        self.mode = "hardware"
        self.rig = Rig(joint_configs(loaded), ao, ai, clock)
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
    """A protocol whose input board is the DT9814: say which file, line and key choose it, why it cannot
    run, and what to do instead (InvalidInput, exit 2: a choice in the files, fixed by editing them)."""
    rig_spec = loaded.protocol.rig
    if rig_spec.input.board != "dt9814":
        return
    if loaded.protocol.rig_overrides.input_board is not None:  # the protocol overrides the rig file
        key = "rig_overrides.input_board"
        where = _at(str(loaded.path), line_for(loaded.lines, ("rig_overrides", "input_board")))
        fix = f"set {key}: usb1608fs in the copy"
    else:  # the rig file's own choice
        source = loaded.rig_source
        key = "input_board"
        where = _at(str(source.path or source.shown), line_for(source.lines, ("input_board",)))
        fix = (
            "add rig_overrides: {input_board: usb1608fs} to the copy (or set input_board: usb1608fs in a "
            "copy of the rig file it names)"
        )
    raise InvalidInput(
        f"{where}: {key} is dt9814. protocol-runner cannot record with a DT9814: the only known protocol for "
        "it (the DT9812's, UNVERIFIED for the DT9814) has no hardware-paced scan and reaches 8 channels, so "
        "there is no opt-in to try it. To run on the rig: connect the inputs to three MCC USB-1608FS-Plus "
        "boards (board k gives channels 8k to 8k+7, so the channel numbers stay), copy the protocol's folder "
        f'and {fix} (docs/hardware.md, "The path to the rig"); check the boards with run-protocol '
        "--hardware-check COPY. Or rehearse with --dry-run."
    )


def _at(path: str, line: int | None) -> str:
    return f"{path} line {line}" if line else path
