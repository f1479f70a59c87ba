"""The ROS 1 Master API over XML-RPC (stdlib ``xmlrpc.client``), with timeouts and bounds.

:class:`Master` is one method per Master API call; it returns the call's value when the
master answers code 1, raises :class:`MasterError` with the master's message otherwise,
and :class:`MasterUnreachable` when the master cannot be reached in time. It never
retries: waiting for a master that is down is the node's job (it logs it and retries).

:func:`server_proxy` is the same bounded client for any XML-RPC peer (a node's slave API).
Every call opens its own connection, so both are thread-safe.
"""

from __future__ import annotations

import http.client
import xmlrpc.client
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, TypeAlias, cast

if TYPE_CHECKING:
    from xmlrpc.client import _Marshallable  # typeshed's: what the unmarshaller gives

__all__ = ["Master", "MasterError", "MasterUnreachable", "XmlRpcValue", "server_proxy"]

#: A value XML-RPC carries: a parameter, an argument or answer of the Master and Slave
#: APIs (arrays may be lists or tuples; ``None`` is ``nil``, which both ends allow).
XmlRpcValue: TypeAlias = "bool | int | float | str | bytes | None | Sequence[XmlRpcValue] | Mapping[str, XmlRpcValue]"

MAX_RESPONSE_BYTES = 16 << 20  #: an XML-RPC answer larger than this is refused


class MasterError(RuntimeError):
    """The master (or a peer's XML-RPC API) answered, but refused or failed the call."""


class MasterUnreachable(MasterError):
    """The master (or peer) could not be reached, or did not answer in time."""


class _BoundedTransport(xmlrpc.client.Transport):
    """``xmlrpc.client.Transport`` with a socket timeout and a bound on the answer's size."""

    def __init__(self, timeout: float, max_bytes: int) -> None:
        super().__init__()
        self._timeout, self._max = timeout, max_bytes

    def make_connection(self, host: tuple[str, dict[str, str]] | str) -> http.client.HTTPConnection:
        conn = super().make_connection(host)
        conn.timeout = self._timeout
        return conn

    def parse_response(self, response: http.client.HTTPResponse) -> tuple[_Marshallable, ...]:
        parser, unmarshaller = self.getparser()
        total = 0
        while data := response.read(65536):
            total += len(data)
            if total > self._max:
                raise MasterError(f"XML-RPC answer larger than {self._max} bytes")
            parser.feed(data)
        parser.close()
        return unmarshaller.close()


def server_proxy(uri: str, timeout: float, max_bytes: int = MAX_RESPONSE_BYTES) -> xmlrpc.client.ServerProxy:
    """A one-use XML-RPC proxy for ``uri`` whose calls time out and whose answers are bounded."""
    return xmlrpc.client.ServerProxy(uri, transport=_BoundedTransport(timeout, max_bytes), allow_none=True)


def call(uri: str, method: str, *args: XmlRpcValue, timeout: float, what: str = "XML-RPC peer") -> XmlRpcValue:
    """Call ``method`` on ``uri``; the value of a ``[code, message, value]`` answer with code 1.

    Raises :class:`MasterUnreachable` (connection refused, timeout, reset) or
    :class:`MasterError` (a fault, a code other than 1, or an answer of another shape).
    """
    try:
        answer = getattr(server_proxy(uri, timeout), method)(*args)
    except (OSError, http.client.HTTPException) as exc:
        raise MasterUnreachable(f"{what} {uri} unreachable: {exc or type(exc).__name__}") from None
    except xmlrpc.client.Fault as exc:
        raise MasterError(f"{what} {uri} {method}: fault {exc.faultCode}: {exc.faultString}") from None
    except (xmlrpc.client.ResponseError, xmlrpc.client.ProtocolError, ValueError) as exc:
        raise MasterError(f"{what} {uri} {method}: bad answer: {exc}") from None
    if not isinstance(answer, (list, tuple)) or len(answer) != 3:
        raise MasterError(f"{what} {uri} {method}: answer is not [code, message, value]")
    code, message, value = answer
    if code != 1:
        raise MasterError(f"{what} {uri} {method}: {message} (code {code})")
    return value


