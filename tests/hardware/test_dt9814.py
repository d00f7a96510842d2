"""DT9814 driver (UNVERIFIED DT9812 protocol) against the fake DT9812-protocol board."""

from __future__ import annotations

import logging
import struct

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.conversions import ai12_code_to_volts
from protocol_runner.hardware.dt9814 import Dt9814, Dt9814Settings, sign_extend_12
from protocol_runner.hardware.usb_common import BoardIoError, BoardNotFound, BoardTimeout, DeviceGone
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.device import Faults
from tests.fakeusb.dt9814 import make_dt9814


def test_conversion_is_twos_complement_20_v_over_4096() -> None:
    assert ai12_code_to_volts(2047) == pytest.approx(9.99512, abs=1e-5)
    assert ai12_code_to_volts(-2048) == -10.0
    assert ai12_code_to_volts(1) == pytest.approx(4.883e-3, abs=1e-6)
    assert sign_extend_12(0x800) == -2048
    assert sign_extend_12(0x7FF) == 2047
    assert sign_extend_12(0xFFF) == -1


def test_open_reads_identity_from_flash_with_32_byte_commands(caplog: pytest.LogCaptureFixture) -> None:
    model = make_dt9814(product_id=0x1234, serial_number=987654, device_id=0x0003)
    with caplog.at_level(logging.WARNING):
        dt = Dt9814.open(backend=FakeBackend(model))
    assert "UNVERIFIED" in caplog.text
    assert (dt.info.vendor_id, dt.info.product_id, dt.info.device_id) == (0x0867, 0x1234, 0x0003)
    assert dt.serial == "987654"
    flash_reads = [c for c in model.commands if struct.unpack_from("<I", c)[0] == 1]
    assert all(len(c) == 32 for c in model.commands)
    # offsets 1, 3, 5 (u16) and 7 (u32) after 0xFBFF
    assert [struct.unpack_from("<HH", c, 4) for c in flash_reads] == [
        (2, 0xFC00),
        (2, 0xFC02),
        (2, 0xFC04),
        (4, 0xFC06),
    ]
    assert model.ignored_writes == []
    dt.close()


def test_endpoints_are_taken_by_position_not_address() -> None:
    model = make_dt9814(endpoints=(0x85, 0x06, 0x87, 0x08, 0x89))
    dt = Dt9814.open(backend=FakeBackend(model))
    assert (dt.command_out, dt.command_in) == (0x06, 0x87)
    assert dt.info.serial_number == 12345678
    dt.close()


def test_product_id_is_a_setting() -> None:
    backend = FakeBackend(make_dt9814(product_id=0x4444))
    with pytest.raises(BoardNotFound, match="0x5555"):
        Dt9814.open(backend=backend, settings=Dt9814Settings(product_id=0x5555))
    dt = Dt9814.open(backend=backend, settings=Dt9814Settings(product_id=0x4444))
    assert dt.info.product_id == 0x4444
    dt.close()


def test_device_id_filter() -> None:
    backend = FakeBackend(make_dt9814(device_id=7))
    with pytest.raises(BoardIoError, match="device id 0x0007"):
        Dt9814.open(backend=backend, settings=Dt9814Settings(accepted_device_ids=(0, 1)))


def test_select_by_flash_serial() -> None:
    a, b = make_dt9814(serial_number=111), make_dt9814(serial_number=222)
    dt = Dt9814.open(serial="222", backend=FakeBackend(a, b))
    assert dt.serial == "222"
    dt.close()
    with pytest.raises(BoardNotFound, match="111"):
        Dt9814.open(serial="333", backend=FakeBackend(a, b))


@pytest.mark.parametrize("volts", [-10.0, -3.3, 0.0, 0.004, 2.5, 9.99])
def test_single_sample_read_returns_the_signed_code(volts: float) -> None:
    model = make_dt9814(signal=lambda t, ch: volts if ch == 5 else 0.0)
    dt = Dt9814.open(backend=FakeBackend(model))
    code = dt.read_code(5)
    assert code == max(-2048, min(2047, round(volts * 4096 / 20)))
    assert dt.read_volts(5) == pytest.approx(volts, abs=20 / 4096)
    assert model.conversions[-1] == 5
    dt.close()


def test_sample_read_sends_rmw_then_register_read() -> None:
    model = make_dt9814()
    dt = Dt9814.open(backend=FakeBackend(model))
    n = len(model.commands)
    dt.read_code(3)
    rmw, read = model.commands[n:]
    assert struct.unpack_from("<I", rmw)[0] == 7
    assert rmw[4:14] == bytes([3, 0xBC, 0x07, 0x01, 0x90, 0xE0, 3 << 5, 0xE8, 0xFF, 0x90])
    assert struct.unpack_from("<I", read)[0] == 4
    assert read[4:8] == bytes([3, 0xE8, 0xBF, 0xBE])
    dt.close()


def test_channels_beyond_the_known_mux_are_refused() -> None:
    dt = Dt9814.open(backend=FakeBackend(make_dt9814()))
    with pytest.raises(InvalidInput, match="n_channels"):
        dt.read_code(8)
    dt.close()


def test_not_a_dt9812_family_board() -> None:
    model = make_dt9814(endpoints=(0x81, 0x01))
    with pytest.raises(BoardIoError, match="5 expected"):
        Dt9814.open(backend=FakeBackend(model))
    assert model.claimed == set()


def test_errors_are_mapped() -> None:
    with pytest.raises(BoardNotFound, match="DT9814"):
        Dt9814.open(backend=FakeBackend())
    with pytest.raises(BoardTimeout):
        Dt9814.open(backend=FakeBackend(make_dt9814(faults=Faults(timeout_after_transfers=0))))
    model = make_dt9814()
    dt = Dt9814.open(backend=FakeBackend(model))
    model.faults.vanish_after_transfers = model.transfer_count
    with pytest.raises(DeviceGone):
        dt.read_code(0)
    dt.close()
