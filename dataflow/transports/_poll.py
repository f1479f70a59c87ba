"""The readiness poll of the transports' io threads (private): ``select.epoll`` (or
``select.poll`` where there is no epoll), with a map from each file number to its socket
and handler.

Why not :mod:`selectors`: an io thread wakes for every sample, cold (after a wait, each
step costs several times its warm price), and the selector's Python layer around the
poll (its keys, its event translation) cost about as much as the poll itself. The loop
reads :attr:`Poller.watched` (``.get(fd, GONE)``) and the raw events directly:
``events & READABLE`` and ``events & WRITABLE`` (for a socket that asked for ``OUT``)
say what to do, as ``selectors`` would (an error or a hang-up wakes both).
"""

from __future__ import annotations

import select
import socket
from typing import Any

__all__ = ["GONE", "IN", "OUT", "Poller", "READABLE", "WRITABLE"]

IN: int = select.POLLIN  #: interest in reading (EPOLLIN has the same value)
OUT: int = select.POLLOUT  #: interest in room to write (EPOLLOUT likewise)
READABLE = ~OUT  #: the events that mean "read now": data, an error, a hang-up
WRITABLE = ~IN  #: the events that mean "write now" to a socket that asked for ``OUT``
#: What :attr:`Poller.watched` gives for a socket unwatched by a handler earlier in the
#: same batch of events: ``(socket, handler, events)``, all empty.
GONE: tuple[None, None, int] = (None, None, 0)


class Poller:
    """Sockets watched for an io thread (that thread only, but :meth:`close`)."""

    def __init__(self) -> None:
        self._epoll = select.epoll() if hasattr(select, "epoll") else None
        self._poll: select.epoll | select.poll = self._epoll if self._epoll is not None else select.poll()
        #: ``{fd: (socket, handler, events asked for)}``: what :meth:`poll` reports on.
        self.watched: dict[int, tuple[socket.socket, Any, int]] = {}

    def register(self, sock: socket.socket, events: int, handler: Any) -> None:
        fd = sock.fileno()
        self._poll.register(fd, events)
        self.watched[fd] = (sock, handler, events)

    def modify(self, sock: socket.socket, events: int, handler: Any) -> None:
        fd = sock.fileno()
        self._poll.modify(fd, events)
        self.watched[fd] = (sock, handler, events)

    def unregister(self, sock: socket.socket) -> None:
        """Stop watching ``sock`` (idempotent; also once it is closed)."""
        fd = sock.fileno()
        if fd < 0:  # closed: its number is known only here
            fd = next((f for f, (s, _, _) in self.watched.items() if s is sock), -1)
        entry = self.watched.get(fd)
        if entry is None or entry[0] is not sock:
            return
        del self.watched[fd]
        try:
            self._poll.unregister(fd)
        except (KeyError, ValueError, OSError):  # closed meanwhile: the kernel forgot it with the file
            pass

    def poll(self, timeout: float | None) -> list[tuple[int, int]]:
        """``[(fd, events)]`` ready within ``timeout`` s (None: no limit)."""
        if self._epoll is not None:
            return self._epoll.poll(-1 if timeout is None else timeout, max(1, len(self.watched)))
        return self._poll.poll(None if timeout is None else timeout * 1000)  # poll takes ms

    def handlers(self) -> list[Any]:
        """Every handler watched now."""
        return [handler for _, handler, _ in self.watched.values()]

    def close(self) -> None:
        self.watched.clear()
        if self._epoll is not None:
            self._epoll.close()
