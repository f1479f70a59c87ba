"""ROS 2 topics on the wire, judged by an independent Cyclone DDS peer and the
``cyclonedds`` command: what we publish they read, what they publish we read, with the
ROS 2 names and types; QoS observable; bad samples refused and counted."""

from __future__ import annotations

import pytest

pytest.importorskip("cyclonedds.domain", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from support.ros2 import cli as _cli  # noqa: E402
from support.ros2 import cli_subscribe as _cli_subscribe  # noqa: E402

from scart_ros2 import Participant, QoS  # noqa: E402
from support import wait_until  # noqa: E402

pytestmark = pytest.mark.integration


def _matched(*endpoints: object) -> None:
    wait_until(lambda: all(e.matched() for e in endpoints), timeout=15, message="endpoints never matched")


def test_the_peer_reads_what_we_publish_and_we_read_what_it_publishes(domain: int, peer) -> None:
    relay = peer("relay")
    got: list[float] = []
    with Participant(domain) as ros:
        pub = ros.publisher("/peer/in", "std_msgs/msg/Float64", QoS.buffer(10))
        sub = ros.subscribe("peer/out", "std_msgs/msg/Float64", lambda m: got.append(m.data), QoS.buffer(10))
        _matched(pub, sub)
        for value in (0.5, 1.5, 2.5):
            assert pub.publish(ros.types.message_class("std_msgs/msg/Float64")(data=value))
        assert [relay.next_event("float64")["data"] for _ in range(3)] == [0.5, 1.5, 2.5]
        wait_until(lambda: len(got) == 3, timeout=15, message=f"relayed values never arrived: {got}")
        assert got == [1.5, 2.5, 3.5]
        assert sub.stats().refused == 0 and pub.stats().published == 3


def test_a_joint_state_with_its_header_round_trips_through_the_peer(domain: int, peer) -> None:
    relay = peer("relay")
    back: list[dict] = []
    sent = {"header": {"stamp": {"sec": 1_700_000_000, "nanosec": 123_456_789}, "frame_id": "base_link"},
            "name": ["joint_1", "joint_2"], "position": [0.25, -1.5], "velocity": [0.0, 2.0], "effort": []}
    with Participant(domain) as ros:
        pub = ros.publisher("/peer/js_in", "sensor_msgs/msg/JointState", QoS.buffer(10))
        sub = ros.subscribe("/peer/js_out", "sensor_msgs/msg/JointState", back.append, QoS.buffer(10), as_dict=True)
        _matched(pub, sub)
        assert pub.publish(sent)
        seen = relay.next_event("joint_state")
        assert (seen["frame_id"], seen["sec"], seen["nanosec"]) == ("base_link", 1_700_000_000, 123_456_789)
        assert (seen["name"], seen["position"], seen["velocity"]) == (["joint_1", "joint_2"], [0.25, -1.5], [0.0, 2.0])
        wait_until(lambda: back, timeout=15, message="the joint state never came back")
    expected = {**sent, "header": {**sent["header"], "frame_id": "peer:base_link"}, "position": [0.5, -3.0]}
    assert back == [expected]


def test_a_malformed_sample_from_a_peer_is_refused_and_counted(domain: int, peer) -> None:
    peer("bad")
    good: list[str] = []
    with Participant(domain) as ros:
        sub = ros.subscribe("/peer/bad", "sensor_msgs/msg/JointState", lambda m: good.append(m.header.frame_id),
                            QoS.buffer(10))
        wait_until(lambda: sub.stats().refused >= 2 and good, timeout=15,
                   message=f"bad samples not counted or good ones lost: {sub.stats()}")
        stats = sub.stats()
    assert set(good) == {"good"}
    assert "malformed" in (stats.last_refusal or "") and stats.callback_errors == 0


def test_our_service_answers_an_independent_rmw_style_client(domain: int, peer) -> None:
    with Participant(domain) as ros:
        server = ros.service("/peer/add", "example_interfaces/srv/AddTwoInts", lambda r: {"sum": r.a + r.b})
        client = peer("client")
        reply = client.next_event("reply")
        assert (reply["sum"], reply["seq"], reply["mine"]) == (42, 7, True)
        assert server.answered == 1 and server.refused == 0


def test_a_service_call_between_two_participants(domain: int) -> None:
    with Participant(domain) as a, Participant(domain) as b:
        a.service("/math/add", "example_interfaces/srv/AddTwoInts", lambda r: {"sum": r.a + r.b})
        bad = a.service("/math/broken", "std_srvs/srv/Trigger", lambda r: 1 / 0)
        client = b.client("math/add", "example_interfaces/srv/AddTwoInts")
        assert client.wait_for_service(15)
        assert [client.call({"a": i, "b": 100}, timeout=10).sum for i in range(3)] == [100, 101, 102]
        broken = b.client("/math/broken", "std_srvs/srv/Trigger")
        assert broken.wait_for_service(15)
        with pytest.raises(TimeoutError):
            broken.call({}, timeout=0.5)
        assert bad.refused == 1 and "division" in (bad.last_refusal or "")


def test_the_cyclonedds_tool_lists_our_topics_with_ros2_type_names(domain: int, topic: str) -> None:
    with Participant(domain) as ros:
        ros.publisher(topic, "std_msgs/msg/Float64")
        ros.publisher(topic + "_js", "sensor_msgs/msg/JointState")
        listing = _cli("ls", "--id", str(domain), "--runtime", "2", "--topic", "rt" + topic + ".*").stdout
    assert "rt" + topic in listing and "std_msgs::msg::dds_::Float64_" in listing, listing
    assert "rt" + topic + "_js" in listing and "sensor_msgs::msg::dds_::JointState_" in listing, listing


def test_the_cyclonedds_tool_prints_our_samples(domain: int, topic: str) -> None:
    with Participant(domain) as ros:
        pub = ros.publisher(topic, "std_msgs/msg/Float64")
        out, err = _cli_subscribe(domain, "rt" + topic, lambda: pub.publish({"data": 41.5}) and pub.matched())
    assert "Float64_(data=41.5)" in out, (out, err)


def test_the_cyclonedds_tool_prints_a_joint_state_with_its_nested_types(domain: int, topic: str) -> None:
    sample = {"header": {"stamp": {"sec": 7, "nanosec": 8}, "frame_id": "arm"}, "name": ["j1"], "position": [0.5]}
    with Participant(domain) as ros:
        pub = ros.publisher(topic, "sensor_msgs/msg/JointState")
        out, err = _cli_subscribe(domain, "rt" + topic, lambda: pub.publish(sample) and pub.matched())
    assert "header=Header_(stamp=Time_(sec=7, nanosec=8), frame_id='arm')" in out, (out, err)
    assert "name=['j1'], position=[0.5]" in out, (out, err)


def test_our_client_calls_an_independent_rmw_style_server(domain: int, peer) -> None:
    server = peer("server")
    with Participant(domain) as ros:
        client = ros.client("/peer/times", "example_interfaces/srv/AddTwoInts")
        assert client.wait_for_service(15)
        assert client.call({"a": 6, "b": 7}, timeout=10).sum == 42
        assert client.call({"a": 3, "b": 3}, timeout=10).sum == 9
    first, second = server.next_event("request"), server.next_event("request")
    assert (first["seq"], second["seq"]) == (1, 2) and first["guid"] == second["guid"] != 0
    assert (first["a"], first["b"]) == (6, 7)


def test_latching_hands_the_last_n_samples_to_a_late_joiner(domain: int, topic: str) -> None:
    with Participant(domain) as ros:
        latched = ros.publisher(topic, "std_msgs/msg/Int64", QoS.buffer(3, latching=True))
        for i in range(6):
            latched.publish({"data": i})
        got: list[int] = []
        ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: got.append(m.data), QoS.buffer(10, latching=True))
        wait_until(lambda: len(got) >= 3, timeout=15, message=f"the late joiner got {got}")
        latched.publish({"data": 99})
        wait_until(lambda: got[-1] == 99, timeout=15)
    assert got == [3, 4, 5, 99]


