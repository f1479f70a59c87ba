"""``<scart:frames>`` in a composite: one tree per process that tasks read and publish through
(``self.frames``), the composite's static frames in it, its task ``tf`` served with the
others; and what cannot be a tree refused at load with file:line and ``SCART-F001``."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from support import wait_until
from support.sca import composite, line_of, write

import scart
from dataflow.tf import Transform
from dataflow.tf.messages import FrameTree
from scart.bindings.dataflow import deployer_of
from scart.cli import main

MODS = '''
from __future__ import annotations

import math
import time

from dataflow import OutputPort, TaskContext
from dataflow.tf import Transform, TransformError


class Wheel(TaskContext):
    """Turns about y, publishing its frame each cycle; reads where its hub is in the world."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.cycles = 0
        self.hub_in_world = None

    def update_hook(self) -> None:
        self.cycles += 1
        a = 0.1 * self.cycles
        self.frames.publish(Transform("axle", "wheel", (0.0, 0.0, 0.0), (0.0, math.sin(a / 2), 0.0, math.cos(a / 2)),
                                      time.time_ns()), authority=self.name)
        try:
            self.hub_in_world = self.frames.lookup("world", "wheel")
        except TransformError:  # the composite's frames come once every component started
            pass
'''

WHEEL = '''
<component name="wheel">
    <scart:implementation.task class="tfmods:Wheel" period="0.01"/>
</component>
'''

FRAMES = '''
<scart:frames cache="5">
    <scart:frame parent="world" child="base" xyz="1 2 0" rpy="0 0 1.5707963267948966"/>
    <scart:frame parent="base" child="axle" xyz="0.5 0 0.1" quaternion="0 0 0 1"/>
</scart:frames>
'''


def test_tasks_publish_and_read_through_the_composites_tree(tmp_path: Path) -> None:
    path = write(tmp_path, {"w.composite": composite(WHEEL + FRAMES), "tfmods.py": MODS}, with_components=False)
    with scart.Runtime.from_file(path) as rt:
        deployer = deployer_of(rt)
        wheel = deployer.task("wheel")
        hub = wait_until(lambda: wheel.hub_in_world, timeout=10)  # type: ignore[attr-defined]
        assert all(abs(a - b) < 1e-9 for a, b in zip(hub.translation, (1.0, 2.5, 0.1), strict=True))
        assert wheel.frames is deployer.frames and deployer.frames.cache_time == 5.0
        server = deployer.task("tf")
        assert server.is_running() and server.get_property("cache") == 5.0
        tree: FrameTree = server.port("tree").last_sample()[1]
        assert {(f.frame, f.parent, f.static) for f in tree.frames} >= {("base", "world", True),
                                                                         ("axle", "base", True)}
        assert server.port("tf_static").last_sample()[1].transforms[0].child_frame_id in ("base", "axle")
        answer = server.call("lookup", "world", "axle", 0.0)
        assert math.isclose(answer.translation[1], 2.5) and answer.frame_id == "world"
    assert not server.is_running()


@pytest.mark.parametrize(("element", "words", "below"), [
    ('<scart:frames cache="0"/>', "cache='0': seconds, more than 0", 0),
    ('<scart:frames ros1="maybe"/>', "@ros1 'maybe' is not a valid boolean", 0),  # the schema's words, SCART-X003
    ('<scart:frames color="red"/>', "unknown attribute(s) color", 0),
    ('<scart:frames/><scart:frames/>', "one per process", 0),
    ('<scart:frames ros1="true" master="ftp://robot"/>', "ros1: ROS master URI 'ftp://robot' is not http://", 0),
    ('<scart:frames ros2="true" domain="999"/>', "ros2: option domain='999': an integer 0..232", 0),
    ('<scart:frames>|<scart:frame parent="a" child="b" xyz="1 2"/></scart:frames>', "xyz='1 2': 3 finite numbers", 1),
    ('<scart:frames>|<scart:frame parent="a" child="b" rpy="0 nan 0"/></scart:frames>', "rpy='0 nan 0'", 1),
    ('<scart:frames>|<scart:frame parent="a" child="b" quaternion="0 0 0 2"/></scart:frames>',
     "is not a unit quaternion", 1),
    ('<scart:frames>|<scart:frame parent="a" child="b"/>|<scart:frame parent="c" child="b"/></scart:frames>',
     "'b' has the parent 'a'", 2),
    ('<scart:frames>|<scart:frame parent="a" child="b"/>|<scart:frame parent="b" child="a"/></scart:frames>',
     "would close a cycle", 2),
], ids=["cache", "flag", "attribute", "two", "master", "domain", "xyz", "nan", "quaternion", "second-parent", "cycle"])
def test_what_cannot_be_a_tree_is_refused_at_load(tmp_path: Path, capsys: pytest.CaptureFixture[str], element: str,
                                                  words: str, below: int) -> None:
    text = composite(WHEEL + "<!--HERE-->" + element.replace("|", "\n"))
    path = write(tmp_path, {"w.composite": text, "tfmods.py": MODS}, with_components=False)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert ("[SCART-F001]" in err or "[SCART-X003]" in err) and words in err, err
    assert f"w.composite:{line_of(text, '<!--HERE-->') + below}: " in err, err


def test_a_composite_without_frames_still_gives_its_tasks_a_tree(tmp_path: Path) -> None:
    path = write(tmp_path, {"w.composite": composite(WHEEL), "tfmods.py": MODS},
                 with_components=False)
    with scart.Runtime.from_file(path) as rt:
        deployer = deployer_of(rt)
        deployer.frames.publish(Transform("world", "axle"), static=True)
        wheel = deployer.task("wheel")
        assert wait_until(lambda: wheel.hub_in_world, timeout=10).child_frame_id == "wheel"  # type: ignore[attr-defined]
        assert "tf" not in deployer.names()
