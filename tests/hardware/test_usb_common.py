"""Shared USB plumbing: error mapping, the udev rule, the real clock, and the fake pyusb backend itself."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest
import usb.core
import usb.util

from protocol_runner.errors import EXIT_HARDWARE_UNAVAILABLE, HardwareUnavailable
from protocol_runner.hardware import discovery, dt9814, usb1608fs, usb1608fs_protocol, usb3105
from protocol_runner.hardware.interfaces import Clock
from protocol_runner.hardware.usb_common import (
    DT_VENDOR_ID,
    MCC_VENDOR_ID,
    UDEV_RULE_FILENAME,
    BoardBusy,
    BoardIoError,
    BoardPermissionDenied,
    BoardTimeout,
    DeviceGone,
    MonotonicClock,
    NoUsbBackend,
    bcd_to_text,
    map_usb_error,
    realtime_priority,
    udev_rule_text,
)
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.usb1608fs import make_usb1608fs
from tests.fakeusb.usb3105 import make_usb3105

RULE_FILE = Path(__file__).resolve().parents[2] / "packaging" / "udev" / UDEV_RULE_FILENAME


@pytest.mark.parametrize(
    ("exc", "kind", "words"),
    [
        (
            usb.core.USBTimeoutError("Operation timed out", -7, errno.ETIMEDOUT),
            BoardTimeout,
            "did not answer",
        ),
        (usb.core.USBError("Access denied", -3, errno.EACCES), BoardPermissionDenied, UDEV_RULE_FILENAME),
        (usb.core.USBError("Resource busy", -6, errno.EBUSY), BoardBusy, "another program"),
        (usb.core.USBError("No such device", -4, errno.ENODEV), DeviceGone, "disappeared"),
        (usb.core.USBError("Pipe error", -9, errno.EPIPE), BoardIoError, "Pipe error"),
    ],
)
def test_usb_errors_map_to_clear_exit_3_errors(exc: usb.core.USBError, kind: type, words: str) -> None:
    err = map_usb_error(exc, "USB-3105 serial X", "writing")
    assert type(err) is kind
    assert isinstance(err, HardwareUnavailable) and err.exit_code == EXIT_HARDWARE_UNAVAILABLE
    assert "USB-3105 serial X" in str(err) and words in str(err)


def test_the_shipped_udev_rule_is_the_generated_one_and_covers_every_driver() -> None:
    text = RULE_FILE.read_text()
    assert text == udev_rule_text()
    rules = [line for line in text.splitlines() if line and not line.startswith("#")]
    ids = {(line.split('idVendor}=="')[1][:4], [*line.split('idProduct}=="'), ""][1][:4]) for line in rules}
    assert (f"{MCC_VENDOR_ID:04x}", f"{usb3105.PRODUCT_ID:04x}") in ids
    assert (f"{MCC_VENDOR_ID:04x}", f"{usb1608fs_protocol.PRODUCT_ID:04x}") in ids
    assert (f"{DT_VENDOR_ID:04x}", "") in ids  # DT9814: product id unknown, so the whole vendor
    assert all('MODE="0660"' in r and 'TAG+="uaccess"' in r for r in rules)


def test_udev_rule_is_printable_from_an_installed_package(capsys: pytest.CaptureFixture[str]) -> None:
    assert discovery.main(["--udev-rule"]) == 0
    assert capsys.readouterr().out == udev_rule_text()


def test_missing_libusb_is_reported_once_and_plainly(monkeypatch: pytest.MonkeyPatch) -> None:
    def no_backend(*args: object, **kwargs: object) -> None:
        raise usb.core.NoBackendError("No backend available")

    monkeypatch.setattr(usb.core, "find", no_backend)
    with pytest.raises(NoUsbBackend, match="libusb"):
        usb3105.Usb3105.open()
    report = discovery.hardware_check({"analog_output": [0]})
    assert [p.kind for p in report.problems] == ["USB"]
    assert "libusb" in discovery.format_report(report)


def test_bcd_firmware_text() -> None:
    assert bcd_to_text(0x0102) == "1.02"
    assert bcd_to_text(0x1010) == "10.10"


def test_monotonic_clock_is_a_clock_and_sleeps_until_the_deadline() -> None:
    clock = MonotonicClock()
    assert isinstance(clock, Clock)
    target = clock.now_s() + 0.002
    clock.sleep_until(target)
    assert clock.now_s() >= target
    before = clock.now_s()
    clock.sleep_until(before - 1.0)  # a past deadline returns at once (no negative sleep error)
    assert clock.now_s() >= before


def test_fake_backend_exposes_real_descriptors_to_pyusb() -> None:
    backend = FakeBackend(make_usb3105(serial="01A2B3C4"), make_usb1608fs(serial="0000000A"))
    devs = list(usb.core.find(find_all=True, backend=backend))
    assert [(d.idVendor, d.idProduct) for d in devs] == [(0x09DB, 0x009E), (0x09DB, 0x00EA)]
    hid = devs[0]
    assert hid.serial_number == "01A2B3C4" and hid.product == "USB-3105"
    cfg = hid.get_active_configuration()
    intf = cfg[(0, 0)]
    assert intf.bInterfaceClass == 3
    eps = {e.bEndpointAddress: usb.util.endpoint_type(e.bmAttributes) for e in intf}
    assert eps == {0x81: usb.util.ENDPOINT_TYPE_INTR, 0x01: usb.util.ENDPOINT_TYPE_INTR}
    bulk = devs[1].get_active_configuration()[(0, 0)][0]
    assert usb.util.endpoint_direction(bulk.bEndpointAddress) == usb.util.ENDPOINT_IN
    assert usb.util.endpoint_type(bulk.bmAttributes) == usb.util.ENDPOINT_TYPE_BULK
    for d in devs:
        usb.util.dispose_resources(d)


def test_fake_read_fills_the_callers_buffer_and_times_out_when_empty() -> None:
    model = make_usb3105(stale_reports=[bytes([0x44, 1])])
    dev = usb.core.find(backend=FakeBackend(model))
    assert dev is not None
    dev.detach_kernel_driver(0)
    buf = usb.util.create_buffer(64)
    assert dev.read(0x81, buf, 10) == 2
    assert bytes(buf[:2]) == bytes([0x44, 1])
    with pytest.raises(usb.core.USBTimeoutError) as err:
        dev.read(0x81, 64, 10)
    assert err.value.errno == errno.ETIMEDOUT
    usb.util.dispose_resources(dev)


def test_fake_claim_is_busy_while_the_kernel_driver_is_bound() -> None:
    dev = usb.core.find(backend=FakeBackend(make_usb3105()))
    assert dev is not None
    with pytest.raises(usb.core.USBError) as err:
        usb.util.claim_interface(dev, 0)
    assert err.value.errno == errno.EBUSY
    usb.util.dispose_resources(dev)


def test_driver_modules_document_what_is_unverified() -> None:
    assert "UNVERIFIED" in (usb3105.__doc__ or "")
    assert "UNVERIFIED" in (dt9814.__doc__ or "")
    assert "UNVERIFIED" in (usb1608fs.__doc__ or "")


def test_realtime_priority_restores_the_previous_policy() -> None:
    before = os.sched_getscheduler(0) if hasattr(os, "sched_getscheduler") else None
    with realtime_priority(10) as granted:
        assert isinstance(granted, bool)
        if granted:
            assert os.sched_getscheduler(0) == os.SCHED_FIFO
    if before is not None:
        assert os.sched_getscheduler(0) == before
