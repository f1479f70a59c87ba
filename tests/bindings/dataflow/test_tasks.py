"""implementation.task and scart:connect inside one runtime (no gRPC)."""

from __future__ import annotations

from pathlib import Path

import pytest

from support import ROOT, wait_until
from support.sca import composite, line_of, write

import scart
from dataflow import PeriodicActivity, SequentialActivity, TaskState
from scart.bindings.dataflow import DataflowSettings, host_of


TASKS = '''
from __future__ import annotations

from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, OutputPort, Property, TaskContext, operation


def _positive(v: float) -> None:
    if v <= 0:
        raise ValueError("must be > 0")


class Source(TaskContext):
    out = OutputPort(float)
    count = OutputPort(int)
    gain = Property(float, 1.0, check=_positive)
    label = Property(str, "src")
    events: list[str] = []

    def configure_hook(self) -> bool:
        Source.events.append(f"configure {self.name}")
        return True

    def start_hook(self) -> bool:
        Source.events.append(f"start {self.name}")
        return True

    def stop_hook(self) -> None:
        Source.events.append(f"stop {self.name}")

    def cleanup_hook(self) -> None:
        Source.events.append(f"cleanup {self.name}")

    @operation
    def emit(self, value: float) -> None:
        """Write gain * value."""
        self.out.write(self.gain * value)

    @operation
    def describe_me(self) -> str:
        return f"{self.label}:{self.gain}"


class Sink(TaskContext):
    inp = InputPort(float, event=True)
    text = InputPort(str)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[float] = []

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, v = self.inp.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.got.append(v)

    @operation
    def received(self) -> list[float]:
        return list(self.got)


class NotATask:
    pass


class Emitting(Protocol):
    def emit(self, value: float) -> None: ...


@scart.component
class Caller:
    src: Emitting = scart.reference()

    def fire(self, value: float) -> None:
        self.src.emit(value)
'''


def make(tmp_path: Path, body: str) -> Path:
    return write(tmp_path, {"t.composite": composite(body), "tasks.py": TASKS})


TWO = """
    <component name="src"><scart:implementation.task class="tasks:Source" period="0.05"/>
      <property name="gain">2.0</property><property name="label">first</property></component>
    <component name="sink"><scart:implementation.task class="tasks:Sink"/></component>
    <scart:connect from="src.out" to="sink.inp" policy="buffer:8"/>
    <component name="caller"><scart:implementation.python class="tasks:Caller"/>
      <reference name="src" target="src"/></component>
"""


def test_task_lifecycle_properties_and_operations(tmp_path: Path) -> None:
    path = make(tmp_path, TWO)
    rt = scart.Runtime.from_file(path)
    with rt:
        deployer = host_of(rt).deployer
        src, sink = deployer.task("src"), deployer.task("sink")
        assert src.state is TaskState.RUNNING and sink.state is TaskState.RUNNING
        assert isinstance(src.activity, PeriodicActivity) and src.activity.period == 0.05
        assert sink.activity.kind == "event"
        assert src.gain == 2.0 and src.label == "first"
        assert rt.service("src/Source").describe_me() == "first:2.0"
        assert rt.service("src").describe_me() == "first:2.0"
        events = type(src).events
    assert src.state is TaskState.PRE_OPERATIONAL and sink.state is TaskState.PRE_OPERATIONAL
    assert events == ["configure src", "start src", "stop src", "cleanup src"]
    assert not src.out.connected()


def test_connect_in_process_and_reference_to_task(tmp_path: Path) -> None:
    with scart.Runtime.from_file(make(tmp_path, TWO)) as rt:
        conn = host_of(rt).deployer.task("src").out.connections()
        assert len(conn) == 1 and str(conn[0].policy) == "buffer:8"
        rt.service("caller").fire(1.5)
        rt.service("src/Source").emit(2.0)
        got = wait_until(lambda: (r := rt.service("sink").received()) and len(r) == 2 and r)
        assert got == [3.0, 4.0]


@pytest.mark.parametrize(
    ("body", "marker", "words"),
    [
        ('<scart:connect from="src.nope" to="sink.inp"/>', "src.nope", ["no port 'nope'", "out (out)"]),
        ('<scart:connect from="src.out" to="sink.text"/>', "sink.text", ["type mismatch", "float64 -> string"]),
        ('<scart:connect from="sink.inp" to="src.out"/>', 'from="sink.inp"', ["not an output port"]),
        ('<scart:connect from="caller.x" to="sink.inp"/>', "caller.x", ["not an implementation.task"]),
        ('<scart:connect from="ghost.a" to="phantom.b"/>', "ghost.a", ["neither 'ghost' nor 'phantom'"]),
        ('<scart:connect from="src.out" to="sink.inp" policy="fifo"/>', "fifo", ["invalid connection policy"]),
        ('<scart:connect from="src" to="sink.inp"/>', 'from="src"', ["expected COMPONENT.PORT"]),
    ],
)
def test_connect_static_errors(tmp_path: Path, body: str, marker: str, words: list[str]) -> None:
    text = composite(TWO.replace('<scart:connect from="src.out" to="sink.inp" policy="buffer:8"/>', body))
    path = write(tmp_path, {"t.composite": text, "tasks.py": TASKS})
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path)
    problem = err.value.errors[0]
    assert (problem.path, problem.line) == (str(path), line_of(text, marker)), str(err.value)
    for w in words:
        assert w in problem.message, problem.message


