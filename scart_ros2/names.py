"""ROS 2 names as rmw_cyclonedds spells them in DDS: topics, service topics and type names.

============================  =======================================================
ROS 2                         DDS (rmw_cyclonedds)
============================  =======================================================
topic ``/foo/bar``            topic ``rt/foo/bar``
service ``/add``              request topic ``rq/addRequest``, reply topic ``rr/addReply``
type ``std_msgs/msg/Float64``  type ``std_msgs::msg::dds_::Float64_``
type ``pkg/srv/Add_Request``   type ``pkg::srv::dds_::Add_Request_`` (``_Response`` alike)
============================  =======================================================

A name without a leading ``/`` is taken relative to the root namespace (there is no node
namespace here): ``chatter`` is ``/chatter``. Names are checked with ROS 2's rules (rcl's
``rmw_validate_full_topic_name``): ``[A-Za-z0-9_/]``, no ``//``, no trailing ``/``, no
token starting with a digit, at most 255 characters once prefixed.
"""

from __future__ import annotations

import re

__all__ = ["check_node_name", "topic_name", "dds_topic", "ros_topic", "service_topics", "dds_type_name",
           "ros_type_name"]

TOPIC_PREFIX = "rt"
REQUEST_PREFIX = "rq"
REPLY_PREFIX = "rr"
_MAX_DDS_TOPIC = 255  # rmw's limit on a fully qualified DDS topic name
_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_TYPE = re.compile(r"([A-Za-z][A-Za-z0-9_]*)/(msg|srv)/([A-Za-z][A-Za-z0-9_]*)\Z")
_NODE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,254}\Z")
_DDS_TYPE = re.compile(r"([A-Za-z][A-Za-z0-9_]*)::(msg|srv)::dds_::([A-Za-z][A-Za-z0-9_]*)_\Z")


def topic_name(name: str) -> str:
    """``name`` fully qualified (``chatter`` → ``/chatter``); raises ``ValueError`` naming
    what is wrong when it is not a valid ROS 2 topic or service name."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"a ROS 2 name must be a non-empty string, got {name!r}")
    full = name if name.startswith("/") else "/" + name
    if full != "/" and full.endswith("/"):
        raise ValueError(f"ROS 2 name {name!r} must not end with '/'")
    tokens = full[1:].split("/")
    for token in tokens:
        if not _TOKEN.match(token):
            raise ValueError(
                f"ROS 2 name {name!r}: {token!r} is not a valid token (letters, digits and _, "
                "not starting with a digit, no empty token)")
    if len(full) + len(TOPIC_PREFIX) > _MAX_DDS_TOPIC:
        raise ValueError(f"ROS 2 name {name!r} is longer than {_MAX_DDS_TOPIC - len(TOPIC_PREFIX)} characters")
    return full


def check_node_name(name: str, namespace: str) -> tuple[str, str]:
    """``(name, namespace)`` as ROS 2 has them (``/`` for the root namespace); raises
    ``ValueError`` for a name or namespace ROS 2 would refuse."""
    if not _NODE_NAME.match(name or ""):
        raise ValueError(f"ROS 2 node name {name!r}: letters, digits and _, not starting with a digit")
    return name, "/" if namespace in ("", "/") else topic_name(namespace)


def dds_topic(name: str) -> str:
    """The DDS topic of ROS 2 topic ``name``: ``/foo/bar`` → ``rt/foo/bar``."""
    return TOPIC_PREFIX + topic_name(name)


def ros_topic(dds_name: str) -> str | None:
    """The ROS 2 topic a DDS topic carries (``rt/foo`` → ``/foo``), or ``None`` for a DDS
    topic that is not a ROS 2 topic (``rq/``, ``rr/``, ``DCPS...``)."""
    if dds_name.startswith(TOPIC_PREFIX + "/"):
        return dds_name[len(TOPIC_PREFIX):]
    return None


def service_topics(name: str) -> tuple[str, str]:
    """The request and reply DDS topics of ROS 2 service ``name``:
    ``/add`` → (``rq/addRequest``, ``rr/addReply``)."""
    full = topic_name(name)
    return f"{REQUEST_PREFIX}{full}Request", f"{REPLY_PREFIX}{full}Reply"


def split_type_name(ros_type: str) -> tuple[str, str, str]:
    """(package, ``msg``/``srv``, name) of ``pkg/msg/Name``; raises ``ValueError``."""
    match = _TYPE.match(ros_type) if isinstance(ros_type, str) else None
    if not match:
        raise ValueError(f"{ros_type!r} is not a ROS 2 type name (pkg/msg/Type or pkg/srv/Type)")
    return match.group(1), match.group(2), match.group(3)


def dds_type_name(ros_type: str) -> str:
    """``pkg/msg/Type`` → ``pkg::msg::dds_::Type_`` (rosidl's DDS type name)."""
    package, kind, name = split_type_name(ros_type)
    return f"{package}::{kind}::dds_::{name}_"


def ros_type_name(dds_type: str) -> str:
    """``pkg::msg::dds_::Type_`` → ``pkg/msg/Type``; raises ``ValueError`` for a DDS type
    name that is not a ROS 2 one."""
    match = _DDS_TYPE.match(dds_type)
    if not match:
        raise ValueError(f"{dds_type!r} is not a ROS 2 DDS type name (pkg::msg::dds_::Type_)")
    return f"{match.group(1)}/{match.group(2)}/{match.group(3)}"
