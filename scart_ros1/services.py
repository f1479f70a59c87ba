"""ROS 1 services over TCPROS, both ways.

* :class:`ServiceServer` (from :meth:`Node.advertise_service`): a client's header is
  checked (``probe=1`` gets the types and is closed, as ``rosservice`` expects; md5sum
  ``*`` is accepted), then each request frame is handed to the node's service
  :class:`Worker` thread, which calls ``handler(request)`` and answers the ok byte 1 and
  the response, or 0 and an error text when the handler raises or returns something that
  is not the response type. A ``persistent=1`` connection takes further requests;
  another is closed after its answer. Registered with the master as
  ``rosrpc://host:port`` (the node's TCPROS port).
* :func:`call_service`: ``lookupService``, header, request, ok byte, response — in the
  caller's thread, all within one timeout; failures raise :class:`ServiceError`.
* :func:`service_type`: a service's type, asked of the service itself (``probe=1``).
"""

from __future__ import annotations

import logging
import queue
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ._threads import OwnedThread
from .io import Conn, Counters, FrameReader, InboundConn
from .master import MasterError, MasterUnreachable, parse_rosrpc
from .msgs import SrvType
from .tcpros import HeaderError, encode_header, frame, read_frame, read_header, recv_exact

if TYPE_CHECKING:
    from .node import Node

__all__ = ["ServiceError", "ServiceServer", "Worker", "call_service", "service_type"]

log = logging.getLogger(__name__)

MAX_PENDING = 256  #: requests waiting for the worker; more are answered "busy"


class ServiceError(RuntimeError):
    """A service call failed: no such service, refused, handler error, bad answer, timeout."""


class Worker:
    """One owned thread running service handlers in arrival order (bounded queue)."""

    def __init__(self, name: str) -> None:
        self._queue: queue.Queue[tuple[Callable[..., object], tuple] | None] = queue.Queue(MAX_PENDING)
        self._closed = False
        self._thread = OwnedThread(lambda _stopping: self._run(), f"ros1-services {name}").start()

    def submit(self, fn: Callable[..., object], *args: object) -> bool:
        """Queue ``fn(*args)``; False if the queue is full or the worker closed (never blocks)."""
        if self._closed:
            return False
        try:
            self._queue.put_nowait((fn, args))
        except queue.Full:
            return False
        return True

    def _run(self) -> None:
        while (job := self._queue.get()) is not None:
            fn, args = job
            try:
                fn(*args)
            except Exception:
                log.exception("ROS 1 service worker: %s failed", getattr(fn, "__qualname__", fn))

    def close(self, timeout: float = 5.0) -> None:
        """Finish the job in hand, skip the rest, end the thread (idempotent)."""
        self._closed = True
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break
        self._queue.put(None)
        self._thread.join(timeout)  # (not from the worker itself)


def _answered(conn: Conn) -> None:
    conn.pending -= 1  # (the io thread)


def _error_reply(text: str) -> bytes:
    return b"\x00" + frame(text.encode("utf-8", "replace"))


