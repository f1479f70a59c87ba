"""``<scart:bridge>``: several ports (local and of another deployer) → converters (callables,
field paths) → one typed output; every trigger mode and missing-input rule; the types
checked at load with file:line; what the bridge saw, through introspection."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from pydantic import BaseModel
from support import wait_until
from support.sca import composite, line_of, write

import scart
from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort
from dataflow.fields import apply_path, parse_path
from dataflow.remote import connect
from scart.bindings.dataflow import DataflowSettings, deployer_of
from scart.bindings.dataflow.bridge import path_type, same_type

MODS = '''
from __future__ import annotations

from pydantic import BaseModel

from dataflow import OutputPort, TaskContext


class Joint(BaseModel):
    position: float
    velocity: float = 0.0


class Arm(BaseModel):
    joints: list[Joint]


class ArmSource(TaskContext):
    status = OutputPort(Arm)


class FlagSource(TaskContext):
    busy = OutputPort(bool)


class CountSource(TaskContext):
    count = OutputPort(int)


class Summary(BaseModel):
    arm: list[float]
    busy: bool


class Triple(BaseModel):
    arm: list[float]
    busy: bool
    count: int


def make(arm: list[float], busy: bool, count: int) -> Triple:
    return Triple(arm=arm, busy=busy, count=count)


def first(arm: Arm) -> float:
    return arm.joints[0].position


def wrong(text: str) -> str:
    return text


def ident(n: str) -> str:
    return n


def half(count: int) -> float:
    if count < 0:
        raise ValueError("negative")
    return count / 2
'''

SOURCES = """
    <component name="armSrc"><scart:implementation.task class="bridgemods:ArmSource"/></component>
    <component name="flagSrc"><scart:implementation.task class="bridgemods:FlagSource"/></component>
"""


def arm(*positions: float) -> object:
    import bridgemods  # the contribution's module, imported by the runtime

    return bridgemods.Arm(joints=[bridgemods.Joint(position=p) for p in positions])


def make(tmp_path: Path, body: str) -> tuple[Path, str]:
    text = composite(body)
    return write(tmp_path, {"b.composite": text, "bridgemods.py": MODS}), text


def refused(tmp_path: Path, body: str) -> tuple[scart.ScdlError, str]:
    path, text = make(tmp_path, body)
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return info.value, text


class Probe:
    """An input port connected to a bridge's output, read with deadlines."""

    def __init__(self, rt: scart.Runtime, bridge: str, port: str) -> None:
        self.task = deployer_of(rt).task(bridge)
        self.port: InputPort[object] = InputPort(self.task.port(port).type, "probe")
        self.task.port(port).connect_to(self.port, ConnPolicy.buffer(1000))
        self.seen: list[object] = []

    def drain(self) -> list[object]:
        for _ in range(1000):
            status, value = self.port.read()
            if status is not FlowStatus.NEW_DATA:
                break
            self.seen.append(value)
        return self.seen

    def wait(self, n: int, message: str = "no output") -> list[object]:
        wait_until(lambda: len(self.drain()) >= n, timeout=10, message=message)
        return self.seen


def stats(task: object) -> dict[str, object]:
    """What ``scart describe`` shows of a task's properties (a bridge's ages and counts)."""
    return {p.name: p.value for p in task.describe().properties}  # type: ignore[attr-defined]


def write_to(rt: scart.Runtime, ref: str, value: object) -> None:
    task, _, port = ref.partition(".")
    deployer_of(rt).task(task).port(port).write(value)


# ---- field paths and types -----------------------------------------------------------------

class Joint(BaseModel):
    position: float


class Arm(BaseModel):
    joints: list[Joint]


