"""The uldaq and mcculw backends against fakes of the libraries' Python APIs: the calls they make (ranges,
channels, rates, scan options), the circular scan buffer read in order across its end, the volts and
codes that come back, the scan stopped on a failure and on closing, and the rig file's `backend:` key."""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from protocol_runner.cli import main
from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.board_group import BoardGroup
from protocol_runner.hardware.conversions import volts_to_ao16_code
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput
from protocol_runner.hardware.mcculw_boards import McculwApi, McculwUsb1608Fs, McculwUsb3105
from protocol_runner.hardware.rig_boards import open_rig_boards
from protocol_runner.hardware.uldaq_boards import UldaqUsb1608Fs, UldaqUsb3105
from protocol_runner.hardware.usb_common import (
    BoardBusy,
    BoardIoError,
    BoardNotFound,
    DeviceGone,
    ScanOverrun,
)
from protocol_runner.hardware.vendor_common import VendorLibraryMissing, contiguous_runs
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.resources import packaged_rigs_dir
from tests.hardware import fake_mcculw, fake_uldaq
from tests.hardware.fake_uldaq import ain_board, aout_board

RATE_HZ = 1000.0


class StepClock:
    """Rig time that moves only when told."""

    def __init__(self) -> None:
        self.t_s = 5.0

    def now_s(self) -> float:
        return self.t_s

    def sleep_until(self, t_s: float) -> None:
        self.t_s = max(self.t_s, t_s)

    def advance(self, dt_s: float) -> None:
        self.t_s += dt_s


def ramp(t: float, ch: int) -> float:
    """A signal whose every sample says where it came from: the channel, and the time (volts)."""
    return ch - 4.0 + 0.5 * math.sin(7.0 * t)


def expected(t_s: np.ndarray, chans: list[int]) -> np.ndarray:
    return np.array([[ramp(t, ch) for ch in chans] for t in t_s])


# ---------------------------------------------------------------------------------------- uldaq output


def test_uldaq_output_calls_and_codes() -> None:
    lib = fake_uldaq.make_fake_uldaq([aout_board("AO1")], StepClock())
    ao = UldaqUsb3105.open(lib=lib)
    assert isinstance(ao, AnalogOutput)
    # found among USB devices, connected, made sync master so that simultaneous updates latch
    assert lib.calls[:4] == [
        ("get_daq_device_inventory", "", lib.InterfaceType.USB),
        ("DaqDevice", "AO1"),
        ("connect", "AO1"),
        ("set_sync_mode", "AO1", lib.AOutSyncMode.MASTER),
    ]
    with pytest.raises(InvalidInput, match="not configured"):
        ao.write_volts(8, 1.0)
    ao.configure_channel(8)
    assert lib.calls[-1] == ("a_out", "AO1", 8, lib.Range.BIP10VOLTS, lib.AOutFlag.DEFAULT, 0.0)
    assert ao.write_volts(8, 2.5) == 32768 + 8192  # the ±10 V code of 2.5 V
    assert lib.calls[-1] == ("a_out", "AO1", 8, lib.Range.BIP10VOLTS, lib.AOutFlag.DEFAULT, 2.5)
    assert ao.write_volts(8, 12.0) == 65535 and lib.boards[0].pins[8] == 10.0  # clamped to the range
    ao.close()
    ao.close()
    assert lib.names("AO1")[-2:] == ["disconnect", "release"]
    assert lib.names().count("release") == 1


