"""`run-protocol --hardware-check`: list the DAQ boards attached, blink their LEDs, check required channels.

Channel numbering (the numbers the protocol file uses, all from 0):

- analog outputs: the USB-3105 boards in serial-number order, 16 channels each (board k: 16k..16k+15);
- analog inputs: the USB-1608FS-Plus boards in serial-number order, 8 channels each, then any DT9814
  (UNVERIFIED protocol; `Dt9814Settings.n_channels` each). This is the numbering `MultiBoardInput` uses.

`hardware_check` never raises for a board it cannot open: the failure becomes a `BoardProblem` with the
driver's plain message (busy, permission denied with the udev rule to install, ...).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any, NamedTuple, Protocol

import usb.core

from protocol_runner.errors import EXIT_HARDWARE_UNAVAILABLE, HardwareUnavailable, InvalidInput
from protocol_runner.hardware import usb1608fs_protocol, usb3105
from protocol_runner.hardware.dt9814 import KIND as DT9814_KIND
from protocol_runner.hardware.dt9814 import Dt9814, Dt9814Settings
from protocol_runner.hardware.usb1608fs import Usb1608FsPlus
from protocol_runner.hardware.usb3105 import Usb3105
from protocol_runner.hardware.usb_common import (
    DT_VENDOR_ID,
    MCC_VENDOR_ID,
    UDEV_RULE_FILENAME,
    NoUsbBackend,
    find_devices,
    read_serial,
    udev_rule_text,
)

log = logging.getLogger(__name__)

ANALOG_OUTPUT = "analog_output"
ANALOG_INPUT = "analog_input"
ROLES = (ANALOG_OUTPUT, ANALOG_INPUT)

NOTHING_FOUND = (
    "No DAQ boards found. Check the USB cables and that the boards are powered, install the udev rule "
    f"(packaging/udev/{UDEV_RULE_FILENAME}, see docs/hardware.md) so this user may open them, "
    "or rehearse the protocol without the rig with --dry-run."
)


@dataclass(frozen=True)
class BoardInfo:
    """One board that opened: what it is and which global channels it provides."""

    kind: str
    role: str
    serial: str
    firmware: str
    first_channel: int
    n_channels: int
    calibration: str
    blinked: bool
    note: str = ""

    @property
    def channels(self) -> range:
        return range(self.first_channel, self.first_channel + self.n_channels)


@dataclass(frozen=True)
class BoardProblem:
    """A board that was seen but could not be used (or a failure to look for boards at all)."""

    kind: str
    message: str


@dataclass(frozen=True)
class ChannelCheck:
    """Whether a required channel exists, and where."""

    role: str
    channel: int
    board: BoardInfo | None

    @property
    def available(self) -> bool:
        return self.board is not None


@dataclass(frozen=True)
class HardwareReport:
    boards: tuple[BoardInfo, ...]
    problems: tuple[BoardProblem, ...]
    checks: tuple[ChannelCheck, ...]

    def channel_count(self, role: str) -> int:
        return sum(b.n_channels for b in self.boards if b.role == role)

    @property
    def ok(self) -> bool:
        """True when boards were found, none failed, and every required channel exists."""
        return bool(self.boards) and not self.problems and all(c.available for c in self.checks)


class _Board(Protocol):
    @property
    def serial(self) -> str: ...
    @property
    def firmware(self) -> str: ...

    def calibration_summary(self) -> str: ...
    def blink(self, count: int = ...) -> None: ...
    def close(self) -> None: ...


def _role_label(role: str) -> str:
    return role.replace("_", " ")


def _check_required(required: Mapping[str, Sequence[int]] | None) -> dict[str, list[int]]:
    if not required:
        return {}
    out: dict[str, list[int]] = {}
    for role, chans in required.items():
        if role not in ROLES:
            raise InvalidInput(
                f"hardware check: unknown channel role {role!r}; use one of {', '.join(ROLES)}"
            )
        try:
            out[role] = sorted({int(c) for c in chans})
        except (TypeError, ValueError) as exc:
            raise InvalidInput(f"hardware check: {role} channels must be integers, got {chans!r}") from exc
        if any(c < 0 for c in out[role]):
            raise InvalidInput(f"hardware check: {role} channel numbers start at 0, got {chans!r}")
    return out


def _serials(
    vendor: int, product: int | None, kind: str, backend: Any, problems: list[BoardProblem]
) -> list[str]:
    try:
        devices = find_devices(vendor, product, backend, kind)
    except HardwareUnavailable as exc:
        problems.append(BoardProblem(kind, exc.message))
        return []
    serials: list[str] = []
    for dev in devices:
        try:
            serials.append(read_serial(dev, kind))
        except HardwareUnavailable as exc:
            problems.append(BoardProblem(kind, exc.message))
    return sorted(serials)


class BoardKind(NamedTuple):
    """What the survey says of every board of one kind: its name, channel role and channel count, a note,
    and whether it has an LED to blink."""

    kind: str
    role: str
    n_channels: int
    note: str = ""
    can_blink: bool = True


def _survey(
    board_kind: BoardKind,
    openers: Sequence[Callable[[], _Board]],
    first_channel: int,
    blink_count: int,
    boards: list[BoardInfo],
    problems: list[BoardProblem],
) -> int:
    """Open each board, describe it, blink it, close it. Returns the next free global channel."""
    kind, role, n_channels, note, can_blink = board_kind
    for opener in openers:
        try:
            board = opener()
        except HardwareUnavailable as exc:
            problems.append(BoardProblem(kind, exc.message))
            continue
        try:
            blinked = False
            if blink_count > 0 and can_blink:
                board.blink(blink_count)
                blinked = True
            boards.append(
                BoardInfo(
                    kind=kind,
                    role=role,
                    serial=str(board.serial),
                    firmware=str(board.firmware),
                    first_channel=first_channel,
                    n_channels=n_channels,
                    calibration=board.calibration_summary(),
                    blinked=blinked,
                    note=note,
                )
            )
            first_channel += n_channels
        except HardwareUnavailable as exc:
            problems.append(BoardProblem(kind, exc.message))
        finally:
            board.close()
    return first_channel


def hardware_check(
    required: dict[str, list[int]] | None = None,
    backend: Any | None = None,
    *,
    blink_count: int = 3,
    dt9814_settings: Dt9814Settings | None = None,
) -> HardwareReport:
    """List the DAQ boards, blink their LEDs, and check that the `required` channels exist.

    `required` maps ``"analog_output"`` / ``"analog_input"`` to global channel numbers, e.g.
    ``{"analog_output": [8], "analog_input": [8, 20]}``. `backend` is passed to `usb.core.find`
    (None: the system libusb; tests pass the fake backend). Every board is closed again on return.
    """
    needed = _check_required(required)
    boards: list[BoardInfo] = []
    problems: list[BoardProblem] = []
    try:
        find_devices(MCC_VENDOR_ID, None, backend, "DAQ boards")
    except NoUsbBackend as exc:  # no libusb: say it once, not once per board kind
        missing = tuple(ChannelCheck(role, ch, None) for role, chans in needed.items() for ch in chans)
        return HardwareReport((), (BoardProblem("USB", exc.message),), missing)

    ao_serials = _serials(MCC_VENDOR_ID, usb3105.PRODUCT_ID, usb3105.KIND, backend, problems)
    _survey(
        BoardKind(usb3105.KIND, ANALOG_OUTPUT, usb3105.N_CHANNELS),
        [partial(Usb3105.open, serial=s, backend=backend) for s in ao_serials],
        0,
        blink_count,
        boards,
        problems,
    )
    ai_serials = _serials(
        MCC_VENDOR_ID, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND, backend, problems
    )
    next_ai = _survey(
        BoardKind(usb1608fs_protocol.KIND, ANALOG_INPUT, usb1608fs_protocol.N_CHANNELS),
        [partial(Usb1608FsPlus.open, serial=s, backend=backend) for s in ai_serials],
        0,
        blink_count,
        boards,
        problems,
    )
    dt_settings = dt9814_settings or Dt9814Settings()
    try:
        dt_devices: list[usb.core.Device] = find_devices(
            DT_VENDOR_ID, dt_settings.product_id, backend, DT9814_KIND
        )
    except HardwareUnavailable:
        dt_devices = []  # the missing-libusb problem is already reported above
    dt_kind = BoardKind(
        DT9814_KIND,
        ANALOG_INPUT,
        dt_settings.n_channels,
        note="UNVERIFIED protocol (DT9812 family); no LED command",
        can_blink=False,
    )
    _survey(
        dt_kind,
        [partial(Dt9814.from_device, d, dt_settings) for d in dt_devices],
        next_ai,
        blink_count,
        boards,
        problems,
    )

    checks: list[ChannelCheck] = []
    for role, chans in needed.items():
        for ch in chans:
            owner = next((b for b in boards if b.role == role and ch in b.channels), None)
            checks.append(ChannelCheck(role, ch, owner))
    return HardwareReport(tuple(boards), tuple(problems), tuple(checks))


def _channel_span(report: HardwareReport, role: str) -> str:
    n = report.channel_count(role)
    return f"channels 0-{n - 1}" if n else "none"


def format_report(report: HardwareReport) -> str:
    """The hardware check in plain words, ready to print."""
    lines = ["DAQ hardware check", ""]
    if not report.boards:
        lines.append(NOTHING_FOUND)
    else:
        lines.append("Boards found:")
        for b in report.boards:
            span = f"{b.channels.start}-{b.channels.stop - 1}"
            led = "LED blinked" if b.blinked else "LED not blinked"
            lines.append(
                f"  {b.kind} serial {b.serial}, firmware {b.firmware}: {b.n_channels} "
                f"{_role_label(b.role)}s (channels {span}), {led}"
            )
            lines.append(f"      {b.calibration}")
            if b.note:
                lines.append(f"      note: {b.note}")
        lines.append(
            f"  In total: analog outputs {_channel_span(report, ANALOG_OUTPUT)}; "
            f"analog inputs {_channel_span(report, ANALOG_INPUT)}."
        )
    if report.problems:
        lines += ["", "Problems:"]
        for p in report.problems:
            lines.append(f"  {p.kind}: {p.message}")
    if report.checks:
        lines += ["", "Channels the protocol needs:"]
        for c in report.checks:
            label = f"{_role_label(c.role)} {c.channel}"
            if c.board is not None:
                local = c.channel - c.board.first_channel
                lines.append(f"  {label}: OK ({c.board.kind} serial {c.board.serial}, its channel {local})")
            else:
                lines.append(
                    f"  {label}: MISSING (available {_role_label(c.role)}s: {_channel_span(report, c.role)})"
                )
    lines += ["", "Ready for a hardware run." if report.ok else "NOT ready for a hardware run."]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m protocol_runner.hardware.discovery [--udev-rule]``: print the hardware check (exit 0 when
    ready, 3 otherwise), or the udev rule text to install."""
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    if "--udev-rule" in args:
        print(udev_rule_text(), end="")
        return 0
    report = hardware_check()
    print(format_report(report))
    return 0 if report.ok else EXIT_HARDWARE_UNAVAILABLE


if __name__ == "__main__":
    raise SystemExit(main())