def test_field_paths_read_and_type() -> None:
    assert parse_path("arm.joints[*].position", "arm") == ("joints", -1, "position")
    assert parse_path("joints[2].position", "arm") == ("joints", 2, "position")
    assert parse_path("joints[", "arm") is None and parse_path("", "arm") is None
    value = Arm(joints=[Joint(position=1.0), Joint(position=2.5)])
    assert apply_path(value, ("joints", -1, "position")) == [1.0, 2.5]
    assert apply_path(value, ("joints", 1, "position")) == 2.5
    assert path_type(Arm, ("joints", -1, "position")) == (list[float], None)
    assert "has no field 'positon'" in str(path_type(Arm, ("joints", -1, "positon"))[1])
    assert same_type(int, float) and not same_type(float, int) and same_type(list[float], list[float])
    assert not same_type(list[float], list[str]) and not same_type(str, float)


@contextlib.contextmanager
def remote_count(folder: Path, start: bool = True) -> Iterator[tuple[Deployer, str]]:
    """Another deployer (embedding the name service) serving ``remoteCount`` — a task of the
    contribution's ``bridgemods`` module, imported from ``folder`` — and its address."""
    sys.path.insert(0, str(folder))
    try:
        import bridgemods

        other = Deployer()
        other.add(bridgemods.CountSource("remoteCount"))
        if start:
            other.configure_all()
            other.start_all()
        server = other.serve("127.0.0.1:0")
        try:
            yield other, server.address
        finally:
            server.stop()
            other.stop_all()
            other.cleanup_all()
    finally:
        sys.path.remove(str(folder))


# ---- running -------------------------------------------------------------------------------------

def test_three_inputs_local_and_of_another_deployer(tmp_path: Path) -> None:
    path, _ = make(tmp_path, SOURCES + """
        <scart:external task="remoteCount"/>
        <scart:bridge name="statusBridge" trigger="any">
          <scart:input name="arm" from="armSrc.status" field="arm.joints[*].position"/>
          <scart:input name="busy" from="flagSrc.busy" missing="default" default="false"/>
          <scart:input name="count" from="remoteCount.count"/>
          <scart:output name="summary" type="bridgemods:Triple" build="bridgemods:make"/>
        </scart:bridge>
    """)
    with remote_count(tmp_path) as (other, address):
        settings = DataflowSettings(ns=address, serve=True).apply()
        with scart.Runtime.from_file(str(path), settings=settings) as rt:
            probe = Probe(rt, "statusBridge", "summary")
            bridge = deployer_of(rt).task("statusBridge")
            # the remote input connects in the background: wait until a count goes through
            wait_until(lambda: bridge.port("count").connection_count() == 1, timeout=15,
                       message="remote input not connected")
            write_to(rt, "armSrc.status", arm(0.5, 1.5))
            other.task("remoteCount").port("count").write(7)
            seen = probe.wait(1)
            last = seen[-1]
            assert (last.arm, last.busy, last.count) == ([0.5, 1.5], False, 7)  # type: ignore[attr-defined]
            write_to(rt, "flagSrc.busy", True)
            seen = probe.wait(len(seen) + 1)
            assert seen[-1].busy is True  # type: ignore[attr-defined]
            props = stats(bridge)
            assert props["arm.samples"] == 1 and props["count.samples"] == 1 and props["outputs"] >= 2
            assert props["arm.age"] is not None and props["arm.age"] >= 0
            system = connect(address)  # what `scart describe statusBridge` shows
            try:
                remote = {p.name: p.value for p in system.component("statusBridge").describe().properties}
            finally:
                system.close()
            assert remote["arm.age"] >= 0 and remote["count.samples"] == 1


def test_a_remote_source_of_the_wrong_type_fails_the_start_or_the_online_load(tmp_path: Path) -> None:
    path, text = make(tmp_path, """
        <scart:external task="remoteCount"/>
        <scart:bridge name="b">
          <scart:input name="n" from="remoteCount.count" convert="bridgemods:wrong"/><!--HERE-->
          <scart:output name="o" type="string" build="bridgemods:ident"/>
        </scart:bridge>
    """)
    with remote_count(tmp_path, start=False) as (_other, address):
        rt = scart.Runtime.from_file(str(path), settings=DataflowSettings(ns=address).apply())  # offline: loads
        with pytest.raises(scart.ScartError) as info:
            rt.start()
        assert "converter bridgemods:wrong takes str, but remoteCount.count is int" in str(info.value)
        with pytest.raises(scart.ScdlError) as load:
            scart.Runtime.from_file(str(path), settings=DataflowSettings(ns=address).apply(scart.Settings(online=True)))
        assert load.value.codes == ["SCART-B002"] and load.value.errors[0].line == line_of(text, "<!--HERE-->")