class ServiceServer:
    """An advertised service (see the module doc); thread-safe."""

    def __init__(self, node: Node, name: str, srvtype: SrvType, handler: Callable[[Any], object]) -> None:
        self.name, self.type, self.handler = name, srvtype, handler
        self._node = node
        self._counters = Counters("requests", "handler_errors", "bad_requests", "busy", "md5_mismatches")
        self._conns: set[Conn] = set()
        self._lock = threading.Lock()
        self.closed = False

    def __repr__(self) -> str:
        return f"ServiceServer({self.name!r}, {self.type.name!r})"

    @property
    def counters(self) -> dict[str, int]:
        """``requests``, ``handler_errors``, ``bad_requests``, ``busy``, ``md5_mismatches``."""
        return self._counters.snapshot()

    # -- the io thread --------------------------------------------------------------------
    def accept(self, conn: InboundConn, header: dict[str, str]) -> None:
        caller = header.get("callerid", "?")
        reply = {"callerid": self._node.caller_id, "md5sum": self.type.md5sum, "type": self.type.name,
                 "request_type": self.type.request.name, "response_type": self.type.response.name}
        conn.peer_id, conn.topic, conn.direction = caller, self.name, "i"
        their = header.get("md5sum", "")
        if their not in ("*", self.type.md5sum):
            return self._refuse(conn, caller, header.get("type", "?"), their)
        conn.send(encode_header(reply), droppable=False)
        if header.get("probe") == "1":
            conn.close_when_flushed()
            return
        persistent = header.get("persistent", "").lower() in ("1", "true")
        reader = FrameReader(self._node.limits.max_message, lambda p: self._request(conn, p, persistent),
                             lambda size: self._oversized(conn, size))
        conn.on_data = reader.feed
        conn.on_close = self._gone
        conn.idle_kind = "service"  # closed when no request comes for long
        with self._lock:
            self._conns.add(conn)

    def _refuse(self, conn: InboundConn, caller: str, their_type: str, their_md5: str) -> None:
        error = (f"Client [{caller}] wants service [{self.name}] to have datatype/md5sum [{their_type}/{their_md5}], "
                 f"but our version has [{self.type.name}/{self.type.md5sum}]. Dropping connection.")
        self._counters["md5_mismatches"] += 1
        self._node.counters["md5_mismatches"] += 1
        log.warning("ROS 1 service %s: %s", self.name, error)
        conn.send(encode_header({"error": error}), droppable=False)
        conn.close_when_flushed()

    def _request(self, conn: Conn, payload: bytes, persistent: bool) -> None:
        self._counters["requests"] += 1
        conn.pending += 1  # not idle while its request is in hand (the io thread counts; see _handle)
        if not self._node.worker().submit(self._handle, conn, payload, persistent):
            self._counters["busy"] += 1
            conn.pending -= 1
            conn.send(_error_reply(f"service [{self.name}] is busy: {MAX_PENDING} requests waiting"), droppable=False)
            conn.close_when_flushed()

    def _oversized(self, conn: Conn, size: int) -> None:
        self._counters["bad_requests"] += 1
        self._node.counters["oversized_messages"] += 1
        log.warning("ROS 1 service %s: a %d-byte request exceeds the limit: refused", self.name, size)
        conn.send(_error_reply(f"request of {size} bytes is larger than the limit"), droppable=False)
        conn.close_when_flushed()

    def _gone(self, conn: Conn, reason: str) -> None:
        with self._lock:
            self._conns.discard(conn)

    # -- the worker thread ----------------------------------------------------------------
    def _handle(self, conn: Conn, payload: bytes, persistent: bool) -> None:
        try:
            if conn.closed:
                return
            conn.send(self._answer(payload), droppable=False)
            if not persistent:
                conn.close_when_flushed()
        finally:
            self._node.loop.call_soon(_answered, conn)

    def _answer(self, payload: bytes) -> bytes:
        try:
            request = self.type.request.deserialize(payload)
        except ValueError as exc:
            self._counters["bad_requests"] += 1
            return _error_reply(f"service [{self.name}]: {exc}")
        try:
            response = self.handler(request)
        except Exception as exc:
            self._counters["handler_errors"] += 1
            self._node.counters["service_errors"] += 1
            log.warning("ROS 1 service %s: the handler raised %s: %s", self.name, type(exc).__name__, exc)
            return _error_reply(f"service [{self.name}] failed: {type(exc).__name__}: {exc}")
        try:
            return b"\x01" + bytes(self.type.response.frame(response))
        except (ValueError, TypeError, AttributeError, struct.error) as exc:
            self._counters["handler_errors"] += 1
            self._node.counters["service_errors"] += 1
            log.warning("ROS 1 service %s: the handler's answer is not a %s: %s", self.name, self.type.response.name, exc)
            return _error_reply(f"service [{self.name}] answered no {self.type.response.name}")

    def close(self) -> None:
        """Unregister and close the connections (idempotent; any thread)."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            conns = list(self._conns)
        for conn in conns:
            conn.close("unadvertised")
        self._node._drop_service(self)


def call_service(node: Node, name: str, srvtype: SrvType, request: object, timeout: float) -> object:
    """Call service ``name`` (resolved) with ``request``; its response (blocks ≤ ``timeout`` s).

    Raises :class:`ServiceError` (no such service, refused, the server's error text,
    a bad answer, no answer in time) and ``ValueError``/``TypeError`` for a ``request``
    that is not a ``srvtype`` request.
    """
    data = bytes(srvtype.request.frame(request))
    deadline = time.monotonic() + timeout
    try:
        uri = node.master_for(min(timeout, node.master.timeout)).lookup_service(name)
        host, port = parse_rosrpc(uri)
        with socket.create_connection((host, port), timeout=max(0.001, deadline - time.monotonic())) as sock:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return _exchange(node, sock, name, srvtype, data, deadline)
    except MasterUnreachable as exc:
        raise ServiceError(f"service {name}: {exc}") from None
    except MasterError as exc:
        raise ServiceError(f"service {name} is not available: {exc}") from None
    except TimeoutError:
        raise ServiceError(f"service {name} gave no answer within {timeout} s") from None
    except (OSError, HeaderError, ValueError) as exc:
        raise ServiceError(f"service {name}: {exc}") from None


def _exchange(node: Node, sock: socket.socket, name: str, srvtype: SrvType, data: bytes, deadline: float) -> object:
    limits = node.limits
    sock.sendall(encode_header({"callerid": node.caller_id, "service": name, "md5sum": srvtype.md5sum,
                                "type": srvtype.name, "persistent": "0"}))
    header = read_header(sock, deadline, limits.max_header)
    if "error" in header:
        raise ServiceError(f"service {name} refused the call: {header['error']}")
    sock.sendall(data)
    ok = recv_exact(sock, 1, deadline)[0]
    body = read_frame(sock, deadline, limits.max_message)
    if ok != 1:
        raise ServiceError(f"service {name} failed: {bytes(body).decode('utf-8', 'replace')}")
    return srvtype.response.deserialize(body)


def service_type(node: Node, service: str, timeout: float = 5.0) -> str:
    """The type (``pkg/Srv``) of the ROS service ``service``, asked of the service itself
    (the ``probe`` header, as ``rosservice``). Raises :class:`ServiceError`."""
    name = node.resolve(service)
    deadline = time.monotonic() + timeout
    try:
        host, port = parse_rosrpc(node.master_for(timeout).lookup_service(name))
        with socket.create_connection((host, port), timeout=timeout) as sock:
            sock.sendall(encode_header({"callerid": node.caller_id, "service": name, "md5sum": "*", "probe": "1"}))
            header = read_header(sock, deadline, node.limits.max_header)
    except MasterError as exc:
        raise ServiceError(f"service {name} is not available: {exc}") from None
    except (OSError, HeaderError, ValueError) as exc:
        raise ServiceError(f"service {name}: {exc}") from None
    if "error" in header or not header.get("type"):
        raise ServiceError(f"service {name} did not say its type: {header.get('error', 'no type in its header')}")
    return header["type"]
