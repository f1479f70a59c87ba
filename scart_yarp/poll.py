"""The io thread's readiness poll: ``select.epoll`` (``select.poll`` where there is none)
with a map from each file number to its socket and what it stands for.

Why not :mod:`selectors`: the io thread wakes for every message, cold, and the selector's
Python layer around the poll (a key per event, its event translation) costs about as
much as the poll itself. Not thread-safe: the io thread alone uses it (but :meth:`close`).
"""

from __future__ import annotations

import select
import socket
from typing import Generic, TypeVar

__all__ = ["Poll", "READ", "WRITE"]

D = TypeVar("D")

READ, WRITE = 1, 2  #: what a socket is watched for, and what :meth:`Poll.select` says is ready
_IN, _OUT = select.POLLIN, select.POLLOUT  # EPOLLIN and EPOLLOUT have the same values
_WRITABLE = select.POLLOUT | select.POLLERR | select.POLLHUP  # an error or a hang-up wakes both sides


class Poll(Generic[D]):
    """Sockets watched by one io thread, each with its ``data`` (of type ``D``)."""

    def __init__(self) -> None:
        self._epoll = select.epoll() if hasattr(select, "epoll") else None
        self._poll: select.epoll | select.poll = self._epoll if self._epoll is not None else select.poll()
        self._watched: dict[int, tuple[socket.socket, D]] = {}

    @staticmethod
    def _mask(events: int) -> int:
        return (_IN if events & READ else 0) | (_OUT if events & WRITE else 0)

    def register(self, sock: socket.socket, events: int, data: D) -> None:
        fd = sock.fileno()
        self._poll.register(fd, self._mask(events))
        self._watched[fd] = (sock, data)

    def modify(self, sock: socket.socket, events: int, data: D) -> None:
        """Change what ``sock`` is watched for; ``KeyError`` when it is not watched."""
        fd = sock.fileno()
        if fd not in self._watched:
            raise KeyError(fd)
        self._poll.modify(fd, self._mask(events))
        self._watched[fd] = (sock, data)

    def unregister(self, sock: socket.socket) -> None:
        """Stop watching ``sock``; ``KeyError`` when it is not watched (also once closed)."""
        fd = sock.fileno()
        if fd < 0:  # closed: its number is known only here
            fd = next((f for f, (s, _) in self._watched.items() if s is sock), -1)
        entry = self._watched.get(fd)
        if entry is None or entry[0] is not sock:
            raise KeyError(fd)
        del self._watched[fd]
        try:
            self._poll.unregister(fd)
        except (KeyError, ValueError, OSError):  # closed meanwhile: the kernel forgot it with the file
            pass

    def select(self, timeout: float) -> list[tuple[D, int]]:
        """``[(data, READ|WRITE)]`` of the sockets ready within ``timeout`` s."""
        if self._epoll is not None:
            ready = self._epoll.poll(timeout, max(1, len(self._watched)))
        else:
            ready = self._poll.poll(timeout * 1000)
        watched, out = self._watched, []
        for fd, events in ready:
            entry = watched.get(fd)
            if entry is not None:
                out.append((entry[1], (READ if events & ~_OUT else 0) | (WRITE if events & _WRITABLE else 0)))
        return out

    def close(self) -> None:
        self._watched.clear()
        if self._epoll is not None:
            self._epoll.close()
