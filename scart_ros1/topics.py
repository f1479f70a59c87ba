"""ROS 1 topics over TCPROS: :class:`Publisher` and :class:`Subscriber`.

A publisher is served by the node's TCPROS listener: a subscriber's header is checked
(md5sum ``*`` is accepted, as ROS does; another md5sum is refused, both types and sums
in the error header and the log), answered, and the connection joins the publisher.
:meth:`Publisher.publish` serialises once and hands the frame to each connection, which
sends it from the caller's thread when the socket takes it (see :class:`~.io.Conn`).

A subscriber connects to every publisher the master names (``registerSubscriber``,
``publisherUpdate``): ``requestTopic``, a TCP connection, a header each way, all on the
control thread, bounded in time. Frames are then read on the io thread and given to the
callback, as a message object or, with ``raw=True``, as bytes. A publisher that goes
away while still listed is tried again, with backoff.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from .io import RECV_BYTES, RECV_LARGE, Conn, Counters, FrameReader, InboundConn
from .master import MasterError, call
from .msgs import MsgType
from .tcpros import LEN, HeaderError, encode_header, read_header

if TYPE_CHECKING:
    from .node import Node

__all__ = ["Publisher", "Subscriber"]

log = logging.getLogger(__name__)

RETRY_FIRST, RETRY_MAX = 0.2, 10.0  # s between attempts to reach a listed publisher
_QUIET = ("done", "node closing", "closed", "publisher no longer listed", "unsubscribed", "unadvertised")


def _often(n: int) -> bool:
    """Log the 1st, 2nd, 4th, 8th... occurrence of a repeated problem."""
    return n & (n - 1) == 0


def md5_refusal(caller: str, topic: str, their: tuple[str, str], ours: tuple[str, str]) -> str:
    """roscpp's words for an md5sum mismatch: both types and both sums."""
    return (f"Client [{caller}] wants topic [{topic}] to have datatype/md5sum [{their[0]}/{their[1]}], "
            f"but our version has [{ours[0]}/{ours[1]}]. Dropping connection.")