@pytest.mark.parametrize(
    ("prop", "words"),
    [
        ('<property name="gain">fast</property>', ["gain", "not a valid float"]),
        ('<property name="gain">-1</property>', ["gain", "must be > 0"]),
        ('<property name="nope">1</property>', ["no property 'nope'", "gain"]),
    ],
)
def test_task_property_errors_at_load(tmp_path: Path, prop: str, words: list[str]) -> None:
    text = composite(f"""
        <component name="src"><scart:implementation.task class="tasks:Source"/>
          {prop}</component>
    """)
    path = write(tmp_path, {"t.composite": text, "tasks.py": TASKS})
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path)
    problem = err.value.errors[0]
    assert problem.line == line_of(text, "<property"), str(err.value)
    for w in words:
        assert w in problem.message, problem.message


@pytest.mark.parametrize(
    ("impl", "words"),
    [
        ('<scart:implementation.task class="tasks:NotATask"/>', ["not a dataflow.TaskContext"]),
        ('<scart:implementation.task class="tasks:Missing"/>', ["cannot import"]),
        ('<scart:implementation.task class="tasks:Source" period="-1"/>', ["period"]),
        ('<scart:implementation.task class="tasks:Source" activity="sequentiel"/>',
         ["'sequentiel'"]),
        ('<scart:implementation.task class="tasks:Source" activity="sequential" period="0.1"/>',
         ["a period goes with activity \"periodic\""]),
        ('<scart:implementation.task class="tasks:Source" activity="periodic"/>', ["\"periodic\" needs one"]),
    ],
)
def test_task_implementation_errors(tmp_path: Path, impl: str, words: list[str]) -> None:
    text = composite(f'<component name="src">{impl}</component>')
    path = write(tmp_path, {"t.composite": text, "tasks.py": TASKS})
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path)
    assert err.value.line == line_of(text, "implementation.task")
    assert any(w in str(err.value) for w in words), str(err.value)


def test_a_sequential_task_runs_its_cycle_in_the_thread_that_stores_the_sample(tmp_path: Path) -> None:
    """activity="sequential": RTT's SequentialActivity, no wake-up: the writer's own
    thread has run the sink's update_hook by the time write() returns."""
    path = make(tmp_path, """
    <component name="src"><scart:implementation.task class="tasks:Source"/></component>
    <component name="sink"><scart:implementation.task class="tasks:Sink" activity="sequential"/></component>
    <component name="woken"><scart:implementation.task class="tasks:Sink" activity="event"/></component>
    <scart:connect from="src.out" to="sink.inp" policy="buffer:8"/>
""")
    with scart.Runtime.from_file(path) as rt:
        deployer = host_of(rt).deployer
        src, sink = deployer.task("src"), deployer.task("sink")
        assert isinstance(sink.activity, SequentialActivity) and deployer.task("woken").activity.kind == "event"
        for value in (1.0, 2.0, 3.0):
            src.out.write(value)
            assert sink.got[-1] == value  # no wait: the cycle ran inside write()


def test_bridge_composites_validate() -> None:
    bridge = ROOT / "composites" / "bridge"
    for name in ("thermostat.composite", "bridge-proxy.composite", "bridge-binding.composite"):
        scart.Runtime.from_file(bridge / name)  # loads and checks; nothing starts


def test_default_name_service_port_taken_falls_back_and_says_where(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Without an ns setting, a busy default port embeds the name service elsewhere, and
    the runtime says where it really is (extensions resolve tasks through that one)."""
    import socket

    import scart.bindings.dataflow.settings

    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen()  # something that is not a name service holds the "default" port
    taken = f"127.0.0.1:{busy.getsockname()[1]}"
    monkeypatch.setattr(scart.bindings.dataflow.settings, "DEFAULT_NS_ADDRESS", taken)
    try:
        with scart.Runtime.from_file(make(tmp_path, TWO), settings=DataflowSettings(serve=True).apply()) as rt:
            real = host_of(rt).ns_address
            assert real != taken and rt.served()["name service"] == f"{real} (embedded)"
    finally:
        busy.close()


def test_an_explicit_name_service_that_cannot_be_bound_fails_the_start(tmp_path: Path) -> None:
    import socket

    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen()
    taken = f"127.0.0.1:{busy.getsockname()[1]}"
    try:
        rt = scart.Runtime.from_file(make(tmp_path, TWO), settings=DataflowSettings(serve=True, ns=taken).apply())
        with pytest.raises(scart.ScartError, match=f"starting implementation.task failed.*{taken}"):
            rt.start()
        assert rt.state is scart.RuntimeState.STOPPED
    finally:
        busy.close()


def test_checked_property_type_built_once_per_declaration() -> None:
    """The checked type of a Property is memoised: the TypeAdapter cache is not defeated."""
    from dataflow import Property
    from scart.bindings.dataflow.task import _checked_type

    def positive(value: float) -> None:
        if value <= 0:
            raise ValueError("must be > 0")

    prop = Property(float, 1.0, check=positive)
    assert _checked_type(prop) is _checked_type(prop)
    assert _checked_type(Property(float, 1.0, check=positive)) is not _checked_type(prop)
