"""The extension SPI, exercised as an extension author uses it: providers given to a
runtime's own registry, never a module-level table.

Every binding passes the same behaviour tests: the local binding, and a "loopback"
binding that goes through the generic path a remote binding uses (an ``Invocation``
handed to ``ServiceEndpoint.invoke``).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import scart
from scart.spi import (
    AssemblyView,
    Binding,
    BindingProvider,
    CheckContext,
    Element,
    ElementProvider,
    Host,
    InterfaceInfo,
    Invocation,
    Operation,
    Participant,
    Problem,
    ReferenceBinding,
    ServiceBinding,
    ServiceEndpoint,
    Side,
)
from support.sca import composite, py, write

EXT = "urn:test-ext"
LOG: list[str] = []


class LoopReference(ReferenceBinding):
    """Calls the endpoint named by ``uri`` through ``invoke`` (like a remote binding's server side)."""

    def __init__(self, model: Binding | None, interface: InterfaceInfo, host: Host) -> None:
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


class LoopService(ServiceBinding):
    def start(self) -> None:
        LOG.append(f"service start {self.endpoint.component}/{self.endpoint.service}")

    def stop(self) -> None:
        LOG.append("service stop")

    @property
    def address(self) -> str | None:
        return "loop://" + self.endpoint.component


class LoopBinding(BindingProvider):
    name = "binding.loop"

    def check(self, model: Binding, interface: InterfaceInfo | None, side: Side,
              context: CheckContext) -> list[Problem]:
        if side == "reference" and "uri" not in model.attributes:
            return [Problem("TEST-1", "binding.loop needs uri", model.loc.path, model.loc.line)]
        return []

    def service(self, model: Binding, endpoint: ServiceEndpoint, host: Host) -> ServiceBinding:
        return LoopService(model, endpoint, host)

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        return LoopReference(model, interface, host)


def runtime(path: Path, *providers: scart.spi.Extension) -> scart.Runtime:
    """A runtime whose registry has the installed kinds plus ``LoopBinding`` and ``providers``."""
    registry = scart.ExtensionRegistry().with_providers(LoopBinding(), *providers)
    return scart.Runtime.from_file(str(path), extensions=registry)


@pytest.fixture(autouse=True)
def _clear_log() -> Iterator[None]:
    LOG.clear()
    yield


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
    with runtime(path) as rt:
        assert rt.service("B1").run_sync(3) == 6
        assert rt.service("B2").run_sync(4) == 8
        assert rt._managers["B1"].instance().received == ["sync 3"]
        assert rt._managers["B2"].instance().received == ["sync 4"]


def test_oneway_and_callback_from_worker(tmp_path: Path, kind: str) -> None:
    path = write(tmp_path, {"c.composite": composite(f"""
        <component name="W">{py("WorkerImpl")}</component>
        <component name="B">{py("Boss")}{wired(kind, "B", "worker", "W/Worker")}</component>
    """)})
    with runtime(path) as rt:
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
    with runtime(path) as rt:
        assert rt.service("S").call("x") == "Yo, x"


def test_service_binding_lifecycle_and_address(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite(f"""
        <service name="Front" promote="A"><e:binding.loop xmlns:e="{EXT}"/></service>
        <component name="A">{py("Tracker")}
          <service name="Tracker"><e:binding.loop xmlns:e="{EXT}"/></service>
        </component>
    """)})
    events = None
    with runtime(path) as rt:
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
        runtime(write(tmp_path, {"b.composite": text}))
    assert info.value.codes == ["SCART-C002", "TEST-1"]
    assert "binding <binding.ws> cannot be used on a reference" in str(info.value)


class _Connect(ElementProvider):
    """A recording stand-in for ``scart:connect``, given to one runtime's registry only."""

    name = "connect"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        return [Problem("TEST-2", "bad connect", el.loc.path, el.loc.line)
                for _, el in elements if "from" not in el.attributes]

    def activate(self, host: Host) -> Participant:
        elements = host.assembly.elements_of(self.name)

        class P(Participant):
            def start(self) -> None:
                LOG.append(f"connect start {[(p, e.attributes['from']) for p, e in elements]}")

            def stop(self) -> None:
                LOG.append("connect stop")
        return P()


def test_composite_extension_element(tmp_path: Path) -> None:
    path = write(tmp_path, {"x.composite": composite(f"""
        <component name="A">{py("Tracker")}</component>
        <scart:connect from="a.out" to="b.in" policy="buffer:8"/>
    """)})
    with runtime(path, _Connect()):
        assert LOG == ["connect start [('', 'a.out')]"]
        assert comps().EVENTS[-1] == "init A"
    assert LOG[-1] == "connect stop"
    bad = write(tmp_path, {"y.composite": composite('<scart:connect to="b.in"/>')})
    with pytest.raises(scart.ScdlError) as info:
        runtime(bad, _Connect())
    assert info.value.codes == ["TEST-2"] and info.value.line == 3


def test_the_registry_is_the_runtimes_own(tmp_path: Path) -> None:
    """A provider given to one runtime changes no other runtime: the next one uses the
    installed ``scart:connect`` again (whose check finds no task ``a`` here)."""
    path = write(tmp_path, {"x.composite": composite(f"""
        <component name="A">{py("Tracker")}</component>
        <scart:connect from="a.out" to="b.in"/>
    """)})
    with runtime(path, _Connect()):
        assert LOG == ["connect start [('', 'a.out')]"]
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    assert info.value.codes == ["SCART-T002"]


