"""The node's own XML-RPC API (ROS's "slave API"), served on one owned thread.

Each call answers ``[code, statusMessage, value]`` as ROS's Slave API says: code 1 is
success, 0 failure, -1 an error in the call. :class:`SlaveApi` is the calls; it asks the
node (a :class:`NodeView`) what it needs. :class:`SlaveServer` serves them on
``host:port`` (loopback unless the node was given another host), one request at a time,
each bounded in bytes and in time (``Limits.xmlrpc_bytes``, ``Limits.xmlrpc_seconds``:
from the connection's first byte to the last), so a stalled or flooding peer costs at
most that. A bad request is counted (``xmlrpc_bad_requests``).
"""

from __future__ import annotations

import io
import logging
import os
import socket
import time
from typing import Any, ClassVar, Protocol
from xmlrpc.server import SimpleXMLRPCRequestHandler, SimpleXMLRPCServer

from dataflow.threads import OwnedThread

from .io import Counters

__all__ = ["NodeView", "SlaveApi", "SlaveServer"]

log = logging.getLogger(__name__)

MAX_PUBLISHERS = 10_000  #: URIs a publisherUpdate may list


class NodeView(Protocol):
    """What the slave API asks of its node."""

    caller_id: str
    master_uri: str
    counters: Counters

    def publications(self) -> list[list[str]]: ...
    def subscriptions(self) -> list[list[str]]: ...
    def bus_info(self) -> list[list[Any]]: ...
    def bus_stats(self) -> list[Any]: ...
    def tcpros_endpoint(self, topic: str) -> tuple[str, int] | None: ...
    def publisher_update(self, topic: str, uris: list[str]) -> None: ...
    def request_shutdown(self, caller_id: str, reason: str) -> None: ...


def _ok_str(*values: Any, limit: int = 4096) -> bool:
    return all(isinstance(v, str) and len(v) <= limit for v in values)


class SlaveApi:
    """The Slave API's calls (names as ROS spells them; run on the server's thread)."""

    def __init__(self, node: NodeView) -> None:
        self._node = node

    def _bad(self, method: str) -> list[Any]:
        self._node.counters["xmlrpc_bad_requests"] += 1
        return [-1, f"{method}: bad arguments", 0]

    def getBusStats(self, caller_id: str) -> list[Any]:  # noqa: N802 (ROS's names)
        return [1, "bus stats", self._node.bus_stats()] if _ok_str(caller_id) else self._bad("getBusStats")

    def getBusInfo(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "bus info", self._node.bus_info()] if _ok_str(caller_id) else self._bad("getBusInfo")

    def getMasterUri(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "", self._node.master_uri] if _ok_str(caller_id) else self._bad("getMasterUri")

    def shutdown(self, caller_id: str, msg: str = "") -> list[Any]:
        if not _ok_str(caller_id, msg):
            return self._bad("shutdown")
        self._node.request_shutdown(caller_id, msg)
        return [1, "shutdown", 0]

    def getPid(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "", os.getpid()] if _ok_str(caller_id) else self._bad("getPid")

    def getSubscriptions(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "subscriptions", self._node.subscriptions()] if _ok_str(caller_id) else self._bad("getSubscriptions")

    def getPublications(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "publications", self._node.publications()] if _ok_str(caller_id) else self._bad("getPublications")

    def paramUpdate(self, caller_id: str, key: str, value: Any) -> list[Any]:  # noqa: N802
        # this node subscribes to no parameter: accepted and ignored, as rospy does for unknown keys
        return [1, "", 0] if _ok_str(caller_id, key) else self._bad("paramUpdate")

    def publisherUpdate(self, caller_id: str, topic: str, publishers: list[str]) -> list[Any]:  # noqa: N802
        if not (_ok_str(caller_id, topic) and isinstance(publishers, list) and len(publishers) <= MAX_PUBLISHERS
                and all(_ok_str(p) for p in publishers)):
            return self._bad("publisherUpdate")
        self._node.publisher_update(topic, list(publishers))
        return [1, "", 0]

    def requestTopic(self, caller_id: str, topic: str, protocols: list[Any]) -> list[Any]:  # noqa: N802
        if not (_ok_str(caller_id, topic) and isinstance(protocols, list) and len(protocols) <= 16):
            return self._bad("requestTopic")
        endpoint = self._node.tcpros_endpoint(topic)
        if endpoint is None:
            return [0, f"{self._node.caller_id} is not a publisher of {topic}", []]
        if not any(isinstance(p, list) and p and p[0] == "TCPROS" for p in protocols):
            return [0, "no supported protocol: this node speaks TCPROS only", []]
        host, port = endpoint
        return [1, f"ready on {host}:{port}", ["TCPROS", host, port]]


