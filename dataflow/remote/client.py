"""The gRPC implementation of the proxy API (JOrocos's *corba* package).

``connect(address)`` talks to a name service (standalone, or embedded in a deployer)
and reaches each component's deployer directly. Every unary call has a deadline
(``timeout``). Proxies hold names, not addresses: a call that finds its deployer gone
re-resolves the name and retries once, so a restarted deployer (same or new address)
is picked up by itself. Only idempotent calls (describe, list, read, get, resolve) are
retried after any UNAVAILABLE; the others (write, call, set, lifecycle, connect) only
when the request provably never left (no connection could be made), so an operation
is never run twice. Subscriptions run on two threads each — a receiver that owns
the stream (and reconnects, reporting the gap), and the observer's dispatcher fed
through a policy-shaped :class:`~dataflow.remote._delivery.Mailbox` — and detect a frozen
peer by the stream's heartbeats (3 missed → reconnect).
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import grpc

from scart_wire import codec
from dataflow.errors import DataflowError, NotFoundError
from dataflow.introspection import (
    LinkDescription, OperationDescription, PortDescription, PortStreamDescription, PropertyDescription,
    SubscriptionDescription, TaskDescription,
)
from dataflow.policy import ConnPolicy, FlowStatus, WaitMode, WriteStatus
from dataflow.remote import _convert as cv
from dataflow.remote import errors
from scart_wire import rpc
from dataflow.remote._links import SOURCE_GONE
from dataflow.remote._proto import df_grpc
from dataflow.remote._proto import df as pb
from dataflow.remote._subscription import GrpcSubscription
from dataflow.remote.api import (
    TRANSITIONS, ComponentInfo, ComponentProxy, GapEvent, Observer, PortWriter, Subscription, System, split_port,
)
from dataflow.remote.naming import Lookups, NameClient
from scart_wire.security import Security

if TYPE_CHECKING:
    from google.protobuf.message import Message

__all__ = ["GrpcSystem", "GrpcComponentProxy", "GrpcSubscription", "GrpcPortWriter", "connect"]

log = logging.getLogger(__name__)

_RETRYABLE = (errors.UnavailableError,)
#: Methods safe to send twice (they change nothing on the deployer).
_IDEMPOTENT = frozenset({"DescribeTask", "ListTasks", "ReadPort", "GetProperty"})
#: gRPC's wording when no connection could be made (the request was never sent).
_NOT_SENT = ("failed to connect to all addresses", "connection refused", "dns resolution failed")


def _never_sent(exc: errors.RemoteError) -> bool:
    """True when ``exc`` says the call failed before its request reached any server."""
    text = str(exc).lower()
    return any(marker in text for marker in _NOT_SENT)


class GrpcSystem(System):
    """A data-flow system reached through the name service at ``address`` (or through
    ``names``, another source of lookups; ``address`` then only names it in messages).

    ``timeout``: deadline of every unary call (s). ``heartbeat_ms``: idle heartbeat the
    subscriptions ask for (a peer silent for 3 of them is treated as frozen).
    Thread-safe; :meth:`close` is idempotent and closes every subscription and writer.
    """

    def __init__(self, address: str, timeout: float = 2.0, heartbeat_ms: int = 500,
                 security: Security | None = None, names: Lookups | None = None) -> None:
        self.address = address
        self.timeout = timeout
        self.heartbeat_ms = heartbeat_ms
        self.security = security or Security()
        # lookups: the name service at ``address``, or another source with the name
        # client's resolve/entries/close (e.g. Zenoh liveliness, ``zenoh_transport.ZenohNames``)
        self._ns = names if names is not None else NameClient(address, timeout=timeout, security=self.security)
        self._lock = threading.Lock()
        self._channels: dict[str, tuple[grpc.Channel, df_grpc.DeployerServiceStub]] = {}
        self._where: dict[str, str] = {}
        self._owned: set[Subscription | PortWriter] = set()
        self._closed = False

    # ---- plumbing ----------------------------------------------------------------------
    def _stub(self, address: str) -> df_grpc.DeployerServiceStub:
        """The DeployerService stub for ``address`` (one channel per address, cached)."""
        with self._lock:
            if self._closed:
                raise errors.ClosedError("this system proxy is closed")
            entry = self._channels.get(address)
            if entry is None:
                channel = self.security.channel(address, rpc.channel_options())
                entry = self._channels[address] = (channel, df_grpc.DeployerServiceStub(channel))
            return entry[1]

    def resolve(self, component: str, fresh: bool = False) -> str:
        """Address of the deployer serving ``component`` (cached unless ``fresh``)."""
        with self._lock:
            cached = self._where.get(component)
        if cached and not fresh:
            return cached
        address = self._ns.resolve(component).address
        with self._lock:
            self._where[component] = address
        return address

    def _invoke(self, component: str, method: str, request: Message, timeout: float | None = None) -> Any:
        """Call ``method`` on the deployer of ``component`` with a deadline; when the deployer is
        gone (UNAVAILABLE) or no longer has the component, re-resolve and retry once — an
        UNAVAILABLE non-idempotent call only if its request was never sent."""
        deadline = timeout or self.timeout
        address = self.resolve(component)
        try:
            return rpc.call(getattr(self._stub(address), method), request, deadline, address)
        except _RETRYABLE as exc:
            if method not in _IDEMPOTENT and not _never_sent(exc):
                try:
                    self.resolve(component, fresh=True)  # the next call goes to the right place
                except DataflowError:
                    pass
                raise
            address = self.resolve(component, fresh=True)
        except errors.RemoteNotFoundError:
            # the cached address may now be served by another deployer: retry only if moved
            moved = self.resolve(component, fresh=True)
            if moved == address:
                raise
            address = moved
        return rpc.call(getattr(self._stub(address), method), request, deadline, address)

    def own(self, item: Subscription | PortWriter) -> None:
        """Track a subscription/writer so :meth:`close` closes it."""
        with self._lock:
            self._owned.add(item)

    def disown(self, item: Subscription | PortWriter) -> None:
        """Stop tracking ``item`` (idempotent)."""
        with self._lock:
            self._owned.discard(item)

    # ---- System API --------------------------------------------------------------------
    def component_names(self) -> list[str]:
        """Names registered in the name service, sorted."""
        return sorted(e.component for e in self._ns.entries())

    def component(self, name: str) -> GrpcComponentProxy:
        """A proxy; raises ``NotFoundError`` listing the registered names."""
        self.resolve(name, fresh=True)
        return GrpcComponentProxy(self, name)

    def components(self) -> list[ComponentInfo]:
        """A summary per registered component (one ListTasks per deployer)."""
        entries = self._ns.entries()
        out: list[ComponentInfo] = []
        for address in sorted({e.address for e in entries}):
            names = {e.component for e in entries if e.address == address}
            try:
                reply = rpc.call(self._stub(address).ListTasks, pb.ListTasksRequest(), self.timeout, address)
            except errors.RemoteError as exc:
                log.warning("deployer %s: %s", address, exc)
                out += [ComponentInfo(n, "UNREACHABLE", "", 0.0, 0, 0, address) for n in sorted(names)]
                continue
            for t in reply.tasks:
                if t.name in names:
                    out.append(ComponentInfo(t.name, t.state, t.activity, t.period, t.cycles, t.overruns, address,
                                             t.last_cycle))
        return sorted(out, key=lambda c: c.name)

    def connect_ports(self, source: str, sink: str, policy: ConnPolicy = ConnPolicy.data(),
                      name: str | None = None) -> str:
        """Connect ``"a.out"`` to ``"b.in"`` as the link ``name`` (default ``"a.out->b.in"``);
        the source's deployer makes the link (see :meth:`System.connect_ports`)."""
        (st, sp), (kt, kp) = split_port(source), split_port(sink)
        req = pb.ConnectPortsRequest(
            source_task=st, source_port=sp, sink_task=kt, sink_port=kp, policy=cv.policy_to_msg(policy),
            name=name or "",
        )
        return str(self._invoke(st, "ConnectPorts", req).note)

    def stream(self, port: str, policy: ConnPolicy, options: dict[str, str] | None = None,
               name: str | None = None) -> LinkDescription:
        """Join ``"task.port"`` to ``policy.topic`` of ``policy.transport``; the port's
        deployer makes the stream (see :meth:`System.stream`)."""
        task, port_name = split_port(port)
        req = pb.StreamPortRequest(task=task, port=port_name, policy=cv.policy_to_msg(policy),
                                   options=options or {}, name=name or "")
        return _link_description(self._invoke(task, "StreamPort", req).link)

    def _listings(self) -> list[tuple[str, pb.ListLinksResponse]]:
        """``(address, ListLinks reply)`` of every deployer the name service knows that answers."""
        out = []
        for address in sorted({e.address for e in self._ns.entries()}):
            try:
                out.append((address, rpc.call(self._stub(address).ListLinks, pb.ListLinksRequest(),
                                               self.timeout, address)))
            except errors.RemoteError as exc:
                log.warning("deployer %s: %s", address, exc)
        return out

    def links(self) -> list[LinkDescription]:
        """Every link of every deployer the name service knows (one ListLinks each), by name."""
        out = [_link_description(lk) for _, reply in self._listings() for lk in reply.links]
        by_source = {(lk.source, lk.sink) for lk in out if lk.detail != SOURCE_GONE}
        out = [lk for lk in out if lk.detail != SOURCE_GONE or (lk.source, lk.sink) not in by_source]
        return sorted(out, key=lambda lk: lk.name)

    def subscriptions(self) -> list[SubscriptionDescription]:
        """Every subscription the deployers the name service knows serve (one ListLinks
        each), by deployer and number."""
        return [SubscriptionDescription(deployer=address, id=sub.id, source=sub.source, subscriber=sub.subscriber,
                                        policy=sub.policy, transport=sub.transport, samples=sub.samples,
                                        dropped=sub.dropped)
                for address, reply in self._listings() for sub in reply.subscriptions]

    def _link(self, name: str) -> LinkDescription:
        links = self.links()
        found = [lk for lk in links if lk.name == name]
        if not found:
            raise NotFoundError(f"no link {name!r}; links: {', '.join(lk.name for lk in links[:20]) or 'none'}")
        if len(found) > 1:
            raise DataflowError(f"link name {name!r} is used in {len(found)} deployers (sources "
                                f"{', '.join(lk.source for lk in found[:5])}): use the ports instead")
        return found[0]

    def reroute(self, name: str, sink: str) -> LinkDescription:
        """Point the link ``name`` at input ``"c.in"`` (its source's deployer does it: the new
        connection first, then the old one undone)."""
        link = self._link(name)
        kt, kp = split_port(sink)
        reply = self._invoke(split_port(link.source)[0], "RerouteLink",
                             pb.RerouteLinkRequest(name=name, sink_task=kt, sink_port=kp))
        return _link_description(reply.link)

    def disconnect_link(self, name: str) -> bool:
        """Undo the link called ``name``; False if it was gone already."""
        return self.disconnect_link_counted(name) is not None

    def disconnect_link_counted(self, name: str) -> int | None:
        """:meth:`disconnect_link`, with the samples never delivered (None: it was gone)."""
        link = self._link(name)
        reply = self._invoke(split_port(link.source)[0], "DisconnectPorts", pb.DisconnectPortsRequest(name=name))
        return int(reply.undelivered) if reply.disconnected else None

    def disconnect_ports(self, source: str, sink: str) -> bool:
        """Undo :meth:`connect_ports`; False if they were not connected."""
        return self.disconnect_counted(source, sink) is not None

    def disconnect_counted(self, source: str, sink: str) -> int | None:
        """:meth:`disconnect_ports`, with the samples never delivered (None: not connected)."""
        (st, sp), (kt, kp) = split_port(source), split_port(sink)
        req = pb.DisconnectPortsRequest(source_task=st, source_port=sp, sink_task=kt, sink_port=kp)
        reply = self._invoke(st, "DisconnectPorts", req)
        return int(reply.undelivered) if reply.disconnected else None

    def close(self) -> None:
        """Close subscriptions, writers, channels (idempotent)."""
        with self._lock:
            if self._closed:
                return
            owned = list(self._owned)
            self._owned.clear()
        for item in owned:
            item.close()
        with self._lock:
            self._closed = True
            channels = [c for c, _ in self._channels.values()]
            self._channels.clear()
        for channel in channels:
            channel.close()
        self._ns.close()


