"""Owned threads: every thread scart starts has an owner that ends it.

Shutdown happens in two steps, as everywhere in scart: **signal** (set the thread's
``stopping`` event and call its wake-up, so a blocked thread notices at once), then
**join** (bounded by a timeout; never from the thread itself, which may be stopping
itself from inside its own loop). :class:`OwnedThread` is that, once, instead of a
``threading.Thread`` plus a stop flag plus a guarded join in every class::

    class Poller:
        def __init__(self) -> None:
            self._thread = OwnedThread(self._run, name="scart-poller")

        def _run(self, stopping: threading.Event) -> None:
            while not stopping.wait(0.5):
                ...

        def start(self) -> None:
            self._thread.start()

        def close(self) -> None:
            self._thread.stop()         # idempotent; safe from inside _run

Threads are daemons (a forgotten one never keeps the interpreter alive), but every
owner stops its own: tests check that none is left behind.
"""

from __future__ import annotations

import _thread
import logging
import threading
from collections.abc import Callable

__all__ = ["OwnedThread", "JOIN_TIMEOUT", "Wake"]

log = logging.getLogger(__name__)

JOIN_TIMEOUT = 5.0  #: seconds a stop waits for a thread, by default


class Wake:
    """A wake-up for one waiting thread: :meth:`set` from any thread, :meth:`clear` and
    :meth:`wait` in the waiter's, as with a ``threading.Event``, but built on one raw
    lock (a binary semaphore): a set and the wait it ends cost a few C calls, where an
    ``Event`` runs a ``Condition`` in Python (a waiter lock made, queued and notified).
    A task woken by a sample pays this at every cycle, cold after each wait.

    ``wait`` returning True means a :meth:`set` came since the last :meth:`clear`, or
    (rarely) just before it: the waiter re-checks what it waits for, as with any wake-up.
    """

    __slots__ = ("_lock", "_set")

    def __init__(self) -> None:
        self._lock = _thread.allocate_lock()
        self._lock.acquire()  # held while not set; a set releases it
        self._set = False

    def set(self) -> None:
        """Wake the waiter, now or at its next :meth:`wait` (any thread; never blocks)."""
        self._set = True
        try:
            self._lock.release()
        except RuntimeError:  # released already: a wake-up is pending
            pass

    def clear(self) -> None:
        """Forget a pending wake-up (the waiter's thread, before it checks its work)."""
        self._lock.acquire(False)
        self._set = False

    def is_set(self) -> bool:
        """Whether a wake-up came since the last :meth:`clear`."""
        return self._set

    def wait(self, timeout: float | None = None) -> bool:
        """Block until :meth:`set` (or ``timeout`` s); True when set. The waiter's thread only."""
        if self._lock.acquire(True, -1 if timeout is None else max(0.0, timeout)):
            self._lock.release()  # still set until cleared, as an Event's wait leaves it
            return True
        return False


class OwnedThread:
    """One thread with an owner (see the module docstring).

    ``target(stopping)`` runs in the thread; it should return soon after ``stopping`` is
    set. ``wake``, if given, is called by :meth:`signal` to unblock a thread waiting on
    something other than ``stopping`` (a socket, a condition). An exception escaping
    ``target`` is logged, never lost. Thread-safe; :meth:`start` runs the thread once.
    """

    __slots__ = ("name", "stopping", "_target", "_wake", "_thread", "_lock")

    def __init__(self, target: Callable[[threading.Event], None], name: str,
                 wake: Callable[[], None] | None = None) -> None:
        self.name = name
        self.stopping = threading.Event()
        self._target = target
        self._wake = wake
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    def start(self) -> OwnedThread:
        """Start the thread (once; a second call, or one after :meth:`signal`, does nothing)."""
        with self._lock:
            if self._thread is None and not self.stopping.is_set():
                self._thread = threading.Thread(target=self._main, name=self.name, daemon=True)
                self._thread.start()
        return self

    def _main(self) -> None:
        try:
            self._target(self.stopping)
        except Exception:  # noqa: BLE001 - an owned thread never dies silently
            log.exception("thread %s failed", self.name)

    @property
    def alive(self) -> bool:
        """Whether the thread runs now."""
        thread = self._thread
        return thread is not None and thread.is_alive()

    def in_thread(self) -> bool:
        """Whether the caller runs in this thread."""
        return self._thread is threading.current_thread()

    def signal(self) -> None:
        """Ask the thread to end: set ``stopping`` and wake it (idempotent, never blocks)."""
        self.stopping.set()
        wake = self._wake
        if wake is not None:
            try:
                wake()
            except Exception:  # noqa: BLE001 - waking is best effort; the thread still sees stopping
                log.debug("waking %s failed", self.name, exc_info=True)

    def join(self, timeout: float = JOIN_TIMEOUT) -> bool:
        """Wait up to ``timeout`` s for the thread to end; True when it has (or never ran,
        or the caller is the thread itself, which cannot wait for itself)."""
        thread = self._thread
        if thread is None or thread is threading.current_thread():
            return True
        thread.join(timeout)
        if thread.is_alive():
            log.warning("thread %s did not end within %.1f s", self.name, timeout)
            return False
        return True

    def stop(self, timeout: float = JOIN_TIMEOUT) -> bool:
        """:meth:`signal`, then :meth:`join`; True when the thread has ended."""
        self.signal()
        return self.join(timeout)

    def __repr__(self) -> str:
        state = "alive" if self.alive else ("stopping" if self.stopping.is_set() else "idle")
        return f"<OwnedThread {self.name} {state}>"
