"""The binding interface and the extension points, exercised the way issue 5 will use them.

Every binding passes the same behaviour tests: the local binding, and a "loopback"
binding that goes through the generic path a remote binding uses (an ``Invocation``
handed to ``ServiceEndpoint.invoke``).
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import scart
from scart.api import InterfaceInfo, Operation
from scart.bindings.base import (
    BINDING_KINDS,
    Invocation,
    ReferenceBinding,
    ServiceBinding,
    register_binding,
)
from scart.errors import Problem
from scart.extensions import COMPOSITE_EXTENSIONS, register_composite_extension
from scart.model import Binding
from scart.scdl import EXTENSION_ELEMENTS
from test_sca_support import composite, py, write

EXT = "urn:test-ext"
LOG: list[str] = []


class LoopReference(ReferenceBinding):
    """Calls the endpoint named by ``uri`` through ``invoke`` (like a remote binding's server side)."""

    def __init__(self, model: Binding | None, interface: InterfaceInfo, host: Any) -> None:
        super().__init__(model, interface, host)
        assert model is not None
        self.target = host.endpoint(model.attributes["uri"])
        self.interface = self.target.interface

    def invoker(self, operation: Operation, callback: object | None) -> Callable[..., Any]:
        target, name = self.target, operation.name
        return lambda *args, **kwargs: target.invoke(Invocation(name, args, kwargs, callback))

    def start(self) -> None:
        LOG.append("reference start")

    def stop(self) -> None:
        LOG.append("reference stop")

    @classmethod
    def check(cls, model: Binding, interface: InterfaceInfo | None, contribution: object) -> list[Problem]:
        if "uri" not in model.attributes:
            return [Problem("TEST-1", "binding.loop needs uri", model.loc.path, model.loc.line)]
        return []


class LoopService(ServiceBinding):
    def start(self) -> None:
        LOG.append(f"service start {self.endpoint.component}/{self.endpoint.service}")

    def stop(self) -> None:
        LOG.append("service stop")

    @property
    def address(self) -> str | None:
        return "loop://" + self.endpoint.component


@pytest.fixture(autouse=True)
def _registered() -> Iterator[None]:
    register_binding("binding.loop", service=LoopService, reference=LoopReference)
    LOG.clear()
    yield
    BINDING_KINDS.pop("binding.loop", None)


def comps():
    return sys.modules["comps"]


def wired(kind: str, source: str, ref: str, target: str) -> str:
    if kind == "local":
        return f'<reference name="{ref}" target="{target}"/>'
    return f'<reference name="{ref}"><e:binding.loop xmlns:e="{EXT}" uri="{target}"/></reference>'


@pytest.fixture(params=["local", "loop"])
def kind(request: pytest.FixtureRequest) -> str:
    return request.param


def test_sync_call_and_callback(tmp_path: Path, kind: str) -> None:
    path = write(tmp_path, {"c.composite": composite(f"""
        <component name="W">{py("WorkerImpl")}</component>
        <component name="B1">{py("Boss")}{wired(kind, "B1", "worker", "W/Worker")}</component>
        <component name="B2">{py("Boss")}{wired(kind, "B2", "worker", "W/Worker")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("B1").run_sync(3) == 6
        assert rt.service("B2").run_sync(4) == 8
        assert rt._managers["B1"].instance().received == ["sync 3"]
        assert rt._managers["B2"].instance().received == ["sync 4"]


def test_oneway_and_callback_from_worker(tmp_path: Path, kind: str) -> None:
    path = write(tmp_path, {"c.composite": composite(f"""
        <component name="W">{py("WorkerImpl")}</component>
        <component name="B">{py("Boss")}{wired(kind, "B", "worker", "W/Worker")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        gate = comps().GATE
        gate.clear()
        try:
            assert rt.service("B").run_async(1) is None
            boss = rt._managers["B"].instance()
            assert boss.received == []
        finally:
            gate.set()
        assert boss.wait_message(10)[0].startswith("async 1 on scart-oneway")


def test_calculator_style_chain(tmp_path: Path, kind: str) -> None:
    path = write(tmp_path, {"c.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">Yo</property></component>
        <component name="S">{py("Single")}{wired(kind, "S", "one", "A/Greeter")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("S").call("x") == "Yo, x"


def test_service_binding_lifecycle_and_address(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite(f"""
        <service name="Front" promote="A"><e:binding.loop xmlns:e="{EXT}"/></service>
        <component name="A">{py("Tracker")}
          <service name="Tracker"><e:binding.loop xmlns:e="{EXT}"/></service>
        </component>
    """)})
    events = None
    with scart.Runtime.from_file(str(path)) as rt:
        events = comps().EVENTS
        assert LOG == ["service start A/Tracker", "service start A/Tracker"]
        assert set(rt.addresses().values()) == {"loop://A"}
        assert events[-1] == "init A"
        LOG.clear()
        events.clear()
    assert LOG == ["service stop", "service stop"] and events == ["destroy A"]


def test_unknown_and_misconfigured_bindings_are_static_errors(tmp_path: Path) -> None:
    text = composite(f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one"><binding.ws uri="http://x"/></reference>
        </component>
        <component name="T">{py("Single")}
          <reference name="one"><e:binding.loop xmlns:e="{EXT}"/></reference>
        </component>
    """)
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(write(tmp_path, {"b.composite": text})))
    assert info.value.codes == ["SCART-C002", "TEST-1"]
    assert "binding <binding.ws> cannot be used on a reference" in str(info.value)


class _Connect:
    """A stand-in for issue 5's ``scart:connect`` handler."""

    def check(self, elements: list, assembly: Any) -> list[Problem]:
        return [Problem("TEST-2", "bad connect", el.loc.path, el.loc.line)
                for _, el in elements if "from" not in el.attributes]

    def participant(self, elements: list, runtime: Any) -> Any:
        class P:
            def start(self) -> None:
                LOG.append(f"connect start {[(p, e.attributes['from']) for p, e in elements]}")

            def stop(self) -> None:
                LOG.append("connect stop")
        return P()


@pytest.fixture
def connect_registered() -> Iterator[None]:
    """Stand a recording handler in for ``scart:connect``; put the real one back after."""
    with _connect_handler(_Connect()):
        yield


@contextlib.contextmanager
def _connect_handler(handler: object | None) -> Iterator[None]:
    """Swap the ``scart:connect`` handler (``None``: unregistered) and restore it after."""
    tables = (COMPOSITE_EXTENSIONS, EXTENSION_ELEMENTS)
    saved = [table.pop("connect", None) for table in tables]
    if handler is not None:
        register_composite_extension("connect", handler)
    try:
        yield
    finally:
        for table, entry in zip(tables, saved):
            table.pop("connect", None)
            if entry is not None:
                table["connect"] = entry


def test_composite_extension_element(tmp_path: Path, connect_registered: None) -> None:
    path = write(tmp_path, {"x.composite": composite(f"""
        <component name="A">{py("Tracker")}</component>
        <scart:connect from="a.out" to="b.in" policy="buffer:8"/>
    """)})
    with scart.Runtime.from_file(str(path)):
        assert LOG == ["connect start [('', 'a.out')]"]
        assert comps().EVENTS[-1] == "init A"
    assert LOG[-1] == "connect stop"
    bad = write(tmp_path, {"y.composite": composite('<scart:connect to="b.in"/>')})
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(bad))
    assert info.value.codes == ["TEST-2"] and info.value.line == 3


def test_unregistered_extension_element_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, {"x.composite": composite('<scart:connect from="a.out" to="b.in"/>')})
    with _connect_handler(None), pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    assert info.value.codes == ["SCART-X004"]


def test_shared_objects_and_stop_hooks(tmp_path: Path) -> None:
    path = write(tmp_path, {"x.composite": composite(f'<component name="A">{py("Tracker")}</component>')})
    with scart.Runtime.from_file(str(path)) as rt:
        made = rt.shared("deployer", lambda: ["the deployer"])
        assert rt.shared("deployer", lambda: ["another"]) is made
        rt.add_stop_hook(lambda: LOG.append("hook 1"))
        rt.add_stop_hook(lambda: LOG.append(f"hook 2 after {comps().EVENTS[-1]}"))
    assert LOG == ["hook 2 after destroy A", "hook 1"]
