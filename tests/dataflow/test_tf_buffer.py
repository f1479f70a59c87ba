"""The frame buffer on its own (``dataflow.tf``): lookups in time, the tree's rules, the errors.

tf2 itself is the judge in ``test_tf_tf2_ros.py``; these check what a user relies on with
values worked out by hand (rotations about one axis interpolate as their angle does)."""

from __future__ import annotations

import logging
import math
import random
import threading
import tracemalloc

import pytest

from dataflow import Deployer, TaskContext
from dataflow.tf import (ConnectivityError, ExtrapolationError, FrameBuffer, FrameTreeError, Transform,
                         TransformValueError, UnknownFrameError)
from dataflow.tf._math import arc, axis_angle, from_rpy, multiply, rpy, slerp

S = 1_000_000_000  # ns per s


def yaw(angle: float) -> tuple[float, float, float, float]:
    return axis_angle((0.0, 0.0, 1.0), angle)


def close(a: tuple[float, ...], b: tuple[float, ...], tol: float = 1e-12) -> bool:
    return len(a) == len(b) and all(abs(x - y) <= tol for x, y in zip(a, b, strict=True))


def same_rotation(a: tuple[float, ...], b: tuple[float, ...], tol: float = 1e-12) -> bool:
    return close(a, b, tol) or close(a, tuple(-x for x in b), tol)


