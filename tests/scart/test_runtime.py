"""The runtime: injection, multiplicity, nesting, include, callbacks, one-way, scopes, lifecycle."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

import pytest
from pydantic import BaseModel, ConfigDict

import scart
from scart.bindings.dataflow import DataflowSettings
from support import ROOT
from support.sca import OSOA, composite, py, write

CALCULATOR = ROOT / "composites" / "calculator" / "calculator.composite"


def comps():
    return sys.modules["comps"]


def test_calculator_sample() -> None:
    with scart.Runtime.from_file(str(CALCULATOR)) as rt:
        calc = rt.service("CalculatorServiceComponent")
        assert (calc.add(3, 2), calc.subtract(3, 2), calc.multiply(3, 2), calc.divide(3, 2)) == (5, 1, 6, 1.5)
        assert rt.service("CalculatorService").add(1, 1) == 2
        assert rt.service("CalculatorServiceComponent/CalculatorService").divide(1, 4) == 0.25


def test_property_kinds(tmp_path: Path) -> None:
    (tmp_path / "config.json").write_text('{"a": 1, "b": [true]}', encoding="utf-8")
    path = write(tmp_path, {"p.composite": composite(f"""
        <property name="shared" type="xsd:string">from-composite</property>
        <component name="P">
          {py("Props")}
          <property name="text" source="$shared"/>
          <property name="number" value="42"/>
          <property name="ratio">2.5</property>
          <property name="flag"><value>1</value></property>
          <property name="many"><value>1</value><value>2</value><value>3</value></property>
          <property name="config" file="config.json"/>
          <property name="point">{{"x": 1, "y": 2}}</property>
        </component>
        <component name="D">{py("Props")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        v = rt.service("P").values()
        assert v["text"] == "from-composite"
        assert v["number"] == 42 and v["ratio"] == 2.5 and v["flag"] is True
        assert v["many"] == [1, 2, 3] and v["config"] == {"a": 1, "b": [True]}
        assert v["point"] == comps().Point(x=1, y=2)
        d = rt.service("D")
        assert d.values()["text"] == "default" and d.values()["flag"] is False
        # a mutable default is copied per instance
        assert d.add_name("x") == ["x"]
        assert rt.service("P").values()["names"] == []


def test_overrides_like_set(tmp_path: Path) -> None:
    path = write(tmp_path, {"o.composite": composite(f"""
        <component name="G">{py("GreeterImpl")}<property name="greeting">Hello</property></component>
    """)})
    with scart.Runtime.from_file(str(path), overrides={"G.greeting": "Salut"}) as rt:
        assert rt.service("G").greet("x") == "Salut, x"


def test_reference_multiplicities(tmp_path: Path) -> None:
    path = write(tmp_path, {"m.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">A</property></component>
        <component name="B">{py("GreeterImpl")}<property name="greeting">B</property></component>
        <component name="C">
          {py("Client")}
          <reference name="one" target="A"/>
          <reference name="some" target="B/Greeter A"/>
        </component>
        <component name="Empty">
          {py("Client")}
          <reference name="one" target="A"/>
        </component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("C").report() == {"one": "A, one", "maybe": None, "some": ["B, some", "A, some"]}
        assert rt.service("Empty").report()["some"] == []


def test_wire_element_and_replace(tmp_path: Path) -> None:
    path = write(tmp_path, {"w.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">A</property></component>
        <component name="B">{py("GreeterImpl")}<property name="greeting">B</property></component>
        <component name="S1">{py("Single")}<reference name="one" target="A"/></component>
        <component name="S2">{py("Single")}</component>
        <wire source="S1/one" target="B" replace="true"/>
        <wire source="S2/one" target="A/Greeter"/>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("S1").call("x") == "B, x"
        assert rt.service("S2").call("x") == "A, x"


def test_autowire(tmp_path: Path) -> None:
    path = write(tmp_path, {"a.composite": composite(f"""
        <component name="F">{py("FarewellImpl")}</component>
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}</component>
    """, extra=' autowire="true"')})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("S").call("x") == "Hello, x"


def test_promotion_through_two_levels_of_nesting(tmp_path: Path) -> None:
    inner = composite(f"""
        <service name="Greeter" promote="G"/>
        <reference name="upstream" promote="S/one"/>
        <property name="greeting" type="xsd:string">inner-default</property>
        <component name="G">{py("GreeterImpl")}<property name="greeting" source="$greeting"/></component>
        <component name="S">{py("Single")}</component>
    """, name="Inner")
    mid = composite("""
        <service name="Greeter" promote="In/Greeter"/>
        <reference name="upstream" promote="In/upstream"/>
        <property name="greeting" type="xsd:string"/>
        <component name="In">
          <implementation.composite name="t:Inner"/>
          <property name="greeting" source="$greeting"/>
        </component>
    """, name="Mid")
    outer = composite(f"""
        <service name="Front" promote="M/Greeter"/>
        <component name="M">
          <implementation.composite name="t:Mid"/>
          <property name="greeting">Howdy</property>
          <reference name="upstream" target="Top"/>
        </component>
        <component name="Top">{py("GreeterImpl")}<property name="greeting">Top</property></component>
    """, name="Outer")
    path = write(tmp_path, {"outer.composite": outer, "mid.composite": mid, "inner.composite": inner})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("Front").greet("x") == "Howdy, x"
        assert rt.service("M/Greeter").greet("y") == "Howdy, y"
        assert rt.service("M").greet("z") == "Howdy, z"
        assert rt.service("M/In/S").call("w") == "Top, w"
        assert set(rt.assembly.nodes) == {"M/In/G", "M/In/S", "Top"}


def test_include_merges_components(tmp_path: Path) -> None:
    parts = composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">Included</property></component>
    """, name="Parts")
    main = composite(f"""
        <include name="t:Parts"/>
        <component name="S">{py("Single")}<reference name="one" target="A"/></component>
    """, name="Main")
    path = write(tmp_path, {"main.composite": main, "parts.composite": parts})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("S").call("x") == "Included, x"


def test_sca10_osoa_namespace(tmp_path: Path) -> None:
    path = write(tmp_path, {"old.composite": composite(f"""
        <component name="A">{py("GreeterImpl")}<property name="greeting">Old</property></component>
    """, ns=OSOA)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("A").greet("x") == "Old, x"


def _bosses(tmp_path: Path) -> Path:
    return write(tmp_path, {"cb.composite": composite(f"""
        <component name="W">{py("WorkerImpl")}</component>
        <component name="B1">{py("Boss")}<reference name="worker" target="W"/></component>
        <component name="B2">{py("Boss")}<reference name="worker" target="W"/></component>
    """)})


def test_callback_on_synchronous_call_reaches_the_caller(tmp_path: Path) -> None:
    with scart.Runtime.from_file(str(_bosses(tmp_path))) as rt:
        assert rt.service("B1").run_sync(2) == 4
        assert rt.service("B2").run_sync(5) == 10
        b1 = rt._managers["B1"].instance()
        b2 = rt._managers["B2"].instance()
        assert b1.received == ["sync 2"] and b2.received == ["sync 5"]


def test_callback_without_caller_is_an_error(tmp_path: Path) -> None:
    with scart.Runtime.from_file(str(_bosses(tmp_path))) as rt:
        with pytest.raises(scart.NoCallbackError):
            rt.service("W").work(1)


def test_oneway_returns_before_callee_finishes_and_calls_back(tmp_path: Path) -> None:
    path = _bosses(tmp_path)
    with scart.Runtime.from_file(str(path)) as rt:
        gate = comps().GATE
        gate.clear()
        try:
            assert rt.service("B2").run_async(7) is None  # returns while the callee waits on GATE
            b2 = rt._managers["B2"].instance()
            b1 = rt._managers["B1"].instance()
            assert b2.received == []
        finally:
            gate.set()
        msgs = b2.wait_message(10)
        assert len(msgs) == 1 and msgs[0].startswith("async 7 on scart-oneway")
        assert b1.received == []


def test_oneway_on_service_proxy(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite(f"<component name='S'>{py('Slow')}</component>")})
    rt = scart.Runtime.from_file(str(path))
    gate = comps().GATE
    gate.clear()
    with rt:
        try:
            assert rt.service("S").fire(1) is None
            assert "fired 1" not in comps().EVENTS
        finally:
            gate.set()
    assert "fired 1" in comps().EVENTS  # stop drains in-flight one-way calls


def test_init_in_dependency_order_destroy_in_reverse(tmp_path: Path) -> None:
    path = write(tmp_path, {"l.composite": composite(f"""
        <component name="A">{py("Tracker")}<reference name="next" target="B"/></component>
        <component name="B">{py("Tracker")}<reference name="next" target="C"/></component>
        <component name="C">{py("Tracker")}</component>
        <component name="L">{py("LazyTracker")}</component>
    """)})
    rt = scart.Runtime.from_file(str(path))
    events = comps().EVENTS
    events.clear()
    with rt:
        assert events == ["init C", "init B", "init A"]
        assert rt.service("L").greet("x") == "L"
        assert events[-1] == "init L"
    assert events[4:] == ["destroy L", "destroy A", "destroy B", "destroy C"]


def test_stateless_vs_composite_scope(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite(f"""
        <component name="S">{py("StatelessCounter")}</component>
        <component name="C">{py("CompositeCounter")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert [rt.service("S").hit() for _ in range(3)] == [1, 1, 1]
        assert [rt.service("C").hit() for _ in range(3)] == [1, 2, 3]


def test_remotable_interfaces_pass_by_value(tmp_path: Path) -> None:
    path = write(tmp_path, {"v.composite": composite(f"""
        <component name="R">{py("RemoteMutatorImpl")}</component>
        <component name="L">{py("LocalMutatorImpl")}</component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        mine = ["caller"]
        assert rt.service("R").mutate(mine) == ["caller", "callee"]
        assert mine == ["caller"]
        assert rt.service("L").mutate(mine) is mine and mine == ["caller", "callee"]


def test_service_lookup_errors_and_states(tmp_path: Path) -> None:
    path = write(tmp_path, {"t.composite": composite(f"<component name='T'>{py('TwoFaced')}</component>")})
    rt = scart.Runtime.from_file(str(path))
    with pytest.raises(scart.RuntimeStateError):
        rt.service("T/Greeter")
    with rt:
        assert rt.service("T/Farewell").bye("x") == "bye x"
        with pytest.raises(scart.ServiceNotFoundError, match="T/Greeter"):
            rt.service("T")
    rt.stop()  # idempotent
    with pytest.raises(scart.RuntimeStateError):
        rt.start()


def test_stop_from_a_oneway_worker_does_not_deadlock(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite(f"<component name='S'>{py('Slow')}</component>")})
    rt = scart.Runtime.from_file(str(path))
    rt.start()
    done = threading.Event()
    rt.submit(lambda: (rt.stop(), done.set()))
    assert done.wait(10)
    assert rt.state is scart.RuntimeState.STOPPED
    rt._pool.join(10)


def test_failing_init_is_a_scart_error_and_stops_what_started(tmp_path: Path) -> None:
    (tmp_path / "boom.py").write_text(
        "import scart\n\nclass Boom:\n    @scart.init\n    def start(self) -> None:\n"
        "        raise OSError('device missing')\n\n    def x(self) -> None: ...\n", encoding="utf-8")
    path = write(tmp_path, {"b.composite": composite(f"""
        <component name="T">{py("Tracker")}</component>
        <component name="B"><scart:implementation.python class="boom:Boom"/></component>
    """)})
    rt = scart.Runtime.from_file(str(path))
    comps().EVENTS.clear()
    with pytest.raises(scart.ScartError, match="starting component B failed: OSError: device missing"):
        rt.start()
    assert comps().EVENTS == ["init T", "destroy T"]
    assert rt.state is scart.RuntimeState.STOPPED


def test_stop_called_by_a_worker_while_the_main_thread_stops(tmp_path: Path) -> None:
    path = write(tmp_path, {"s.composite": composite(f"<component name='S'>{py('Slow')}</component>")})
    rt = scart.Runtime.from_file(str(path))
    rt.start()
    gate = comps().GATE
    gate.clear()
    entered = threading.Event()

    def in_worker() -> None:
        entered.set()
        gate.wait(10)
        rt.stop()  # main is inside stop(), draining the pool: must not deadlock

    rt.submit(in_worker)
    assert entered.wait(10)
    stopper = threading.Thread(target=rt.stop)
    stopper.start()
    gate.set()
    stopper.join(10)
    assert not stopper.is_alive()
    assert rt.state is scart.RuntimeState.STOPPED


def test_many_valued_composite_property_flows_to_a_list(tmp_path: Path) -> None:
    path = write(tmp_path, {"m.composite": composite(f"""
        <property name="ids" type="xsd:int" many="true"><value>4</value><value>5</value></property>
        <component name="P">{py("Props")}<property name="many" source="$ids"/></component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("P").values()["many"] == [4, 5]


def test_oneway_callback_runs_on_a_worker(tmp_path: Path) -> None:
    path = write(tmp_path, {"j.composite": composite(f"""
        <component name="J">{py("JobImpl")}</component>
        <component name="C">{py("JobClient")}<reference name="job" target="J"/></component>
    """)})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("C").go() == "started"
        client = rt._managers["C"].instance()
        assert client.got.wait(10)
        assert len(client.seen) == 1 and client.seen[0].startswith("50 on scart-oneway")


def test_set_override_of_a_nested_component(tmp_path: Path) -> None:
    inner = composite(f"""
        <service name="Greeter" promote="G"/>
        <component name="G">{py("GreeterImpl")}</component>
    """, name="Inner")
    outer = composite('<component name="M"><implementation.composite name="t:Inner"/></component>', name="Outer")
    path = write(tmp_path, {"outer.composite": outer, "inner.composite": inner})
    with scart.Runtime.from_file(str(path), overrides={"M/G.greeting": "Ahoy"}) as rt:
        assert rt.service("M").greet("x") == "Ahoy, x"


def test_remotable_oneway_copies_arguments_once_before_the_caller_returns() -> None:
    """A by-value one-way call: the callee gets a private copy taken at submit time (the
    caller may mutate its value after return), and only that one copy is made."""
    import copy as copy_module
    from unittest import mock

    from scart.api import Operation
    from scart.local import wrap_operation

    queued: list[tuple] = []
    seen: list[list[str]] = []
    wrapped = wrap_operation(seen.append, Operation("put", oneway=True), callback=None, by_value=True,
                             submit=lambda fn, *a, **k: queued.append((fn, a, k)))
    mine = ["caller"]
    with mock.patch("scart.local.copy.deepcopy", wraps=copy_module.deepcopy) as deepcopy:
        assert wrapped(mine) is None
        mine.append("after return")
        fn, args, kwargs = queued.pop()
        fn(*args, **kwargs)
    assert seen == [["caller"]] and seen[0] is not mine
    assert deepcopy.call_count == 1


def test_components_read_the_runtimes_settings_through_their_context(tmp_path: Path) -> None:
    """Settings travel in an object given to the runtime, never a module global: two
    runtimes in one process each see their own."""
    path = write(tmp_path, {"c.composite": composite(f'<component name="T">{py("Tracker")}</component>')})
    with scart.Runtime.from_file(str(path), settings=scart.Settings(timeout=1.0)) as one, \
            scart.Runtime.from_file(str(path), settings=scart.Settings(timeout=0.5)) as two:
        assert one._managers["T"].instance().ctx.settings.timeout == 1.0
        assert two._managers["T"].instance().ctx.settings == two.settings
        assert two.settings.timeout == 0.5


@pytest.mark.parametrize("bad", [{"timeout": float("nan")}, {"timeout": -1.0}])
def test_settings_refuse_bad_values(bad: dict) -> None:
    with pytest.raises(ValueError):
        scart.Settings(**bad)


def test_settings_hold_only_what_the_core_reads() -> None:
    """An extension's settings are its own (``extensions=``); the core's fields are few, and
    a data-flow field given to the core is refused, saying where it goes."""
    assert set(scart.Settings.model_fields) == {"online", "timeout", "security", "extensions"}
    with pytest.raises(ValueError, match=r"ns: not a setting of the SCA core .* extensions=\(\.\.\.\)"):
        scart.Settings(ns="127.0.0.1:1")


class _Own(BaseModel):
    model_config = ConfigDict(frozen=True)
    level: int = 1


def test_an_extensions_settings_travel_in_the_core_settings() -> None:
    settings = scart.Settings().with_extension(_Own(level=3))
    assert settings.extension(_Own).level == 3 and scart.Settings().extension(_Own) == _Own()
    assert settings.with_extension(_Own(level=4)).extension(_Own).level == 4  # one value per type
    with pytest.raises(ValueError, match="at most one value of each type"):
        scart.Settings(extensions=(_Own(), _Own(level=2)))


def test_settings_from_env_reads_each_extensions_own() -> None:
    registry = scart.ExtensionRegistry()
    assert registry.settings_from_env({"SCART_NS": " 10.0.0.1:7850 "}).extension(DataflowSettings).ns == "10.0.0.1:7850"
    assert registry.settings_from_env({}).extension(DataflowSettings).ns_address == "127.0.0.1:7850"
    with pytest.raises(scart.ScartError, match=r"\$SCART_NS: name service 'x': expected"):
        registry.settings_from_env({"SCART_NS": "x"})

