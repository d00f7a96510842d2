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
import contextlib
from collections.abc import Iterator

import usb.backend
import usb.core

from tests.fakeusb.descriptors import Descriptor, descriptor
from tests.fakeusb.device import (
    FakeUsbDevice,
    Setup,
    Stall,
    access_denied,
    no_device,
    pipe_error,
    resource_busy,
    timed_out,
)


class _Handle:
    def __init__(self, device: FakeUsbDevice) -> None:
        self.device = device
        self.claimed: set[int] = set()
        self.open = True


def _present(dev_handle: _Handle) -> FakeUsbDevice:
    """The handle's device; errno 19 once it is unplugged."""
    if dev_handle.device.gone:
        raise no_device()
    return dev_handle.device


def _claimable(dev_handle: _Handle) -> FakeUsbDevice:
    """The handle's device, when it lets its interfaces be taken (errno 13 without a udev rule)."""
    dev = _present(dev_handle)
    if dev.faults.access_denied_on_claim:
        raise access_denied()
    return dev


@contextlib.contextmanager
def _halt_on_stall(dev: FakeUsbDevice, ep: int) -> Iterator[None]:
    """A model's `Stall` halts the endpoint: the host sees a pipe error (errno 32) until `clear_halt`."""
    try:
        yield
    except Stall:
        dev.halted.add(ep)
        raise pipe_error() from None


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

    def get_device_descriptor(self, dev: FakeUsbDevice) -> Descriptor:
        return descriptor("device", dev.vendor_id, dev.product_id, dev.bcd_device, dev.address, dev.bus)

    def get_configuration_descriptor(self, dev: FakeUsbDevice, config: int) -> Descriptor:
        if config != 0:
            raise IndexError("configuration index out of range")
        n_eps = sum(len(i.endpoints) for i in dev.interfaces)
        return descriptor("configuration", 9 + 9 * len(dev.interfaces) + 7 * n_eps, len(dev.interfaces))

    def get_interface_descriptor(self, dev: FakeUsbDevice, intf: int, alt: int, config: int) -> Descriptor:
        if config != 0 or alt != 0 or not 0 <= intf < len(dev.interfaces):
            raise IndexError("interface index out of range")
        spec = dev.interfaces[intf]
        n_eps = len(spec.endpoints)
        return descriptor("interface", spec.number, n_eps, spec.interface_class, spec.subclass, spec.protocol)

    def get_endpoint_descriptor(
        self, dev: FakeUsbDevice, ep: int, intf: int, alt: int, config: int
    ) -> Descriptor:
        spec = dev.interfaces[intf].endpoints[ep]
        return descriptor("endpoint", spec.address, spec.transfer_type, spec.max_packet_size, spec.interval)

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
        _present(dev_handle)

    def get_configuration(self, dev_handle: _Handle) -> int:
        _present(dev_handle)
        return 1

    def set_interface_altsetting(self, dev_handle: _Handle, intf: int, altsetting: int) -> None:
        _present(dev_handle)

    def claim_interface(self, dev_handle: _Handle, intf: int) -> None:
        dev = _claimable(dev_handle)
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
        return intf in _present(dev_handle).kernel_driver_on

    def detach_kernel_driver(self, dev_handle: _Handle, intf: int) -> None:
        _claimable(dev_handle).kernel_driver_on.discard(intf)

    def attach_kernel_driver(self, dev_handle: _Handle, intf: int) -> None:
        dev_handle.device.kernel_driver_on.add(intf)

    def clear_halt(self, dev_handle: _Handle, ep: int) -> None:
        _present(dev_handle).halted.discard(ep)

    def reset_device(self, dev_handle: _Handle) -> None:
        _present(dev_handle)

    # ---- transfers -------------------------------------------------------------------------------------
    def _start_transfer(self, dev_handle: _Handle, ep: int, intf: int) -> FakeUsbDevice:
        """The device, for a data transfer on endpoint `ep`: the interface claimed, the transfer counted
        (`Faults`), the pipe not halted."""
        if intf not in dev_handle.claimed:
            # pyusb claims implicitly; reaching here means the claim failed earlier
            raise resource_busy()
        dev = dev_handle.device
        dev.count_transfer()
        if ep in dev.halted:
            raise pipe_error()
        return dev

    def _write(self, dev_handle: _Handle, ep: int, intf: int, data: array.array[int]) -> int:
        dev = self._start_transfer(dev_handle, ep, intf)
        payload = data.tobytes()
        if dev.keep_transfer_log:
            dev.transfer_log.append(("write", ep, payload))
        with _halt_on_stall(dev, ep):
            dev.handle_write(ep, payload)
        return len(payload)

    def _read(self, dev_handle: _Handle, ep: int, intf: int, buff: array.array[int]) -> int:
        dev = self._start_transfer(dev_handle, ep, intf)
        size = len(buff) * buff.itemsize
        with _halt_on_stall(dev, ep):
            data = dev.handle_read(ep, size)
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
        setup = Setup(bmRequestType, bRequest, wValue, wIndex)
        try:
            if is_in:
                length = len(data) * data.itemsize
                reply = dev.handle_control_in(setup, length)
                n = min(len(reply), length)
                memoryview(data).cast("B")[:n] = reply[:n]
                if dev.keep_transfer_log:
                    dev.transfer_log.append(("ctrl_in", bRequest, bytes(reply[:n])))
                return n
            payload = data.tobytes()
            if dev.keep_transfer_log:
                dev.transfer_log.append(("ctrl_out", bRequest, payload))
            dev.handle_control_out(setup, payload)
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
