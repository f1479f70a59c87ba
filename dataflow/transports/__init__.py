"""Transports: how samples cross a process boundary, in one shape (RTT's
``ConnPolicy.transport``, ``createStream(port, policy, is_sender)``), as plug-ins.

Vocabulary — these words, and no others, name the parts of a crossing:

==================  ======================================================================
word                what it is
==================  ======================================================================
**channel**         one connection whose two ends are in different processes, with its
                    :class:`~dataflow.policy.ConnPolicy`.
**writer end**      :class:`~dataflow.transports.ends.WriterEnd`: the channel's side next to
                    an output port. It takes every sample the port writes, in the
                    writer's thread, never blocking, and hands it to its carrier.
**reader end**      :class:`~dataflow.transports.ends.ReaderEnd`: the side next to an input
                    port (or an observer). It checks each sample once and keeps it in the
                    channel's **one policy-shaped buffer** (RTT: the connection owns the
                    buffer, at the reader); it counts what was lost, and reports it back.
**carrier**         what a transport attaches to a writer end while connected
                    (:class:`~dataflow.transports.ends.Carrier`): ``send(sample)``.
**fan-out**         the writer ends of one output port; a sample is encoded once for all.
**link**            a channel between an output port of one deployer and an input port
                    of another, made through the control plane (``scart connect``).
**subscription**    a channel from an output port to an observer in another process
                    (``proxy.subscribe``, ``scart echo``). On scart's own transports,
                    subscriptions alike (one system proxy, port and policy) share one
                    channel, each with its own reader end (:mod:`._shared`).
**stream**          one end joined to a named **topic** of a transport instead of a
                    peer's port (``ConnPolicy(transport=..., topic=...)``, ``scart
                    stream``, ``<scart:stream>``): RTT's ``name_id``.
**peer**            the other side of a link or subscription as the control plane found
                    it (:class:`Peer`): its address, port and control-plane stub.
==================  ======================================================================

gRPC is the control plane (lookups, introspection, operations, negotiating a channel);
a transport only moves samples. :class:`Transport` has three methods, one per kind of
channel; each returns False when it cannot carry that one (``auto`` then tries the
next), True once a connection it carried has ended, and raises what interrupted it:

* :meth:`Transport.link` — carry a link's writer end to a peer's input port;
* :meth:`Transport.subscribe` — carry a peer's output port to a subscription's reader end;
* :meth:`Transport.stream` — join a writer or reader end to a topic (transports with
  :attr:`Transport.topics`; a transport that converts types, such as ROS, says so with
  :attr:`Transport.converts` and maps the port's type: the writer end's ``port``, the
  reader end's ``port``; it hands the reader end Python values, checked there as any
  outside input, and counts what it cannot convert with :meth:`ReaderEnd.refuse
  <dataflow.transports.ends.ReaderEnd.refuse>` or its :attr:`Stream.refused`).
  :meth:`Transport.check_stream` says, without joining anything, what would keep a port
  from a topic (a composite's load-time check).

What a transport carries, of these three kinds, it says at registration
(:attr:`Transport.carries`; by default, what its class implements): a policy naming it for
another kind is refused at once with :class:`CannotCarry`, naming the transport, what it
carries and which transports carry that kind (``scart connect --transport ros1``).

A transport is whole: what connects (these methods) and what answers in the deployer a
peer connects to (its serving half, :meth:`Transport.serving`; see :mod:`.serving`) are
in its own folder. The control plane only negotiates (finds the peer, checks the policy,
hands out what the transport asks for) and routes the calls of the sample path to the
transport that serves them. No transport imports another.

``transport="auto"`` tries every transport that takes part in ``auto`` by
:attr:`Transport.rank` (lowest first); a named transport is the only one tried.
Transports are found through the ``scart.transports`` entry points; scart's own (``ipc``,
``shm``, ``grpc``, ``zenoh``, ``ros1``, ``ros2``, ``yarp``) are registered exactly as a third party's would
be::

    [project.entry-points."scart.transports"]
    mine = "my_package.transport:MyTransport"

The entry point names a :class:`Transport` subclass (made with no arguments) or an
instance whose :attr:`~Transport.name` is the entry point's name (a lower-case word of at
most :data:`MAX_NAME` characters). It is loaded when a channel first asks for it (or for
``auto``); one that cannot be loaded is not tried again. This module imports no transport.
"""

from __future__ import annotations

