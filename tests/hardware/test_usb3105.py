"""USB-3105 driver, tested through pyusb against the fake backend at the byte level."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest
import usb.core

from protocol_runner.errors import EXIT_HARDWARE_UNAVAILABLE, HardwareUnavailable, InvalidInput
from protocol_runner.hardware.interfaces import AnalogOutput
from protocol_runner.hardware.usb3105 import ChannelNotConfigured, Usb3105, Usb3105Settings
from protocol_runner.hardware.usb3105_calibration import ChannelCalibration, calibrated_code
from protocol_runner.hardware.usb_common import (
    UDEV_RULE_FILENAME,
    BoardBusy,
    BoardNotFound,
    BoardPermissionDenied,
    BoardTimeout,
    DeviceGone,
    UnexpectedReply,
)
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.device import Faults
from tests.fakeusb.usb3105 import Usb3105Model, make_usb3105


def open_board(model: Usb3105Model, settings: Usb3105Settings | None = None) -> Usb3105:
    return Usb3105.open(backend=FakeBackend(model), settings=settings)


def ideal_code(volts: float) -> int:
    return round(32768 + 3276.8 * volts)


# ---- opening -------------------------------------------------------------------------------------------


def test_satisfies_the_analog_output_protocol() -> None:
    ao = open_board(make_usb3105())
    assert isinstance(ao, AnalogOutput)
    ao.close()


def test_open_detaches_the_hid_driver_claims_and_reports_identity() -> None:
    model = make_usb3105(serial="0A1B2C3D", bcd_device=0x0205)
    assert model.kernel_driver_on == {0}
    ao = open_board(model)
    assert ao.kernel_driver_detached
    assert model.kernel_driver_on == set()
    assert model.claimed == {0}
    assert ao.serial == "0A1B2C3D"
    assert ao.firmware == "2.05"
    ao.close()
    assert model.claimed == set()


def test_open_selects_the_board_by_serial() -> None:
    a, b = make_usb3105(serial="AAAA0001"), make_usb3105(serial="BBBB0002")
    ao = Usb3105.open(serial="BBBB0002", backend=FakeBackend(a, b))
    assert ao.serial == "BBBB0002"
    assert b.claimed == {0} and a.claimed == set()
    ao.close()


def test_unknown_serial_names_the_attached_boards() -> None:
    with pytest.raises(BoardNotFound) as err:
        Usb3105.open(serial="NOPE", backend=FakeBackend(make_usb3105(serial="AAAA0001")))
    assert "AAAA0001" in str(err.value) and "NOPE" in str(err.value)


def test_stale_input_reports_are_drained_on_open() -> None:
    stale = [bytes([0x44, 0x01]), bytes([0x30, 1, 2, 3]), bytes([0x99])]
    model = make_usb3105(stale_reports=stale)
    ao = open_board(model)
    assert ao.stale_reports_drained == 3
    # the calibration read after the drain got real replies: calibration is the stored identity
    assert all(c.valid and c.slope == 1.0 and c.offset == 0.0 for c in ao.calibration)
    ao.close()


def test_calibration_is_read_with_mem_read_reports_from_0x108() -> None:
    model = make_usb3105()
    model.set_calibration(0, 1.002, -7.5)
    model.set_calibration(15, 0.998, 11.25)
    ao = open_board(model)
    mem_reads = model.reports_with_command(0x30)
    assert mem_reads, "calibration must be read with MEM_READ"
    first = mem_reads[0]
    assert first[0] == 0x30 and first[1] | (first[2] << 8) == 0x108 and first[3] == 0 and first[4] <= 62
    assert all(r[4] <= 62 for r in mem_reads)
    assert ao.calibration[0].slope == pytest.approx(1.002, rel=1e-6)
    assert ao.calibration[0].offset == pytest.approx(-7.5)
    assert ao.calibration[15].slope == pytest.approx(0.998, rel=1e-6)
    assert ao.calibration[15].offset == pytest.approx(11.25)
    ao.close()


def test_erased_calibration_falls_back_to_identity_and_says_so() -> None:
    model = make_usb3105()
    addr = 0x108 + 0x10 * 4
    model.memory[addr : addr + 8] = b"\xff" * 8  # erased flash: NaN floats
    ao = open_board(model)
    assert not ao.calibration[4].valid
    assert ao.calibration[4].slope == 1.0 and ao.calibration[4].offset == 0.0
    assert "15/16" in ao.calibration_summary()
    ao.close()


def test_reply_with_wrong_command_byte_is_rejected() -> None:
    model = make_usb3105()
    ao = open_board(model)
    # queue unrelated input reports: GET_STATUS must skip them and then give up with a clear error
    model.in_queue.extend(bytes([0x30, 0]) for _ in range(10))
    with pytest.raises(UnexpectedReply, match="0x44"):
        ao.get_status()
    ao.close()


# ---- the output path on the wire -------------------------------------------------------------------------


def test_write_volts_sends_exactly_the_aout_report() -> None:
    model = make_usb3105()
    ao = open_board(model)
    ao.configure_channel(3)
    n_before = len(model.reports)
    code = ao.write_volts(3, 2.5)
    k = ideal_code(2.5)
    assert code == k == 40960
    assert model.reports[n_before:] == [bytes([0x14, 3, k & 0xFF, k >> 8, 0])]
    assert model.codes[3] == k
    assert model.pin_volts(3) == pytest.approx(2.5, abs=305.2e-6)
    ao.close()


def test_configure_sends_aout_config_once_and_writes_never_do() -> None:
    model = make_usb3105()
    ao = open_board(model)
    ao.configure_channel(8)
    for i in range(50):
        ao.write_volts(8, -9.0 + 0.3 * i)
    configs = model.reports_with_command(0x1C)
    assert configs == [bytes([0x1C, 8, 1])]  # +-10 V range, once
    assert model.config_count[8] == 1
    assert len(model.reports_with_command(0x14)) == 50
    ao.close()


def test_calibration_is_applied_to_the_code_sent() -> None:
    model = make_usb3105()
    model.set_calibration(2, 1.0015, -12.0)
    ao = open_board(model)
    ao.configure_channel(2)
    slope, offset = model.calibration(2)  # float32 values as stored
    for volts in (-9.5, -1.25, 0.0, 3.3, 9.9):
        code = ao.write_volts(2, volts)
        assert code == round(slope * (32768 + 3276.8 * volts) + offset)
        assert model.reports[-1][2] | (model.reports[-1][3] << 8) == code
        # the fake DAC has the error the calibration corrects: the pin is within one LSB of the request
        assert model.pin_volts(2) == pytest.approx(volts, abs=20.0 / 65536)
    ao.close()


def test_codes_clamp_at_the_ends_of_the_range() -> None:
    assert calibrated_code(10.5, ChannelCalibration(1.0, 0.0)) == 65535
    assert calibrated_code(-10.5, ChannelCalibration(1.0, 0.0)) == 0
    assert calibrated_code(-10.0, ChannelCalibration(1.0, 0.0)) == 0
    assert calibrated_code(9.99969, ChannelCalibration(1.0, 0.0)) == 65535


def test_write_on_unconfigured_channel_is_refused_without_traffic() -> None:
    model = make_usb3105()
    ao = open_board(model)
    n = len(model.reports)
    with pytest.raises(ChannelNotConfigured, match="configure_channel"):
        ao.write_volts(5, 1.0)
    assert len(model.reports) == n
    ao.close()


@pytest.mark.parametrize("channel", [-1, 16, 99])
def test_channel_out_of_range_is_invalid_input(channel: int) -> None:
    ao = open_board(make_usb3105())
    with pytest.raises(InvalidInput):
        ao.configure_channel(channel)
    ao.close()


def test_nan_volts_is_invalid_input() -> None:
    ao = open_board(make_usb3105())
    ao.configure_channel(0)
    with pytest.raises(InvalidInput):
        ao.write_volts(0, float("nan"))
    ao.close()


def test_sync_write_holds_each_channel_then_latches_once() -> None:
    model = make_usb3105()
    ao = open_board(model)
    for ch in (1, 4, 7):
        ao.configure_channel(ch)
    n = len(model.reports)
    codes = ao.write_volts_sync({1: 1.0, 4: -2.0, 7: 5.0})
    sent = model.reports[n:]
    assert sent[:3] == [bytes([0x14, ch, codes[ch] & 0xFF, codes[ch] >> 8, 1]) for ch in (1, 4, 7)]
    assert sent[3:] == [bytes([0x15])]
    assert codes == {1: ideal_code(1.0), 4: ideal_code(-2.0), 7: ideal_code(5.0)}
    assert [model.codes[ch] for ch in (1, 4, 7)] == [codes[1], codes[4], codes[7]]
    ao.close()


def test_a_board_left_as_sync_slave_is_made_master_when_opened() -> None:
    """A slave ignores AOUT_SYNC: several joints' held updates would never reach the pins."""
    model = make_usb3105()
    assert not model.sync_master  # the fake powers up as a board another program left as slave
    ao = open_board(model)
    assert bytes([0x43, 0]) in model.reports and model.sync_master
    ao.configure_channel(2)
    codes = ao.write_volts_sync({2: 3.0})
    assert model.codes[2] == codes[2] == ideal_code(3.0)
    ao.close()


