"""MCC USB-3105 analog output board over pyusb (satisfies `interfaces.AnalogOutput`).

The USB-3105 is a HID-class device: every command is an output report whose first byte is the command
code (it doubles as the report id); replies come back as input reports ``[command, data...]`` on the
interrupt IN endpoint. Facts used (docs/hardware.md, reference "USB facts"):

- VID 0x09DB, PID 0x009E; serial number = USB iSerialNumber; firmware = bcdDevice.
- ``AOUT_CONFIG [0x1C, ch, range]`` (range 1 = +-10 V) also drives the pin to 0 V: it is sent once per
  channel by `configure_channel`, never by `write_volts`.
- ``AOUT [0x14, ch, lo, hi, update]`` (update 0 = now, 1 = wait for sync) and ``AOUT_SYNC [0x15]``.
- ``MEM_READ [0x30, addr lo, addr hi, 0, count <= 62]`` -> ``[0x30, data...]``; the +-10 V calibration of
  channel ch is float32 LE (slope, offset) at ``0x108 + 0x10 * ch``; ``code = round(slope * k + offset)``
  with the ideal code ``k = 32768 + 3276.8 * V`` (clamped to 0..65535).

UNVERIFIED on hardware: the endpoint addresses (interrupt OUT 0x01, IN 0x81). They are settings
(`Usb3105Settings`); when the configured OUT endpoint is absent from the descriptor, reports go through
HID SET_REPORT on the control pipe (0x21, 0x09, 0x0200 | report id, interface).
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import usb.core
import usb.util

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.usb3105_calibration import (
    IDENTITY_CALIBRATION,
    ChannelCalibration,
    calibrated_code,
    parse_calibration,
)
from protocol_runner.hardware.usb_board import InPipeSettings, OpenedBoard
from protocol_runner.hardware.usb_common import (
    MCC_VENDOR_ID,
    BoardIoError,
    UnexpectedReply,
    claim_interface,
    find_board,
    finite_volts,
    map_usb_error,
    output_channel,
    usb_call,
)

log = logging.getLogger(__name__)

PRODUCT_ID = 0x009E
KIND = "USB-3105"
N_CHANNELS = 16

CMD_AOUT = 0x14
CMD_AOUT_SYNC = 0x15
CMD_AOUT_CONFIG = 0x1C
CMD_MEM_READ = 0x30
CMD_BLINK_LED = 0x40
CMD_SET_SYNC = 0x43
CMD_GET_STATUS = 0x44

RANGE_PM10V = 1
CAL_BASE_PM10V = 0x108
CAL_STRIDE = 0x10
MEM_READ_MAX = 62

HID_SET_REPORT_REQUEST_TYPE = 0x21
HID_SET_REPORT = 0x09
HID_REPORT_TYPE_OUTPUT = 0x0200


@dataclass(frozen=True)
class Usb3105Settings(InPipeSettings):
    """Transport settings. The endpoint addresses are the documented defaults, UNVERIFIED on hardware."""

    out_endpoint: int = 0x01
    reply_timeout_ms: int = 500
    max_unexpected_replies: int = 4


class ChannelNotConfigured(InvalidInput):
    """`write_volts` on a channel that `configure_channel` has not set to +-10 V."""


class Usb3105(OpenedBoard[Usb3105Settings]):
    """An opened USB-3105. Use `Usb3105.open(serial=None, backend=None)`; close it (or use ``with``): the
    outputs keep their last value."""

    kind = KIND
    n_channels = N_CHANNELS

    def __init__(
        self,
        device: usb.core.Device,
        serial: str,
        settings: Usb3105Settings,
    ) -> None:
        """Wrap an already claimed device; prefer `Usb3105.open`."""
        self._dev = device
        self._serial = serial
        self.settings = settings
        self.name = f"{KIND} serial {serial}"
        self._configured: set[int] = set()
        self._closed = False
        self.calibration: tuple[ChannelCalibration, ...] = tuple([IDENTITY_CALIBRATION] * N_CHANNELS)
        self.stale_reports_drained = 0
        self.uses_set_report = False
        self.kernel_driver_detached = False

    @classmethod
    def open(
        cls, serial: str | None = None, backend: Any | None = None, *, settings: Usb3105Settings | None = None
    ) -> Usb3105:
        """Find the board (VID 0x09DB PID 0x009E, optionally by serial), claim it, drain stale reports and
        read the calibration. `backend` is passed to `usb.core.find` (None: the system libusb).

        Raises a `HardwareUnavailable` subclass naming the board and the cure (not found, busy,
        permission denied, timeout, gone).
        """
        device, board_serial = find_board(MCC_VENDOR_ID, PRODUCT_ID, serial, backend, KIND)
        return cls(device, board_serial, settings or Usb3105Settings())._set_up()

    def _setup(self) -> None:
        s = self.settings
        self.kernel_driver_detached = claim_interface(self._dev, s.interface, self.name)
        cfg = self._active_configuration()
        intf = usb.util.find_descriptor(cfg, bInterfaceNumber=s.interface)
        if intf is None:
            raise BoardIoError(f"the {self.name} has no USB interface {s.interface}; check the settings")
        addresses = {int(ep.bEndpointAddress) for ep in intf}
        if s.in_endpoint not in addresses:
            raise BoardIoError(
                f"the {self.name} has no IN endpoint 0x{s.in_endpoint:02X} (it has "
                f"{', '.join(f'0x{a:02X}' for a in sorted(addresses)) or 'none'}); set "
                "Usb3105Settings.in_endpoint to the right address (see docs/hardware.md)"
            )
        self.uses_set_report = s.out_endpoint not in addresses
        if self.uses_set_report:
            log.info("%s: no interrupt OUT endpoint 0x%02X; using HID SET_REPORT", self.name, s.out_endpoint)
        self.stale_reports_drained = self._drain()
        if self.stale_reports_drained:
            log.warning("%s: drained %d stale input reports", self.name, self.stale_reports_drained)
        self.calibration = self._read_calibration()
        bad = [ch for ch, c in enumerate(self.calibration) if not c.valid]
        if bad:
            log.warning("%s: no valid calibration for channels %s; using slope 1, offset 0", self.name, bad)
        # AOUT_SYNC latches the held outputs only on a sync master; a board left as slave (by another
        # program, or its jumper) would hold every joint's update of a several-joint tick for ever
        self.set_sync_master(True)

    def _active_configuration(self) -> Any:
        try:
            return self._dev.get_active_configuration()
        except usb.core.USBError as exc:
            if getattr(exc, "errno", None) is not None:
                raise map_usb_error(exc, self.name, "reading the active configuration") from exc
            usb_call(self.name, "setting the configuration", self._dev.set_configuration)
            return self._dev.get_active_configuration()

    def _drain(self) -> int:
        """Read and discard input reports left over from an earlier session (they can hang the board)."""
        n = 0
        s = self.settings
        while n < s.max_drain_packets:
            try:
                self._dev.read(s.in_endpoint, s.packet_size, s.drain_timeout_ms)
            except usb.core.USBTimeoutError:
                break
            except usb.core.USBError as exc:
                raise map_usb_error(exc, self.name, "draining stale input reports") from exc
            n += 1
        return n

    def _send(self, report: bytes, action: str) -> None:
        s = self.settings
        if self.uses_set_report:
            request = HID_SET_REPORT_REQUEST_TYPE, HID_SET_REPORT, HID_REPORT_TYPE_OUTPUT | report[0]
            self._usb(action, self._dev.ctrl_transfer, *request, s.interface, report, s.timeout_ms)
        else:
            self._usb(action, self._dev.write, s.out_endpoint, report, s.timeout_ms)

    def _query(self, report: bytes, action: str) -> bytes:
        """Send a command and return its reply (byte 0 checked against the command code)."""
        self._send(report, action)
        s = self.settings
        for _ in range(s.max_unexpected_replies + 1):
            try:
                reply = bytes(self._dev.read(s.in_endpoint, s.packet_size, s.reply_timeout_ms))
            except usb.core.USBError as exc:
                raise map_usb_error(exc, self.name, action) from exc
            if reply and reply[0] == report[0]:
                return reply
            log.warning("%s: discarding unexpected input report %s while %s", self.name, reply.hex(), action)
        raise UnexpectedReply(
            f"the {self.name} answered command 0x{report[0]:02X} with unrelated reports while {action}. "
            "Unplug and replug the board, then retry."
        )

    def _read_calibration(self) -> tuple[ChannelCalibration, ...]:
        """Every channel's (slope, offset) from board memory (MEM_READ, in chunks of at most 62 bytes)."""
        span = CAL_STRIDE * (N_CHANNELS - 1) + 8
        mem = bytearray()
        while len(mem) < span:
            n = min(MEM_READ_MAX, span - len(mem))
            addr = CAL_BASE_PM10V + len(mem)
            reply = self._query(
                bytes((CMD_MEM_READ, addr & 0xFF, (addr >> 8) & 0xFF, 0, n)), "reading calibration memory"
            )
            data = reply[1 : 1 + n]
            if len(data) < n:
                raise UnexpectedReply(
                    f"the {self.name} returned {len(data)} of {n} memory bytes at 0x{addr:04X}; "
                    "unplug and replug the board"
                )
            mem += data
        return tuple(
            parse_calibration(*struct.unpack_from("<ff", mem, CAL_STRIDE * ch)) for ch in range(N_CHANNELS)
        )

    def configure_channel(self, channel: int) -> None:
        """Set `channel` to +-10 V (AOUT_CONFIG). This drives the pin to 0 V: call once before a run."""
        channel = output_channel(KIND, channel, N_CHANNELS)
        self._send(bytes((CMD_AOUT_CONFIG, channel, RANGE_PM10V)), f"configuring output channel {channel}")
        self._configured.add(channel)

    def _checked_code(self, channel: int, volts: float) -> int:
        """The calibrated code to send for `volts` on a configured `channel`."""
        if channel not in self._configured:
            output_channel(KIND, channel, N_CHANNELS)
            raise ChannelNotConfigured(
                f"output channel {channel} of the {self.name} is not configured: call "
                "configure_channel() once before writing (it sets +-10 V and drives the pin to 0 V)"
            )
        return calibrated_code(finite_volts(channel, volts), self.calibration[channel])

    def write_volts(self, channel: int, volts: float) -> int:
        """Output `volts` on `channel` now (AOUT, update 0); return the calibrated code sent."""
        code = self._checked_code(channel, volts)
        self._send(bytes((CMD_AOUT, channel, code & 0xFF, code >> 8, 0)), f"writing output channel {channel}")
        return code

    def write_volts_sync(self, volts_by_channel: Mapping[int, float]) -> dict[int, int]:
        """Hold every channel's value (AOUT, update 1), then latch them together with one AOUT_SYNC."""
        codes = {ch: self._checked_code(ch, v) for ch, v in volts_by_channel.items()}
        for ch, code in codes.items():
            self._send(bytes((CMD_AOUT, ch, code & 0xFF, code >> 8, 1)), f"writing output channel {ch}")
        if codes:
            self._send(bytes((CMD_AOUT_SYNC,)), "latching the outputs (AOUT_SYNC)")
        return codes

    def measure_report_time_s(
        self, channel: int, n_reports: int, clock: Callable[[], float] = time.perf_counter
    ) -> float:
        """The mean time of one output report: `n_reports` single-channel writes of 0 V (AOUT, update 0) on
        `channel`, after its AOUT_CONFIG (which also sets it to 0 V). Use a channel no joint is wired to:
        the writes change that output."""
        if n_reports < 1:
            raise InvalidInput(f"measuring the report time needs at least 1 report, got {n_reports}")
        self.configure_channel(channel)
        start_s = clock()
        for _ in range(n_reports):
            self.write_volts(channel, 0.0)
        return (clock() - start_s) / n_reports

    @property
    def serial(self) -> str:
        return self._serial

    def blink(self, count: int = 5) -> None:
        """Blink the board's LED `count` times (to find it on the rig)."""
        self._check_blink(count)
        self._send(bytes((CMD_BLINK_LED, count)), "blinking the LED")

    def get_status(self) -> int:
        """GET_STATUS byte (bit 0: 1 = sync master)."""
        return self._query(bytes((CMD_GET_STATUS,)), "reading the status")[1]

    def set_sync_master(self, master: bool = True) -> None:
        """SET_SYNC: master latches on AOUT_SYNC; slave waits for the external SYNC pin."""
        self._send(bytes((CMD_SET_SYNC, 0 if master else 1)), "setting the sync mode")

    def calibration_summary(self) -> str:
        """One line: how many channels carry a valid +-10 V calibration and its spread."""
        valid = [c for c in self.calibration if c.valid]
        if not valid:
            return "no valid +-10 V calibration in memory (using slope 1, offset 0)"
        slopes = [c.slope for c in valid]
        offsets = [c.offset for c in valid]
        return (
            f"+-10 V calibration for {len(valid)}/{N_CHANNELS} channels: slope {min(slopes):.5f}.."
            f"{max(slopes):.5f}, offset {min(offsets):+.1f}..{max(offsets):+.1f} counts"
        )

    def __repr__(self) -> str:
        return f"Usb3105(serial={self._serial!r}, firmware={self.firmware!r})"
