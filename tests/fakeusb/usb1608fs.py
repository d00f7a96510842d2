"""Byte-level model of the MCC USB-1608FS-Plus (8 x 16-bit analog inputs, hardware-paced scans).

Vendor control requests (0xC0 in / 0x40 out) configure and start scans; the samples leave through bulk
IN 0x81 in 64-byte packets of little-endian u16 codes, rows in ascending channel order. Samples are
produced lazily from `signal(time_s, channel) -> volts` at the pacer rate on the model's clock; when the
host leaves more than `fifo_samples` unread the scan overruns: STATUS bit 2 is set, the scan stops and the
bulk pipe stalls (errno 32) until `clear_halt`.

The ADC has a gain/offset error that the calibration memory corrects: the raw code is chosen so that
``raw * slope + intercept`` is the ideal code ``32768 + V * 3276.8`` (rounded, clamped).
"""

from __future__ import annotations

import math
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from tests.fakeusb.descriptors import ENDPOINT_BULK, UsbIdentity, single_interface
from tests.fakeusb.device import FakeUsbDevice, Faults, Setup, Stall

N_CHANNELS = 8
N_RANGES = 8
PACKET = 64
FIFO_SAMPLES = 32768
PACER_HZ = 40_000_000.0

AIN = 0x10
AIN_SCAN_START = 0x11
AIN_SCAN_STOP = 0x12
AIN_CONFIG = 0x14
AIN_CLR_FIFO = 0x15
CAL_MEMORY = 0x30
BLINK_LED = 0x41
RESET = 0x42
STATUS = 0x44
SERIAL = 0x48

STATUS_RUNNING = 0x02
STATUS_OVERRUN = 0x04

Signal = Callable[[Any, int], Any]
"""`signal(time_s, channel) -> volts`. Called with a float64 array of sample times (the result is broadcast to
it); a function that only takes floats is called once per sample instead."""


def cal_address(channel: int, range_code: int) -> int:
    """Address of the (slope, intercept) float32 pair: ranges outer, channels inner, 8 bytes each."""
    return (range_code * N_CHANNELS + channel) * 8


def zero_signal(time_s: float, channel: int) -> float:
    return 0.0


