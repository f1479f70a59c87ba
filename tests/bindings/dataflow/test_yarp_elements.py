"""``<scart:stream transport="yarp">`` and ``<scart:yarprpc>`` in a composite: what has no
bottle form and what names nothing refused at load with file:line and a SCART code, then
— with a real ``yarpserver`` — ``yarp rpc`` and ``scart call yarp:/...`` calling a task's
operations and an SCA service's, arguments checked as on every other entry."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from support.sca import composite, line_of, write
from support.yarp import yarpserver

import scart
from scart.cli import main

MODS = '''
from __future__ import annotations

from typing import Protocol

from pydantic import BaseModel

import scart
from dataflow import InputPort, OutputPort, TaskContext, operation


class Pose(BaseModel):
    x: float
    y: float
    theta: float


class Rover(TaskContext):
    pose = OutputPort(Pose)
    speed = InputPort(float, ge=0.0, le=2.0)
    table = InputPort(dict[str, float])

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.limit = 1.0

    @operation
    def set_limit(self, limit: float) -> float:
        self.limit = limit
        return limit

    @operation
    def where(self) -> Pose:
        return Pose(x=1.0, y=2.0, theta=0.5)

    @operation
    def halt(self) -> None:
        pass


@scart.interface
class Counting(Protocol):
    def add(self, a: int, b: int) -> int: ...
    def count(self) -> int: ...


@scart.component(services=[Counting])
class Counter:
    def __init__(self) -> None:
        self.calls = 0

    def add(self, a: int, b: int) -> int:
        self.calls += 1
        return a + b

    def count(self) -> int:
        return self.calls
'''

ROVER = '''
<component name="rover">
    <scart:implementation.task class="yarpmods:Rover"/>
</component>
<component name="counter">
    <scart:implementation.python class="yarpmods:Counter"/>
</component>
'''


def test_what_has_no_bottle_form_or_names_nothing_is_refused_at_load(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    body = '''
        <scart:stream port="rover.pose" transport="yarp" topic="/rover/pose"/>
        <scart:yarprpc component="rover"/>
        <scart:stream port="rover.table" transport="yarp" topic="/rover/table"/><!--TABLE-->
        <scart:stream port="rover.speed" transport="yarp" topic="/rover/speed" carrier="mcast"/><!--MCAST-->
        <scart:yarprpc component="rovr"/><!--RPC-->
    '''
    text = composite(ROVER + body)
    path = write(tmp_path, {"r.composite": text, "yarpmods.py": MODS}, with_components=False)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    expected = {"TABLE": ("SCART-T006", "the value is dict[str, float], which has no bottle form"),
                "MCAST": ("SCART-T005", "carrier='mcast': scart speaks YARP over tcp, fast_tcp, text, udp"),
                "RPC": ("SCART-T008", "component: 'rovr' is in no composite here")}
    for marker, (code, words) in expected.items():
        line = line_of(text, f"<!--{marker}-->")
        assert any(f"r.composite:{line}: " in row and f"[{code}]" in row and words in row
                   for row in err.splitlines()), (marker, err)
    assert "r.composite: 3 problem(s); nothing started" in err, err


@pytest.mark.integration
def test_yarp_rpc_and_scart_call_reach_a_task_and_an_sca_service(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    with yarpserver(tmp_path / "yarp") as yarp:
        body = f'''
            <scart:yarprpc component="rover" server="{yarp.address}"/>
            <scart:yarprpc component="counter" port="/counter" server="{yarp.address}"/>
        '''
        path = write(tmp_path, {"r.composite": composite(ROVER + body), "yarpmods.py": MODS}, with_components=False)
        with scart.Runtime.from_file(str(path)) as rt:
            assert yarp.registered("/scart/rover/rpc") and yarp.registered("/counter")
            done = yarp.tool("rpc", "/scart/rover/rpc", stdin="set_limit 1.5\nwhere\nset_limit nan\nset_limit\n"
                                                               "fly\nhelp\n")
            answers = [line for line in done.stdout.splitlines() if line.startswith("Response:")]
            assert answers[:2] == ["Response: 1.5", "Response: 1.0 2.0 0.5"], done.stdout
            assert answers[2].startswith('Response: [fail] "') and "rover.set_limit(limit)" in answers[2]
            assert "set_limit takes 1 argument(s) (limit), got 0" in answers[3]
            assert "no operation 'fly'" in answers[4] and "halt, set_limit, where" in answers[4]
            assert "Responses:\n  halt\n  set_limit limit\n  where\n" in done.stdout, done.stdout  # help: [many]
            assert yarp.tool("rpc", "/counter", stdin="add 2 3\nadd 2 x\n").stdout.count("Response:") == 2
            assert rt.service("counter/Counting").count() == 1  # "add 2 x" was refused before the call
            assert main(["call", "yarp:/counter", "add", "40", "2", "--yarp-server", yarp.address, "--json"]) == 0
            assert json.loads(capsys.readouterr().out) == [42]
            assert main(["call", "yarp:/counter", "add", "2", "x", "--yarp-server", yarp.address]) == 1
            assert "yarp:/counter answered [fail] " in capsys.readouterr().err  # a refusal is no result
            assert main(["call", "yarp:/nowhere", "x", "--yarp-server", yarp.address]) == 1
            assert "no YARP port /nowhere is registered" in capsys.readouterr().err
        assert not yarp.registered("/scart/rover/rpc") and not yarp.registered("/counter")
