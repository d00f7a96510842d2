"""A fake of the `mcculw` Python API (MCC's Universal Library for Windows) for the mcculw backend's tests.

`make_fake_mcculw(boards, clock)` returns ``(package, ul, enums)``: module-like objects with the names
`mcculw_boards.py` uses (`ul` functions, `enums` classes). Every `ul` call is recorded in ``ul.calls`` as
``(name, *arguments)``. Memory handles are keys of ``ul.buffers`` (numpy arrays). A background continuous
input scan writes ``signal(t, channel)`` at buffer position ``k mod size`` for sample ``k`` whenever
`get_status` is called, for every row produced by ``clock.now_s()``; `get_status` returns (status,
cur_count, cur_index) with cur_index the start of the last complete row, as the UL documents. `fail`
makes a named call raise `ULError`.
"""

from __future__ import annotations

import math
from enum import IntEnum, IntFlag
from types import SimpleNamespace
from typing import Any

import numpy as np

from tests.hardware.fake_uldaq import FakeBoard, ain_board, aout_board

__all__ = ["FakeBoard", "ain_board", "aout_board", "make_fake_mcculw"]


class InterfaceType(IntEnum):
    USB = 1
    BLUETOOTH = 2
    ETHERNET = 4
    ANY = 7


class ULRange(IntEnum):
    BIP10VOLTS = 1
    UNI10VOLTS = 100


class ScanOptions(IntFlag):
    BACKGROUND = 0x0001
    CONTINUOUS = 0x0002
    SIMULTANEOUS = 0x0200
    SCALEDATA = 0x10000000


class FunctionType(IntEnum):
    AIFUNCTION = 1
    AOFUNCTION = 2


class Status(IntEnum):
    IDLE = 0
    RUNNING = 1


class InfoType(IntEnum):
    BOARDINFO = 2


class BoardInfo(IntEnum):
    SYNCMODE = 251


class ULError(Exception):
    def __init__(self, errorcode: int) -> None:
        super().__init__(errorcode)
        self.errorcode = errorcode
        self.message = f"fake UL error {errorcode}"


