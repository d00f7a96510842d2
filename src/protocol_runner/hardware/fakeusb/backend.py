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
from collections.abc import Iterator
from typing import Any

import usb.backend
import usb.core

from protocol_runner.hardware.fakeusb.device import (
    FakeUsbDevice,
    Stall,
    access_denied,
    no_device,
    pipe_error,
    resource_busy,
    timed_out,
)


# libusb error codes (what USBError.backend_error_code holds with the libusb1 backend)
class _Descriptor:
    """A descriptor object: every field given as a keyword is an attribute."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)


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
