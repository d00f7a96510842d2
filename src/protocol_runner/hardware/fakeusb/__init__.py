"""Fake USB for tests and benchmarks: a pyusb backend (`FakeBackend`) and byte-level board models.

from protocol_runner.hardware.fakeusb import FakeBackend, make_usb3105
board = make_usb3105(serial="01A2B3C4")
ao = Usb3105.open(backend=FakeBackend(board))
"""

from protocol_runner.hardware.fakeusb.backend import (
    EndpointSpec,
    FakeBackend,
    FakeUsbDevice,
    Faults,
    InterfaceSpec,
    Stall,
)
from protocol_runner.hardware.fakeusb.usb3105 import Usb3105Model, make_usb3105

__all__ = [
    "EndpointSpec",
    "FakeBackend",
    "FakeUsbDevice",
    "Faults",
    "InterfaceSpec",
    "Stall",
    "Usb3105Model",
    "make_usb3105",
]
