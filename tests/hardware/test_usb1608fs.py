"""USB-1608FS-Plus driver and BoardGroup, through pyusb against the fake board on a manual clock."""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.board_group import BoardGroup
from protocol_runner.hardware.interfaces import AnalogInput, ScanBlock
from protocol_runner.hardware.usb1608fs import Usb1608FsPlus, open_all_1608fs
from protocol_runner.hardware.usb1608fs_protocol import pacer_period
from protocol_runner.hardware.usb_common import BoardNotFound, BoardPermissionDenied, DeviceGone, ScanOverrun
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.device import Faults
from tests.fakeusb.usb1608fs import ManualClock, Usb1608FsModel, make_usb1608fs


class RigClock:
    """The driver's Clock reading the same manual time as the fake board."""

    def __init__(self, manual: ManualClock) -> None:
        self.manual = manual

    def now_s(self) -> float:
        return self.manual()

    def sleep_until(self, t_s: float) -> None:
        self.manual.t_s = max(self.manual.t_s, t_s)


def ramp(t: npt.ArrayLike, ch: int) -> npt.NDArray[np.float64]:
    """A signal whose value says which channel and when: ch volts plus 1 V/s."""
    return -8.0 + ch + np.asarray(t, dtype=np.float64)


def level(volts: float) -> Callable[[float, int], float]:
    """A board whose channel ch reads `volts` + 0.1 * ch."""
    return lambda t, ch: volts + 0.1 * ch


def open_board(model: Usb1608FsModel, clock: ManualClock) -> Usb1608FsPlus:
    return Usb1608FsPlus.open(backend=FakeBackend(model), clock=RigClock(clock))


def ctrl_outs(model: Usb1608FsModel, request: int) -> list[bytes]:
    return [d for kind, req, d in model.transfer_log if kind == "ctrl_out" and req == request]


def test_satisfies_the_analog_input_protocol_with_16_bits() -> None:
    clock = ManualClock()
    ai = open_board(make_usb1608fs(clock=clock), clock)
    assert isinstance(ai, AnalogInput)
    assert ai.resolution_bits == 16
    ai.close()


def test_identity_from_the_serial_request_and_bcd_device() -> None:
    clock = ManualClock()
    model = make_usb1608fs(serial="01ABCDEF", clock=clock)
    ai = open_board(model, clock)
    assert ai.serial == "01ABCDEF"
    assert ai.firmware == "1.03"
    assert any(kind == "ctrl_in" and req == 0x48 for kind, req, _ in model.transfer_log)
    ai.close()


def test_pacer_is_40_mhz_over_rate_minus_one() -> None:
    assert pacer_period(1000.0) == 39_999
    assert pacer_period(100_000.0) == 399


def test_scan_start_bytes_on_the_wire() -> None:
    clock = ManualClock()
    model = make_usb1608fs(clock=clock)
    ai = open_board(model, clock)
    ai.start_scan([6, 1, 3], 1000.0)
    (start,) = ctrl_outs(model, 0x11)
    assert start == struct.pack("<IIBB", 0, 39_999, 0b0100_1010, 0)
    assert ctrl_outs(model, 0x14)[-1] == bytes(8)  # every channel +-10 V
    ai.stop_scan()
    ai.close()


def test_rows_times_and_channel_order() -> None:
    clock = ManualClock(t_s=5.0)
    model = make_usb1608fs(signal=ramp, clock=clock)
    ai = open_board(model, clock)
    ai.start_scan([6, 1], 1000.0)
    clock.advance(0.2)
    block = ai.read_available()
    assert block.n_samples > 150
    # rows come every 1 ms from the start time
    np.testing.assert_allclose(block.t_s, 5.0 + np.arange(block.n_samples) / 1000.0)
    # columns follow the requested order even though the board scans in ascending order
    expected = np.column_stack([ramp(block.t_s - 0.0, 6), ramp(block.t_s, 1)])
    np.testing.assert_allclose(block.volts, expected, atol=2 * 20.0 / 65536)
    np.testing.assert_array_equal(block.volts, (block.codes - 32768) * 10.0 / 32768)
    ai.stop_scan()
    ai.close()


def test_no_row_is_lost_or_repeated_across_reads_and_stop() -> None:
    clock = ManualClock()
    model = make_usb1608fs(signal=ramp, clock=clock)
    ai = open_board(model, clock)
    ai.start_scan([0, 1, 2], 1000.0)  # 6 bytes a row: rows straddle the 64-byte packets
    blocks = []
    for dt in (0.013, 0.0007, 0.25, 0.031, 0.1):
        clock.advance(dt)
        blocks.append(ai.read_available())
    clock.advance(0.0123)
    blocks.append(ai.stop_scan())
    allrows = ScanBlock.concatenate(blocks, 3)
    n_expected = int(np.floor((clock() - 0.0) * 1000.0 + 1e-9)) + 1
    assert allrows.n_samples == n_expected
    np.testing.assert_allclose(np.diff(allrows.t_s), 1e-3)
    np.testing.assert_allclose(allrows.volts[:, 0], ramp(allrows.t_s, 0), atol=2 * 20.0 / 65536)
    assert model.lost_samples == 0
    ai.close()


