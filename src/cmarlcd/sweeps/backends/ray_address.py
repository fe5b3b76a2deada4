"""Where a Ray cluster is: its address as ``--address`` writes it, whether its head
answers, and the address this sweep joins it at (:mod:`cmarlcd.sweeps.backends.ray_cluster`
uses them; nothing here imports Ray).

A cluster whose nodes listen on loopback only (``127.0.0.1``, as ``ray start
--node-ip-address=127.0.0.1`` or ``ray.cluster_utils.Cluster`` make them) is joined at
that address: Ray's own client would rewrite a loopback address to the machine's outside
address, where such a cluster answers nothing.
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import socket
import sys
from pathlib import Path
from typing import Any

from cmarlcd.errors import BackendLost, require

#: [choice] Seconds for a cluster's head to accept a TCP connection before the sweep
#: ends (a wrong host or port, a firewall, a head that is down).
REACH_SECONDS = 10.0
#: Ray reads this switch when it is imported: off, its client keeps a loopback address.
KEEP_LOOPBACK_ENV = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"


def head_of(address: str) -> tuple[str, int]:
    """``(host, port)`` of ``address`` (``host:port`` or ``ray://host:port``; ``auto``,
    Ray's own search for a cluster on this machine, has none), or a one-line error."""
    where = address.removeprefix("ray://")
    host, sep, port = where.rpartition(":")
    require(
        bool(sep and host and port.isdigit()),
        "address",
        f"expected HOST:PORT or ray://HOST:PORT (got {address!r})",
    )
    return host.strip("[]"), int(port)


def answers(host: str, port: int, seconds: float) -> str | None:
    """None when ``host:port`` accepts a TCP connection within ``seconds``, else why not."""
    try:
        with socket.create_connection((host, port), timeout=seconds):
            return None
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    except ValueError:  # a host name no resolver takes ("a..b", a label over 63 letters)
        return "not a host name"


def is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(socket.gethostbyname(host)).is_loopback
    except (OSError, ValueError):
        return False


def outside_address() -> str | None:
    """The address other machines reach this one at (the interface of the default route,
    found as Ray finds it: a UDP socket "connected" to a public address sends nothing)."""
    with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        udp.connect(("8.8.8.8", 80))
        return udp.getsockname()[0]
    return None


def keep_loopback(ray: Any | None) -> None:
    """Make Ray's client keep a loopback address instead of rewriting it."""
    os.environ[KEEP_LOOPBACK_ENV] = "0"
    if ray is not None:  # imported before the switch was read: set what it read
        with contextlib.suppress(ImportError, AttributeError):
            ray._private.ray_constants.ENABLE_RAY_CLUSTER = False


def reach(address: str) -> tuple[str, int]:
    """The head of the cluster at ``address``, once it accepts a connection within
    :data:`REACH_SECONDS`; a loopback-only cluster is joined at its loopback address (see
    :func:`join_address` for the others)."""
    host, port = head_of(address)
    why = answers(host, port, REACH_SECONDS)
    if why is not None:
        raise BackendLost(
            f"--address: cannot reach the Ray cluster at {address} ({why}); start "
            "its head with `ray start --head` and give the address it prints"
        )
    if not address.startswith("ray://") and is_loopback(host):
        loopback_only = listens_on_loopback_only(port)
        if loopback_only is None:  # no /proc to look in: ask the outside address
            outside = outside_address()
            loopback_only = outside is None or answers(outside, port, 2.0) is not None
        if loopback_only:
            keep_loopback(sys.modules.get("ray"))
    return host, port


def join_address(address: str | None, head: tuple[str, int] | None) -> str | None:
    """What to hand ``ray.init``: ``address``, or ``auto`` for a loopback address of the
    cluster Ray last started on this machine. Ray's client takes the node's own address
    from the node (``auto``) but guesses it for an explicit one, as the machine's outside
    address: wrong for a node started with ``--node-ip-address 127.0.0.1``."""
    if address is None or head is None or address.startswith("ray://"):
        return address
    if not is_loopback(head[0]) or os.environ.get(KEEP_LOOPBACK_ENV) == "0":
        return address
    record = Path(os.environ.get("RAY_TMPDIR", "/tmp")) / "ray" / "ray_current_cluster"
    with contextlib.suppress(OSError, ValueError):
        if head_of(record.read_text().strip())[1] == head[1]:
            return "auto"
    return address


def listens_on_loopback_only(port: int) -> bool | None:
    """Whether this machine listens on ``port`` at loopback addresses only (read from
    Linux's /proc/net/tcp{,6}, without opening a connection), or None where there is no
    such table or nothing listens on it."""
    addresses = []
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            local, state = fields[1], fields[3]
            host, _, hex_port = local.partition(":")
            if state == "0A" and int(hex_port, 16) == port and len(host) == width:
                addresses.append(_proc_address(host))
    if not addresses:
        return None
    return all(_is_loopback_ip(a) for a in addresses)


def _proc_address(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """An address as /proc/net/tcp{,6} writes it: 32-bit words in host (little) order."""
    raw = b"".join(bytes.fromhex(text[i : i + 8])[::-1] for i in range(0, len(text), 8))
    return ipaddress.ip_address(raw)


def _is_loopback_ip(address: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bool:
    mapped = getattr(address, "ipv4_mapped", None)
    return address.is_loopback or (mapped is not None and mapped.is_loopback)