import logging
import re
import threading
from abc import ABC
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from dataflow.errors import DataflowError

if TYPE_CHECKING:  # the ends import the policy, which reads the names from this registry
    import grpc

    from dataflow.policy import ConnPolicy
    from dataflow.ports import Port
    from dataflow.transports.ends import ReaderEnd, WriterEnd
    from dataflow.transports.serving import Serving
    from scart_wire.proto.scart.dataflow.v1.dataflow_pb2 import ConnPolicy as PolicyMsg
    from scart_wire.proto.scart.dataflow.v1.dataflow_pb2_grpc import DeployerServiceStub

__all__ = ["CannotCarry", "ENTRY_POINT_GROUP", "KINDS", "Kind", "LinkRefused", "MAX_NAME", "Peer", "Stream",
           "StreamProblem", "Transport", "TransportError", "TransportRegistry", "candidates", "carry", "default",
           "load", "names", "refusal"]

log = logging.getLogger(__name__)

ENTRY_POINT_GROUP = "scart.transports"
MAX_NAME = 32  #: characters of a transport's name, at most (it travels in every remote policy)
NAME = re.compile(rf"^[a-z][a-z0-9_.-]{{0,{MAX_NAME - 1}}}$")

#: scart's own transports, used also when its entry points are not installed (a source tree).
BUILTIN = MappingProxyType({"ipc": "dataflow.transports.ipc:IpcTransport",
                            "shm": "dataflow.transports.ipc.shm:ShmTransport",
                            "grpc": "dataflow.transports.grpc:GrpcTransport",
                            "zenoh": "dataflow.transports.zenoh:ZenohTransport",
                            "ros1": "dataflow.transports.ros1.transport:Ros1Transport",
                            "ros2": "dataflow.transports.ros2:Ros2Transport",
                            "yarp": "dataflow.transports.yarp:YarpTransport"})


class TransportError(DataflowError):
    """A transport is unknown, cannot be loaded, is not what its name says, or cannot do
    what a channel asks of it (a stream on a transport without topics)."""


#: The kinds of channel a transport may carry (see the module docstring).
Kind = Literal["link", "subscription", "stream"]
KINDS: tuple[Kind, ...] = ("link", "subscription", "stream")
_NOUNS = MappingProxyType({"link": "links", "subscription": "subscriptions", "stream": "topics"})


class CannotCarry(TransportError, ValueError):
    """A policy names a transport for a kind of channel it does not carry (it says what
    it carries at registration: :attr:`Transport.carries`)."""


class LinkRefused(TransportError):
    """The sink refused a link (another type, no such input port): retrying cannot help."""


class Peer:
    """The other side of a link or a subscription, as the control plane found it.

    ``address`` and ``stub`` (its ``DeployerService``), the ``task`` and ``port`` there,
    ``timeout`` (s) for control-plane calls, ``heartbeat`` (s, a subscription's), and
    ``channel`` (a link's id: ``boot id/serial`` of its source). ``policy_msg`` is the
    channel's policy as the control plane negotiated it, in its wire form: a transport
    sends it as it is. The owner cancels a connection in progress through :meth:`cancel`;
    a transport registers how with :meth:`opened`. Thread-safe.
    """

    def __init__(self, address: str, task: str, port: str, stub: DeployerServiceStub, timeout: float, *,
                 policy_msg: PolicyMsg, policy: ConnPolicy | None = None, channel_of: grpc.Channel | None = None,
                 heartbeat: float = 0.5, channel: str = "", name: str = "", boot_id: str = "",
                 source_ns: str = "") -> None:
        self.address = address
        self.task = task
        self.port = port
        self.stub = stub
        self.timeout = timeout
        self.policy_msg = policy_msg
        self.policy = policy  #: a subscription's policy (a link's is its writer end's)
        self.channel_of = channel_of  #: the gRPC channel to the peer (for a transport's own calls)
        self.heartbeat = heartbeat
        self.channel = channel
        self.name = name
        self.boot_id = boot_id
        self.source_ns = source_ns
        self.cancelled = threading.Event()
        self._cancel: Callable[[], object] | None = None
        self._finish: Callable[[float], bool] | None = None
        self._lock = threading.Lock()

    @property
    def transport(self) -> str:
        """The transport a subscription's policy names (``auto`` by default)."""
        return self.policy.transport if self.policy is not None else "auto"

    @property
    def where(self) -> str:
        """``task.port`` at the peer."""
        return f"{self.task}.{self.port}"

    def opened(self, cancel: Callable[[], object], finish: Callable[[float], bool] | None = None) -> bool:
        """A connection is up; ``cancel`` ends it at once, ``finish(timeout)`` (a link's)
        ends it gracefully. False (and ``cancel`` called) when the owner cancelled meanwhile."""
        with self._lock:
            self._cancel, self._finish = cancel, finish
            cancelled = self.cancelled.is_set()
        if cancelled:
            cancel()
        return not cancelled

    def cancel(self) -> None:
        """End the connection in progress, and any later one (idempotent)."""
        with self._lock:
            self.cancelled.set()
            cancel, self._cancel, self._finish = self._cancel, None, None
        if cancel is not None:
            cancel()

    def finish(self, timeout: float) -> bool:
        """End the connection in progress gracefully (what waits is delivered, the reader
        reports) within ``timeout`` s, and any later one; True when the reader confirmed."""
        with self._lock:
            self.cancelled.set()
            finish, cancel, self._cancel, self._finish = self._finish, self._cancel, None, None
        if finish is not None:
            return finish(timeout)
        if cancel is not None:
            cancel()
        return False


