"""`hardware_check` / `format_report` against fake boards."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, cast

import pytest

from protocol_runner.errors import HardwareUnavailable, InvalidInput
from protocol_runner.hardware.discovery import NOTHING_FOUND, OutputTiming, format_report, hardware_check
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock
from protocol_runner.hardware.rig_boards import open_rig_boards
from protocol_runner.hardware.usb1608fs import Usb1608FsPlus
from protocol_runner.hardware.usb_common import UDEV_RULE_FILENAME
from protocol_runner.protocol.rig_file import output_timing, shipped_rig
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.device import Faults
from tests.fakeusb.dt9814 import make_dt9814
from tests.fakeusb.usb1608fs import ManualClock, make_usb1608fs
from tests.fakeusb.usb3105 import AOUT, make_usb3105

RSST_TIMING = output_timing(shipped_rig("rsst"))


def rig_backend() -> FakeBackend:
    return FakeBackend(
        make_usb3105(serial="AO000001"),
        make_usb1608fs(serial="AI00000B"),
        make_usb1608fs(serial="AI00000A"),
        make_usb1608fs(serial="AI00000C"),
    )


def test_nothing_attached_says_what_to_do() -> None:
    report = hardware_check(backend=FakeBackend())
    assert report.boards == () and not report.ok
    text = format_report(report)
    assert NOTHING_FOUND in text
    assert "No DAQ boards found" in text and UDEV_RULE_FILENAME in text and "--dry-run" in text
    assert "NOT ready" in text


def test_lists_boards_with_global_channels_and_blinks_them() -> None:
    backend = rig_backend()
    report = hardware_check(backend=backend, blink_count=2)
    kinds = [(b.kind, b.serial, b.first_channel, b.n_channels) for b in report.boards]
    assert kinds == [
        ("USB-3105", "AO000001", 0, 16),
        ("USB-1608FS-Plus", "AI00000A", 0, 8),
        ("USB-1608FS-Plus", "AI00000B", 8, 8),
        ("USB-1608FS-Plus", "AI00000C", 16, 8),
    ]
    assert all(b.blinked for b in report.boards)
    assert all(getattr(m, "blinks") == 2 for m in backend.devices)  # noqa: B009
    assert all(m.claimed == set() for m in backend.devices)  # everything closed again
    assert report.ok
    assert report.channel_count("analog_input") == 24
    text = format_report(report)
    assert "USB-3105 serial AO000001, firmware 1.02" in text
    assert "calibration" in text
    assert "analog inputs channels 0-23" in text
    assert "Ready for a hardware run." in text


def test_required_channels_are_located_or_reported_missing() -> None:
    report = hardware_check({"analog_output": [8], "analog_input": [8, 20, 30]}, backend=rig_backend())
    found = {(c.role, c.channel): (c.board.serial if c.board else None) for c in report.checks}
    assert found == {
        ("analog_output", 8): "AO000001",
        ("analog_input", 8): "AI00000B",
        ("analog_input", 20): "AI00000C",
        ("analog_input", 30): None,
    }
    assert not report.ok
    text = format_report(report)
    assert "analog input 20: OK (USB-1608FS-Plus serial AI00000C, its channel 4)" in text
    assert "analog input 30: MISSING (available analog inputs: channels 0-23)" in text


def test_a_board_that_cannot_be_opened_is_a_problem_not_a_crash() -> None:
    backend = FakeBackend(
        make_usb3105(serial="AO000001", faults=Faults(busy_on_claim=True)),
        make_usb1608fs(serial="AI00000A", faults=Faults(access_denied_on_open=True)),
    )
    report = hardware_check({"analog_output": [0]}, backend=backend)
    assert report.boards == ()
    kinds = sorted(p.kind for p in report.problems)
    assert kinds == ["USB-1608FS-Plus", "USB-3105"]
    text = format_report(report)
    assert "busy" in text and UDEV_RULE_FILENAME in text
    assert "analog output 0: MISSING" in text


def test_dt9814_is_listed_as_unverified_after_the_1608_channels() -> None:
    backend = FakeBackend(make_usb1608fs(serial="AI00000A"), make_dt9814(serial_number=4242))
    report = hardware_check(backend=backend)
    dt = [b for b in report.boards if b.kind == "DT9814"]
    assert len(dt) == 1 and dt[0].first_channel == 8 and "UNVERIFIED" in dt[0].note and not dt[0].blinked
    assert "UNVERIFIED" in format_report(report)


@pytest.mark.parametrize(
    "required", [{"analog_outputs": [1]}, {"analog_input": ["x"]}, {"analog_input": [-1]}]
)
def test_bad_requirements_are_invalid_input(required: dict[str, list[int]]) -> None:
    with pytest.raises(InvalidInput):
        hardware_check(required, backend=FakeBackend())


# ---- opening the boards a protocol names -------------------------------------------------------------------


def rig_spec(
    board: str = "usb1608fs", angle: int = 8, torque: int = 20, serials: list[str] | None = None
) -> Any:
    return SimpleNamespace(
        output=SimpleNamespace(
            board="usb3105", channel=8, serial=None, volts_range=(-10.0, 10.0), backend="pyusb"
        ),
        input=SimpleNamespace(
            board=board,
            angle_channel=angle,
            torque_channel=torque,
            serials=serials or [],
            volts_range=(-10.0, 10.0),
            backend="pyusb",
        ),
    )


def test_open_rig_boards_gives_a_3105_and_24_inputs() -> None:
    ao, ai, clock = open_rig_boards(rig_spec(), backend=rig_backend())
    assert isinstance(ao, AnalogOutput) and isinstance(ai, AnalogInput) and isinstance(clock, Clock)
    assert ai.n_channels == 24
    assert [cast(Usb1608FsPlus, b).serial for b in ai.boards] == ["AI00000A", "AI00000B", "AI00000C"]
    ao.close()
    ai.close()


def test_open_rig_boards_follows_the_serials_order() -> None:
    _, ai, _ = open_rig_boards(rig_spec(serials=["AI00000C", "AI00000A", "AI00000B"]), backend=rig_backend())
    assert [cast(Usb1608FsPlus, b).serial for b in ai.boards] == ["AI00000C", "AI00000A", "AI00000B"]
    ai.close()


def test_open_rig_boards_names_a_missing_input_channel_and_closes_everything() -> None:
    backend = FakeBackend(make_usb3105(serial="AO000001"), make_usb1608fs(serial="AI00000A"))
    with pytest.raises(HardwareUnavailable, match=r"input channel 8.*channels 0-7"):
        open_rig_boards(rig_spec(), backend=backend)
    assert all(m.claimed == set() for m in backend.devices)


def test_open_rig_boards_refuses_the_dt9814_plainly() -> None:
    with pytest.raises(HardwareUnavailable, match="usb1608fs"):
        open_rig_boards(rig_spec(board="dt9814"), backend=rig_backend())


def test_open_rig_boards_without_output_board() -> None:
    with pytest.raises(HardwareUnavailable, match="no USB-3105 found"):
        open_rig_boards(rig_spec(), backend=FakeBackend(make_usb1608fs()))


def test_times_one_output_report_on_a_channel_no_joint_uses_and_states_it_beside_the_rig_files() -> None:
    # the fake board spends 1.3 ms of simulated time per report it receives (no sleep, no wall clock)
    clock = ManualClock()
    board = make_usb3105(serial="AO000001", report_time_s=0.0013, advance=clock.advance)
    report = hardware_check(
        backend=FakeBackend(board), blink_count=0, timing=RSST_TIMING, timing_reports=50, clock=clock
    )
    (info,) = report.boards
    assert info.report_time_s == pytest.approx(0.0013)
    # the RSST's joints are wired to outputs 0-11: the timing writes go to channel 15 only
    assert info.timing_channel == 15
    assert {r[1] for r in board.reports_with_command(AOUT)} == {15}
    assert len(board.reports_with_command(AOUT)) == 50
    assert board.pin_volts(15) == pytest.approx(0.0, abs=1e-3)
    text = format_report(report)
    assert "one output report: 1.300 ms measured" in text
    assert "rigs/rsst.yaml states report_time_s 1 ms" in text
    assert "a 10 ms tick at 100 Hz holds 6 joints" in text  # floor(10 / 1.3) = 7 reports: 6 AOUT + 1 sync
    assert "set report_time_s: 0.0013 in rigs/rsst.yaml" in text


def test_a_report_time_within_the_rig_files_needs_no_change() -> None:
    clock = ManualClock()
    board = make_usb3105(serial="AO000001", report_time_s=0.0008, advance=clock.advance)
    report = hardware_check(
        backend=FakeBackend(board), blink_count=0, timing=RSST_TIMING, timing_reports=20, clock=clock
    )
    text = format_report(report)
    assert "one output report: 0.800 ms measured" in text and "holds 11 joints" in text
    assert "set report_time_s" not in text


def test_no_output_is_written_when_every_channel_is_a_joints_or_the_wiring_is_unknown() -> None:
    timing = OutputTiming("lab_rig.yaml", 0.001, 100.0, frozenset(range(16)))
    for given in (timing, None):
        board = make_usb3105(serial="AO000001")
        report = hardware_check(backend=FakeBackend(board), blink_count=0, timing=given)
        assert report.boards[0].report_time_s is None and board.reports_with_command(AOUT) == []
