"""A ROS 2 participant: one DDS domain participant, its topics, endpoints and thread.

Lifecycle: ``Participant(...)`` joins the domain (no thread yet); ``publisher``,
``subscribe``, ``service`` and ``client`` make endpoints (the first reader starts the one
dispatcher thread); ``close()`` closes every endpoint, ends the thread, deletes the
participant and, when it was the last of this process on its domain, the domain.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from typing import Any

from cyclonedds.core import DDSException
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from .endpoints import Accept, Dispatcher, Publisher, Subscription
from .errors import DomainError, Ros2Error
from .graph import NodeGraph
from .names import dds_topic, service_topics, topic_name
from .network import DOMAINS, Network, delete_entity, resolve_domain_id
from .qos import QoS
from .services import SERVICE_QOS, ServiceClient, ServiceServer
from .msgs import MessageTypes, message_to_dict

__all__ = ["Participant"]


class Participant:
    """A ROS 2 (DDS) participant on ``domain_id`` (else ``ROS_DOMAIN_ID``, else 0).

    ``network`` defaults to :meth:`Network.loopback`; ``insecure=True`` means
    :meth:`Network.open` (any host on the network may read and write). ``types`` gives
    the message definitions (default: ``MessageTypes(distro)``). With ``node``, the
    participant is that ROS 2 node (in ``namespace``) for ``ros2 node list``/``info``
    (see :mod:`._graph`). Raises :class:`DomainError` when the domain cannot be joined,
    ``ValueError`` for a bad node name. Thread-safe; a context manager.
    """

    def __init__(self, domain_id: int | None = None, *, network: Network | None = None, insecure: bool = False,
                 types: MessageTypes | None = None, distro: str = "jazzy", node: str | None = None,
                 namespace: str = "/") -> None:
        self.domain_id = resolve_domain_id(domain_id)
        self.network = network if network is not None else (Network.open() if insecure else Network.loopback())
        self.types = types if types is not None else MessageTypes(distro)
        DOMAINS.acquire(self.domain_id, self.network.config_xml())
        try:  # rmw announces the participant's security enclave in its user data
            self._dp = DomainParticipant(self.domain_id, qos=Qos(Policy.Userdata(data=b"enclave=/;")))
        except DDSException as exc:
            DOMAINS.release(self.domain_id)
            raise DomainError(f"cannot join DDS domain {self.domain_id}: {exc}") from None
        self._lock = threading.Lock()
        self._topics: dict[str, Topic] = {}
        self._endpoints: list[Publisher | Subscription | ServiceServer | ServiceClient] = []
        self._dispatcher = Dispatcher(self._dp, f"ros2-dispatch-d{self.domain_id}")
        self._closed = False
        try:
            self.node = NodeGraph(self._dp, self.types, node, namespace) if node is not None else None
        except Exception:
            self.close()
            raise

    def __enter__(self) -> Participant:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    # ------------------------------------------------------------------ topics
    def publisher(self, topic: str, type_name: str, qos: QoS | None = None, *,
                  accept: Accept | None = None, cdr: bool = False) -> Publisher:
        """A publisher of ``type_name`` (``pkg/msg/Type``) on ROS 2 topic ``topic``.

        ``accept(message) -> bool`` may refuse a message before it is converted (e.g. a
        NaN). With ``cdr``, ``publish`` takes a rosbags message of the type (serialised
        by rosbags: its arrays copied once) or CDR bytes already made, and writes the
        bytes as they are (the fast way for large arrays). Raises ``ValueError`` for a
        bad topic name, :class:`UnknownTypeError`.
        """
        qos = qos or QoS.data()
        dds_name, idl = dds_topic(topic), self.types.idl_type(type_name)
        user_data = self._type_hash_data(type_name)
        with self._lock:
            self._check_open()
            writer = DataWriter(self._dp, self._topic(dds_name, idl), qos=qos.to_cyclone(user_data))
            types = self.types
            convert = (lambda m: m if isinstance(m, (bytes, bytearray, memoryview)) else types.to_cdr(type_name, m)) \
                if cdr else (lambda m: types.to_idl(type_name, m))
            endpoint = Publisher(writer, convert, topic_name(topic), type_name, accept, cdr)
            self._endpoints.append(endpoint)
        self._announce(endpoint, writers=(writer,))
        return endpoint

    def subscribe(self, topic: str, type_name: str, callback: Callable[[Any], object], qos: QoS | None = None, *,
                  accept: Accept | None = None, as_dict: bool = False, raw: bool = False,
                  cdr: bool = False) -> Subscription:
        """Call ``callback(message)`` on this participant's thread for every message of
        ``type_name`` on ``topic``: a rosbags message, a plain dict if ``as_dict``, or the
        instance of the IDL type (:meth:`MessageTypes.idl_type`) as Cyclone made it if
        ``raw`` (no conversion at all). With ``cdr`` the bytes received are read by rosbags
        instead of Cyclone's Python deserialiser (the fast way for large arrays: a rosbags
        message whose arrays are read-only views of the bytes), or given as they are if
        ``raw`` too.

        ``accept(message) -> bool`` may refuse one (counted). Raises as :meth:`publisher`.
        """
        qos = qos or QoS.data()
        dds_name, idl = dds_topic(topic), self.types.idl_type(type_name)
        types = self.types
        if cdr and not raw:
            def convert(sample: Any) -> Any:
                message = types.from_cdr(type_name, sample)
                return message_to_dict(message) if as_dict else message
        elif raw:
            def convert(sample: Any) -> Any:
                return sample
        elif as_dict:
            def convert(sample: Any) -> Any:
                return message_to_dict(types.from_idl(type_name, sample))
        else:
            def convert(sample: Any) -> Any:
                return types.from_idl(type_name, sample)
        with self._lock:
            self._check_open()
            reader = DataReader(self._dp, self._topic(dds_name, idl),
                                qos=qos.to_cyclone(self._type_hash_data(type_name), reader=True))
            endpoint = Subscription(reader, convert, callback, topic_name(topic), type_name, accept,
                                    self._dispatcher, cdr)
            self._endpoints.append(endpoint)
        self._announce(endpoint, readers=(reader,))
        return endpoint

    # ------------------------------------------------------------------ services
    def service(self, name: str, srv_type: str, handler: Callable[[Any], object], *, raw: bool = False) -> ServiceServer:
        """Answer ROS 2 service ``name`` of ``srv_type`` (``pkg/srv/Name``) with
        ``handler(request) -> response`` on this participant's thread: the request a
        rosbags message, or the IDL instance as Cyclone made it if ``raw`` (its fields,
        and rmw's header as ``guid_``/``seq_``)."""
        request_topic, reply_topic = service_topics(name)
        request, response = self.types.service(srv_type)
        with self._lock:
            self._check_open()
            reader, writer = self._service_pair(request_topic, request, reply_topic, response, "serviceid")
            endpoint = ServiceServer(reader, writer, self.types, srv_type, handler, self._dispatcher, raw)
            self._endpoints.append(endpoint)
        self._announce(endpoint, (reader,), (writer,))
        return endpoint

    def client(self, name: str, srv_type: str) -> ServiceClient:
        """A client of ROS 2 service ``name`` of ``srv_type``."""
        request_topic, reply_topic = service_topics(name)
        request, response = self.types.service(srv_type)
        with self._lock:
            self._check_open()
            reader, writer = self._service_pair(reply_topic, response, request_topic, request, "clientid")
            endpoint = ServiceClient(reader, writer, self.types, srv_type, self._dispatcher)
            self._endpoints.append(endpoint)
        self._announce(endpoint, (reader,), (writer,))
        return endpoint

    def _service_pair(self, read_topic: str, read_type: str, write_topic: str, write_type: str,
                      role: str) -> tuple[DataReader, DataWriter]:
        """A reader and a writer sharing rmw's ``clientid=``/``serviceid=`` user data."""
        user_data = f"{role}={_new_id()};".encode()
        reader = DataReader(self._dp, self._topic(read_topic, self.types.service_idl_type(read_type)),
                            qos=SERVICE_QOS.to_cyclone(user_data, reader=True))
        writer = DataWriter(self._dp, self._topic(write_topic, self.types.service_idl_type(write_type)),
                            qos=SERVICE_QOS.to_cyclone(user_data))
        return reader, writer

    # ------------------------------------------------------------------ plumbing
    def _announce(self, endpoint: Any, readers: tuple[Any, ...] = (), writers: tuple[Any, ...] = ()) -> None:
        """Put the endpoint's readers and writers in the node graph, until it closes."""
        graph = self.node
        if graph is None:
            return
        for reader in readers:
            graph.add(reader, reader=True)
        for writer in writers:
            graph.add(writer, reader=False)

        def forget() -> None:
            for entity in (*readers, *writers):
                graph.remove(entity)
        endpoint.closed_hook = forget

    def _topic(self, dds_name: str, idl: type) -> Topic:
        found = self._topics.get(dds_name)
        if found is None:
            found = self._topics[dds_name] = Topic(self._dp, dds_name, idl)
        elif found.data_type is not idl:
            raise Ros2Error(f"topic {dds_name} already carries another type in this participant")
        return found

    def _type_hash_data(self, type_name: str) -> bytes:
        type_hash = self.types.type_hash(type_name)
        return f"typehash={type_hash};".encode() if type_hash else b""

    def _check_open(self) -> None:
        if self._closed:
            raise Ros2Error("the ROS 2 participant is closed")

    def close(self) -> None:
        """Close every endpoint, end the thread (joined, not from itself), delete the
        participant and free the domain if it was the last user. Idempotent; thread-safe;
        callable from a callback."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            endpoints, self._endpoints = self._endpoints, []
        node = getattr(self, "node", None)
        if node is not None:
            node.close()  # the node leaves the graph before its endpoints do
        for endpoint in reversed(endpoints):
            endpoint.close()
        self._dispatcher.close()
        for topic in self._topics.values():
            delete_entity(topic)
        self._topics.clear()
        delete_entity(self._dp)
        DOMAINS.release(self.domain_id)


def _new_id() -> str:
    """A client/service id written as rmw_cyclonedds writes its 16-byte ids."""
    data = os.urandom(16)
    return f"{data[0]:02x}" + "".join(f".{b:x}" for b in data[1:])
