"""Activities: slave determinism, periodic and event-driven threads, stopping, operations."""

from __future__ import annotations

import threading

from support import wait_until

from dataflow import (
    ConnPolicy,
    EventActivity,
    FlowStatus,
    InputPort,
    OutputPort,
    PeriodicActivity,
    SequentialActivity,
    SlaveActivity,
    TaskContext,
    TaskState,
    operation,
)


class Counter(TaskContext):
    inp = InputPort(int, event=True)
    out = OutputPort(int)

    def __init__(self, name: str = "counter") -> None:
        super().__init__(name)
        self.n = 0
        self.threads: set[str] = set()
        self.stop_at: int | None = None
        self.slow_first = 0.0

    def update_hook(self) -> None:
        self.n += 1
        self.threads.add(threading.current_thread().name)
        flow, v = self.inp.read()
        if flow is FlowStatus.NEW_DATA:
            self.out.write(v * 2)
        if self.slow_first and self.n == 1:
            threading.Event().wait(self.slow_first)  # simulates a slow cycle (not a test sync)
        if self.stop_at is not None and self.n >= self.stop_at:
            self.stop()

    @operation(own_thread=True)
    def where(self) -> str:
        return threading.current_thread().name

    @operation
    def where_caller(self) -> str:
        return threading.current_thread().name


def test_default_activity_is_event():
    t = Counter()
    assert isinstance(t.activity, EventActivity)
    assert (t.activity.kind, t.activity.period) == ("event", 0.0)


def test_slave_activity_deterministic():
    t = Counter()
    act = SlaveActivity()
    assert t.set_activity(act)
    assert act.step() is False  # not running
    t.start()
    for _ in range(5):
        assert act.step()
    assert t.update() and t.trigger()
    assert t.n == 7 and act.cycles == 7
    assert threading.current_thread().name in t.threads
    assert act.kind == "slave" and act.period == 0.0 and act.overruns == 0
    t.stop()


def test_event_activity_runs_on_event_port_data_only_while_running():
    t = Counter()
    src, sink = OutputPort(int, "src"), InputPort(int, "sink")
    src.connect_to(t.inp, ConnPolicy.buffer(4))
    t.out.connect_to(sink, ConnPolicy.buffer(4))
    src.write(1)  # not running: nothing happens
    assert t.n == 0
    assert t.start()
    new = lambda: (lambda r: r[1] if r[0] is FlowStatus.NEW_DATA else None)(sink.read())  # noqa: E731
    assert wait_until(new) == 2  # RTT: start triggers one cycle (which reads the 1)
    src.write(5)
    assert wait_until(new, message="event cycle") == 10
    assert t.trigger()
    n = t.n
    wait_until(lambda: t.n > n)
    assert t.stop()
    assert not any(th.name == "event:counter" for th in threading.enumerate() if th.is_alive())


def test_event_not_fired_by_rejected_write():
    t = Counter()
    t.set_activity(SlaveActivity())  # event ports only trigger an EventActivity
    fired = []
    t.inp.add_data_callback(fired.append)
    src = OutputPort(int, "src")
    src.connect_to(t.inp, ConnPolicy.buffer(1))
    src.write(1)
    src.write(2)  # rejected: full
    assert len(fired) == 1


def test_periodic_activity_runs_and_stops():
    t = Counter()
    act = PeriodicActivity(0.002)
    t.set_activity(act)
    assert act.kind == "periodic" and act.period == 0.002
    assert t.trigger() is False  # refused, as in RTT
    assert t.start()
    assert t.trigger() is False
    wait_until(lambda: act.cycles >= 5)
    assert t.update() is False  # only a slave executes in the caller's thread
    assert t.stop()
    assert t.state is TaskState.STOPPED
    n = act.cycles
    assert t.stop() is False
    assert not act._run.thread.is_alive()  # stop() joined the thread: no cycle can follow
    assert act.cycles == n


def test_period_writable_while_running():
    t = Counter()
    act = PeriodicActivity(5.0)  # long: without the change the second cycle would take 5 s
    t.set_activity(act)
    t.start()
    wait_until(lambda: act.cycles >= 1)
    act.period = 0.002
    wait_until(lambda: act.cycles >= 10, timeout=5.0)
    t.stop()
    import pytest

    with pytest.raises(ValueError):
        act.period = 0.0
    with pytest.raises(ValueError):
        PeriodicActivity(-1.0)


