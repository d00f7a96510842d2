"""`run-protocol --hardware-check`: list the DAQ boards attached, blink their LEDs, check required channels.

Channel numbering (the numbers the protocol file uses, all from 0):

- analog outputs: the USB-3105 boards in serial-number order, 16 channels each (board k: 16k..16k+15);
- analog inputs: the USB-1608FS-Plus boards in serial-number order, 8 channels each, then any DT9814
  (UNVERIFIED protocol; `Dt9814Settings.n_channels` each). This is the numbering `BoardGroup` uses.

Each USB-3105 is also timed: `timing_reports` single-channel writes of 0 V on its highest channel that no
joint of the rig file is wired to, giving the time one output report takes, printed beside the rig file's
`report_time_s` (a tick of N joints sends N + 1 reports: docs/hardware.md).

`hardware_check` never raises for a board it cannot open: the failure becomes a `BoardProblem` with the
driver's plain message (busy, permission denied with the udev rule to install, ...).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

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


TIMING_REPORTS = 200
"""Single-channel writes timed per USB-3105 (about 0.2 s at 1 ms each)."""


@dataclass(frozen=True)
class OutputTiming:
    """What the rig file says of its output board: the time one output report takes (`report_time_s`),
    the board's rate, and the global output channels its joints are wired to (the timing writes avoid them)."""

    rig_file: str
    report_time_s: float | None
    rate_hz: float
    joint_channels: frozenset[int]


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
    report_time_s: float | None = None  # measured (USB-3105): mean time of one output report
    timing_channel: int | None = None  # the board's own channel the timing writes used

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
    """Whether a required channel exists, and where (`board` None: it does not)."""

    role: str
    channel: int
    board: BoardInfo | None


@dataclass(frozen=True)
class HardwareReport:
    boards: tuple[BoardInfo, ...]
    problems: tuple[BoardProblem, ...]
    checks: tuple[ChannelCheck, ...]
    timing: OutputTiming | None = None

    def channel_count(self, role: str) -> int:
        return sum(b.n_channels for b in self.boards if b.role == role)

    @property
    def ok(self) -> bool:
        """True when boards were found, none failed, and every required channel exists."""
        return bool(self.boards) and not self.problems and all(c.board is not None for c in self.checks)


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


def _survey(
    kind: str,
    role: str,
    n_channels: int,
    openers: Sequence[Callable[[], Any]],
    blink_count: int,
    boards: list[BoardInfo],
    problems: list[BoardProblem],
    timer: Callable[[Any, int], tuple[float | None, int | None]] | None = None,
    note: str = "",
) -> None:
    """Open each board, describe it, blink it (the DT9814 has no LED command), time it (`timer`: (board,
    its first global channel) -> (report time, the board channel used)), close it. A board's global
    channels follow those of the boards of its role found before it."""
    for opener in openers:
        try:
            board = opener()
        except HardwareUnavailable as exc:
            problems.append(BoardProblem(kind, exc.message))
            continue
        try:
            first_channel = sum(b.n_channels for b in boards if b.role == role)
            blinked = blink_count > 0 and kind != DT9814_KIND
            if blinked:
                board.blink(blink_count)
            measured, timing_channel = timer(board, first_channel) if timer else (None, None)
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
                    report_time_s=measured,
                    timing_channel=timing_channel,
                )
            )
        except HardwareUnavailable as exc:
            problems.append(BoardProblem(kind, exc.message))
        finally:
            board.close()


