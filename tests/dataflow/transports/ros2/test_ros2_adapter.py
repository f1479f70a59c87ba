"""The ``ros2`` transport's own names over :mod:`scart_ros2`: a stream's QoS from its
policy, and what the adapter exports (no network used)."""

from __future__ import annotations

import pytest

pytest.importorskip("cyclonedds.qos", reason="cyclonedds is not installed (pip install 'scart[ros2]')")

from cyclonedds.qos import Policy  # noqa: E402

from dataflow import ConnPolicy  # noqa: E402
from dataflow.transports.ros2 import qos_of  # noqa: E402
from scart_ros2 import Durability, QoS, Reliability  # noqa: E402


def test_a_streams_qos_follows_rclpy_unless_asked_otherwise() -> None:
    assert qos_of(ConnPolicy.data()) == QoS(10, Reliability.RELIABLE, Durability.VOLATILE)  # rclpy's default
    assert qos_of(ConnPolicy.buffer(4)) == QoS(4, Reliability.RELIABLE, Durability.VOLATILE)
    asked = qos_of(ConnPolicy.data(), best_effort=True, latch=True,
                   seconds={"deadline": 0.5, "lifespan": 2.0, "liveliness_lease": 3.0})
    assert str(asked) == ("keep-last 10, best-effort, transient-local, deadline 0.5 s, lifespan 2 s, "
                          "liveliness lease 3 s")
    cyclone = asked.to_cyclone()
    assert cyclone[Policy.Deadline].deadline == 500_000_000 and cyclone[Policy.Lifespan].lifespan == 2_000_000_000
    assert cyclone[Policy.Liveliness] == Policy.Liveliness.Automatic(lease_duration=3_000_000_000)
    with pytest.raises(ValueError, match="deadline"):
        QoS(deadline=0.0)


def test_the_adapters_public_api_is_exactly_this() -> None:
    import dataflow.transports.ros2 as ros2

    assert sorted(ros2.__all__) == sorted(["Ros2Transport", "qos_of", "serve", "serve_operation", "ServedService",
                                           "ServiceProxy", "call_service", "check_service", "ros2_transport",
                                           "NETWORK_OPTIONS", "add_type_file"])
    assert all(hasattr(ros2, name) for name in ros2.__all__)
