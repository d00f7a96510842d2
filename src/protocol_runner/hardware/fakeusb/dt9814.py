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

from protocol_runner.hardware.fakeusb.device import (
    ENDPOINT_BULK,
    FakeUsbDevice,
    Faults,
    Stall,
    UsbIdentity,
    single_interface,
)

VENDOR_ID = 0x0867
FAKE_PRODUCT_ID = 0x9814  # a stand-in: the DT9814's real product id is not public
IDENTITY = UsbIdentity(VENDOR_ID, FAKE_PRODUCT_ID, 0x0100, "Data Translation", "DT9814")
BOARD_INFO_ADDR = 0xFBFF

OP_R_FLASH_DATA = 1
OP_R_MULTI_BYTE_REG = 4
OP_W_MULTI_BYTE_REG = 5
OP_RMW_MULTI_BYTE_REG = 7

SFR_P1 = 0x90
SFR_ADC0CF = 0xBC
SFR_ADC0L = 0xBE
SFR_ADC0H = 0xBF
SFR_ADC0CN = 0xE8
ADC0CN_AD0BUSY = 0x10
ADC0CN_AD0INT = 0x20

# endpoint addresses in descriptor order: message-IN, command-OUT, command-IN, stream-OUT, stream-IN
DEFAULT_ENDPOINTS = (0x81, 0x01, 0x82, 0x02, 0x83)


def volts_to_code12(volts: float) -> int:
    """12-bit two's complement +-10 V code: ``round(V * 4096 / 20)`` clamped to -2048..2047."""
    return max(-2048, min(2047, round(volts * 4096.0 / 20.0)))


@dataclass(eq=False)
class Dt9814Model(FakeUsbDevice):
    """A fake DT9814 (DT9812 protocol). `endpoints` gives the five endpoint addresses in descriptor order."""

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

    @property
    def command_out(self) -> int:
        return self.endpoints[1]

    @property
    def command_in(self) -> int:
        return self.endpoints[2]

    def handle_write(self, endpoint: int, data: bytes) -> None:
        if endpoint != self.command_out:
            raise Stall()
        if len(data) != 32:  # the DT9812 only responds to 32-byte writes
            self.ignored_writes.append(data)
            return
        self.commands.append(data)
        opcode = struct.unpack_from("<I", data)[0]
        body = data[4:]
        if opcode == OP_R_FLASH_DATA:
            count, address = struct.unpack_from("<HH", body)
            self.replies.append(bytes(self.flash[address : address + count]))
        elif opcode == OP_R_MULTI_BYTE_REG:
            count = body[0]
            self.replies.append(bytes(self.registers[a] for a in body[1 : 1 + count]))
        elif opcode == OP_W_MULTI_BYTE_REG:
            count = body[0]
            for i in range(count):
                self._write_register(body[1 + 2 * i], body[2 + 2 * i])
        elif opcode == OP_RMW_MULTI_BYTE_REG:
            count = body[0]
            for i in range(count):
                addr, mask, value = body[1 + 3 * i : 4 + 3 * i]
                self._write_register(addr, (self.registers[addr] & ~mask & 0xFF) | (value & mask))
        else:
            self.ignored_writes.append(data)

    def _write_register(self, address: int, value: int) -> None:
        self.registers[address] = value
        if address == SFR_ADC0CN and value & ADC0CN_AD0BUSY:
            channel = (self.registers[SFR_P1] >> 5) & 0x07
            code = volts_to_code12(self.signal(self.clock(), channel))
            self.conversions.append(channel)
            raw = code & 0x0FFF
            self.registers[SFR_ADC0H] = raw >> 8
            self.registers[SFR_ADC0L] = raw & 0xFF
            self.registers[SFR_ADC0CN] = (value & ~ADC0CN_AD0BUSY) | ADC0CN_AD0INT

    def handle_read(self, endpoint: int, size: int) -> bytes | None:
        if endpoint != self.command_in:
            return None
        if not self.replies:
            return None
        return self.replies.popleft()[:size]


def make_dt9814(
    *,
    product_id: int = FAKE_PRODUCT_ID,
    serial_number: int = 12345678,
    device_id: int = 0x0000,
    signal: Callable[[float, int], float] | None = None,
    faults: Faults | None = None,
    endpoints: tuple[int, ...] = DEFAULT_ENDPOINTS,
) -> Dt9814Model:
    return Dt9814Model(
        **IDENTITY._replace(product_id=product_id)._asdict(),
        serial=str(serial_number),
        serial_number=serial_number,
        device_id=device_id,
        signal=signal or (lambda t, ch: 0.0),
        faults=faults or Faults(),
        endpoints=endpoints,
    )