@pytest.mark.parametrize("board_ppm", [-150.0, 150.0])
def test_reads_never_ask_for_data_the_board_has_not_produced(board_ppm: float) -> None:
    # a bulk read asking for more than is there times out and loses data on libusb: the driver must only
    # ask for packets that surely exist, even when the board's crystal runs slow or fast
    host = ManualClock()
    model = make_usb1608fs(signal=ramp, clock=lambda: host() * (1.0 + board_ppm * 1e-6))
    ai = open_board(model, host)
    ai.start_scan([0, 1, 2], 2000.0)
    rows = 0
    for _ in range(650):  # 65 s, read every 100 ms
        host.advance(0.1)
        rows += ai.read_available().n_samples
    rows += ai.stop_scan().n_samples
    assert model.lost_samples == 0
    assert rows == model.sent_samples // 3
    ai.close()


def test_rows_lag_by_at_most_a_few_packets() -> None:
    clock = ManualClock()
    model = make_usb1608fs(clock=clock)
    ai = open_board(model, clock)
    ai.start_scan([0, 1], 1000.0)
    clock.advance(1.0)
    got = ai.read_available().n_samples
    assert 1001 - 3 * 16 <= got <= 1001  # 16 rows per 64-byte packet
    ai.stop_scan()
    ai.close()


def test_calibration_is_read_and_applied() -> None:
    clock = ManualClock()
    model = make_usb1608fs(signal=lambda t, ch: 3.0, clock=clock)
    model.set_calibration(4, 1.02, -150.0, range_code=0)
    model.set_calibration(4, 0.5, 0.0, range_code=3)  # another range: must not be used at +-10 V
    ai = open_board(model, clock)
    assert ai.calibration[0][4][0] == pytest.approx(1.02, rel=1e-6)
    ai.start_scan([4], 500.0)
    clock.advance(0.5)
    block = ai.stop_scan()
    raw_expected = model.raw_code(3.0, 4)
    assert raw_expected != round(32768 + 3.0 * 3276.8)  # the ADC really has an error to correct
    np.testing.assert_array_equal(block.codes[:, 0], round(raw_expected * model.calibration(4)[0] - 150.0))
    np.testing.assert_allclose(block.volts, 3.0, atol=2 * 20.0 / 65536)
    ai.close()


def test_overrun_is_a_clear_error() -> None:
    clock = ManualClock()
    model = make_usb1608fs(clock=clock, fifo_samples=1024)
    ai = open_board(model, clock)
    ai.start_scan(list(range(8)), 10_000.0)
    clock.advance(0.5)  # 40 000 samples produced, 1024 fit in the FIFO
    with pytest.raises(ScanOverrun, match="overran") as err:
        ai.read_available()
    assert err.value.exit_code == 3
    # a new scan clears the stall and works again
    ai.start_scan([0], 100.0)
    clock.advance(1.0)
    got = ai.read_available().n_samples + ai.stop_scan().n_samples
    assert got == 101  # rows at 0, 10, ..., 1000 ms
    ai.close()


def test_stop_sends_stop_and_clear_fifo() -> None:
    clock = ManualClock()
    model = make_usb1608fs(clock=clock)
    ai = open_board(model, clock)
    ai.start_scan([0], 100.0)
    n_stop, n_clr = len(ctrl_outs(model, 0x12)), len(ctrl_outs(model, 0x15))
    ai.stop_scan()
    assert len(ctrl_outs(model, 0x12)) == n_stop + 1
    assert len(ctrl_outs(model, 0x15)) == n_clr + 1
    assert not model.running
    ai.close()


@pytest.mark.parametrize(
    ("channels", "rate"), [([], 100.0), ([0, 0], 100.0), ([8], 100.0), ([0], 0.0), ([0], 200_000.0)]
)
def test_bad_scan_requests_are_invalid_input(channels: list[int], rate: float) -> None:
    clock = ManualClock()
    ai = open_board(make_usb1608fs(clock=clock), clock)
    with pytest.raises(InvalidInput):
        ai.start_scan(channels, rate)
    ai.close()


def test_blink_is_a_vendor_request() -> None:
    clock = ManualClock()
    model = make_usb1608fs(clock=clock)
    ai = open_board(model, clock)
    ai.blink(3)
    assert ctrl_outs(model, 0x41)[-1] == bytes([3])
    assert model.blinks == 3
    ai.close()


