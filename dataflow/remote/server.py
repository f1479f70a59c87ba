"""Serve a :class:`dataflow.Deployer` over gRPC: ``server = deployer.serve(address)``.

The server offers ``scart.dataflow.v1.DeployerService``, standard gRPC health checking
and server reflection (``grpcurl -plaintext ADDRESS list`` works), and — unless told to
join another one with ``ns=`` — an embedded ``scart.naming.v1.NamingService`` in which
its tasks are registered, so one deployer is a whole system. With ``ns="host:port"``
the tasks are registered there under a lease renewed by heartbeats.

Limits: messages ≤ 4 MiB (RESOURCE_EXHAUSTED beyond), at most ``max_workers``
concurrent RPCs (RESOURCE_EXHAUSTED beyond, never an unbounded queue), at most
``max_workers - 8`` subscriptions. It binds 127.0.0.1 unless given another address.

Shutdown: :meth:`DeployerServer.stop` signals every stream and cross-deployer link,
unregisters, stops the gRPC server, waits for it and ends its worker threads (idempotent, safe from any thread
except an RPC handler of this server).
"""

from __future__ import annotations

import itertools
import logging
import secrets
import threading
import time
from typing import TYPE_CHECKING, cast

import grpc

from scart_wire.rpc import MethodHandler
from grpc_health.v1 import health_pb2

from dataflow.deployer import Deployer, same_policy
from dataflow.errors import CONNECT_DIRECTION, CONNECT_TYPE, DeploymentError, NotFoundError, PortTypeError
from dataflow.introspection import LinkDescription
from dataflow.policy import ConnPolicy
from dataflow.transports import CannotCarry, load, names, refusal
from dataflow.transports.flow import waits
from dataflow.remote import errors
from scart_wire import rpc
from dataflow.remote._links import CLOSE_S, SETTLE_S, LinkKeeper, RemoteLink
from dataflow.remote._proto import df as pb
from dataflow.remote._proto import (
    DEPLOYER_ROLES,
    DEPLOYER_SERVICE_NAME,
    NAMING_ROLES,
    NAMING_SERVICE_NAME,
    df_grpc,
    ns,
    ns_grpc,
)
from dataflow.remote._channels import Channels
from dataflow.remote._servicer import DeployerServicer
from dataflow.remote.naming import (
    DEFAULT_LEASE,
    NameClient,
    NameRegistry,
    NamingServicer,
    Registration,
    RegistryFullError,
    boot_service,
    held_elsewhere,
    security_probe,
)
from scart_wire.security import Security

if TYPE_CHECKING:
    from dataflow.ports import OutputPort
    from dataflow.remote._registry import NameEntry
from dataflow.transports.limits import check_fits
from dataflow.transports.streams import PortStream

__all__ = ["DeployerServer"]

log = logging.getLogger(__name__)

REASSERT_S = 1.0  #: how often an embedded deployer claims again the names another deployer held


def add_deployer_service(servicer: DeployerServicer, server: grpc.Server) -> None:
    """Register the DeployerService: the control plane's methods (the servicer's own),
    and the sample path's, answered by the transports that serve them (dispatched by
    :meth:`~dataflow.remote._channels.Channels.handler`)."""
    handlers: dict[str, MethodHandler] = {}

    class _Capture:
        def add_generic_rpc_handlers(self, found: object) -> None:
            pass

        def add_registered_method_handlers(self, _name: str, found: dict[str, MethodHandler]) -> None:
            handlers.update(found)

    df_grpc.add_DeployerServiceServicer_to_server(servicer, _Capture())
    base = df_grpc.DeployerServiceServicer
    own = {name: h for name, h in handlers.items() if getattr(type(servicer), name) is not getattr(base, name)}
    server.add_generic_rpc_handlers((_Routes(own, servicer.channels),))