def test_uldaq_sync_writes_each_contiguous_run_together_and_never_a_channel_between() -> None:
    lib = fake_uldaq.make_fake_uldaq([aout_board("AO1")], StepClock())
    board = lib.boards[0]
    ao = UldaqUsb3105.open(lib=lib)
    for ch in (5, 8, 9, 11):
        ao.configure_channel(ch)
    board.pins[10] = 3.3  # another joint's output, not driven by this protocol
    codes = ao.write_volts_sync({11: 2.0, 8: 1.0, 9: -1.0, 5: 0.5})
    lists = [c for c in lib.calls if c[0] == "a_out_list"]
    bip10, sim = lib.Range.BIP10VOLTS, lib.AOutListFlag.SIMULTANEOUS
    assert lists == [
        ("a_out_list", "AO1", 5, 5, [bip10], sim, [0.5]),
        ("a_out_list", "AO1", 8, 9, [bip10, bip10], sim, [1.0, -1.0]),
        ("a_out_list", "AO1", 11, 11, [bip10], sim, [2.0]),
    ]
    assert board.pins[10] == 3.3
    assert board.pins[8] == 1.0 and board.pins[9] == -1.0 and board.pins[11] == 2.0
    assert codes == {ch: int(volts_to_ao16_code(v)) for ch, v in {11: 2.0, 8: 1.0, 9: -1.0, 5: 0.5}.items()}
    assert contiguous_runs([3, 1, 2, 7]) == [[1, 2, 3], [7]]


def test_uldaq_board_not_found_names_the_serials_seen() -> None:
    lib = fake_uldaq.make_fake_uldaq([aout_board("AO1")], StepClock())
    with pytest.raises(BoardNotFound, match=r"no USB-3105 with serial XYZ.*AO1"):
        UldaqUsb3105.open("XYZ", lib=lib)
    assert "connect" not in lib.names()


# ----------------------------------------------------------------------------------------- uldaq input


def uldaq_input(buffer_s: float = 10.0) -> tuple[Any, StepClock, UldaqUsb1608Fs]:
    clock = StepClock()
    lib = fake_uldaq.make_fake_uldaq([ain_board("AI1", ramp)], clock)
    return lib, clock, UldaqUsb1608Fs.open(clock=clock, lib=lib, buffer_s=buffer_s)


def test_uldaq_scan_calls_and_rows() -> None:
    lib, clock, ai = uldaq_input()
    assert isinstance(ai, AnalogInput)
    ai.start_scan([3, 1], RATE_HZ)  # any order: the library scans 1..3 and the columns are picked
    (scan,) = [c for c in lib.calls if c[0] == "a_in_scan"]
    assert scan == (
        "a_in_scan", "AI1", 1, 3, lib.AiInputMode.SINGLE_ENDED, lib.Range.BIP10VOLTS,
        10000, RATE_HZ, lib.ScanOption.CONTINUOUS, lib.AInScanFlag.DEFAULT, 3 * 10000,
    )  # fmt: skip
    clock.advance(0.2495)
    block = ai.read_available()
    assert block.n_samples == 250  # rows at 0, 1, ..., 249 ms
    np.testing.assert_allclose(block.t_s, 5.0 + np.arange(250) / RATE_HZ)
    np.testing.assert_allclose(block.volts, expected(block.t_s, [3, 1]), atol=1e-12)
    assert np.array_equal(block.codes, np.rint(32768 + 3276.8 * block.volts).astype(np.int32))
    clock.advance(0.1)
    rest = ai.stop_scan()
    assert rest.n_samples == 100 and rest.t_s[0] == pytest.approx(5.250)
    assert lib.names("AI1")[-2:] == ["scan_stop", "get_scan_status"]
    ai.close()
    assert lib.names("AI1")[-2:] == ["disconnect", "release"]


def test_uldaq_circular_buffer_wrap_keeps_every_row_in_order() -> None:
    _, clock, ai = uldaq_input(buffer_s=0.05)  # 50 rows of 2 channels
    ai.start_scan([0, 1], RATE_HZ)
    blocks = []
    for _ in range(9):  # 30 rows each read: the reads cross the buffer's end again and again
        clock.advance(0.030)
        blocks.append(ai.read_available())
    t_s = np.concatenate([b.t_s for b in blocks])
    volts = np.concatenate([b.volts for b in blocks])
    assert len(t_s) == 271 and np.allclose(np.diff(t_s), 1e-3)
    np.testing.assert_allclose(volts, expected(t_s, [0, 1]), atol=1e-12)


def test_uldaq_overrun_is_said_and_the_scan_stopped() -> None:
    lib, clock, ai = uldaq_input(buffer_s=0.05)
    ai.start_scan([0], RATE_HZ)
    clock.advance(0.2)  # 200 rows into a 50-row buffer: the oldest were overwritten unread
    with pytest.raises(ScanOverrun, match="overran its buffer"):
        ai.read_available()
    assert "scan_stop" in lib.names("AI1")
    assert ai.read_available().n_samples == 0  # no longer scanning
    ai.close()
    assert lib.names("AI1").count("scan_stop") == 1


