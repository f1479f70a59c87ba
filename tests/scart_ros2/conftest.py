"""The ROS 2 fixtures (:mod:`support.ros2`): this run's domain, unique topics, the peers."""

from support.ros2 import domain, peer, stream_peer, topic  # noqa: F401  (fixtures)
