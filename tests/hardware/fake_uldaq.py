"""A fake of the `uldaq` Python API (MCC's Universal Library for Linux) for the uldaq backend's tests.

`make_fake_uldaq(boards, clock)` returns a module-like object with the names `uldaq_boards.py` uses: the
enums (the values of uldaq's `ul_enums`), `ULException`, `create_float_buffer` (a real ctypes double
array, as uldaq's), `get_daq_device_inventory`, `DaqDevice`. Every call is recorded in ``lib.calls`` as a
tuple ``(name, serial, *arguments)``. An input board's continuous scan writes ``signal(t, channel)`` into
the caller's buffer at position ``k mod len(buffer)`` for sample ``k`` when `get_scan_status` is called,
for every row the pacer (at the rate asked) has produced by ``clock.now_s()``. `fail` makes a named call
raise a `ULException` with the given code.
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from types import SimpleNamespace
from typing import Any


class ULError(IntEnum):
    NO_ERROR = 0
    USB_DEV_NO_PERMISSION = 4
    USB_INTERFACE_CLAIMED = 5
    DEV_NOT_FOUND = 6
    DEV_NOT_CONNECTED = 7
    DEAD_DEV = 8
    OVERRUN = 18
    TIMEDOUT = 20


class InterfaceType(IntEnum):
    USB = 1 << 0
    BLUETOOTH = 1 << 1
    ETHERNET = 1 << 2
    ANY = USB | BLUETOOTH | ETHERNET


class AiInputMode(IntEnum):
    DIFFERENTIAL = 1
    SINGLE_ENDED = 2


class AInScanFlag(IntEnum):
    DEFAULT = 0
    NOSCALEDATA = 1 << 0
    NOCALIBRATEDATA = 1 << 1


class Range(IntEnum):
    BIP10VOLTS = 5
    UNI10VOLTS = 1005


class ScanOption(IntEnum):
    DEFAULTIO = 0
    SINGLEIO = 1 << 0
    BLOCKIO = 1 << 1
    BURSTIO = 1 << 2
    CONTINUOUS = 1 << 3


class ScanStatus(IntEnum):
    IDLE = 0
    RUNNING = 1


class AOutFlag(IntEnum):
    DEFAULT = 0
    NOSCALEDATA = 1 << 0
    NOCALIBRATEDATA = 1 << 1


class AOutListFlag(IntEnum):
    DEFAULT = 0
    NOSCALEDATA = 1 << 0
    NOCALIBRATEDATA = 1 << 1
    SIMULTANEOUS = 1 << 2


class AOutSyncMode(IntEnum):
    SLAVE = 0
    MASTER = 1


class ULException(Exception):
    def __init__(self, error_code: int) -> None:
        super().__init__(error_code)
        self.error_code = ULError(error_code)
        self.error_message = f"fake uldaq error {self.error_code.name}"


def create_float_buffer(number_of_channels: int, samples_per_channel: int) -> Any:
    return (ctypes.c_double * (number_of_channels * samples_per_channel))()


@dataclass
class FakeBoard:
    """One attached board: its USB product id and serial; an input board's signal per channel (volts)."""

    product_id: int
    serial: str
    signal: Callable[[float, int], float] = lambda t, ch: 0.0
    pins: dict[int, float] = field(default_factory=dict)  # output: the volts on each pin
    sync_mode: int = AOutSyncMode.SLAVE


def aout_board(serial: str = "AO000001") -> FakeBoard:
    return FakeBoard(0x9E, serial)


def ain_board(serial: str, signal: Callable[[float, int], float] = lambda t, ch: 0.0) -> FakeBoard:
    return FakeBoard(0xEA, serial, signal)


class TransferStatus(SimpleNamespace):
    current_scan_count: int
    current_total_count: int
    current_index: int


class FakeLib(SimpleNamespace):
    """The module-like object handed to the backend (or put into ``sys.modules['uldaq']``)."""

    def __init__(self, boards: list[FakeBoard], clock: Any) -> None:
        super().__init__(
            ULError=ULError,
            InterfaceType=InterfaceType,
            AiInputMode=AiInputMode,
            AInScanFlag=AInScanFlag,
            Range=Range,
            ScanOption=ScanOption,
            ScanStatus=ScanStatus,
            AOutFlag=AOutFlag,
            AOutListFlag=AOutListFlag,
            AOutSyncMode=AOutSyncMode,
            ULException=ULException,
            create_float_buffer=create_float_buffer,
        )
        self.boards = boards
        self.clock = clock
        self.calls: list[tuple[Any, ...]] = []
        self.failures: dict[str, int] = {}
        self.DaqDevice = lambda descriptor: FakeDaqDevice(self, descriptor)

    def fail(self, call: str, code: ULError) -> None:
        """Make every later call named `call` raise ULException(code)."""
        self.failures[call] = code

    def record(self, name: str, serial: str, *args: Any) -> None:
        self.calls.append((name, serial, *args))
        if name in self.failures:
            raise ULException(self.failures[name])

    def names(self, serial: str | None = None) -> list[str]:
        return [c[0] for c in self.calls if serial is None or c[1] == serial]

    def get_daq_device_inventory(self, interface_type: int, number_of_devices: int = 100) -> list[Any]:
        self.record("get_daq_device_inventory", "", interface_type)
        return [
            SimpleNamespace(product_name="fake", product_id=b.product_id, unique_id=b.serial, dev_interface=1)
            for b in self.boards[:number_of_devices]
        ]


