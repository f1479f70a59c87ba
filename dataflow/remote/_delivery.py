"""Handing samples from a transport's thread to the consumer's (private; no gRPC here).

A :class:`Mailbox` is the policy-shaped hand-over: it keeps items in the core's own
connection storage (:mod:`dataflow.buffers`), so DATA / BUFFER / CIRCULAR_BUFFER mean
exactly what they mean between two local ports, and losses are counted where a local
connection counts them. A :class:`Dispatcher` is the observer's thread that drains one.
Used by the client side of a subscription (:mod:`dataflow.remote._subscription`) and the
in-process one (:mod:`dataflow.remote.local`).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Generic, TypeVar

from dataflow.buffers import make_storage
from dataflow.policy import ConnPolicy, ConnType, FlowStatus, LockPolicy
from dataflow.threads import OwnedThread

__all__ = ["Dispatcher", "Mailbox"]

log = logging.getLogger(__name__)

T = TypeVar("T")
_NEW = FlowStatus.NEW_DATA


class Mailbox(Generic[T]):
    """A policy-shaped hand-over between a producer and a consumer's thread.

    DATA keeps only the newest item; BUFFER(n) refuses items when n are pending;
    CIRCULAR_BUFFER(n) drops the oldest — the storage of a local connection with that
    policy, which counts every item lost (:attr:`dropped`). :meth:`put` never blocks;
    :meth:`get` blocks up to ``timeout``. Thread-safe.
    """

    def __init__(self, policy: ConnPolicy) -> None:
        self._storage = make_storage(policy.with_(lock_policy=LockPolicy.UNSYNC))  # every use holds _cond
        self._ring = policy.type is ConnType.CIRCULAR_BUFFER
        self._limit = self._capacity = policy.size if policy.type is not ConnType.DATA else 1
        self._limited = 0  # items lost to limit() (the storage counts the policy's own)
        self._cond = threading.Condition()
        self._closed = False

    @property
    def dropped(self) -> int:
        """Items lost: overwritten, refused or evicted by the policy, or by :meth:`limit`."""
        return self._storage.dropped + self._limited

    def __len__(self) -> int:
        """Items pending."""
        with self._cond:
            return self._storage.size()

    def limit(self, size: int) -> None:
        """Hold at most ``size`` items from now on (never more than the policy says; items
        already pending stay). Used to keep a subscription within a byte budget."""
        with self._cond:
            self._limit = max(1, min(size, self._capacity))

    def put(self, item: T) -> bool:
        """Store ``item``; False when it was refused (full BUFFER)."""
        with self._cond:
            storage = self._storage
            if self._limit < self._capacity and storage.size() >= self._limit:  # below the policy's size
                self._limited += 1
                if not self._ring:
                    return False
                storage.read()  # a ring makes room by losing its oldest
            stored = storage.write(item)
            if stored:
                self._cond.notify()
            return stored

    def get(self, timeout: float) -> T | None:
        """The oldest pending item, or None after ``timeout`` s or when closed."""
        with self._cond:
            status, item = self._storage.read()
            if status is not _NEW and not self._closed and timeout > 0:
                self._cond.wait(timeout)
                status, item = self._storage.read()
            return item if status is _NEW else None

    def clear(self) -> None:
        """Forget the pending items (the storage's own clear, which counts them as a local
        connection's clear does)."""
        with self._cond:
            self._storage.clear()

    def close(self) -> None:
        """Wake :meth:`get` for good (idempotent)."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()


class Dispatcher:
    """The observer's thread: takes items from a :class:`Mailbox` and calls ``deliver``.

    ``on_idle`` is called whenever ``idle`` s pass without an item (heartbeat watchdog).
    An exception in ``deliver`` is logged and does not end the thread.
    """

    def __init__(
        self,
        name: str,
        mailbox: Mailbox,
        deliver: Callable[[object], None],
        idle: float = 0.5,
        on_idle: Callable[[], None] | None = None,
    ) -> None:
        self._mailbox = mailbox
        self._deliver = deliver
        self._idle = idle
        self._on_idle = on_idle
        self._thread = OwnedThread(self._run, name, wake=mailbox.close)

    def start(self) -> None:
        """Start the thread (once)."""
        self._thread.start()

    def _run(self, stopping: threading.Event) -> None:
        while not stopping.is_set():
            item = self._mailbox.get(self._idle)
            if stopping.is_set():
                return
            if item is None:
                if self._on_idle is not None:
                    self._on_idle()
                continue
            try:
                self._deliver(item)
            except Exception:
                log.exception("observer of %s raised", self._thread.name)

    def stop(self) -> None:
        """Signal and join (unless called from the dispatcher thread itself)."""
        self._thread.stop()
