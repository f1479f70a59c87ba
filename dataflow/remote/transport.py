"""Transports: how a data-flow connection's samples cross between two processes (RTT's
``ConnPolicy.transport``, as plug-ins).

gRPC stays the control plane (lookups, introspection, operations, properties, and the
negotiation of a connection); a transport only moves samples. It carries the two kinds
of crossing:

* a **link** (:class:`LinkEnd`): an output port of this deployer feeding an input port of
  another deployer (``scart connect``, ``<scart:connect>``);
* a **subscription** (:class:`ReaderEnd`): an observer in this process reading an output
  port of a deployer (``proxy.subscribe``, ``scart echo``, ``binding.dataflow``).

Both ends keep the connection's policy-shaped storage (DATA / BUFFER / CIRCULAR_BUFFER,
with its drop count) and its reconnection loop; a transport gets the end, carries samples
until the connection ends, and returns. ``transport="auto"`` tries every transport that
takes part in ``auto`` by :attr:`Transport.rank` (lowest first) until one carries the
connection; a named transport is the only one tried.

Transports are found through the ``scart.transports`` entry points, like the SCA
extensions; scart's own (``ipc``, ``grpc``) are registered the same way. A package adds
one with a line in its ``pyproject.toml`` and no change to scart::

    [project.entry-points."scart.transports"]
    mine = "my_package.transport:MyTransport"

The entry point names a :class:`Transport` subclass (made with no arguments) or
instance whose :attr:`~Transport.name` is the entry point's name (a lower-case word of at
most :data:`MAX_NAME` characters). It is loaded when a connection first asks for it, or
for ``auto`` (which loads every registered transport to learn its rank); one that cannot
be loaded is not tried again. No gRPC is imported here.
"""

from __future__ import annotations

import logging
import re
import threading
from abc import ABC
from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points
from types import MappingProxyType
from typing import Any, Protocol

from dataflow.errors import DataflowError
from dataflow.policy import ConnPolicy

__all__ = ["ENTRY_POINT_GROUP", "LinkEnd", "ReaderEnd", "Transport", "TransportError", "TransportRegistry",
           "candidates", "carry", "default", "load", "names"]

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "scart.transports"
MAX_NAME = 32  #: characters of a transport's name, at most (it travels in every remote policy)
NAME = re.compile(rf"^[a-z][a-z0-9_.-]{{0,{MAX_NAME - 1}}}$")

#: scart's own transports, used also when its entry points are not installed (a source tree).
BUILTIN = MappingProxyType({"ipc": "dataflow.remote._transports:IpcTransport",
                            "grpc": "dataflow.remote._transports:GrpcTransport"})


class TransportError(DataflowError):
    """A transport is unknown, or cannot be loaded, or is not what its name says."""


class LinkEnd(Protocol):
    """What a transport sees of a link (the sending side, next to the output port).

    Attributes: ``sink_task``, ``sink_port`` (the input port in the other deployer),
    ``policy``, ``out`` (the output port), ``closed`` (set when the link is undone) and
    ``timeout`` (s, for control-plane calls). Once the transport's method has returned,
    the link forgets what :meth:`opened` gave it and keeps the ``dropped`` count.
    """

    sink_task: str
    sink_port: str
    policy: ConnPolicy
    out: Any
    closed: threading.Event

    @property
    def timeout(self) -> float:
        """Deadline (s) of the control-plane calls a transport makes."""

    def take(self) -> list[Any]:
        """The next samples waiting in the link's policy storage (at most 64; [] when none)."""

    def messages(self, values: list[Any], batch_bytes: int = 0) -> list[bytes]:
        """``values`` encoded as ``WritePortStreamRequest`` messages (the wire format of
        every transport): one per value, or with ``batch_bytes`` as few as fit in that many
        bytes each (``values``; only for a sink that said it reads them)."""

    def requests(self, values: list[Any], batch_bytes: int = 0) -> list[Any]:
        """:meth:`messages`, as message objects (for a transport that serializes them itself)."""

    def reads_batches(self) -> bool:
        """Whether the sink's deployer reads ``WritePortStreamRequest.values`` (several
        values per message), asked over the control plane; False for an older one."""

    def wait_data(self, timeout: float) -> bool:
        """Block until the output port was written since the last call (True) or ``timeout`` s."""

    def wake(self) -> None:
        """Make the next :meth:`wait_data` return at once."""

    def opened(self, transport: str, cancel: Callable[[], None], *, pump: Callable[[], None] | None = None,
                  dropped: Callable[[], int] | None = None) -> bool:
        """The connection is up over ``transport``. ``cancel`` ends it (called when the link
        is undone); ``pump``, if given, is called in the writer's thread after each write
        instead of waking :meth:`wait_data`; ``dropped`` counts what the transport lost so
        far on this connection. False when the link was undone meanwhile (``cancel`` was called)."""


