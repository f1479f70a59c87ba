"""A native ROS 1 node in Python, without rospy: the Master API, the Slave API, TCPROS
topics and services, message definitions and md5sums, names and remapping, parameters.

A library of its own: it depends on the standard library, ``rosbags`` (message types and
the ROS 1 wire format) and numpy (rosbags' arrays) only, and knows nothing of scart's
ports (it imports nothing of scart): its edges are bytes and rosbags message objects.
scart's ``ros1`` transport (``dataflow.transports.ros1``) is a thin adapter over it.

The story — make a node, offer and use topics and services, close it::

    from scart_ros1 import Node

    node = Node("scart", master_uri=None, host="127.0.0.1", remaps=["__ns:=/robot"])
    pub = node.advertise("/joint_states", "sensor_msgs/JointState", latch=False)
    pub.publish(pub.type.new(name=["a1"], position=[0.5]))    # or pub.publish_raw(ros1_bytes)
    sub = node.subscribe("cmd", "std_msgs/Float64", lambda msg: print(msg.data))  # /robot/cmd
    srv = node.advertise_service("~reset", "std_srvs/Trigger",
                                 lambda req: srv.type.response.new(success=True, message="done"))
    trigger = node.types.srv("std_srvs/Trigger")
    resp = node.call_service("/other/trigger", "std_srvs/Trigger", trigger.request.new(), timeout=2.0)
    node.close()

**Threads.** ``Node(...)`` starts, and :meth:`Node.close` ends (idempotent, from any
thread): one *io* thread reading every TCPROS socket through a selector (subscriber
callbacks run there: keep them short); one *XML-RPC* thread accepting calls to the node's
Slave API and up to 8 serving them side by side (a slow client holds one); one *control*
thread for blocking control-plane work (master calls, connecting to publishers); and,
once a service is advertised, one *service* thread running handlers.
``publish()`` sends from the caller's thread when the socket takes the bytes, else queues
them for the io thread; a slow subscriber's queue is bounded (oldest dropped, counted).

**The master.** Taken from ``master_uri``, ``__master:=``, ``ROS_MASTER_URI``, or ROS's
default. Registration is asynchronous and kept true: while the master is down the node
waits and retries with backoff, logging that it waits (once, then every 30 s); when it
answers again, or a poll shows a new master forgot the node, everything is registered
again. :meth:`Node.wait_registered` blocks until the master knows it all.

**Names.** As rospy: global ``/a``, relative ``a`` (in the node's namespace), private
``~a``; remaps ``from:=to``, ``__name:=``, ``__ns:=`` (:mod:`.names`).

**Parameters and lifecycle.** :meth:`Node.get_param`, :meth:`~Node.set_param` and
:meth:`~Node.subscribe_param` (``paramUpdate``, kept subscribed across master restarts)
use the master's parameter server. A peer's ``shutdown`` (``rosnode kill``) closes the
node and calls its :meth:`~Node.add_shutdown_hook` hooks, as rospy's ``on_shutdown``; a
``respawn`` node registers everything again instead; a ``read_only`` node publishes only
(it neither subscribes nor serves, and refuses ``shutdown``).

**Types.** :class:`MessageTypes`: rosbags' Noetic store, std_srvs' Empty/Trigger/SetBool,
and ``.msg``/``.srv`` files or texts the user adds; md5sums and definitions as genmsg.

**Robustness.** Peers are bounded (:class:`Limits`): header size and time, message size,
connections in all and from one address, XML-RPC request size and time; a service
connection with no request, or a subscriber taking none of what waits for it, for
``idle_seconds`` is closed. Malformed headers, oversized messages,
stalled peers, md5sum mismatches, vanished peers and master retries are each counted in
``node.counters`` (and the publisher's, subscriber's or service's ``counters``), logged,
and survived.

**Security.** ROS 1 authenticates no one: the node listens on ``host`` (loopback by
default); an explicit other host opens it to that network.
"""

from __future__ import annotations

import importlib
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .master import Master, MasterError, MasterUnreachable
    from .msgs import FieldDef, MessageTypes, MsgType, SrvType, TypeDefinitionError, UnknownTypeError
    from .names import NodeNames, RosNameError
    from .node import NODE_COUNTERS, Node
    from .services import ServiceError, ServiceServer
    from .tcpros import HeaderError, Limits
    from .topics import Publisher, Subscriber

#: Where each public name lives: imported when first asked for, so that loading scart's
#: ``ros1`` transport (``auto`` reads every transport's rank) costs no rosbags or numpy import.
_WHERE = MappingProxyType({
    "FieldDef": "msgs", "MessageTypes": "msgs", "MsgType": "msgs", "SrvType": "msgs", "TypeDefinitionError": "msgs",
    "UnknownTypeError": "msgs", "Master": "master", "MasterError": "master", "MasterUnreachable": "master",
    "NodeNames": "names", "RosNameError": "names", "NODE_COUNTERS": "node", "Node": "node",
    "ServiceError": "services", "ServiceServer": "services", "HeaderError": "tcpros", "Limits": "tcpros",
    "Publisher": "topics", "Subscriber": "topics",
})


def __getattr__(name: str) -> object:
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


__all__ = [
    "NODE_COUNTERS",
    "FieldDef",
    "HeaderError",
    "Limits",
    "Master",
    "MasterError",
    "MasterUnreachable",
    "MessageTypes",
    "MsgType",
    "Node",
    "NodeNames",
    "Publisher",
    "RosNameError",
    "ServiceError",
    "ServiceServer",
    "SrvType",
    "Subscriber",
    "TypeDefinitionError",
    "UnknownTypeError",
]