def test_uldaq_library_failure_during_a_scan_stops_it_and_says_gone() -> None:
    lib, clock, ai = uldaq_input()
    ai.start_scan([0], RATE_HZ)
    clock.advance(0.1)
    lib.fail("get_scan_status", lib.ULError.DEAD_DEV)
    with pytest.raises(DeviceGone, match="unplugged"):
        ai.read_available()
    assert "scan_stop" in lib.names("AI1")


def test_uldaq_closing_while_scanning_stops_the_scan_first() -> None:
    lib, clock, ai = uldaq_input()
    with ai:
        ai.start_scan([2], RATE_HZ)
        clock.advance(0.05)
    assert lib.names("AI1")[-3:] == ["scan_stop", "disconnect", "release"]


# -------------------------------------------------------------------------------------------- mcculw


def mcculw_api(boards: list[Any], clock: StepClock) -> tuple[McculwApi, Any]:
    _, ul, enums = fake_mcculw.make_fake_mcculw(boards, clock)
    return McculwApi(ul=ul, enums=enums), ul


def test_mcculw_output_calls_and_a_simultaneous_run() -> None:
    api, ul = mcculw_api([aout_board("AO1")], StepClock())
    enums = api.enums
    ao = McculwUsb3105.open(api=api)
    assert ul.calls[:4] == [
        ("ignore_instacal",),
        ("get_daq_device_inventory", enums.InterfaceType.USB),
        ("create_daq_device", 0, "AO1"),
        ("set_config", enums.InfoType.BOARDINFO, 0, 0, enums.BoardInfo.SYNCMODE, 0),  # 0 = master
    ]
    ao.configure_channel(8)
    ao.configure_channel(9)
    assert ao.write_volts(8, -2.5) == 32768 - 8192
    assert ul.calls[-1] == ("a_out", 0, 8, enums.ULRange.BIP10VOLTS, 32768 - 8192)
    ao.write_volts_sync({8: 1.0, 9: -1.0})
    handle = ul.calls[-3][2]
    assert ul.calls[-4:] == [
        ("win_buf_alloc", 2),
        ("win_array_to_buf", [36045, 29491], handle, 0, 2),
        ("a_out_scan", 0, 8, 9, 2, 100, enums.ULRange.BIP10VOLTS, handle, enums.ScanOptions.SIMULTANEOUS),
        ("win_buf_free", handle),
    ]
    pins = api.ul.boards[0].pins
    assert pins[8] == pytest.approx(1.0, abs=2e-4) and pins[9] == pytest.approx(-1.0, abs=2e-4)
    ao.close()
    assert ul.calls[-1] == ("release_daq_device", 0) and ul.buffers == {}


def test_mcculw_boards_get_distinct_numbers_and_instacal_is_ignored_once() -> None:
    clock = StepClock()
    api, ul = mcculw_api([aout_board("AO1"), ain_board("AI1", ramp)], clock)
    ao = McculwUsb3105.open(api=api)
    ai = McculwUsb1608Fs.open(clock=clock, api=api)
    assert (ao.board_num, ai.board_num) == (0, 1) and ul.names().count("ignore_instacal") == 1
    ao.close()
    ai.close()
    assert ul.created == {}