@pytest.mark.parametrize("missing, expect", [("hold", [(1.0, True), (2.0, True)]),
                                             ("skip", [(1.0, True)]),
                                             ("default", [(1.0, False), (1.0, True), (2.0, True)])])
def test_missing_input_rules(tmp_path: Path, missing: str, expect: list[tuple[float, bool]]) -> None:
    default = ' default="false"' if missing == "default" else ""
    path, _ = make(tmp_path, SOURCES + f"""
        <scart:bridge name="b" trigger="any">
          <scart:input name="arm" from="armSrc.status" convert="bridgemods:first"/>
          <scart:input name="busy" from="flagSrc.busy" missing="{missing}"{default}/>
          <scart:output name="out" type="bridgemods:Pair" build="bridgemods:pair"/>
        </scart:bridge>
    """)
    (tmp_path / "bridgemods.py").write_text(MODS + '''

class Pair(BaseModel):
    arm: float
    busy: bool


def pair(arm: float, busy: bool) -> Pair:
    return Pair(arm=arm, busy=busy)
''')
    with scart.Runtime.from_file(str(path)) as rt:
        probe = Probe(rt, "b", "out")
        bridge = deployer_of(rt).task("b")

        def samples(name: str) -> int:
            return stats(bridge)[f"{name}.samples"]

        write_to(rt, "armSrc.status", arm(1.0))  # no flag yet
        wait_until(lambda: samples("arm") == 1, timeout=10, message="arm not read")
        write_to(rt, "flagSrc.busy", True)
        wait_until(lambda: samples("busy") == 1, timeout=10, message="flag not read")
        write_to(rt, "armSrc.status", arm(2.0))  # the flag has no new sample now
        wait_until(lambda: samples("arm") == 2, timeout=10, message="second arm sample not read")
        wait_until(lambda: stats(bridge)["outputs"] == len(expect),
                   timeout=10, message="outputs not written")
        assert [(s.arm, s.busy) for s in probe.wait(len(expect))] == expect  # type: ignore[attr-defined]


def test_periodic_trigger_holds_the_last_values(tmp_path: Path) -> None:
    path, _ = make(tmp_path, SOURCES + """
        <scart:bridge name="b" period="0.01">
          <scart:input name="arm" from="armSrc.status" field="joints[*].position"/>
          <scart:input name="busy" from="flagSrc.busy"/>
          <scart:output name="out" type="bridgemods:Summary"/>
        </scart:bridge>
    """)
    with scart.Runtime.from_file(str(path)) as rt:
        probe = Probe(rt, "b", "out")
        write_to(rt, "armSrc.status", arm(3.0))
        write_to(rt, "flagSrc.busy", False)
        seen = probe.wait(5, "the periodic bridge does not repeat its output")
        assert all(s.arm == [3.0] and s.busy is False for s in seen[-3:])  # type: ignore[attr-defined]
        assert deployer_of(rt).task("b").activity.kind == "periodic"


