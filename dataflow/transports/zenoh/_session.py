"""Opening Zenoh sessions as scart does: loopback, no multicast, scart's tokens (private;
see :mod:`dataflow.transports.zenoh`)."""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
from collections.abc import Iterable
from typing import TYPE_CHECKING

from scart_wire.security import is_loopback
from dataflow.transports.zenoh._keys import MAX_PAYLOAD

if TYPE_CHECKING:
    import zenoh

    from scart_wire.security import Security

__all__ = ["check_endpoint", "open_session", "zenoh_credentials"]

_ENDPOINT = re.compile(r"^[a-z][a-z0-9-]*/\S+$")


def check_endpoint(endpoint: str, insecure: bool = False) -> None:
    """Raise ``ValueError`` for an endpoint that is not ``PROTOCOL/ADDRESS`` (with a port
    for the IP protocols), or not loopback (nor a Unix socket) unless ``insecure``."""
    if not _ENDPOINT.match(endpoint) or (endpoint.startswith(("tcp/", "udp/", "tls/", "quic/"))
                                         and not re.search(r":\d+$", endpoint.split("#")[0])):
        raise ValueError(f"Zenoh endpoint {endpoint!r}: expected PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447 "
                         "or unixsock-stream/PATH")
    protocol, _, address = endpoint.partition("/")
    host = address.rpartition(":")[0].strip("[]")
    loopback = protocol in ("tcp", "udp", "quic", "tls") and "#" not in address and is_loopback(host)
    if not (insecure or protocol == "unixsock-stream" or loopback):
        raise ValueError(f"Zenoh endpoint {endpoint!r} is not loopback: scart does not encrypt Zenoh traffic "
                         "(use Zenoh's TLS), so it needs --zenoh-insecure (zenoh-insecure=\"true\" in a composite)")


def zenoh_credentials(token: str) -> tuple[str, str]:
    """The Zenoh user name and password a scart token authenticates with (Zenoh's
    ``usrpwd``): ``scart-`` and 16 hex digits of the token's SHA-256, and the hex SHA-256
    of ``scart-zenoh:`` and the token. Derived, so they hold no character Zenoh's
    ``user:password`` lines cannot, and the token itself never goes into Zenoh's file."""
    user = "scart-" + hashlib.sha256(token.encode()).hexdigest()[:16]
    return user, hashlib.sha256(b"scart-zenoh:" + token.encode()).hexdigest()


def open_session(connect: Iterable[str] = (), listen: Iterable[str] = (), insecure: bool = False,
                 mode: str = "peer", security: Security | None = None) -> zenoh.Session:
    """A Zenoh session in ``mode`` (``peer``; ``router`` for a fleet's router; ``client``
    to talk through routers only): listening on ``listen`` (default ``tcp/127.0.0.1:0``;
    a client listens on nothing) and connecting to ``connect``, with multicast scouting
    off. Raises ``ValueError`` for a routable endpoint to listen on without ``insecure``
    or an unknown mode, and Zenoh's own error when it cannot open.

    ``security`` (scart's tokens, as for gRPC): a session that listens, given an auth file,
    admits only the peers that present one of its ``operate`` or ``admin`` tokens (a Zenoh
    link both reads and writes, so ``read`` tokens are not admitted); a session given a
    token presents it (:func:`zenoh_credentials`). Zenoh refuses a link whose two ends
    disagree (one presents a token the other does not check, or one checks and the other
    presents none)."""
    import zenoh

    if mode not in ("peer", "router", "client"):
        raise ValueError(f"Zenoh mode {mode!r}: expected peer, router or client")
    connect, listen = list(connect), list(listen) or (["tcp/127.0.0.1:0"] if mode != "client" else [])
    for endpoint in connect + listen:
        check_endpoint(endpoint, insecure)
    admitted = _admitted(security) if listen else []
    config = zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("scouting/multicast/enabled", "false")
    if not insecure:  # reach only the endpoints given (gossip would pass on others' too)
        config.insert_json5("scouting/gossip/enabled", "false")
    drop = "transport/link/tx/queue/congestion_control/drop/"
    config.insert_json5(drop + "wait_before_drop", "0")  # never wait for room: the writer's thread
    config.insert_json5(drop + "max_wait_before_drop_fragments", "0")
    config.insert_json5("transport/link/rx/max_message_size", str(MAX_PAYLOAD + 64 * 1024))
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    if security is not None and security.token:
        user, password = zenoh_credentials(security.token)
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(password))
    if not admitted:
        return zenoh.open(config)
    with tempfile.TemporaryDirectory(prefix="scart-zenoh-") as folder:  # only this user may enter
        users = os.path.join(folder, "users")
        with os.fdopen(os.open(users, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600), "w") as out:
            out.write("".join(f"{user}:{password}\n" for user, password in admitted))
        config.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(users))
        return zenoh.open(config)  # Zenoh reads the file as it opens: it goes right after


def _admitted(security: Security | None) -> list[tuple[str, str]]:
    """The credentials of the auth file's ``operate`` and ``admin`` tokens (none without
    one). Raises ``ValueError`` for an auth file with neither: no peer could connect."""
    from scart_wire.security import Role

    table = security.auth_table() if security is not None else None
    if security is None or table is None:
        return []
    admitted = sorted({zenoh_credentials(token.decode()) for token, role in table.entries if role >= Role.OPERATE})
    if not admitted:
        raise ValueError(f"{security.auth_file}: no operate or admin token, so no Zenoh peer could connect "
                         "(a Zenoh link both reads and writes)")
    return admitted


