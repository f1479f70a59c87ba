"""Time as tasks see it: one clock abstraction for every task of a deployer.

A :class:`Clock` says what time it is (:meth:`Clock.now_ns`, ROS time: nanoseconds since
the epoch), what a periodic activity counts its deadlines in (:meth:`Clock.monotonic`,
seconds) and how it waits for the next one (:meth:`Clock.wait`), and what stamp goes on a
sample written at a given wall time (:meth:`Clock.stamp`, for the messages scart stamps).

* :data:`WALL` (a :class:`WallClock`) is the default: the system's clocks, unchanged
  (``time.monotonic`` for periods, ``time.time_ns`` for stamps).
* :class:`SimClock` follows a simulation's time, set from outside (ROS's ``/clock`` when
  ``use_sim_time`` is set): periods then pass in simulated seconds, so a bag played at
  twice its speed runs periodic tasks twice as fast, and a paused one pauses them. Before
  its first time arrives, it is 0 and no periodic cycle runs (as in ROS).

A task reads its deployer's clock (``task.clock``; :meth:`Deployer.use_clock` changes it
for every task it holds, running or not); a periodic activity follows the change at its
next wake-up.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable

from dataflow.threads import Wake

__all__ = ["Clock", "SimClock", "WALL", "WallClock"]

#: How long a periodic activity waits on a simulated clock before it looks again whether
#: its task still follows that clock (s, wall time).
RECHECK = 0.5


class Clock:
    """What time it is for the tasks that read it (see the module docstring). Thread-safe."""

    #: True when the time is a simulation's (not the system's).
    simulated = False

    def now_ns(self) -> int:
        """ROS time now: nanoseconds since the epoch (or the simulation's)."""
        return time.time_ns()

    def stamp(self, wall_ns: int) -> int:
        """The stamp of something written at the wall time ``wall_ns`` (a sample)."""
        return wall_ns

    def monotonic(self) -> float:
        """Seconds that only go forward, what periods are counted in."""
        return time.monotonic()

    def wait(self, wake: Wake, deadline: float) -> None:
        """Block until :meth:`monotonic` reaches ``deadline``, or ``wake`` is set (the
        waiter's own thread; it may return early: the caller looks again)."""
        wake.wait(deadline - time.monotonic())


class WallClock(Clock):
    """The system's clocks (the default). Stateless: one instance serves everyone."""


WALL: Clock = WallClock()


class SimClock(Clock):
    """A simulation's time, set by :meth:`set` (see the module docstring). Thread-safe."""

    simulated = True

    def __init__(self) -> None:
        self._t_ns = 0
        self._lock = threading.Lock()
        self._waiting: set[Wake] = set()

    @classmethod
    def among(cls, clocks: Iterable[Clock]) -> SimClock:
        """The first simulated clock of ``clocks``, else a new one: what a source of
        simulated time feeds when another (a process's ROS 1 and ROS 2 nodes, each
        following its ``/clock``) put its tasks on one already, so that both feed one clock
        and never take the tasks from each other."""
        return next((c for c in clocks if isinstance(c, SimClock)), None) or cls()

    def set(self, t_ns: int) -> None:
        """The simulation's time is now ``t_ns``; wakes every periodic activity following it."""
        self._t_ns = t_ns
        with self._lock:
            waiting = list(self._waiting)
        for wake in waiting:
            wake.set()

    def now_ns(self) -> int:
        return self._t_ns

    def stamp(self, wall_ns: int) -> int:
        return self._t_ns

    def monotonic(self) -> float:
        return self._t_ns / 1e9

    def wait(self, wake: Wake, deadline: float) -> None:
        with self._lock:
            self._waiting.add(wake)
        try:
            if self._t_ns / 1e9 < deadline:  # (looked at once registered: no set() is missed)
                wake.wait(RECHECK)
        finally:
            with self._lock:
                self._waiting.discard(wake)

    def __repr__(self) -> str:
        return f"SimClock({self._t_ns / 1e9:.3f} s)"
