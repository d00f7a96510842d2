"""Byte-level model of the MCC USB-3105 (16-channel analog output, HID class).

It keeps what the board keeps: the code latched on every output, each channel's range, the codes held
for a synchronous update, the sync mode, the calibration memory, and the LED blinks. Every output report
received (through the interrupt OUT endpoint or HID SET_REPORT) is appended to `reports`, so tests check
the exact bytes on the wire, and may move a test clock by `report_time_s` (the time a report takes). Replies are queued as input reports `[command, data...]` on IN `0x81`.

The DAC is modelled with a gain/offset error that the factory calibration in memory corrects: a code
`c` makes the pin voltage of the ideal code `(c - offset) / slope` (the inverse of the calibration rule
`code = slope * k + offset`), so a driver that applies the calibration gets the requested volts.
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar

from tests.fakeusb.descriptors import ENDPOINT_INTERRUPT, UsbIdentity, single_interface
from tests.fakeusb.device import FakeUsbDevice, Faults, Setup, Stall

N_CHANNELS = 16
MEMORY_SIZE = 0x400

AOUT = 0x14
AOUT_SYNC = 0x15
AOUT_CONFIG = 0x1C
MEM_READ = 0x30
BLINK_LED = 0x40
RESET = 0x41
SET_SYNC = 0x43
GET_STATUS = 0x44

RANGE_0_10V = 0
RANGE_PM10V = 1


def calibration_address(channel: int, range_code: int) -> int:
    """Memory address of a channel's (slope, offset) pair: 0x108 + 0x10*ch for +-10 V, 0x100 + ... for 0-10 V."""
    return (0x108 if range_code == RANGE_PM10V else 0x100) + 0x10 * channel


