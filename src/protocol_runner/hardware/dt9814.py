"""Data Translation DT9814 analog input over pyusb — UNVERIFIED.

**Nothing in this module has been checked against a DT9814.** Data Translation publishes no product id,
no protocol document and no Linux driver for it. The code speaks the protocol of its sibling, the DT9812,
as the Linux comedi driver implements it, and every fact that might differ is a setting
(`Dt9814Settings`); opening a board logs a warning saying so. For 24 channels on Linux with a known
protocol, use the USB-1608FS-Plus (`hardware/usb1608fs.py`, `BoardGroup`).

DT9812 facts used:

- USB vendor id 0x0867; product id configurable (`Dt9814Settings.product_id`, None = any DT device).
- One interface with five bulk endpoints, in descriptor order: message-IN, command-OUT, command-IN,
  stream-OUT, stream-IN (taken by position, not by address).
- Every command is exactly 32 bytes: u32 LE opcode then payload, written to command-OUT; replies are read
  from command-IN. Opcode 1 reads flash: ``u16 count, u16 address`` with address ``0xFBFF + offset``:
  offset 1 vendor id (u16), 3 product id (u16), 5 device id (u16), 7 serial (u32).
- One analog sample = opcode 7 (read-modify-write registers: gain in ADC0CF, channel mux in P1 bits 5-7,
  start conversion in ADC0CN) then opcode 4 (read ADC0CN, ADC0H, ADC0L): two USB round trips per sample,
  so software-paced and well under 1 kHz. This module therefore offers single reads (`read_code`), not
  the hardware-paced `AnalogInput` scan.
- Conversion, 12-bit +-10 V two's complement: ``V = 20 * code / 4096`` (LSB 4.883 mV).
"""

from __future__ import annotations

import logging
import struct
from dataclasses import dataclass
from typing import Any

import usb.core
import usb.util

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.conversions import ai12_code_to_volts
from protocol_runner.hardware.usb_board import OpenedBoard, TransportSettings
from protocol_runner.hardware.usb_common import (
    DRY_RUN_HINT,
    DT_VENDOR_ID,
    BoardIoError,
    BoardNotFound,
    BoardTimeout,
    claim_interface,
    find_devices,
    map_usb_error,
    no_board,
)

log = logging.getLogger(__name__)

KIND = "DT9814"
COMMAND_SIZE = 32

OP_R_FLASH_DATA = 1
OP_R_MULTI_BYTE_REG = 4
OP_RMW_MULTI_BYTE_REG = 7

SFR_P1 = 0x90
SFR_ADC0CF = 0xBC
SFR_ADC0L = 0xBE
SFR_ADC0H = 0xBF
SFR_ADC0CN = 0xE8
ADC0CF_GAIN_MASK = 0x07
ADC0CN_AD0EN = 0x80
ADC0CN_AD0INT = 0x20
ADC0CN_AD0BUSY = 0x10

UNVERIFIED_WARNING = (
    "DT9814 support is UNVERIFIED: it speaks the DT9812 protocol of the Linux comedi driver, which has "
    "never been checked against a DT9814 (see docs/hardware.md)"
)


@dataclass(frozen=True)
class Dt9814Settings(TransportSettings):
    """Every UNVERIFIED DT9814 fact, as a setting (defaults = the DT9812/10V values from comedi)."""

    product_id: int | None = None
    board_info_address: int = 0xFBFF
    accepted_device_ids: tuple[int, ...] | None = None
    n_channels: int = 8
    mux_register: int = SFR_P1
    mux_mask: int = 0xE0
    mux_shift: int = 5
    gain_bits: int = 0x01  # gain 1 on the +-10 V board: the amplifier runs at x2 behind a x0.5 front end
    conversion_retries: int = 3


def sign_extend_12(raw: int) -> int:
    """The 12-bit two's-complement value of ``raw & 0xFFF`` (-2048..2047)."""
    raw &= 0x0FFF
    return raw - 0x1000 if raw & 0x0800 else raw


@dataclass(frozen=True)
class Dt9814Info:
    """Board identity read from flash."""

    vendor_id: int
    product_id: int
    device_id: int
    serial_number: int