class _DeadlineReader(io.RawIOBase):
    """A socket reader that stops at a deadline, however slowly the peer trickles bytes.

    ``on_timeout()`` runs once when it stops (http.server turns the error into a reply).
    """

    def __init__(self, sock: socket.socket, deadline: float, on_timeout: Any) -> None:
        super().__init__()
        self._sock, self._deadline, self._on_timeout = sock, deadline, on_timeout

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        try:
            left = self._deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("XML-RPC request took too long")
            self._sock.settimeout(left)
            return self._sock.recv_into(buffer)
        except TimeoutError:
            if self._on_timeout is not None:
                self._on_timeout()
                self._on_timeout = None
            raise


class _Handler(SimpleXMLRPCRequestHandler):
    rpc_paths = ("/", "/RPC2")
    counters: Counters  # these three are set per server (a subclass per node)
    max_bytes: int
    timeout: ClassVar[float]  # StreamRequestHandler's per-operation timeout; the deadline bounds the whole

    def setup(self) -> None:
        super().setup()
        deadline = time.monotonic() + self.timeout
        self.rfile = io.BufferedReader(_DeadlineReader(self.connection, deadline, self._timed_out))

    def _timed_out(self) -> None:
        self.counters["xmlrpc_bad_requests"] += 1
        self.close_connection = True
        log.warning("ROS 1 XML-RPC: request from %s took over %.1f s: dropped", self.client_address[0], self.timeout)

    def do_POST(self) -> None:  # noqa: N802
        length = self.headers.get("content-length", "")
        if not length.isdigit() or int(length) > self.max_bytes:
            self.send_error(413 if length.isdigit() else 411, "request too large or without Content-Length")
            return
        super().do_POST()

    def handle(self) -> None:
        try:
            super().handle()
        except (TimeoutError, OSError) as exc:
            self.counters["xmlrpc_bad_requests"] += 1
            log.warning("ROS 1 XML-RPC: request from %s dropped: %s", self.client_address[0], exc or "timeout")

    def log_error(self, format: str, *args: Any) -> None:  # noqa: A002
        """http.server reports here each request it refuses: count it (a timeout is counted once)."""
        if "timed out" not in format:
            self.counters["xmlrpc_bad_requests"] += 1
            log.warning("ROS 1 XML-RPC: request from %s dropped: " + format, self.client_address[0], *args)

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        log.debug("ROS 1 XML-RPC: " + format, *args)


def _handle_error(server: Any, request: Any, client_address: Any) -> None:
    """socketserver prints a traceback to stderr here: log it instead (the server goes on)."""
    log.error("ROS 1 XML-RPC: request from %s failed", client_address[0], exc_info=True)


class SlaveServer:
    """The Slave API on ``host:port`` (0: any free port), one owned thread (see module doc)."""

    def __init__(self, api: SlaveApi, host: str, port: int, counters: Counters, name: str,
                 max_bytes: int, max_seconds: float) -> None:
        handler = type("Handler", (_Handler,), {"counters": counters, "max_bytes": max_bytes, "timeout": max_seconds})
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        server_class = type("Server", (SimpleXMLRPCServer,), {"address_family": family, "handle_error": _handle_error})
        self._server = server_class((host, port), requestHandler=handler, logRequests=False,
                                          allow_none=True, bind_and_activate=True)
        self._server.timeout = 0.2  # handle_request() returns this often to see a stop
        self._server.register_instance(api)
        self.port: int = self._server.server_address[1]
        self._stopping = False
        self._thread = OwnedThread(lambda _stopping: self._run(), f"ros1-xmlrpc {name}")

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        while not self._stopping:
            self._server.handle_request()
        self._server.server_close()

    def close(self, timeout: float = 5.0) -> None:
        """Stop serving (idempotent); from the server's own thread it only signals."""
        self._stopping = True
        self._thread.join(timeout)  # (not from the server's own thread)
        if not self._thread.alive:
            self._server.server_close()
