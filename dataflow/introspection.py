"""Plain-data descriptions of tasks (pydantic models): what the remote layer and CLI print."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict

__all__ = ["LinkDescription", "SubscriptionDescription", "TaskDescription", "PortDescription", "PortStreamDescription", "PropertyDescription", "OperationDescription"]


class PortStreamDescription(BaseModel):
    """A stream on a port, as ``scart describe`` shows it under the port: its name, its
    ``transport:topic``, the topic's own type when the transport converts (a ROS message
    type: ``type_name``), ``connected`` or ``waiting``, the samples refused (could not be
    converted, or failed the port's type or bounds) and why the last one was, and whether
    its publishers are unauthenticated (ROS: anyone who reaches the master may publish)."""

    model_config = ConfigDict(frozen=True)
    name: str
    topic: str
    type_name: str = ""
    state: Literal["connected", "waiting"] = "connected"
    refused: int = 0
    refusal: str = ""
    unauthenticated: bool = False


class PortDescription(BaseModel):
    """A port: direction, registry type name, doc, number of connections, event port or not,
    (input ports) the bounds of what may be written to it from outside, and its streams."""

    model_config = ConfigDict(frozen=True)
    name: str
    direction: Literal["in", "out"]
    type_name: str
    doc: str = ""
    connections: int = 0
    event: bool = False
    bounds: str = ""
    streams: list[PortStreamDescription] = []


class PropertyDescription(BaseModel):
    """A property: registry type name, current value (JSON-able), doc and bounds."""

    model_config = ConfigDict(frozen=True)
    name: str
    type_name: str
    value: Any = None
    doc: str = ""
    bounds: str = ""


class OperationDescription(BaseModel):
    """An operation: parameters (name, type name), return type name, doc, thread mode, signature."""

    model_config = ConfigDict(frozen=True)
    name: str
    params: list[tuple[str, str]] = []
    returns: str = "None"
    doc: str = ""
    own_thread: bool = False
    signature: str = ""


class TaskDescription(BaseModel):
    """A task: state, activity kind and period, counters, ports, properties, operations."""

    model_config = ConfigDict(frozen=True)
    name: str
    state: str
    activity: str
    period: float = 0.0
    cycles: int = 0
    overruns: int = 0
    ports: list[PortDescription] = []
    properties: list[PropertyDescription] = []
    operations: list[OperationDescription] = []


class LinkDescription(BaseModel):
    """A connection between ports, or a stream, as ``scart links`` shows it: its name,
    ``task.port`` ends (a stream's sink or source is ``transport:topic``), policy,
    transport (``local``: in one process; ``ipc``, ``grpc``...: to another deployer; with
    ``?`` while not connected), samples the source port wrote so far and samples lost on
    the link (counted wherever they were lost, the sink's buffer included). ``kind`` is
    ``link`` or ``stream``; ``state`` ``connected``, ``waiting`` (for its peer) or
    ``refused`` (``detail`` says why); ``pending``: samples sent and not yet confirmed by
    the reader end."""

    model_config = ConfigDict(frozen=True)
    name: str
    source: str
    sink: str
    policy: str
    transport: str = "local"
    samples: int = 0
    dropped: int = 0
    kind: Literal["link", "stream"] = "link"
    state: Literal["connected", "waiting", "refused"] = "connected"
    detail: str = ""
    pending: int = 0


class SubscriptionDescription(BaseModel):
    """A subscription a deployer serves to another process, as ``scart links
    --subscriptions`` shows it: the deployer's address and its number for it (``id``), the
    ``task.port`` it reads, the subscriber's address, its policy and transport (``grpc``,
    ``ipc``), samples the port wrote so far and samples lost on the way to the subscriber."""

    model_config = ConfigDict(frozen=True)
    deployer: str
    id: int
    source: str
    subscriber: str
    policy: str
    transport: str
    samples: int = 0
    dropped: int = 0

    @property
    def name(self) -> str:
        """``deployer#id``: unique among the subscriptions of a system."""
        return f"{self.deployer}#{self.id}"
