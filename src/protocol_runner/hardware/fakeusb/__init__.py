"""Fake USB for tests and benchmarks: a pyusb backend (`FakeBackend`) and byte-level board models.

    from protocol_runner.hardware.fakeusb import FakeBackend, make_usb3105
    board = make_usb3105(serial="01A2B3C4")
    ao = Usb3105.open(backend=FakeBackend(board))

Models: `make_usb3105` (USB-3105 analog output), `make_usb1608fs` (USB-1608FS-Plus scans, with
`ManualClock` for simulated time), `make_dt9814` (DT9814 speaking the UNVERIFIED DT9812 protocol).
Faults: `Faults` per device, `FakeBackend.unplug(model)`.
"""

from protocol_runner.hardware.fakeusb.backend import FakeBackend
from protocol_runner.hardware.fakeusb.descriptors import EndpointSpec, InterfaceSpec
from protocol_runner.hardware.fakeusb.device import FakeUsbDevice, Faults, Stall
from protocol_runner.hardware.fakeusb.dt9814 import Dt9814Model, make_dt9814
from protocol_runner.hardware.fakeusb.usb1608fs import ManualClock, Usb1608FsModel, make_usb1608fs
from protocol_runner.hardware.fakeusb.usb3105 import Usb3105Model, make_usb3105

__all__ = [
    "Dt9814Model",
    "EndpointSpec",
    "FakeBackend",
    "FakeUsbDevice",
    "Faults",
    "InterfaceSpec",
    "ManualClock",
    "Stall",
    "Usb1608FsModel",
    "Usb3105Model",
    "make_dt9814",
    "make_usb1608fs",
    "make_usb3105",
]