def test_overruns_counted():
    t = Counter()
    act = PeriodicActivity(0.001)
    t.set_activity(act)
    t.slow_first = 0.02  # the first cycle ends well past its deadline
    t.start()
    wait_until(lambda: act.overruns >= 1)
    wait_until(lambda: act.cycles >= 3)  # and it goes on afterwards
    t.stop()


def test_stop_from_inside_update_hook():
    t = Counter()
    t.set_activity(PeriodicActivity(0.001))
    t.stop_at = 3
    t.start()
    wait_until(lambda: t.state is TaskState.STOPPED)
    assert t.n == 3
    wait_until(lambda: not any(th.name == "periodic:counter" for th in threading.enumerate()))
    assert t.start()  # restartable: a new thread
    wait_until(lambda: t.state is TaskState.STOPPED)


def test_no_thread_before_start_and_threads_are_daemon():
    before = {th.name for th in threading.enumerate()}
    t = Counter("daemon")
    t.set_activity(PeriodicActivity(0.01))
    assert {th.name for th in threading.enumerate()} == before
    t.start()
    th = next(th for th in threading.enumerate() if th.name == "periodic:daemon")
    assert th.daemon
    t.stop()


def test_operations_caller_and_own_thread():
    t = Counter("ops")
    t.set_activity(PeriodicActivity(0.005))
    me = threading.current_thread().name
    assert t.call("where") == me  # not running: no thread, runs in the caller
    t.start()
    assert t.call("where") == "periodic:ops"
    assert t.call("where_caller") == me
    t.stop()
    e = Counter("ev")
    e.start()
    assert e.call("where") == "event:ev"
    e.stop()


def test_own_thread_operation_exception_reaches_caller():
    import pytest

    class Bad(TaskContext):
        @operation(own_thread=True)
        def fail(self) -> None:
            raise ValueError("nope")

    t = Bad("bad")
    t.start()
    with pytest.raises(ValueError, match="nope"):
        t.call("fail")
    t.stop()


def test_periodic_exception_moves_to_exception_and_thread_ends():
    class Crash(TaskContext):
        def update_hook(self) -> None:
            raise RuntimeError("crash")

    t = Crash("crash")
    t.set_activity(PeriodicActivity(0.001))
    t.start()
    wait_until(lambda: t.state is TaskState.EXCEPTION)
    wait_until(lambda: not any(th.name == "periodic:crash" for th in threading.enumerate()))
    assert t.recover() and t.state is TaskState.STOPPED


def test_a_wake_set_from_many_threads_wakes_its_waiter_and_none_is_lost():
    """The activities' wake-up (a raw-lock binary semaphore): a set before the wait is
    kept, a clear forgets it, and every set from other threads ends a wait (none lost)."""
    from dataflow.threads import Wake

    wake = Wake()
    assert not wake.wait(0.01) and not wake.is_set()
    wake.set()
    wake.set()  # twice: still one pending wake-up, never an error
    assert wake.is_set() and wake.wait(0) and wake.wait(0)  # a wait leaves it set, as an Event's does
    wake.clear()
    assert not wake.is_set() and not wake.wait(0.01)

    rounds, woken = 300, []
    pending = threading.Semaphore(0)  # one per set still to come

    def waiter() -> None:
        for _ in range(rounds):
            wake.clear()
            pending.release()
            if not wake.wait(10):
                return
            woken.append(1)

    thread = threading.Thread(target=waiter)
    thread.start()
    for _ in range(rounds):
        assert pending.acquire(timeout=10)
        wake.set()
    thread.join(10)
    assert not thread.is_alive() and len(woken) == rounds


