"""The runtime's bounded pool for one-way calls: daemon worker threads fed by a bounded
queue, started on demand, drained with a deadline on close."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from typing import TypeAlias

__all__ = ["WORKER_PREFIX", "OnewayPool"]

#: A one-way call: what runs, and its arguments (only passed on: its result is dropped).
Job: TypeAlias = Callable[..., object]
Args: TypeAlias = tuple[object, ...]
Kwargs: TypeAlias = dict[str, object]

#: Name prefix of the worker threads (``scart-oneway_0``, ...): ``stop()`` called from one
#: of them does not wait for itself.
WORKER_PREFIX = "scart-oneway"


class OnewayPool:
    """Daemon worker threads fed by a bounded queue; knows which operation each worker runs.

    ``submit`` raises ``queue.Full`` when ``max_pending`` calls wait and ``RuntimeError``
    once closed. ``close(deadline)`` lets workers drain the queue until ``deadline``, then
    drops what is still queued; returns (dropped count, labels of calls still running)."""

    def __init__(self, workers: int, max_pending: int, run: Callable[[str, Job, Args, Kwargs], None]) -> None:
        self._queue: queue.Queue[tuple[str, Job, Args, Kwargs] | None] = queue.Queue(max_pending + max(1, workers))  # room for the stop sentinels
        self._max_pending = max_pending
        self._run = run
        self._lock = threading.Lock()
        self._progress = threading.Condition(self._lock)  # notified when a worker takes or finishes a call
        self._closed = False
        self.running: dict[threading.Thread, str] = {}
        self._workers = max(1, workers)
        self._threads: list[threading.Thread] = []  # started on demand, up to ``workers``
        self._idle = 0

    def submit(self, label: str, fn: Job, args: Args, kwargs: Kwargs) -> None:
        with self._lock:
            if self._closed:
                raise RuntimeError("runtime stopped")
            if self._queue.qsize() >= self._max_pending:
                raise queue.Full
            self._queue.put_nowait((label, fn, args, kwargs))
            if self._idle < self._queue.qsize() and len(self._threads) < self._workers:
                t = threading.Thread(target=self._work, name=f"{WORKER_PREFIX}_{len(self._threads)}", daemon=True)
                self._threads.append(t)
                self._idle += 1  # counted idle until it takes its first call
                t.start()

    def _work(self) -> None:
        me = threading.current_thread()
        while True:
            item = self._queue.get()
            with self._lock:
                self._idle -= 1
                self._progress.notify_all()
            if item is None:
                return
            label, fn, args, kwargs = item
            self.running[me] = label
            try:
                self._run(label, fn, args, kwargs)
            finally:
                self.running.pop(me, None)
                with self._lock:
                    self._idle += 1
                    self._progress.notify_all()

    def close(self, deadline: float) -> tuple[int, list[str]]:
        """Stop accepting calls; wait (until ``deadline``, a monotonic time) for the queue to
        drain and the workers to finish, except the calling worker itself."""
        with self._lock:
            self._closed = True
            threads = list(self._threads)
        me = threading.current_thread()
        others = [t for t in threads if t is not me]
        with self._progress:  # a worker's get() is followed by a notify under this lock
            while self._queue.qsize():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._progress.wait(remaining)
        dropped = 0
        while True:  # bounded: the pool is closed, nothing is added any more
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if item is not None:
                dropped += 1
        for _ in threads:
            self._queue.put(None)  # the queue is empty now and closed: never blocks
        for t in others:
            t.join(max(0.0, deadline - time.monotonic()))
        stuck = [self.running.get(t, "?") for t in others if t.is_alive()]
        return dropped, stuck

    def join(self, timeout: float) -> None:
        """Wait (bounded) for every worker thread to end (after ``close``)."""
        deadline = time.monotonic() + timeout
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(max(0.0, deadline - time.monotonic()))
