"""The node's XML-RPC server: requests served side by side, each bounded in bytes and time.

:class:`RpcServer` accepts on one owned thread and hands each connection to a small pool
of worker threads (started as needed, at most ``workers``; rospy serves each request on
a thread of its own), so that a slow or stalled client holds one worker, never the node:
``rostopic echo`` is answered while others trickle. A connection waits for a worker in
a bounded queue; past it, it is closed at once (counted). Each request is bounded in
bytes (``max_bytes``, from ``Content-Length``) and in time (``max_seconds``, from the
connection's first byte to its last), so a stalled or flooding peer costs at most that.
A bad request is counted (``xmlrpc_bad_requests``).
"""

from __future__ import annotations

import collections
import io
import logging
import socket
import sys
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, ClassVar, TypeAlias, cast
from xmlrpc.server import SimpleXMLRPCRequestHandler, SimpleXMLRPCServer

from ._threads import OwnedThread
from .io import Counters

if TYPE_CHECKING:
    from _typeshed import WriteableBuffer

__all__ = ["RpcServer"]

_Request: TypeAlias = "socket.socket | tuple[bytes, socket.socket]"  # socketserver's; TCP's is the socket
_Address: TypeAlias = tuple[str, int]

log = logging.getLogger(__name__)

WORKERS = 8  #: requests served at once, by default
WAITING = 64  #: accepted connections waiting for a worker; more are closed


class _DeadlineReader(io.RawIOBase):
    """A socket reader that stops at a deadline, however slowly the peer trickles bytes.

    ``on_timeout()`` runs once when it stops (http.server turns the error into a reply).
    """

    def __init__(self, sock: socket.socket, deadline: float, on_timeout: Callable[[], None] | None) -> None:
        super().__init__()
        self._sock, self._deadline, self._on_timeout = sock, deadline, on_timeout

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: WriteableBuffer) -> int:
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

    def log_error(self, format: str, *args: object) -> None:  # noqa: A002
        """http.server reports here each request it refuses: count it (a timeout is counted once)."""
        if "timed out" not in format:
            self.counters["xmlrpc_bad_requests"] += 1
            log.warning("ROS 1 XML-RPC: request from %s dropped: " + format, self.client_address[0], *args)

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002
        log.debug("ROS 1 XML-RPC: " + format, *args)


class _PooledServer(SimpleXMLRPCServer):
    """``SimpleXMLRPCServer`` whose connections are served by :class:`_Workers`."""

    workers: _Workers

    def process_request(self, request: _Request, client_address: _Address) -> None:
        if not self.workers.submit(cast(socket.socket, request), client_address):  # TCP: the request is its socket
            self.shutdown_request(request)

    def handle_error(self, request: _Request, client_address: _Address) -> None:
        """socketserver prints a traceback to stderr here: log it instead (the server goes
        on). A connection cut (the client gone, or ours cut at close) is one line, no trace."""
        exc = sys.exc_info()[1]
        if isinstance(exc, OSError):
            log.info("ROS 1 XML-RPC: connection from %s cut: %s", client_address[0], exc)
        else:
            log.error("ROS 1 XML-RPC: request from %s failed", client_address[0], exc_info=True)


