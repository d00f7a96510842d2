"""`backend: mcculw`: the USB-3105 and the USB-1608FS-Plus through MCC's Universal Library for Windows
(the `mcculw` Python package over cbw64.dll, installed with InstaCal / MCC DAQ software), behind the same
interfaces as the pyusb drivers.

Install: ``pip install protocol-runner[mcculw]`` and MCC's DAQ software (docs/hardware.md). The package is
imported only when a rig file selects this backend.

Calls made (mcculw's Python API, `mcculw.ul` and `mcculw.enums`):

- finding: ``ul.ignore_instacal()`` once (boards are found by the program, not InstaCal's cb.cfg);
  ``ul.get_daq_device_inventory(InterfaceType.USB)``, the descriptors whose ``product_id`` is the
  board's (0x9E USB-3105, 0xEA USB-1608FS-Plus), chosen by ``unique_id`` (the serial);
  ``ul.create_daq_device(board_num, descriptor)``; closing: ``ul.release_daq_device(board_num)``.
- output: ``ul.set_config(InfoType.BOARDINFO, board_num, 0, BoardInfo.SYNCMODE, 0)`` when opening
  (0 = sync master, so that a simultaneous update latches); ``ul.from_eng_units(board_num,
  ULRange.BIP10VOLTS, volts)`` -> code, ``ul.a_out(board_num, ch, ULRange.BIP10VOLTS, code)``; several
  channels, per contiguous run: ``ul.win_buf_alloc(n)``, ``ul.win_array_to_buf(codes, memhandle, 0, n)``,
  ``ul.a_out_scan(board_num, low, high, n, rate, ULRange.BIP10VOLTS, memhandle,
  ScanOptions.SIMULTANEOUS)``, ``ul.win_buf_free(memhandle)``.
- input: ``ul.scaled_win_buf_alloc(rows * width)``; ``ul.a_in_scan(board_num, low, high, rows * width,
  rate, ULRange.BIP10VOLTS, memhandle, ScanOptions.BACKGROUND | CONTINUOUS | SCALEDATA)`` (returns the
  rate set; the UL takes an integer rate); ``ul.get_status(board_num, FunctionType.AIFUNCTION)`` ->
  (status, cur_count, cur_index), ``cur_index`` being the start of the last complete row in the
  circular buffer; ``ul.scaled_win_buf_to_array(memhandle, array, first, count)``;
  ``ul.stop_background(board_num, FunctionType.AIFUNCTION)``; ``ul.win_buf_free(memhandle)``.

The UL's ``cur_count`` behaves differently from board to board in a continuous scan, so the samples are
counted from ``cur_index``'s progress; a read later than one buffer (10 s by the host clock) cannot be
counted and is a `ScanOverrun`.

UNVERIFIED on hardware: tested only against a fake of this API (`tests/hardware/fake_mcculw.py`).
"""

from __future__ import annotations