class ReaderEnd(Protocol):
    """What a transport sees of a subscription (the receiving side, next to the observer).

    Attributes: ``component``, ``port``, ``policy``, ``heartbeat`` (s: the deployer
    sends a heartbeat at least this often; silence for 3 of them is a frozen peer),
    ``heartbeat_ms`` and ``timeout`` (s, for control-plane calls), ``closed``.
    """

    component: str
    port: str
    policy: ConnPolicy
    heartbeat: float
    closed: threading.Event

    @property
    def heartbeat_ms(self) -> int:
        """The heartbeat period the deployer is asked for (ms)."""

    @property
    def timeout(self) -> float:
        """Deadline (s) of the control-plane calls a transport makes."""

    def stub(self, address: str) -> Any:
        """The ``DeployerService`` stub of the deployer at ``address`` (the control plane)."""

    def opened(self, transport: str, cancel: Callable[[], None]) -> bool:
        """A new stream is up over ``transport``; ``cancel`` ends it (called on close, or by
        the heartbeat watchdog). False when the subscription was closed meanwhile."""

    def receive(self, message: Any) -> None:
        """One ``SubscribeResponse`` (samples, the deployer's drop report, its boot id)."""


class Transport(ABC):
    """One way of carrying samples between two processes (see the module docstring).

    A method returns False when this transport cannot join these two ends (another host,
    no such facility in the peer): under ``auto`` the next transport is tried. It returns
    True once a connection it carried has ended; it raises what interrupted it (the
    owner logs it, backs off and reconnects).
    """

    #: The name a policy selects it by (``ConnPolicy(transport=name)``).
    name: str = ""
    #: ``auto`` tries lower ranks first; None: used only when named.
    rank: int | None = None

    def link(self, end: LinkEnd, address: str, stub: Any) -> bool:
        """Carry the samples of link ``end`` to the sink's deployer at ``address`` (``stub``
        is its ``DeployerService``) until the connection ends. Default: links unsupported."""
        return False

    def subscribe(self, end: ReaderEnd, address: str) -> bool:
        """Carry samples from the deployer at ``address`` to subscription ``end`` until the
        stream ends. Default: subscriptions unsupported."""
        return False

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"


