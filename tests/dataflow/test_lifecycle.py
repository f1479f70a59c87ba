"""TaskContext lifecycle: every state × every transition, hook vetoes and exceptions."""

from __future__ import annotations

import logging

import pytest

from dataflow import SlaveActivity, TaskContext, TaskState

S = TaskState


class Probe(TaskContext):
    """Records hook calls; hooks can be told to veto or raise."""

    def __init__(self, name: str = "probe", initial_state: TaskState = S.STOPPED) -> None:
        super().__init__(name, initial_state)
        self.calls: list[str] = []
        self.veto: set[str] = set()
        self.raise_in: set[str] = set()
        self.set_activity(SlaveActivity())

    def _hook(self, name: str):
        self.calls.append(name)
        if name in self.raise_in:
            raise RuntimeError(f"boom in {name}")
        return name not in self.veto

    def configure_hook(self):
        return self._hook("configure")

    def start_hook(self):
        return self._hook("start")

    def update_hook(self):
        self._hook("update")

    def error_hook(self):
        self._hook("error")

    def stop_hook(self):
        self._hook("stop")

    def cleanup_hook(self):
        self._hook("cleanup")

    def exception_hook(self):
        self._hook("exception")


def make(state: TaskState, initial: TaskState = S.STOPPED) -> Probe:
    t = Probe(initial_state=initial)
    if state is S.PRE_OPERATIONAL:
        t = Probe(initial_state=S.PRE_OPERATIONAL)
    elif state in (S.RUNNING, S.RUN_TIME_ERROR):
        assert t.start()
        if state is S.RUN_TIME_ERROR:
            assert t.error()
    elif state is S.EXCEPTION:
        t.start()
        t.raise_in = {"update"}
        t.update()
        t.raise_in = set()
    elif state is S.FATAL_ERROR:
        t.start()
        t.raise_in = {"update", "exception"}
        t.update()
        t.raise_in = set()
    elif state is S.INIT:
        t._tc_state = t._tc_target = S.INIT  # transient in RTT: only reachable by hand
    assert t.state is state
    t.calls.clear()
    return t


R, X = True, False
# (state, transition) -> (returns, new state, hooks called)
TABLE = {
    (S.INIT, "configure"): (X, S.INIT, []),
    (S.INIT, "start"): (X, S.INIT, []),
    (S.INIT, "stop"): (X, S.INIT, []),
    (S.INIT, "cleanup"): (X, S.INIT, []),
    (S.INIT, "recover"): (X, S.INIT, []),
    (S.INIT, "error"): (X, S.INIT, []),
    (S.PRE_OPERATIONAL, "configure"): (R, S.STOPPED, ["configure"]),
    (S.PRE_OPERATIONAL, "start"): (X, S.PRE_OPERATIONAL, []),
    (S.PRE_OPERATIONAL, "stop"): (X, S.PRE_OPERATIONAL, []),
    (S.PRE_OPERATIONAL, "cleanup"): (X, S.PRE_OPERATIONAL, []),
    (S.PRE_OPERATIONAL, "recover"): (X, S.PRE_OPERATIONAL, []),
    (S.PRE_OPERATIONAL, "error"): (X, S.PRE_OPERATIONAL, []),
    (S.FATAL_ERROR, "configure"): (X, S.FATAL_ERROR, []),
    (S.FATAL_ERROR, "start"): (X, S.FATAL_ERROR, []),
    (S.FATAL_ERROR, "stop"): (X, S.FATAL_ERROR, []),
    (S.FATAL_ERROR, "cleanup"): (X, S.FATAL_ERROR, []),
    (S.FATAL_ERROR, "recover"): (X, S.FATAL_ERROR, []),
    (S.FATAL_ERROR, "error"): (X, S.FATAL_ERROR, []),
    (S.EXCEPTION, "configure"): (X, S.EXCEPTION, []),
    (S.EXCEPTION, "start"): (X, S.EXCEPTION, []),
    (S.EXCEPTION, "stop"): (X, S.EXCEPTION, []),
    (S.EXCEPTION, "cleanup"): (X, S.EXCEPTION, []),
    (S.EXCEPTION, "recover"): (R, S.STOPPED, []),
    (S.EXCEPTION, "error"): (X, S.EXCEPTION, []),
    (S.STOPPED, "configure"): (R, S.STOPPED, ["configure"]),
    (S.STOPPED, "start"): (R, S.RUNNING, ["start"]),
    (S.STOPPED, "stop"): (X, S.STOPPED, []),
    (S.STOPPED, "cleanup"): (R, S.PRE_OPERATIONAL, ["cleanup"]),
    (S.STOPPED, "recover"): (X, S.STOPPED, []),
    (S.STOPPED, "error"): (X, S.STOPPED, []),
    (S.RUNNING, "configure"): (X, S.RUNNING, []),
    (S.RUNNING, "start"): (X, S.RUNNING, []),
    (S.RUNNING, "stop"): (R, S.STOPPED, ["stop"]),
    (S.RUNNING, "cleanup"): (X, S.RUNNING, []),
    (S.RUNNING, "recover"): (X, S.RUNNING, []),
    (S.RUNNING, "error"): (R, S.RUN_TIME_ERROR, []),
    (S.RUN_TIME_ERROR, "configure"): (X, S.RUN_TIME_ERROR, []),
    (S.RUN_TIME_ERROR, "start"): (X, S.RUN_TIME_ERROR, []),
    (S.RUN_TIME_ERROR, "stop"): (R, S.STOPPED, ["stop"]),
    (S.RUN_TIME_ERROR, "cleanup"): (X, S.RUN_TIME_ERROR, []),
    (S.RUN_TIME_ERROR, "recover"): (R, S.RUNNING, []),
    (S.RUN_TIME_ERROR, "error"): (R, S.RUN_TIME_ERROR, []),
}


