"""What every SCA-side youBot driver proxy shares, however it reaches the data-flow driver.

:class:`DriverProxyCore` keeps the newest ``YouBotStatus`` sample, serves
``RetrievingStatus`` from it, runs ``SendingCommands.set_joints_positions`` (``busy``,
write, wait until reached, ``idle``) and delivers the ``Notifying`` callbacks to the
registered clients. Subclasses say how samples arrive (they call :meth:`_on_status`)
and how commands leave (:meth:`_write_commands`):

* ``sca_driver.SCAYouBotDriver`` — the paper's hand-written proxy on the client library;
* ``bound_driver.BoundYouBotDriver`` — the same services on ``binding.dataflow``.

Callbacks: one *notifier* thread per registered client (a :class:`Listener`) delivers its
``notify`` calls in order: ``busy``/``idle`` as queued, ``refresh`` coalesced (at most one
pending per client), so a slow client never slows the sample source or other clients. A
client registers by calling any operation of ``RetrievingStatus``/``SendingCommands``
through a wired reference: ``self.client`` is that caller's callback proxy.
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
import time
from collections import deque
from typing import Any

import scart
from interfaces import Notifying
from youbot_model import JOINT_LIMITS, N_JOINTS, YouBotStatus

__all__ = ["DriverProxyCore", "Listener", "MAX_LISTENERS"]

log = logging.getLogger("youbot.proxy")

MAX_LISTENERS = 16
"""Callback targets kept at most (oldest forgotten first): bounded even if a binding
hands out a fresh callback object per call."""


class Listener:
    """One client's notifier thread: ordered events plus one coalesced ``refresh``.

    ``push``/``refresh`` never block; ``stop`` signals and joins (idempotent)."""

    def __init__(self, target: Any, index: int) -> None:
        self.target = target
        self._cond = threading.Condition()
        self._events: deque[tuple[str, str]] = deque(maxlen=256)
        self._refresh = False
        self._stopped = False
        self._thread = threading.Thread(target=self._run, name=f"scart-youbot-notify-{index}", daemon=True)
        self._thread.start()

    def push(self, event: str, detail: str = "") -> None:
        """Queue an ordered event (``busy``/``idle``/...)."""
        with self._cond:
            self._events.append((event, detail))
            self._cond.notify()

    def refresh(self) -> None:
        """Mark a refresh pending (coalesces with one already pending)."""
        with self._cond:
            if not self._refresh:
                self._refresh = True
                self._cond.notify()

    def _next(self) -> tuple[str, str] | None:
        with self._cond:
            if not self._stopped and not self._events and not self._refresh:
                self._cond.wait(1.0)
            if self._stopped:
                return None
            if self._events:
                return self._events.popleft()
            if self._refresh:
                self._refresh = False
                return ("refresh", "")
            return ("", "")

    def _run(self) -> None:
        for _ in range(1_000_000_000):  # bounded; ends when stopped
            item = self._next()
            if item is None:
                return
            if not item[0]:
                continue
            try:
                self.target.notify(*item)
            except Exception:  # noqa: BLE001 - a client bug must not end its notifier
                log.exception("notify(%r) to a client failed", item[0])

    def stop(self) -> None:
        """Signal, then join (≤ 5 s); a notifier stopping itself does not join."""
        with self._cond:
            self._stopped = True
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)


class DriverProxyCore:
    """Mixin of the youBot proxies (see the module docstring). Not a component by itself.

    Subclasses call :meth:`_core_open` first in their ``@init`` and :meth:`_core_close`
    last in their ``@destroy``; they implement :meth:`_write_commands` and
    :meth:`_driver_info`."""

    component: str = scart.prop(default="youBotDriver")
    tolerance: float = scart.prop(default=0.02)
    command_timeout: float = scart.prop(default=10.0)
    client: Notifying = scart.callback()

    # --- for subclasses ----------------------------------------------------------------

    def _core_open(self) -> None:
        self._lock = threading.Lock()
        self._sample_cond = threading.Condition(self._lock)
        self._stop = threading.Event()
        self._sample: YouBotStatus | None = None
        self._sample_dict: dict[str, Any] | None = None
        self._received_at = 0.0
        self._arrivals: deque[float] = deque(maxlen=20_000)
        self.received = 0
        self._listeners: dict[Any, Listener] = {}
        self._listener_count = 0
        self._command_id = 0
        self._link_down = False

    def _core_link(self, up: bool) -> None:
        """The connection to the driver changed: a command waiting for its target ends at
        once with ``disconnected`` when the link goes down."""
        with self._sample_cond:
            self._link_down = not up
            self._sample_cond.notify_all()

    def _core_close(self) -> None:
        """Signal waiters, stop and join every notifier (idempotent)."""
        self._stop.set()
        with self._sample_cond:
            self._sample_cond.notify_all()
            listeners = list(self._listeners.values())
            self._listeners.clear()
        for listener in listeners:
            listener.stop()

    def _write_commands(self, values: list[float]) -> None:
        """Send the set-points to the driver; raise with a message when impossible."""
        raise NotImplementedError

    def _driver_info(self) -> dict[str, Any]:
        """{"state", "period", "period_status", "connected"} as last known (never blocks)."""
        raise NotImplementedError

    def _on_status(self, value: Any) -> None:
        """A new ``jointStatus`` sample: store it, wake waiters, mark a refresh per client.
        Never blocks (called on the subscription's thread)."""
        if not isinstance(value, YouBotStatus):
            try:
                value = YouBotStatus.model_validate(dict(value))
            except Exception:  # noqa: BLE001 - an unexpected sample is skipped
                log.debug("skipping a sample of unexpected type %s", type(value).__name__)
                return
        now = time.monotonic()
        with self._sample_cond:
            self._sample = value
            self._sample_dict = None
            self._received_at = now
            self._arrivals.append(now)
            self.received += 1
            self._sample_cond.notify_all()
            listeners = list(self._listeners.values())
        for listener in listeners:
            listener.refresh()

    def _broadcast(self, event: str, detail: str) -> None:
        """Queue ``event`` to every registered client."""
        with self._lock:
            listeners = list(self._listeners.values())
        for listener in listeners:
            listener.push(event, detail)

    # --- RetrievingStatus --------------------------------------------------------------

    def get_joints_positions(self) -> list[float]:
        """Positions of the newest sample (empty before any); registers the caller."""
        self._register()
        with self._lock:
            sample = self._sample
        return [j.position for j in sample.joints] if sample is not None else []

    def get_joints_status(self) -> dict | None:
        """The newest sample as a dict (None before any); registers the caller."""
        self._register()
        with self._lock:
            if self._sample_dict is None and self._sample is not None:
                self._sample_dict = self._sample.model_dump()
            return self._sample_dict

    def get_driver_info(self) -> dict:
        """State, period, period status, measured rate, connection, sample age (never blocks)."""
        self._register()
        now = time.monotonic()
        info = dict(self._driver_info())
        with self._lock:
            cutoff = now - 1.0
            # arrivals are appended in time order: count back until the first older one
            rate = sum(1 for _ in itertools.takewhile(lambda t: t >= cutoff, reversed(self._arrivals)))
            info["sample_age"] = (now - self._received_at) if self._sample is not None else None
            info["sequence"] = self._sample.sequence if self._sample is not None else None
        info["measured_rate"] = float(rate)
        info["received"] = self.received
        info["component"] = self.component
        return info

    # --- SendingCommands ---------------------------------------------------------------

    def set_joints_positions(self, values: list[float]) -> None:
        """One-way (runs on the runtime's worker pool): ``busy``, write ``commands``, wait
        (≤ ``command_timeout``) until within ``tolerance`` of the clipped target, ``idle``.

        ``idle`` details: ``""`` reached, ``"timeout"``, ``"superseded"`` (a newer command
        arrived), ``"rejected: ..."`` (malformed values or not connected), ``"disconnected"`` (the link to
        the driver went down while waiting), ``"stopped"`` (the proxy is being destroyed)."""
        listener = self._register()
        emit = listener.push if listener is not None else (lambda event, detail="": None)
        with self._lock:
            self._command_id += 1
            my_id = self._command_id
        emit("busy", describe(values))
        target, problem = clip_target(values)
        if problem is None:
            try:
                self._write_commands([float(v) for v in values])  # unclipped: the driver flags a clip
            except Exception as exc:  # noqa: BLE001 - reported to the caller, not raised into the pool
                problem = str(exc) or type(exc).__name__
        if problem is not None:
            log.warning("command %s rejected: %s", describe(values), problem)
            emit("idle", f"rejected: {problem}")
            return
        emit("idle", self._wait_reached(target, my_id))

    def _wait_reached(self, target: list[float], my_id: int) -> str:
        deadline = time.monotonic() + max(0.0, self.command_timeout)
        with self._sample_cond:
            for _ in range(10_000_000):  # bounded by the deadline; one pass per sample
                if self._stop.is_set():
                    return "stopped"
                if self._link_down:
                    return "disconnected"
                if self._command_id != my_id:
                    return "superseded"
                if self._sample is not None and within(self._sample, target, self.tolerance):
                    return ""
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return "timeout"
                self._sample_cond.wait(min(remaining, 0.5))
        return "timeout"

    def _register(self) -> Listener | None:
        """The caller's listener (created on first call); None for a call without callback."""
        try:
            target = self.client
        except scart.NoCallbackError:
            return None
        try:  # equal callback targets are one listener (a binding may define equality)
            key: Any = target
            hash(key)
        except TypeError:
            key = id(target)
        with self._lock:
            listener = self._listeners.get(key)
            if listener is not None:
                return listener
            if self._stop.is_set():
                return None
            self._listener_count += 1
            listener = Listener(target, self._listener_count)
            self._listeners[key] = listener
            evicted = None
            if len(self._listeners) > MAX_LISTENERS:
                evicted = self._listeners.pop(next(iter(self._listeners)))
        if evicted is not None:
            evicted.stop()
        return listener


def describe(values: Any) -> str:
    """``[0.100, 0.200, ...]`` (or the repr of something that is not numbers)."""
    try:
        return "[" + ", ".join(f"{float(v):.3f}" for v in values) + "]"
    except (TypeError, ValueError):
        return repr(values)


def clip_target(values: Any) -> tuple[list[float], str | None]:
    """The target the driver will really use (clipped to the joint limits), or a problem."""
    try:
        floats = [float(v) for v in values]
    except (TypeError, ValueError):
        return [], f"expected {N_JOINTS} numbers, got {values!r}"
    if len(floats) != N_JOINTS or not all(math.isfinite(v) for v in floats):
        return [], f"expected {N_JOINTS} finite numbers, got {len(floats)}"
    return [min(max(v, lo), hi) for v, (lo, hi) in zip(floats, JOINT_LIMITS)], None


def within(sample: YouBotStatus, target: list[float], tolerance: float) -> bool:
    """True when every joint of ``sample`` is within ``tolerance`` of ``target``."""
    joints = sample.joints
    return len(joints) == len(target) and all(abs(j.position - t) <= tolerance for j, t in zip(joints, target))
