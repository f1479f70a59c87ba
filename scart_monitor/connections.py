"""The monitor's open connections: how many, whose, and whether each is still sending its
request; the bounds that keep a slow or flooding client from taking the server.

- at most ``max_connections`` open at once;
- at most ``max_pending_per_peer`` of one peer address still sending their request;
- each request (head and body) must have arrived ``deadline`` s after its connection
  opened, whatever its pace: a client sending one byte now and then is cut then.

A new connection beyond a bound takes the place of the oldest connection still sending
its request (of that peer; of anyone when the server is full): a slowloris cannot keep
an honest request out, because honest requests arrive at once. When every connection is
being answered (event streams), the new one is refused. Thread-safe.
"""

from __future__ import annotations

import socket
import threading
import time

__all__ = ["Connections"]


class _Connection:
    """One open connection: its socket, peer address, when it opened, and whether it is
    being answered (its request has arrived)."""

    __slots__ = ("sock", "peer", "opened", "answering")

    def __init__(self, sock: socket.socket, peer: str) -> None:
        self.sock, self.peer, self.opened, self.answering = sock, peer, time.monotonic(), False

    def drop(self) -> None:
        """Shut the socket: the handler's read ends and its thread finishes."""
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass


class Connections:
    """The connections of one server, each owned by its handler thread (see the module)."""

    def __init__(self, max_connections: int, max_pending_per_peer: int, deadline: float) -> None:
        self.max_connections = max_connections
        self.max_pending_per_peer = max_pending_per_peer
        self.deadline = deadline
        self.dropped = 0  #: connections dropped before their request arrived (deadline or room)
        self._lock = threading.Lock()
        self._conns: dict[threading.Thread, _Connection] = {}
        self._swept = 0.0

    def admit(self, thread: threading.Thread, sock: socket.socket, peer: str) -> bool:
        """Register ``sock`` of ``peer``, served by ``thread``, making room if need be;
        False when it does not fit (every connection is being answered)."""
        with self._lock:
            pending = [c for c in self._conns.values() if not c.answering]
            mine = [c for c in pending if c.peer == peer]
            if len(mine) >= self.max_pending_per_peer:
                oldest = min(mine, key=lambda c: c.opened)
                self._drop(oldest)
                pending.remove(oldest)
            if len(self._conns) >= self.max_connections:
                if not pending:
                    return False
                self._drop(min(pending, key=lambda c: c.opened))
            self._conns[thread] = _Connection(sock, peer)
            return True

    def answering(self, thread: threading.Thread) -> None:
        """``thread``'s request has arrived: it is being answered (no deadline any more)."""
        with self._lock:
            conn = self._conns.get(thread)
            if conn is not None:
                conn.answering = True

    def sweep(self) -> None:
        """Drop the connections whose request has not arrived in time (cheap when called
        often: it looks at most ten times a second)."""
        now = time.monotonic()
        if now - self._swept < 0.1:
            return
        self._swept = now
        with self._lock:
            for conn in [c for c in self._conns.values() if not c.answering and now - c.opened > self.deadline]:
                self._drop(conn)

    def forget(self, thread: threading.Thread) -> None:
        """``thread``'s connection has ended."""
        with self._lock:
            self._conns.pop(thread, None)

    def count(self) -> int:
        """How many connections are open now."""
        with self._lock:
            return len(self._conns)

    def close_all(self, timeout: float) -> list[str]:
        """Shut every connection and join its thread (except the caller's own: ``stop()``
        called from a request answers it); the names of threads still alive after ``timeout``."""
        me = threading.current_thread()
        with self._lock:
            conns = [(t, c) for t, c in self._conns.items() if t is not me]
        for _thread, conn in conns:
            conn.drop()
        deadline = time.monotonic() + timeout
        for thread, _conn in conns:
            thread.join(max(0.0, deadline - time.monotonic()))
        return [t.name for t, _ in conns if t.is_alive()]

    def _drop(self, conn: _Connection) -> None:
        """Shut ``conn`` and forget it at once (its thread ends on its own). Lock held."""
        conn.drop()
        self.dropped += 1
        for thread, c in list(self._conns.items()):
            if c is conn:
                del self._conns[thread]