class _Routes(grpc.GenericRpcHandler):
    """The DeployerService's calls: the control plane's to its servicer, the others to
    the transport that serves them (None: UNIMPLEMENTED)."""

    def __init__(self, own: dict[str, MethodHandler], channels: Channels) -> None:
        self._own = own
        self._channels = channels
        self._prefix = f"/{DEPLOYER_SERVICE_NAME}/"

    def service(self, handler_call_details: grpc.HandlerCallDetails) -> MethodHandler | None:
        path = handler_call_details.method
        if not path.startswith(self._prefix):
            return None
        method = path[len(self._prefix):]
        return self._own.get(method) or self._channels.handler(method)


class _EmbeddedNaming(NamingServicer):
    """The embedded name service: publishes tasks added to the deployer after it started
    serving before answering a lookup."""

    def __init__(self, owner: DeployerServer, registry: NameRegistry) -> None:
        super().__init__(registry)
        self._owner = owner

    def Resolve(self, request: ns.ResolveRequest, context: grpc.ServicerContext) -> ns.ResolveResponse:  # noqa: N802
        self._owner.refresh_names()
        return super().Resolve(request, context)

    def ListEntries(self, request: ns.ListEntriesRequest, context: grpc.ServicerContext) -> ns.ListEntriesResponse:  # noqa: N802
        self._owner.refresh_names()
        return super().ListEntries(request, context)


