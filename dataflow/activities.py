"""Activities: what runs a task's update cycle, and in which thread.

* :class:`EventActivity` (the default, RTT's non-periodic ``Activity``): one daemon
  thread while the task runs; a cycle runs when triggered — by ``task.trigger()``, by
  data arriving on an event port (``InputPort(T, event=True)``), and once right after
  ``start()`` (as RTT's ``TaskCore::start`` triggers). Triggers arriving during a cycle
  coalesce into one more cycle.
* :class:`PeriodicActivity` (``period`` seconds): one daemon thread while the task runs,
  cycles at absolute deadlines ``t0 + k*period`` (no drift); a cycle that ends after its
  next deadline counts one overrun and the missed deadlines are skipped (no burst of
  catch-up cycles). ``period`` is writable while running (takes effect from the cycle
  in progress). ``trigger()`` is refused (False), as in RTT. Periods pass on the task's
  clock (``task.clock``, :mod:`dataflow.clock`): the system's, or a simulation's.
* :class:`SlaveActivity`: no thread; its owner calls ``step()`` (or ``task.update()``);
  deterministic tests use it.
* :class:`SequentialActivity` (RTT's ``SequentialActivity``): no thread of its own; a
  cycle runs in the thread that triggers it — for an event port, the thread that stored
  the sample — with no wake-up, so the task sees a sample as soon as a ROS callback
  would. Its ``update_hook`` then holds that thread (ipc's io thread, a writer's): keep
  it as short as a callback.

Threads are created in ``start()``, never in ``__init__``; they are daemon threads and
end when the task stops running. ``stop()`` signals (sets the stop flag and wakes the
thread), then joins with a timeout — it never hangs, is idempotent, and called from the
activity's own thread (e.g. from ``update_hook``) it only signals.

Operations declared ``own_thread=True`` are queued to the activity's thread and run
between cycles; with no live thread (stopped task, slave activity, or a call made from
that very thread) they run in the caller's thread.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from typing import TYPE_CHECKING, Any, TypeVar

from dataflow.clock import WALL, Clock
from dataflow.threads import Wake

if TYPE_CHECKING:
    from .task import TaskContext

R = TypeVar("R")

__all__ = ["Activity", "PeriodicActivity", "SequentialActivity", "SlaveActivity", "EventActivity",
           "fit_switch_interval", "freeze_heap"]

log = logging.getLogger(__name__)
DEFAULT_JOIN_TIMEOUT = 2.0


class Activity:
    """Base of activities. ``cycles``/``overruns`` are counters; ``kind`` names the activity."""

    kind = "activity"

    def __init__(self) -> None:
        self.task: TaskContext | None = None
        self.cycles = 0
        #: ``(cycles, when)``: the number of the latest cycle and the monotonic time it began
        #: (one tuple: a reader on another thread sees a matching pair).
        self.stamp: tuple[int, float] = (0, 0.0)
        self.overruns = 0
        self._active = False

    @property
    def period(self) -> float:
        """Seconds between cycles; 0.0 for a non-periodic activity."""
        return 0.0

    def is_active(self) -> bool:
        """True between ``start()`` and ``stop()``."""
        return self._active

    def start(self) -> bool:
        """Begin running the task's cycles; False if already active. Called by ``task.start()``."""
        if self._active or self.task is None:
            return False
        self._active = True
        return True

    def stop(self, timeout: float = DEFAULT_JOIN_TIMEOUT) -> bool:
        """Stop running cycles; idempotent; never blocks longer than ``timeout``."""
        self._active = False
        return True

    def trigger(self) -> bool:
        """Ask for one cycle; True when accepted."""
        return False

    def execute(self) -> bool:
        """Run one cycle in the caller's thread (only a slave activity accepts: RTT's ``execute``)."""
        return False

    def _on_event(self) -> None:
        """Data arrived on an event port (called in the writer's thread; must not block)."""

    def _submit(self, fn: Callable[[], R]) -> Future[R] | None:
        """Queue ``fn`` to this activity's thread; None means 'run it yourself, now'."""
        return None

    def _run_cycle(self) -> None:
        task = self.task
        if task is not None:
            self.cycles += 1
            self.stamp = (self.cycles, time.monotonic())
            task._cycle()


class SlaveActivity(Activity):
    """No thread: the owner steps the task (``step()`` or ``task.update()``). Deterministic."""

    kind = "slave"

    def step(self) -> bool:
        """Run one update cycle now, in the caller's thread; False when the task is not running."""
        if not self._active:
            return False
        self._run_cycle()
        return True

    def execute(self) -> bool:
        return self.step()

    def trigger(self) -> bool:
        return self.step()


