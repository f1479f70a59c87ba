"""binding.dataflow against tasks of the same runtime (in-process proxies, no gRPC)."""

from __future__ import annotations

from pathlib import Path

import pytest

from support import wait_until
from support.sca import composite, line_of, write

import scart
from scart.bindings.dataflow import host_of
from scart.bindings.dataflow import DataflowServiceBinding, bindings_of


TASKS = '''
from __future__ import annotations

import threading
from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, OutputPort, TaskContext, operation

GATE = threading.Event()
ENTERED = threading.Event()
SEEN: list[float] = []


class Scaler(TaskContext):
    """Writes 10 * each sample of ``x`` on ``y``; ``level`` holds the last one."""

    x = InputPort(float, event=True)
    y = OutputPort(float)
    level = OutputPort(float)
    flag = InputPort(bool)

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, v = self.x.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.y.write(10.0 * v)
            self.level.write(v)

    @operation
    def burst(self, n: int) -> None:
        for i in range(n):
            self.y.write(float(i))


class ScalerPorts(Protocol):
    def push(self, value: float) -> None: ...
    def level(self) -> float | None: ...


class BadPorts(Protocol):
    def push(self, value: str) -> None: ...


class WrongDirection(Protocol):
    def y(self, value: float) -> None: ...


class Samples(Protocol):
    def y(self, value: float) -> None: ...


class Control(Protocol):
    def send(self, value: float) -> None: ...
    def current(self) -> float | None: ...
    def samples(self) -> list[float]: ...


@scart.component(services=[Control, Samples])
class Client:
    scaler: ScalerPorts = scart.reference()

    @scart.init
    def open(self) -> None:
        self.got: list[float] = []
        self.lock = threading.Lock()

    def send(self, value: float) -> None:
        self.scaler.push(value)

    def current(self) -> float | None:
        return self.scaler.level()

    def y(self, value: float) -> None:
        with self.lock:
            self.got.append(value)

    def samples(self) -> list[float]:
        with self.lock:
            return list(self.got)


@scart.component(services=[Samples])
class SlowSink:
    def y(self, value: float) -> None:
        ENTERED.set()
        GATE.wait(10)
        SEEN.append(value)


@scart.component
class Bad:
    scaler: BadPorts = scart.reference()


@scart.component
class Wrong:
    scaler: WrongDirection = scart.reference()
'''

BASE = """
    <component name="scaler"><scart:implementation.task class="tasks:Scaler"/></component>
    <component name="client"><scart:implementation.python class="tasks:Client"/>
      <service name="Samples"><scart:binding.dataflow component="scaler"/></service>
      <reference name="scaler">
        <scart:binding.dataflow component="scaler"><scart:map operation="push" port="x"/></scart:binding.dataflow>
      </reference>
    </component>
"""


def make(tmp_path: Path, body: str) -> Path:
    return write(tmp_path, {"t.composite": composite(body), "tasks.py": TASKS})


@pytest.mark.parametrize("service_attrs", ["", ' period="0.02"'], ids=["push", "polling"])
def test_reference_writes_and_reads_service_receives(tmp_path: Path, service_attrs: str) -> None:
    body = BASE.replace('<service name="Samples"><scart:binding.dataflow component="scaler"/>',
                        f'<service name="Samples"><scart:binding.dataflow component="scaler"{service_attrs}/>')
    with scart.Runtime.from_file(make(tmp_path, body)) as rt:
        client = rt.service("client/Control")
        assert client.current() is None  # nothing written yet
        service = next(b for b in bindings_of(rt) if isinstance(b, DataflowServiceBinding))
        wait_until(lambda: service.connected, message="service binding never subscribed")
        client.send(1.5)
        assert wait_until(lambda: client.samples() == [15.0] and client.samples())
        assert wait_until(lambda: client.current() == 1.5)
        client.send(2.0)
        assert wait_until(lambda: client.samples() == [15.0, 20.0] and client.samples())
        assert service.delivered == 2 and service.address == "dataflow:scaler"


def test_ports_attribute_mapping(tmp_path: Path) -> None:
    body = BASE.replace('<scart:binding.dataflow component="scaler"><scart:map operation="push" port="x"/>'
                        "</scart:binding.dataflow>", '<scart:binding.dataflow component="scaler" ports="push=x"/>')
    with scart.Runtime.from_file(make(tmp_path, body)) as rt:
        rt.service("client/Control").send(3.0)
        assert wait_until(lambda: rt.service("client/Control").current() == 3.0)


