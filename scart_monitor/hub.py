"""The monitor's shared state: newest status, measured rate, driver info and the event log.

`StatusHub` is the meeting point between the host's threads (which *publish*) and the
HTTP handler threads (which *wait and read*). Publishing never waits for a reader: the
hub keeps only the latest status (older ones are coalesced away), a bounded event log and
counters, all under one short lock, and wakes waiting readers through a condition.

What the page shows is computed here, not in the browser: sample age (from receipt time,
on this host's monotonic clock), measured rate (from the samples' own timestamps over a
1 s window) and error flags decoded to names.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import NotRequired, TypedDict

RATE_WINDOW_S = 1.0
"""Measured rate = samples whose timestamp lies in the last RATE_WINDOW_S of sample time."""

STALE_AFTER_S = 1.0
"""No sample for this long: the measured rate reads 0 (the stream stopped)."""

MAX_EVENTS = 200
HISTORY_S = 60.0  #: how much recent history a page opened now gets at once
HISTORY_EVERY_S = 0.04  #: at most one kept status per 40 ms (the page's own update rate)
"""Event log length kept by the server (older entries are dropped)."""

COALESCED_EVENTS = frozenset({"refresh"})
"""Events too frequent to log one by one: counted, with the time of the last one."""


def _sample_time(sample: dict[str, object], fallback: float) -> float:
    """The sample's own timestamp in seconds if it has a finite number, else ``fallback``."""
    stamp = sample.get("timestamp")
    if isinstance(stamp, (int, float)) and not isinstance(stamp, bool) and math.isfinite(stamp):
        return float(stamp)
    return fallback


def flag_names(word: int, names: dict[int, str]) -> list[str]:
    """Names of the bits set in ``word`` (bit index → name; unknown bits read ``bitN``)."""
    if not isinstance(word, int) or word <= 0:
        return []
    return [names.get(bit, f"bit{bit}") for bit in range(word.bit_length()) if word >> bit & 1]


class Driver(TypedDict):
    """The driver's state as the page shows it."""

    state: str
    period: float | None
    connected: bool


class Event(TypedDict):
    """One event of the log (``busy``, ``idle``, ``error``, ...)."""

    id: int
    name: str
    detail: str
    time: float


class Coalesced(TypedDict):
    """An event counted, not logged one by one: how often, when last, its detail (and, in a
    snapshot, how long ago)."""

    count: int
    last: float
    detail: str
    age: NotRequired[float]


class Snapshot(TypedDict):
    """The page's view (:meth:`StatusHub.snapshot`); ``status`` a JSON text, put in last."""

    version: int
    age: float | None
    rate: float
    samples: int
    driver: Driver
    summary: dict[str, object] | None
    gripper: dict[str, object] | None
    flags: list[list[str]]
    events: list[Event]
    coalesced: dict[str, Coalesced]
    status: NotRequired[str]