def test_all_trigger_waits_for_every_input_within_the_window(tmp_path: Path) -> None:
    path, _ = make(tmp_path, SOURCES + """
        <scart:bridge name="b" trigger="all" window="5">
          <scart:input name="arm" from="armSrc.status" field="joints[*].position"/>
          <scart:input name="busy" from="flagSrc.busy"/>
          <scart:output name="out" type="bridgemods:Summary"/>
        </scart:bridge>
    """)
    with scart.Runtime.from_file(str(path)) as rt:
        probe = Probe(rt, "b", "out")
        bridge = deployer_of(rt).task("b")
        write_to(rt, "armSrc.status", arm(1.0))
        wait_until(lambda: stats(bridge)["arm.samples"] == 1,
                   timeout=10, message="arm not read")
        assert probe.drain() == []  # one input alone: nothing
        write_to(rt, "flagSrc.busy", True)
        seen = probe.wait(1)
        assert (seen[0].arm, seen[0].busy) == ([1.0], True)  # type: ignore[attr-defined]
        write_to(rt, "flagSrc.busy", False)  # the arm's sample was used: wait for a new one
        wait_until(lambda: stats(bridge)["busy.samples"] == 2,
                   timeout=10, message="flag not read")
        assert len(probe.drain()) == 1
        write_to(rt, "armSrc.status", arm(2.0))
        assert [s.arm for s in probe.wait(2)] == [[1.0], [2.0]]  # type: ignore[attr-defined]


def test_a_converter_that_raises_skips_the_sample_and_counts_it(tmp_path: Path) -> None:
    path, _ = make(tmp_path, """
        <component name="c"><scart:implementation.task class="bridgemods:CountSource"/></component>
        <scart:bridge name="b">
          <scart:input name="n" from="c.count" convert="bridgemods:half"/>
          <scart:output name="out" type="float64" build="bridgemods:half_of"/>
        </scart:bridge>
    """)
    (tmp_path / "bridgemods.py").write_text(MODS + '''

def half_of(n: float) -> float:
    return n
''')
    with scart.Runtime.from_file(str(path)) as rt:
        probe = Probe(rt, "b", "out")
        write_to(rt, "c.count", -1)
        bridge = deployer_of(rt).task("b")
        wait_until(lambda: stats(bridge)["errors"] == 1,
                   timeout=10, message="the refused sample is not counted")
        write_to(rt, "c.count", 4)
        assert probe.wait(1) == [2.0]
        assert bridge.state.name == "RUNNING"


# ---- load-time checks ------------------------------------------------------------------------------

@pytest.mark.parametrize("inputs, output, words", [
    ('<scart:input name="arm" from="armSrc.status" convert="bridgemods:wrong"/>',
     '<scart:output name="o" type="bridgemods:Summary"/>',
     ["input 'arm'", "converter bridgemods:wrong takes str", "armSrc.status is Arm"]),
    ('<scart:input name="arm" from="armSrc.status" field="joints[*].positon"/>',
     '<scart:output name="o" type="bridgemods:Summary"/>', ["Joint has no field 'positon'"]),
    ('<scart:input name="arm" from="armSrc.status" field="joints[*].position"/>'
     '<scart:input name="busy" from="flagSrc.busy"/><scart:input name="count" from="flagSrc.busy"/>',
     '<scart:output name="o" type="bridgemods:Triple" build="bridgemods:make"/>',
     ["builder bridgemods:make parameter 'count' is int, but input 'count' gives bool"]),
    ('<scart:input name="arm" from="armSrc.status" convert="bridgemods:first"/>'
     '<scart:input name="busy" from="flagSrc.busy"/>',
     '<scart:output name="o" type="bridgemods:Summary"/>', ["Summary.arm is list[float], but input 'arm' gives float"]),
    ('<scart:input name="arm" from="armSrc.nope"/>', '<scart:output name="o" type="bridgemods:Summary"/>',
     ["task 'armSrc' has no output port 'nope'; outputs: status"]),
    ('<scart:input name="arm" from="armSrc.status" convert="bridgemods:first"/>',
     '<scart:output name="o" type="float64" build="bridgemods:make"/>',
     ["builder bridgemods:make parameter 'busy' is no input", "returns Triple, but the output is float"]),
    ('<scart:input name="arm" from="armSrc.status" missing="default" default="[1"/>',
     '<scart:output name="o" type="bridgemods:Summary"/>', ["default '[1' is not a Arm"]),
])
def test_a_type_mismatch_is_refused_at_load_naming_both_types(tmp_path: Path, inputs: str, output: str,
                                                              words: list[str]) -> None:
    err, text = refused(tmp_path, SOURCES + f"""
        <scart:bridge name="b" trigger="any"><!--HERE-->
          {inputs}
          {output}
        </scart:bridge>""")
    assert set(err.codes) <= {"SCART-B001", "SCART-B002"}, str(err)
    assert err.errors[0].line == line_of(text, "<!--HERE-->") and err.errors[0].path.endswith("b.composite")
    for word in words:
        assert word in str(err)