class Publisher:
    """An advertised topic (from :meth:`Node.advertise`): thread-safe, never blocks."""

    def __init__(self, node: Node, topic: str, msgtype: MsgType, latch: bool, queue_size: int, queue_bytes: int) -> None:
        self.topic, self.type, self.latch = topic, msgtype, latch
        self._node, self._queue = node, (queue_size, queue_bytes)
        self._cond = threading.Condition()
        self._conns: tuple[Conn, ...] = ()
        self._latched: bytes | bytearray | None = None
        self._counters = Counters("published", "md5_mismatches", "subscribers_gone")
        self._gone_stats = Counters("messages_sent", "bytes_sent", "dropped")
        self.closed = False
        self.last_refusal = ""  #: the last subscriber refused (another md5sum), in ROS's words

    def __repr__(self) -> str:
        return f"Publisher({self.topic!r}, {self.type.name!r}, connections={len(self._conns)})"

    def publish(self, msg: object) -> int:
        """Send ``msg`` (a message object of this type) to every subscriber.

        Returns how many connections took it (sent or queued); 0 once closed. With no
        subscriber and no latch, ``msg`` is not even serialised. Raises
        ``ValueError``/``TypeError``/``AttributeError`` if ``msg`` is not of this type.
        """
        if not self._conns and not self.latch:
            with self._cond:
                self._counters["published"] += not self.closed
            return 0
        return self._send(self.type.frame(msg))

    def publish_raw(self, data: bytes | bytearray | memoryview) -> int:
        """Send ``data``, already ROS 1 bytes of this type (not checked); as :meth:`publish`."""
        return self._send(LEN.pack(len(data)) + bytes(data))

    def publish_frame(self, frame: bytes | bytearray) -> int:
        """Send ``frame``, one message of this type as :meth:`MsgType.frame` makes it (not
        checked, not copied: never change it afterwards); as :meth:`publish`."""
        return self._send(frame)

    @property
    def wanted(self) -> bool:
        """Whether a message published now goes anywhere (a subscriber, or the latch)."""
        return bool(self._conns) or self.latch

    def _send(self, frame: bytes | bytearray) -> int:
        with self._cond:
            if self.closed:
                return 0
            if self.latch:
                self._latched = frame
            conns = self._conns
            self._counters["published"] += 1
        taken = 0
        for conn in conns:
            taken += conn.send(frame)
        return taken

    @property
    def num_connections(self) -> int:
        return len(self._conns)

    def wait_for_connections(self, count: int = 1, timeout: float = 5.0) -> bool:
        """Block until at least ``count`` subscribers are connected (True) or ``timeout`` s pass."""
        with self._cond:
            return self._cond.wait_for(lambda: len(self._conns) >= count or self.closed, timeout) and not self.closed

    @property
    def counters(self) -> dict[str, int]:
        """``published``, ``messages_sent``, ``bytes_sent``, ``dropped`` (queues full),
        ``md5_mismatches``, ``subscribers_gone``, ``connections``."""
        with self._cond:
            out = self._counters.snapshot()
            for key, value in self._gone_stats.items():
                out[key] = value + sum(c.stats[key] for c in self._conns)
            out["connections"] = len(self._conns)
            return out

    def connections(self) -> list[Conn]:
        return list(self._conns)

    # -- the io thread --------------------------------------------------------------------
    def accept(self, conn: InboundConn, header: dict[str, str]) -> None:
        """A subscriber's header for this topic: refuse it or answer and join it."""
        caller = header.get("callerid", "?")
        their = (header.get("type", "*"), header.get("md5sum", ""))
        if their[1] not in ("*", self.type.md5sum):
            self._refuse(conn, md5_refusal(caller, self.topic, their, (self.type.name, self.type.md5sum)))
            return
        conn.set_nodelay(header.get("tcp_nodelay") == "1")
        conn.peer_id, conn.topic, conn.direction = caller, self.topic, "o"
        conn.max_queue, conn.max_queue_bytes = self._queue
        conn.idle_kind = "subscriber"  # closed when it takes nothing of what waits for it, for long
        conn.send(encode_header({
            "callerid": self._node.caller_id, "topic": self.topic, "type": self.type.name,
            "md5sum": self.type.md5sum, "message_definition": self.type.definition,
            "latching": "1" if self.latch else "0",
        }), droppable=False)
        conn.on_data = _ignore
        conn.on_close = self._gone
        with self._cond:
            if self.closed:
                conn.close_when_flushed()
                return
            self._conns += (conn,)
            if self._latched is not None:
                conn.send(self._latched)
            self._cond.notify_all()

    def _refuse(self, conn: InboundConn, error: str) -> None:
        self.last_refusal = error
        self._counters["md5_mismatches"] += 1
        self._node.counters["md5_mismatches"] += 1
        log.warning("ROS 1 publisher %s: %s", self.topic, error)
        conn.send(encode_header({"error": error}), droppable=False)
        conn.close_when_flushed()

    def _gone(self, conn: Conn, reason: str) -> None:
        with self._cond:
            self._conns = tuple(c for c in self._conns if c is not conn)
            for key in self._gone_stats:
                self._gone_stats[key] += conn.stats[key]
            self._counters["subscribers_gone"] += 1
            self._cond.notify_all()
        log.debug("ROS 1 publisher %s: subscriber %s gone: %s", self.topic, getattr(conn, "peer_id", "?"), reason)

    def close(self) -> None:
        """Unadvertise and drop every subscriber (idempotent; any thread)."""
        with self._cond:
            if self.closed:
                return
            self.closed = True
            conns = self._conns
            self._cond.notify_all()
        for conn in conns:
            conn.close("unadvertised")
        self._node._drop_publisher(self)


def _ignore(data: bytes) -> None:
    """A subscriber has nothing more to say after its header: what it sends is dropped."""


