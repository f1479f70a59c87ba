"""ROS 2 names, QoS values, domain ids and the network configuration (no network used)."""

from __future__ import annotations

import pytest

pytest.importorskip("cyclonedds.qos", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from cyclonedds.qos import Policy  # noqa: E402

from scart_ros2 import (  # noqa: E402
    DomainError, Durability, Network, QoS, Reliability, dds_topic, dds_type_name, resolve_domain_id, ros_topic,
    ros_type_name, service_topics)


def test_topic_service_and_type_names_as_rmw_cyclonedds_spells_them() -> None:
    assert dds_topic("/foo/bar") == "rt/foo/bar" and dds_topic("chatter") == "rt/chatter"
    assert ros_topic("rt/foo/bar") == "/foo/bar" and ros_topic("rq/addRequest") is None
    assert service_topics("/add_two_ints") == ("rq/add_two_intsRequest", "rr/add_two_intsReply")
    assert dds_type_name("std_msgs/msg/Float64") == "std_msgs::msg::dds_::Float64_"
    assert dds_type_name("pkg/srv/Add_Request") == "pkg::srv::dds_::Add_Request_"
    assert ros_type_name("sensor_msgs::msg::dds_::JointState_") == "sensor_msgs/msg/JointState"


@pytest.mark.parametrize("name", ["", "/foo/", "/foo//bar", "/1abc", "/foo bar", "/ü", "~/x", "/" + "a" * 260])
def test_bad_ros_names_are_refused(name: str) -> None:
    with pytest.raises(ValueError, match="ROS 2 name"):
        dds_topic(name)


def test_bad_type_names_are_refused() -> None:
    with pytest.raises(ValueError, match="not a ROS 2 type name"):
        dds_type_name("std_msgs/Float64")  # the ROS 1 form
    with pytest.raises(ValueError, match="not a ROS 2 DDS type name"):
        ros_type_name("Float64")


def test_qos_named_constructors_follow_the_policies() -> None:
    assert QoS.data() == QoS(1, Reliability.RELIABLE, Durability.VOLATILE)
    assert QoS.buffer(8) == QoS(8, Reliability.RELIABLE, Durability.VOLATILE)
    assert QoS.data(best_effort=True).reliability is Reliability.BEST_EFFORT
    assert QoS.buffer(3, latching=True) == QoS.buffer(3).with_latching()
    assert QoS.data().with_best_effort() == QoS.data(best_effort=True)
    assert str(QoS.buffer(3, latching=True)) == "keep-last 3, reliable, transient-local"
    for bad in (0, -1, 10_001, 2.5, True):
        with pytest.raises(ValueError, match="depth"):
            QoS.buffer(bad)  # type: ignore[arg-type]


def test_qos_becomes_rmw_cyclonedds_policies() -> None:
    latched = QoS.buffer(5, latching=True).to_cyclone(b"typehash=x;", reader=True)
    assert latched[Policy.History].depth == 5
    assert latched[Policy.Durability] == Policy.Durability.TransientLocal
    assert latched[Policy.DurabilityService].history.depth == 5
    assert latched[Policy.Userdata].data == b"typehash=x;"
    assert latched[Policy.WriterDataLifecycle].autodispose is False
    assert latched[Policy.DataRepresentation].use_cdrv0_representation
    assert latched[Policy.TypeConsistency].ignore_member_names
    best_effort = QoS.data(best_effort=True).to_cyclone()
    assert best_effort[Policy.Reliability] == Policy.Reliability.BestEffort
    assert best_effort[Policy.Durability] == Policy.Durability.Volatile


def test_ros_domain_id_is_honoured_and_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    assert resolve_domain_id() == 0
    monkeypatch.setenv("ROS_DOMAIN_ID", " 42 ")
    assert resolve_domain_id() == 42 and resolve_domain_id(7) == 7
    for bad in ("x", "233", "-1"):
        monkeypatch.setenv("ROS_DOMAIN_ID", bad)
        with pytest.raises(DomainError, match="ROS_DOMAIN_ID"):
            resolve_domain_id()
    with pytest.raises(DomainError, match="domain_id=300"):
        resolve_domain_id(300)


def test_the_default_network_is_loopback_only() -> None:
    xml = Network.loopback().config_xml()
    assert '<NetworkInterface address="127.0.0.1"/>' in xml
    assert "<AllowMulticast>false</AllowMulticast>" in xml
    assert '<Peers><Peer address="127.0.0.1"/></Peers>' in xml
    assert "<MaxAutoParticipantIndex>31</MaxAutoParticipantIndex>" in xml
    assert xml.count("address=") == 2  # nothing but 127.0.0.1
    # large samples in 64 KB datagrams on loopback (its MTU: no IP fragments), Cyclone's default elsewhere
    assert "<MaxMessageSize>65500B</MaxMessageSize>" in xml and "MaxMessageSize" not in Network.open().config_xml()


def test_the_network_switch_opens_it_and_checks_what_it_is_given() -> None:
    xml = Network.open().config_xml()
    assert "<AllowMulticast>true</AllowMulticast>" in xml and "127.0.0.1" not in xml
    xml = Network.open("eth0", ("10.0.0.2",), multicast=False).config_xml()
    assert '<NetworkInterface name="eth0"/>' in xml and '<Peer address="10.0.0.2"/>' in xml
    with pytest.raises(DomainError, match="not an interface name"):
        Network.open('eth0"/><evil')
    with pytest.raises(DomainError, match="use Network.open"):
        Network(multicast=True)


def test_the_public_api_is_exactly_this() -> None:
    import scart_ros2 as ros2

    assert sorted(ros2.__all__) == sorted([
        "Participant", "Publisher", "Subscription", "ServiceServer", "ServiceClient",
        "PublisherStats", "SubscriptionStats", "QoS", "Reliability", "Durability", "Network",
        "MessageTypes", "DISTROS", "message_to_dict", "resolve_domain_id",
        "dds_topic", "ros_topic", "service_topics", "topic_name", "dds_type_name", "ros_type_name",
        "Ros2Error", "ConversionError", "DomainError", "UnknownTypeError"])
    assert all(hasattr(ros2, name) for name in ros2.__all__)
    assert all(issubclass(getattr(ros2, e), ros2.Ros2Error) for e in ("ConversionError", "DomainError",
                                                                      "UnknownTypeError"))