def test_mcculw_scan_calls_wrap_and_stop() -> None:
    clock = StepClock()
    api, ul = mcculw_api([ain_board("AI1", ramp)], clock)
    enums = api.enums
    ai = McculwUsb1608Fs.open(clock=clock, api=api, buffer_s=0.05)
    ai.start_scan([2, 0], RATE_HZ)
    (scan,) = [c for c in ul.calls if c[0] == "a_in_scan"]
    options = enums.ScanOptions.BACKGROUND | enums.ScanOptions.CONTINUOUS | enums.ScanOptions.SCALEDATA
    handle = scan[7]
    assert scan == ("a_in_scan", 0, 0, 2, 150, 1000, enums.ULRange.BIP10VOLTS, handle, options)
    assert ("scaled_win_buf_alloc", 150) in ul.calls
    blocks = []
    for _ in range(7):
        clock.advance(0.020)
        blocks.append(ai.read_available())
    blocks.append(ai.stop_scan())
    t_s = np.concatenate([b.t_s for b in blocks])
    volts = np.concatenate([b.volts for b in blocks])
    assert np.allclose(np.diff(t_s), 1e-3) and t_s[0] == 5.0
    np.testing.assert_allclose(volts, expected(t_s, [2, 0]), atol=1e-12)
    assert ul.calls[-2:] == [
        ("stop_background", 0, enums.FunctionType.AIFUNCTION),
        ("win_buf_free", handle),
    ]
    ai.close()
    assert ul.calls[-1] == ("release_daq_device", 0)


def test_mcculw_a_read_later_than_the_buffer_is_an_overrun_and_stops_the_scan() -> None:
    clock = StepClock()
    api, ul = mcculw_api([ain_board("AI1", ramp)], clock)
    ai = McculwUsb1608Fs.open(clock=clock, api=api, buffer_s=0.05)
    ai.start_scan([0], RATE_HZ)
    clock.advance(0.060)
    with pytest.raises(ScanOverrun, match=r"not read for 0\.1 s"):
        ai.read_available()
    assert "stop_background" in ul.names() and ul.buffers == {}


# ----------------------------------------------------------------------------- rig file and the CLI


def write_campaign(folder: Path, backend: str) -> Path:
    """The elbow example on a copy of the RSST rig file whose MCC boards use `backend`, with the inputs
    on three USB-1608FS-Plus boards."""
    folder.mkdir()
    rig_lines = []
    for line in (packaged_rigs_dir() / "rsst.yaml").read_text().splitlines(keepends=True):
        rig_lines.append(line)
        if line.strip().startswith(("usb3105:", "usb1608fs:")) and line.startswith("  ") and "#" in line:
            rig_lines.append(f"    backend: {backend}\n")
    (folder / "lab_rig.yaml").write_text("".join(rig_lines))
    text = find_protocol("elbow_example.yaml").read_text()
    text = text.replace("rig: rsst\n", "rig: lab_rig.yaml\nrig_overrides: {input_board: usb1608fs}\n")
    (folder / "elbow.yaml").write_text(text)
    return folder / "elbow.yaml"


