"""Open the boards a protocol's `rig` section names: the analog output, the input boards joined as one
`BoardGroup`, and the real clock (docs/hardware.md, "Opening the rig from a protocol").

Each board is driven by the library its rig file entry names (`backend:`): pyusb (this package's
drivers, the default), MCC's uldaq (Linux, macOS) or mcculw (Windows). The vendor libraries are imported
only when a rig file selects them."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

from protocol_runner.errors import HardwareUnavailable, InvalidInput
from protocol_runner.hardware import usb1608fs_protocol
from protocol_runner.hardware.board_group import BoardGroup
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput
from protocol_runner.hardware.usb_common import BoardNotFound, MonotonicClock


class _BoardSpec(Protocol):
    """What opening reads of a rig section that names a board (structural: the protocol's models)."""

    @property
    def volts_range(self) -> tuple[float, float]: ...
    @property
    def backend(self) -> str: ...


class _OutputSpec(_BoardSpec, Protocol):
    @property
    def serial(self) -> str | None: ...


class _InputSpec(_BoardSpec, Protocol):
    @property
    def board(self) -> str: ...
    @property
    def angle_channel(self) -> int: ...
    @property
    def torque_channel(self) -> int: ...
    @property
    def serials(self) -> list[str]: ...


class _RigSpec(Protocol):
    @property
    def output(self) -> _OutputSpec: ...
    @property
    def input(self) -> _InputSpec: ...


def open_output(spec: _OutputSpec, usb_backend: Any | None = None) -> AnalogOutput:
    """The USB-3105 with ``spec.serial`` (or the first one), through the library ``spec.backend`` names."""
    if spec.backend == "uldaq":
        from protocol_runner.hardware.uldaq_boards import UldaqUsb3105

        return UldaqUsb3105.open(spec.serial)
    if spec.backend == "mcculw":
        from protocol_runner.hardware.mcculw_boards import McculwUsb3105

        return McculwUsb3105.open(spec.serial)
    from protocol_runner.hardware.usb3105 import Usb3105

    return Usb3105.open(serial=spec.serial, backend=usb_backend)


def open_inputs(spec: _InputSpec, usb_backend: Any | None, clock: MonotonicClock) -> Sequence[AnalogInput]:
    """The USB-1608FS-Plus boards of ``spec.serials`` (in that order; empty = every attached board in
    serial order), through the library ``spec.backend`` names."""
    serials = spec.serials or None
    if spec.backend == "uldaq":
        from protocol_runner.hardware.uldaq_boards import open_all_uldaq_1608fs

        return open_all_uldaq_1608fs(serials, clock=clock)
    if spec.backend == "mcculw":
        from protocol_runner.hardware.mcculw_boards import open_all_mcculw_1608fs

        return open_all_mcculw_1608fs(serials, clock=clock)
    from protocol_runner.hardware.usb1608fs import open_all_1608fs

    return open_all_1608fs(serials, usb_backend, clock=clock)


def open_rig_boards(
    rig_spec: _RigSpec, backend: Any | None = None, *, clock: MonotonicClock | None = None
) -> tuple[AnalogOutput, BoardGroup, MonotonicClock]:
    """Open the boards a protocol's ``rig`` section names: (analog output, analog input, real clock).

    Output: the USB-3105 with ``output.serial`` (or the first one). Input: ``board: usb1608fs`` opens the
    USB-1608FS-Plus boards listed in ``input.serials`` (in that order; empty = every attached board in
    serial order) as one `BoardGroup`. Each through its rig file entry's ``backend`` (pyusb, uldaq,
    mcculw); `backend` here is the pyusb backend object (None: the system libusb; tests pass the fake).
    ``board: dt9814`` is refused: the only known DT9814 protocol (comedi's DT9812) has no hardware-paced
    scan and addresses 8 channels (the CLI says where the file chooses it before opening anything).
    Raises `HardwareUnavailable` (exit 3) naming what is missing, `VendorLibraryMissing` (exit 2) when a
    selected vendor library is not installed; nothing stays open on failure.
    """
    out_spec, in_spec = rig_spec.output, rig_spec.input
    for what, rng in (("output", out_spec.volts_range), ("input", in_spec.volts_range)):
        if tuple(float(v) for v in rng) != (-10.0, 10.0):
            raise InvalidInput(
                f"rig.{what}.volts_range: the USB drivers support only [-10, 10] V, got {list(rng)}"
            )
    if in_spec.board == "dt9814":
        raise HardwareUnavailable(
            "the input board is the DT9814, which protocol-runner cannot drive: its only known protocol (the "
            "DT9812's, UNVERIFIED for the DT9814) has no hardware-paced scan and reaches 8 channels. Use "
            "three USB-1608FS-Plus boards (input board usb1608fs; see docs/hardware.md), or rehearse with "
            "--dry-run."
        )
    clock = clock or MonotonicClock()
    ao = open_output(out_spec, backend)
    try:
        boards = open_inputs(in_spec, backend, clock)
        ai = BoardGroup(boards)
        for name, ch in (("angle", in_spec.angle_channel), ("torque", in_spec.torque_channel)):
            if ch >= ai.n_channels:
                ai.close()
                raise BoardNotFound(
                    f"the protocol reads the {name} on input channel {ch}, but the {len(boards)} "
                    f"{usb1608fs_protocol.KIND} board(s) attached give channels 0-{ai.n_channels - 1} (8 per board). "
                    "Connect the missing boards, or rehearse with --dry-run."
                )
    except BaseException:
        ao.close()
        raise
    return ao, ai, clock