import ctypes
import importlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import HardwareUnavailable
from protocol_runner.hardware import usb1608fs_protocol, usb3105
from protocol_runner.hardware.interfaces import Clock
from protocol_runner.hardware.usb_common import (
    BoardIoError,
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

BACKEND = "mcculw"
SCAN_BUFFER_S = 10.0
"""Seconds of scan data the circular buffer holds (the rig reads it every 100 ms)."""
SIMULTANEOUS_RATE = 100
"""The rate passed to a simultaneous `a_out_scan`; software-paced boards ignore it (UL documentation)."""
SYNC_MASTER = 0
"""BoardInfo.SYNCMODE: 0 = master, 1 = slave (UL documentation)."""


@dataclass
class McculwApi:
    """The two modules of mcculw these backends use, and which board numbers this process has taken."""

    ul: Any
    enums: Any
    board_nums: set[int] = field(default_factory=set)
    instacal_ignored: bool = False

    def take_board_num(self) -> int:
        num = next(n for n in range(len(self.board_nums) + 1) if n not in self.board_nums)
        self.board_nums.add(num)
        return num


_APIS: dict[int, McculwApi] = {}  # per `mcculw.ul` module: the board numbers are the process's


def load_mcculw() -> McculwApi:
    """The `mcculw` package, or `VendorLibraryMissing` (exit 2) naming the extra to install."""
    ul = import_vendor("mcculw.ul", BACKEND, "MCC's Universal Library (cbw64.dll, installed with InstaCal)")
    api = _APIS.get(id(ul))
    if api is None or api.ul is not ul:
        api = _APIS[id(ul)] = McculwApi(ul=ul, enums=importlib.import_module("mcculw.enums"))
    return api


def map_error(api: McculwApi, exc: Exception, name: str, action: str) -> HardwareUnavailable | None:
    """A `mcculw.ul.ULError` as a `BoardIoError` carrying the UL's own message."""
    if not isinstance(exc, api.ul.ULError):
        return None
    code = getattr(exc, "errorcode", "?")
    message = getattr(exc, "message", "") or str(exc)
    return BoardIoError(f"the {name} failed while {action}: {message} (Universal Library error {code}).")


def _mapped(api: McculwApi, exc: Exception, name: str, action: str) -> BaseException:
    return map_error(api, exc, name, action) or exc


def _inventory(api: McculwApi, product_id: int, kind: str) -> list[Any]:
    """The descriptors of every attached board of one kind, sorted by serial number."""
    ul, enums = api.ul, api.enums
    try:
        if not api.instacal_ignored:
            ul.ignore_instacal()
            api.instacal_ignored = True
        return of_kind(ul.get_daq_device_inventory(enums.InterfaceType.USB), product_id)
    except Exception as exc:
        raise _mapped(api, exc, f"{kind} search", "listing the boards") from exc


def create_board(api: McculwApi, product_id: int, kind: str, serial: str | None) -> tuple[int, str]:
    """Find the board with `serial` (or the first by serial number) and add it to the UL: (board number,
    serial). `BoardNotFound` names the serials seen."""
    hint = "plugged in and its driver installed (InstaCal lists it)"
    descriptor = pick(_inventory(api, product_id, kind), serial, kind, "the Universal Library", hint)
    num = api.take_board_num()
    try:
        api.ul.create_daq_device(num, descriptor)
    except Exception as exc:
        api.board_nums.discard(num)
        raise _mapped(api, exc, kind, "adding it to the Universal Library") from exc
    return num, str(descriptor.unique_id)


def backend(api: McculwApi, board_num: int, name: str) -> dict[str, Any]:
    """A board added to the UL's part of a `VendorBoard`: releasing it, its errors, its LED (the UL's
    flash_led takes no count)."""

    def release() -> None:
        try:
            api.ul.release_daq_device(board_num)
        finally:
            api.board_nums.discard(board_num)

    return {
        "release": release,
        "map_error": lambda exc, action: map_error(api, exc, name, action),
        "flash_led": lambda _count: api.ul.flash_led(board_num),
    }


class McculwUsb3105(VendorAnalogOutput):
    """The USB-3105 through mcculw. Use `McculwUsb3105.open(serial=None)`."""

    def __init__(self, api: McculwApi, board_num: int, serial: str) -> None:
        name = f"{usb3105.KIND} serial {serial} (mcculw board {board_num})"
        super().__init__(name, serial, **backend(api, board_num, name))
        self.api = api
        self.board_num = board_num

    @classmethod
    def open(cls, serial: str | None = None, *, api: McculwApi | None = None) -> McculwUsb3105:
        api = api or load_mcculw()
        num, board_serial = create_board(api, usb3105.PRODUCT_ID, usb3105.KIND, serial)
        board = cls(api, num, board_serial)
        enums = api.enums
        try:
            board._call(
                "making it the sync master",
                lambda: api.ul.set_config(
                    enums.InfoType.BOARDINFO, num, 0, enums.BoardInfo.SYNCMODE, SYNC_MASTER
                ),
            )
        except BaseException:
            board.close()
            raise
        return board

    def _code(self, volts: float) -> int:
        return int(self.api.ul.from_eng_units(self.board_num, self.api.enums.ULRange.BIP10VOLTS, volts))

    def _write(self, channel: int, volts: float) -> None:
        bip10 = self.api.enums.ULRange.BIP10VOLTS
        self.api.ul.a_out(self.board_num, channel, bip10, self._code(volts))

    def _write_run(self, low: int, volts: Sequence[float]) -> None:
        ul, enums = self.api.ul, self.api.enums
        n = len(volts)
        codes = (ctypes.c_ushort * n)(*(self._code(v) for v in volts))
        memhandle = ul.win_buf_alloc(n)
        if not memhandle:
            raise BoardIoError(f"the {self.name}: the Universal Library could not allocate {n} output values")
        try:
            ul.win_array_to_buf(codes, memhandle, 0, n)
            ul.a_out_scan(
                self.board_num,
                low,
                low + n - 1,
                n,
                SIMULTANEOUS_RATE,
                enums.ULRange.BIP10VOLTS,
                memhandle,
                enums.ScanOptions.SIMULTANEOUS,
            )
        finally:
            ul.win_buf_free(memhandle)


class McculwUsb1608Fs(VendorScanInput):
    """One USB-1608FS-Plus through mcculw. Use `McculwUsb1608Fs.open(serial=None, clock=None)`;
    `open_all_mcculw_1608fs` opens several for `BoardGroup`."""

    status_after_stop = False  # stop_background clears the UL's scan variables

    def __init__(self, api: McculwApi, board_num: int, serial: str, clock: Clock, buffer_s: float) -> None:
        name = f"{usb1608fs_protocol.KIND} serial {serial} (mcculw board {board_num})"
        super().__init__(name, serial, clock, buffer_s, **backend(api, board_num, name))
        self.api = api
        self.board_num = board_num
        self._memhandle: Any = None
        self._size = 0
        self._width = 0
        self._total = 0
        self._last_end = 0
        self._last_status_s = 0.0

    @classmethod
    def open(
        cls,
        serial: str | None = None,
        *,
        clock: Clock | None = None,
        api: McculwApi | None = None,
        buffer_s: float = SCAN_BUFFER_S,
    ) -> McculwUsb1608Fs:
        api = api or load_mcculw()
        num, board_serial = create_board(api, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND, serial)
        return cls(api, num, board_serial, clock or MonotonicClock(), buffer_s)

    def _start_scan(self, low: int, high: int, rows: int, rate_hz: float) -> float:
        ul, enums = self.api.ul, self.api.enums
        self._width = high - low + 1
        self._size = rows * self._width
        self._memhandle = ul.scaled_win_buf_alloc(self._size)
        if not self._memhandle:
            raise BoardIoError(f"the {self.name}: the Universal Library could not allocate the scan buffer")
        self._total = 0
        self._last_end = 0
        options = enums.ScanOptions.BACKGROUND | enums.ScanOptions.CONTINUOUS | enums.ScanOptions.SCALEDATA
        rate = ul.a_in_scan(
            self.board_num,
            low,
            high,
            self._size,
            round(rate_hz),
            enums.ULRange.BIP10VOLTS,
            self._memhandle,
            options,
        )
        self._last_status_s = self.clock.now_s()
        return float(rate)

    def _scan_status(self) -> tuple[bool, int]:
        ul, enums = self.api.ul, self.api.enums
        status, _count, index = ul.get_status(self.board_num, enums.FunctionType.AIFUNCTION)
        now_s = self.clock.now_s()
        if (now_s - self._last_status_s) * self._rate_hz * self._width >= self._size:
            raise ScanOverrun(
                f"the {self.name} scan was not read for {now_s - self._last_status_s:.1f} s, longer than its "
                f"{self.buffer_s:g} s buffer: rows were overwritten before they were read. Close other programs; "
                "the trial is marked failed and can be redone."
            )
        self._last_status_s = now_s
        end = index + self._width if index >= 0 else 0  # the end of the last complete row
        self._total += (end - self._last_end) % self._size
        self._last_end = end % self._size
        return status == enums.Status.RUNNING, self._total

    def _stop(self) -> None:
        self.api.ul.stop_background(self.board_num, self.api.enums.FunctionType.AIFUNCTION)

    def _copy(self, first: int, count: int) -> npt.NDArray[np.float64]:
        values = (ctypes.c_double * count)()
        self.api.ul.scaled_win_buf_to_array(self._memhandle, values, first, count)
        return np.array(values, dtype=np.float64)

    def _free_buffer(self) -> None:
        if self._memhandle:
            handle, self._memhandle = self._memhandle, None
            self.api.ul.win_buf_free(handle)


def open_all_mcculw_1608fs(
    serials: Sequence[str] | None = None, *, clock: Clock | None = None, api: McculwApi | None = None
) -> list[McculwUsb1608Fs]:
    """The boards with `serials` in that order, or every attached one sorted by serial number."""
    api = api or load_mcculw()
    clock = clock or MonotonicClock()
    if not serials:
        found = _inventory(api, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND)
        serials = [str(d.unique_id) for d in found]
    if not serials:
        create_board(api, usb1608fs_protocol.PRODUCT_ID, usb1608fs_protocol.KIND, None)  # raises not found
    return open_each(partial(McculwUsb1608Fs.open, clock=clock, api=api), serials)
