"""Building the rig a session runs on: the DAQ simulator (--dry-run) or the real boards."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..errors import HardwareUnavailable
from ..hardware.calibration import load_calibration_table
from ..hardware.rig import JointConfig, Rig
from ..models.interim_knee_device import KNEE_SIMULATOR, knee_brace
from ..protocol.levels import Settings
from ..protocol.loader import LoadedProtocol
from ..protocol.stream_check import safety_limits

if TYPE_CHECKING:
    from ..hardware.simulator.params import SimulatorParams


def joint_config(loaded: LoadedProtocol) -> JointConfig:
    """The protocol's joint, channels, rates, look-up tables and safety envelope as a hardware JointConfig."""
    rig = loaded.protocol.rig
    base = loaded.base_dir
    cal = rig.calibration
    return JointConfig(
        name=rig.joint.name,
        range_deg=rig.joint.range_deg,
        torque_range_nm=rig.joint.torque_range_nm,
        output_channel=rig.output.channel,
        angle_input_channel=rig.input.angle_channel,
        torque_input_channel=rig.input.torque_channel,
        output_rate_hz=rig.output.rate_hz,
        input_rate_hz=rig.input.rate_hz,
        command_table=load_calibration_table(base / cal.command_table) if cal.command_table else None,
        angle_table=load_calibration_table(base / cal.angle_table) if cal.angle_table else None,
        torque_table=load_calibration_table(base / cal.torque_table) if cal.torque_table else None,
        limits=safety_limits(rig),
    )


class SimulatedBench:
    """The dry-run bench: the simulated rig plus the simulated operator's hands on the brace."""

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

        self.sim = SimulatedRig(
            joint_config(loaded),
            seed=seed,
            params=params or SimulatorParams(**KNEE_SIMULATOR),  # INTERIM until the rig file (PROTO)
            realtime=realtime,
        )
        self.rig: Rig = self.sim.make_rig()
        self.mode = "dry-run"

    def begin_step(self, step_id: str) -> None:
        self.sim.begin_step(step_id)

    def fit_brace(self, settings: Settings | None) -> None:
        device = getattr(settings, "device", None)
        if settings is not None and device is None:  # INTERIM until the protocol declares its device (PROTO)
            s = settings
            device = knee_brace(s.brace_rom_deg, s.friction_nm, s.stiffness_n_per_mm, s.preload_position)
        self.sim.set_device(device)

    def close(self) -> None:
        self.sim.ao.close()
        self.sim.ai.close()


class HardwareBench:
    """The real rig: USB boards chosen by the protocol's rig section. The operator handles the brace."""

    def __init__(self, loaded: LoadedProtocol) -> None:
        from ..hardware.usb_common import realtime_priority

        self.mode = "hardware"
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