class Master:
    """The ROS master at ``uri``, called as ``caller_id`` (thread-safe; see the module doc)."""

    def __init__(self, uri: str, caller_id: str, timeout: float = 3.0) -> None:
        self.uri, self.caller_id, self.timeout = uri, caller_id, timeout

    def _call(self, method: str, *args: XmlRpcValue) -> XmlRpcValue:
        return call(self.uri, method, self.caller_id, *args, timeout=self.timeout, what="ROS master")

    def register_publisher(self, topic: str, topic_type: str, caller_api: str) -> list[str]:
        """Register a publisher; returns the subscribers' XML-RPC URIs."""
        return list(cast("list[str]", self._call("registerPublisher", topic, topic_type, caller_api)))

    def unregister_publisher(self, topic: str, caller_api: str) -> int:
        return int(cast("int", self._call("unregisterPublisher", topic, caller_api)))

    def register_subscriber(self, topic: str, topic_type: str, caller_api: str) -> list[str]:
        """Register a subscriber; returns the publishers' XML-RPC URIs."""
        return list(cast("list[str]", self._call("registerSubscriber", topic, topic_type, caller_api)))

    def unregister_subscriber(self, topic: str, caller_api: str) -> int:
        return int(cast("int", self._call("unregisterSubscriber", topic, caller_api)))

    def register_service(self, service: str, service_api: str, caller_api: str) -> None:
        """Register a service at ``service_api`` (``rosrpc://host:port``)."""
        self._call("registerService", service, service_api, caller_api)

    def unregister_service(self, service: str, service_api: str) -> int:
        return int(cast("int", self._call("unregisterService", service, service_api)))

    def lookup_node(self, node: str) -> str:
        """A node's XML-RPC URI; :class:`MasterError` if the master does not know it."""
        return str(self._call("lookupNode", node))

    def lookup_service(self, service: str) -> str:
        """A service's ``rosrpc://host:port``; :class:`MasterError` if none is registered."""
        return str(self._call("lookupService", service))

    def get_system_state(self) -> list[list[list[XmlRpcValue]]]:
        """``[publishers, subscribers, services]``, each ``[[name, [node, ...]], ...]``."""
        return cast("list[list[list[XmlRpcValue]]]", self._call("getSystemState"))

    def get_published_topics(self, subgraph: str = "") -> list[list[str]]:
        """``[[topic, type], ...]`` of the topics with publishers (under ``subgraph``)."""
        return cast("list[list[str]]", self._call("getPublishedTopics", subgraph))

    def get_topic_types(self) -> list[list[str]]:
        """``[[topic, type], ...]`` of every topic the master knows."""
        return cast("list[list[str]]", self._call("getTopicTypes"))

    # -- the parameter server ---------------------------------------------------------
    def get_param(self, key: str) -> XmlRpcValue:
        """The value at ``key`` (a namespace: a dict); :class:`MasterError` if unset."""
        return self._call("getParam", key)

    def set_param(self, key: str, value: XmlRpcValue) -> None:
        """Set ``key`` (a dict sets a namespace); subscribers but this node are told."""
        self._call("setParam", key, value)

    def delete_param(self, key: str) -> None:
        self._call("deleteParam", key)

    def subscribe_param(self, key: str, caller_api: str) -> XmlRpcValue:
        """Be told of ``key``'s changes (``paramUpdate``); returns its value now (``{}``: unset)."""
        return self._call("subscribeParam", caller_api, key)

    def unsubscribe_param(self, key: str, caller_api: str) -> int:
        return int(cast("int", self._call("unsubscribeParam", caller_api, key)))

    def get_uri(self) -> str:
        return str(self._call("getUri"))

    def get_pid(self) -> int:
        return int(cast("int", self._call("getPid")))


def parse_rosrpc(uri: str) -> tuple[str, int]:
    """``rosrpc://host:port`` → ``(host, port)``; raises ``ValueError``."""
    prefix = "rosrpc://"
    if not isinstance(uri, str) or not uri.startswith(prefix):
        raise ValueError(f"service URI {uri!r} is not rosrpc://HOST:PORT")
    host, _, port = uri[len(prefix) :].rstrip("/").rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"service URI {uri!r} is not rosrpc://HOST:PORT")
    return host, int(port)