class StatusHub:
    """Latest-value store with a condition; thread-safe; no method blocks except `wait`.

    `version` counts every change (status, event, driver info); readers remember the
    version they sent and `wait` for a newer one. `close` wakes every waiter for good.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock  #: monotonic seconds (a test may give its own)
        self._cond = threading.Condition(threading.Lock())
        self._version = 0
        self._closed = False
        self._status: dict[str, object] | None = None
        self._summary: dict[str, object] | None = None  # the demo bridge's newest ArmSummary
        self._gripper: dict[str, object] | None = None  # the gripper in base_link, from the frame tree
        self._status_json = "null"
        self._status_json_of = 0  # the sample count that _status_json encodes
        self._received_at: float | None = None
        self._stamps: deque[float] = deque()
        self._samples = 0
        self._events: deque[Event] = deque(maxlen=MAX_EVENTS)
        self._event_id = 0
        self._coalesced: dict[str, Coalesced] = {}
        self._driver: Driver = {"state": "unknown", "period": None, "connected": False}
        self._flag_names: dict[int, str] = {}
        self._flag_words: list[int] | None = None  # each joint's error word in the last sample
        self._history: deque[tuple[float, dict[str, object]]] = deque()  # (arrival, status), last HISTORY_S

    # -- publishing side (host threads) -------------------------------------------------

    def publish_status(self, sample: dict[str, object]) -> None:
        """Store ``sample`` as the newest status and wake readers. Never waits for readers.

        The hub keeps a reference: the caller must not mutate ``sample`` afterwards.
        """
        now = self._clock()
        with self._cond:
            self._status = sample
            self._received_at = now
            self._samples += 1
            stamp = _sample_time(sample, now)
            if self._stamps and stamp < self._stamps[-1]:
                self._stamps.clear()  # the source restarted or its clock went back
            self._stamps.append(stamp)
            while self._stamps and self._stamps[0] <= stamp - RATE_WINDOW_S:
                self._stamps.popleft()
            self._flag_events(sample)
            if not self._history or now - self._history[-1][0] >= HISTORY_EVERY_S * 0.999:  # clock rounding
                self._history.append((now, sample))
            while self._history and self._history[0][0] < now - HISTORY_S:
                self._history.popleft()
            self._bump()

    def history(self) -> list[dict[str, object]]:
        """The statuses of the last :data:`HISTORY_S` s, oldest first, one per
        :data:`HISTORY_EVERY_S` at most (what a page opened now draws before going live)."""
        with self._cond:
            return [sample for _, sample in self._history]

    def publish_event(self, name: str, detail: str = "") -> None:
        """Log an event (``refresh`` is only counted). Thread-safe, never waits for readers."""
        with self._cond:
            self._add_event(str(name), str(detail))
            self._bump()

    def set_driver_info(self, state: str, period: float | None, connected: bool) -> None:
        """Record the driver's state, accepted period and reachability; logs connection changes."""
        with self._cond:
            before = self._driver
            self._driver = {"state": str(state), "period": period, "connected": bool(connected)}
            if before["connected"] != bool(connected):
                self._add_event("connected" if connected else "disconnected", str(state))
            elif connected and before["state"] != str(state) and before["state"] != "unknown":
                self._add_event("state", f"{before['state']} → {state}")
            if connected and before["connected"] and period is not None and before["period"] is not None \
                    and period != before["period"]:
                self._add_event("period", f"{before['period'] * 1000:g} ms → {period * 1000:g} ms")
            self._bump()

    def set_summary(self, summary: dict[str, object]) -> None:
        """Keep the newest bridge summary; it goes out with the next status (no wake-up of
        its own: it changes at the status's rate)."""
        with self._cond:
            self._summary = dict(summary)

    def set_gripper(self, gripper: dict[str, object]) -> None:
        """Keep where the gripper is in ``base_link`` (``x``, ``y``, ``z`` [m], ``stamp`` [s]);
        it goes out with the next status, as the summary does."""
        with self._cond:
            self._gripper = dict(gripper)

    @property
    def error_flag_names(self) -> dict[int, str]:
        """A copy of the bit index → name table used to decode error flag words."""
        with self._cond:
            return dict(self._flag_names)

    @error_flag_names.setter
    def error_flag_names(self, names: dict[int, str]) -> None:
        table = {int(bit): str(name) for bit, name in dict(names).items()}
        with self._cond:
            self._flag_names = table
            self._bump()

    def close(self) -> None:
        """Wake every waiter; later `wait` calls return at once. Idempotent."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    # -- reading side (HTTP handler threads) --------------------------------------------

    @property
    def closed(self) -> bool:
        """True once `close` was called."""
        with self._cond:
            return self._closed

    def wait(self, seen_version: int, timeout: float) -> int:
        """Block up to ``timeout`` s until the version differs from ``seen_version`` or the
        hub is closed; returns the current version (unchanged on timeout)."""
        with self._cond:
            self._cond.wait_for(lambda: self._closed or self._version != seen_version, timeout)
            return self._version

    def snapshot(self, after_event: int = 0) -> tuple[Snapshot, int]:
        """The page's view now, with events whose id is greater than ``after_event``.

        Returns ``(message, last_event_id)``; the status is embedded pre-serialised as
        ``message["status"]`` (a JSON string), encoded once per sample and outside the
        lock, so publishers never wait for JSON encoding.
        """
        now = self._clock()
        with self._cond:
            status, samples = self._status, self._samples
            cached = self._status_json if self._status_json_of == samples else None
            age = None if self._received_at is None else now - self._received_at
            events = [e for e in self._events if e["id"] > after_event]
            message: Snapshot = {
                "version": self._version,
                "age": age,
                "rate": self._rate(age),
                "samples": self._samples,
                "driver": self._driver.copy(),
                "summary": None if self._summary is None else dict(self._summary),
                "gripper": None if self._gripper is None else dict(self._gripper),
                "flags": self._decoded_flags(status),
                "events": events,
                "coalesced": {k: {**v, "age": time.time() - v["last"]} for k, v in self._coalesced.items()},
            }
            last_event = self._event_id
        if cached is None:
            cached = json.dumps(status, default=str)
            with self._cond:
                if self._samples == samples:
                    self._status_json, self._status_json_of = cached, samples
        message["status"] = cached
        return message, last_event

    # -- internals (call with the lock held) ------------------------------------------

    def _flag_events(self, sample: dict[str, object]) -> None:
        """An ``error`` event for each error flag that a joint raised or cleared since the last sample."""
        joints = sample.get("joints") if isinstance(sample, dict) else None
        words = [int(j.get("error_flags", 0)) if isinstance(j, dict) else 0 for j in joints] \
            if isinstance(joints, list) else []
        previous, self._flag_words = self._flag_words, words
        if previous is None or len(previous) != len(words):
            return
        for j, (old, new) in enumerate(zip(previous, words), start=1):
            if old == new:
                continue
            raised = flag_names(new & ~old, self._flag_names)
            cleared = flag_names(old & ~new, self._flag_names)
            parts = ([f"{', '.join(raised)} set"] if raised else []) + ([f"{', '.join(cleared)} cleared"] if cleared else [])
            self._add_event("error", f"joint {j}: {'; '.join(parts)}")

    def _bump(self) -> None:
        self._version += 1
        self._cond.notify_all()

    def _add_event(self, name: str, detail: str) -> None:
        wall = time.time()
        if name in COALESCED_EVENTS:
            entry = self._coalesced.setdefault(name, {"count": 0, "last": wall, "detail": ""})
            entry["count"] += 1
            entry["last"] = wall
            entry["detail"] = detail
            return
        self._event_id += 1
        self._events.append({"id": self._event_id, "name": name, "detail": detail, "time": wall})

    def _rate(self, age: float | None) -> float:
        if age is None or age > STALE_AFTER_S or len(self._stamps) < 2:
            return 0.0
        span = self._stamps[-1] - self._stamps[0]
        return (len(self._stamps) - 1) / span if span > 0 else 0.0

    def _decoded_flags(self, status: dict[str, object] | None) -> list[list[str]]:
        joints = status.get("joints") if isinstance(status, dict) else None
        if not isinstance(joints, list):
            return []
        return [
            flag_names(j.get("error_flags", 0), self._flag_names) if isinstance(j, dict) else []
            for j in joints
        ]
