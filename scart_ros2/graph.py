"""A ROS 2 node in the graph, announced as rmw_dds_common does over DDS.

ROS 2 tools (``ros2 node list``, ``ros2 node info``, ``ros2 topic info -v``) learn which
node owns which reader and writer from the DDS topic ``ros_discovery_info`` (no ``rt/``
prefix): each participant publishes one ``rmw_dds_common/msg/ParticipantEntitiesInfo``,
reliable, transient-local, keep-last 1, holding its GID and, per node, the namespace,
the name and the GIDs of the node's readers and writers. A GID is the entity's DDS GUID
(16 bytes; Humble's ``Gid`` holds 24, the rest zero). The sample is written again each
time an endpoint comes or goes. Topics themselves need none of this: ``ros2 topic list``
and ``echo`` see them through DDS discovery alone.
"""

from __future__ import annotations

import threading
from typing import Any

from cyclonedds.core import DDSException
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.topic import Topic

from .names import check_node_name
from .network import delete_entity
from .qos import QoS
from .msgs import MessageTypes

__all__ = ["NodeGraph", "DISCOVERY_TOPIC"]

DISCOVERY_TOPIC = "ros_discovery_info"
_INFO = "rmw_dds_common/msg/ParticipantEntitiesInfo"


class NodeGraph:
    """Announces one node of a participant and its endpoints (thread-safe).

    Raises ``ValueError`` for a node name or namespace ROS 2 would refuse.
    """

    def __init__(self, participant: DomainParticipant, types: MessageTypes, name: str, namespace: str) -> None:
        self.name, self.namespace = check_node_name(name, namespace)
        self._types = types
        self._gid_size = len(types.zero("rmw_dds_common/msg/Gid").data)
        self._gid = self._gid_of(participant)
        self._topic = Topic(participant, DISCOVERY_TOPIC, types.idl_type(_INFO))
        self._writer = DataWriter(participant, self._topic, qos=QoS.data(latching=True).to_cyclone())
        self._lock = threading.Lock()
        self._readers: dict[int, list[int]] = {}
        self._writers: dict[int, list[int]] = {}
        self._closed = False
        self._announce()

    def _gid_of(self, entity: Any) -> list[int]:
        guid = entity.guid.bytes  # dds_get_guid, as rmw_cyclonedds' get_entity_gid
        return list(guid.ljust(self._gid_size, b"\0")[: self._gid_size])

    def add(self, entity: object, reader: bool) -> None:
        """Announce ``entity`` (a DataReader or DataWriter) as this node's."""
        with self._lock:
            (self._readers if reader else self._writers)[id(entity)] = self._gid_of(entity)
        self._announce()

    def remove(self, entity: object) -> None:
        """Stop announcing ``entity``."""
        with self._lock:
            self._readers.pop(id(entity), None)
            self._writers.pop(id(entity), None)
        self._announce()

    def _announce(self) -> None:
        with self._lock:
            if self._closed:
                return
            node = {"node_namespace": self.namespace, "node_name": self.name,
                    "reader_gid_seq": [{"data": g} for g in self._readers.values()],
                    "writer_gid_seq": [{"data": g} for g in self._writers.values()]}
            try:
                self._writer.write(self._types.to_idl(_INFO, {"gid": {"data": self._gid},
                                                              "node_entities_info_seq": [node]}))
            except DDSException:
                pass  # the participant is being deleted

    def close(self) -> None:
        """Announce the node gone (no nodes), delete the writer. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._readers.clear()
            self._writers.clear()
        try:
            self._writer.write(self._types.to_idl(_INFO, {"gid": {"data": self._gid}, "node_entities_info_seq": []}))
        except DDSException:
            pass
        with self._lock:
            self._closed = True
        delete_entity(self._writer)
        delete_entity(self._topic)