class SequentialActivity(Activity):
    """Runs a cycle in the thread that triggers it (see the module docstring): an event
    port's sample is handled in the thread that stored it, with no hand-over. One cycle at
    a time: a trigger while another thread cycles is run by that thread, right after
    (triggers coalesce, as an event activity's do). ``stop()`` waits (bounded) for a
    cycle running in another thread; from inside ``update_hook`` it returns at once."""

    kind = "sequential"
    MAX_ROUNDS = 1000  #: cycles one thread runs for triggers that came meanwhile, at most in a row

    def __init__(self) -> None:
        super().__init__()
        self._cycling = threading.Lock()
        self._pending = False
        self._owner = 0  # the thread cycling now (its ident), 0 when none

    def start(self) -> bool:
        """Start, then run one cycle at once (RTT: starting an event-driven task triggers it)."""
        if not super().start():
            return False
        self.trigger()
        return True

    def trigger(self) -> bool:
        if not self._active:
            return False
        self._cycles_here()
        return True

    def _on_event(self) -> None:
        if self._active:
            self._cycles_here()

    def _cycles_here(self) -> None:
        """Run the pending cycles in this thread, unless another one runs them."""
        self._pending = True
        for _ in range(self.MAX_ROUNDS):
            if not self._cycling.acquire(blocking=False):
                return  # the thread cycling sees _pending once its cycle ends
            try:
                self._owner = threading.get_ident()
                while self._pending and self._active:
                    self._pending = False
                    self._run_cycle()
            finally:
                self._owner = 0
                self._cycling.release()
            if not (self._pending and self._active):  # a trigger that came as the lock was let go
                return

    def stop(self, timeout: float = DEFAULT_JOIN_TIMEOUT) -> bool:
        self._active = False
        if self._owner == threading.get_ident():  # from inside update_hook: the cycle ends by itself
            return True
        if not self._cycling.acquire(timeout=timeout):
            log.warning("task %s: a cycle did not end within %.1f s", self.task.name if self.task else "?", timeout)
            return False
        self._cycling.release()
        return True


class _Run:
    """State of one start()..stop() run: its own wake event and stop flag (never reused)."""

    __slots__ = ("wake", "stopping", "accepting", "thread")

    def __init__(self) -> None:
        self.wake = Wake()
        self.stopping = False
        self.accepting = True
        self.thread: threading.Thread | None = None


class _ThreadedActivity(Activity):
    """An activity with one owned daemon thread while active, and an operation queue."""

    def __init__(self) -> None:
        super().__init__()
        self._run = _Run()
        self._run.accepting = False
        self._ops: deque[tuple[Callable[[], Any], Future[Any]]] = deque()  # each its own result type
        self._ops_lock = threading.Lock()  # operation queue only; cycles never take it

    @property
    def _wake(self) -> Wake:
        return self._run.wake

    def start(self) -> bool:
        old = self._run.thread
        if old is not None and old.is_alive() and old is not threading.current_thread():
            old.join(DEFAULT_JOIN_TIMEOUT)  # a run stopped from its own thread is finishing
        if not super().start():
            return False
        run = _Run()
        name = f"{self.kind}:{self.task.name if self.task else '?'}"
        run.thread = threading.Thread(target=self._main, args=(run,), name=name, daemon=True)
        with self._ops_lock:
            self._run = run
        run.thread.start()
        return True

    def stop(self, timeout: float = DEFAULT_JOIN_TIMEOUT) -> bool:
        self._active = False
        run = self._run
        run.stopping = True
        run.wake.set()
        thread = run.thread
        if thread is None or thread is threading.current_thread() or not thread.is_alive():
            return True
        thread.join(timeout)
        if thread.is_alive():
            log.warning("activity thread %s did not end within %.1f s", thread.name, timeout)
            return False
        return True

    def in_own_thread(self) -> bool:
        """True when called from this activity's thread."""
        return self._run.thread is threading.current_thread()

    def _submit(self, fn: Callable[[], R]) -> Future[R] | None:
        if self.in_own_thread():
            return None
        with self._ops_lock:
            run = self._run
            if not run.accepting:
                return None
            fut: Future[R] = Future()
            self._ops.append((fn, fut))
        run.wake.set()
        return fut

    def _process_ops(self) -> None:
        while self._ops:
            try:
                fn, fut = self._ops.popleft()
            except IndexError:
                return
            if fut.set_running_or_notify_cancel():
                try:
                    fut.set_result(fn())
                except BaseException as exc:  # handed to the caller, who re-raises it
                    fut.set_exception(exc)

    def _main(self, run: _Run) -> None:
        try:
            self._loop(run)
        except Exception:
            log.exception("activity %s crashed", self.kind)
        finally:
            with self._ops_lock:
                run.accepting = False
            self._process_ops()  # no caller is left waiting on a dead thread

    def _loop(self, run: _Run) -> None:  # pragma: no cover - interface
        raise NotImplementedError