class _Workers:
    """At most ``size`` owned threads serving queued connections (started as needed), at
    most half of them (and half of the queue) for one peer address."""

    def __init__(self, server: _PooledServer, name: str, size: int, waiting: int, counters: Counters) -> None:
        self._server, self._name, self._size, self._waiting = server, name, size, waiting
        self._per_peer, self._waiting_per_peer = max(1, size // 2), max(1, waiting // 2)
        self._counters = counters
        self._cond = threading.Condition()
        self._queue: collections.deque[tuple[socket.socket, _Address]] = collections.deque()
        self._threads: list[OwnedThread] = []
        self._idle = 0
        self._active: dict[socket.socket, str] = {}  # request being served -> its peer's address
        self._serving: collections.Counter[str] = collections.Counter()  # peer address -> requests served now
        self._closing = False

    def submit(self, request: socket.socket, address: _Address) -> bool:
        """Queue a connection; False when closing, the queue is full, or its peer has half
        of it already (the caller closes it)."""
        with self._cond:
            peer = address[0]
            if self._closing or len(self._queue) >= self._waiting or \
                    sum(1 for _, a in self._queue if a[0] == peer) >= self._waiting_per_peer:
                self._counters["xmlrpc_bad_requests"] += not self._closing
                return False
            self._queue.append((request, address))
            if self._idle < len(self._queue) and len(self._threads) < self._size:
                thread = OwnedThread(self._work, f"{self._name}-{len(self._threads) + 1}")
                self._threads.append(thread)
                thread.start()
            self._cond.notify_all()  # (an idle worker may wait for its peer's turn: each looks)
        return True

    def _take(self) -> tuple[socket.socket, _Address] | None:
        """The first queued connection whose peer has fewer than its share being served."""
        for job in self._queue:
            if self._serving[job[1][0]] < self._per_peer:
                self._queue.remove(job)
                return job
        return None

    def _next(self) -> tuple[socket.socket, _Address] | None:
        with self._cond:
            self._idle += 1
            job = None
            while not self._closing and (job := self._take()) is None:
                self._cond.wait()
            self._idle -= 1
            if self._closing or job is None:
                return None
            self._active[job[0]] = job[1][0]
            self._serving[job[1][0]] += 1
            return job

    def _work(self, _stopping: threading.Event) -> None:
        server = self._server
        while (job := self._next()) is not None:
            request, address = job
            try:
                server.finish_request(request, address)
            except Exception:  # noqa: BLE001 - one request's failure never ends the worker
                server.handle_error(request, address)
            finally:
                self._done(request)
                server.shutdown_request(request)

    def _done(self, request: socket.socket) -> None:
        with self._cond:
            peer = self._active.pop(request, None)
            if peer is not None:
                self._serving[peer] -= 1
                if self._serving[peer] <= 0:
                    del self._serving[peer]
                if self._queue:
                    self._cond.notify_all()  # a connection of that peer may now be served

    def close(self, timeout: float) -> None:
        """Drop what waits, cut what is being served, end the threads (idempotent)."""
        with self._cond:
            self._closing = True
            waiting, active = list(self._queue), list(self._active)
            self._queue.clear()
            self._cond.notify_all()
        for request, _ in waiting:
            self._server.shutdown_request(request)
        for request in active:
            try:
                request.shutdown(socket.SHUT_RDWR)  # its worker sees the end and closes it
            except OSError:
                pass
        for thread in list(self._threads):
            thread.join(timeout)


class RpcServer:
    """An XML-RPC API (``instance``'s methods) on ``host:port`` (0: any free port): one
    accept thread, at most ``workers`` request threads (see the module doc). Raises
    ``OSError`` when it cannot bind. :meth:`close` is idempotent."""

    def __init__(self, instance: object, host: str, port: int, counters: Counters, name: str,
                 max_bytes: int, max_seconds: float, workers: int = WORKERS) -> None:
        handler = type("Handler", (_Handler,), {"counters": counters, "max_bytes": max_bytes, "timeout": max_seconds})
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        server_class = type("Server", (_PooledServer,), {"address_family": family})
        self._server = server_class((host, port), requestHandler=handler, logRequests=False,
                                    allow_none=True, bind_and_activate=True)
        self._server.workers = _Workers(self._server, f"ros1-xmlrpc {name}", workers, WAITING, counters)
        self._server.timeout = 0.2  # handle_request() returns this often to see a stop
        self._server.register_instance(instance)
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
        """Stop accepting, cut the requests in hand, end every thread (idempotent; from a
        worker or the accept thread it only signals)."""
        self._stopping = True
        self._thread.join(timeout)  # (not from the server's own thread)
        if not self._thread.alive:
            self._server.server_close()
        self._server.workers.close(timeout)