class DeployerServer:
    """A running deployer server. ``address`` is where it serves; ``ns_address`` is the name
    service its tasks are registered in (its own address when embedded)."""

    def __init__(
        self,
        deployer: Deployer,
        address: str = "127.0.0.1:0",
        ns: str | None = None,
        lease_seconds: float = DEFAULT_LEASE,
        heartbeat_ms: int = 500,
        max_workers: int = 64,
        ns_timeout: float = 2.0,
        security: Security | None = None,
        advertise: str | None = None,
    ) -> None:
        if advertise:
            rpc.parse_advertise(advertise)  # a malformed one raises before anything is bound
        self.deployer = deployer
        #: Public id of this server's process (random per start): its health service answers
        #: SERVING for ``scart.boot.<boot_id>``, name services and clients tell restarts by it.
        self.boot_id = secrets.token_hex(8)
        self.security = security = security or Security()
        self.ns_timeout = ns_timeout
        self.registry: NameRegistry | None = None if ns else NameRegistry(
            default_lease=lease_seconds, probe=security_probe(security), own_boot_id=self.boot_id)
        self._lease_id = ""  # of our own names in the embedded registry
        self._servicer = DeployerServicer(self, heartbeat_ms=heartbeat_ms, max_streams=max(1, max_workers - 8))
        servicers: list[rpc.Servicer] = [(add_deployer_service, self._servicer)]
        names = [DEPLOYER_SERVICE_NAME]
        roles = dict(DEPLOYER_ROLES)
        if self.registry is not None:
            servicers.append((ns_grpc.add_NamingServiceServicer_to_server, _EmbeddedNaming(self, self.registry)))
            names.append(NAMING_SERVICE_NAME)
            roles.update(NAMING_ROLES)
        self._server, port, health, self._executor = rpc.make_server(
            address, servicers, names, max_workers, security=security, roles=roles)
        health.set(boot_service(self.boot_id), health_pb2.HealthCheckResponse.SERVING)
        self._health = health
        self.address = rpc.bound_address(address, port)
        #: What the server listens on (``0.0.0.0:P`` when bound to every interface).
        self.listen_address = f"{address.rpartition(':')[0] or '127.0.0.1'}:{port}"
        #: Where other processes are told to reach it (name service, Zenoh): ``advertise``,
        #: or the bound address; this host's name for a wildcard listener.
        self.advertised = rpc.advertised_address(self.listen_address, advertise)
        self.ns_address = ns or self.address
        self._links: dict[tuple[str, str, str, str], RemoteLink] = {}
        self._serials = itertools.count(1)
        self._lock = threading.Lock()
        self._reroute_lock = threading.Lock()  # one reroute at a time (check, connect, disconnect)
        self._stopped = False
        self._ns_client: NameClient | None = None
        self._registration: Registration | None = None
        self._published: list[str] = []
        self._refused: list[str] = []
        self._retry_at = 0.0
        self._keeper = LinkKeeper(self, self._servicer.channels.sinks)
        try:
            if self.registry is not None:
                self.refresh_names()
            else:
                self._ns_client = NameClient(self.ns_address, timeout=ns_timeout, security=security)
                self._registration = Registration(
                    self.ns_address, self.advertised, self.deployer.names, lease_seconds,
                    boot_id=self.boot_id, timeout=ns_timeout, security=security,
                )
                self._registration.start()
        except BaseException:
            self.stop()
            raise

    # ---- names -------------------------------------------------------------------------
    def refresh_names(self) -> list[str]:
        """Publish tasks added to the deployer after it started serving (embedded name
        service; a joined one learns them from the next heartbeat). Cheap when nothing changed.

        A name already held by another live deployer is not published: a warning names the
        component and that deployer, :attr:`refused_names` lists it, and every free name is
        published as usual — the name service keeps serving everyone. Never raises;
        returns the refused names (empty when all are published).
        """
        names = sorted(self.deployer.names())
        if self.registry is None or (names == self._published and
                                      (not self._refused or time.monotonic() < self._retry_at)):
            return self.refused_names
        self._retry_at = time.monotonic() + REASSERT_S  # refused names: claimed again after a while
        try:
            self._lease_id, _ = self.registry.register(self.advertised, names, permanent=True, boot_id=self.boot_id,
                                                       lease_id=self._lease_id)
            self._refused = []
        except errors.AlreadyRegisteredError:
            held = held_elsewhere(self.registry.resolve, names, self.boot_id)
            free = [n for n in names if n not in held]
            for name, where in sorted(held.items()):
                log.warning(
                    "component %r of the deployer at %s is not published: the name is held by the "
                    "deployer at %s; rename one of them", name, self.address, where,
                )
            self._refused = sorted(held)
            try:
                self._lease_id, _ = self.registry.register(self.advertised, free, permanent=True, boot_id=self.boot_id,
                                                           lease_id=self._lease_id)
            except (errors.AlreadyRegisteredError, RegistryFullError) as exc:  # raced, or busy
                log.warning("deployer at %s: publishing %s failed: %s", self.address, free, exc)
                return self.refused_names
        except RegistryFullError as exc:  # busy probing other claims: the next lookup tries again
            log.warning("deployer at %s: publishing its names is delayed: %s", self.address, exc)
            return self.refused_names
        self._published = names
        return self.refused_names

    @property
    def refused_names(self) -> list[str]:
        """Names of this deployer's tasks the name service refused (held by another deployer),
        as of the last publication (embedded) or heartbeat (joined)."""
        if self._registration is not None:
            return list(self._registration.refused)
        return list(self._refused)

    def resolve(self, component: str) -> str:
        """Address of the deployer serving ``component`` (this one, or via the name service)."""
        if component in self.deployer.names():
            return self.address
        if self.registry is not None:
            return self.registry.resolve(component).address
        assert self._ns_client is not None
        return self._ns_client.resolve(component).address

    def resolve_entry(self, component: str, ns: str = "") -> NameEntry:
        """The name service's entry for ``component`` (address and boot id): from the name
        service at ``ns`` when given and not this deployer's own, else from its own."""
        if ns and ns != self.ns_address:
            client = NameClient(ns, timeout=self.ns_timeout, security=self.security)
            try:
                return client.resolve(component)
            finally:
                client.close()
        if self.registry is not None:
            self.refresh_names()
            return self.registry.resolve(component)
        assert self._ns_client is not None
        return self._ns_client.resolve(component)

    # ---- connections -------------------------------------------------------------------
    def _output(self, task: str, port: str) -> OutputPort[object]:
        """The output port ``task.port`` of this deployer; raises naming what is wrong."""
        if task not in self.deployer.names():
            raise NotFoundError(
                f"source task {task!r} is not in the deployer at {self.address}; "
                f"it has: {', '.join(self.deployer.names()) or '(none)'} — send the request to the source's deployer"
            )
        out = self.deployer.task(task).port(port)
        if out.is_input:
            raise DeploymentError(f"{task}.{port} is an input port; a link's source must be an output port "
                                  f"[{CONNECT_DIRECTION}]")
        return cast("OutputPort[object]", out)  # not an input: an output

    def connect_ports(self, source_task: str, source_port: str, sink_task: str, sink_port: str, policy: ConnPolicy,
                      defer: bool = False, name: str | None = None,
                      resume: bool = False) -> tuple[bool, str, str, LinkDescription | None]:
        """Connect a local output port to a local or remote input port, as the link ``name``
        (default ``"a.out->b.in"``); returns ``(local, sink address, note, link)`` where
        ``note`` says what holds when the pair was connected already (its policy changed,
        it was renamed, or nothing changed; "" for a new link).

        Refused before anything is linked: the source not here or not an output port, the
        sink unknown (unless ``defer``: then the link waits for it, as when deployers
        start in any order), not an input port, or of another type (``PortTypeError``,
        both types named). A sink's refusal or a limit met by the first connection (a
        transport's streams per peer) is raised too, and the link undone. ``resume``: the
        sink's deployer makes the link again after this deployer restarted.
        """
        out = self._output(source_task, source_port)
        source, sink = f"{source_task}.{source_port}", f"{sink_task}.{sink_port}"
        if sink_task in self.deployer.names():
            note = self.deployer.connect_or_change(source, sink, policy, name)
            return True, self.address, note, self.deployer.find_link(self.deployer.link_name(source, sink))
        if name is not None:
            self.deployer.check_link_name(source, sink, name)
        refused = refusal(policy.transport, "link")  # ros1 carries topics, not links: said, by name
        if refused is not None:
            raise CannotCarry(f"link {source} -> {sink}: {refused}")
        if waits(policy) and policy.transport != "auto" and not load(policy.transport).waits:  # said, not dropped
            raise ValueError(f"link {source} -> {sink}: transport {policy.transport} carries no writer that waits "
                             f"({policy.wait.value}); {', '.join(n for n in names() if _waits(n))} do")
        check_fits(out, f"a link to {sink}")
        try:
            address = self.resolve(sink_task)
        except NotFoundError:
            if not defer:
                raise
            address = ""
        if address:
            self._check_sink(address, sink_task, sink_port, out)
        key = (source_task, source_port, sink_task, sink_port)
        with self._lock:
            old = self._links.get(key)
            given = name or (old.name if old is not None else f"{source}->{sink}")
            if old is not None and same_policy(old.policy, policy) and old.policy.transport == policy.transport:
                note = f"renamed from {old.name} to {given}" if given != old.name else "connected already"
                old.name = given
                if name is not None:
                    self.deployer.name_link(source, sink, name)
                return False, address, note, old.describe()
            link = self._links[key] = RemoteLink(self, out, sink_task, sink_port, policy, given, next(self._serials),
                                                 resume=resume)
        note = ""
        if old is not None:
            old.close()
            note = _changes(old.policy, policy, old.name, given)
        if name is not None:
            self.deployer.name_link(source, sink, name)
        if address:  # the sink is known: return once the first connection is settled (links then tells how)
            link.settled.wait(SETTLE_S)
            if link.refusal is not None:
                self.disconnect_ports(source_task, source_port, sink_task, sink_port, graceful=False)
                raise link.refusal
        return False, address, note, link.describe()

    def _check_sink(self, address: str, task: str, port: str, out: OutputPort[object]) -> None:
        """Refuse a link whose sink is not an input port of the source's type (asked to
        the sink's deployer): naming both types, as a composite's check does."""
        with self.security.channel(address, rpc.channel_options()) as channel:
            reply = rpc.call(df_grpc.DeployerServiceStub(channel).DescribeTask, pb.DescribeTaskRequest(task=task),
                              self.ns_timeout, address)
        ports = {p.name: p for p in reply.task.ports}
        info = ports.get(port)
        if info is None:
            raise NotFoundError(f"{task} has no port {port!r}; its ports: {', '.join(sorted(ports)) or '(none)'}")
        if info.direction != "in":
            raise DeploymentError(f"{task}.{port} is an output port; a link's sink must be an input port "
                                  f"[{CONNECT_DIRECTION}]")
        if info.type_name != out.type_name:
            raise PortTypeError(f"cannot connect {out.qualname} ({out.type_name}) to {task}.{port} "
                                f"({info.type_name}): types differ [{CONNECT_TYPE}]")

    def disconnect_ports(self, source_task: str, source_port: str, sink_task: str, sink_port: str,
                         graceful: bool = True) -> bool:
        """Undo :meth:`connect_ports` (what waits is delivered first, unless not
        ``graceful``); False when they were not connected."""
        return self.disconnect_counted(source_task, source_port, sink_task, sink_port, graceful) is not None

    def disconnect_counted(self, source_task: str, source_port: str, sink_task: str, sink_port: str,
                           graceful: bool = True) -> int | None:
        """:meth:`disconnect_ports`, saying how many samples written were never delivered
        (None: they were not connected; an in-process pair: 0, nothing leaves)."""
        key = (source_task, source_port, sink_task, sink_port)
        with self._lock:
            link = self._links.pop(key, None)
        if link is not None:
            lost = link.close(graceful)
            self.deployer.forget_link(f"{source_task}.{source_port}", f"{sink_task}.{sink_port}")
            return lost
        if source_task in self.deployer.names() and sink_task in self.deployer.names():
            return 0 if self.deployer.disconnect(f"{source_task}.{source_port}", f"{sink_task}.{sink_port}") else None
        return None

    def disconnect_link(self, name: str) -> bool:
        """Undo the link or stream called ``name``; raises ``NotFoundError`` listing names."""
        return self.disconnect_link_counted(name) is not None

    def disconnect_link_counted(self, name: str) -> int | None:
        """:meth:`disconnect_link`, saying how many samples were never delivered (see
        :meth:`disconnect_counted`; a stream: 0)."""
        if name in self.deployer.streams():
            return 0 if self.unstream(name) else None
        link = self.find_link(name)
        (st, sp), (kt, kp) = link.source.rsplit(".", 1), link.sink.rsplit(".", 1)
        return self.disconnect_counted(st, sp, kt, kp)

    def links(self) -> list[LinkDescription]:
        """The links whose source is one of these tasks (in-process ones, then those to
        other deployers), then the streams of these tasks, then the links into these
        tasks whose source's deployer is gone (``waiting``, until it is back)."""
        with self._lock:
            remote = [link.describe() for link in self._links.values()]
        return self.deployer.links(remote) + self._keeper.waiting()

    def find_link(self, name: str) -> LinkDescription:
        """The link called ``name``; raises ``NotFoundError`` listing some names."""
        if len(name) > 300:
            raise NotFoundError(f"no link of a {len(name)}-character name (names have at most 128)")
        links = self.links()
        found = next((lk for lk in links if lk.name == name), None)
        if found is None:
            raise NotFoundError(f"no link {name!r} in the deployer at {self.address}; links: "
                                f"{', '.join(lk.name for lk in links[:20]) or 'none'}")
        return found

    def reroute(self, name: str, sink_task: str, sink_port: str) -> LinkDescription:
        """Point the link ``name`` at ``sink_task.sink_port`` (same source, policy and name):
        connected first, then the old sink disconnected. Raises ``NotFoundError``,
        ``PortTypeError``, ``DeploymentError`` (the source feeds that sink already, or the
        new sink is not an input)."""
        with self._reroute_lock:
            link = self.find_link(name)
            if link.kind != "link":
                raise DeploymentError(f"{name} is a stream; streams are not rerouted (unstream it, stream again)")
            new_sink = f"{sink_task}.{sink_port}"
            if new_sink == link.sink:
                return link
            if any(lk.source == link.source and lk.sink == new_sink for lk in self.links()):
                raise DeploymentError(f"{link.source} feeds {new_sink} already: disconnect that link first")
            (st, sp), (ot, op) = link.source.rsplit(".", 1), link.sink.rsplit(".", 1)
            policy = self._policy_of(link)
            given = name if name != f"{link.source}->{link.sink}" else None
            self.deployer.forget_link(link.source, link.sink)
            try:
                self.connect_ports(st, sp, sink_task, sink_port, policy, name=given)
            except BaseException:
                if given is not None:
                    self.deployer.name_link(link.source, link.sink, given)
                raise
            self.disconnect_ports(st, sp, ot, op)
            return self.find_link(given or f"{link.source}->{new_sink}")

    def _policy_of(self, link: LinkDescription) -> ConnPolicy:
        """The policy object a link was made with (every field, not only its short form)."""
        (st, sp), (kt, kp) = link.source.rsplit(".", 1), link.sink.rsplit(".", 1)
        with self._lock:
            remote = self._links.get((st, sp, kt, kp))
        if remote is not None:
            return remote.policy
        conn = self.deployer.connection(link.source, link.sink)
        return conn.policy if conn is not None else ConnPolicy.parse(link.policy)

    # ---- streams -----------------------------------------------------------------------
    def stream(self, task: str, port: str, policy: ConnPolicy, options: dict[str, str] | None = None,
               name: str | None = None) -> LinkDescription:
        """:meth:`dataflow.Deployer.stream` of the port ``task.port`` (the server undoes
        the streams it made when it stops)."""
        return self.deployer.stream(f"{task}.{port}", policy, options, name)

    def unstream(self, name: str) -> bool:
        """:meth:`dataflow.Deployer.unstream`."""
        return self.deployer.unstream(name)

    # ---- lifecycle ---------------------------------------------------------------------
    def stop(self, grace: float = 0.2) -> None:
        """Stop serving: end streams and links, unregister, stop gRPC, wait (idempotent)."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
            links = list(self._links.values())
            self._links.clear()
        streams = [self.deployer.remove_stream(n) for n, s in self.deployer.streams().items() if isinstance(s, PortStream)]
        deadline = time.monotonic() + CLOSE_S  # one deadline for them all
        for link in links:
            link.stop(deadline)  # what waits is delivered; the sink keeps it, and makes it again once back
        for stream in streams:
            stream.close()
        self._keeper.stop()
        if self._registration is not None:
            self._registration.stop()
        if self._ns_client is not None:
            self._ns_client.close()
        self._servicer.stop()
        rpc.stop_server(self._server, self._executor, grace)

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the server terminates or ``timeout`` s pass; True if terminated."""
        return self._server.wait_for_termination(timeout)

    def __enter__(self) -> DeployerServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _changes(old: ConnPolicy, new: ConnPolicy, old_name: str, new_name: str) -> str:
    """What connecting a linked pair again changed: its policy, its transport, its name."""
    notes = []
    if not same_policy(old, new):
        notes.append(f"policy changed from {old} to {new}")
    if old.transport != new.transport:
        notes.append(f"transport changed from {old.transport} to {new.transport}")
    if old_name != new_name:
        notes.append(f"renamed from {old_name} to {new_name}")
    return "; ".join(notes) or "connected again"


def _waits(name: str) -> bool:
    """Transport ``name`` holds a waiting writer back on a link (loaded; False if it cannot be)."""
    try:
        return load(name).waits
    except Exception:  # noqa: BLE001 - a transport that cannot be loaded carries nothing
        return False
