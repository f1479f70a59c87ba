"""``<scart:stream transport="ros2">`` in a composite: checked at load like the bridge's
conversions (file:line, SCART-T006 for types that do not fit, SCART-T005 for the rest;
a converter imported from the composite's folder and checked by its annotations), made
when the composite starts and undone when it stops."""

from __future__ import annotations

import random
from pathlib import Path

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

import scart  # noqa: E402
from dataflow.transports import load  # noqa: E402
from scart.bindings.dataflow import deployer_of  # noqa: E402
from support import wait_until  # noqa: E402
from support.sca import composite, write  # noqa: E402

TASKS = '''
from __future__ import annotations

from dataflow import FlowStatus, InputPort, OutputPort, TaskContext


class Ticker(TaskContext):
    level = OutputPort(float)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.n = 0

    def update_hook(self) -> None:
        self.n += 1
        self.level.write(self.n / 4)


class Listener(TaskContext):
    level = InputPort(float)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.heard: list[float] = []

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, value = self.level.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.heard.append(value)


def halve(message) -> float:
    return message.data / 2


def wrong(value: str) -> dict:
    return {"data": 0.0}
'''

TASKS_XML = '''<component name="ticker"><scart:implementation.task class="rostasks:Ticker" period="0.01"/></component>
<component name="listener"><scart:implementation.task class="rostasks:Listener" period="0.01"/></component>'''


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def test_a_stream_whose_types_do_not_fit_is_refused_at_load_with_its_line(tmp_path: Path) -> None:
    text = composite(f'''{TASKS_XML}
        <scart:stream port="ticker.level" transport="ros2" topic="/a" type="std_msgs/msg/Int32"/>
        <scart:stream port="ticker.level" transport="ros2" topic="/b" qos="fast"/>
        <scart:stream port="ticker.level" transport="ros2" topic="/c" converter="rostasks:wrong"/>
        <scart:stream port="listener.level" transport="ros2" topic="/d" converter="rostasks:nothing_here"/>''')
    path = write(tmp_path, {"t.composite": text, "rostasks.py": TASKS}, with_components=False)
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    found = {(p.line, p.code): p.message for p in info.value.errors}
    int32 = found[(line_of(text, 'topic="/a"'), "SCART-T006")]
    assert "ticker.level: ros2 from port level (float64)" in int32 and "float and int32 (a float never narrows" in int32
    assert "unknown option(s) qos" in found[(line_of(text, 'topic="/b"'), "SCART-T005")]
    assert "takes str; the port gives float" in found[(line_of(text, 'topic="/c"'), "SCART-T006")]
    assert "cannot be imported" in found[(line_of(text, 'topic="/d"'), "SCART-T006")]
    assert len(found) == 4


def test_streams_of_a_composite_carry_samples_and_go_with_it(tmp_path: Path) -> None:
    domain = random.SystemRandom().randint(1, 232)
    text = composite(f'''{TASKS_XML}
        <scart:stream port="ticker.level" transport="ros2" topic="/scart_test/element" domain="{domain}"/>
        <scart:stream port="listener.level" transport="ros2" topic="/scart_test/element" domain="{domain}"
                      converter="rostasks:halve" policy="buffer:100"/>''')
    path = write(tmp_path, {"t.composite": text, "rostasks.py": TASKS}, with_components=False)
    with scart.Runtime.from_file(str(path)) as rt:
        deployer = deployer_of(rt)
        listener = deployer.task("listener")
        wait_until(lambda: len(listener.heard) >= 5, timeout=15, message=f"heard {listener.heard}")
        heard = list(listener.heard)
        assert all(v * 8 == round(v * 8) for v in heard) and heard == sorted(heard)  # n/4 halved, in order
        (note,) = next(p for p in listener.describe().ports if p.name == "level").streams
        assert (note.type_name, note.unauthenticated, note.refused) == ("std_msgs/msg/Float64", True, 0)
    assert deployer.streams() == {} and load("ros2").participants() == {}
