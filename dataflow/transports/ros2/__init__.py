"""scart's ``ros2`` transport: a thin adapter over :mod:`scart_ros2` (a DDS participant with
ROS 2's names, which knows nothing of scart's ports).

:class:`Ros2Transport` (the ``scart.transports`` entry point ``ros2``: a port joined to a
ROS 2 topic by a stream, its type mapped onto a ROS 2 message, see :mod:`._transport` and
:mod:`._convert`), and services both ways (:func:`serve_operation`, :func:`serve`,
:class:`ServiceProxy`, :func:`call_service`; :mod:`._calls`), on the process's one
participant per domain. The transport's node also serves its tasks' properties as
parameters (``rcl_interfaces`` services) and logs to ``/rosout`` (:mod:`._citizen`).
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING

from scart_ros2.errors import lazy_names

if TYPE_CHECKING:
    from ._calls import ServedService, ServiceProxy, call_service, check_service, ros2_transport, serve, serve_operation
    from ._transport import NETWORK_OPTIONS, Ros2Transport, add_type_file, qos_of

#: Where each public name lives: imported when first asked for, so that loading the ``ros2``
#: transport (``auto`` reads every transport's rank) imports neither Cyclone DDS nor rosbags,
#: and works without the ``scart[ros2]`` extra (a stream then says it is missing).
_WHERE = MappingProxyType({
    **dict.fromkeys(("ServedService", "ServiceProxy", "call_service", "check_service", "ros2_transport", "serve",
                     "serve_operation"), "_calls"),
    **dict.fromkeys(("NETWORK_OPTIONS", "Ros2Transport", "add_type_file", "qos_of"), "_transport"),
})


__getattr__ = lazy_names(__name__, _WHERE)


__all__ = ["NETWORK_OPTIONS", "Ros2Transport", "ServedService", "ServiceProxy", "add_type_file", "call_service",
           "check_service", "qos_of", "ros2_transport", "serve", "serve_operation"]
