"""Connection storage: data objects and buffers, lock-free, locked or unsynchronised.

Every connection (or, depending on ``BufferPolicy``, every port) owns one *storage*:
a data object (``ConnType.DATA``: the last sample only) or a bounded buffer
(``BUFFER``: FIFO, rejects when full; ``CIRCULAR_BUFFER``: ring, drops the oldest).

Lock-free guarantee
-------------------
No ``write``/``read``/``read_newest`` of a ``LOCK_FREE`` storage ever waits on a lock
held by another thread. Each operation is built only from steps that CPython performs
atomically under the GIL (one bytecode that runs C code which does not release the GIL):

* a data object publishes a new sample by one attribute store (a reference swap);
  a reader takes one attribute load, so it sees either the old or the new sample,
  never a mix (no torn sample: samples are whole Python objects, never copied field
  by field);
* "is this sample new?" is decided by ``list.pop()`` on the sample's one-element claim
  list: exactly one of {a reader, the writer that overwrites it} wins the claim, so a
  sample is delivered as NEW_DATA at most once and an overwritten unread sample is
  counted ``dropped`` at most once;
* a buffer is a ``collections.deque`` of samples plus a list of free-slot tokens:
  a writer pops a token (``list.pop``) then ``deque.append``s; a reader ``popleft``s
  then gives the token back. Capacity is exact, every sample is read at most once,
  and ``writes == reads + dropped + left`` holds for any mix of threads.

A thread preempted in the middle of an operation never blocks the others: they see
the storage either before or after each atomic step. Connect/disconnect (the setup
path) take a lock; the hot path never does.

Truth table of a ``DATA`` storage (after RTT's ``DataObjectLockFree``):

=========================  ==============================  =========================
situation                  ``read()`` returns              ``dropped``
=========================  ==============================  =========================
never written / cleared    ``(NO_DATA, None)``             —
written, not yet read      ``(NEW_DATA, v)``, then OLD     —
read, nothing new since    ``(OLD_DATA, v)`` (last value)  —
written twice before read  ``(NEW_DATA, v2)``              +1 (v1 overwritten unread)
=========================  ==============================  =========================

Buffers: ``read()`` pops the oldest sample (NEW_DATA); an empty buffer that delivered
before answers ``(OLD_DATA, last)``; one that never did answers ``(NO_DATA, None)``.

Free-threaded CPython (PEP 703, ``python3.13t``): there is no GIL, but ``list.pop``,
``list.append``, ``deque.append``/``popleft`` and attribute stores are still made
thread-safe by per-object critical sections; the claims above then rest on those
short internal per-object locks (held for a few instructions, never across user code)
instead of the GIL — formally "obstruction-free with tiny critical sections" rather
than lock-free. ``dropped`` counters are per-thread cells, so they stay exact.
With several *concurrent writers* on one DATA storage, the "overwritten unread" count
may miss a sample replaced in the same instant (no atomic exchange in Python); the
value delivered is still always a whole, single sample.

``LOCKED`` storages serialise every operation on a ``threading.Lock`` (RTT's
``DataObjectLocked``): simple, fair, but a preempted holder delays the others.

A buffer whose policy makes its writer wait (YARP's flow control: ``ConnPolicy.wait``) is a
:class:`WaitingStorage`: a write to a full buffer waits for a read to make room (at most
``wait_timeout`` s, then refused and counted), and every read tells the waiting writer.
Only such a connection's writer ever waits; its reads take a lock to tell it.
``UNSYNC`` storages are for single-threaded use; in CPython they share the lock-free
implementation (which costs no more than an unsynchronised one would).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from .policy import ConnPolicy, ConnType, FlowStatus, LockPolicy, WaitMode

if TYPE_CHECKING:
    from .ports import InputPort

__all__ = ["Storage", "DataObject", "Buffer", "LockedStorage", "WaitingStorage", "make_storage"]

_NONE: Any = object()  # "no value", distinct from a written None
_NEW = FlowStatus.NEW_DATA
_OLD = FlowStatus.OLD_DATA
_NO = FlowStatus.NO_DATA
_get_ident = threading.get_ident
T = TypeVar("T")


class _Counter:
    """A counter incremented from many threads without a lock: one cell per thread."""

    __slots__ = ("_cells",)

    def __init__(self) -> None:
        self._cells: dict[int, int] = {}

    def add(self, n: int = 1) -> None:
        cells = self._cells
        tid = _get_ident()
        cells[tid] = cells.get(tid, 0) + n  # only this thread writes this key

    @property
    def value(self) -> int:
        return sum(list(self._cells.values()))


class Storage(Generic[T]):
    """Base of a connection's storage of samples of type ``T``. ``readers`` are the input
    ports fed by it."""

    __slots__ = ("policy", "readers", "_drops")

    def __init__(self, policy: ConnPolicy) -> None:
        self.policy = policy
        self.readers: tuple[InputPort[T], ...] = ()
        self._drops = _Counter()

    @property
    def dropped(self) -> int:
        """Samples lost before being read (rejected, evicted, overwritten or cleared)."""
        return self._drops.value

    def write(self, value: T) -> bool:  # pragma: no cover - interface
        """Store ``value``; False when it was rejected (full BUFFER). Never blocks (but a
        :class:`WaitingStorage`'s, whose writer asked to wait)."""
        raise NotImplementedError

    def write_now(self, value: T) -> bool:
        """:meth:`write` that never waits, whatever the policy (a transport's thread, which
        must not: it holds the writer back by other means)."""
        return self.write(value)

    def has_room(self) -> bool:
        """A write now would be taken without dropping anything (DATA: always)."""
        return True

    def read(self) -> tuple[FlowStatus, T | None]:  # pragma: no cover - interface
        """Take the next sample (see the truth table). Never blocks."""
        raise NotImplementedError

    def read_newest(self) -> tuple[FlowStatus, T | None]:
        """Like ``read`` but skips to the newest sample (skipped ones count as dropped)."""
        return self.read()

    def clear(self) -> None:  # pragma: no cover - interface
        """Forget every sample: the next read is NO_DATA until a new write."""
        raise NotImplementedError

    def size(self) -> int:
        """Samples currently held unread (0 or 1 for a data object)."""
        return 0


class DataObject(Storage[T]):
    """Last-value storage (``ConnType.DATA``), lock-free: one reference swap per write.

    A sample lives in a cell ``[value, token]``; whoever pops the token first (a reader:
    NEW_DATA, or the writer replacing it: dropped) consumes its newness.
    """

    __slots__ = ("_cell",)

    def __init__(self, policy: ConnPolicy) -> None:
        super().__init__(policy)
        self._cell: list[Any] | None = None

    def write(self, value: T) -> bool:
        prev = self._cell
        self._cell = [value, True]
        if prev is not None and len(prev) == 2:
            try:
                prev.pop()
            except IndexError:  # a reader consumed it in the meantime
                return True
            self._drops.add()
        return True

    write_now = write  # never waits: the same, one call less (a transport's thread, every sample)

    def read(self) -> tuple[FlowStatus, T | None]:
        cell = self._cell
        if cell is None:
            return _NO, None
        if len(cell) == 2:
            try:
                cell.pop()
                return _NEW, cell[0]
            except IndexError:
                pass
        return _OLD, cell[0]

    def clear(self) -> None:
        cell, self._cell = self._cell, None
        if cell is not None and len(cell) == 2:  # unread: counted as dropped, as a buffer's clear counts
            try:
                cell.pop()
                self._drops.add()
            except IndexError:  # a reader took it meanwhile
                pass

    def size(self) -> int:
        cell = self._cell
        return 1 if cell is not None and len(cell) == 2 else 0


class Buffer(Storage[T]):
    """Bounded FIFO (``BUFFER``) or ring (``CIRCULAR_BUFFER``), lock-free MPMC.

    Capacity is exact: a writer must take a free-slot token before appending.
    """

    __slots__ = ("_items", "_free", "_last", "_circular")

    def __init__(self, policy: ConnPolicy) -> None:
        super().__init__(policy)
        self._items: deque[T] = deque()
        self._free: list[None] = [None] * policy.size
        self._last: T = _NONE
        self._circular = policy.type is ConnType.CIRCULAR_BUFFER

    def write(self, value: T) -> bool:
        try:
            self._free.pop()
        except IndexError:
            if not self._circular or not self._evict_oldest():
                self._drops.add()
                return False
        self._items.append(value)
        return True

    write_now = write  # never waits (as DataObject's)

    def _evict_oldest(self) -> bool:
        """Make room in a full ring by dropping its oldest sample; True when a slot is ours."""
        for _ in range(8):  # bounded: each failure means another thread made progress
            try:
                self._items.popleft()
                self._drops.add()
                return True
            except IndexError:
                pass
            try:  # a reader emptied it and is returning its token
                self._free.pop()
                return True
            except IndexError:
                continue
        return False

    def read(self) -> tuple[FlowStatus, T | None]:
        try:
            value = self._items.popleft()
        except IndexError:
            last = self._last
            return (_NO, None) if last is _NONE else (_OLD, last)
        self._free.append(None)
        self._last = value
        return _NEW, value

    def read_newest(self) -> tuple[FlowStatus, T | None]:
        status, value = self.read()
        if status is not _NEW:
            return status, value
        while True:
            more, newer = self.read()
            if more is not _NEW:
                return _NEW, value
            self._drops.add()  # the skipped sample never reached the user
            value = newer

    def clear(self) -> None:
        while True:
            try:
                self._items.popleft()
            except IndexError:
                break
            self._free.append(None)
            self._drops.add()
        self._last = _NONE

    def size(self) -> int:
        return len(self._items)


class LockedStorage(Storage[T]):
    """Wraps a storage so that every operation holds one ``threading.Lock`` (``LOCKED``)."""

    __slots__ = ("_inner", "_lock")

    def __init__(self, inner: Storage[T]) -> None:
        super().__init__(inner.policy)
        self._inner = inner
        self._lock = threading.Lock()

    @property
    def dropped(self) -> int:
        return self._inner.dropped

    def write(self, value: T) -> bool:
        with self._lock:
            return self._inner.write(value)

    def read(self) -> tuple[FlowStatus, T | None]:
        with self._lock:
            return self._inner.read()

    def read_newest(self) -> tuple[FlowStatus, T | None]:
        with self._lock:
            return self._inner.read_newest()

    def clear(self) -> None:
        with self._lock:
            self._inner.clear()

    def size(self) -> int:
        return self._inner.size()


class WaitingStorage(Storage[T]):
    """Wraps a buffer whose writer waits for room (``ConnPolicy.wait``): :meth:`write` to a
    full buffer blocks until a read frees a slot or ``wait_timeout`` s pass (then it is
    refused and counted, as a full buffer refuses); every read wakes the writer. Thread-safe.
    ``room`` callbacks (:meth:`on_room`) are called after each read that freed a slot."""

    __slots__ = ("_inner", "_room", "_callbacks", "waited")

    def __init__(self, inner: Storage[T]) -> None:
        super().__init__(inner.policy)
        self._inner = inner
        self._room = threading.Condition(threading.Lock())
        self._callbacks: tuple[Callable[[], object], ...] = ()
        self.waited = 0.0  #: seconds writers spent waiting for room, in all

    @property
    def dropped(self) -> int:
        return self._inner.dropped

    def has_room(self) -> bool:
        return self._inner.size() < self.policy.size

    def write_now(self, value: T) -> bool:
        return self._inner.write(value)

    def write(self, value: T) -> bool:
        if not self.has_room():
            started = time.monotonic()
            with self._room:
                self._room.wait_for(self.has_room, self.policy.wait_timeout)
            self.waited += time.monotonic() - started
        return self._inner.write(value)

    def _freed(self, status: FlowStatus) -> None:
        if status is _NEW:
            with self._room:
                self._room.notify_all()
            for callback in self._callbacks:
                callback()

    def read(self) -> tuple[FlowStatus, T | None]:
        status, value = self._inner.read()
        self._freed(status)
        return status, value

    def read_newest(self) -> tuple[FlowStatus, T | None]:
        status, value = self._inner.read_newest()
        self._freed(status)
        return status, value

    def clear(self) -> None:
        self._inner.clear()
        self._freed(_NEW)

    def size(self) -> int:
        return self._inner.size()

    def on_room(self, callback: Callable[[], object]) -> None:
        """Call ``callback()`` (in the reader's thread) whenever a read makes room."""
        self._callbacks = (*self._callbacks, callback)


def make_storage(policy: ConnPolicy) -> Storage[Any]:
    """The storage a connection with ``policy`` needs (new, empty), for samples of any
    type (the port it serves decides which)."""
    inner: Storage[Any] = DataObject(policy) if policy.type is ConnType.DATA else Buffer(policy)
    if policy.lock_policy is LockPolicy.LOCKED:
        inner = LockedStorage(inner)
    if policy.wait is not WaitMode.NO_WAIT and policy.type is not ConnType.DATA:
        return WaitingStorage(inner)
    return inner
