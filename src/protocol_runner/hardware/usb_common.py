"""What the USB drivers share: the error types, pyusb error mapping, device lookup, interface claiming,
the output channel and volts checks, and a real monotonic clock.

Every USB failure reaches the user as a `protocol_runner.errors.HardwareUnavailable` subclass (exit status
3) whose message names the board and says what to do about it. `map_usb_error` maps the `errno` of
libusb's `usb.core.USBError` (the Linux numbers: 13 access, 16 busy, 19 no device, 110 timeout; docs/
hardware.md, "Errors") to `BoardPermissionDenied`, `BoardBusy`, `DeviceGone`, `BoardTimeout`, and
anything else to `BoardIoError`.
"""

from __future__ import annotations

import contextlib
import errno as errno_codes
import logging
import math
import operator
import os
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

import usb.core
import usb.util

from protocol_runner.errors import HardwareUnavailable, InvalidInput

UDEV_RULE_FILENAME = "60-protocol-runner-daq.rules"
"""The udev rule shipped in `packaging/udev/` that lets a non-root user open the boards."""

UDEV_INSTALL_HINT = (
    f"install the udev rule: sudo cp packaging/udev/{UDEV_RULE_FILENAME} /etc/udev/rules.d/ && "
    "sudo udevadm control --reload-rules && sudo udevadm trigger, then unplug and replug the board "
    "(see docs/hardware.md)"
)

DRY_RUN_HINT = "use --dry-run to rehearse without the rig"

MCC_VENDOR_ID = 0x09DB
"""Measurement Computing's USB vendor id (USB-3105, USB-1608FS-Plus)."""

DT_VENDOR_ID = 0x0867
"""Data Translation's USB vendor id (DT9814)."""

UDEV_BOARDS: tuple[tuple[str, int, int | None], ...] = (
    ("MCC USB-3105 (analog output)", MCC_VENDOR_ID, 0x009E),
    ("MCC USB-1608FS-Plus (analog input)", MCC_VENDOR_ID, 0x00EA),
    (
        "Data Translation DT9814 (analog input; its product id is not public: every DT device)",
        DT_VENDOR_ID,
        None,
    ),
)


def udev_rule_text() -> str:
    """The text of `packaging/udev/60-protocol-runner-daq.rules` (print it with
    ``python -m protocol_runner.hardware.discovery --udev-rule`` where the source tree is not at hand)."""
    lines = [
        "# protocol-runner: let the logged-in user (uaccess) and the plugdev group open the DAQ boards",
        "# through libusb, without root.",
        f"# Install: sudo cp {UDEV_RULE_FILENAME} /etc/udev/rules.d/",
        "#          sudo udevadm control --reload-rules && sudo udevadm trigger",
        "#          then unplug and replug the boards. See docs/hardware.md.",
    ]
    for name, vid, pid in UDEV_BOARDS:
        match = f'SUBSYSTEM=="usb", ENV{{DEVTYPE}}=="usb_device", ATTR{{idVendor}}=="{vid:04x}"'
        if pid is not None:
            match += f', ATTR{{idProduct}}=="{pid:04x}"'
        lines += [f"# {name}", f'{match}, MODE="0660", GROUP="plugdev", TAG+="uaccess"']
    return "\n".join(lines) + "\n"


class BoardNotFound(HardwareUnavailable):
    """No board with the wanted vendor/product id (and serial) is attached."""


class BoardBusy(HardwareUnavailable):
    """Another program (or another protocol-runner) holds the board's interface (errno 16)."""


class BoardPermissionDenied(HardwareUnavailable):
    """The operating system refused access to the board: the udev rule is missing (errno 13)."""


class BoardTimeout(HardwareUnavailable):
    """The board did not answer in time (errno 110)."""


class DeviceGone(HardwareUnavailable):
    """The board disappeared (unplugged, powered off, re-enumerated) while in use (errno 19).

    The session catches this to mark the running trial failed and park the joint.
    """


class BoardIoError(HardwareUnavailable):
    """Any other USB failure."""


class UnexpectedReply(HardwareUnavailable):
    """The board answered with bytes that do not match the command sent (protocol mismatch)."""


class ScanOverrun(HardwareUnavailable):
    """The input board's FIFO overflowed because the host did not read the scan data fast enough."""


class NoUsbBackend(HardwareUnavailable):
    """pyusb found no libusb library on this computer."""


