"""What a fake device's USB descriptors say: who it is (`UsbIdentity`), its interfaces and endpoints, and
the standard descriptor records the fake backend hands pyusb, built from one table of their layouts."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

ENDPOINT_BULK = 0x02
ENDPOINT_INTERRUPT = 0x03


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


def single_interface(
    interface_class: int, transfer_type: int, addresses: tuple[int, ...], packet_size: int = 64
) -> list[InterfaceSpec]:
    """The one interface (number 0) of a model whose endpoints all share one transfer type and packet size,
    `addresses` in descriptor order."""
    return [
        InterfaceSpec(0, interface_class, [EndpointSpec(a, transfer_type, packet_size) for a in addresses])
    ]


class UsbIdentity(NamedTuple):
    """What a model's device descriptor and strings say it is (its serial is per device)."""

    vendor_id: int
    product_id: int
    bcd_device: int
    manufacturer: str
    product: str


class Descriptor:
    """A descriptor object as pyusb reads it: every field given as a keyword is an attribute."""

    def __init__(self, **fields: Any) -> None:
        self.__dict__.update(fields)


LAYOUTS: dict[str, str] = {
    "device": "bLength=18 bDescriptorType=1 bcdUSB=0x0200 bDeviceClass=0 bDeviceSubClass=0 bDeviceProtocol=0 "
    "bMaxPacketSize0=64 idVendor idProduct bcdDevice iManufacturer=1 iProduct=2 iSerialNumber=3 "
    "bNumConfigurations=1 address bus port_number=None port_numbers=None speed=None",
    "configuration": "bLength=9 bDescriptorType=2 wTotalLength bNumInterfaces bConfigurationValue=1 "
    "iConfiguration=0 bmAttributes=0x80 bMaxPower=50 extra_descriptors=[]",
    "interface": "bLength=9 bDescriptorType=4 bInterfaceNumber bAlternateSetting=0 bNumEndpoints "
    "bInterfaceClass bInterfaceSubClass bInterfaceProtocol iInterface=0 extra_descriptors=[]",
    "endpoint": "bLength=7 bDescriptorType=5 bEndpointAddress bmAttributes wMaxPacketSize bInterval "
    "bRefresh=0 bSynchAddress=0 extra_descriptors=[]",
}
"""The standard descriptors (USB 2.0 §9.6) in wire order, then the attributes pyusb's backends add. A field
with ``=value`` is the same for every fake device; a bare field takes the next value given to `descriptor`."""


def _fixed_value(text: str) -> int | list[object] | None:
    if text == "None":
        return None
    if text == "[]":
        return []
    return int(text, 0)


def descriptor(kind: str, *values: object) -> Descriptor:
    """The `kind` descriptor ("device", "configuration", "interface", "endpoint") of `LAYOUTS`, its bare
    fields taken from `values` in order."""
    items = [item.partition("=") for item in LAYOUTS[kind].split()]
    fields: dict[str, object] = dict(
        zip([name for name, fixed, _ in items if not fixed], values, strict=True)
    )
    fields.update({name: _fixed_value(text) for name, fixed, text in items if fixed})
    return Descriptor(**fields)
