"""A fake pyusb backend: `usb.core.find(backend=FakeBackend(...))` enumerates byte-level device models.

The backend implements the `usb.backend.IBackend` calls pyusb makes (enumeration, device, configuration,
interface and endpoint descriptors, open/close, claim/release, kernel-driver detach, control, interrupt
and bulk transfers) and forwards the data to a `FakeUsbDevice` model. The read calls fill the buffer
pyusb hands in and return the byte count, like the libusb backends.

Faults are injected per device through `Faults` and raise exactly what libusb raises:
`usb.core.USBTimeoutError` (errno 110), `usb.core.USBError` with errno 13 (access denied), 16 (busy),
19 (no such device) and 32 (pipe error / stall).
"""

from __future__ import annotations

import array
import errno
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import usb.backend
import usb.core

# libusb error codes (what USBError.backend_error_code holds with the libusb1 backend)
LIBUSB_ERROR_ACCESS = -3
LIBUSB_ERROR_NO_DEVICE = -4
LIBUSB_ERROR_BUSY = -6
LIBUSB_ERROR_TIMEOUT = -7
LIBUSB_ERROR_PIPE = -9

ENDPOINT_BULK = 0x02
ENDPOINT_INTERRUPT = 0x03


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
class EndpointSpec:
    """One endpoint descriptor: address (bit 7 set = IN), transfer type (2 bulk, 3 interrupt)."""

    address: int
    transfer_type: int
    max_packet_size: int = 64
    interval: int = 1


@dataclass
class InterfaceSpec:
    """One interface (alternate setting 0) with its endpoints in descriptor order."""

    number: int
    interface_class: int
    endpoints: list[EndpointSpec]
    subclass: int = 0
    protocol: int = 0


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