class Stream(ABC):
    """A writer or reader end joined to a topic (what :meth:`Transport.stream` returns).

    What it says of itself (``scart links``, ``scart describe``) beyond its ends' counts
    has defaults for a transport with nothing more to say."""

    topic: str = ""
    #: The topic's own type when the transport converts (a ROS message type), else "".
    type_name: str = ""
    #: Whether whoever publishes on the topic is authenticated (False: ROS); None: not said.
    authenticated: bool | None = None

    @property
    def waiting(self) -> str:
        """What the stream waits for before it is joined (a master, a broker), "" when joined."""
        return ""

    @property
    def refused(self) -> int:
        """Samples the transport itself refused (a value it could not convert), not
        counted by the ends."""
        return 0

    @property
    def refusal(self) -> str:
        """Why the last of :attr:`refused` was refused ("" before any)."""
        return ""

    def close(self) -> None:
        """Leave the topic (idempotent)."""


@dataclass(frozen=True)
class StreamProblem:
    """Why a stream cannot be made as asked (:meth:`Transport.check_stream`); a
    ``warning`` does not keep it from being made; ``types``: it is about the port's type
    and the topic's (a converting transport's), not the options."""

    message: str
    warning: bool = False
    types: bool = False


class Transport(ABC):
    """One way of carrying samples between processes (see the module docstring)."""

    #: The name a policy selects it by (``ConnPolicy(transport=name)``).
    name: str = ""
    #: ``auto`` tries lower ranks first; None: used only when named.
    rank: int | None = None
    #: It joins ends to named topics (:meth:`stream`).
    topics: bool = False
    #: It carries its own message types (a port's type is mapped onto them: ROS).
    converts: bool = False
    #: What it carries, of links, subscriptions and streams — what a policy may name it
    #: for. Said by the class (what is registered): a class that does not say it carries
    #: what it implements (:meth:`link`, :meth:`subscribe`; :attr:`topics` for streams).
    carries: ClassVar[frozenset[Kind]] = frozenset()
    #: Its links hold a waiting writer back (``ConnPolicy.wait``, YARP's flow control: its
    #: reader ends report at once after each sample and each read that frees room; see
    #: :mod:`.flow`). A link whose writer waits is carried only by such a transport.
    waits: bool = False

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        if "carries" not in cls.__dict__:  # not said: what the class implements
            has: dict[Kind, bool] = {"link": cls.link is not Transport.link,
                                     "subscription": cls.subscribe is not Transport.subscribe, "stream": cls.topics}
            cls.carries = frozenset(kind for kind in KINDS if has[kind])

    def lacks(self, kind: Kind) -> str:
        """Why a policy naming this transport cannot have a channel of ``kind`` ("" when
        it carries it): what it carries, and the transports that carry ``kind``."""
        if kind in self.carries:
            return ""
        carried = " and ".join(_NOUNS[k] for k in KINDS if k in self.carries) or "nothing"
        return (f"transport {self.name!r} carries {carried}, not {_NOUNS[kind]}; {kind}s need one of: "
                f"{', '.join(_carriers(kind)) or 'none'}")

    def link(self, end: WriterEnd, peer: Peer) -> bool:
        """Carry ``end``'s samples to the input port ``peer.where`` until the connection
        ends. Default: links not carried (False)."""
        return False

    def subscribe(self, end: ReaderEnd, peer: Peer) -> bool:
        """Carry the samples of the output port ``peer.where`` to ``end`` until the
        connection ends. Default: subscriptions not carried (False)."""
        return False

    def serving(self) -> type[Serving] | None:
        """The class of this transport's serving half: what answers, in a deployer, the
        links and subscriptions its peers ask for there (:mod:`.serving`). Default: None,
        nothing to serve (a transport of topics)."""
        return None

    def stream(self, end: WriterEnd | ReaderEnd, topic: str, options: dict[str, str]) -> Stream:
        """Join ``end`` to ``topic`` (a writer end publishes, a reader end receives);
        ``options``: what the user gave besides (a ROS message type...). Raises
        :class:`TransportError` for a transport without topics or a bad topic."""
        raise CannotCarry(self.lacks("stream"))

    def check_stream(self, port: Port[Any], topic: str, options: dict[str, str]) -> list[StreamProblem]:
        """What keeps ``port`` (an input or output port, a task's or its class's template)
        from being joined to ``topic`` with ``options``, found without joining anything:
        a composite's load-time check asks it. Default: nothing for a transport with
        topics; for a converting one, whether the port's type maps onto the topic's."""
        if "stream" not in self.carries:
            return [StreamProblem(self.lacks("stream").partition(";")[0])]
        return []

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"


