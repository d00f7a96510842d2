"""A fake USB device for the fake backend: the base of the byte-level models and the requests they answer,
the faults to inject, and the libusb errors it raises (what its descriptors say: `fakeusb/descriptors.py`)."""

from __future__ import annotations

import errno
from dataclasses import dataclass, field
from typing import Any, ClassVar, Self

import usb.core

from tests.fakeusb.descriptors import EndpointSpec, InterfaceSpec, UsbIdentity

LIBUSB_ERROR_ACCESS = -3
LIBUSB_ERROR_NO_DEVICE = -4
LIBUSB_ERROR_BUSY = -6
LIBUSB_ERROR_TIMEOUT = -7
LIBUSB_ERROR_PIPE = -9


def access_denied() -> usb.core.USBError:
    return usb.core.USBError("Access denied (insufficient permissions)", LIBUSB_ERROR_ACCESS, errno.EACCES)


def resource_busy() -> usb.core.USBError:
    return usb.core.USBError("Resource busy", LIBUSB_ERROR_BUSY, errno.EBUSY)


def no_device() -> usb.core.USBError:
    return usb.core.USBError(
        "No such device (it may have been disconnected)", LIBUSB_ERROR_NO_DEVICE, errno.ENODEV
    )


def timed_out() -> usb.core.USBTimeoutError:
    return usb.core.USBTimeoutError("Operation timed out", LIBUSB_ERROR_TIMEOUT, errno.ETIMEDOUT)


def pipe_error() -> usb.core.USBError:
    return usb.core.USBError("Pipe error", LIBUSB_ERROR_PIPE, errno.EPIPE)


class Stall(Exception):
    """Raised by a device model to stall a request (the host sees a pipe error, errno 32)."""


@dataclass
class Faults:
    """Faults to inject into one fake device.

    - `access_denied_on_open` / `access_denied_on_claim`: errno 13 (no udev rule).
    - `busy_on_claim`: errno 16 (another program holds the interface).
    - `timeout_after_transfers`: every data transfer after this many succeeds no more: USBTimeoutError.
    - `vanish_after_transfers`: after this many data transfers the device is gone: errno 19 from then on.
    Data transfers are control requests other than standard descriptor reads, plus every interrupt and
    bulk transfer.
    """

    access_denied_on_open: bool = False
    access_denied_on_claim: bool = False
    busy_on_claim: bool = False
    timeout_after_transfers: int | None = None
    vanish_after_transfers: int | None = None


@dataclass(frozen=True)
class Setup:
    """The setup packet of a (non-standard) control request, less its length (USB 2.0 §9.3)."""

    request_type: int
    request: int
    value: int
    index: int


@dataclass(eq=False)
class FakeUsbDevice:
    """Base of the byte-level device models. Subclasses state their board's `IDENTITY` and override the
    `handle_*` methods; their factories go through `make`.

    Models never sleep: a read with no data ready raises the timeout at once.
    """

    IDENTITY: ClassVar[UsbIdentity]

    vendor_id: int
    product_id: int
    serial: str
    bcd_device: int = 0x0100
    manufacturer: str = "Fake"
    product: str = "Fake device"
    interfaces: list[InterfaceSpec] = field(default_factory=list)
    faults: Faults = field(default_factory=Faults)
    kernel_driver_on: set[int] = field(default_factory=set)
    bus: int = 1
    address: int = 1

    @classmethod
    def make(cls, serial: str, faults: Faults | None = None, **fields: Any) -> Self:
        """A model of the board's `IDENTITY` (a field of it given in `fields` replaces it) with `serial`
        and `faults` (none by default)."""
        identity = {name: fields.pop(name, value) for name, value in cls.IDENTITY._asdict().items()}
        return cls(**identity, serial=serial, faults=faults or Faults(), **fields)

    def __post_init__(self) -> None:
        self.gone = False
        self.transfer_count = 0
        self.claimed: set[int] = set()
        self.open_handles = 0
        self.halted: set[int] = set()
        self.transfer_log: list[tuple[str, int, bytes]] = []
        self.keep_transfer_log = True

    # ---- overridable behaviour -------------------------------------------------------------------
    def handle_control_in(self, setup: Setup, length: int) -> bytes:
        """Answer an IN control request (non-standard). Raise `Stall` to refuse it."""
        raise Stall()

    def handle_control_out(self, setup: Setup, data: bytes) -> None:
        """Accept an OUT control request (non-standard). Raise `Stall` to refuse it."""
        raise Stall()

    def handle_write(self, endpoint: int, data: bytes) -> None:
        """Accept data written to an OUT endpoint."""
        raise Stall()

    def handle_read(self, endpoint: int, size: int) -> bytes | None:
        """Return the next data on an IN endpoint (at most `size` bytes), or None when nothing is ready."""
        return None

    # ---- helpers ---------------------------------------------------------------------------------
    def unplug(self) -> None:
        """The cable is pulled: every further call fails with errno 19."""
        self.gone = True

    def strings(self) -> dict[int, str]:
        return {1: self.manufacturer, 2: self.product, 3: self.serial}

    def count_transfer(self) -> None:
        """Apply the transfer-count faults; called before every data transfer."""
        if self.gone:
            raise no_device()
        self.transfer_count += 1
        f = self.faults
        if f.vanish_after_transfers is not None and self.transfer_count > f.vanish_after_transfers:
            self.gone = True
            raise no_device()
        if f.timeout_after_transfers is not None and self.transfer_count > f.timeout_after_transfers:
            raise timed_out()

    def endpoint(self, address: int) -> EndpointSpec | None:
        for intf in self.interfaces:
            for ep in intf.endpoints:
                if ep.address == address:
                    return ep
        return None
