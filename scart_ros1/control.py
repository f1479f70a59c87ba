"""The node's control thread: blocking control-plane work, and its registrations kept true.

* :class:`Control` owns one thread running jobs (now or after a delay) and, between
  them, a periodic *tick*. Blocking work lives here, never on the io thread: master
  calls, ``requestTopic`` to publishers, connecting to them.
* :class:`Registrar` is the tick: it keeps what the node wants registered with the
  master (publishers, subscribers, services, parameter subscriptions) registered. While the master is down it
  waits, retrying with backoff (0.1 s doubling to 2 s), and logs that it waits — once,
  then every 30 s. When the master answers again, or polls show that it forgot the node
  (a new rosmaster), it registers everything again.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from ._threads import OwnedThread
from .io import Counters
from .master import Master, MasterError, MasterUnreachable, XmlRpcValue

__all__ = ["Control", "Registrar"]

log = logging.getLogger(__name__)

BACKOFF_FIRST, BACKOFF_MAX = 0.1, 2.0
WAIT_LOG_EVERY = 30.0  #: while the master is down, say so again this often (s)


class Control:
    """One thread: jobs in due order, and ``tick()`` when due (it returns the next delay)."""

    def __init__(self, name: str, tick: Callable[[], float]) -> None:
        self._tick = tick
        self._cond = threading.Condition()
        self._jobs: list[tuple[float, int, Callable[..., object], tuple]] = []
        self._seq = itertools.count()
        self._next_tick = 0.0
        self._stopping = False
        self._thread = OwnedThread(lambda _stopping: self._run(), f"ros1-control {name}")

    def start(self) -> None:
        self._thread.start()

    def here(self) -> bool:
        return self._thread.in_thread()

    def submit(self, fn: Callable[..., object], *args: object, delay: float = 0.0) -> None:
        """Run ``fn(*args)`` on the control thread after ``delay`` s (thread-safe)."""
        with self._cond:
            heapq.heappush(self._jobs, (time.monotonic() + delay, next(self._seq), fn, args))
            self._cond.notify()

    def tick_now(self) -> None:
        """Run the tick as soon as the thread is free (thread-safe)."""
        with self._cond:
            self._next_tick = 0.0
            self._cond.notify()

    def close(self, timeout: float = 5.0) -> None:
        """Stop after the current job (idempotent; from the thread itself, only signals)."""
        with self._cond:
            self._stopping = True
            self._cond.notify()
        self._thread.join(timeout)  # (not from the thread itself)

    @property
    def stopping(self) -> bool:
        return self._stopping

    def _run(self) -> None:
        while True:
            job = self._next()
            if job is None:
                return
            fn, args = job
            try:
                fn(*args)
            except Exception:
                log.exception("ROS 1 control: %s failed", getattr(fn, "__qualname__", fn))

    def _next(self) -> tuple[Callable[..., object], tuple] | None:
        with self._cond:
            while not self._stopping:
                now = time.monotonic()
                if self._jobs and self._jobs[0][0] <= now:
                    _, _, fn, args = heapq.heappop(self._jobs)
                    return fn, args
                if self._next_tick <= now:
                    self._next_tick = float("inf")
                    return self._run_tick, ()
                due = min(self._next_tick, self._jobs[0][0] if self._jobs else float("inf"))
                self._cond.wait(None if due == float("inf") else due - now)
            return None

    def _run_tick(self) -> None:
        delay = self._tick()
        with self._cond:
            self._next_tick = min(self._next_tick, time.monotonic() + delay)


Key = tuple[str, str]  # ("pub" | "sub" | "srv" | "param", name)


class Registrar:
    """What the node wants registered, kept registered (runs on :class:`Control`).

    ``on_publishers(topic, uris)`` receives each ``registerSubscriber`` answer,
    ``on_param(key, value)`` each ``subscribeParam`` answer (kind ``param``).
    """

    def __init__(self, master: Master, caller_api: str, poll: float, counters: Counters,
                 on_publishers: Callable[[str, list[str]], None],
                 on_param: Callable[[str, XmlRpcValue], None] | None = None) -> None:
        self.master, self.caller_api, self.poll = master, caller_api, poll
        self.counters, self.on_publishers, self.on_param = counters, on_publishers, on_param
        self._cond = threading.Condition()
        self._desired: dict[Key, tuple[str, ...]] = {}
        self._registered: set[Key] = set()
        self._failed: set[Key] = set()
        self._stale: dict[Key, tuple[str, ...]] = {}
        self._down_since: float | None = None
        self._last_wait_log = 0.0
        self._backoff = BACKOFF_FIRST
        self._last_check = 0.0

    # -- any thread -----------------------------------------------------------------------
    def want(self, key: Key, args: tuple[str, ...]) -> None:
        with self._cond:
            self._desired[key] = args
            self._stale.pop(key, None)
            self._failed.discard(key)

    def drop(self, key: Key) -> None:
        with self._cond:
            args = self._desired.pop(key, None)
            if key in self._registered and args is not None:
                self._stale[key] = args
            self._registered.discard(key)
            self._failed.discard(key)

    def wait_registered(self, timeout: float) -> bool:
        """Block until everything wanted is registered (True) or ``timeout`` s pass (False)."""
        with self._cond:
            return self._cond.wait_for(lambda: self._complete(), timeout)

    def is_registered(self, key: Key) -> bool:
        with self._cond:
            return key in self._registered

    def _complete(self) -> bool:
        return set(self._desired) <= self._registered | self._failed

    @property
    def master_reachable(self) -> bool:
        return self._down_since is None

    def unregister_all(self, timeout: float) -> None:
        """Unregister everything once, without waiting for a master that is down (closing)."""
        self._unregister_once(timeout, keep=False)

    def reset(self, timeout: float) -> None:
        """Unregister everything once (not waiting for a master that is down), keeping what
        is wanted: the next :meth:`tick` registers it all again (a restart)."""
        self._unregister_once(timeout, keep=True)

    def _unregister_once(self, timeout: float, keep: bool) -> None:
        with self._cond:
            todo = {k: self._desired[k] for k in self._registered if k in self._desired} | self._stale
            if not keep:
                self._desired.clear()
            self._registered.clear()
            self._failed.clear()
            self._stale.clear()
        quick = Master(self.master.uri, self.master.caller_id, timeout)
        for key, args in todo.items():
            try:
                self._unregister(quick, key, args)
            except MasterUnreachable:
                return
            except MasterError:
                continue

    # -- the control thread ---------------------------------------------------------------
    def tick(self) -> float:
        """Reconcile with the master; returns when to tick again (s)."""
        try:
            if self._down_since is not None:
                self.master.get_pid()  # raises while the master is still down
                self._back(time.monotonic() - self._down_since)
            self._reconcile()
            if self._registered and time.monotonic() - self._last_check >= self.poll:
                self._check_remembered()
        except MasterUnreachable as exc:
            return self._waiting(exc)
        return self.poll

    def _reconcile(self) -> None:
        with self._cond:
            todo = [(k, a) for k, a in self._desired.items() if k not in self._registered and k not in self._failed]
            stale = list(self._stale.items())
        for key, args in todo:
            self._register(key, args)
        for key, args in stale:
            try:
                self._unregister(self.master, key, args)
            except MasterError as exc:
                if isinstance(exc, MasterUnreachable):
                    raise
            with self._cond:
                self._stale.pop(key, None)

    def _register(self, key: Key, args: tuple[str, ...]) -> None:
        kind, name = key
        try:
            if kind == "pub":
                self.master.register_publisher(name, args[0], self.caller_api)
            elif kind == "sub":
                self.on_publishers(name, self.master.register_subscriber(name, args[0], self.caller_api))
            elif kind == "param":
                value = self.master.subscribe_param(name, self.caller_api)
                if self.on_param is not None:
                    self.on_param(name, value)
            else:
                self.master.register_service(name, args[0], self.caller_api)
        except MasterUnreachable:
            raise
        except MasterError as exc:
            log.error("ROS 1: the master refused to register %s %s: %s", kind, name, exc)
            with self._cond:
                self._failed.add(key)
                self._cond.notify_all()
            return
        with self._cond:
            if self._desired.get(key) == args:
                self._registered.add(key)
            self._cond.notify_all()

    def _unregister(self, master: Master, key: Key, args: tuple[str, ...]) -> None:
        kind, name = key
        if kind == "pub":
            master.unregister_publisher(name, self.caller_api)
        elif kind == "sub":
            master.unregister_subscriber(name, self.caller_api)
        elif kind == "param":
            master.unsubscribe_param(name, self.caller_api)
        else:
            master.unregister_service(name, args[0])

    def _check_remembered(self) -> None:
        """Poll the master for this node: a new master has forgotten it, so register again."""
        self._last_check = time.monotonic()
        try:
            uri = self.master.lookup_node(self.master.caller_id)
        except MasterUnreachable:
            raise
        except MasterError:
            uri = None
        if uri == self.caller_api:
            return
        if uri is not None:
            log.warning("ROS 1: node name %s is now held by %s; not registering again", self.master.caller_id, uri)
            return
        log.warning("ROS master %s forgot node %s (restarted?): registering again", self.master.uri, self.master.caller_id)
        self.counters["master_reregistrations"] += 1
        self._forget()
        self._reconcile()

    def _forget(self) -> None:
        with self._cond:
            self._registered.clear()
            self._failed.clear()

    def _waiting(self, exc: MasterUnreachable) -> float:
        now = time.monotonic()
        self.counters["master_retries"] += 1
        if self._down_since is None:
            self._down_since, self._last_wait_log = now, now
            log.warning("%s: node %s waits for it, retrying", exc, self.master.caller_id)
        elif now - self._last_wait_log >= WAIT_LOG_EVERY:
            self._last_wait_log = now
            log.warning("still waiting for the ROS master %s (%.0f s)", self.master.uri, now - self._down_since)
        self._forget()  # whichever master answers next may be a new one
        delay, self._backoff = self._backoff, min(self._backoff * 2, BACKOFF_MAX)
        return delay

    def _back(self, downtime: float) -> None:
        """The master answers after being down: count it; the caller registers everything."""
        log.warning("ROS master %s answers again after %.1f s: registering node %s again",
                    self.master.uri, downtime, self.master.caller_id)
        self.counters["master_reregistrations"] += 1
        self._down_since, self._backoff = None, BACKOFF_FIRST
        self._last_check = time.monotonic()