def _link_description(lk: pb.LinkInfo) -> LinkDescription:
    """A ``LinkInfo`` message as the core's description."""
    return LinkDescription(name=lk.name, source=lk.source, sink=lk.sink, policy=lk.policy, transport=lk.transport,
                           samples=lk.samples, dropped=lk.dropped, kind=lk.kind or "link",
                           state=lk.state or "connected", detail=lk.detail, pending=lk.pending)


def _task_description(info: pb.TaskInfo) -> tuple[TaskDescription, dict[str, object]]:
    s = info.summary
    ports = [
        PortDescription(
            name=p.name, direction=p.direction, type_name=p.type_name, doc=p.doc,
            connections=p.connections, event=p.event, bounds=p.bounds, check=p.check, writes=p.writes,
            streams=[PortStreamDescription(name=s.name, topic=s.topic, type_name=s.type_name, state=s.state or "connected",
                                           refused=s.refused, refusal=s.refusal, unauthenticated=s.unauthenticated)
                     for s in p.streams],
        )
        for p in info.ports
    ]
    props = [
        PropertyDescription(name=p.name, type_name=p.type_name, value=json.loads(p.json_value or "null"), doc=p.doc,
                            bounds=p.bounds)
        for p in info.properties
    ]
    ops = [
        OperationDescription(
            name=o.name, params=[(x.name, x.type_name) for x in o.params], returns=o.returns,
            doc=o.doc, own_thread=o.own_thread, signature=o.signature,
        )
        for o in info.operations
    ]
    desc = TaskDescription(
        name=s.name, state=s.state, activity=s.activity, period=s.period, cycles=s.cycles,
        overruns=s.overruns, last_cycle=s.last_cycle, ports=ports, properties=props, operations=ops,
    )
    last = {p.name: codec.decode(p.last_value) for p in info.ports if p.has_last_value}
    return desc, last