def test_held_values_do_not_reach_the_pins_before_the_sync() -> None:
    model = make_usb3105()
    ao = open_board(model)
    ao.configure_channel(0)
    ao._send(bytes([0x14, 0, 0x00, 0xA0, 1]), "test")  # a held value, no sync yet
    assert model.pin_volts(0) == pytest.approx(0.0, abs=1e-3)
    ao.close()


def test_blink_sends_the_count() -> None:
    model = make_usb3105()
    ao = open_board(model)
    ao.blink(4)
    assert model.reports[-1] == bytes([0x40, 4])
    assert model.blinks == 4
    ao.close()


def test_set_report_fallback_when_there_is_no_interrupt_out_endpoint() -> None:
    model = make_usb3105(interrupt_out=False)
    ao = open_board(model)
    assert ao.uses_set_report
    ao.configure_channel(3)
    code = ao.write_volts(3, 2.5)
    assert model.reports[-1] == bytes([0x14, 3, code & 0xFF, code >> 8, 0])
    assert ("ctrl_out", 0x09, bytes([0x14, 3, code & 0xFF, code >> 8, 0])) in model.transfer_log
    assert not model.bad_reports
    ao.close()


def test_endpoints_are_settings() -> None:
    model = make_usb3105()
    with pytest.raises(HardwareUnavailable, match="0x83"):
        open_board(model, settings=Usb3105Settings(in_endpoint=0x83))
    assert model.claimed == set()  # released after the failed open


