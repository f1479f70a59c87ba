"""The serving half of a transport (part of the transport SPI): how a deployer answers
the channels other processes ask it for, over the transport that carries them.

RTT keeps a transport whole: the plug-in that connects and the dispatcher that answers
are in one place. So here: a transport whose peers ask a deployer for channels (a link
into one of its input ports, a subscription of one of its output ports) names the class
of its serving half (:meth:`~dataflow.transports.Transport.serving`), and that class
answers, in each deployer, the ``DeployerService`` methods it lists in
:attr:`Serving.methods` (``grpc``: ``Subscribe`` and ``Link``; ``ipc``: the tickets of
``OpenIpcWriter`` and ``OpenIpcReader``).

The control plane (:mod:`dataflow.remote`) only negotiates and dispatches: it owns what
every transport shares and offers it as a :class:`ChannelHost` — the links coming in
(:class:`~dataflow.transports.sinks.Sinks`), the subscriptions going out
(:class:`~dataflow.transports.served.ServedSet`), its boot id, the policies as it reads
them off the wire, its heartbeat bounds — makes a transport's serving half when the first
call of one of its methods comes, and hands it that method's calls. Transports that name
one class (``ipc`` and ``shm``; a plug-in derived from ``grpc``) share its one instance.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, ClassVar, Protocol

if TYPE_CHECKING:
    import grpc

    from scart_wire.rpc import MethodHandler

    from dataflow.policy import ConnPolicy
    from dataflow.ports import OutputPort
    from dataflow.transports.served import Served, ServedSet
    from dataflow.transports.sinks import Sinks
    from scart_wire.proto.scart.dataflow.v1.dataflow_pb2 import ConnPolicy as PolicyMsg

__all__ = ["ChannelHost", "Serving"]


class ChannelHost(Protocol):
    """What a deployer's control plane offers the serving halves of its transports."""

    @property
    def boot_id(self) -> str:
        """This deployer's process id (random per start): peers tell restarts by it."""

    @property
    def sinks(self) -> Sinks:
        """The links coming into this deployer, whatever carries them."""

    @property
    def served(self) -> ServedSet:
        """The subscriptions this deployer serves, whatever carries them."""

    @property
    def stopping(self) -> threading.Event:
        """Set once this deployer stops serving channels."""

    def policy(self, msg: PolicyMsg) -> ConnPolicy:
        """A policy off the wire, as the control plane accepts it (``ValueError`` naming
        the bad field otherwise)."""

    def output(self, task: str, port: str) -> OutputPort:
        """The output port ``task.port`` (``NotFoundError``; refused for an input port)."""

    @property
    def max_streams(self) -> int:
        """How many calls may each hold one of the deployer's gRPC workers for their life
        (a streamed subscription), at most."""

    def serve(self, task: str, port: str, policy: ConnPolicy, who: str, transport: str,
              limit: int | None = None) -> Served:
        """A new subscription of the output port ``task.port`` for ``who``, carried by
        ``transport``, of which there may be at most ``limit`` (refused when a sample
        could never fit, or past a limit)."""

    def heartbeat_s(self, asked_ms: int) -> float:
        """A subscriber's heartbeat period (s): what it asked for (0: the deployer's), bounded."""


class Serving(ABC):
    """A transport's serving half in one deployer (see the module docstring): made with
    the deployer's :class:`ChannelHost` when the first call of one of its
    :attr:`methods` comes; :meth:`stop` ends what it serves when the deployer stops."""

    #: The ``DeployerService`` methods it answers (by name).
    methods: ClassVar[frozenset[str]] = frozenset()

    def __init__(self, host: ChannelHost) -> None:
        self.host = host

    @abstractmethod
    def handler(self, method: str) -> MethodHandler:
        """The gRPC handler of ``method`` (one of :attr:`methods`)."""

    def stop(self) -> None:
        """The deployer stops: end what this serving half carries (idempotent). The
        control plane has closed its incoming links' buffers before, and closes the
        subscriptions it serves after."""
