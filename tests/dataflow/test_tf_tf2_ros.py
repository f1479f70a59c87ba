"""scart's frame tree against ROS's own tf2 (Debian's python3-tf2-ros) through a real ``rosmaster``.

rospy's ``TransformBroadcaster`` and ``StaticTransformBroadcaster`` publish a 4-frame tree
with two moving joints; scart's buffer, joined to ``/tf`` and ``/tf_static``
(:class:`dataflow.tf.ros.Ros1Frames`), must answer every lookup as
``tf2_ros.Buffer.lookup_transform`` does at the same stamps, within 1e-9, between stamps
too; and refuse, count and say once what tf2 is sent that a tree should not hold."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from typing import Any

import pytest
from support import wait_until
from support.ros1 import needs_ros, rosmaster
from support.tf2 import Peer, require_tf2

from dataflow.tf import ConnectivityError, ExtrapolationError, FrameBuffer, Transform, TransformError
from dataflow.tf.ros import Ros1Frames
from dataflow.transports import TransportError

pytestmark = [pytest.mark.integration, pytest.mark.subprocess, needs_ros]

TOLERANCE = 1e-9


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[FrameBuffer, Peer, dict[str, Any]]]:
    """A rosmaster, scart's buffer on /tf, and tf2_ros' broadcasters having sent the tree
    (one for the module's tests, the last of which sends what must be refused)."""
    require_tf2()
    with rosmaster(tmp_path_factory.mktemp("ros")) as ros:
        buffer = FrameBuffer()
        bridge = Ros1Frames(buffer, {"master": ros.uri})
        peer = Peer(ros, "broadcast", "2")
        try:
            assert "ready" in peer.next(60)
            sent = peer.next(60)
            assert sent["ok"], sent
            last = sent["first"] + (sent["sent"] - 1) * sent["step"]
            buffer.lookup("world", "arm", time_ns=last, timeout=20)  # scart has heard it all too
            buffer.lookup("sensor", "world", time_ns=last, timeout=20)
            yield buffer, peer, sent
        finally:
            peer.stop()
            bridge.close()


def scart_answer(call: Any) -> dict[str, Any]:
    try:
        t: Transform = call()
    except TransformError as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}
    return {"t": list(t.translation), "q": list(t.rotation), "stamp": t.stamp_ns}


def agree(ours: dict[str, Any], theirs: dict[str, Any]) -> bool:
    if "error" in ours or "error" in theirs:
        return False
    return ours["stamp"] == theirs["stamp"] and all(
        abs(a - b) <= TOLERANCE for a, b in zip(ours["t"] + ours["q"], theirs["t"] + theirs["q"], strict=True))


def test_lookups_equal_tf2s_at_the_stamps_and_between_them(world: tuple[FrameBuffer, Peer, dict[str, Any]]) -> None:
    buffer, peer, sent = world
    first, step, count = sent["first"], sent["step"], sent["sent"]
    times = [0, first, first + (count - 1) * step, first + 7 * step, first + 20 * step,
             first + round(7.3 * step), first + round(19.91 * step), first + round(33.5 * step) + 1]
    pairs = [("world", "arm"), ("arm", "world"), ("sensor", "arm"), ("arm", "sensor"), ("world", "sensor"),
             ("sensor", "world"), ("base", "arm")]
    differ = []
    for target, source in pairs:
        for t in times:
            theirs = peer.ask(lookup=[target, source, t])
            ours = scart_answer(lambda: buffer.lookup(target, source, time_ns=t))
            if not agree(ours, theirs):
                differ.append((target, source, t, ours, theirs))
    tt, ts = first + round(30.25 * step), first + round(4.5 * step)
    theirs = peer.ask(full=["sensor", tt, "arm", ts, "world"])
    ours = scart_answer(lambda: buffer.lookup("sensor", tt / 1e9, "arm", ts / 1e9, "world"))
    if not agree(ours, theirs):
        differ.append(("full", tt, ts, ours, theirs))
    assert differ == []


def test_both_refuse_a_time_before_the_first_stamp_and_a_tree_apart(
        world: tuple[FrameBuffer, Peer, dict[str, Any]]) -> None:
    buffer, peer, sent = world
    early = sent["first"] - 5_000_000
    assert peer.ask(lookup=["world", "arm", early])["error"].startswith("ExtrapolationException")
    with pytest.raises(ExtrapolationError) as ours:
        buffer.lookup("world", "arm", time_ns=early)
    assert "'arm' in 'world' at 999.995000000 s" in str(ours.value) and "before its oldest" in str(ours.value)

    buffer.publish(Transform("island", "isle", (1.0, 0.0, 0.0)), static=True)  # scart's own, on /tf_static
    heard = wait_until(lambda: (a := peer.ask(lookup=["isle", "island", 0])).get("t") and a, timeout=10,
                       interval=0.1, message="tf2 never heard scart's static transform")
    assert heard["t"] == [-1.0, 0.0, 0.0]  # tf2 has it: the pose of island in isle...
    assert peer.ask(lookup=["world", "isle", 0])["error"].startswith("ConnectivityException")  # ...apart
    with pytest.raises(ConnectivityError, match="no path joins them"):
        buffer.lookup("world", "isle")


def test_a_second_tree_on_the_processs_node_is_refused_saying_why(
        world: tuple[FrameBuffer, Peer, dict[str, Any]]) -> None:
    with pytest.raises(TransportError, match="already publishes /tf"):
        Ros1Frames(FrameBuffer())  # the process's one node has /tf: one tree per process


def test_what_a_tree_must_not_hold_is_refused_counted_and_said_once(
        world: tuple[FrameBuffer, Peer, dict[str, Any]], caplog: pytest.LogCaptureFixture) -> None:
    buffer, peer, _ = world
    caplog.set_level(logging.WARNING, "dataflow.tf.buffer")
    tf2 = peer.ask(bad=True)["bad"]
    assert tf2 == {"nan_frame": False, "long_frame": False}  # tf2 refuses these two as well
    wanted = {"not finite": 1, "not a unit quaternion": 1, "second parent": 1, "cycle": 1}
    wait_until(lambda: buffer.refused == wanted, timeout=10, message=f"refused {buffer.refused}")
    said = [r.getMessage() for r in caplog.records if "refused" in r.getMessage()]
    assert len(said) == 4, said
    assert "'arm' has the parent 'base'" in " ".join(said) and "would close a cycle" in " ".join(said)
    assert buffer.lookup("world", "arm").frame_id == "world"  # the tree is whole