def test_table_is_exhaustive():
    assert len(TABLE) == len(TaskState) * 6


@pytest.mark.parametrize(("state", "transition"), sorted(TABLE, key=lambda k: (k[0], k[1])))
def test_state_transition(state, transition, caplog):
    expected, new_state, hooks = TABLE[(state, transition)]
    task = make(state)
    with caplog.at_level(logging.WARNING, logger="dataflow"):
        result = getattr(task, transition)()
    assert result is expected
    assert task.state is new_state
    assert task.calls == hooks
    if not expected:  # refused: logged with task, state and transition, never silently
        text = caplog.text
        assert task.name in text and transition in text and state.name in text


def test_initial_state_pre_operational_and_invalid():
    assert Probe(initial_state=S.PRE_OPERATIONAL).state is S.PRE_OPERATIONAL
    assert Probe().state is S.STOPPED
    with pytest.raises(ValueError):
        TaskContext("x", initial_state=S.RUNNING)


def test_configure_veto_lands_in_pre_operational():
    t = make(S.STOPPED)
    t.veto = {"configure"}
    assert t.configure() is False
    assert t.state is S.PRE_OPERATIONAL


def test_start_veto_stays_stopped():
    t = make(S.STOPPED)
    t.veto = {"start"}
    assert t.start() is False
    assert t.state is S.STOPPED
    assert t.update() is False  # not running: a slave refuses to step


def test_update_and_error_hook_cycles():
    t = make(S.RUNNING)
    assert t.update()
    assert t.calls == ["update"]
    t.calls.clear()

    def update_with_error():
        t.calls.append("update")
        t.error()

    t.update_hook = update_with_error  # type: ignore[method-assign]
    t.update()
    assert t.state is S.RUN_TIME_ERROR
    assert t.calls == ["update", "error"]  # error_hook already in that cycle
    t.calls.clear()
    t.update()
    assert t.calls == ["error"]  # instead of update_hook until recover
    del t.update_hook
    assert t.recover()
    t.calls.clear()
    t.update()
    assert t.calls == ["update"]


@pytest.mark.parametrize(
    ("initial", "hook", "expected_calls"),
    [
        (S.STOPPED, "update", ["update", "stop", "exception"]),
        (S.PRE_OPERATIONAL, "update", ["update", "stop", "cleanup", "exception"]),
        (S.STOPPED, "start", ["start", "exception"]),
        (S.PRE_OPERATIONAL, "start", ["start", "cleanup", "exception"]),
        (S.PRE_OPERATIONAL, "configure", ["configure", "exception"]),
        (S.STOPPED, "stop", ["stop", "exception"]),
        (S.STOPPED, "error", ["error", "stop", "exception"]),
        (S.PRE_OPERATIONAL, "cleanup", ["cleanup", "exception"]),
    ],
)
def test_exception_path(initial, hook, expected_calls, caplog):
    t = Probe(initial_state=initial)
    if hook != "configure":
        assert t.configure()
    t.calls.clear()
    t.raise_in = {hook}
    with caplog.at_level(logging.ERROR, logger="dataflow"):
        if hook == "configure":
            assert t.configure() is False
        elif hook == "cleanup":
            assert t.cleanup() is False
        elif hook == "start":
            assert t.start() is False
        else:
            t.raise_in = set()
            assert t.start()
            t.calls.clear()
            t.raise_in = {hook}
            if hook == "stop":
                assert t.stop() is False
            elif hook == "error":
                t.error()
                t.update()
            else:
                t.update()
    assert t.state is S.EXCEPTION
    assert t.calls == expected_calls
    assert caplog.text.count("Traceback") == 1  # logged once, with its traceback
    t.raise_in = set()
    assert t.recover()
    assert t.state is initial


def test_exception_while_handling_is_fatal():
    t = make(S.RUNNING)
    t.raise_in = {"update", "stop"}
    t.update()
    assert t.state is S.FATAL_ERROR
    assert not t.activity.is_active()
    t.raise_in = set()
    for transition in ("configure", "start", "stop", "cleanup", "recover", "error"):
        assert getattr(t, transition)() is False
    assert t.update() is False


def test_exception_leaves_other_tasks_alone():
    a, b = make(S.RUNNING), make(S.RUNNING)
    a.raise_in = {"update"}
    a.update()
    b.update()
    assert a.state is S.EXCEPTION and b.state is S.RUNNING
    assert b.calls == ["update"]


def test_error_in_start_hook_with_target_running():
    t = make(S.STOPPED)
    t.start_hook = lambda: t.error() or True  # type: ignore[method-assign]
    assert t.start()
    assert t.state is S.RUN_TIME_ERROR


def test_set_activity_refused_while_running():
    t = make(S.RUNNING)
    assert t.set_activity(SlaveActivity()) is False
    assert t.stop()
    other = SlaveActivity()
    assert t.set_activity(other) and t.activity is other
    u = Probe("u")
    assert u.set_activity(other) is False  # owned by t


def test_stop_idempotent():
    t = make(S.RUNNING)
    assert t.stop() is True
    assert t.stop() is False
    assert t.state is S.STOPPED


def test_state_str_is_name():
    assert str(S.RUNNING) == "RUNNING"