class SubConn(Conn):
    """A connection to one publisher: frames in, to the subscriber (io thread)."""

    reader: FrameReader

    def on_readable(self) -> None:
        reader = self.reader
        data = self.recv(RECV_LARGE if reader.missing() > RECV_BYTES else RECV_BYTES)
        if data:
            reader.feed(data)


class _Refused(Exception):
    """A publisher refused the connection (its error header) or answered another md5sum."""


class Subscriber:
    """A subscription (from :meth:`Node.subscribe`); the callback runs on the io thread."""

    def __init__(self, node: Node, topic: str, msgtype: MsgType | None, callback: Callable[[Any], None],
                 raw: bool, tcp_nodelay: bool) -> None:
        self.topic, self.type, self.raw, self.tcp_nodelay = topic, msgtype, raw, tcp_nodelay
        self._node, self._callback = node, callback
        self._de = None if raw or msgtype is None else msgtype.deserialize
        self._md5 = msgtype.md5sum if msgtype else "*"
        self._type_name = msgtype.name if msgtype else "*"
        self._lock = threading.Lock()
        self._publishers: set[str] = set()
        self._conns: dict[str, SubConn] = {}
        self._retry: dict[str, float] = {}
        self._counters = Counters("received", "bad_messages", "callback_errors", "oversized", "connect_failures",
                                  "md5_mismatches", "publishers_gone")
        self.closed = False
        self.last_refusal = ""  #: the last publisher refused (another md5sum, or it refused us), in ROS's words

    def __repr__(self) -> str:
        return f"Subscriber({self.topic!r}, {self._type_name!r}, connections={len(self._conns)})"

    @property
    def counters(self) -> dict[str, int]:
        """``received``, ``bad_messages``, ``callback_errors``, ``oversized``,
        ``connect_failures``, ``md5_mismatches``, ``publishers_gone``, ``connections``."""
        out = self._counters.snapshot()
        out["connections"] = len(self._conns)
        return out

    @property
    def num_connections(self) -> int:
        return len(self._conns)

    def connections(self) -> list[Conn]:
        with self._lock:
            return list(self._conns.values())

    # -- the control thread ---------------------------------------------------------------
    def update_publishers(self, uris: list[str]) -> None:
        """The master's list of publishers: connect to new ones, drop the unlisted."""
        with self._lock:
            self._publishers = set(uris)
            gone = [c for uri, c in self._conns.items() if uri not in self._publishers]
        for conn in gone:
            conn.close("publisher no longer listed")
        for uri in uris:
            self._node.control.submit(self._connect, uri)

    def _connect(self, uri: str) -> None:
        with self._lock:
            if self.closed or uri not in self._publishers or uri in self._conns:
                return
        try:
            sock = self._handshake(uri)
        except (_Refused, MasterError, HeaderError, OSError, ValueError) as exc:
            self._failed(uri, exc)
            return
        self._retry.pop(uri, None)
        self._join(uri, sock)

    def _join(self, uri: str, sock: socket.socket) -> None:
        conn = SubConn(self._node.loop, sock, uri)
        conn.peer_id, conn.topic, conn.direction = uri, self.topic, "i"
        conn.reader = FrameReader(self._node.limits.max_message, self._deliver, self._oversized)
        conn.on_close = self._gone
        with self._lock:
            if self.closed or uri not in self._publishers:
                conn.close("publisher no longer listed")
                return
            self._conns[uri] = conn
        self._node.loop.call_soon(self._node.loop.register, sock, conn)

    def _failed(self, uri: str, exc: Exception) -> None:
        if isinstance(exc, _Refused):
            self.last_refusal = f"{uri}: {exc}"
        self._counters["connect_failures"] += 1
        self._node.counters["connect_failures"] += 1
        delay = self._retry.get(uri, RETRY_FIRST)
        self._retry[uri] = min(delay * 2, RETRY_MAX)
        if isinstance(exc, _Refused):
            delay = RETRY_MAX  # a refusal will not change soon
        if _often(self._counters["connect_failures"]):
            log.warning("ROS 1 subscriber %s: publisher %s: %s (retrying in %.1f s)", self.topic, uri, exc, delay)
        self._node.control.submit(self._connect, uri, delay=delay)

    def _handshake(self, uri: str) -> socket.socket:
        limits, node = self._node.limits, self._node
        proto = call(uri, "requestTopic", node.caller_id, self.topic, [["TCPROS"]],
                     timeout=limits.connect_timeout, what="publisher")
        if not (isinstance(proto, list) and len(proto) >= 3 and proto[0] == "TCPROS" and isinstance(proto[1], str)
                and isinstance(proto[2], int) and 0 < proto[2] < 65536):
            raise ValueError(f"requestTopic answered {str(proto)[:80]}, not ['TCPROS', host, port]")
        sock = socket.create_connection((proto[1], proto[2]), timeout=limits.connect_timeout)
        try:
            self._exchange_headers(sock)
        except BaseException:
            sock.close()
            raise
        return sock

    def _exchange_headers(self, sock: socket.socket) -> None:
        if self.tcp_nodelay:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        ours = {"callerid": self._node.caller_id, "topic": self.topic, "md5sum": self._md5, "type": self._type_name,
                "tcp_nodelay": "1" if self.tcp_nodelay else "0"}
        if self.type is not None:
            ours["message_definition"] = self.type.definition
        sock.sendall(encode_header(ours))
        header = read_header(sock, time.monotonic() + self._node.limits.connect_timeout, self._node.limits.max_header)
        if "error" in header:
            raise _Refused(f"publisher refused: {header['error']} (we asked for {self._type_name}/{self._md5})")
        theirs = (header.get("type", "?"), header.get("md5sum", "?"))
        if self._md5 != "*" and theirs[1] != self._md5:
            self._counters["md5_mismatches"] += 1
            self._node.counters["md5_mismatches"] += 1
            raise _Refused(md5_refusal(self._node.caller_id, self.topic, (self._type_name, self._md5), theirs))

    # -- the io thread --------------------------------------------------------------------
    def _deliver(self, payload: bytes) -> None:
        counters = self._counters
        counters["received"] += 1
        if self._de is None:
            value: object = payload
        else:
            try:
                value = self._de(payload)
            except ValueError as exc:
                counters["bad_messages"] += 1
                if _often(counters["bad_messages"]):
                    log.warning("ROS 1 subscriber %s: %s (dropped)", self.topic, exc)
                return
        try:
            self._callback(value)
        except Exception:
            counters["callback_errors"] += 1
            self._node.counters["callback_errors"] += 1
            if _often(counters["callback_errors"]):
                log.exception("ROS 1 subscriber %s: the callback failed", self.topic)

    def _oversized(self, size: int) -> None:
        self._counters["oversized"] += 1
        self._node.counters["oversized_messages"] += 1
        if _often(self._counters["oversized"]):
            log.warning("ROS 1 subscriber %s: a %d-byte message exceeds the %d-byte limit: skipped",
                        self.topic, size, self._node.limits.max_message)

    def _gone(self, conn: Conn, reason: str) -> None:
        uri = conn.peer
        with self._lock:
            if self._conns.get(uri) is conn:
                del self._conns[uri]
            listed = uri in self._publishers and not self.closed
        if reason in _QUIET:
            return
        self._counters["publishers_gone"] += 1
        self._node.counters["peer_disconnects"] += 1
        if listed:
            log.info("ROS 1 subscriber %s: publisher %s went away (%s): reconnecting", self.topic, uri, reason)
            self._node.control.submit(self._connect, uri, delay=RETRY_FIRST)

    def close(self) -> None:
        """Unsubscribe and close every connection (idempotent; any thread)."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            conns = list(self._conns.values())
        for conn in conns:
            conn.close("unsubscribed")
        self._node._drop_subscriber(self)
