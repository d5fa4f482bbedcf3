"""Zenoh endpoints, parsed for what they reach: which address a ``listen`` endpoint opens.

Commands reach the vehicle through what navd listens on, so the check is on the
address the operating system will bind, not on the text: ``tcp/0:7447``,
``tcp/[0:0:0:0:0:0:0:0]:7447`` and ``tcp/[::ffff:0.0.0.0]:7447`` all listen on every
interface, as ``0.0.0.0`` does.  An endpoint is ``<protocol>/<address>``, with
optional ``?metadata`` and ``#config`` (zenoh's locator syntax).
"""

from __future__ import annotations

import ipaddress
import socket
from dataclasses import dataclass

__all__ = ["Endpoint", "parse", "listen_problem"]

#: protocols whose address is ``host:port``
_IP_PROTOCOLS = frozenset({"tcp", "udp", "tls", "quic", "ws"})
#: protocols that reach only this machine
_LOCAL_PROTOCOLS = frozenset({"unixsock-stream", "unixpipe", "serial", "vsock"})

Address = ipaddress.IPv4Address | ipaddress.IPv6Address


@dataclass(frozen=True, slots=True)
class Endpoint:
    protocol: str
    host: str  # as written
    port: int | None
    address: Address | None  # None for a name, or a protocol without one

    @property
    def local_only(self) -> bool:
        if self.protocol in _LOCAL_PROTOCOLS:
            return True
        if self.address is not None:
            return self.address.is_loopback
        return self.host == "localhost"

    @property
    def every_interface(self) -> bool:
        return self.address is not None and self.address.is_unspecified


def _address(host: str) -> Address | None:
    """The address the OS makes of ``host``, or None for a name."""
    text = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    text = text.split("%", 1)[0]  # an IPv6 zone
    try:
        addr: Address = ipaddress.ip_address(text)
    except ValueError:
        try:
            # the forms inet_aton takes and ipaddress does not: "0", "127.1", "0x7f.1"
            addr = ipaddress.IPv4Address(socket.inet_aton(text))
        except (OSError, ValueError):
            return None
    if isinstance(addr, ipaddress.IPv6Address) and addr.ipv4_mapped is not None:
        return addr.ipv4_mapped
    return addr


def parse(text: str) -> Endpoint:
    """The endpoint ``text``; ``ValueError`` saying what is wrong with it."""
    locator = text.split("#", 1)[0].split("?", 1)[0]
    protocol, sep, rest = locator.partition("/")
    if not sep or not protocol or not rest:
        raise ValueError("expected <protocol>/<address>, e.g. tcp/127.0.0.1:7447")
    if protocol in _LOCAL_PROTOCOLS:
        return Endpoint(protocol, rest, None, None)
    if protocol not in _IP_PROTOCOLS:
        raise ValueError(f"unknown protocol {protocol!r:.20}")
    host, colon, port_text = rest.rpartition(":")
    if not colon or not host or not port_text.isdigit() or int(port_text) > 65535:
        raise ValueError("expected <address>:<port>")
    if ":" in host and not host.startswith("["):
        raise ValueError("an IPv6 address goes in brackets: [::1]:7447")
    return Endpoint(protocol, host, int(port_text), _address(host))


def listen_problem(text: str, beyond_loopback: bool, every_interface: bool) -> str | None:
    """Why navd must not listen on ``text`` under the config's permissions, or None."""
    try:
        ep = parse(text)
    except ValueError as exc:
        return str(exc)
    if ep.every_interface:
        if every_interface:
            return None
        return (
            f"{text} listens on every interface; give an address "
            "(or zenoh.listen_on_every_interface: true)"
        )
    if ep.local_only or beyond_loopback or every_interface:
        if ep.address is None and not ep.local_only:
            return f"{text}: give the address, not a name (a name may mean every interface)"
        return None
    return (
        f"{text} is reachable from outside the vehicle; set zenoh.listen_beyond_loopback: true "
        "to mean it"
    )