class Dt9814(OpenedBoard[Dt9814Settings]):
    """An opened DT9814 (UNVERIFIED protocol). Use `Dt9814.open(serial=None, backend=None)`."""

    kind = KIND

    def __init__(self, device: usb.core.Device, settings: Dt9814Settings) -> None:
        self._dev = device
        self.settings = settings
        self.name = f"{KIND} (VID 0x{DT_VENDOR_ID:04X} PID 0x{int(device.idProduct):04X})"
        self._closed = False
        self.endpoints: tuple[int, ...] = ()
        self.info = Dt9814Info(0, 0, 0, 0)

    @classmethod
    def open(
        cls, serial: str | None = None, backend: Any | None = None, *, settings: Dt9814Settings | None = None
    ) -> Dt9814:
        """Open the first Data Translation board (or the one whose flash serial is `serial`)."""
        settings = settings or Dt9814Settings()
        pid = "any PID" if settings.product_id is None else f"PID 0x{settings.product_id:04X}"
        ids = f"VID 0x{DT_VENDOR_ID:04X} {pid}"
        devices = find_devices(DT_VENDOR_ID, settings.product_id, backend, KIND)
        if not devices:
            raise no_board(KIND, ids)
        seen: list[str] = []
        for dev in devices:
            board = cls.from_device(dev, settings)
            if serial is None or board.serial == serial:
                return board
            seen.append(board.serial)
            board.close()
        raise BoardNotFound(
            f"no {KIND} with serial {serial!r} found ({ids}); attached: {', '.join(seen)}. {DRY_RUN_HINT}"
        )

    @classmethod
    def from_device(cls, device: usb.core.Device, settings: Dt9814Settings | None = None) -> Dt9814:
        """Open an already found pyusb device (claim it, read its identity from flash)."""
        return cls(device, settings or Dt9814Settings())._set_up()

    def _setup(self) -> None:
        log.warning("%s: %s", self.name, UNVERIFIED_WARNING)
        s = self.settings
        claim_interface(self._dev, s.interface, self.name)
        try:
            cfg = self._dev.get_active_configuration()
        except usb.core.USBError as exc:
            raise map_usb_error(exc, self.name, "reading the configuration") from exc
        intf = usb.util.find_descriptor(cfg, bInterfaceNumber=s.interface)
        eps = tuple(int(ep.bEndpointAddress) for ep in intf) if intf is not None else ()
        if len(eps) < 5:
            raise BoardIoError(
                f"the {self.name} does not look like a DT9812-family board: interface {s.interface} has "
                f"{len(eps)} endpoints, 5 expected. Its protocol is unknown (see docs/hardware.md)"
            )
        self.endpoints = eps[:5]
        vendor, product, device_id = (int.from_bytes(self.read_flash(off, 2), "little") for off in (1, 3, 5))
        serial_number = int.from_bytes(self.read_flash(7, 4), "little")
        self.info = Dt9814Info(vendor, product, device_id, serial_number)
        if vendor != DT_VENDOR_ID:
            log.warning("%s: flash vendor id 0x%04X is not Data Translation's", self.name, vendor)
        accepted = s.accepted_device_ids
        if accepted is not None and device_id not in accepted:
            raise BoardIoError(
                f"the {self.name} reports device id 0x{device_id:04X}, not one of "
                f"{', '.join(f'0x{d:04X}' for d in accepted)} (Dt9814Settings.accepted_device_ids)"
            )

    @property
    def command_out(self) -> int:
        return self.endpoints[1]

    @property
    def command_in(self) -> int:
        return self.endpoints[2]

    def _command(self, opcode: int, payload: bytes, reply_size: int, action: str) -> bytes:
        timeout_ms = self.settings.timeout_ms
        command = struct.pack("<I", opcode) + payload.ljust(COMMAND_SIZE - 4, b"\x00")  # exactly 32 bytes
        self._usb(action, self._dev.write, self.command_out, command, timeout_ms)
        if reply_size == 0:
            return b""
        reply = bytes(self._usb(action, self._dev.read, self.command_in, reply_size, timeout_ms))
        if len(reply) != reply_size:
            raise BoardIoError(
                f"the {self.name} returned {len(reply)} of {reply_size} bytes while {action} "
                "(the DT9812 protocol may not apply to this board; see docs/hardware.md)"
            )
        return reply

    def read_flash(self, offset: int, count: int) -> bytes:
        """Read `count` bytes of the board-info flash at ``0xFBFF + offset`` (opcode 1)."""
        address = self.settings.board_info_address + offset
        return self._command(OP_R_FLASH_DATA, struct.pack("<HH", count, address), count, "reading flash")

    def read_registers(self, addresses: list[int]) -> bytes:
        """Read processor registers (opcode 4)."""
        payload = bytes([len(addresses), *addresses])
        return self._command(OP_R_MULTI_BYTE_REG, payload, len(addresses), "reading registers")

    def rmw_registers(self, triples: list[tuple[int, int, int]]) -> None:
        """Read-modify-write registers (opcode 7): (address, mask, value) per register."""
        payload = bytes([len(triples)]) + b"".join(bytes(t) for t in triples)
        self._command(OP_RMW_MULTI_BYTE_REG, payload, 0, "writing registers")

    @property
    def resolution_bits(self) -> int:
        return 12

    def read_code(self, channel: int) -> int:
        """One software-timed sample of `channel`: the 12-bit two's-complement code (-2048..2047)."""
        s = self.settings
        if not 0 <= channel < s.n_channels:
            raise InvalidInput(
                f"{KIND}: channel {channel} cannot be addressed with the DT9812 register protocol "
                f"(channels 0-{s.n_channels - 1}; Dt9814Settings.n_channels)"
            )
        self.rmw_registers(
            [
                (SFR_ADC0CF, ADC0CF_GAIN_MASK, s.gain_bits),
                (s.mux_register, s.mux_mask, (channel << s.mux_shift) & s.mux_mask),
                (SFR_ADC0CN, 0xFF, ADC0CN_AD0EN | ADC0CN_AD0BUSY),
            ]
        )
        for _ in range(s.conversion_retries):
            status, high, low = self.read_registers([SFR_ADC0CN, SFR_ADC0H, SFR_ADC0L])
            if status & (ADC0CN_AD0INT | ADC0CN_AD0BUSY) == ADC0CN_AD0INT:
                return sign_extend_12((high << 8) | low)
        raise BoardTimeout(f"the {self.name} did not finish an A/D conversion on channel {channel}")

    def read_volts(self, channel: int) -> float:
        """One sample of `channel` in volts (``20 * code / 4096``)."""
        return float(ai12_code_to_volts(self.read_code(channel)))

    @property
    def serial(self) -> str:
        return str(self.info.serial_number)

    def calibration_summary(self) -> str:
        return "no calibration read (DT9812 protocol: none known)"

    def blink(self, count: int = 5) -> None:
        """The DT9812 protocol has no LED command: nothing to do (kept for a uniform board API)."""
