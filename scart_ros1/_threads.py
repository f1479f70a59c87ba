"""The node's threads (private): each has an owner that starts it once and joins it,
bounded, when it closes. Daemons, so that a forgotten one never keeps the interpreter
alive; every owner still ends its own. An exception escaping a thread is logged, never
lost. (The stack stands alone, so it keeps this small helper rather than borrowing one.)
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

__all__ = ["OwnedThread"]

log = logging.getLogger(__name__)


class OwnedThread:
    """One thread running ``target(stopping)``; thread-safe, :meth:`start` runs it once."""

    __slots__ = ("name", "stopping", "_target", "_thread", "_lock")

    def __init__(self, target: Callable[[threading.Event], None], name: str) -> None:
        self.name = name
        self.stopping = threading.Event()
        self._target = target
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()

    def start(self) -> OwnedThread:
        """Start the thread (once; a second call does nothing)."""
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

    def join(self, timeout: float) -> bool:
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