def map_usb_error(exc: BaseException, board: str, action: str) -> HardwareUnavailable:
    """Translate a pyusb exception met while doing `action` on `board` into a clear `HardwareUnavailable`.

    `board` is a human name such as ``"USB-3105 serial 01ABCDEF"``; `action` says what was being done
    (``"claiming the interface"``). The original exception is kept as ``__cause__`` by the callers
    (``raise map_usb_error(e, ...) from e``).
    """
    if isinstance(exc, HardwareUnavailable):
        return exc
    code = getattr(exc, "errno", None)
    if isinstance(exc, usb.core.USBTimeoutError) or code == errno_codes.ETIMEDOUT:
        return BoardTimeout(
            f"{board} did not answer in time while {action} (USB timeout). Check the cable and the "
            "board's power; unplug and replug it, then retry."
        )
    if code == errno_codes.EACCES:
        return BoardPermissionDenied(
            f"permission denied while {action} on the {board}: this user may not open the board. "
            f"To fix it, {UDEV_INSTALL_HINT}."
        )
    if code == errno_codes.EBUSY:
        return BoardBusy(
            f"the {board} is busy while {action}: another program (or another protocol-runner) is "
            "using it. Close that program, or unplug and replug the board, then retry."
        )
    if code == errno_codes.ENODEV:
        return DeviceGone(
            f"the {board} disappeared while {action} (unplugged or powered off). Reconnect it; the "
            "running trial is marked failed and can be redone by resuming the session."
        )
    return BoardIoError(f"USB error while {action} on the {board}: {exc}. Unplug and replug the board.")


T = TypeVar("T")