@pytest.mark.parametrize("bridge, words", [
    ('<scart:bridge name="b" trigger="periodic"><scart:input name="a" from="armSrc.status"/>'
     '<scart:output name="o" type="float64"/></scart:bridge>', ["needs a period"]),
    ('<scart:bridge name="b"><scart:input name="a" from="armSrc"/><scart:output name="o" type="float64"/>'
     '</scart:bridge>', ["expected TASK.PORT"]),
    ('<scart:bridge name="armSrc"><scart:input name="a" from="flagSrc.busy"/><scart:output name="o" type="bool" '
     'build="bridgemods:first"/></scart:bridge>', ["a component or bridge of that name exists"]),
    ('<scart:bridge name="b" trigger="all"><scart:input name="a" from="flagSrc.busy" missing="hold"/>'
     '<scart:output name="o" type="bool"/></scart:bridge>', ['does not apply to trigger "all"']),
])
def test_a_malformed_bridge_is_refused(tmp_path: Path, bridge: str, words: list[str]) -> None:
    err, _ = refused(tmp_path, SOURCES + bridge)
    for word in words:
        assert word in str(err), str(err)


# ---- review: what a bridge must survive ---------------------------------------------------------

EXTRA = '''

class Flag(BaseModel):
    on: bool


class Plain:
    pass


def wrong_type(n: int):  # no annotation: returns a str where the output is a float
    return "not a float"


def flag_of(busy: bool) -> Flag:
    return Flag(on=busy)


def plain(n: int) -> Plain:
    return Plain()
'''


def test_a_bridge_output_feeds_a_connect_and_bad_samples_are_counted_once(tmp_path: Path) -> None:
    path, _ = make(tmp_path, SOURCES + """
        <component name="c"><scart:implementation.task class="bridgemods:CountSource"/></component>
        <scart:bridge name="b">
          <scart:input name="n" from="c.count" convert="bridgemods:half"/>
          <scart:input name="busy" from="flagSrc.busy" missing="default" default="false"/>
          <scart:output name="out" type="bridgemods:Pair2" build="bridgemods:pair2"/>
        </scart:bridge>
        <component name="sink"><scart:implementation.task class="bridgemods:PairSink"/></component>
        <scart:connect from="b.out" to="sink.inp" policy="buffer:100"/>
    """)
    (tmp_path / "bridgemods.py").write_text(MODS + EXTRA + '''

from dataflow import InputPort


class Pair2(BaseModel):
    n: float
    busy: bool


def pair2(n: float, busy: bool) -> Pair2:
    return Pair2(n=n, busy=busy)


class PairSink(TaskContext):
    inp = InputPort(Pair2)
''')
    with scart.Runtime.from_file(str(path)) as rt:
        bridge = deployer_of(rt).task("b")
        sink_port = deployer_of(rt).task("sink").port("inp")
        assert sink_port.connection_count() == 1  # the connect to a bridge is made in-process
        write_to(rt, "c.count", -1)  # refused by the converter: counted once, never held
        wait_until(lambda: stats(bridge)["errors"] == 1, timeout=10,
                   message="the refusal is not counted")
        for i in range(3):
            write_to(rt, "flagSrc.busy", bool(i % 2))
        write_to(rt, "c.count", 4)
        wait_until(lambda: stats(bridge)["outputs"] >= 1, timeout=10,
                   message="no output after a refused sample")
        assert stats(bridge)["errors"] == 1
        got = wait_until(lambda: sink_port.read()[1], timeout=10, message="the connect from the bridge carries nothing")
        assert got.n == 2.0