class GrpcComponentProxy(ComponentProxy):
    """A component reached over gRPC (see :class:`~dataflow.remote.api.ComponentProxy`)."""

    def __init__(self, system: GrpcSystem, name: str) -> None:
        self.system = system
        self.name = name
        self._seen: dict[str, tuple[str, int]] = {}
        self._lock = threading.Lock()

    def _invoke(self, method: str, request: Message, timeout: float | None = None) -> Any:
        return self.system._invoke(self.name, method, request, timeout)  # noqa: SLF001

    @property
    def state(self) -> str:
        return self.describe().state

    def describe(self) -> TaskDescription:
        return self.describe_with_values()[0]

    def describe_with_values(self) -> tuple[TaskDescription, dict[str, object]]:
        """Description and output ports' last values from one call."""
        return _task_description(self._invoke("DescribeTask", pb.DescribeTaskRequest(task=self.name)).task)

    def last_values(self) -> dict[str, object]:
        return self.describe_with_values()[1]

    def change_state(self, transition: str) -> bool:
        if transition not in TRANSITIONS:
            raise ValueError(f"unknown transition {transition!r}; expected one of {', '.join(TRANSITIONS)}")
        req = pb.ChangeStateRequest(task=self.name, transition=f"TRANSITION_{transition.upper()}")
        return bool(self._invoke("ChangeState", req).accepted)

    def connect_input(self, port: str, policy: ConnPolicy = ConnPolicy.data()) -> GrpcPortWriter:
        return GrpcPortWriter(self, port, policy)

    def write(self, port: str, value: object) -> WriteStatus:
        req = pb.WritePortRequest(task=self.name, port=port, value=codec.encode(value))
        return cv.write_from_msg(self._invoke("WritePort", req).status)

    def write_json(self, port: str, json_value: object) -> WriteStatus:
        req = pb.WritePortRequest(task=self.name, port=port, json=json.dumps(json_value))
        return cv.write_from_msg(self._invoke("WritePort", req).status)

    def read(self, port: str) -> tuple[FlowStatus, object | None]:
        return self.read_sample(port)[:2]

    def read_sample(self, port: str, timeout: float | None = None) -> tuple[FlowStatus, object | None, int, int]:
        """``(flow, value, sequence, source_time_ns)``; NEW_DATA when written since this
        proxy's last read; ``sequence`` is the port's write number."""
        return self.read_sample_of(port, timeout)[:4]

    def read_sample_of(self, port: str, timeout: float | None = None) -> tuple[FlowStatus, object | None, int, int, str]:
        """:meth:`read_sample` plus the deployer's boot id (write numbers restart with a new one)."""
        reply = self._invoke("ReadPort", pb.ReadPortRequest(task=self.name, port=port), timeout)
        flow = cv.flow_from_msg(reply.flow_status)
        if flow is FlowStatus.NO_DATA:
            return FlowStatus.NO_DATA, None, 0, 0, reply.boot_id
        with self._lock:
            new = self._seen.get(port) != (reply.boot_id, reply.sequence)
            self._seen[port] = (reply.boot_id, reply.sequence)
        flow = FlowStatus.NEW_DATA if new else FlowStatus.OLD_DATA
        return flow, codec.decode(reply.value), reply.sequence, reply.source_time_ns, reply.boot_id

    def subscribe(
        self,
        port: str,
        observer: Observer,
        policy: ConnPolicy = ConnPolicy.data(),
        period: float | None = None,
        on_gap: Callable[[GapEvent], None] | None = None,
    ) -> GrpcSubscription:
        if policy.wait is not WaitMode.NO_WAIT:  # said, never dropped on the way
            raise ValueError(f"policy {policy}: a subscription's writer never waits for it (a link's may: "
                             "connect the port to an input port)")
        try:
            self.read_sample(port)  # raises now for an unknown port or an input port
        except errors.RemoteError as exc:
            if exc.code != "RESOURCE_EXHAUSTED":  # a value too large to read: the port is there
                raise
        with self._lock:
            self._seen.pop(port, None)
        return GrpcSubscription(self, port, observer, policy, period, on_gap)

    def call(self, operation: str, *args: object, timeout: float | None = None) -> object:
        req = pb.CallOperationRequest(task=self.name, operation=operation, args=[codec.encode(a) for a in args])
        return codec.decode(self._invoke("CallOperation", req, timeout).result)

    def call_json(self, operation: str, json_args: list[object], timeout: float | None = None) -> object:
        req = pb.CallOperationRequest(
            task=self.name, operation=operation, json_args=[json.dumps(a) for a in json_args], use_json=True
        )
        return codec.decode(self._invoke("CallOperation", req, timeout).result)

    def get_property(self, name: str) -> object:
        return codec.decode(self._invoke("GetProperty", pb.GetPropertyRequest(task=self.name, name=name)).value)

    def set_property(self, name: str, value: object) -> None:
        self._invoke("SetProperty", pb.SetPropertyRequest(task=self.name, name=name, value=codec.encode(value)))

    def set_property_json(self, name: str, json_value: object) -> object:
        req = pb.SetPropertyRequest(task=self.name, name=name, json=json.dumps(json_value))
        return json.loads(self._invoke("SetProperty", req).json_value)