def test_a_rig_file_selecting_uldaq_opens_its_boards_through_uldaq(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    protocol = load_protocol(write_campaign(tmp_path / "c", "uldaq"))
    spec = protocol.protocol.rig
    assert (spec.output.backend, spec.input.backend) == ("uldaq", "uldaq")
    clock = StepClock()
    lib = fake_uldaq.make_fake_uldaq(
        [aout_board("AO1"), ain_board("AI3", ramp), ain_board("AI1", ramp), ain_board("AI2", ramp)], clock
    )
    monkeypatch.setitem(sys.modules, "uldaq", lib)
    ao, ai, _ = open_rig_boards(spec, clock=clock)  # type: ignore[arg-type]
    assert isinstance(ao, UldaqUsb3105) and isinstance(ai, BoardGroup)
    assert [b.serial for b in ai.boards] == ["AI1", "AI2", "AI3"] and ai.n_channels == 24
    assert all(isinstance(b, UldaqUsb1608Fs) for b in ai.boards)
    ai.start_scan([spec.input.angle_channel, spec.input.torque_channel], RATE_HZ)  # elbow: 3 and 15
    clock.advance(0.0995)
    block = ai.read_available()
    np.testing.assert_allclose(block.volts, expected(block.t_s, [3 % 8, 15 % 8]), atol=1e-12)
    ai.stop_scan()
    ai.close()
    ao.close()
    assert sorted(lib.names()).count("release") == 4


def test_a_rig_file_selecting_mcculw_opens_its_boards_through_mcculw(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    protocol = load_protocol(write_campaign(tmp_path / "c", "mcculw"))
    spec = protocol.protocol.rig
    clock = StepClock()
    package, ul, enums = fake_mcculw.make_fake_mcculw(
        [aout_board("AO1"), ain_board("AI1", ramp), ain_board("AI2", ramp), ain_board("AI3", ramp)], clock
    )
    monkeypatch.setitem(sys.modules, "mcculw", package)
    monkeypatch.setitem(sys.modules, "mcculw.ul", ul)
    monkeypatch.setitem(sys.modules, "mcculw.enums", enums)
    ao, ai, _ = open_rig_boards(spec, clock=clock)  # type: ignore[arg-type]
    assert isinstance(ao, McculwUsb3105) and all(isinstance(b, McculwUsb1608Fs) for b in ai.boards)
    assert sorted(ul.created) == [0, 1, 2, 3]
    ai.close()
    ao.close()
    assert ul.created == {}


@pytest.mark.parametrize("backend", ["uldaq", "mcculw"])
def test_a_missing_vendor_library_is_a_plain_error_naming_the_extra(
    backend: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in (backend, f"{backend}.ul"):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ModuleNotFoundError
    protocol = write_campaign(tmp_path / "c", backend)
    session = tmp_path / "session"
    assert main([str(protocol), "--session", str(session), "--yes"]) == 2
    err = capsys.readouterr().err
    assert f"pip install protocol-runner[{backend}]" in err and "backend: pyusb" in err
    assert err.startswith("run-protocol: lab_rig.yaml: the rig file selects backend:"), err
    assert "Traceback" not in err and not session.exists()
    with pytest.raises(VendorLibraryMissing):
        open_rig_boards(load_protocol(protocol).protocol.rig)  # type: ignore[arg-type]


def test_the_dt9814_has_no_vendor_backend(tmp_path: Path) -> None:
    from protocol_runner.protocol.rig_file import load_rig

    text = (packaged_rigs_dir() / "rsst.yaml").read_text()
    text = text.replace("  dt9814:                            #", "  dt9814:\n    backend: uldaq\n    #", 1)
    (tmp_path / "r.yaml").write_text(text)
    with pytest.raises(InvalidInput, match=r"boards\.dt9814\.backend: MCC's uldaq does not drive the DT9814"):
        load_rig(tmp_path / "r.yaml")


def test_sample_row_times_follow_the_rate_the_library_set() -> None:
    _, clock, ai = uldaq_input()
    ai.start_scan([0], 333.3)
    clock.advance(0.1)
    block = ai.read_available()
    assert math.isclose(block.t_s[1] - block.t_s[0], 1 / 333.3)
    ai.close()


def test_mcculw_a_scan_that_does_not_start_frees_its_buffer_and_says_the_uls_message() -> None:
    clock = StepClock()
    api, ul = mcculw_api([ain_board("AI1", ramp)], clock)
    ai = McculwUsb1608Fs.open(clock=clock, api=api)
    ul.fail("a_in_scan", 26)
    with pytest.raises(
        BoardIoError, match=r"starting the scan: fake UL error 26 \(Universal Library error 26\)"
    ):
        ai.start_scan([0, 1], RATE_HZ)
    assert ul.buffers == {} and ai.read_available().n_samples == 0
    ai.close()


def test_uldaq_a_board_held_by_another_program_is_busy_and_released_again() -> None:
    lib = fake_uldaq.make_fake_uldaq([aout_board("AO1")], StepClock())
    lib.fail("connect", lib.ULError.USB_INTERFACE_CLAIMED)
    with pytest.raises(BoardBusy, match="another program is using it"):
        UldaqUsb3105.open(lib=lib)
    assert lib.names("AO1") == ["DaqDevice", "connect", "release"]


def test_a_vendor_package_that_cannot_load_its_library_is_a_plain_error(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from protocol_runner.hardware import vendor_common

    def import_failing(name: str) -> Any:
        raise OSError("libuldaq.so: cannot open shared object file")

    monkeypatch.setitem(sys.modules, "uldaq", fake_uldaq.make_fake_uldaq([], StepClock()))  # installed
    monkeypatch.setattr(vendor_common.importlib, "import_module", import_failing)
    with pytest.raises(
        VendorLibraryMissing, match=r"installed but could not load MCC's libuldaq \(OSError: libuldaq"
    ):
        UldaqUsb3105.open()
