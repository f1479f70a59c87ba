"""``<scart:rosservice transport="ros2">``: a composite's task operation or SCA service
answers a ROS 2 service, called by an independent Cyclone DDS participant and by scart's
own client; what does not map is refused at load with file:line and SCART-T007, and the
service goes when the composite stops."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

import scart  # noqa: E402
from dataflow.transports import load  # noqa: E402
from dataflow.transports.ros2 import call_service  # noqa: E402
from scart.cli import main  # noqa: E402
from support.sca import composite, line_of, write  # noqa: E402

MODS = '''
from __future__ import annotations

from typing import Protocol

import scart
from dataflow import TaskContext, operation


class Calc(TaskContext):
    @operation
    def add(self, a: int, b: int) -> int:
        return a + b

    @operation
    def halve(self, a: float, b: float) -> float:
        return (a + b) / 2


@scart.interface
class Switch(Protocol):
    def set(self, data: bool) -> str: ...


@scart.component(services=[Switch])
class SwitchService:
    def set(self, data: bool) -> str:
        return "on" if data else "off"
'''

MEAN = "float64 a\nfloat64 b\n---\nfloat64 mean\n"

COMPONENTS = '''
<component name="calc"><scart:implementation.task class="svcmods:Calc"/></component>
<component name="switch"><scart:implementation.python class="svcmods:SwitchService"/></component>
'''


def _write(tmp_path: Path, body: str) -> tuple[Path, str]:
    text = composite(COMPONENTS + body)
    return write(tmp_path, {"s.composite": text, "svcmods.py": MODS}, with_components=False), text


T007, X003 = "SCART-T007", "SCART-X003"  # the element's check; the schema's (a transport it does not know)


@pytest.mark.parametrize(("element", "code", "words"), [
    ('<scart:rosservice transport="ros2" service="/x" type="example_interfaces/srv/AddTwoInts" '
     'operation="calc.halve"/>', T007, "by operation calc.halve: the return type float vs "
                                       "example_interfaces/srv/AddTwoInts_Response"),
    ('<scart:rosservice transport="ros2" service="/x" type="std_srvs/srv/SetBool" target="switch/Switch.set" '
     'converter="svcmods:nothing"/>', T007, "converter: ROS 1 services only"),
    ('<scart:rosservice transport="ros2" service="/x" type="std_srvs/srv/SetBool" target="switch/Switch.set" '
     'master="http://127.0.0.1:11311/"/>', T007, "unknown attribute(s) master"),
    ('<scart:rosservice transport="ros3" service="/x" type="std_srvs/srv/SetBool" target="switch/Switch.set"/>',
     X003, "'ros3' is not an element of the set {'ros1', 'ros2'}"),
    ('<scart:rosservice transport="ros2" service="/x" type="std_srvs/srv/Nope" target="switch/Switch.set"/>',
     T007, "std_srvs/srv/Nope"),
    ('<scart:rosservice transport="ros2" service="/x" type="my_srvs/srv/Mean" operation="calc.halve" '
     'msgs="Mean.srv"/>', T007, "a ROS 2 type file is named .../PACKAGE/srv/TYPE.srv"),
    ('<scart:rosservice transport="ros2" service="/x" type="my_srvs/srv/Big" operation="calc.halve" '
     'msgs="my_srvs/srv/Big.srv"/>', T007, "my_srvs/srv/Big.srv: larger than 1048576 bytes"),
], ids=["types", "converter", "ros1-option", "transport", "srv-type", "msgs-name", "msgs-size"])
def test_what_does_not_map_is_refused_at_load_with_file_line_and_code(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], element: str, code: str, words: str) -> None:
    path, text = _write(tmp_path, element + "<!--HERE-->")
    if 'msgs="Mean.srv"' in element:  # a real file, in the wrong place
        (tmp_path / "Mean.srv").write_text(MEAN, encoding="utf-8")
    if "Big.srv" in element:  # a file over the bound
        (tmp_path / "my_srvs" / "srv").mkdir(parents=True)
        (tmp_path / "my_srvs" / "srv" / "Big.srv").write_text("#" * (1 << 20) + "\n---\n", encoding="utf-8")
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"s.composite:{line_of(text, '<!--HERE-->')}: " in err and f"[{code}]" in err and words in err, err


def test_a_users_srv_file_gives_the_type(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, _ = _write(tmp_path, '<scart:rosservice transport="ros2" service="/mean" type="my_srvs/srv/Mean" '
                               'operation="calc.halve" msgs="my_srvs/srv/Mean.srv"/>')
    (tmp_path / "my_srvs" / "srv").mkdir(parents=True)
    (tmp_path / "my_srvs" / "srv" / "Mean.srv").write_text(MEAN, encoding="utf-8")
    assert main(["validate", str(path)]) == 0, capsys.readouterr().err


def test_a_composite_answers_an_independent_ros2_client_and_withdraws_at_stop(tmp_path: Path, domain: int,
                                                                              topic: str, peer) -> None:
    path, _ = _write(tmp_path, f'''
        <scart:rosservice transport="ros2" service="/peer/add" type="example_interfaces/srv/AddTwoInts"
                          operation="calc.add" domain="{domain}"/>
        <scart:rosservice transport="ros2" service="{topic}/set" type="std_srvs/srv/SetBool"
                          target="switch/Switch.set" domain="{domain}"/>''')
    with scart.Runtime.from_file(str(path)):
        client = peer("client")  # an independent participant: calls /peer/add with a=20, b=22, seq 7
        reply = client.next_event("reply")
        assert (reply["sum"], reply["seq"], reply["mine"]) == (42, 7, True)
        assert call_service(f"{topic}/set", {"data": True}, type_name="std_srvs/srv/SetBool", timeout=10,
                            options={"domain": str(domain)}) == {"success": True, "message": "on"}
    assert load("ros2").participants() == {}