def test_a_builder_of_the_wrong_type_is_counted_not_fatal(tmp_path: Path) -> None:
    path, _ = make(tmp_path, """
        <component name="c"><scart:implementation.task class="bridgemods:CountSource"/></component>
        <scart:bridge name="b">
          <scart:input name="n" from="c.count"/>
          <scart:output name="out" type="float64" build="bridgemods:wrong_type"/>
        </scart:bridge>
    """)
    (tmp_path / "bridgemods.py").write_text(MODS + EXTRA)
    with scart.Runtime.from_file(str(path)) as rt:
        bridge = deployer_of(rt).task("b")
        write_to(rt, "c.count", 1)
        wait_until(lambda: stats(bridge)["errors"] == 1, timeout=10,
                   message="the wrong type is not counted")
        assert bridge.state.name == "RUNNING"


@pytest.mark.parametrize("bridge, words", [
    ('<scart:bridge name="b"><scart:input name="n" from="c.count" missing="default" default="1"/>'
     '<scart:output name="o" type="bridgemods:Plain" build="bridgemods:plain"/></scart:bridge>', None),
    ('<scart:bridge name="b"><scart:input name="n" from="c.count" convert="bridgemods:plain" missing="default" '
     'default="1"/><scart:output name="o" type="bridgemods:Plain"/></scart:bridge>', "default '1' is not a Plain"),
    ('<scart:bridge name="b"><scart:input name="a.b" from="c.count"/><scart:output name="o" type="int64"/>'
     '</scart:bridge>', "must be an identifier"),
])
def test_names_and_defaults_are_refused_in_words(tmp_path: Path, bridge: str, words: str | None) -> None:
    body = '<component name="c"><scart:implementation.task class="bridgemods:CountSource"/></component>' + bridge
    path, _ = make(tmp_path, body)
    (tmp_path / "bridgemods.py").write_text(MODS + EXTRA)
    if words is None:  # a plain class output built by a builder: fine
        scart.Runtime.from_file(str(path))
        return
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    assert words in str(info.value)


def test_an_input_named_like_the_first_field_keeps_its_path(tmp_path: Path) -> None:
    path, _ = make(tmp_path, SOURCES + """
        <scart:bridge name="b">
          <scart:input name="joints" from="armSrc.status" field="joints[*].position"/>
          <scart:output name="o" type="bridgemods:Only" build="bridgemods:only"/>
        </scart:bridge>
    """)
    (tmp_path / "bridgemods.py").write_text(MODS + '''

class Only(BaseModel):
    joints: list[float]


def only(joints: list[float]) -> Only:
    return Only(joints=joints)
''')
    with scart.Runtime.from_file(str(path)) as rt:
        probe = Probe(rt, "b", "o")
        write_to(rt, "armSrc.status", arm(1.0, 2.0))
        assert probe.wait(1)[0].joints == [1.0, 2.0]  # type: ignore[attr-defined]


def test_a_composite_with_only_a_bridge_is_served(tmp_path: Path) -> None:
    path, _ = make(tmp_path, """
        <scart:external task="remoteCount"/>
        <scart:bridge name="lonely">
          <scart:input name="n" from="remoteCount.count"/>
          <scart:output name="o" type="int64" build="bridgemods:same"/>
        </scart:bridge>
    """)
    (tmp_path / "bridgemods.py").write_text(MODS + "\n\ndef same(n: int) -> int:\n    return n\n")
    with remote_count(tmp_path, start=False) as (_other, address):
        with scart.Runtime.from_file(str(path), settings=DataflowSettings(ns=address, serve=True).apply()) as rt:
            assert rt.served(), "the bridge's runtime serves nothing"
            bridge = deployer_of(rt).task("lonely")
            wait_until(lambda: bridge.port("n").connection_count() == 1, timeout=15,
                       message="the remote input of a bridge-only composite never connects")
