"""`--monitor [HOST:]PORT` (docs/monitor.md "Address, token, port in use"): default host 127.0.0.1; a host
that is not loopback needs the token on every request; port 0 lets the system pick.
"""

from __future__ import annotations

import ipaddress
import socket
from dataclasses import dataclass

from ..errors import InvalidInput

DEFAULT_HOST = "127.0.0.1"

_USAGE = "give [HOST:]PORT, e.g. --monitor 8765 or --monitor 127.0.0.1:8765 (IPv6: --monitor [::1]:8765)"


@dataclass(frozen=True)
class MonitorAddress:
    host: str
    port: int
    family: socket.AddressFamily
    loopback: bool

    def url_host(self) -> str:
        """The host as a URL writes it (an unspecified address becomes this machine's name)."""
        host = self.host
        if host in ("0.0.0.0", "::", ""):
            host = socket.gethostname()
        return f"[{host}]" if ":" in host else host


def parse_address(spec: str) -> MonitorAddress:
    text = spec.strip()
    if text.startswith("["):
        host, sep, port_text = text[1:].partition("]:")
        if not sep:
            raise InvalidInput(f"--monitor {spec!r}: {_USAGE}")
    elif text.count(":") == 1:
        host, port_text = text.split(":")
    elif ":" in text:
        raise InvalidInput(f"--monitor {spec!r}: an IPv6 host goes in brackets, e.g. --monitor [::1]:8765")
    else:
        host, port_text = DEFAULT_HOST, text
    host = host.strip() or DEFAULT_HOST
    try:
        port = int(port_text)
    except ValueError:
        raise InvalidInput(f"--monitor {spec!r}: {port_text!r} is not a port number; {_USAGE}") from None
    if not 0 <= port <= 65535:
        raise InvalidInput(
            f"--monitor {spec!r}: port {port} is out of range (1-65535, or 0 for any free port)"
        )
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError):
        raise InvalidInput(f"--monitor {spec!r}: cannot resolve the host {host!r}") from None
    loopback = all(_is_loopback(str(info[4][0])) for info in infos)
    return MonitorAddress(host=host, port=port, family=infos[0][0], loopback=loopback)


def _is_loopback(address: str) -> bool:
    try:
        return ipaddress.ip_address(address.split("%", 1)[0]).is_loopback
    except ValueError:
        return False


def is_loopback_host_header(value: str) -> bool:
    """Does an HTTP Host header name this machine's loopback (localhost, 127.x.x.x, [::1])?"""
    value = value.strip()
    if value.startswith("["):
        name = value[1 : value.find("]")] if "]" in value else value[1:]
    else:
        name = value.rsplit(":", 1)[0] if value.count(":") == 1 else value
    return name.lower() == "localhost" or _is_loopback(name)