class FakeUl(SimpleNamespace):
    def __init__(self, boards: list[FakeBoard], clock: Any) -> None:
        super().__init__(ULError=ULError)
        self.boards = boards
        self.clock = clock
        self.calls: list[tuple[Any, ...]] = []
        self.failures: dict[str, int] = {}
        self.created: dict[int, FakeBoard] = {}
        self.buffers: dict[int, np.ndarray] = {}
        self.scans: dict[int, dict[str, Any]] = {}
        self._next_handle = 100

    def fail(self, call: str, code: int) -> None:
        self.failures[call] = code

    def _record(self, name: str, *args: Any) -> None:
        self.calls.append((name, *args))
        if name in self.failures:
            raise ULError(self.failures[name])

    def names(self) -> list[str]:
        return [c[0] for c in self.calls]

    # ---- devices ------------------------------------------------------------------------------------
    def ignore_instacal(self) -> None:
        self._record("ignore_instacal")

    def get_daq_device_inventory(self, interface_type: int, number_of_devices: int = 100) -> list[Any]:
        self._record("get_daq_device_inventory", interface_type)
        return [
            SimpleNamespace(product_name="fake", product_id=b.product_id, unique_id=b.serial)
            for b in self.boards
        ]

    def create_daq_device(self, board_num: int, descriptor: Any) -> None:
        self._record("create_daq_device", board_num, descriptor.unique_id)
        if board_num in self.created:
            raise ULError(1)  # BADBOARD: the number is taken
        self.created[board_num] = next(b for b in self.boards if b.serial == descriptor.unique_id)

    def release_daq_device(self, board_num: int) -> None:
        self._record("release_daq_device", board_num)
        self.created.pop(board_num)

    def set_config(
        self, info_type: int, board_num: int, dev_num: int, config_item: int, config_val: int
    ) -> None:
        self._record("set_config", info_type, board_num, dev_num, config_item, config_val)
        if config_item == BoardInfo.SYNCMODE:
            self.created[board_num].sync_mode = 1 - config_val  # UL: 0 = master; the model: 1 = master

    def flash_led(self, board_num: int) -> None:
        self._record("flash_led", board_num)

    # ---- output -------------------------------------------------------------------------------------
    def from_eng_units(self, board_num: int, ul_range: int, eng_units_value: float) -> int:
        self._record("from_eng_units", board_num, ul_range, eng_units_value)
        return int(min(65535, max(0, round(32768 + 3276.8 * eng_units_value))))

    def a_out(self, board_num: int, channel: int, ul_range: int, data_value: int) -> None:
        self._record("a_out", board_num, channel, ul_range, data_value)
        self.created[board_num].pins[channel] = (data_value - 32768) / 3276.8

    def win_buf_alloc(self, num_points: int) -> int:
        self._record("win_buf_alloc", num_points)
        return self._alloc(num_points, np.uint16)

    def scaled_win_buf_alloc(self, num_points: int) -> int:
        self._record("scaled_win_buf_alloc", num_points)
        return self._alloc(num_points, np.float64)

    def _alloc(self, n: int, dtype: Any) -> int:
        self._next_handle += 1
        self.buffers[self._next_handle] = np.zeros(n, dtype=dtype)
        return self._next_handle

    def win_buf_free(self, memhandle: int) -> None:
        self._record("win_buf_free", memhandle)
        del self.buffers[memhandle]

    def win_array_to_buf(self, data_array: Any, memhandle: int, first_point: int, count: int) -> None:
        self._record("win_array_to_buf", list(data_array), memhandle, first_point, count)
        self.buffers[memhandle][first_point : first_point + count] = list(data_array)[:count]

    def a_out_scan(
        self,
        board_num: int,
        low_chan: int,
        high_chan: int,
        num_points: int,
        rate: int,
        ul_range: int,
        memhandle: int,
        options: int,
    ) -> int:
        self._record(
            "a_out_scan", board_num, low_chan, high_chan, num_points, rate, ul_range, memhandle, options
        )
        board = self.created[board_num]
        if options & ScanOptions.SIMULTANEOUS and board.sync_mode != 1:
            return rate  # a slave waits for the external SYNC pin
        for i, code in enumerate(self.buffers[memhandle][:num_points]):
            board.pins[low_chan + i] = (int(code) - 32768) / 3276.8
        return rate

    # ---- input --------------------------------------------------------------------------------------
    def a_in_scan(
        self,
        board_num: int,
        low_chan: int,
        high_chan: int,
        num_points: int,
        rate: int,
        ul_range: int,
        memhandle: int,
        options: int,
    ) -> int:
        self._record(
            "a_in_scan", board_num, low_chan, high_chan, num_points, rate, ul_range, memhandle, options
        )
        self.scans[board_num] = {
            "low": low_chan,
            "width": high_chan - low_chan + 1,
            "rate": rate,
            "t0": self.clock.now_s(),
            "handle": memhandle,
            "produced": 0,
            "running": True,
        }
        return rate

    def _produce(self, board_num: int) -> None:
        scan = self.scans[board_num]
        board, width, buf = self.created[board_num], scan["width"], self.buffers[scan["handle"]]
        rows = math.floor((self.clock.now_s() - scan["t0"]) * scan["rate"] + 1e-9) + 1
        for k in range(scan["produced"], rows * width):
            row, col = divmod(k, width)
            buf[k % len(buf)] = board.signal(scan["t0"] + row / scan["rate"], scan["low"] + col)
        scan["produced"] = max(scan["produced"], rows * width)

    def get_status(self, board_num: int, function_type: int) -> tuple[Status, int, int]:
        self._record("get_status", board_num, function_type)
        scan = self.scans.get(board_num)
        if scan is None or not scan["running"]:
            return Status.IDLE, 0, -1
        self._produce(board_num)
        size = len(self.buffers[scan["handle"]])
        last = scan["produced"] - scan["width"]
        return Status.RUNNING, scan["produced"], (last % size if last >= 0 else -1)

    def scaled_win_buf_to_array(self, memhandle: int, data_array: Any, first_point: int, count: int) -> None:
        self._record("scaled_win_buf_to_array", memhandle, first_point, count)
        buf = self.buffers[memhandle]
        assert first_point + count <= len(buf), "the UL copies from one contiguous stretch of the buffer"
        for i in range(count):
            data_array[i] = buf[first_point + i]

    def stop_background(self, board_num: int, function_type: int) -> None:
        self._record("stop_background", board_num, function_type)
        scan = self.scans.get(board_num)
        if scan is not None:
            scan["running"] = False


def make_fake_mcculw(boards: list[FakeBoard], clock: Any) -> tuple[SimpleNamespace, FakeUl, SimpleNamespace]:
    ul = FakeUl(boards, clock)
    enums = SimpleNamespace(
        InterfaceType=InterfaceType,
        ULRange=ULRange,
        ScanOptions=ScanOptions,
        FunctionType=FunctionType,
        Status=Status,
        InfoType=InfoType,
        BoardInfo=BoardInfo,
    )
    package = SimpleNamespace(ul=ul, enums=enums)
    return package, ul, enums
