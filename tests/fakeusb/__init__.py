"""Fake USB for tests and benchmarks: a pyusb backend (`FakeBackend`) and byte-level board models.

    from tests.fakeusb.backend import FakeBackend
    from tests.fakeusb.usb3105 import make_usb3105

    board = make_usb3105(serial="01A2B3C4")
    ao = Usb3105.open(backend=FakeBackend(board))

Models: `make_usb3105` (USB-3105 analog output), `make_usb1608fs` (USB-1608FS-Plus scans, with
`ManualClock` for simulated time), `make_dt9814` (DT9814 speaking the UNVERIFIED DT9812 protocol).
Faults: `Faults` per device, `FakeBackend.unplug(model)`.
"""