class FakeDaqDevice:
    def __init__(self, lib: FakeLib, descriptor: Any) -> None:
        self.lib = lib
        self.board = next(b for b in lib.boards if b.serial == descriptor.unique_id)
        lib.record("DaqDevice", self.board.serial)
        self.ao = FakeAo(lib, self.board) if self.board.product_id == 0x9E else None
        self.ai = FakeAi(lib, self.board) if self.board.product_id == 0xEA else None

    def connect(self) -> None:
        self.lib.record("connect", self.board.serial)

    def disconnect(self) -> None:
        self.lib.record("disconnect", self.board.serial)

    def release(self) -> None:
        self.lib.record("release", self.board.serial)

    def flash_led(self, number_of_flashes: int) -> None:
        self.lib.record("flash_led", self.board.serial, number_of_flashes)

    def get_ao_device(self) -> FakeAo | None:
        return self.ao

    def get_ai_device(self) -> FakeAi | None:
        return self.ai


class FakeAo:
    def __init__(self, lib: FakeLib, board: FakeBoard) -> None:
        self.lib, self.board = lib, board

    def get_config(self) -> Any:
        def set_sync_mode(mode: int) -> None:
            self.lib.record("set_sync_mode", self.board.serial, mode)
            self.board.sync_mode = mode

        return SimpleNamespace(set_sync_mode=set_sync_mode)

    def a_out(self, channel: int, analog_range: int, flags: int, data: float) -> None:
        self.lib.record("a_out", self.board.serial, channel, analog_range, flags, data)
        self.board.pins[channel] = data

    def a_out_list(
        self, low_chan: int, high_chan: int, ranges: list[int], flags: int, data: list[float]
    ) -> None:
        self.lib.record("a_out_list", self.board.serial, low_chan, high_chan, list(ranges), flags, list(data))
        if len(ranges) != high_chan - low_chan + 1 or len(data) != len(ranges):
            raise ULException(45)  # BAD_ARG, as uldaq's a_out_list checks
        if flags & AOutListFlag.SIMULTANEOUS and self.board.sync_mode != AOutSyncMode.MASTER:
            return  # a slave waits for the external SYNC pin: nothing changes
        for i, v in enumerate(data):
            self.board.pins[low_chan + i] = v


class FakeAi:
    def __init__(self, lib: FakeLib, board: FakeBoard) -> None:
        self.lib, self.board = lib, board
        self.buffer: Any = None
        self.running = False
        self.produced = 0  # samples written so far

    def a_in_scan(
        self,
        low_channel: int,
        high_channel: int,
        input_mode: int,
        analog_range: int,
        samples_per_channel: int,
        rate: float,
        options: int,
        flags: int,
        data: Any,
    ) -> float:
        self.lib.record(
            "a_in_scan",
            self.board.serial,
            low_channel,
            high_channel,
            input_mode,
            analog_range,
            samples_per_channel,
            rate,
            options,
            flags,
            len(data),
        )
        self.buffer, self.low, self.width = data, low_channel, high_channel - low_channel + 1
        self.rate, self.t0, self.running, self.produced = float(rate), self.lib.clock.now_s(), True, 0
        return float(rate)

    def _produce(self) -> None:
        rows = math.floor((self.lib.clock.now_s() - self.t0) * self.rate + 1e-9) + 1
        for k in range(self.produced, rows * self.width):
            row, col = divmod(k, self.width)
            self.buffer[k % len(self.buffer)] = self.board.signal(self.t0 + row / self.rate, self.low + col)
        self.produced = max(self.produced, rows * self.width)

    def get_scan_status(self) -> tuple[ScanStatus, TransferStatus]:
        self.lib.record("get_scan_status", self.board.serial)
        if self.running:
            self._produce()
        status = ScanStatus.RUNNING if self.running else ScanStatus.IDLE
        last = self.produced - self.width if self.produced else -1
        index = last % len(self.buffer) if last >= 0 else -1
        return status, TransferStatus(
            current_scan_count=self.produced // max(1, self.width),
            current_total_count=self.produced,
            current_index=index,
        )

    def scan_stop(self) -> None:
        self.lib.record("scan_stop", self.board.serial)
        if self.running:
            self._produce()
        self.running = False


def make_fake_uldaq(boards: list[FakeBoard], clock: Any) -> FakeLib:
    return FakeLib(boards, clock)