class EventActivity(_ThreadedActivity):
    """Runs a cycle when triggered (``trigger()``, event ports, once after start)."""

    kind = "event"

    def __init__(self) -> None:
        super().__init__()
        self._pending = False

    def start(self) -> bool:
        """Start, then run one cycle at once (RTT: starting an event-driven task triggers it)."""
        if not super().start():
            return False
        self.trigger()
        return True

    def trigger(self) -> bool:
        if not self._active:
            return False
        self._pending = True
        self._wake.set()
        return True

    def _on_event(self) -> None:
        if self._active:  # trigger(), inlined: every sample on an event port comes through here, cold
            self._pending = True
            self._run.wake.set()

    def _loop(self, run: _Run) -> None:
        wake = run.wake
        while True:
            wake.clear()
            if run.stopping:
                return
            self._process_ops()
            if self._pending:
                self._pending = False
                self._run_cycle()
                continue
            wake.wait()


class PeriodicActivity(_ThreadedActivity):
    """Runs a cycle every ``period`` seconds at absolute deadlines, in its own thread.

    Raises ``ValueError`` for a period <= 0 (also when set while running).
    """

    kind = "periodic"

    def __init__(self, period: float) -> None:
        super().__init__()
        self._period = self._checked(period)
        self._period_changed = False

    @staticmethod
    def _checked(period: float) -> float:
        period = float(period)
        if not period > 0.0 or period != period or period == float("inf"):
            raise ValueError(f"a periodic activity needs a finite period > 0, got {period}")
        return period

    @property
    def period(self) -> float:
        return self._period

    @period.setter
    def period(self, value: float) -> None:
        """Change the period, also while running (thread-safe, takes effect at once)."""
        self._period = self._checked(value)
        self._period_changed = True
        if self._active:
            fit_switch_interval(self._period)
        self._wake.set()

    def trigger(self) -> bool:
        return False

    def start(self) -> bool:
        """Start cycling; a period under 10 ms also shortens the interpreter's switch
        interval (see :func:`fit_switch_interval`)."""
        if not super().start():
            return False
        fit_switch_interval(self._period)
        return True

    def _clock(self) -> Clock:
        task = self.task
        return task.clock if task is not None else WALL

    def _loop(self, run: _Run) -> None:
        source = self._clock()
        clock = source.monotonic
        wake = run.wake
        start = clock()
        deadline = start
        while True:
            wake.clear()
            if run.stopping:
                return
            self._process_ops()
            if self._clock() is not source:  # the deployer's clock changed (sim time on or off)
                source = self._clock()
                clock = source.monotonic
                start = deadline = clock()
            now = clock()
            if now < start:  # a simulated time went back (a bag played again): start over from there
                start = deadline = now
            if self._period_changed:
                self._period_changed = False
                deadline = start + self._period
            if now >= deadline:
                start = deadline
                self._run_cycle()
                period = self._period
                deadline += period
                now = clock()
                if now > deadline:
                    self.overruns += 1
                    missed = int((now - deadline) / period) + 1
                    deadline += missed * period
                continue
            source.wait(wake, deadline)


#: The shortest switch interval :func:`fit_switch_interval` sets (s): shorter costs every
#: thread of the process more in GIL hand-overs than it gains.
MIN_SWITCH_INTERVAL = 0.0002


def fit_switch_interval(period: float) -> float:
    """Make CPython's GIL switch interval (``sys.setswitchinterval``, 5 ms by default) at
    most a tenth of ``period``, but not under :data:`MIN_SWITCH_INTERVAL`; returns the
    interval now in force. A periodic thread woken at its deadline must take the GIL from
    whichever thread holds it, and waits up to that interval for it: with the default, a
    1 kHz task misses whole cycles as soon as another thread computes (a subscriber's
    sender, a converter). Process-wide and never raised back: the shortest period asked
    for wins."""
    import sys

    wanted = max(MIN_SWITCH_INTERVAL, period / 10)
    current = sys.getswitchinterval()
    if wanted < current:
        sys.setswitchinterval(wanted)
        log.info("switch interval %.2f ms for a period of %g s", wanted * 1000, period)
        return wanted
    return current


def freeze_heap() -> int:
    """Collect once, then move every object alive into CPython's permanent generation
    (``gc.freeze``), so that the collector never walks them again; returns how many. Call
    it once a process's tasks run (``scart deploy`` does): what imports and configuration
    built (gRPC, protobuf, pydantic: about half a million objects) then no longer makes a
    full collection a 20 ms pause of every thread, which a 1 kHz event task would see as
    its p99. Objects frozen that later become cyclic garbage are not freed (they are few:
    what was alive at start). Process-wide; idempotent enough to call again (it freezes
    what is alive then). Blocks for one full collection (tens of ms)."""
    import gc

    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()