def test_a_periodic_task_counts_its_periods_on_its_deployers_clock() -> None:
    from dataflow import Deployer
    from dataflow.clock import WALL, SimClock

    clock = SimClock()
    with Deployer() as deployer:
        task = deployer.add(Counter("simulated"))
        assert task.set_activity(PeriodicActivity(0.1))
        deployer.use_clock(clock)
        assert task.clock is clock and deployer.add(Counter("later")).clock is clock
        clock.set(5_000_000_000)  # the simulation is at 5 s
        assert task.configure() and task.start()
        wait_until(lambda: task.n == 1, timeout=5)  # the first cycle at once
        for step in range(1, 21):  # 2 simulated seconds, 50 ms a step, however fast the wall clock goes
            clock.set(5_001_000_000 + step * 50_000_000)  # (1 ms past: no deadline falls on a step)
            wait_until(lambda: task.n == 1 + step // 2, timeout=5, message=f"step {step}: {task.n} cycles")
        assert task.activity.overruns == 0
        deployer.use_clock(WALL)  # sim time off: the system's clock again, at its next wake-up
        wait_until(lambda: task.n >= 23, timeout=5)


class Reader(TaskContext):
    """Records, in its update_hook, what it read and in which thread; at most one cycle
    at a time is checked (``overlaps`` counts the others)."""

    inp = InputPort(int, event=True)

    def __init__(self, name: str = "reader") -> None:
        super().__init__(name)
        self.seen: list[tuple[int, str]] = []
        self.inside = 0
        self.overlaps = 0
        self.hold: threading.Event | None = None

    def update_hook(self) -> None:
        self.inside += 1
        self.overlaps += self.inside > 1
        if self.hold is not None:
            self.hold.wait(5)
        for _ in range(1000):
            flow, value = self.inp.read()
            if flow is not FlowStatus.NEW_DATA:
                break
            self.seen.append((value, threading.current_thread().name))
        self.inside -= 1


def test_a_sequential_activity_runs_the_cycle_in_the_writers_thread_before_write_returns():
    out: OutputPort[int] = OutputPort(int, name="out")
    reader = Reader()
    assert reader.set_activity(SequentialActivity())
    out.connect_to(reader.inp, ConnPolicy.buffer(10))
    reader.configure()
    reader.start()
    try:
        out.write(1)
        assert reader.seen == [(1, threading.current_thread().name)]  # no hand-over, no wake-up
        writer = threading.Thread(target=lambda: out.write(2), name="writer")
        writer.start()
        writer.join(5)
        assert reader.seen[-1] == (2, "writer") and reader.activity.cycles >= 3
    finally:
        reader.stop()


def test_a_sequential_activity_runs_one_cycle_at_a_time_and_loses_no_trigger():
    out: OutputPort[int] = OutputPort(int, name="out")
    reader = Reader()
    reader.set_activity(SequentialActivity())
    out.connect_to(reader.inp, ConnPolicy.buffer(100))
    reader.configure()
    reader.start()
    reader.hold = threading.Event()
    first = threading.Thread(target=lambda: out.write(1), name="first")
    first.start()
    wait_until(lambda: reader.inside == 1, timeout=5)
    for k in range(2, 12):  # while the first writer's thread cycles: these coalesce into its next cycle
        out.write(k)
    assert [v for v, _ in reader.seen] == []
    reader.hold.set()
    first.join(5)
    assert [v for v, _ in reader.seen] == list(range(1, 12)) and {t for _, t in reader.seen} == {"first"}
    assert reader.overlaps == 0
    reader.hold = threading.Event()  # a stop waits for a cycle running in another thread
    late = threading.Thread(target=lambda: out.write(99), name="late")
    late.start()
    wait_until(lambda: reader.inside == 1, timeout=5)
    threading.Timer(0.05, reader.hold.set).start()
    assert reader.stop() and reader.inside == 0
    late.join(5)


def test_freeze_heap_takes_what_is_alive_out_of_every_later_collection() -> None:
    """What start-up built is never walked again: a full collection then looks only at what
    came after (scart deploy calls it once its tasks run)."""
    import gc

    from dataflow.activities import freeze_heap

    kept = [[k] for k in range(1000)]  # lists: tracked by the collector
    assert id(kept[0]) in {id(o) for o in gc.get_objects()}
    try:
        frozen = freeze_heap()
        assert frozen == gc.get_freeze_count() > len(kept)
        assert id(kept[0]) not in {id(o) for o in gc.get_objects()}  # in no generation a collection walks
    finally:
        gc.unfreeze()  # this test process goes on as it was
    assert gc.get_freeze_count() == 0
