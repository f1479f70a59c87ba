"""scart's ``ros1`` transport: a thin adapter over the ROS 1 node library :mod:`scart_ros1`
(which knows nothing of scart's ports). Its modules are imported only when used:
:mod:`.transport` (:class:`~.transport.Ros1Transport`: streams joining ports to topics
through one node per process), :mod:`.convert` (a port's type onto a message type:
std_msgs wrappers, field names, converters; checked when planned), :mod:`.calls`
(services both ways: task or SCA operations answering ROS services, ROS services called
from scart) and :mod:`.citizen` (the tasks' properties as the node's parameters,
``use_sim_time``, the log on ``/rosout`` through :mod:`.rosout`).
"""
