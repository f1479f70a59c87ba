"""Remapping at launch (``--remap FROM=TO``, ``DataflowSettings(remap=...)``): task and port names
change wherever the composite names them — the task itself, ``scart:connect``, bridge
inputs, ``binding.dataflow`` — with no edit to the composite; ``scart graph`` shows them."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import scart
from scart.bindings.dataflow import DataflowSettings, Remap, deployer_of
from support import wait_until
from support.sca import composite, write

TASKS = '''
from __future__ import annotations

from typing import Protocol

import scart
from dataflow import FlowStatus, InputPort, OutputPort, TaskContext


class Source(TaskContext):
    out = OutputPort(float)


class Sink(TaskContext):
    inp = InputPort(float, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[float] = []

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, v = self.inp.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.got.append(v)


class Feeding(Protocol):
    def inp(self, value: float) -> None: ...


@scart.component
class Feeder:
    sink: Feeding = scart.reference()

    def feed(self, value: float) -> None:
        self.sink.inp(value)


def twice(value: float) -> float:
    return 2 * value
'''

BODY = """
    <component name="src"><scart:implementation.task class="tasks:Source"/></component>
    <component name="sink"><scart:implementation.task class="tasks:Sink"/></component>
    <component name="sink2"><scart:implementation.task class="tasks:Sink"/></component>
    <scart:connect from="src.out" to="sink.inp" name="feed"/>
    <scart:bridge name="doubler">
      <scart:input name="value" from="src.out" convert="tasks:twice"/>
      <scart:output name="out" type="float64" build="tasks:twice"/>
    </scart:bridge>
    <scart:connect from="doubler.out" to="sink2.inp"/>
    <component name="feeder"><scart:implementation.python class="tasks:Feeder"/>
      <reference name="sink"><scart:binding.dataflow component="sink"/></reference></component>
"""


def test_rules_parse_and_apply() -> None:
    remap = Remap.parse(["youBotDriver=left/youBotDriver", "jointStatus:=joint_states",
                               "arm.out=position", "__ns=robot1"])
    assert remap.component("youBotDriver") == "left/youBotDriver"
    assert remap.component("arm") == "robot1/arm"  # the namespace, for names not renamed otherwise
    assert remap.port("youBotDriver", "jointStatus") == "joint_states"
    assert remap.port("arm", "out") == "position" and remap.port("other", "out") == "out"
    assert not Remap() and remap
    for bad in ["nothing", "a=", "=b", "a b=c", "a=b/", "__ns=a.b", "a=b c"]:
        with pytest.raises(ValueError, match="--remap"):
            Remap.parse([bad])
    # a target it would cut (the port would silently become 'states') is refused, saying so
    for cut in ["jointStatus=joint.states", "youBotDriver.jointStatus=youBotDriver.joint_states", "a=b.c"]:
        with pytest.raises(ValueError, match=r"a new name has no '\.'"):
            Remap.parse([cut])


def test_tasks_ports_links_bridges_and_bindings_follow_the_remap(tmp_path: Path) -> None:
    path = write(tmp_path, {"t.composite": composite(BODY), "tasks.py": TASKS})
    remap = Remap.parse(["src=left/src", "sink=left/sink", "out=value_out", "inp=value_in", "__ns=left"])
    with scart.Runtime.from_file(str(path), settings=DataflowSettings(remap=remap).apply()) as rt:
        deployer = deployer_of(rt)
        assert set(deployer.names()) == {"left/src", "left/sink", "left/sink2", "left/doubler"}
        src, sink, sink2 = (deployer.task(n) for n in ("left/src", "left/sink", "left/sink2"))
        assert set(src.ports()) == {"value_out"} and set(sink.ports()) == {"value_in"}
        assert set(deployer.task("left/doubler").ports()) == {"value", "value_out"}
        src.port("value_out").write(1.5)
        wait_until(lambda: sink.got == [1.5] and sink2.got == [6.0], timeout=10,
                   message=f"links not made under the new names: {sink.got} {sink2.got}")
        links = {lk.name: (lk.source, lk.sink) for lk in deployer.links()}  # what `scart links` lists
        assert links["feed"] == ("left/src.value_out", "left/sink.value_in")
        assert links["left/src.value_out->left/doubler.value"] == ("left/src.value_out", "left/doubler.value")
        rt.service("feeder").feed(4.0)  # binding.dataflow writes the renamed port of the renamed task
        wait_until(lambda: sink.got == [1.5, 4.0], timeout=10, message=f"binding missed the remap: {sink.got}")


def test_the_command_line_takes_remaps_and_graph_shows_them(tmp_path: Path) -> None:
    path = write(tmp_path, {"t.composite": composite(BODY), "tasks.py": TASKS})
    cmd = [sys.executable, "-m", "scart", "graph", str(path), "--remap", "src=left/src", "--remap", "out:=value_out"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert 'label="left/src\\n[Source]"' in done.stdout
    assert '"src" -> "sink" [style=bold, color=blue, label="value_out -> inp [data]"]' in done.stdout
    assert '"src" -> "bridge:doubler"' in done.stdout and '"bridge:doubler" -> "sink2"' in done.stdout
    assert '"feeder.sink:binding.dataflow" -> "sink" [style=dotted, label="ports"]' in done.stdout  # binding.dataflow
    bad = subprocess.run([*cmd[:5], "--remap", "no rule"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--remap 'no rule': expected FROM=TO" in bad.stderr
