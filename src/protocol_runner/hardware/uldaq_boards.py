"""`backend: uldaq`: the USB-3105 and the USB-1608FS-Plus through MCC's Universal Library for Linux and
macOS (the `uldaq` Python package over libuldaq), behind the same interfaces as the pyusb drivers.

Install: ``pip install protocol-runner[uldaq]`` and libuldaq itself (docs/hardware.md). The package is
imported only when a rig file selects this backend.

Calls made (uldaq's Python API):

- finding: ``get_daq_device_inventory(InterfaceType.USB)``, the descriptors whose ``product_id`` is the
  board's USB product id (0x9E USB-3105, 0xEA USB-1608FS-Plus), chosen by ``unique_id`` (the serial);
  ``DaqDevice(descriptor)``, ``connect()``; closing: ``disconnect()``, ``release()``.
- output: ``get_ao_device()``; ``get_config().set_sync_mode(AOutSyncMode.MASTER)`` when opening (so that
  a simultaneous update latches); ``a_out(ch, Range.BIP10VOLTS, AOutFlag.DEFAULT, volts)``; several
  channels: ``a_out_list(low, high, [Range.BIP10VOLTS] * n, AOutListFlag.SIMULTANEOUS, volts)`` per
  contiguous run.
- input: ``get_ai_device()``; ``create_float_buffer(width, rows)``; ``a_in_scan(low, high,
  AiInputMode.SINGLE_ENDED, Range.BIP10VOLTS, rows, rate, ScanOption.CONTINUOUS, AInScanFlag.DEFAULT,
  buffer)`` (returns the rate set); ``get_scan_status()`` -> (ScanStatus, TransferStatus) whose
  ``current_total_count`` counts the samples written into the circular buffer; ``scan_stop()``.

UNVERIFIED on hardware: tested only against a fake of this API (`tests/hardware/fake_uldaq.py`).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from types import ModuleType
from typing import Any

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import HardwareUnavailable
from protocol_runner.hardware import usb1608fs_protocol, usb3105
from protocol_runner.hardware.interfaces import Clock
from protocol_runner.hardware.usb_common import (
    BoardBusy,
    BoardIoError,
    BoardPermissionDenied,
    BoardTimeout,
    DeviceGone,
    MonotonicClock,
    ScanOverrun,
    open_each,
)
from protocol_runner.hardware.vendor_common import (
    VendorAnalogOutput,
    VendorScanInput,
    import_vendor,
    of_kind,
    pick,
)

BACKEND = "uldaq"
SCAN_BUFFER_S = 10.0
"""Seconds of scan data the circular buffer holds (the rig reads it every 100 ms)."""


def load_uldaq() -> ModuleType:
    """The `uldaq` package, or `VendorLibraryMissing` (exit 2) naming the extra to install."""
    return import_vendor("uldaq", BACKEND, "MCC's libuldaq")


def map_error(lib: ModuleType, exc: Exception, name: str, action: str) -> HardwareUnavailable | None:
    """A `uldaq.ULException` as the `HardwareUnavailable` the pyusb drivers raise for the same cause."""
    if not isinstance(exc, lib.ULException):
        return None
    code = getattr(exc, "error_code", None)
    text = f"the {name} failed while {action}: {getattr(exc, 'error_message', '') or exc} (uldaq {code!s})"
    errors = lib.ULError
    if code == errors.USB_DEV_NO_PERMISSION:
        return BoardPermissionDenied(f"{text}. Install MCC's udev rule for libuldaq (docs/hardware.md).")
    if code == errors.USB_INTERFACE_CLAIMED:
        return BoardBusy(f"{text}: another program is using it; close it and retry.")
    if code in (errors.DEV_NOT_FOUND, errors.DEV_NOT_CONNECTED, errors.DEAD_DEV):
        return DeviceGone(f"{text} (unplugged or powered off).")
    if code == errors.OVERRUN:
        return ScanOverrun(f"{text}: the computer did not read the data fast enough; lower the input rate.")
    if code == errors.TIMEDOUT:
        return BoardTimeout(f"{text}.")
    return BoardIoError(f"{text}.")


def find_descriptors(lib: ModuleType, product_id: int, kind: str) -> list[Any]:
    """The descriptors of every attached board of one kind, sorted by serial number."""
    try:
        return of_kind(lib.get_daq_device_inventory(lib.InterfaceType.USB), product_id)
    except lib.ULException as exc:
        raise map_error(lib, exc, f"{kind} search", "listing the boards") or exc from exc


def pick_descriptor(lib: ModuleType, product_id: int, kind: str, serial: str | None) -> Any:
    """The board with `serial` (or the first by serial number); `BoardNotFound` naming what was seen."""
    return pick(find_descriptors(lib, product_id, kind), serial, kind, "uldaq", "plugged in")


def connect(lib: ModuleType, descriptor: Any, name: str) -> Any:
    """A connected `DaqDevice` (released again when connecting fails)."""
    device = lib.DaqDevice(descriptor)
    try:
        device.connect()
    except lib.ULException as exc:
        device.release()
        raise map_error(lib, exc, name, "connecting") or exc from exc
    return device


def backend(lib: ModuleType, device: Any, name: str) -> dict[str, Any]:
    """A connected `DaqDevice`'s part of a `VendorBoard`: letting it go (disconnect, release), its errors,
    its LED."""

    def release() -> None:
        try:
            device.disconnect()
        finally:
            device.release()

    return {
        "release": release,
        "map_error": lambda exc, action: map_error(lib, exc, name, action),
        "flash_led": device.flash_led,
    }


class UldaqUsb3105(VendorAnalogOutput):
    """The USB-3105 through uldaq. Use `UldaqUsb3105.open(serial=None)`."""

    def __init__(self, lib: ModuleType, device: Any, serial: str) -> None:
        name = f"{usb3105.KIND} serial {serial} (uldaq)"
        super().__init__(name, serial, **backend(lib, device, name))
        self.lib = lib
        self.device = device
        self.ao = device.get_ao_device()

    @classmethod
    def open(cls, serial: str | None = None, *, lib: ModuleType | None = None) -> UldaqUsb3105:
        lib = lib or load_uldaq()
        descriptor = pick_descriptor(lib, usb3105.PRODUCT_ID, usb3105.KIND, serial)
        board = cls(lib, connect(lib, descriptor, usb3105.KIND), str(descriptor.unique_id))
        try:
            board._call(
                "making it the sync master",
                lambda: board.ao.get_config().set_sync_mode(lib.AOutSyncMode.MASTER),
            )
        except BaseException:
            board.close()
            raise
        return board

    def _write(self, channel: int, volts: float) -> None:
        self.ao.a_out(channel, self.lib.Range.BIP10VOLTS, self.lib.AOutFlag.DEFAULT, volts)

    def _write_run(self, low: int, volts: Sequence[float]) -> None:
        n = len(volts)
        ranges = [self.lib.Range.BIP10VOLTS] * n
        self.ao.a_out_list(low, low + n - 1, ranges, self.lib.AOutListFlag.SIMULTANEOUS, list(volts))


class UldaqUsb1608Fs(VendorScanInput):
    """One USB-1608FS-Plus through uldaq. Use `UldaqUsb1608Fs.open(serial=None, clock=None)`;
    `open_all_uldaq_1608fs` opens several for `BoardGroup`."""

    def __init__(self, lib: ModuleType, device: Any, serial: str, clock: Clock, buffer_s: float) -> None:
        name = f"{usb1608fs_protocol.KIND} serial {serial} (uldaq)"
        super().__init__(name, serial, clock, buffer_s, **backend(lib, device, name))
        self.lib = lib
        self.device = device
        self.ai = device.get_ai_device()
        self._buffer: Any = None

    @classmethod
    def open(
        cls,
        serial: str | None = None,
        *,
        clock: Clock | None = None,
        lib: ModuleType | None = None,
        buffer_s: float = SCAN_BUFFER_S,
    ) -> UldaqUsb1608Fs:
        lib = lib or load_uldaq()
        descriptor = pick_descriptor(lib, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND, serial)
        device = connect(lib, descriptor, usb1608fs_protocol.KIND)
        return cls(lib, device, str(descriptor.unique_id), clock or MonotonicClock(), buffer_s)

    def _start_scan(self, low: int, high: int, rows: int, rate_hz: float) -> float:
        lib = self.lib
        self._buffer = lib.create_float_buffer(high - low + 1, rows)
        return float(
            self.ai.a_in_scan(
                low,
                high,
                lib.AiInputMode.SINGLE_ENDED,
                lib.Range.BIP10VOLTS,
                rows,
                rate_hz,
                lib.ScanOption.CONTINUOUS,
                lib.AInScanFlag.DEFAULT,
                self._buffer,
            )
        )

    def _scan_status(self) -> tuple[bool, int]:
        status, transfer = self.ai.get_scan_status()
        return status == self.lib.ScanStatus.RUNNING, int(transfer.current_total_count)

    def _stop(self) -> None:
        self.ai.scan_stop()

    def _copy(self, first: int, count: int) -> npt.NDArray[np.float64]:
        return np.array(self._buffer[first : first + count], dtype=np.float64)

    def _free_buffer(self) -> None:
        self._buffer = None  # a ctypes array: Python frees it


def open_all_uldaq_1608fs(
    serials: Sequence[str] | None = None, *, clock: Clock | None = None, lib: ModuleType | None = None
) -> list[UldaqUsb1608Fs]:
    """The boards with `serials` in that order, or every attached one sorted by serial number."""
    lib = lib or load_uldaq()
    clock = clock or MonotonicClock()
    if not serials:
        serials = [
            str(d.unique_id)
            for d in find_descriptors(lib, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND)
        ]
        if not serials:
            pick_descriptor(lib, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND, None)  # not found
    return open_each(partial(UldaqUsb1608Fs.open, clock=clock, lib=lib), serials)
