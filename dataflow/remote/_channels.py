"""A deployer's sample path, as its control plane keeps it (private): what every
transport shares — the links coming in (:class:`~dataflow.transports.sinks.Sinks`), the
subscriptions going out (:class:`~dataflow.transports.served.ServedSet`), the policies
read off the wire, the heartbeat bounds — offered to the transports' serving halves as
their :class:`~dataflow.transports.serving.ChannelHost`.

The control plane only negotiates and dispatches: a call of the ``DeployerService`` that
its servicer does not answer itself (``Subscribe``, ``Link``, ``OpenIpcWriter``...) goes to
the serving half of the transport that lists it (:meth:`Channels.handler`), made with the
first such call. No transport's serving code is here.
"""

from __future__ import annotations

import logging
import threading
from typing import TYPE_CHECKING, TypeVar

from dataflow.policy import ConnPolicy
from dataflow.ports import OutputPort
from dataflow.remote import _convert as cv
from dataflow.transports import Transport, TransportError
from dataflow.transports import default as registry
from dataflow.transports.limits import check_fits
from dataflow.transports.served import Served, ServedSet
from dataflow.transports.serving import Serving
from dataflow.transports.sinks import Sinks
from scart_wire.rpc import Abort, MethodHandler

if TYPE_CHECKING:
    import grpc

    from dataflow.remote.server import DeployerServer
    from scart_wire.proto.scart.dataflow.v1.dataflow_pb2 import ConnPolicy as PolicyMsg

__all__ = ["Channels", "MAX_HEARTBEAT_MS", "MIN_HEARTBEAT_MS"]

log = logging.getLogger(__name__)

MIN_HEARTBEAT_MS = 50  #: shortest idle heartbeat a subscriber may ask for
MAX_HEARTBEAT_MS = 10_000  #: longest

S = TypeVar("S", bound=Serving)


class Channels:
    """One deployer's channels and the serving halves that carry them (see the module
    docstring); the :class:`~dataflow.transports.serving.ChannelHost` of its transports."""

    def __init__(self, owner: DeployerServer, heartbeat_ms: int, max_streams: int) -> None:
        self._owner = owner
        self.heartbeat_ms = heartbeat_ms
        self.sinks = Sinks(lambda task, port: owner.deployer.task(task).port(port))
        self.max_streams = max_streams
        self.served = ServedSet()
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._servings: dict[type[Serving], Serving] = {}
        self._handlers: dict[str, MethodHandler | None] = {}  # by method, once looked up

    # ---- the ChannelHost ------------------------------------------------------------------
    @property
    def boot_id(self) -> str:
        return self._owner.boot_id

    def policy(self, msg: PolicyMsg) -> ConnPolicy:
        return cv.policy_from_msg(msg)

    def output(self, task: str, port: str) -> OutputPort:
        found = self._owner.deployer.task(task).port(port)
        if not isinstance(found, OutputPort):
            raise Abort("INVALID_ARGUMENT", f"{task}.{port} is an input port; this needs an output port")
        return found

    def heartbeat_s(self, asked_ms: int) -> float:
        """A reader's heartbeat period (s): what it asked for (else this deployer's), clamped:
        too often is a busy loop, too rare hides a frozen peer."""
        return min(max(asked_ms or self.heartbeat_ms, MIN_HEARTBEAT_MS), MAX_HEARTBEAT_MS) / 1000.0

    def serve(self, task: str, port: str, policy: ConnPolicy, who: str, transport: str,
              limit: int | None = None) -> Served:
        output = self.output(task, port)
        check_fits(output, "a subscription")  # every sample would be refused: said now
        try:
            return self.served.open(output, policy, who, transport, limit)
        except OverflowError as exc:
            raise Abort("RESOURCE_EXHAUSTED", str(exc)) from None

    # ---- dispatch -------------------------------------------------------------------------
    def handler(self, method: str) -> MethodHandler | None:
        """The handler of the ``DeployerService`` method ``method`` from the serving half
        of the first transport that lists it (``auto``'s order, then the others by name;
        made now if it is the first), or None when none does (the call is then
        UNIMPLEMENTED: a peer's transport falls back to another). A serving half made
        once this deployer stops sees :attr:`stopping`, and refuses."""
        if method in self._handlers:  # each method's is set once, never removed: read without the lock
            return self._handlers[method]
        with self._lock:
            if method in self._handlers:
                return self._handlers[method]
            found = None
            for transport in _every_transport():
                try:
                    found = self._handler_of(transport, method)
                except Exception as exc:  # noqa: BLE001 - a plug-in's bug never stops the others serving
                    registry.warn_once(f"serving:{transport.name}", f"transport {transport.name!r} cannot serve "
                                       f"{method} ({type(exc).__name__}: {exc}); passed over")
                    continue
                if found is not None:
                    break
            self._handlers[method] = found
            return found

    def _handler_of(self, transport: Transport, method: str) -> MethodHandler | None:
        """``method``'s handler from ``transport``'s serving half (made now if it is the
        first), None when it does not list it. Under the lock."""
        kind = transport.serving()
        if kind is None or method not in kind.methods:
            return None
        serving = self._servings.get(kind)
        if serving is None:
            serving = self._servings[kind] = kind(self)
        return serving.handler(method)

    def serving_of(self, kind: type[S]) -> S | None:
        """The serving half of class ``kind``, once made."""
        with self._lock:
            found = self._servings.get(kind)
        return found if isinstance(found, kind) else None

    def stop(self) -> None:
        """Stop serving the sample path. The incoming links' buffers are counted first,
        and each transport sends its link's source a last report: a source that comes to
        a restarted sink knows what the old one lost (its buffer included), to the sample."""
        with self._lock:
            self.stopping.set()
            servings = list(self._servings.values())
        self.sinks.close_all()
        for serving in servings:
            serving.stop()
        self.served.close_all()


def _every_transport() -> list[Transport]:
    """Every transport that can be loaded: ``auto``'s, lowest rank first, then the others
    by name (one that cannot be loaded is said once, and passed over)."""
    ranked = registry.candidates("auto")
    found = list(ranked)
    for name in registry.names():
        if any(t.name == name for t in ranked):
            continue
        try:
            found.append(registry.load(name))
        except TransportError as exc:
            registry.warn_once(name, f"{exc}; it serves nothing here")
    return found
