"""The node's own XML-RPC API (ROS's "slave API").

Each call answers ``[code, statusMessage, value]`` as ROS's Slave API says: code 1 is
success, 0 failure, -1 an error in the call. :class:`SlaveApi` is the calls; it asks the
node (a :class:`NodeView`) what it needs. :class:`~.rpcserver.RpcServer` serves them on
``host:port`` (loopback unless the node was given another host), several requests at
once, each bounded in bytes and time; calls may therefore run side by side.
"""

from __future__ import annotations

import logging
import os
from typing import Protocol

from .io import Counters
from .master import XmlRpcValue

__all__ = ["NodeView", "SlaveApi"]

log = logging.getLogger(__name__)

MAX_PUBLISHERS = 10_000  #: URIs a publisherUpdate may list


class NodeView(Protocol):
    """What the slave API asks of its node."""

    caller_id: str
    master_uri: str
    counters: Counters

    def publications(self) -> list[list[str]]: ...
    def subscriptions(self) -> list[list[str]]: ...
    def bus_info(self) -> list[list[XmlRpcValue]]: ...
    def bus_stats(self) -> list[XmlRpcValue]: ...
    def tcpros_endpoint(self, topic: str) -> tuple[str, int] | None: ...
    def publisher_update(self, topic: str, uris: list[str]) -> None: ...
    def request_shutdown(self, caller_id: str, reason: str) -> bool: ...
    def param_update(self, key: str, value: XmlRpcValue) -> None: ...


def _ok_str(*values: object, limit: int = 4096) -> bool:
    return all(isinstance(v, str) and len(v) <= limit for v in values)


class SlaveApi:
    """The Slave API's calls (names as ROS spells them; run on the server's worker threads)."""

    def __init__(self, node: NodeView) -> None:
        self._node = node

    def _bad(self, method: str) -> list[XmlRpcValue]:
        self._node.counters["xmlrpc_bad_requests"] += 1
        return [-1, f"{method}: bad arguments", 0]

    def getBusStats(self, caller_id: str) -> list[XmlRpcValue]:  # noqa: N802 (ROS's names)
        return [1, "bus stats", self._node.bus_stats()] if _ok_str(caller_id) else self._bad("getBusStats")

    def getBusInfo(self, caller_id: str) -> list[XmlRpcValue]:  # noqa: N802
        return [1, "bus info", self._node.bus_info()] if _ok_str(caller_id) else self._bad("getBusInfo")

    def getMasterUri(self, caller_id: str) -> list[XmlRpcValue]:  # noqa: N802
        return [1, "", self._node.master_uri] if _ok_str(caller_id) else self._bad("getMasterUri")

    def shutdown(self, caller_id: str, msg: str = "") -> list[XmlRpcValue]:
        if not _ok_str(caller_id, msg):
            return self._bad("shutdown")
        if not self._node.request_shutdown(caller_id, msg):
            return [0, "shutdown refused: this node is read-only", 0]
        return [1, "shutdown", 0]

    def getPid(self, caller_id: str) -> list[XmlRpcValue]:  # noqa: N802
        return [1, "", os.getpid()] if _ok_str(caller_id) else self._bad("getPid")

    def getSubscriptions(self, caller_id: str) -> list[XmlRpcValue]:  # noqa: N802
        return [1, "subscriptions", self._node.subscriptions()] if _ok_str(caller_id) else self._bad("getSubscriptions")

    def getPublications(self, caller_id: str) -> list[XmlRpcValue]:  # noqa: N802
        return [1, "publications", self._node.publications()] if _ok_str(caller_id) else self._bad("getPublications")

    def paramUpdate(self, caller_id: str, key: str, value: XmlRpcValue) -> list[XmlRpcValue]:  # noqa: N802
        # a key this node does not subscribe to is accepted and ignored, as rospy does
        if not _ok_str(caller_id, key):
            return self._bad("paramUpdate")
        self._node.param_update(key, value)
        return [1, "", 0]

    def publisherUpdate(self, caller_id: str, topic: str, publishers: list[str]) -> list[XmlRpcValue]:  # noqa: N802
        if not (_ok_str(caller_id, topic) and isinstance(publishers, list) and len(publishers) <= MAX_PUBLISHERS
                and all(_ok_str(p) for p in publishers)):
            return self._bad("publisherUpdate")
        self._node.publisher_update(topic, list(publishers))
        return [1, "", 0]

    def requestTopic(self, caller_id: str, topic: str, protocols: list[XmlRpcValue]) -> list[XmlRpcValue]:  # noqa: N802
        if not (_ok_str(caller_id, topic) and isinstance(protocols, list) and len(protocols) <= 16):
            return self._bad("requestTopic")
        endpoint = self._node.tcpros_endpoint(topic)
        if endpoint is None:
            return [0, f"{self._node.caller_id} is not a publisher of {topic}", []]
        if not any(isinstance(p, list) and p and p[0] == "TCPROS" for p in protocols):
            return [0, "no supported protocol: this node speaks TCPROS only", []]
        host, port = endpoint
        return [1, f"ready on {host}:{port}", ["TCPROS", host, port]]
