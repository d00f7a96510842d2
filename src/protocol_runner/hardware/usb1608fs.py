"""MCC USB-1608FS-Plus analog input over pyusb (satisfies `interfaces.AnalogInput`); `board_group.py` joins
several boards into one 24-channel (or wider) input, `usb1608fs_protocol.py` holds the USB protocol.

Sample times are not sent by the board: row ``i`` is at ``t0 + i / rate`` where ``rate`` is the rate the
pacer really runs at (40 MHz / (pacer + 1)) and ``t0`` the clock reading around AIN_SCAN_START.

UNVERIFIED on hardware: the calibration-memory address layout and that wValue carries the address.
"""

from __future__ import annotations

import logging
import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import numpy.typing as npt
import usb.core

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.conversions import ai16_code_to_volts
from protocol_runner.hardware.interfaces import Clock, ScanBlock
from protocol_runner.hardware.usb1608fs_protocol import (
    CMD_AIN_CLR_FIFO,
    CMD_AIN_CONFIG,
    CMD_AIN_SCAN_START,
    CMD_AIN_SCAN_STOP,
    CMD_BLINK_LED,
    CMD_CAL_MEMORY,
    CMD_SERIAL,
    CMD_STATUS,
    KIND,
    MAX_RATE_HZ,
    N_CHANNELS,
    N_RANGES,
    PACER_CLOCK_HZ,
    PRODUCT_ID,
    RANGE_PM10V,
    REQ_IN,
    REQ_OUT,
    STATUS_OVERRUN,
    pacer_period,
    pacer_rate_hz,
)
from protocol_runner.hardware.usb3105_calibration import parse_calibration
from protocol_runner.hardware.usb_board import InPipeSettings, OpenedBoard
from protocol_runner.hardware.usb_common import (
    MCC_VENDOR_ID,
    BoardTimeout,
    MonotonicClock,
    ScanOverrun,
    check_scan_channels,
    claim_interface,
    find_board,
    find_devices,
    map_usb_error,
    no_board,
    open_each,
    read_serial,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Usb1608FsSettings(InPipeSettings):
    """Transport settings of the USB-1608FS-Plus."""

    max_read_packets: int = 64
    """The most packets one bulk read asks for while a scan runs."""
    max_drain_packets: int = 1024
    """Draining after AIN_SCAN_STOP reads at most the FIFO's 64 KiB."""
    cal_address: int = 0x0000
    """Where the calibration memory starts (UNVERIFIED on hardware, as is its layout)."""
    scan_options: int = 0x00
    """AIN_SCAN_START options: block transfer mode, no trigger, stall on overrun."""


class Usb1608FsPlus(OpenedBoard[Usb1608FsSettings]):
    """An opened USB-1608FS-Plus. Use `Usb1608FsPlus.open(serial=None, backend=None, clock=None)`."""

    kind = KIND
    n_channels = N_CHANNELS
    channels_per_board = N_CHANNELS

    def __init__(
        self, device: usb.core.Device, serial: str, settings: Usb1608FsSettings, clock: Clock
    ) -> None:
        self._dev = device
        self._usb_serial = serial
        self.settings = settings
        self.clock = clock
        self.name = f"{KIND} serial {serial}"
        self._closed = False
        self._board_serial = serial
        # calibration[range][channel] = (slope, intercept)
        self.calibration: list[list[tuple[float, float]]] = [
            [(1.0, 0.0)] * N_CHANNELS for _ in range(N_RANGES)
        ]
        self.calibration_valid = False
        self._scanning = False
        self._channels: list[int] = []
        self._order: npt.NDArray[np.intp] = np.zeros(0, dtype=np.intp)
        self._rate_hz = 0.0
        self._t0 = 0.0
        self._rows_emitted = 0
        self._bytes_received = 0
        self._pending = bytearray()
        self._slope = np.ones(0)
        self._intercept = np.zeros(0)

    @classmethod
    def open(
        cls,
        serial: str | None = None,
        backend: Any | None = None,
        *,
        clock: Clock | None = None,
        settings: Usb1608FsSettings | None = None,
    ) -> Usb1608FsPlus:
        """Find the board (VID 0x09DB PID 0x00EA, optionally by serial), claim it, read its serial and
        calibration, and make sure no scan is left running. Errors are clear `HardwareUnavailable`s."""
        device, usb_serial = find_board(MCC_VENDOR_ID, PRODUCT_ID, serial, backend, KIND)
        return cls(device, usb_serial, settings or Usb1608FsSettings(), clock or MonotonicClock())._set_up()

    def _setup(self) -> None:
        claim_interface(self._dev, self.settings.interface, self.name)
        self._ctrl_out(CMD_AIN_SCAN_STOP, b"", "stopping a scan left running")
        self._ctrl_out(CMD_AIN_CLR_FIFO, b"", "clearing the scan FIFO")
        raw = bytes(self._ctrl_in(CMD_SERIAL, 0, 8, "reading the serial number"))
        self._board_serial = raw.rstrip(b"\x00 ").decode("ascii", errors="replace") or self._usb_serial
        self._read_calibration()

    def _read_calibration(self) -> None:
        n = N_RANGES * N_CHANNELS * 8
        mem = bytearray()
        while len(mem) < n:
            chunk = min(64, n - len(mem))
            addr = self.settings.cal_address + len(mem)
            mem += bytes(self._ctrl_in(CMD_CAL_MEMORY, addr, chunk, "reading calibration memory"))
        pairs = [parse_calibration(*p) for p in struct.iter_unpack("<ff", bytes(mem))]
        self.calibration = [
            [(c.slope, c.offset) for c in pairs[rng * N_CHANNELS : (rng + 1) * N_CHANNELS]]
            for rng in range(N_RANGES)
        ]
        self.calibration_valid = all(c.valid for c in pairs)
        if not self.calibration_valid:
            log.warning(
                "%s: calibration memory holds implausible values; using slope 1, intercept 0", self.name
            )

    def _ctrl_in(self, request: int, value: int, length: int, action: str) -> Any:
        return self._usb(
            action, self._dev.ctrl_transfer, REQ_IN, request, value, 0, length, self.settings.timeout_ms
        )

    def _ctrl_out(self, request: int, data: bytes, action: str) -> None:
        self._usb(action, self._dev.ctrl_transfer, REQ_OUT, request, 0, 0, data, self.settings.timeout_ms)

    def status(self) -> int:
        """STATUS word (bit 1 running, bit 2 overrun)."""
        raw = bytes(self._ctrl_in(CMD_STATUS, 0, 2, "reading the status"))
        return int.from_bytes(raw[:2].ljust(2, b"\x00"), "little")

    @property
    def serial(self) -> str:
        return self._board_serial

    def blink(self, count: int = 5) -> None:
        self._check_blink(count)
        self._ctrl_out(CMD_BLINK_LED, bytes((count,)), "blinking the LED")

    def calibration_summary(self) -> str:
        pairs = self.calibration[RANGE_PM10V]
        slopes = [p[0] for p in pairs]
        inter = [p[1] for p in pairs]
        state = "" if self.calibration_valid else " (memory implausible: slope 1, intercept 0 used)"
        return (
            f"+-10 V calibration: slope {min(slopes):.5f}..{max(slopes):.5f}, intercept "
            f"{min(inter):+.1f}..{max(inter):+.1f} counts{state}"
        )

    @property
    def resolution_bits(self) -> int:
        return 16

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        """Start a continuous hardware-paced scan of `channels` (0-7, any order) at `rate_hz` rows/s."""
        chans = check_scan_channels(KIND, channels, N_CHANNELS, rate_hz)
        if not PACER_CLOCK_HZ / 2**32 < rate_hz <= MAX_RATE_HZ:
            raise InvalidInput(f"{KIND}: scan rate must be between 0.01 Hz and 100 kHz; got {rate_hz!r}")
        if self._scanning:
            raise InvalidInput(f"the {self.name} is already scanning; stop_scan() first")
        pacer = pacer_period(rate_hz)
        ascending = sorted(chans)
        mask = 0
        for c in ascending:
            mask |= 1 << c
        self._channels = chans
        self._order = np.array([ascending.index(c) for c in chans], dtype=np.intp)
        cal = [self.calibration[RANGE_PM10V][c] for c in ascending]
        self._slope = np.array([c[0] for c in cal])
        self._intercept = np.array([c[1] for c in cal])
        self._rate_hz = pacer_rate_hz(pacer)
        self._pending = bytearray()
        self._bytes_received = 0
        self._rows_emitted = 0
        self._ctrl_out(CMD_AIN_SCAN_STOP, b"", "stopping a previous scan")
        self._ctrl_out(CMD_AIN_CLR_FIFO, b"", "clearing the scan FIFO")
        try:
            self._dev.clear_halt(self.settings.in_endpoint)
        except usb.core.USBError as exc:
            raise map_usb_error(exc, self.name, "clearing the data pipe") from exc
        self._ctrl_out(CMD_AIN_CONFIG, bytes([RANGE_PM10V] * N_CHANNELS), "setting the +-10 V input ranges")
        packet = struct.pack("<IIBB", 0, pacer, mask, self.settings.scan_options)
        before = self.clock.now_s()
        self._ctrl_out(CMD_AIN_SCAN_START, packet, "starting the scan")
        after = self.clock.now_s()
        self._t0 = 0.5 * (before + after)
        self._scanning = True

    def _sure_packets(self) -> int:
        """Full packets certainly produced by now, judged on the host clock with a safety margin.

        A bulk read asking for more than the board has waits for its timeout and then loses what it got
        (libusb reports a timeout, pyusb drops the partial data), so reads during a scan ask only for
        packets that must exist: the host clock's rows, less 200 ppm for crystal tolerance, less 2 ms
        for the start latency, less one packet of slack.
        """
        elapsed_s = self.clock.now_s() - self._t0
        rows = math.floor(elapsed_s * self._rate_hz * (1.0 - 200e-6) - 0.002 * self._rate_hz) + 1
        produced_bytes = max(0, rows) * 2 * len(self._channels)
        return produced_bytes // self.settings.packet_size - 1

    def _bulk_read(self, size: int, timeout_ms: int) -> bytes | None:
        """One bulk read; None on timeout; an overrun stall becomes `ScanOverrun`."""
        try:
            data = self._dev.read(self.settings.in_endpoint, size, timeout_ms)
        except usb.core.USBTimeoutError:
            return None
        except usb.core.USBError as exc:
            if getattr(exc, "errno", None) == 32:  # stalled pipe: the board stalls it on overrun
                self._raise_if_overrun()
            raise map_usb_error(exc, self.name, "reading scan data") from exc
        return bytes(data)

    def _read_packets(self) -> None:
        """Move the packets surely waiting on the bulk pipe into `_pending`, without ever blocking."""
        s = self.settings
        missing = self._sure_packets() - self._bytes_received // s.packet_size
        while missing > 0:
            n = min(missing, s.max_read_packets)
            data = self._bulk_read(n * s.packet_size, s.timeout_ms)
            if data is None:
                raise BoardTimeout(
                    f"the {self.name} sent less scan data than its pacer should have produced; the scan "
                    "stream is no longer trustworthy. Unplug and replug the board, then redo the trial."
                )
            self._pending += data
            self._bytes_received += len(data)
            missing -= n

    def _drain_packets(self) -> None:
        """After AIN_SCAN_STOP: read single packets until the pipe is empty (a short packet ends it)."""
        s = self.settings
        for _ in range(s.max_drain_packets):
            data = self._bulk_read(s.packet_size, s.drain_timeout_ms)
            if data is None:
                return
            self._pending += data
            self._bytes_received += len(data)
            if len(data) < s.packet_size:
                return

    def _raise_if_overrun(self) -> None:
        if self.status() & STATUS_OVERRUN:
            self._scanning = False
            raise ScanOverrun(
                f"the {self.name} scan overran its FIFO at {self._rate_hz:g} rows/s x "
                f"{len(self._channels)} channels: the computer did not read the data fast enough. "
                "Lower the input rate or the number of channels, or close other programs; the trial "
                "is marked failed and can be redone."
            )

    def _take_rows(self) -> ScanBlock:
        nch = len(self._channels)
        nrows = len(self._pending) // (2 * nch)
        if nrows == 0:
            return ScanBlock.empty(nch)
        nb = nrows * nch * 2
        raw = np.frombuffer(bytes(self._pending[:nb]), dtype="<u2").reshape(nrows, nch)
        del self._pending[:nb]
        corrected = np.rint(raw * self._slope + self._intercept)
        codes = np.clip(corrected, 0, 65535).astype(np.int32)[:, self._order]
        t_s = self._t0 + (self._rows_emitted + np.arange(nrows, dtype=np.float64)) / self._rate_hz
        self._rows_emitted += nrows
        return ScanBlock(t_s=t_s, codes=np.ascontiguousarray(codes), volts=ai16_code_to_volts(codes))

    def read_available(self) -> ScanBlock:
        """Every complete row received since the last call (calibrated codes, volts, times)."""
        if not self._scanning:
            return ScanBlock.empty(len(self._channels))
        self._read_packets()
        return self._take_rows()

    def stop_scan(self) -> ScanBlock:
        """Stop the scan, collect the rows still in flight, clear the FIFO."""
        if not self._scanning:
            return ScanBlock.empty(len(self._channels))
        self._read_packets()
        self._ctrl_out(CMD_AIN_SCAN_STOP, b"", "stopping the scan")
        self._drain_packets()
        self._scanning = False
        self._ctrl_out(CMD_AIN_CLR_FIFO, b"", "clearing the scan FIFO")
        return self._take_rows()

    def _before_release(self) -> None:
        if self._scanning:
            try:
                self._ctrl_out(CMD_AIN_SCAN_STOP, b"", "stopping the scan")
            except Exception:  # closing must not hide the original failure
                log.warning("%s: could not stop the scan while closing", self.name)
            self._scanning = False


def open_all_1608fs(
    serials: Sequence[str] | None = None,
    backend: Any | None = None,
    *,
    clock: Clock | None = None,
    settings: Usb1608FsSettings | None = None,
) -> list[Usb1608FsPlus]:
    """Open the boards with `serials` in that order, or every attached board sorted by serial number."""
    clock = clock or MonotonicClock()
    if serials is None:
        devices = find_devices(MCC_VENDOR_ID, PRODUCT_ID, backend, KIND)
        serials = sorted(read_serial(d, KIND) for d in devices)
        if not serials:
            raise no_board(KIND, f"VID 0x{MCC_VENDOR_ID:04X} PID 0x{PRODUCT_ID:04X}")
    return open_each(partial(Usb1608FsPlus.open, backend=backend, clock=clock, settings=settings), serials)