def test_board_gone_during_scan() -> None:
    clock = ManualClock()
    model = make_usb1608fs(clock=clock)
    ai = open_board(model, clock)
    ai.start_scan([0], 1000.0)
    model.unplug()
    clock.advance(0.1)
    with pytest.raises(DeviceGone):
        ai.read_available()
    ai.close()


def test_permission_denied() -> None:
    with pytest.raises(BoardPermissionDenied, match="udev"):
        open_board(make_usb1608fs(faults=Faults(access_denied_on_open=True)), ManualClock())


def test_not_found_names_the_board() -> None:
    with pytest.raises(BoardNotFound, match="USB-1608FS-Plus"):
        Usb1608FsPlus.open(backend=FakeBackend())


# ---- several boards ----------------------------------------------------------------------------------------


def three_boards(clock: ManualClock) -> tuple[FakeBackend, list[Usb1608FsModel]]:
    models = [
        make_usb1608fs(serial=s, signal=level(k), clock=clock)
        for k, s in ((2.0, "0000000C"), (0.0, "0000000A"), (1.0, "0000000B"))
    ]
    return FakeBackend(*models), models


def test_open_all_sorts_boards_by_serial() -> None:
    clock = ManualClock()
    backend, _ = three_boards(clock)
    boards = open_all_1608fs(backend=backend, clock=RigClock(clock))
    assert [b.serial for b in boards] == ["0000000A", "0000000B", "0000000C"]
    for b in boards:
        b.close()


def test_multi_board_maps_global_channels_and_merges_rows() -> None:
    clock = ManualClock()
    backend, _ = three_boards(clock)
    multi = BoardGroup(open_all_1608fs(backend=backend, clock=RigClock(clock)))
    assert multi.n_channels == 24
    assert multi.locate(20) == (2, 4)
    assert isinstance(multi, AnalogInput)
    multi.start_scan([8, 20, 3], 1000.0)
    clock.advance(0.3)
    first = multi.read_available()
    clock.advance(0.05)
    rest = multi.stop_scan()
    block = ScanBlock.concatenate([first, rest], 3)
    assert block.n_samples == 351
    # board B (serial ...B) outputs 1 + 0.1*ch, board C 2 + 0.1*ch, board A 0.1*ch
    np.testing.assert_allclose(block.volts[:, 0], 1.0, atol=1e-3)  # global 8 = board 1, local 0
    np.testing.assert_allclose(block.volts[:, 1], 2.4, atol=1e-3)  # global 20 = board 2, local 4
    np.testing.assert_allclose(block.volts[:, 2], 0.3, atol=1e-3)  # global 3 = board 0, local 3
    np.testing.assert_allclose(np.diff(block.t_s), 1e-3)
    multi.close()


def test_multi_board_waits_for_the_slowest_board() -> None:
    class Canned:
        """An input that delivers prepared blocks."""

        resolution_bits = 16

        def __init__(self, rows: list[int]) -> None:
            self.rows = rows
            self.calls = 0

        def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
            self.n = len(channels)

        def _block(self, n: int, start: int) -> ScanBlock:
            t = (start + np.arange(n)) / 100.0
            codes = np.full((n, self.n), start, dtype=np.int32) + np.arange(n, dtype=np.int32)[:, None]
            return ScanBlock(t_s=t, codes=codes, volts=codes.astype(float))

        def read_available(self) -> ScanBlock:
            n = self.rows[self.calls]
            start = sum(self.rows[: self.calls])
            self.calls += 1
            return self._block(n, start)

        def stop_scan(self) -> ScanBlock:
            return self.read_available()

        def close(self) -> None:
            pass

    fast, slow = Canned([5, 5, 2]), Canned([2, 3, 10])
    multi = BoardGroup([fast, slow], channels_per_board=8)
    multi.start_scan([0, 9], 100.0)
    b1 = multi.read_available()
    assert b1.n_samples == 2
    b2 = multi.read_available()
    assert b2.n_samples == 3
    b3 = multi.stop_scan()
    assert b3.n_samples == 7  # fast delivered 12 rows, slow 15: three of slow's are dropped
    assert multi.dropped_rows == 3
    merged = ScanBlock.concatenate([b1, b2, b3], 2)
    np.testing.assert_array_equal(merged.codes[:, 0], np.arange(12))
    np.testing.assert_array_equal(merged.codes[:, 1], np.arange(12))


def test_multi_board_rejects_missing_channels() -> None:
    clock = ManualClock()
    backend, _ = three_boards(clock)
    multi = BoardGroup(open_all_1608fs(backend=backend, clock=RigClock(clock)))
    with pytest.raises(InvalidInput, match="0-23"):
        multi.start_scan([24], 1000.0)
    multi.close()