def test_a_volatile_late_joiner_gets_nothing_old(domain: int, topic: str) -> None:
    with Participant(domain) as ros:
        pub = ros.publisher(topic, "std_msgs/msg/Int64", QoS.buffer(3))
        for i in range(3):
            pub.publish({"data": i})
        got: list[int] = []
        sub = ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: got.append(m.data), QoS.buffer(10))
        _matched(pub, sub)
        pub.publish({"data": 99})
        wait_until(lambda: got, timeout=15)
    assert got == [99]


def test_keep_last_n_keeps_the_newest_n_for_a_slow_reader(domain: int, topic: str) -> None:
    import threading

    release, got = threading.Event(), []

    def slow(message) -> None:
        got.append(message.data)
        if len(got) == 1:
            release.wait(15)  # holds the dispatcher while 20 more samples arrive

    with Participant(domain) as a, Participant(domain) as b:
        pub = a.publisher(topic, "std_msgs/msg/Int64", QoS.buffer(20))
        sub = b.subscribe(topic, "std_msgs/msg/Int64", slow, QoS.buffer(4))
        _matched(pub, sub)
        pub.publish({"data": 0})
        wait_until(lambda: got, timeout=15)
        for i in range(1, 21):
            pub.publish({"data": i})
        # the reader's history holds at most 4: wait until the newest is there, then let go
        wait_until(lambda: sub._reader.read(N=10) and sub._reader.read(N=10)[-1].data == 20, timeout=15)
        release.set()
        wait_until(lambda: got[-1:] == [20], timeout=15)
    assert got == [0, 17, 18, 19, 20]


def test_a_best_effort_writer_does_not_match_a_reliable_reader(domain: int, topic: str) -> None:
    with Participant(domain) as ros:
        reliable_reader = ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: None, QoS.data())
        best_effort_reader = ros.subscribe(topic, "std_msgs/msg/Int64", lambda m: None, QoS.data(best_effort=True))
        pub = ros.publisher(topic, "std_msgs/msg/Int64", QoS.data(best_effort=True))
        wait_until(lambda: best_effort_reader.matched(), timeout=15)
        assert pub.matched() == 1 and reliable_reader.matched() == 0


def test_a_named_participant_is_a_node_in_the_ros2_graph(domain: int, peer, topic: str) -> None:
    graph = peer("graph")
    with Participant(domain, node="scart_arm", namespace="/robot") as ros:
        pub = ros.publisher(topic, "std_msgs/msg/Int64")
        sub = ros.subscribe(topic + "_in", "std_msgs/msg/Int64", lambda m: None)
        writer, reader = pub._writer.guid.bytes.hex(), sub._reader.guid.bytes.hex()
        participant = ros._dp.guid.bytes.hex()

        def node_event() -> dict:
            while True:
                event = graph.next_event("participant")
                if event["gid"] == participant:
                    return event

        while True:  # bounded by next_event's deadline: until both endpoints are announced
            event = node_event()
            if event["nodes"] and event["nodes"][0]["readers"]:
                break
        assert event["nodes"] == [{"namespace": "/robot", "name": "scart_arm", "readers": [reader],
                                   "writers": [writer]}]
        sub.close()
        assert node_event()["nodes"][0]["readers"] == []
    assert node_event()["nodes"] == []  # closing the participant takes the node out of the graph