def hardware_check(
    required: dict[str, list[int]] | None = None,
    backend: Any | None = None,
    *,
    blink_count: int = 3,
    dt9814_settings: Dt9814Settings | None = None,
    timing: OutputTiming | None = None,
    timing_reports: int = TIMING_REPORTS,
    clock: Callable[[], float] = time.perf_counter,
) -> HardwareReport:
    """List the DAQ boards, blink their LEDs, time each USB-3105's output report, and check that the
    `required` channels exist.

    `required` maps ``"analog_output"`` / ``"analog_input"`` to global channel numbers, e.g.
    ``{"analog_output": [8], "analog_input": [8, 20]}``. `backend` is passed to `usb.core.find`
    (None: the system libusb; tests pass the fake backend). `timing` is the rig file's word on its output
    board (`rig_file.output_timing`); without it no output is written, since which channels are wired to
    joints is unknown. `timing_reports` writes are timed on `clock` (0: none). Every board is closed
    again on return.
    """
    needed = _check_required(required)

    def time_reports(board: Usb3105, first_channel: int) -> tuple[float | None, int | None]:
        if timing is None:
            return None, None
        free = [c for c in range(usb3105.N_CHANNELS) if first_channel + c not in timing.joint_channels]
        if timing_reports < 1 or not free:
            return None, None
        return board.measure_report_time_s(free[-1], timing_reports, clock), free[-1]

    boards: list[BoardInfo] = []
    problems: list[BoardProblem] = []
    try:
        find_devices(MCC_VENDOR_ID, None, backend, "DAQ boards")
    except NoUsbBackend as exc:  # no libusb: say it once, not once per board kind
        missing = tuple(ChannelCheck(role, ch, None) for role, chans in needed.items() for ch in chans)
        return HardwareReport((), (BoardProblem("USB", exc.message),), missing, timing)

    for board_cls, facts, role, timer in (
        (Usb3105, usb3105, ANALOG_OUTPUT, time_reports),
        (Usb1608FsPlus, usb1608fs_protocol, ANALOG_INPUT, None),
    ):
        serials = _serials(MCC_VENDOR_ID, facts.PRODUCT_ID, facts.KIND, backend, problems)
        openers = [partial(board_cls.open, serial=s, backend=backend) for s in serials]
        _survey(facts.KIND, role, facts.N_CHANNELS, openers, blink_count, boards, problems, timer)
    dt_settings = dt9814_settings or Dt9814Settings()
    try:
        dt_devices: list[usb.core.Device] = find_devices(
            DT_VENDOR_ID, dt_settings.product_id, backend, DT9814_KIND
        )
    except HardwareUnavailable:
        dt_devices = []  # the missing-libusb problem is already reported above
    _survey(
        DT9814_KIND,
        ANALOG_INPUT,
        dt_settings.n_channels,
        [partial(Dt9814.from_device, d, dt_settings) for d in dt_devices],
        blink_count,
        boards,
        problems,
        note="UNVERIFIED protocol (DT9812 family); no LED command",
    )

    checks: list[ChannelCheck] = []
    for role, chans in needed.items():
        for ch in chans:
            owner = next((b for b in boards if b.role == role and ch in b.channels), None)
            checks.append(ChannelCheck(role, ch, owner))
    return HardwareReport(tuple(boards), tuple(problems), tuple(checks), timing)


def _channel_span(report: HardwareReport, role: str) -> str:
    n = report.channel_count(role)
    return f"channels 0-{n - 1}" if n else "none"


def _timing_lines(board: BoardInfo, timing: OutputTiming | None) -> list[str]:
    """The measured report time beside the rig file's, and how many joints one tick then holds."""
    measured = float(board.report_time_s or 0.0)
    lines = [
        f"      one output report: {measured * 1e3:.3f} ms measured (single-channel writes of 0 V on its "
        f"channel {board.timing_channel}, wired to no joint)"
    ]
    if timing is None:
        return lines
    stated = (
        f"{timing.rig_file} states report_time_s {timing.report_time_s * 1e3:g} ms"
        if timing.report_time_s is not None
        else f"{timing.rig_file} states no report_time_s"
    )
    tick_s = 1.0 / timing.rate_hz
    holds = math.floor(tick_s / measured + 1e-9) - 1 if measured > 0 else None
    fits = f"; a {tick_s * 1e3:g} ms tick at {timing.rate_hz:g} Hz holds {holds} joints (N + 1 reports)"
    lines.append(f"      {stated}{fits if holds is not None else ''}")
    if timing.report_time_s is not None and measured > timing.report_time_s:
        lines.append(
            f"      the measured time is above the rig file's: set report_time_s: {measured:.4f} in "
            f"{timing.rig_file} so that campaigns are checked against it"
        )
    return lines


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
            if b.report_time_s is not None:
                lines += _timing_lines(b, report.timing)
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