def test_unregistered_extension_element_is_refused(tmp_path: Path) -> None:
    path = write(tmp_path, {"x.composite": composite('<scart:connect from="a.out" to="b.in"/>')})
    without = scart.ExtensionRegistry(
        [p for n in ("implementation.python", "binding.sca") if (p := scart.ExtensionRegistry().get(n))],
        discover=False)
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path), extensions=without)
    assert info.value.codes == ["SCART-X004"]


def test_a_broken_extension_is_a_problem_naming_it(tmp_path: Path) -> None:
    """An entry point that cannot be imported is reported where its element is used."""
    from importlib.metadata import EntryPoint

    registry = scart.ExtensionRegistry()
    registry._found["binding.broken"] = EntryPoint("binding.broken", "no_such_module_xyz:Nope", "scart.extensions")
    path = write(tmp_path, {"b.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one"><e:binding.broken xmlns:e="{EXT}"/></reference>
        </component>""")})
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path), extensions=registry)
    assert info.value.codes == ["SCART-C002"]
    assert "extension 'binding.broken' (entry point 'no_such_module_xyz:Nope'" in str(info.value)
    assert "ModuleNotFoundError" in str(info.value)


def test_shared_objects_and_stop_hooks(tmp_path: Path) -> None:
    path = write(tmp_path, {"x.composite": composite(f'<component name="A">{py("Tracker")}</component>')})
    with runtime(path) as rt:
        made = rt.shared("deployer", lambda: ["the deployer"])
        assert rt.shared("deployer", lambda: ["another"]) is made
        rt.add_stop_hook(lambda: LOG.append("hook 1"))
        rt.add_stop_hook(lambda: LOG.append(f"hook 2 after {comps().EVENTS[-1]}"))
    assert LOG == ["hook 2 after destroy A", "hook 1"]


class _Thing(ElementProvider):
    """A third-party composite element in its own namespace (no XSD of scart's)."""

    name = "thing"

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        return [Problem("THING-1", "a thing needs a size", el.loc.path, el.loc.line)
                for _, el in elements if "size" not in el.attributes]

    def activate(self, host: Host) -> Participant:
        sizes = [el.attributes["size"] for _, el in host.assembly.elements_of(self.name)]

        class P(Participant):
            def start(self) -> None:
                LOG.append(f"things {sizes}")

            def stop(self) -> None:
                LOG.append("things stop")
        return P()


def test_a_third_party_element_in_its_own_namespace(tmp_path: Path) -> None:
    path = write(tmp_path, {"t.composite": composite(f"""
        <component name="A">{py("Tracker")}</component>
        <t:thing xmlns:t="urn:things" size="3"/>
    """)})
    with runtime(path, _Thing()):
        assert LOG == ["things ['3']"]
    assert LOG[-1] == "things stop"
    bad = write(tmp_path, {"b.composite": composite('<t:thing xmlns:t="urn:things"/>')})
    with pytest.raises(scart.ScdlError) as info:
        runtime(bad, _Thing())
    assert info.value.codes == ["THING-1"]
    with pytest.raises(scart.ScdlError) as info:  # without the provider: an unknown element
        scart.Runtime.from_file(str(bad))
    assert info.value.codes == ["SCART-X004"]


class _Exploding(BindingProvider):
    name = "binding.exploding"

    def reference(self, model: Binding, interface: InterfaceInfo, host: Host) -> ReferenceBinding:
        raise RuntimeError("no such transport here")


def test_an_extension_failing_at_start_is_a_scart_error_naming_it(tmp_path: Path) -> None:
    path = write(tmp_path, {"e.composite": composite(f"""
        <component name="S">{py("Single")}
          <reference name="one"><e:binding.exploding xmlns:e="{EXT}"/></reference>
        </component>""")})
    rt = runtime(path, _Exploding())
    with pytest.raises(scart.ScartError, match="S/one: binding.exploding: RuntimeError: no such transport here"):
        rt.start()
    assert rt.state is scart.RuntimeState.STOPPED


def test_without_installed_entry_points_the_core_kinds_still_load(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture) -> None:
    """From a source tree (or stale metadata) plain composites still run, and the log says
    how to get the extensions back."""
    import scart.extensions

    monkeypatch.setattr(scart.extensions, "entry_points", lambda group: [])
    registry = scart.ExtensionRegistry()
    assert registry.names() == ["binding.sca", "implementation.python"]
    assert "install scart (pip install -e .)" in caplog.text
    path = write(tmp_path, {"c.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}<reference name="one" target="A"/></component>""")})
    with scart.Runtime.from_file(str(path), extensions=registry) as rt:
        assert rt.service("S").call("x") == "Hello, x"


def test_without_installed_entry_points_the_core_verbs_remain(monkeypatch: pytest.MonkeyPatch,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    import scart.cli

    monkeypatch.setattr(scart.cli, "entry_points", lambda group: [])
    parser = scart.cli.build_parser()
    assert "install scart" in capsys.readouterr().err
    assert parser.parse_args(["validate", "x.composite"]).command == "validate"
