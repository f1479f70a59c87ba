"""A participant's lifecycle: one owned thread, ended by close() (idempotent, from a
callback too); closing frees the domain; refusals counted; hooks refuse."""

from __future__ import annotations

import math
import threading

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from scart_ros2 import DomainError, Network, Participant, QoS, Ros2Error  # noqa: E402
from support import wait_until  # noqa: E402

pytestmark = pytest.mark.integration


def _ros2_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("ros2-dispatch")]


def test_one_thread_per_participant_started_by_a_reader_and_ended_by_close(domain: int, topic: str) -> None:
    ros = Participant(domain)
    try:
        ros.publisher(topic, "std_msgs/msg/Int64")
        assert _ros2_threads() == []  # no reader, no thread
        for i in range(3):
            ros.subscribe(f"{topic}_{i}", "std_msgs/msg/Int64", lambda m: None)
        assert len(_ros2_threads()) == 1
        ros.close()
        ros.close()  # idempotent
        assert _ros2_threads() == [] and ros.closed
        with pytest.raises(Ros2Error, match="closed"):
            ros.publisher(topic, "std_msgs/msg/Int64")
    finally:
        ros.close()  # idempotent: also when an assertion failed


def test_close_from_a_callback(domain: int, topic: str) -> None:
    ros = Participant(domain)
    try:
        closed = threading.Event()

        def on_message(message) -> None:
            ros.close()
            closed.set()

        pub = ros.publisher(topic, "std_msgs/msg/Int64")
        sub = ros.subscribe(topic, "std_msgs/msg/Int64", on_message)
        wait_until(lambda: pub.matched() and sub.matched(), timeout=15)
        pub.publish({"data": 1})
        assert closed.wait(15)
        wait_until(lambda: not _ros2_threads(), timeout=10, message="the dispatcher outlived close()")
        assert pub.publish({"data": 2}) is False  # closed: refused quietly, not counted
    finally:
        ros.close()  # idempotent: also when an assertion failed


def test_closing_the_last_participant_frees_the_domain_for_another_config(domain: int) -> None:
    with Participant(domain) as first, Participant(domain) as second:
        assert first.domain_id == second.domain_id == domain
        with pytest.raises(DomainError, match="another network configuration"):
            Participant(domain, network=Network.loopback(max_participants=8))
    with Participant(domain, network=Network.loopback(max_participants=8)) as third:
        assert third.network.max_participants == 8


def test_unconvertible_samples_are_refused_and_counted_and_hooks_refuse(domain: int, topic: str) -> None:
    got: list[float] = []
    finite = lambda m: math.isfinite(m.data)  # noqa: E731  (the caller's range check)
    with Participant(domain) as ros:
        pub = ros.publisher(topic, "std_msgs/msg/Float64", QoS.buffer(10))
        strict = ros.publisher(topic, "std_msgs/msg/Float64", QoS.buffer(10),
                               accept=lambda m: math.isfinite(m["data"]))
        sub = ros.subscribe(topic, "std_msgs/msg/Float64", lambda m: got.append(m.data), QoS.buffer(10),
                            accept=finite)
        wait_until(lambda: pub.matched() and sub.matched(), timeout=15)
        assert pub.publish({"data": "one"}) is False
        assert pub.publish({"data": 1.0, "extra": 2}) is False
        assert strict.publish({"data": math.inf}) is False
        assert pub.publish({"data": math.nan}) is True  # NaN is the caller's concern: it goes
        assert pub.publish({"data": 2.0}) is True
        wait_until(lambda: got == [2.0] and sub.stats().refused == 1, timeout=15,
                   message=f"{got} {sub.stats()}")
        assert pub.stats().refused == 2 and pub.stats().published == 2
        assert "no field 'extra'" in (pub.stats().last_refusal or "")
        assert strict.stats().last_refusal == "refused by the accept hook"
        assert sub.stats().last_refusal == "refused by the accept hook"


def test_a_callback_that_raises_is_counted_and_delivery_goes_on(domain: int, topic: str) -> None:
    got: list[int] = []

    def flaky(message) -> None:
        if message.data == 1:
            raise RuntimeError("boom")
        got.append(message.data)

    with Participant(domain) as ros:
        pub = ros.publisher(topic, "std_msgs/msg/Int64", QoS.buffer(10))
        sub = ros.subscribe(topic, "std_msgs/msg/Int64", flaky, QoS.buffer(10))
        wait_until(lambda: pub.matched() and sub.matched(), timeout=15)
        for i in range(3):
            pub.publish({"data": i})
        wait_until(lambda: got == [0, 2], timeout=15)
        assert sub.stats().callback_errors == 1 and sub.stats().delivered == 2


def test_a_closed_subscription_stops_delivering(domain: int, topic: str) -> None:
    got: list[int] = []
    with Participant(domain) as ros:
        pub = ros.publisher(topic, "std_msgs/msg/Int64", QoS.buffer(10))
        sub = ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: got.append(m.data), QoS.buffer(10))
        other = ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: got.append(-m.data), QoS.buffer(10))
        wait_until(lambda: pub.matched() == 2, timeout=15)
        sub.close()
        sub.close()
        wait_until(lambda: pub.matched() == 1, timeout=15)
        pub.publish({"data": 5})
        wait_until(lambda: got, timeout=15)
        assert got == [-5] and other.stats().delivered == 1


def test_close_while_threads_publish_and_a_callback_runs(domain: int, topic: str) -> None:
    ros = Participant(domain)
    workers: list[threading.Thread] = []
    try:
        pub = ros.publisher(topic, "std_msgs/msg/Int64", QoS.buffer(10))
        got = threading.Event()
        ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: got.set(), QoS.buffer(10))
        results: list[bool] = []
        errors: list[BaseException] = []

        def hammer() -> None:
            try:
                for i in range(200_000):  # bounded; ends at the first refusal after close
                    sent = pub.publish({"data": i})
                    results.append(sent)
                    if not sent and ros.closed:
                        break
            except BaseException as exc:  # noqa: BLE001  (the test is that nothing escapes)
                errors.append(exc)

        workers += [threading.Thread(target=hammer, name=f"hammer-{i}") for i in range(3)]
        for worker in workers:
            worker.start()
        assert got.wait(15)
        ros.close()
        for worker in workers:
            worker.join(30)
        assert errors == [] and not any(w.is_alive() for w in workers)
        assert True in results and results[-1] is False  # sent before close, refused quietly after
        assert _ros2_threads() == []
    finally:
        ros.close()  # idempotent: also when an assertion failed; the hammers then stop
        for worker in workers:
            worker.join(30)


def test_a_bad_node_name_is_refused_and_frees_the_domain(domain: int) -> None:
    with pytest.raises(ValueError, match="ROS 2 node name '1arm'"):
        Participant(domain, node="1arm")
    with pytest.raises(ValueError, match="ROS 2 name"):
        Participant(domain, node="arm", namespace="/a//b")
    with Participant(domain, network=Network.loopback(max_participants=4), node="arm", distro="humble") as ros:
        assert ros.node is not None and ros.node.namespace == "/"
        assert len(ros.node._gid) == 24  # Humble's Gid: the 16-byte GUID, zero-padded
