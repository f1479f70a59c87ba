"""scart's frame tree on ROS 2's ``/tf`` and ``/tf_static`` (DDS ``rt/tf``, ``rt/tf_static``), with
tf2_ros' QoS: a static transform sent before scart joined still reaches it (transient-local),
dynamic ones flow both ways. The peer is another DDS participant (no ROS 2 install on PyPI:
the ROS 2 tests' own stand-in)."""

from __future__ import annotations

import itertools
import random
from collections.abc import Iterator
from typing import Any

import pytest
from support import wait_until

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from dataflow.tf import FrameBuffer, Transform  # noqa: E402
from dataflow.tf.ros import Ros2Frames  # noqa: E402
from scart_ros2 import Participant, QoS  # noqa: E402

pytestmark = pytest.mark.integration

TYPE = "tf2_msgs/msg/TFMessage"


def message(parent: str, child: str, x: float, stamp_ns: int) -> dict[str, Any]:
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    return {"transforms": [{"header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": parent},
                            "child_frame_id": child,
                            "transform": {"translation": {"x": x, "y": 0.0, "z": 0.0},
                                          "rotation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}]}


@pytest.fixture
def domain() -> int:
    return random.SystemRandom().randint(1, 232)  # concurrent runs on one host stay apart


@pytest.fixture
def peer(domain: int) -> Iterator[Participant]:
    with Participant(domain, node="tf_peer") as participant:
        yield participant


def test_statics_latched_before_scart_joined_and_transforms_both_ways(domain: int, peer: Participant) -> None:
    static = peer.publisher("/tf_static", TYPE, QoS.data(latching=True))
    assert static.publish(message("world", "base", 1.0, 0))  # sent before scart is there
    heard: list[Any] = []
    peer.subscribe("/tf", TYPE, heard.append, QoS.buffer(100))
    latched: list[Any] = []
    peer.subscribe("/tf_static", TYPE, latched.append, QoS.buffer(100, latching=True))
    dynamic = peer.publisher("/tf", TYPE, QoS.buffer(100))

    buffer = FrameBuffer()
    bridge = Ros2Frames(buffer, {"domain": str(domain)})
    try:
        assert buffer.lookup("world", "base", timeout=15).translation == (1.0, 0.0, 0.0)
        stamp = 1_000_000_000_000

        def heard_arm() -> bool:
            dynamic.publish(message("base", "arm", 0.5, stamp))
            return buffer.can_transform("world", "arm", time_ns=stamp)

        wait_until(heard_arm, timeout=15, interval=0.05, message="scart never heard /tf")
        assert buffer.lookup("world", "arm", time_ns=stamp).translation == (1.5, 0.0, 0.0)

        tries = itertools.count(1)

        def sent_hand() -> bool:  # a new stamp each time: the same one again would change nothing, and not be sent
            buffer.publish(Transform("arm", "hand", (0.25, 0.0, 0.0), stamp_ns=stamp + next(tries)))
            return any(t.child_frame_id == "hand" for m in list(heard) for t in m.transforms)

        wait_until(sent_hand, timeout=15, interval=0.05, message="the peer never heard scart's /tf")
        buffer.publish(Transform("base", "camera", (0.0, 0.0, 0.4)), static=True)
        wait_until(lambda: any({t.child_frame_id for t in m.transforms} == {"camera"} for m in list(latched)),
                   timeout=15, message="the peer never got scart's statics")
        assert buffer.refused == {}
    finally:
        bridge.close()
