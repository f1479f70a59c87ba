"""ROS 2 over DDS with Cyclone DDS: a participant with ROS 2's names, topics and services
as rmw_cyclonedds puts them on the wire.

The story: make a :class:`Participant` (a domain id, else ``ROS_DOMAIN_ID``; loopback
only unless told otherwise), then publish and subscribe ROS 2 messages by their ROS names,
serve and call services, and close it::

    from scart_ros2 import Participant, QoS

    with Participant(node="scart") as ros:
        pub = ros.publisher("/joint_states", "sensor_msgs/msg/JointState", QoS.buffer(10))
        sub = ros.subscribe("/cmd", "std_msgs/msg/Float64", on_cmd)   # on_cmd(msg) on ros's thread
        pub.publish({"name": ["j1"], "position": [0.5]})   # False if refused (counted)
        ros.client("/add", "example_interfaces/srv/AddTwoInts").call({"a": 1, "b": 2})

A library of its own: it depends on the standard library, Cyclone DDS, ``rosbags`` and
numpy only, and knows nothing of scart's ports (it imports nothing of scart): messages
are rosbags message objects or plain dicts at its edges, and QoS is its own small value
(:class:`QoS`). scart's ``ros2`` transport (``dataflow.transports.ros2``: streams joining
ports to topics, a port's type mapped onto a message, services both ways, the tasks'
properties as parameters) is a thin adapter over it.

What it puts on the wire (what ``ros2 topic echo`` over rmw_cyclonedds reads):

================  =========================================================================
topic             ``/foo/bar`` → DDS topic ``rt/foo/bar`` (:func:`dds_topic`)
type              ``pkg/msg/Type`` → ``pkg::msg::dds_::Type_``, a final IDL struct built from
                  rosbags' definitions of the distro (default Jazzy) or the user's ``.msg``
                  (:class:`MessageTypes`); plain CDR (XCDR1, little-endian), the bytes
                  rosbag2 stores (checked against rosbags' serialiser)
QoS               :class:`QoS`: keep-last n, reliable unless best-effort, latching →
                  transient-local, deadline, lifespan, liveliness lease (as rmw maps ROS 2 QoS)
user data         ``typehash=RIHS01_...;`` on each endpoint (Iron and later), ``enclave=/;``
                  on the participant, as rmw_cyclonedds announces them
service           ``/add`` → ``rq/addRequest`` + ``rr/addReply``, types
                  ``pkg::srv::dds_::Name_Request_``/``_Response_`` prefixed with rmw's request
                  header (client writer's instance handle, sequence number); see :mod:`.services`
network           :class:`Network`: loopback only (no multicast, peer 127.0.0.1) by default;
                  ``insecure=True`` opens it to the network
================  =========================================================================

Services went the rmw_cyclonedds way in full: header, ``clientid=``/``serviceid=`` user
data, the server waiting (≤ 100 ms) for the client's reply reader as rmw does. It is
tested against an independent peer written from rmw_cyclonedds' sources, not against a
ROS 2 install (none is on PyPI). ``Participant(node="name", namespace="/ns")`` also
makes it a ROS 2 node: rmw_dds_common's ``ros_discovery_info`` names the node and its
readers and writers, which ``ros2 node list``/``node info`` read (``ros2 topic list`` and
``echo`` need only DDS discovery). Not done: actions, content filters, ``wstring``.

Robustness: a sample that cannot be converted (wrong shape, out of its type's range,
malformed CDR, refused by an ``accept`` hook) is refused and counted
(:meth:`Publisher.stats`, :meth:`Subscription.stats`), never raised into the peer or the
callback. NaN and application ranges are the caller's: pass ``accept=`` hooks. Cyclone
itself checks CDR structure: a truncated sample is refused by the writer's Cyclone
before it is sent. Each participant owns one thread, started with its first reader and
ended by ``close()`` (idempotent, callable from a callback), which also deletes every DDS
entity and, with the last participant of the process on that domain, the domain.

**rmw_zenoh, and what scart's Zenoh transport lacks to be seen by a ROS 2 node there.**
rmw_zenoh_cpp (Jazzy and later) puts a topic's samples, in the same CDR as above, on the
key expression ``<domain_id>/<fully qualified name without the leading />/<DDS type
name>/<type hash>``, e.g.
``0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c74...``; services are Zenoh
queryables on the same form (``2/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/
RIHS01_...``), called with ``get`` (target ALL_COMPLETE). Every put and get carries an
attachment: int64 sequence number, int64 source timestamp (ns since the epoch), both
little-endian, a length byte (16) and the 16-byte GID of the publisher/client. The graph
is liveliness tokens: ``@ros2_lv/<domain>/<session id>/<node id>/<node id>/NN/<enclave>/
<namespace>/<node name>`` for a node and ``@ros2_lv/<domain>/<session id>/<node id>/
<entity id>/<MP|MS|SS|SC>/<enclave>/<namespace>/<node name>/<mangled topic>/<type name>/
<type hash>/<qos>`` for an endpoint (names mangled ``/`` → ``%``, empty ``%``; QoS in a
compact ``reliability:durability:history,depth:deadline:lifespan:liveliness`` form where
defaults are left empty). Transient-local uses Zenoh's advanced publisher cache. Sessions
are peers that connect to a router on ``tcp/localhost:7447`` (multicast scouting off).
So scart's Zenoh transport, to be seen and read by a ROS 2 node, would still need: keys in
that form instead of scart's own; CDR payloads of ROS message types (this package's
:class:`MessageTypes` gives the bytes and :meth:`MessageTypes.type_hash` the RIHS01 hash)
instead of scart's codec; the attachment on every put; a node token and one token per
endpoint for ``ros2 node list``/``topic list`` and for rmw_zenoh's matched counts; the
advanced publisher/subscriber for latching; queryables for services; and to run as a
peer of the router ROS 2 uses.

**DDS Security (SROS2).** SROS2 gives each enclave a governance and a permissions document
(signed, ``.p7s``) and an identity certificate, set as the participant properties
``dds.sec.auth.*``, ``dds.sec.access.*`` and ``dds.sec.crypto.*`` naming Cyclone's
plugins (``dds_security_auth``, ``dds_security_ac``, ``dds_security_crypto``).
cyclonedds-python can set such properties (``Policy.Property``) and the ``libddsc`` in its
wheel has the security core compiled in, but the wheel ships none of the three plugin
libraries (they need OpenSSL): with a Cyclone DDS C build of the same version providing
them on the library path it is reachable; from PyPI alone it is not. Not built here.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import TYPE_CHECKING

from .errors import lazy_names

if TYPE_CHECKING:
    from .endpoints import Publisher, PublisherStats, Subscription, SubscriptionStats
    from .errors import ConversionError, DomainError, Ros2Error, UnknownTypeError
    from .msgs import DISTROS, MessageTypes, message_to_dict
    from .names import dds_topic, dds_type_name, ros_topic, ros_type_name, service_topics, topic_name
    from .network import Network, resolve_domain_id
    from .participant import Participant
    from .qos import Durability, QoS, Reliability
    from .services import ServiceClient, ServiceServer

#: Where each public name lives: imported when first asked for, so that importing the package
#: imports neither Cyclone DDS nor rosbags, and works without them (a name that needs Cyclone
#: DDS then says it is missing).
_WHERE = MappingProxyType({
    **dict.fromkeys(("Publisher", "PublisherStats", "Subscription", "SubscriptionStats"), "endpoints"),
    **dict.fromkeys(("ConversionError", "DomainError", "Ros2Error", "UnknownTypeError"), "errors"),
    **dict.fromkeys(("dds_topic", "dds_type_name", "ros_topic", "ros_type_name", "service_topics", "topic_name"),
                    "names"),
    **dict.fromkeys(("Network", "resolve_domain_id"), "network"),
    "Participant": "participant",
    **dict.fromkeys(("Durability", "QoS", "Reliability"), "qos"),
    **dict.fromkeys(("ServiceClient", "ServiceServer"), "services"),
    **dict.fromkeys(("DISTROS", "MessageTypes", "message_to_dict"), "msgs"),
})


__getattr__ = lazy_names(__name__, _WHERE)


__all__ = [
    "Participant", "Publisher", "Subscription", "ServiceServer", "ServiceClient",
    "PublisherStats", "SubscriptionStats", "QoS", "Reliability", "Durability", "Network",
    "MessageTypes", "DISTROS", "message_to_dict", "resolve_domain_id",
    "dds_topic", "ros_topic", "service_topics", "topic_name", "dds_type_name", "ros_type_name",
    "Ros2Error", "ConversionError", "DomainError", "UnknownTypeError",
]