def usb_call(board: str, action: str, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
    """Run one pyusb call, mapping its failures with `map_usb_error`."""
    try:
        return fn(*args, **kwargs)
    except usb.core.USBError as exc:
        raise map_usb_error(exc, board, action) from exc


def find_devices(
    vendor_id: int, product_id: int | None, backend: Any | None, board_kind: str
) -> list[usb.core.Device]:
    """Every attached device with the given ids (`product_id` None: any product of the vendor).

    Raises `NoUsbBackend` when pyusb finds no libusb library.
    """
    criteria: dict[str, int] = {"idVendor": vendor_id}
    if product_id is not None:
        criteria["idProduct"] = product_id
    try:
        return list(usb.core.find(find_all=True, backend=backend, **criteria))
    except usb.core.NoBackendError as exc:
        raise NoUsbBackend(
            f"cannot look for the {board_kind}: no libusb library was found on this computer. "
            "Install libusb-1.0 (e.g. `sudo apt install libusb-1.0-0`), or "
            f"{DRY_RUN_HINT}."
        ) from exc
    except usb.core.USBError as exc:
        raise map_usb_error(exc, board_kind, "listing USB devices") from exc


def read_serial(device: usb.core.Device, board_kind: str) -> str:
    """The board's serial number string (the USB iSerialNumber descriptor), errors mapped."""
    try:
        serial = usb_call(board_kind, "reading the serial number", lambda: device.serial_number)
    except ValueError as exc:
        # pyusb reports "no langid" when it could not open the device to read the string descriptors:
        # with libusb that is a permission problem (the open failed with errno 13).
        raise BoardPermissionDenied(
            f"cannot read the {board_kind}'s serial number: this user may not open the board. "
            f"To fix it, {UDEV_INSTALL_HINT}."
        ) from exc
    return (serial or "").strip("\x00 ")


def no_board(board_kind: str, ids: str) -> BoardNotFound:
    """The error for no attached board of a kind; `ids` is the id text, e.g. ``"VID 0x09DB PID 0x009E"``."""
    return BoardNotFound(f"no {board_kind} found ({ids}); is it plugged in? {DRY_RUN_HINT}")


def find_board(
    vendor_id: int, product_id: int, serial: str | None, backend: Any | None, board_kind: str
) -> tuple[usb.core.Device, str]:
    """Find the attached board with these ids (and `serial`, None: the first one) and read its serial.

    Returns the device and its USB serial number. Raises `BoardNotFound` (none attached, or none with
    `serial`), `NoUsbBackend`, or the mapped USB error met while listing or reading the serial.
    """
    ids = f"VID 0x{vendor_id:04X} PID 0x{product_id:04X}"
    devices = find_devices(vendor_id, product_id, backend, board_kind)
    if not devices:
        raise no_board(board_kind, ids)
    seen: list[str] = []
    for dev in devices:
        found = read_serial(dev, board_kind)
        if serial is None or found == serial:
            return dev, found
        seen.append(found)
    raise BoardNotFound(
        f"no {board_kind} with serial {serial!r} found ({ids}); attached: "
        f"{', '.join(repr(s) for s in seen)}. Check the serial in the protocol file, or {DRY_RUN_HINT}"
    )


BoardT = TypeVar("BoardT", bound=contextlib.AbstractContextManager[Any])


def open_each(open_one: Callable[[str], BoardT], serials: Sequence[str]) -> list[BoardT]:
    """The board of each serial, opened in order; one that fails to open closes those opened before it."""
    with contextlib.ExitStack() as opened:
        boards = [opened.enter_context(open_one(s)) for s in serials]
        opened.pop_all()
    return boards


def claim_interface(device: usb.core.Device, interface: int, board: str) -> bool:
    """Detach the kernel driver (usbhid for the HID boards) if it holds `interface`, then claim it.

    Returns True when a kernel driver was detached. Errors are mapped (busy, permission, gone).
    """
    detached = False
    try:
        active = bool(device.is_kernel_driver_active(interface))
    except NotImplementedError:  # backends without the call (e.g. on some platforms)
        active = False
    except usb.core.USBError as exc:
        raise map_usb_error(exc, board, "checking for a kernel driver") from exc
    if active:
        usb_call(board, "detaching the kernel driver", device.detach_kernel_driver, interface)
        detached = True
    usb_call(board, "claiming the USB interface", usb.util.claim_interface, device, interface)
    return detached


def release_device(device: usb.core.Device, interface: int) -> None:
    """Release `interface` and free pyusb's resources; never raises (used on close and error paths)."""
    with contextlib.suppress(usb.core.USBError, ValueError):
        usb.util.release_interface(device, interface)
    with contextlib.suppress(usb.core.USBError, ValueError):
        usb.util.dispose_resources(device)


def check_scan_channels(kind: str, channels: Sequence[int], n_channels: int, rate_hz: float) -> list[int]:
    """The scan's channels as ints, refused when empty, repeated or outside the board, or at a bad rate."""
    chans = [int(c) for c in channels]
    if not chans:
        raise InvalidInput(f"{kind}: give at least one input channel to scan")
    if len(set(chans)) != len(chans) or any(not 0 <= c < n_channels for c in chans):
        raise InvalidInput(f"{kind}: scan channels must be distinct numbers 0-{n_channels - 1}; got {chans}")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise InvalidInput(
            f"{kind}: the scan rate must be a positive number of rows per second; got {rate_hz!r}"
        )
    return chans


def output_channel(kind: str, channel: int, n_channels: int) -> int:
    """`channel` as an int, refused unless it is one of the output board's channels 0..n_channels - 1."""
    try:
        ch = operator.index(channel)
    except TypeError:
        ch = -1
    if not 0 <= ch < n_channels:
        raise InvalidInput(f"the {kind} has output channels 0-{n_channels - 1}; got {channel!r}")
    return ch


def finite_volts(channel: int, volts: float) -> float:
    """`volts` as a float, refused unless finite."""
    volts = float(volts)
    if not math.isfinite(volts):
        raise InvalidInput(f"output channel {channel}: volts must be a finite number, got {volts!r}")
    return volts


def bcd_to_text(bcd: int) -> str:
    """USB bcdDevice (binary-coded decimal major.minor) as text: 0x0102 -> ``"1.02"``."""
    return f"{(bcd >> 8) & 0xFF:x}.{bcd & 0xFF:02x}"


class MonotonicClock:
    """The real clock for hardware runs (satisfies `interfaces.Clock`): `time.monotonic` seconds.

    `sleep_until` sleeps in the kernel until `spin_s` before the deadline, then polls the clock, which
    keeps tick lateness well under a millisecond at the cost of a short busy wait per tick.
    """

    def __init__(self, spin_s: float = 0.0005) -> None:
        self.spin_s = spin_s

    def now_s(self) -> float:
        return time.monotonic()

    def sleep_until(self, t_s: float) -> None:
        remaining = t_s - time.monotonic()
        if remaining > self.spin_s:
            time.sleep(remaining - self.spin_s)
        while time.monotonic() < t_s:
            pass


@contextlib.contextmanager
def realtime_priority(priority: int = 50) -> Iterator[bool]:
    """Run the block under the SCHED_FIFO real-time policy when the system allows it (root, CAP_SYS_NICE,
    or an ``rtprio`` limit in /etc/security/limits.d/); yields whether it was granted.

    The paced output loop then wakes on time even when other programs keep the CPUs busy. The previous
    policy is restored on exit. Linux only; elsewhere (or when refused) the block runs unchanged.
    """
    setter = getattr(os, "sched_setscheduler", None)
    if setter is None:
        yield False
        return
    try:
        old_policy = os.sched_getscheduler(0)
        old_param = os.sched_getparam(0)
        setter(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as exc:
        logging.getLogger(__name__).info(
            "real-time priority not granted (%s); running at normal priority", exc
        )
        yield False
        return
    try:
        yield True
    finally:
        with contextlib.suppress(OSError):
            setter(0, old_policy, old_param)
