"""Byte-level model of a DT9814 speaking the DT9812-family protocol as the Linux comedi driver implements it.

UNVERIFIED: nobody has checked that a DT9814 speaks this protocol. The model follows the DT9812 facts:
one interface with five bulk endpoints in this order: message-IN, command-OUT, command-IN, stream-OUT,
stream-IN; every command is exactly 32 bytes (u32 LE opcode + payload; other lengths are ignored);
opcode 1 reads flash (u16 count, u16 address); opcode 4 reads registers (u8 count, u8 addresses);
opcode 5 writes registers (u8 count, (address, value) pairs); opcode 7 read-modify-writes registers
(u8 count, (address, mask, value) triples; the bits in `mask` take the bits of `value`). Writing AD0BUSY
in ADC0CN converts the channel selected by P1 bits 5-7 into ADC0H:ADC0L as a 12-bit two's-complement
code (``code = round(V * 4096 / 20)``) and sets AD0INT.
"""

from __future__ import annotations

import struct
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

from tests.fakeusb.descriptors import ENDPOINT_BULK, UsbIdentity, single_interface
from tests.fakeusb.device import FakeUsbDevice, Faults, Stall

BOARD_INFO_ADDR = 0xFBFF

SFR = {"P1": 0x90, "ADC0CF": 0xBC, "ADC0L": 0xBE, "ADC0H": 0xBF, "ADC0CN": 0xE8}
"""The 8051 special function registers of the protocol, by name: address."""
ADC0CN_BITS = {"AD0BUSY": 0x10, "AD0INT": 0x20}

ENDPOINT_ROLES = ("message_in", "command_out", "command_in", "stream_out", "stream_in")
"""The five bulk endpoints by role, in descriptor order."""
DEFAULT_ENDPOINTS = (0x81, 0x01, 0x82, 0x02, 0x83)


def volts_to_code12(volts: float) -> int:
    """12-bit two's complement +-10 V code: ``round(V * 4096 / 20)`` clamped to -2048..2047."""
    return max(-2048, min(2047, round(volts * 4096.0 / 20.0)))


@dataclass(eq=False)
class Dt9814Model(FakeUsbDevice):
    """A fake DT9814 (DT9812 protocol). `endpoints` gives the five endpoint addresses in descriptor order."""

    IDENTITY: ClassVar[UsbIdentity] = UsbIdentity(0x0867, 0x9814, 0x0100, "Data Translation", "DT9814")
    """Data Translation's vendor id; product id 0x9814 is a stand-in (the DT9814's real one is not public)."""

    device_id: int = 0x0000
    serial_number: int = 12345678
    endpoints: tuple[int, ...] = DEFAULT_ENDPOINTS
    signal: Callable[[float, int], float] = lambda t, ch: 0.0
    clock: Callable[[], float] = time.monotonic

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.interfaces:
            self.interfaces = single_interface(0xFF, ENDPOINT_BULK, self.endpoints)
        self.flash = bytearray(b"\xff" * 0x10000)
        struct.pack_into(
            "<HHHI",
            self.flash,
            BOARD_INFO_ADDR + 1,
            self.vendor_id,
            self.product_id,
            self.device_id,
            self.serial_number,
        )
        self.registers = bytearray(256)
        self.replies: deque[bytes] = deque()
        self.commands: list[bytes] = []
        self.ignored_writes: list[bytes] = []
        self.conversions: list[int] = []

    def pipe(self, role: str) -> int:
        """The address of the endpoint with `role` (`ENDPOINT_ROLES`): taken by position, not address."""
        return self.endpoints[ENDPOINT_ROLES.index(role)]

    def handle_write(self, endpoint: int, data: bytes) -> None:
        if endpoint != self.pipe("command_out"):
            raise Stall()
        if len(data) != 32:  # the DT9812 only responds to 32-byte writes
            self.ignored_writes.append(data)
            return
        self.commands.append(data)
        opcode = struct.unpack_from("<I", data)[0]
        handler = self._opcodes().get(opcode)
        if handler is None:
            self.ignored_writes.append(data)
            return
        handler(data[4:])

    def _opcodes(self) -> dict[int, Callable[[bytes], None]]:
        """The commands the model obeys, by opcode: 1 reads flash, 4 reads registers, 5 writes registers,
        7 read-modify-writes registers."""
        return {
            1: self._read_flash,
            4: self._read_registers,
            5: self._write_registers,
            7: self._modify_registers,
        }

    def _read_flash(self, body: bytes) -> None:
        count, address = struct.unpack_from("<HH", body)
        self.replies.append(bytes(self.flash[address : address + count]))

    def _read_registers(self, body: bytes) -> None:
        self.replies.append(bytes(self.registers[a] for a in body[1 : 1 + body[0]]))

    def _write_registers(self, body: bytes) -> None:
        for i in range(body[0]):
            self._write_register(body[1 + 2 * i], body[2 + 2 * i])

    def _modify_registers(self, body: bytes) -> None:
        for i in range(body[0]):
            addr, mask, value = body[1 + 3 * i : 4 + 3 * i]
            self._write_register(addr, (self.registers[addr] & ~mask & 0xFF) | (value & mask))

    def _write_register(self, address: int, value: int) -> None:
        self.registers[address] = value
        busy, done = ADC0CN_BITS["AD0BUSY"], ADC0CN_BITS["AD0INT"]
        if address == SFR["ADC0CN"] and value & busy:
            channel = (self.registers[SFR["P1"]] >> 5) & 0x07
            code = volts_to_code12(self.signal(self.clock(), channel))
            self.conversions.append(channel)
            raw = code & 0x0FFF
            self.registers[SFR["ADC0H"]] = raw >> 8
            self.registers[SFR["ADC0L"]] = raw & 0xFF
            self.registers[SFR["ADC0CN"]] = (value & ~busy) | done

    def handle_read(self, endpoint: int, size: int) -> bytes | None:
        if endpoint != self.pipe("command_in"):
            return None
        if not self.replies:
            return None
        return self.replies.popleft()[:size]


def make_dt9814(
    *,
    product_id: int = Dt9814Model.IDENTITY.product_id,
    serial_number: int = 12345678,
    device_id: int = 0x0000,
    signal: Callable[[float, int], float] | None = None,
    faults: Faults | None = None,
    endpoints: tuple[int, ...] = DEFAULT_ENDPOINTS,
) -> Dt9814Model:
    return Dt9814Model.make(
        str(serial_number),
        faults,
        product_id=product_id,
        serial_number=serial_number,
        device_id=device_id,
        signal=signal or (lambda t, ch: 0.0),
        endpoints=endpoints,
    )