def _carriers(kind: Kind) -> list[str]:
    """The transports that carry ``kind`` (each loaded; one that cannot be is left out)."""
    found = []
    for name in names():
        try:
            if kind in load(name).carries:
                found.append(name)
        except TransportError:
            continue
    return found


class TransportRegistry:
    """The transports of this process, by name: entry points read once, each transport
    loaded once, when first asked for. Thread-safe. :data:`default` is the one channels
    use (the entry points are process-wide, so is it)."""

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
                                 "not a dataflow.transports.Transport")
        if transport.name != name:
            raise TransportError(f"transport {name!r} ({ep.value}) says its name is {transport.name!r}")
        return transport

    def candidates(self, wanted: str) -> list[Transport]:
        """The transports to try, in order, for a policy's ``transport``: the one named, or
        for ``auto`` every one with a rank, lowest first (one that cannot be loaded is
        skipped with a warning, once)."""
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
        """Log ``message`` about transport ``name`` once per process."""
        with self._lock:
            first = name not in self._warned
            self._warned.add(name)
        if first:
            log.warning("%s", message)


#: The registry channels use (entry points are process-wide; so is it).
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


def refusal(wanted: str, kind: Kind) -> CannotCarry | None:
    """Why a policy's ``wanted`` transport cannot carry a channel of ``kind`` (None when it
    can, and for ``auto``); a :class:`TransportError` naming it when it cannot be loaded."""
    if wanted == "auto":
        return None
    lacking = load(wanted).lacks(kind)
    return CannotCarry(lacking) if lacking else None


def carry(wanted: str, attempt: Callable[[Transport], bool], what: str,
          peer_failures: tuple[type[BaseException], ...], kind: Kind) -> None:
    """Offer one connection to the transports for a policy's ``wanted`` in order, until
    ``attempt(transport)`` says one carried it (and it ended). Raises what an attempt
    raised when it is a peer's failure (``peer_failures``, the owner's: it reconnects), or
    :class:`TransportError` naming ``what`` and the transports tried when every one
    declined; :class:`CannotCarry` at once when the transport named does not carry
    ``kind`` (under ``auto``, only those that do are tried). Under ``auto``, a transport
    that raises anything else (a plug-in's bug) is passed over, said once, and the next
    one tried: it never keeps the connection from the transports that work."""
    refused = refusal(wanted, kind)
    if refused is not None:
        raise refused
    tried = []
    for transport in candidates(wanted):
        if kind not in transport.carries:
            continue
        tried.append(transport.name)
        try:
            if attempt(transport):
                return
        except peer_failures:
            raise
        except Exception as exc:
            if wanted != "auto":
                raise
            default.warn_once(f"failed:{transport.name}", f"transport {transport.name!r} failed for {what} "
                              f"({type(exc).__name__}: {exc}); auto goes on with the next one")
    raise NoTransportError(f"no transport reaches {what} (tried {', '.join(tried) or 'none'})")


class NoTransportError(TransportError):
    """Every transport a policy allows declined a connection (a peer with none in common)."""