class GrpcPortWriter(PortWriter):
    """A remote writer (OpenWriter); re-opened by itself after its deployer restarted."""

    def __init__(self, proxy: GrpcComponentProxy, port: str, policy: ConnPolicy) -> None:
        super().__init__(proxy.name, port, policy)
        self._proxy = proxy
        self._id = ""
        self._closed = False
        self._open()
        proxy.system.own(self)

    def _open(self) -> None:
        req = pb.OpenWriterRequest(task=self.component, port=self.port, policy=cv.policy_to_msg(self.policy))
        self._id = self._proxy._invoke("OpenWriter", req).writer

    def write(self, value: object) -> WriteStatus:
        if self._closed:
            raise errors.ClosedError(f"writer to {self.component}.{self.port} is closed")
        req = pb.WritePortRequest(writer=self._id, value=codec.encode(value))
        try:
            return cv.write_from_msg(self._proxy._invoke("WritePort", req).status)
        except errors.RemoteNotFoundError:
            # the deployer restarted, or reclaimed our writer after it sat unused: the
            # sample was not written; a new writer takes it
            self._open()
            req.writer = self._id
            return cv.write_from_msg(self._proxy._invoke("WritePort", req).status)

    def close(self) -> None:
        """Close the writer: the deployer first lets its task read what is still pending
        (a moment, at most); samples it never read are logged here, as not delivered."""
        if self._closed:
            return
        self._closed = True
        self._proxy.system.disown(self)
        try:
            reply = self._proxy._invoke("CloseWriter", pb.CloseWriterRequest(writer=self._id), timeout=2.0)
        except DataflowError:
            return
        self.undelivered = int(reply.undelivered)
        if self.undelivered:
            log.warning("writer to %s.%s closed: %d sample(s) were never read by the task", self.component,
                        self.port, self.undelivered)


def connect(address: str, timeout: float = 2.0, heartbeat_ms: int = 500,
            security: Security | None = None) -> GrpcSystem:
    """Connect to the name service at ``address`` (standalone or embedded in a deployer).

    ``security``: TLS files and the token to send (default: ``Security.from_env()``, the
    ``SCART_TLS_*`` and ``SCART_TOKEN`` variables). Checks at once that it answers:
    raises :class:`errors.UnavailableError` naming the address otherwise (or
    :class:`errors.RemoteTimeoutError`, :class:`errors.AuthenticationError`,
    :class:`errors.PermissionDeniedError`).
    """
    system = GrpcSystem(address, timeout=timeout, heartbeat_ms=heartbeat_ms,
                        security=security if security is not None else Security.from_env())
    try:
        system.component_names()
    except BaseException:
        system.close()
        raise
    return system