@pytest.fixture
def arm() -> FrameBuffer:
    """base → shoulder (static, 1 m up) → elbow (turning about z, 0 → 90° over 1 s, moving
    0 → 2 m along x) → hand (static, 1 m along x)."""
    frames = FrameBuffer()
    frames.publish(Transform("base", "shoulder", (0.0, 0.0, 1.0)), static=True)
    frames.publish(Transform("elbow", "hand", (1.0, 0.0, 0.0)), static=True)
    for k in range(11):
        frames.publish(Transform("shoulder", "elbow", (0.2 * k, 0.0, 0.0), yaw(math.pi / 20 * k), 100 * S + k * S // 10))
    return frames


def test_a_chain_composes_and_interpolates_between_the_two_nearest_stamps(arm: FrameBuffer) -> None:
    at = arm.lookup("base", "hand", 100.25)  # between the stamps 100.2 and 100.3
    angle = math.pi / 2 * 0.25
    assert close(at.translation, (0.5 + math.cos(angle), math.sin(angle), 1.0))
    assert same_rotation(at.rotation, yaw(angle))
    assert (at.frame_id, at.child_frame_id, at.stamp_ns) == ("base", "hand", 100_250_000_000)
    assert close(arm.lookup("hand", "base", 100.25).inverse().translation, at.translation)
    assert close(at.apply((1.0, 0.0, 0.0)), (0.5 + 2 * math.cos(angle), 2 * math.sin(angle), 1.0))


def test_time_zero_is_the_newest_time_the_whole_path_has(arm: FrameBuffer) -> None:
    arm.publish(Transform("base", "wheel", (0.0, 0.0, 0.0), stamp_ns=100 * S + S // 2))
    assert arm.lookup("base", "hand").stamp_ns == 101 * S
    assert arm.lookup("wheel", "hand").stamp_ns == 100 * S + S // 2  # the older of the two
    assert arm.lookup("base", "shoulder").stamp_ns == 0  # statics only: for all time
    assert close(arm.lookup("base", "shoulder", 1e6).translation, (0.0, 0.0, 1.0))


def test_a_time_outside_what_is_kept_names_both_frames_the_time_and_the_span(arm: FrameBuffer) -> None:
    with pytest.raises(ExtrapolationError) as before:
        arm.lookup("base", "hand", 99.5)
    text = str(before.value)
    for part in ("'hand'", "'base'", "99.500000000", "'elbow'", "100.000000000 to 101.000000000", "before its oldest"):
        assert part in text, text
    with pytest.raises(ExtrapolationError, match=r"0\.250000000 s after its newest .*extrapolation not asked for"):
        arm.lookup("base", "hand", 101.25)
    assert not arm.can_transform("base", "hand", 101.25)


def test_extrapolation_only_when_asked_and_within_its_bound(arm: FrameBuffer) -> None:
    ahead = arm.lookup("shoulder", "elbow", 101.1, extrapolate=0.2)  # the last two stamps, carried on
    assert close(ahead.translation, (2.2, 0.0, 0.0), 1e-9)
    assert same_rotation(ahead.rotation, yaw(math.pi / 20 * 11), 1e-9)
    with pytest.raises(ExtrapolationError, match="more than the 0.200000000 s of extrapolation allowed"):
        arm.lookup("shoulder", "elbow", 101.3, extrapolate=0.2)
    with pytest.raises(ValueError):
        arm.lookup("shoulder", "elbow", 101.1, extrapolate=-1.0)


def test_no_path_and_unknown_frames_are_clear_errors(arm: FrameBuffer) -> None:
    arm.publish(Transform("map", "odom"), static=True)
    with pytest.raises(ConnectivityError) as no_path:
        arm.lookup("map", "hand", 100.5)
    assert "'hand' in 'map' at 100.500000000 s: no path joins them" in str(no_path.value)
    assert "the tree of 'base'" in str(no_path.value) and "the tree of 'map'" in str(no_path.value)
    with pytest.raises(UnknownFrameError, match="no frame 'nowhere' in the tree; frames: base, elbow, hand"):
        arm.lookup("base", "nowhere")
    assert arm.lookup("hand", "hand", 5.0).translation == (0.0, 0.0, 0.0)


def test_a_cycle_and_a_second_parent_are_refused_when_published(arm: FrameBuffer) -> None:
    with pytest.raises(FrameTreeError, match="would close a cycle"):
        arm.publish(Transform("hand", "base"), static=True)
    with pytest.raises(FrameTreeError, match="'elbow' has the parent 'shoulder'.*parent 'base' is refused"):
        arm.publish(Transform("base", "elbow", stamp_ns=101 * S))
    with pytest.raises(FrameTreeError, match="its own parent"):
        arm.publish(Transform("base", "base"))
    assert [(f.name, f.parent) for f in arm.frames()] == [("elbow", "shoulder"), ("hand", "elbow"),
                                                          ("shoulder", "base")]
    assert arm.roots() == ["base"]
    assert arm.refused == {"cycle": 1, "second parent": 1, "bad name": 1}


def test_nan_and_non_unit_rotations_are_refused_counted_and_said_once(caplog: pytest.LogCaptureFixture) -> None:
    frames = FrameBuffer()
    with pytest.raises(TransformValueError, match="not finite"):
        frames.publish(Transform("a", "b", (math.nan, 0.0, 0.0)))
    caplog.set_level(logging.WARNING, "dataflow.tf.buffer")
    bad = [Transform("a", "b", rotation=(0.0, 0.0, 0.0, math.nan), stamp_ns=k) for k in range(1, 4)]
    bad += [Transform("a", "b", rotation=(0.0, 0.0, 0.0, 1.5), stamp_ns=k) for k in range(4, 6)]
    good = Transform("a", "b", rotation=(0.0, 0.0, 0.0, 1.004), stamp_ns=9)  # within tf2's tolerance: normalised
    assert frames.receive([*bad, good], origin="ros1") == 1
    assert frames.refused == {"not finite": 4, "not a unit quaternion": 2}
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 2 and "said once" in said[0], said
    assert frames.lookup("a", "b").rotation == (0.0, 0.0, 0.0, 1.0)


def test_the_history_is_bounded_by_the_cache_time() -> None:
    frames = FrameBuffer(cache_time=1.0)
    for k in range(50):
        frames.publish(Transform("a", "b", (float(k), 0.0, 0.0), stamp_ns=k * S // 10))
    (info,) = frames.frames()
    assert (info.oldest_ns, info.newest_ns, info.kept) == (39 * S // 10, 49 * S // 10, 11)
    assert info.rate == pytest.approx(10.0) and info.received == 50
    assert frames.publish(Transform("a", "b", stamp_ns=S)) == 0  # older than what is kept: refused, counted
    assert frames.refused == {"old": 1}
    with pytest.raises(ExtrapolationError, match="the buffer keeps 1 s"):
        frames.lookup("a", "b", 3.0)


def test_stamps_out_of_order_and_repeated_keep_the_interpolation_right() -> None:
    frames = FrameBuffer()
    seen: list[int] = []
    frames.on_publish(lambda ts, static, origin: seen.extend(t.stamp_ns for t in ts))
    for k in (0, 4, 2, 1, 3):
        frames.publish(Transform("a", "b", (float(k), 0.0, 0.0), yaw(0.1 * k), stamp_ns=k * S))
    assert close(frames.lookup("a", "b", 2.5).translation, (2.5, 0.0, 0.0))
    assert same_rotation(frames.lookup("a", "b", 1.5).rotation, yaw(0.15))
    frames.publish(Transform("a", "b", (3.0, 0.0, 0.0), yaw(0.1 * 3), stamp_ns=3 * S))  # the same: nothing new
    frames.publish(Transform("a", "b", (30.0, 0.0, 0.0), yaw(0.3), stamp_ns=3 * S))  # another value: replaces
    assert close(frames.lookup("a", "b", 3.5).translation, (17.0, 0.0, 0.0))
    assert seen == [0, 4 * S, 2 * S, S, 3 * S, 3 * S]


def test_the_time_travel_form_goes_through_the_fixed_frame() -> None:
    """A robot drives along x in odom; its laser is 1 m ahead. Where was the laser at 1 s,
    seen from the robot at 3 s? 2 m behind it, less the 1 m ahead: -1 m."""
    frames = FrameBuffer()
    frames.publish(Transform("base", "laser", (1.0, 0.0, 0.0)), static=True)
    for k in range(5):
        frames.publish(Transform("odom", "base", (float(k), 0.0, 0.0), stamp_ns=k * S))
    seen = frames.lookup("base", 3.0, "laser", 1.0, "odom")
    assert close(seen.translation, (-1.0, 0.0, 0.0)) and seen.stamp_ns == 3 * S
    assert (seen.frame_id, seen.child_frame_id) == ("base", "laser")


def test_a_lookup_with_a_timeout_waits_for_the_transform() -> None:
    frames = FrameBuffer()
    frames.publish(Transform("a", "b", stamp_ns=S))
    later = threading.Timer(0.05, lambda: frames.publish(Transform("a", "b", (1.0, 0.0, 0.0), stamp_ns=3 * S)))
    later.start()
    try:
        assert close(frames.lookup("a", "b", 2.0, timeout=10.0).translation, (0.5, 0.0, 0.0))
        with pytest.raises(ExtrapolationError):
            frames.lookup("a", "b", 9.0, timeout=0.05)
    finally:
        later.join()


def test_listeners_get_what_is_stored_but_not_back_what_their_origin_gave() -> None:
    frames = FrameBuffer()
    got: list[tuple[str, bool, str]] = []
    stop = frames.on_publish(lambda ts, static, origin: got.append((ts[0].child_frame_id, static, origin)), "ros1")
    frames.publish(Transform("a", "b", stamp_ns=1))
    frames.receive([Transform("a", "c", stamp_ns=1)], origin="ros1")
    frames.receive([Transform("a", "d")], static=True, origin="ros2")
    stop()
    frames.publish(Transform("a", "e", stamp_ns=1))
    assert got == [("b", False, ""), ("d", True, "ros2")]


def test_a_task_reads_and_publishes_through_its_deployers_tree() -> None:
    deployer = Deployer()
    one, two = deployer.add(TaskContext("one")), deployer.add(TaskContext("two"))
    one.frames.publish(Transform("world", "one", (1.0, 2.0, 3.0)), static=True)
    assert two.frames is deployer.frames and two.frames.lookup("world", "one").translation == (1.0, 2.0, 3.0)
    alone = TaskContext("alone")
    assert alone.frames is not deployer.frames and alone.frames is alone.frames
    other = FrameBuffer()
    deployer.frames = other
    assert one.frames is other and two.frames is other


def test_the_math_agrees_with_itself() -> None:
    q = from_rpy(0.1, -0.2, 0.3)
    assert close(rpy(q), (0.1, -0.2, 0.3))
    assert close(multiply(yaw(0.2), yaw(0.3)), yaw(0.5))
    assert close(slerp(yaw(0.0), yaw(1.0), 0.25), yaw(0.25))
    assert slerp(yaw(0.5), yaw(0.5), 0.3) == yaw(0.5)
    t = Transform.from_rpy("a", "b", (1.0, 2.0, 3.0), (0.0, 0.0, math.pi / 2))
    assert close((t * t.inverse()).translation, (0.0, 0.0, 0.0)) and close(t.rpy, (0.0, 0.0, math.pi / 2))


def unit(rng: random.Random, near: tuple[float, ...] | None = None, step: float = 0.2) -> tuple[float, ...]:
    """A random unit quaternion (near ``near``, within about ``step``), its sign drawn too."""
    q = [rng.gauss(0.0, 1.0) for _ in range(4)] if near is None else [c + rng.uniform(-step, step) for c in near]
    n = math.sqrt(sum(c * c for c in q)) * rng.choice((1.0, -1.0))  # q and -q: one rotation, slerp goes the short way
    return tuple(c / n for c in q)


def test_arc_is_tf2s_slerp_rewritten() -> None:
    """The buffer interpolates with :func:`arc`'s ``cos(r θ) q0 + sin(r θ) p``; tf2's
    ``Quaternion::slerp`` (``slerp``, step for step) is the judge, the far side, an angle
    of zero and ratios beyond [0, 1] (extrapolation) included."""
    rng = random.Random(7)
    pairs = [(yaw(0.3), yaw(0.3)), (yaw(0.3), tuple(-c for c in yaw(0.3)))]
    for _ in range(200):
        q0 = unit(rng)
        pairs.append((q0, unit(rng, q0, rng.choice((1e-6, 0.01, 0.5, 2.0)))))
    for q0, q1 in pairs:
        theta, p = arc(q0, q1)
        for r in (0.0, 0.25, 0.5, 0.999, 1.0, -0.5, 1.5):
            got = tuple(math.cos(r * theta) * a + math.sin(r * theta) * b for a, b in zip(q0, p, strict=True))
            assert close(got, slerp(q0, q1, r), 1e-14), (q0, q1, r)


def test_a_long_history_answers_as_tf2_after_the_oldest_are_dropped() -> None:
    """Transforms dropped from the front (by count and by age), stamps arriving out of
    order, a value replaced: a lookup between two stamps is still tf2's lerp and slerp of
    the two kept around it, at a stamp exactly the stored value, before the oldest an error."""
    rng = random.Random(11)
    frames = FrameBuffer(cache_time=1.0, max_kept=60)
    truth: dict[str, dict[int, tuple[tuple[float, ...], tuple[float, ...]]]] = {"b": {}, "c": {}}
    q = {"b": unit(rng), "c": unit(rng)}

    def publish(child: str, parent: str, stamp: int) -> None:
        q[child] = unit(rng, q[child])
        xyz = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1))
        frames.publish(Transform(parent, child, xyz, q[child], stamp))
        truth[child][stamp] = (xyz, q[child])

    for k in range(400):  # b at 100 Hz (60 kept: the count bites), c at 25 Hz (1 s kept: the age bites)
        publish("b", "a", 100 * S + k * S // 100 + (S // 100 if k % 7 == 3 else 0) - (S // 100 if k % 7 == 4 else 0))
        if k % 4 == 0:
            publish("c", "b", 100 * S + k * S // 100)
        if k == 390:
            publish("b", "a", 100 * S + 385 * S // 100)  # another value at a stamp held: replaces it
    for child, parent in (("b", "a"), ("c", "b")):
        kept = sorted(truth[child])[-60:] if child == "b" else [s for s in truth[child] if s >= max(truth[child]) - S]
        info = next(f for f in frames.frames() if f.name == child)
        assert (info.kept, info.oldest_ns, info.newest_ns) == (len(kept), kept[0], kept[-1])
        for s0, s1 in zip(kept, kept[1:]):
            t = s0 + rng.randrange(1, s1 - s0)
            r = (t - s0) / (s1 - s0)
            (x0, q0), (x1, q1) = truth[child][s0], truth[child][s1]
            got = frames.lookup(parent, child, time_ns=t)
            assert close(got.translation, tuple((1 - r) * a + r * b for a, b in zip(x0, x1, strict=True)))
            assert close(got.rotation, slerp(q0, q1, r))
            assert frames.lookup(parent, child, time_ns=s0).rotation == q0
        with pytest.raises(ExtrapolationError, match="before its oldest"):
            frames.lookup(parent, child, time_ns=kept[0] - 1)


def test_frames_at_their_own_stamps_compose_as_each_alone() -> None:
    """Frames published together share their stamps, and a lookup uses it; a frame with a
    stamp more than the one below it, or with stamps all its own, is looked up right: the
    chain is what each frame looked up alone composes to."""
    rng = random.Random(3)
    frames = FrameBuffer()
    q = {name: unit(rng) for name in "bcde"}
    for k in range(200):
        stamp = 100 * S + k * S // 100
        batch = []
        for child, parent, at in (("e", "d", stamp), ("d", "c", stamp), ("c", "b", stamp), ("b", "a", stamp + 1_234_567)):
            q[child] = unit(rng, q[child])
            batch.append(Transform(parent, child, (rng.uniform(-1, 1), 0.5, 0.0), q[child], at))
        if k == 190:  # c has a stamp more, 5 ms after one it shares with d and e
            batch.append(Transform("b", "c", (0.0, 0.0, 0.0), unit(rng), stamp + 5_000_000))
        frames.publish(batch)
    times = [100 * S + rng.randrange(S // 50, 198 * S // 100) for _ in range(200)]
    times += [100 * S + 190 * S // 100 + rng.randrange(0, S // 100) for _ in range(50)]  # around c's stamp more
    for t in times:
        alone = frames.lookup("a", "b", time_ns=t)
        for child, parent in (("c", "b"), ("d", "c"), ("e", "d")):
            alone = alone * frames.lookup(parent, child, time_ns=t)
        chain = frames.lookup("a", "e", time_ns=t)
        assert close(chain.translation, alone.translation, 1e-12) and close(chain.rotation, alone.rotation, 1e-12)


def test_a_tree_keeps_about_a_hundred_and_fifty_bytes_per_transform() -> None:
    """What a tree holds per transform kept (the stamp, the transform, what its
    interpolation needs): flat arrays, not an object per transform."""
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        frames = FrameBuffer()
        for i in range(500):  # 10 frames at 100 Hz for 5 s, each stamp's transforms in one message
            frames.publish([Transform(f"g{k - 1}" if k else "root", f"g{k}", (0.1 * k, 0.001 * i, 0.0),
                                      yaw(0.01 * i + k), 100 * S + i * S // 100) for k in range(10)])
        size = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    kept = sum(f.kept for f in frames.frames())
    assert kept == 5000 and size / kept < 170, size / kept
