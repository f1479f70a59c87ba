"""binding.dataflow and scart:connect at their edges: interface parameter names and wrong
calls, a nested composite's sibling task, a task missing from the name service, and the
load-time checks of periods, properties and attributes."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from scart.bindings.dataflow import DataflowSettings
from scart.errors import InvocationError

RV5TASKS = '''
from __future__ import annotations

from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, OutputPort, TaskContext


class Scaler(TaskContext):
    x = InputPort(float, event=True)
    level = OutputPort(float)

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, v = self.x.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.level.write(v)


class Ports(Protocol):
    def push(self, sample: float) -> None: ...
    def level(self) -> float | None: ...


class Control(Protocol):
    def send(self, value: float) -> None: ...
    def send_wrong(self) -> None: ...
    def current(self) -> float | None: ...


@scart.component(services=[Control])
class Client:
    scaler: Ports = scart.reference()

    def send(self, value: float) -> None:
        self.scaler.push(sample=value)  # the interface's own parameter name

    def send_wrong(self) -> None:
        self.scaler.push(1.0, 2.0)

    def current(self) -> float | None:
        return self.scaler.level()
'''

CLIENT = '''<component name="client"><scart:implementation.python class="rv5tasks:Client"/>
      <reference name="scaler">
        <scart:binding.dataflow component="scaler"><scart:map operation="push" port="x"/></scart:binding.dataflow>
      </reference></component>'''


def test_dataflow_reference_takes_the_interface_parameter_names_and_names_a_wrong_call(tmp_path: Path) -> None:
    import scart
    from support import wait_until
    from support.grpc_binding import composite, gwrite
    (tmp_path / "rv5tasks.py").write_text(RV5TASKS)
    body = f'<component name="scaler"><scart:implementation.task class="rv5tasks:Scaler"/></component>{CLIENT}'
    with scart.Runtime.from_file(str(gwrite(tmp_path, {"t.composite": composite(body)}))) as rt:
        control = rt.service("client/Control")
        control.send(2.5)
        wait_until(lambda: control.current() == 2.5, timeout=10)
        with pytest.raises(InvocationError, match=r"Ports\.push \(port scaler\.x\).*(argument|positional)"):
            control.send_wrong()


def test_dataflow_binding_in_a_nested_composite_finds_its_sibling_task(tmp_path: Path) -> None:
    import scart
    from support import wait_until
    from support.grpc_binding import composite, gwrite
    (tmp_path / "rv5tasks.py").write_text(RV5TASKS)
    inner = composite(f'<component name="scaler"><scart:implementation.task class="rv5tasks:Scaler"/></component>'
                      f'{CLIENT}', name="Inner")
    gwrite(tmp_path, {"inner.composite": inner})
    outer = composite('<component name="Cell"><implementation.composite name="t:Inner"/></component>', name="Outer")
    with scart.Runtime.from_file(str(gwrite(tmp_path, {"outer.composite": outer}))) as rt:
        control = rt.service("Cell/client/Control")
        control.send(4.0)
        wait_until(lambda: control.current() == 4.0, timeout=5)


def test_connect_to_a_missing_task_says_so_once_and_links_are_undone_at_stop(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    import logging

    import scart
    from support import free_port, wait_until
    from support.grpc_binding import composite, gwrite, instance
    monkeypatch.delenv("SCART_NS", raising=False)
    caplog.set_level(logging.INFO, logger="scart")
    (tmp_path / "rv5tasks.py").write_text(RV5TASKS)
    ns = f"127.0.0.1:{free_port()}"
    one = composite('<component name="scaler"><scart:implementation.task class="rv5tasks:Scaler"/></component>'
                    '<scart:external task="ghost"/><scart:connect from="scaler.level" to="ghost.x"/>', name="One")
    two = composite('<component name="ghost"><scart:implementation.task class="rv5tasks:Scaler"/></component>',
                    name="Two")
    d1, d2 = tmp_path / "one", tmp_path / "two"
    d1.mkdir()
    d2.mkdir()
    (d1 / "rv5tasks.py").write_text(RV5TASKS)
    (d2 / "rv5tasks.py").write_text(RV5TASKS)
    served = DataflowSettings(ns=ns, serve=True).apply()  # as scart run --ns does
    rt1 = scart.Runtime.from_file(str(gwrite(d1, {"one.composite": one})), settings=served)
    rt2 = scart.Runtime.from_file(str(gwrite(d2, {"two.composite": two})), settings=served)
    with rt1:
        wait_until(lambda: f"waiting for ghost in name service {ns}" in caplog.text, timeout=5)
        with rt2:
            ghost_in = instance(rt2, "ghost").ports()["x"]
            wait_until(lambda: ghost_in.connected(), timeout=10, message="link never made")
            assert caplog.text.count("waiting for ghost") == 1
            rt1.stop()
            assert "disconnected at stop" in caplog.text
            # the sink's end closes when it reads the source's close: soon, not within the call
            wait_until(lambda: not ghost_in.connected(), timeout=10, message="the link outlived its stop")


def test_a_bad_task_period_hides_no_other_problem_and_checks_say_refused(tmp_path: Path) -> None:
    import scart
    from support.grpc_binding import composite, gwrite
    (tmp_path / "rv5ptask.py").write_text('''
from dataflow import InputPort, Property, TaskContext


def positive(v: float) -> None:
    if v <= 0:
        raise ValueError("must be > 0")


class T(TaskContext):
    gain = Property(float, 1.0, check=positive)
    x = InputPort(float)
''')
    body = '''<component name="a"><scart:implementation.task class="rv5ptask:T" period="-1"/>
      <property name="gain">-2</property></component>
    <scart:connect from="a.y" to="b.x"/>
    <component name="b"><scart:implementation.task class="rv5ptask:T" period="0.0001"/></component>'''
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(gwrite(tmp_path, {"p.composite": composite(body)})))
    text = str(info.value)
    assert "period '-1': expected seconds > 0" in text
    assert "property 'gain': '-2' refused by its check: must be > 0" in text and "pydantic" not in text
    assert "task 'a' has no port 'y'; ports: x (in)" in text
    assert "period '0.0001': at least 0.001 s" in text


@pytest.mark.parametrize(("attrs", "words"), [
    ('ns="nohost"', "ns 'nohost': expected the name service as \"host:port\""),
    ('ns="h:99999"', "ns 'h:99999'"),
    ('period="1e-9"', "period '1e-9': at least 0.001 s"),
    ('transport="tcp"', "transport='tcp': expected auto, ipc, shm, grpc, ros1, ros2, yarp or zenoh"),
    ('zenoh="tcp/10.0.0.1:7447"', "Zenoh endpoint 'tcp/10.0.0.1:7447' is not loopback"),
    ('zenoh="nowhere"', "expected PROTOCOL/ADDRESS"),
    ('zenoh="unixsock-stream/z.sock" zenoh-ns="a/b"', "'a/b' cannot be a Zenoh key chunk"),
    ('zenoh="unixsock-stream/z.sock" ns="127.0.0.1:1"', "give either ns (a scart name service) or zenoh"),
])
def test_binding_dataflow_ns_and_period_are_checked_at_load(tmp_path: Path, attrs: str, words: str) -> None:
    import scart
    from support.grpc_binding import composite, gwrite
    (tmp_path / "rv5tasks.py").write_text(RV5TASKS)
    body = ('<component name="scaler"><scart:implementation.task class="rv5tasks:Scaler"/></component>'
            '<component name="client"><scart:implementation.python class="rv5tasks:Client"/>'
            f'<service name="Control"><scart:binding.dataflow component="scaler" {attrs}/></service>'
            '<reference name="scaler"><scart:binding.dataflow component="scaler" ports="push=x"/></reference>'
            '</component>')
    with pytest.raises(scart.ScdlError, match=re.escape(words)):
        scart.Runtime.from_file(str(gwrite(tmp_path, {"b.composite": composite(body)})))