# ---- errors ---------------------------------------------------------------------------------------------


def test_no_board_gives_the_plain_not_found_message() -> None:
    with pytest.raises(BoardNotFound) as err:
        Usb3105.open(backend=FakeBackend())
    assert str(err.value) == (
        "no USB-3105 found (VID 0x09DB PID 0x009E); is it plugged in? use --dry-run to rehearse without "
        "the rig"
    )
    assert err.value.exit_code == EXIT_HARDWARE_UNAVAILABLE


def test_other_vendor_products_are_not_taken_for_a_3105() -> None:
    other = make_usb3105()
    other.product_id = 0x009A  # a USB-3101
    with pytest.raises(BoardNotFound):
        Usb3105.open(backend=FakeBackend(other))


def test_busy_board() -> None:
    with pytest.raises(BoardBusy, match="USB-3105") as err:
        open_board(make_usb3105(faults=Faults(busy_on_claim=True)))
    assert isinstance(err.value.__cause__, usb.core.USBError) and err.value.__cause__.errno == 16
    assert err.value.exit_code == EXIT_HARDWARE_UNAVAILABLE


def test_board_already_opened_elsewhere_is_busy() -> None:
    backend = FakeBackend(make_usb3105())
    first = Usb3105.open(backend=backend)
    with pytest.raises(BoardBusy):
        Usb3105.open(backend=backend)
    first.close()