@pytest.mark.parametrize(("policy", "expect_dropped"), [("data", False), ("buffer:4", True)])
def test_busy_component_follows_policy(tmp_path: Path, policy: str, expect_dropped: bool) -> None:
    body = f"""
        <component name="scaler"><scart:implementation.task class="tasks:Scaler"/></component>
        <component name="sink"><scart:implementation.python class="tasks:SlowSink"/>
          <service name="Samples"><scart:binding.dataflow component="scaler" policy="{policy}"/></service>
        </component>
    """
    path = make(tmp_path, body)
    rt = scart.Runtime.from_file(path)
    with rt:
        import tasks  # the contribution's module (its folder is on sys.path now)

        tasks.GATE.clear()
        tasks.ENTERED.clear()
        tasks.SEEN.clear()
        binding = bindings_of(rt)[0]
        wait_until(lambda: binding.connected)
        host_of(rt).deployer.task("scaler").burst(1)  # the sink blocks on this one
        wait_until(tasks.ENTERED.is_set)
        host_of(rt).deployer.task("scaler").burst(20)  # 0.0 .. 19.0 while the sink is busy
        tasks.GATE.set()
        wait_until(lambda: len(tasks.SEEN) >= (5 if expect_dropped else 2), timeout=10)
        if expect_dropped:
            assert tasks.SEEN[:5] == [0.0, 0.0, 1.0, 2.0, 3.0]  # the first, then BUFFER(4) kept the oldest 4
            assert binding.dropped == 16
        else:
            assert tasks.SEEN == [0.0, 19.0]  # DATA: only the newest after the busy period
            assert binding.dropped >= 1
        tasks.GATE.set()


@pytest.mark.parametrize(
    ("cls", "extra", "words"),
    [
        ("Wrong", "", ["operation 'y'", "port is an output, not an input: 'y'"]),
        ("Bad", ' ports="push=nope"', ["has no input port 'nope'", "x (in float64)"]),
    ],
)
def test_static_port_errors(tmp_path: Path, cls: str, extra: str, words: list[str]) -> None:
    text = composite(f"""
        <component name="scaler"><scart:implementation.task class="tasks:Scaler"/></component>
        <component name="c"><scart:implementation.python class="tasks:{cls}"/>
          <reference name="scaler"><scart:binding.dataflow component="scaler"{extra}/></reference>
        </component>
    """)
    path = write(tmp_path, {"t.composite": text, "tasks.py": TASKS})
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path)
    (problem,) = err.value.errors
    assert (problem.code, problem.path, problem.line) == ("SCART-D002", str(path), line_of(text, "binding.dataflow"))
    for w in words:
        assert w in problem.message, problem.message


def test_static_type_mismatch_on_mapped_port(tmp_path: Path) -> None:
    text = composite("""
        <component name="scaler"><scart:implementation.task class="tasks:Scaler"/></component>
        <component name="c"><scart:implementation.python class="tasks:Bad"/>
          <reference name="scaler"><scart:binding.dataflow component="scaler" ports="push=x"/></reference>
        </component>
    """)
    path = write(tmp_path, {"t.composite": text, "tasks.py": TASKS})
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path)
    (problem,) = err.value.errors
    assert (problem.code, problem.line) == ("SCART-D003", line_of(text, "binding.dataflow"))
    assert "interface type string does not match port scaler.x of type float64" in problem.message


def test_static_attribute_errors(tmp_path: Path) -> None:
    text = composite("""
        <component name="scaler"><scart:implementation.task class="tasks:Scaler"/></component>
        <component name="client"><scart:implementation.python class="tasks:Client"/>
          <service name="Samples"><scart:binding.dataflow component="scaler" policy="lifo"/></service>
          <reference name="scaler"><scart:binding.dataflow component="scaler" ports="push=x" period="1"/></reference>
        </component>
    """)
    path = write(tmp_path, {"t.composite": text, "tasks.py": TASKS})
    with pytest.raises(scart.ScdlError) as err:
        scart.Runtime.from_file(path)
    text_err = str(err.value)
    assert f":{line_of(text, 'lifo')}: invalid connection policy 'lifo'" in text_err
    assert f":{line_of(text, 'period=')}: period is for services" in text_err