@dataclass(eq=False)
class Usb3105Model(FakeUsbDevice):
    """A fake USB-3105. `interrupt_out=False` gives a descriptor without OUT endpoint (SET_REPORT only)."""

    IDENTITY: ClassVar[UsbIdentity] = UsbIdentity(0x09DB, 0x009E, 0x0102, "MCC", "USB-3105")

    interrupt_out: bool = True
    stale_reports: list[bytes] = field(default_factory=list)
    # the time one output report takes on the wire, spent on `advance` (a `ManualClock.advance`): the
    # model never sleeps, its reports move the test's clock
    report_time_s: float = 0.0
    advance: Callable[[float], None] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.interfaces:
            addresses = (0x81, 0x01) if self.interrupt_out else (0x81,)
            self.interfaces = single_interface(3, ENDPOINT_INTERRUPT, addresses)
            self.kernel_driver_on = {0}
        self.memory = bytearray(b"\xff" * MEMORY_SIZE)
        for ch in range(N_CHANNELS):
            for rng in (RANGE_0_10V, RANGE_PM10V):
                self.set_calibration(ch, 1.0, 0.0, rng)
        self.codes: list[int] = [0] * N_CHANNELS
        self.ranges: list[int | None] = [None] * N_CHANNELS
        self.held: dict[int, int] = {}
        self.sync_master = False  # as a board left as slave: the driver must make it master
        self.blinks = 0
        self.resets = 0
        self.reports: list[bytes] = []
        self.bad_reports: list[bytes] = []
        self.in_queue: deque[bytes] = deque(self.stale_reports)
        self.config_count = [0] * N_CHANNELS

    # ---- test helpers ------------------------------------------------------------------------------
    def set_calibration(
        self, channel: int, slope: float, offset: float, range_code: int = RANGE_PM10V
    ) -> None:
        """Store a calibration pair in the board memory (float32 little-endian)."""
        addr = calibration_address(channel, range_code)
        self.memory[addr : addr + 8] = struct.pack("<ff", slope, offset)

    def calibration(self, channel: int, range_code: int = RANGE_PM10V) -> tuple[float, float]:
        addr = calibration_address(channel, range_code)
        slope, offset = struct.unpack_from("<ff", self.memory, addr)
        return float(slope), float(offset)

    def pin_volts(self, channel: int) -> float:
        """The voltage on the output pin: the DAC's ideal code `(code - offset)/slope`, in the range set."""
        rng = self.ranges[channel]
        if rng is None:
            return 0.0
        slope, offset = self.calibration(channel, rng)
        k = (self.codes[channel] - offset) / slope
        if rng == RANGE_PM10V:
            return (k - 32768.0) / 3276.8
        return k / 6553.6

    def reports_with_command(self, command: int) -> list[bytes]:
        return [r for r in self.reports if r and r[0] == command]

    # ---- the wire --------------------------------------------------------------------------------
    def handle_write(self, endpoint: int, data: bytes) -> None:
        if endpoint != 0x01 or not self.interrupt_out:
            raise Stall()
        self._report(data)

    def handle_control_out(self, setup: Setup, data: bytes) -> None:
        # HID SET_REPORT (output report): 0x21, 0x09, wValue = 0x0200 | report id, wIndex = interface
        if setup.request_type == 0x21 and setup.request == 0x09 and (setup.value >> 8) == 0x02:
            if not data or data[0] != (setup.value & 0xFF):
                self.bad_reports.append(bytes(data))
                return
            self._report(data)
            return
        raise Stall()

    def handle_read(self, endpoint: int, size: int) -> bytes | None:
        if endpoint != 0x81:
            raise Stall()
        if not self.in_queue:
            return None
        return self.in_queue.popleft()

    def _report(self, data: bytes) -> None:
        self.reports.append(bytes(data))
        if self.advance is not None:
            self.advance(self.report_time_s)
        cmd = data[0]
        if cmd == AOUT and len(data) >= 5:
            ch = data[1]
            if ch >= N_CHANNELS:
                self.bad_reports.append(bytes(data))
                return
            code = data[2] | (data[3] << 8)
            if data[4] == 0:
                self.codes[ch] = code
            else:
                self.held[ch] = code
        elif cmd == AOUT_SYNC:
            if self.sync_master:
                for ch, code in self.held.items():
                    self.codes[ch] = code
                self.held.clear()
        elif cmd == AOUT_CONFIG and len(data) >= 3:
            ch, rng = data[1], data[2]
            if ch >= N_CHANNELS or rng not in (RANGE_0_10V, RANGE_PM10V):
                self.bad_reports.append(bytes(data))
                return
            self.ranges[ch] = rng
            self.config_count[ch] += 1
            slope, offset = self.calibration(ch, rng)
            zero_k = 32768.0 if rng == RANGE_PM10V else 0.0
            self.codes[ch] = max(0, min(65535, round(slope * zero_k + offset)))  # drives the pin to 0 V
        elif cmd == MEM_READ and len(data) >= 5:
            addr = data[1] | (data[2] << 8)
            count = min(data[4], 62)
            self.in_queue.append(bytes([MEM_READ]) + bytes(self.memory[addr : addr + count]))
        elif cmd == BLINK_LED and len(data) >= 2:
            self.blinks += data[1]
        elif cmd == SET_SYNC and len(data) >= 2:
            self.sync_master = data[1] == 0
        elif cmd == GET_STATUS:
            self.in_queue.append(bytes([GET_STATUS, 1 if self.sync_master else 0]))
        elif cmd == RESET:
            self.resets += 1
        else:
            self.bad_reports.append(bytes(data))


def make_usb3105(
    serial: str = "01A2B3C4",
    *,
    faults: Faults | None = None,
    interrupt_out: bool = True,
    stale_reports: list[bytes] | None = None,
    bcd_device: int = Usb3105Model.IDENTITY.bcd_device,
    report_time_s: float = 0.0,
    advance: Callable[[float], None] | None = None,
) -> Usb3105Model:
    """A fake USB-3105 with ideal calibration (slope 1, offset 0) and the usbhid driver bound; each output
    report it receives calls `advance(report_time_s)` (e.g. a `ManualClock`'s: simulated time, no sleep)."""
    return Usb3105Model.make(
        serial,
        faults,
        bcd_device=bcd_device,
        interrupt_out=interrupt_out,
        stale_reports=list(stale_reports or []),
        report_time_s=report_time_s,
        advance=advance,
    )