class TransportRegistry:
    """The transports of this process, by name: entry points read once, each transport
    loaded once, when first asked for. Thread-safe. :data:`default` is the one connections use."""

    def __init__(self) -> None:
        self._lock = threading.RLock()  # a plug-in's import may build a policy naming a transport
        self._found: dict[str, EntryPoint] | None = None
        self._loaded: dict[str, Transport] = {}
        self._failed: dict[str, str] = {}  # why: not imported again on every reconnect
        self._warned: set[str] = set()

    def _entry_points(self) -> dict[str, EntryPoint]:
        with self._lock:
            if self._found is None:
                found: dict[str, EntryPoint] = {}
                for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: (e.name, e.value)):
                    if not NAME.match(ep.name):
                        log.warning("transport entry point %r (%s) ignored: a name is a lower-case word of at "
                                    "most %d characters", ep.name, ep.value, MAX_NAME)
                        continue
                    if ep.name in found and found[ep.name].value != ep.value:
                        log.warning("transport %r is provided twice (%s and %s); using %s", ep.name,
                                    found[ep.name].value, ep.value, found[ep.name].value)
                        continue
                    found.setdefault(ep.name, ep)
                for name, value in BUILTIN.items():
                    found.setdefault(name, EntryPoint(name, value, ENTRY_POINT_GROUP))
                self._found = found
            return self._found

    def names(self) -> tuple[str, ...]:
        """Every transport a policy may name (nothing is loaded), sorted."""
        return tuple(sorted(self._entry_points()))

    def load(self, name: str) -> Transport:
        """The transport called ``name`` (loaded once); :class:`TransportError` naming the
        entry point when it is unknown or cannot be loaded."""
        found = self._entry_points()
        with self._lock:
            transport = self._loaded.get(name)
            if transport is not None:
                return transport
            if name in self._failed:
                raise TransportError(self._failed[name])  # a new one: a re-raised one would grow its traceback
            ep = found.get(name)
            if ep is None:
                raise TransportError(f"no transport {name!r}; known: {', '.join(sorted(found))}")
            try:
                transport = self._make(name, ep)
            except TransportError as exc:
                self._failed[name] = str(exc)
                raise
            self._loaded[name] = transport
            return transport

    @staticmethod
    def _make(name: str, ep: EntryPoint) -> Transport:
        try:
            obj = ep.load()
            transport = obj() if isinstance(obj, type) else obj
        except Exception as exc:
            dist = getattr(getattr(ep, "dist", None), "name", None) or "scart"
            raise TransportError(f"transport {name!r} (entry point {ep.value!r} of {dist}) cannot be loaded: "
                                 f"{type(exc).__name__}: {exc}") from exc
        if not isinstance(transport, Transport):
            raise TransportError(f"transport {name!r} ({ep.value}) is a {type(transport).__qualname__}, "
                                 "not a dataflow.remote.transport.Transport")
        if transport.name != name:
            raise TransportError(f"transport {name!r} ({ep.value}) says its name is {transport.name!r}")
        return transport

    def candidates(self, wanted: str) -> list[Transport]:
        """The transports to try, in order, for a policy's ``transport``: the one named, or
        for ``auto`` every one with a rank, lowest first (a plug-in that cannot be loaded is
        skipped with a warning, once). A transport that declines a connection passes it to
        the next; one that fails is retried when the owner reconnects (see :func:`carry`)."""
        if wanted != "auto":
            return [self.load(wanted)]
        found = []
        for name in self.names():
            try:
                transport = self.load(name)
            except TransportError as exc:
                self.warn_once(name, f"{exc}; auto goes without it")
                continue
            if transport.rank is not None:
                found.append(transport)
        return sorted(found, key=lambda t: (t.rank, t.name))

    def warn_once(self, name: str, message: str) -> None:
        """Log ``message`` about transport ``name`` once per process (a flood of failures
        is no flood of logs)."""
        with self._lock:
            first = name not in self._warned
            self._warned.add(name)
        if first:
            log.warning("%s", message)


#: The registry connections use (entry points are process-wide).
default = TransportRegistry()


def names() -> tuple[str, ...]:
    """:meth:`TransportRegistry.names` of :data:`default`."""
    return default.names()


def load(name: str) -> Transport:
    """:meth:`TransportRegistry.load` of :data:`default`."""
    return default.load(name)


def candidates(wanted: str) -> list[Transport]:
    """:meth:`TransportRegistry.candidates` of :data:`default`."""
    return default.candidates(wanted)


def carry(wanted: str, attempt: Callable[[Transport], bool], after: Callable[[], None], what: str,
          address: str) -> None:
    """Offer one connection to the transports for a policy's ``wanted`` in order, until
    ``attempt(transport)`` says one carried it (and it ended); ``after()`` runs after each
    attempt, however it went. Raises what an attempt raised (the peer's failure: a
    :class:`~dataflow.remote.errors.RemoteError`, a gRPC or socket error; the owner
    reconnects), or ``UnavailableError`` naming ``what`` and the transports tried when
    every one declined. Under ``auto``, a transport that raises anything else (a plug-in's
    bug) is passed over, said once, and the next one tried: it never keeps the connection
    from the transports that work."""
    import grpc

    from dataflow.remote.errors import RemoteError, UnavailableError

    tried = []
    for transport in candidates(wanted):
        tried.append(transport.name)
        try:
            if attempt(transport):
                return
        except (RemoteError, grpc.RpcError, OSError):
            raise
        except Exception as exc:
            if wanted != "auto":
                raise
            default.warn_once(f"failed:{transport.name}", f"transport {transport.name!r} failed for {what} "
                              f"({type(exc).__name__}: {exc}); auto goes on with the next one")
        finally:
            after()
    raise UnavailableError(f"no transport reaches {what} (tried {', '.join(tried) or 'none'})", "UNAVAILABLE", address)