@dataclass(eq=False)
class Usb1608FsModel(FakeUsbDevice):
    """A fake USB-1608FS-Plus. `clock` is the model's time source (seconds); tests pass a manual one."""

    IDENTITY: ClassVar[UsbIdentity] = UsbIdentity(0x09DB, 0x00EA, 0x0103, "MCC", "USB-1608FS-Plus")

    signal: Signal = zero_signal
    clock: Callable[[], float] = time.monotonic
    fifo_samples: int = FIFO_SAMPLES

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.interfaces:
            self.interfaces = single_interface(0xFF, ENDPOINT_BULK, (0x81,), PACKET)
        self.memory = bytearray(0x400)
        for rng in range(N_RANGES):
            for ch in range(N_CHANNELS):
                self.set_calibration(ch, 1.0, 0.0, rng)
        self.ranges = [0] * N_CHANNELS
        self.running = False
        self.overrun = False
        self.blinks = 0
        self.scan_channels: list[int] = []
        self.scan_count = 0
        self.pacer = 0
        self.options = 0
        self.t0 = 0.0
        self.rate_hz = 0.0
        self.sent_samples = 0
        self.scan_starts = 0
        self.end_samples: int | None = None  # samples produced when the scan stopped
        self.lost_samples = 0  # consumed by reads that timed out (a driver bug if ever non-zero)

    # ---- helpers ---------------------------------------------------------------------------------
    def set_calibration(self, channel: int, slope: float, intercept: float, range_code: int = 0) -> None:
        addr = cal_address(channel, range_code)
        self.memory[addr : addr + 8] = struct.pack("<ff", slope, intercept)

    def calibration(self, channel: int, range_code: int = 0) -> tuple[float, float]:
        s, i = struct.unpack_from("<ff", self.memory, cal_address(channel, range_code))
        return float(s), float(i)

    def raw_code(self, volts: float, channel: int) -> int:
        """The uncalibrated code the ADC returns for `volts` (+-10 V range)."""
        ideal = 32768.0 + volts * 3276.8
        slope, intercept = self.calibration(channel, self.ranges[channel])
        raw = round((ideal - intercept) / slope)
        return max(0, min(65535, raw))

    def _produced_samples(self) -> int:
        if not self.scan_channels:
            return 0
        rows = math.floor((self.clock() - self.t0) * self.rate_hz + 1e-9) + 1
        if self.scan_count:
            rows = min(rows, self.scan_count)
        return max(0, rows) * len(self.scan_channels)

    def _advance(self) -> None:
        """Bring the FIFO up to the clock; flag an overrun when it would hold too many samples."""
        if not self.running:
            return
        produced = self._produced_samples()
        if produced - self.sent_samples > self.fifo_samples:
            self.overrun = True
            self.running = False
            self.halted.add(0x81)
            self.end_samples = self.sent_samples + self.fifo_samples
        elif self.scan_count and produced >= self.scan_count * len(self.scan_channels):
            self.running = False
            self.end_samples = produced

    def _available_samples(self) -> int:
        if self.running:
            return self._produced_samples() - self.sent_samples
        end = self.end_samples if self.end_samples is not None else self.sent_samples
        return max(0, end - self.sent_samples)

    def _sample_bytes(self, first: int, n: int) -> bytes:
        """Samples `first` .. `first + n - 1` of the scan as LE u16 raw codes (vectorised per channel)."""
        nch = len(self.scan_channels)
        idx = np.arange(first, first + n)
        rows, cols = np.divmod(idx, nch)
        codes = np.empty(n, dtype=np.float64)
        for col, ch in enumerate(self.scan_channels):
            sel = cols == col
            if not sel.any():
                continue
            t = self.t0 + rows[sel] / self.rate_hz
            try:
                volts = np.broadcast_to(np.asarray(self.signal(t, ch), dtype=np.float64), t.shape)
            except (TypeError, ValueError):  # a scalar-only signal function
                volts = np.array([self.signal(float(x), ch) for x in t], dtype=np.float64)
            slope, intercept = self.calibration(ch, self.ranges[ch])
            codes[sel] = np.rint((32768.0 + volts * 3276.8 - intercept) / slope)
        return np.clip(codes, 0, 65535).astype("<u2").tobytes()

    # ---- the wire --------------------------------------------------------------------------------
    def handle_control_in(self, setup: Setup, length: int) -> bytes:
        if setup.request_type != 0xC0:
            raise Stall()
        request, value = setup.request, setup.value
        if request == STATUS:
            self._advance()
            status = (STATUS_RUNNING if self.running else 0) | (STATUS_OVERRUN if self.overrun else 0)
            return struct.pack("<H", status)
        if request == SERIAL:
            return self.serial.encode("ascii")[:8].ljust(8, b"\x00")
        if request == CAL_MEMORY:
            return bytes(self.memory[value : value + length])
        if request == AIN_CONFIG:
            return bytes(self.ranges)
        if request == AIN:
            if self.running:
                raise Stall()
            ch = value
            return struct.pack("<H", self.raw_code(self.signal(self.clock(), ch), ch))
        raise Stall()

    def handle_control_out(self, setup: Setup, data: bytes) -> None:
        if setup.request_type != 0x40:
            raise Stall()
        request = setup.request
        if request == AIN_CONFIG:
            if self.running or len(data) != N_CHANNELS or any(r >= N_RANGES for r in data):
                raise Stall()
            self.ranges = list(data)
        elif request == AIN_SCAN_START:
            if self.running or len(data) != 10:
                raise Stall()
            count, pacer, mask, options = struct.unpack("<IIBB", data)
            if mask == 0 or pacer == 0:
                raise Stall()
            self.scan_count, self.pacer, self.options = count, pacer, options
            self.scan_channels = [ch for ch in range(N_CHANNELS) if mask & (1 << ch)]
            self.rate_hz = PACER_HZ / (pacer + 1)
            self.t0 = self.clock()
            self.sent_samples = 0
            self.overrun = False
            self.running = True
            self.scan_starts += 1
            self.end_samples = None
        elif request == AIN_SCAN_STOP:
            self._advance()
            if self.running:
                self.end_samples = self._produced_samples()
                self.running = False
        elif request == AIN_CLR_FIFO:
            self.end_samples = self.sent_samples
        elif request == BLINK_LED:
            self.blinks += data[0] if data else 1
        elif request == RESET:
            pass
        else:
            raise Stall()

    def handle_read(self, endpoint: int, size: int) -> bytes | None:
        """Bulk IN like libusb sees it: a read completes when `size` bytes or a short packet arrived; a
        read asking for more full packets than the board has while scanning times out, and the packets
        it had received are lost (libusb reports the timeout; pyusb drops the partial data)."""
        if endpoint != 0x81:
            raise Stall()
        self._advance()
        if 0x81 in self.halted:
            raise Stall()
        avail_bytes = 2 * self._available_samples()
        wanted_packets = max(1, size // PACKET)
        full_packets = avail_bytes // PACKET
        if full_packets >= wanted_packets:
            n_bytes = wanted_packets * PACKET
        elif self.running:
            if full_packets:
                self.lost_samples += full_packets * PACKET // 2
                self.sent_samples += full_packets * PACKET // 2
            return None
        elif avail_bytes:
            n_bytes = min(avail_bytes, full_packets * PACKET if full_packets else avail_bytes)
        else:
            return None
        n = n_bytes // 2
        data = self._sample_bytes(self.sent_samples, n)
        self.sent_samples += n
        return data


@dataclass
class ManualClock:
    """A clock for tests: time moves only when told."""

    t_s: float = 0.0

    def __call__(self) -> float:
        return self.t_s

    def advance(self, dt_s: float) -> None:
        self.t_s += dt_s


def make_usb1608fs(
    serial: str = "01D2E3F4",
    *,
    signal: Signal = zero_signal,
    clock: Callable[[], float] = time.monotonic,
    faults: Faults | None = None,
    fifo_samples: int = FIFO_SAMPLES,
) -> Usb1608FsModel:
    """A fake USB-1608FS-Plus with ideal calibration (slope 1, intercept 0)."""
    return Usb1608FsModel.make(serial, faults, signal=signal, clock=clock, fifo_samples=fifo_samples)