class _Descriptor:
    """A descriptor object: every field given as a keyword is an attribute."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)


@dataclass(eq=False)
class FakeUsbDevice:
    """Base of the byte-level device models. Subclasses override the `handle_*` methods.

    Models never sleep: a read with no data ready raises the timeout at once.
    """

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

    def __post_init__(self) -> None:
        self.gone = False
        self.transfer_count = 0
        self.claimed: set[int] = set()
        self.open_handles = 0
        self.halted: set[int] = set()
        self.transfer_log: list[tuple[str, int, bytes]] = []
        self.keep_transfer_log = True

    # ---- overridable behaviour -------------------------------------------------------------------
    def handle_control_in(
        self, request_type: int, request: int, value: int, index: int, length: int
    ) -> bytes:
        """Answer an IN control request (non-standard). Raise `Stall` to refuse it."""
        raise Stall()

    def handle_control_out(
        self, request_type: int, request: int, value: int, index: int, data: bytes
    ) -> None:
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


class _Handle:
    def __init__(self, device: FakeUsbDevice) -> None:
        self.device = device
        self.claimed: set[int] = set()
        self.open = True


class FakeBackend(usb.backend.IBackend):
    """pyusb backend over a list of `FakeUsbDevice` models (pass it as `backend=` to `usb.core.find`)."""

    def __init__(self, *devices: FakeUsbDevice) -> None:
        super().__init__()
        self.devices: list[FakeUsbDevice] = list(devices)

    def add(self, device: FakeUsbDevice) -> None:
        self.devices.append(device)

    def unplug(self, device: FakeUsbDevice) -> None:
        device.unplug()
        self.devices.remove(device)

    # ---- enumeration and descriptors ---------------------------------------------------------------
    def enumerate_devices(self) -> Iterator[FakeUsbDevice]:
        yield from list(self.devices)

    def get_parent(self, dev: FakeUsbDevice) -> None:
        return None

    def get_device_descriptor(self, dev: FakeUsbDevice) -> _Descriptor:
        return _Descriptor(
            bLength=18,
            bDescriptorType=1,
            bcdUSB=0x0200,
            bDeviceClass=0,
            bDeviceSubClass=0,
            bDeviceProtocol=0,
            bMaxPacketSize0=64,
            idVendor=dev.vendor_id,
            idProduct=dev.product_id,
            bcdDevice=dev.bcd_device,
            iManufacturer=1,
            iProduct=2,
            iSerialNumber=3,
            bNumConfigurations=1,
            address=dev.address,
            bus=dev.bus,
            port_number=None,
            port_numbers=None,
            speed=None,
        )

    def get_configuration_descriptor(self, dev: FakeUsbDevice, config: int) -> _Descriptor:
        if config != 0:
            raise IndexError("configuration index out of range")
        n_eps = sum(len(i.endpoints) for i in dev.interfaces)
        return _Descriptor(
            bLength=9,
            bDescriptorType=2,
            wTotalLength=9 + 9 * len(dev.interfaces) + 7 * n_eps,
            bNumInterfaces=len(dev.interfaces),
            bConfigurationValue=1,
            iConfiguration=0,
            bmAttributes=0x80,
            bMaxPower=50,
            extra_descriptors=[],
        )

    def get_interface_descriptor(self, dev: FakeUsbDevice, intf: int, alt: int, config: int) -> _Descriptor:
        if config != 0 or alt != 0 or not 0 <= intf < len(dev.interfaces):
            raise IndexError("interface index out of range")
        spec = dev.interfaces[intf]
        return _Descriptor(
            bLength=9,
            bDescriptorType=4,
            bInterfaceNumber=spec.number,
            bAlternateSetting=0,
            bNumEndpoints=len(spec.endpoints),
            bInterfaceClass=spec.interface_class,
            bInterfaceSubClass=spec.subclass,
            bInterfaceProtocol=spec.protocol,
            iInterface=0,
            extra_descriptors=[],
        )

    def get_endpoint_descriptor(
        self, dev: FakeUsbDevice, ep: int, intf: int, alt: int, config: int
    ) -> _Descriptor:
        spec = dev.interfaces[intf].endpoints[ep]
        return _Descriptor(
            bLength=7,
            bDescriptorType=5,
            bEndpointAddress=spec.address,
            bmAttributes=spec.transfer_type,
            wMaxPacketSize=spec.max_packet_size,
            bInterval=spec.interval,
            bRefresh=0,
            bSynchAddress=0,
            extra_descriptors=[],
        )

    # ---- opening and claiming -------------------------------------------------------------------------
    def open_device(self, dev: FakeUsbDevice) -> _Handle:
        if dev.gone:
            raise no_device()
        if dev.faults.access_denied_on_open:
            raise access_denied()
        dev.open_handles += 1
        return _Handle(dev)

    def close_device(self, dev_handle: _Handle) -> None:
        if dev_handle.open:
            dev_handle.open = False
            dev_handle.device.open_handles -= 1
            for i in list(dev_handle.claimed):
                dev_handle.device.claimed.discard(i)
            dev_handle.claimed.clear()

    def set_configuration(self, dev_handle: _Handle, config_value: int) -> None:
        if dev_handle.device.gone:
            raise no_device()

    def get_configuration(self, dev_handle: _Handle) -> int:
        if dev_handle.device.gone:
            raise no_device()
        return 1

    def set_interface_altsetting(self, dev_handle: _Handle, intf: int, altsetting: int) -> None:
        if dev_handle.device.gone:
            raise no_device()

    def claim_interface(self, dev_handle: _Handle, intf: int) -> None:
        dev = dev_handle.device
        if dev.gone:
            raise no_device()
        if dev.faults.access_denied_on_claim:
            raise access_denied()
        if dev.faults.busy_on_claim or intf in dev.kernel_driver_on:
            raise resource_busy()
        if intf in dev.claimed and intf not in dev_handle.claimed:
            raise resource_busy()
        dev.claimed.add(intf)
        dev_handle.claimed.add(intf)

    def release_interface(self, dev_handle: _Handle, intf: int) -> None:
        dev = dev_handle.device
        if intf in dev_handle.claimed:
            dev_handle.claimed.discard(intf)
            dev.claimed.discard(intf)
        if dev.gone:
            raise no_device()

    def is_kernel_driver_active(self, dev_handle: _Handle, intf: int) -> bool:
        if dev_handle.device.gone:
            raise no_device()
        return intf in dev_handle.device.kernel_driver_on

    def detach_kernel_driver(self, dev_handle: _Handle, intf: int) -> None:
        dev = dev_handle.device
        if dev.gone:
            raise no_device()
        if dev.faults.access_denied_on_claim:
            raise access_denied()
        dev.kernel_driver_on.discard(intf)

    def attach_kernel_driver(self, dev_handle: _Handle, intf: int) -> None:
        dev_handle.device.kernel_driver_on.add(intf)

    def clear_halt(self, dev_handle: _Handle, ep: int) -> None:
        if dev_handle.device.gone:
            raise no_device()
        dev_handle.device.halted.discard(ep)

    def reset_device(self, dev_handle: _Handle) -> None:
        if dev_handle.device.gone:
            raise no_device()

    # ---- transfers -------------------------------------------------------------------------------------
    def _check_claimed(self, dev_handle: _Handle, intf: int) -> None:
        if intf not in dev_handle.claimed:
            # pyusb claims implicitly; reaching here means the claim failed earlier
            raise resource_busy()

    def _write(self, dev_handle: _Handle, ep: int, intf: int, data: array.array[int]) -> int:
        dev = dev_handle.device
        self._check_claimed(dev_handle, intf)
        dev.count_transfer()
        if ep in dev.halted:
            raise pipe_error()
        payload = data.tobytes()
        if dev.keep_transfer_log:
            dev.transfer_log.append(("write", ep, payload))
        try:
            dev.handle_write(ep, payload)
        except Stall:
            dev.halted.add(ep)
            raise pipe_error() from None
        return len(payload)

    def _read(self, dev_handle: _Handle, ep: int, intf: int, buff: array.array[int]) -> int:
        dev = dev_handle.device
        self._check_claimed(dev_handle, intf)
        dev.count_transfer()
        if ep in dev.halted:
            raise pipe_error()
        size = len(buff) * buff.itemsize
        try:
            data = dev.handle_read(ep, size)
        except Stall:
            dev.halted.add(ep)
            raise pipe_error() from None
        if data is None:
            raise timed_out()
        n = min(len(data), size)
        memoryview(buff).cast("B")[:n] = data[:n]
        if dev.keep_transfer_log:
            dev.transfer_log.append(("read", ep, bytes(data[:n])))
        return n

    def bulk_write(
        self, dev_handle: _Handle, ep: int, intf: int, data: array.array[int], timeout: int
    ) -> int:
        return self._write(dev_handle, ep, intf, data)

    def intr_write(
        self, dev_handle: _Handle, ep: int, intf: int, data: array.array[int], timeout: int
    ) -> int:
        return self._write(dev_handle, ep, intf, data)

    def bulk_read(self, dev_handle: _Handle, ep: int, intf: int, buff: array.array[int], timeout: int) -> int:
        return self._read(dev_handle, ep, intf, buff)

    def intr_read(self, dev_handle: _Handle, ep: int, intf: int, buff: array.array[int], timeout: int) -> int:
        return self._read(dev_handle, ep, intf, buff)

    def ctrl_transfer(
        self,
        dev_handle: _Handle,
        bmRequestType: int,
        bRequest: int,
        wValue: int,
        wIndex: int,
        data: array.array[int],
        timeout: int,
    ) -> int:
        dev = dev_handle.device
        if dev.gone:
            raise no_device()
        is_in = bool(bmRequestType & 0x80)
        if bmRequestType == 0x80 and bRequest == 0x06:  # standard GET_DESCRIPTOR
            return self._get_descriptor(dev, wValue, wIndex, data)
        dev.count_transfer()
        try:
            if is_in:
                length = len(data) * data.itemsize
                reply = dev.handle_control_in(bmRequestType, bRequest, wValue, wIndex, length)
                n = min(len(reply), length)
                memoryview(data).cast("B")[:n] = reply[:n]
                if dev.keep_transfer_log:
                    dev.transfer_log.append(("ctrl_in", bRequest, bytes(reply[:n])))
                return n
            payload = data.tobytes()
            if dev.keep_transfer_log:
                dev.transfer_log.append(("ctrl_out", bRequest, payload))
            dev.handle_control_out(bmRequestType, bRequest, wValue, wIndex, payload)
            return len(payload)
        except Stall:
            raise pipe_error() from None

    def _get_descriptor(self, dev: FakeUsbDevice, value: int, index: int, data: array.array[int]) -> int:
        kind, idx = value >> 8, value & 0xFF
        if kind != 3:  # only string descriptors are read through the control pipe by pyusb
            raise pipe_error()
        if idx == 0:
            body = (0x0409).to_bytes(2, "little")
        else:
            text = dev.strings().get(idx)
            if text is None:
                raise pipe_error()
            body = text.encode("utf-16-le")
        desc = bytes([2 + len(body), 3]) + body
        length = len(data) * data.itemsize
        n = min(len(desc), length)
        memoryview(data).cast("B")[:n] = desc[:n]
        return n
