"""Calls to another YARP port, as ``yarp connect`` and ``yarp rpc`` make them: one
connection over the ``text_ack`` carrier, one bottle, its reply (blocking, bounded by the
name client's timeout; thread-safe: nothing is shared).

* :func:`admin_call` — an administrative bottle (``[add] /r``, ``[list] [out]``...);
* :func:`rpc_call` — a request to an RPC port, its reply bottle.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

from . import bottle
from .bottle import Item, Vocab
from .names import NameClient

if TYPE_CHECKING:
    from .network import Network

__all__ = ["admin_call", "rpc_call"]

MAX_REPLY = 1 << 20


def admin_call(network: Network | NameClient, port: str, words: Sequence[str]) -> list[Item]:
    """Send the administrative bottle ``words`` (strings naming commands become vocabs) to
    ``port``; its reply. Raises ``OSError`` when the port cannot be found or answer."""
    cmd = [Vocab(w) if i == 0 or (i == 1 and words[0] == "list") else w for i, w in enumerate(words)]
    return _call(network, port, "a", cmd)


def rpc_call(network: Network | NameClient, port: str, values: Sequence[object]) -> list[Item]:
    """Send ``values`` to the RPC port ``port``; its reply bottle. Raises ``OSError``."""
    return _call(network, port, "d", values)


def _call(network: Network | NameClient, port: str, key: str, values: Sequence[object]) -> list[Item]:
    names = network if isinstance(network, NameClient) else network.names
    contact = names.query(port)
    if contact is None:
        raise OSError(f"no YARP port {port} is registered with the name server at {names.address[0]}:"
                      f"{names.address[1]}")
    if not isinstance(network, NameClient):
        sock = network.connect_to(contact.host, contact.port)
    else:
        sock = socket.create_connection((contact.host, contact.port), timeout=names.timeout)
    deadline = time.monotonic() + names.timeout
    with sock:
        sock.settimeout(names.timeout)
        sock.sendall(b"CONNACK admin\r\n")
        _line(sock, deadline)  # Welcome
        sock.sendall(f"{key}\r\n{bottle.to_text(values)}\r\n".encode("utf-8"))
        lines = []
        while True:
            line = _line(sock, deadline)
            if line == "<ACK>":
                break
            lines.append(line)
    return bottle.from_text(" ".join(lines)) if lines else []


def _line(sock: socket.socket, deadline: float) -> str:
    data = b""
    while not data.endswith(b"\n"):
        left = deadline - time.monotonic()
        if left <= 0 or len(data) > MAX_REPLY:
            raise OSError("no whole reply in time")
        sock.settimeout(left)
        chunk = sock.recv(1)
        if not chunk:
            raise OSError("the port closed the connection before its reply")
        data += chunk
    return data.decode("utf-8", errors="replace").rstrip("\r\n")