@pytest.mark.parametrize("faults", [Faults(access_denied_on_open=True), Faults(access_denied_on_claim=True)])
def test_permission_denied_names_the_udev_rule(faults: Faults) -> None:
    with pytest.raises(BoardPermissionDenied) as err:
        open_board(make_usb3105(faults=faults))
    msg = str(err.value)
    assert UDEV_RULE_FILENAME in msg and "/etc/udev/rules.d/" in msg and "udevadm" in msg
    assert err.value.exit_code == EXIT_HARDWARE_UNAVAILABLE


def test_timeout_while_reading_calibration() -> None:
    with pytest.raises(BoardTimeout, match="USB-3105") as err:
        open_board(make_usb3105(faults=Faults(timeout_after_transfers=1)))
    assert isinstance(err.value.__cause__, usb.core.USBTimeoutError)


def test_timeout_on_write() -> None:
    model = make_usb3105()
    ao = open_board(model)
    ao.configure_channel(0)
    model.faults.timeout_after_transfers = model.transfer_count
    with pytest.raises(BoardTimeout, match="writing output channel 0"):
        ao.write_volts(0, 1.0)
    ao.close()


def test_device_vanishing_mid_run_raises_device_gone() -> None:
    model = make_usb3105()
    ao = open_board(model)
    ao.configure_channel(0)
    model.faults.vanish_after_transfers = model.transfer_count + 5
    written = 0
    with pytest.raises(DeviceGone, match="disappeared") as err:
        for i in range(100):
            ao.write_volts(0, 0.01 * i)
            written += 1
    assert written == 5
    assert isinstance(err.value, HardwareUnavailable)
    cause = err.value.__cause__
    assert isinstance(cause, usb.core.USBError) and cause.errno == 19
    ao.close()  # closing a vanished board does not raise


def test_unplugged_board_raises_device_gone() -> None:
    model = make_usb3105()
    backend = FakeBackend(model)
    ao = Usb3105.open(backend=backend)
    ao.configure_channel(1)
    backend.unplug(model)
    with pytest.raises(DeviceGone):
        ao.write_volts(1, 0.5)
    ao.close()


def test_closed_board_refuses_writes() -> None:
    ao = open_board(make_usb3105())
    ao.configure_channel(0)
    ao.close()
    ao.close()  # idempotent
    with pytest.raises(HardwareUnavailable, match="closed"):
        ao.write_volts(0, 0.0)


def test_context_manager_releases_the_interface() -> None:
    model = make_usb3105()
    with open_board(model) as ao:
        ao.configure_channel(0)
        assert model.claimed == {0}
    assert model.claimed == set()


def test_calibration_memory_layout_matches_the_documented_addresses() -> None:
    model = make_usb3105()
    model.set_calibration(6, 1.25, 3.5)
    assert struct.unpack_from("<ff", model.memory, 0x108 + 0x10 * 6) == (1.25, 3.5)


def test_numpy_numbers_are_accepted() -> None:
    model = make_usb3105()
    ao = open_board(model)
    channel: Any = np.int64(2)  # what a channel read from an array looks like
    ao.configure_channel(channel)
    code = ao.write_volts(channel, np.float64(-2.5))
    assert type(code) is int and code == ideal_code(-2.5)
    assert model.reports[-1] == bytes([0x14, 2, code & 0xFF, code >> 8, 0])
    ao.close()
