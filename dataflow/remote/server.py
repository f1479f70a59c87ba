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

import logging
import secrets
import threading
import time
from collections.abc import Callable
from typing import Any

import grpc
from grpc_health.v1 import health_pb2

from dataflow import codec
from dataflow.deployer import Deployer
from dataflow.errors import DeploymentError, NotFoundError
from dataflow.introspection import LinkDescription
from dataflow.policy import ConnPolicy, FlowStatus
from dataflow.ports import InputPort
from dataflow.remote import _rpc, errors
from dataflow.remote._proto import (
    DEPLOYER_ROLES,
    DEPLOYER_SERVICE_NAME,
    NAMING_ROLES,
    NAMING_SERVICE_NAME,
    df_grpc,
    ns_grpc,
)
from dataflow.remote._proto import df as pb
from dataflow.remote._registry import BATCHES_SERVICE
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
from dataflow.remote.security import Security
from dataflow.remote.transport import TransportError, carry

__all__ = ["DeployerServer"]

log = logging.getLogger(__name__)

REASSERT_S = 1.0  #: how often an embedded deployer claims again the names another deployer held
SETTLE_S = 2.0  #: how long connecting a remote link waits for its first connection


class _RemoteLink:
    """An output port of this deployer feeding an input port in another deployer.

    A free InputPort with the connection's policy is connected to the output port: its
    storage is the link's, and it counts the policy's drops. A transport (see
    :mod:`dataflow.remote.transport`; ``auto``: ipc on one host, else gRPC) carries the
    samples to the sink's deployer: over ipc they are sent from the writer's thread as
    they are written; over gRPC the port's data callback wakes the transport's call.
    The link's thread re-resolves the sink through the name service and reconnects after
    failures until :meth:`close`. This is the :class:`~dataflow.remote.transport.LinkEnd`
    a transport sees.
    """

    def __init__(self, server: DeployerServer, out: Any, sink_task: str, sink_port: str, policy: ConnPolicy) -> None:
        self.server = server
        self.out = out
        self.sink_task = sink_task
        self.sink_port = sink_port
        self.policy = policy
        self.inp: InputPort = InputPort(out.type, name=f"link_{out.name}")
        self.closed = threading.Event()
        self._wake = threading.Event()
        # set by the transport while connected (see opened())
        self._cancel: Callable[[], None] | None = None
        self._pump: Callable[[], None] | None = None
        self._dropping: Callable[[], int] | None = None
        self._lost = 0  # by the transports of earlier connections
        self._channel: Any = None  # to the sink's deployer, while connected
        #: How samples go now: the transport's name (``ipc``, ``grpc``), or ``""`` while not connected.
        self.transport = ""
        self.settled = threading.Event()  # the first connection was made (or failed)
        self.inp.add_data_callback(self._on_data)
        out.connect_to(self.inp, policy)
        self._wake.set()
        self._thread = threading.Thread(target=self._run, name=f"scart-link-{out.name}->{sink_task}", daemon=True)
        self._thread.start()

    @property
    def timeout(self) -> float:
        """Deadline (s) of the control-plane calls a transport makes."""
        return self.server.ns_timeout

    @property
    def dropped(self) -> int:
        """Samples lost: by the connection's policy, or by the transports (a full or broken socket)."""
        conn = next((c for c in self.out.connections() if c.input is self.inp), None)
        dropping = self._dropping
        return (conn.dropped if conn else 0) + self._lost + (dropping() if dropping else 0)

    def _on_data(self, _inp: InputPort) -> None:  # the writer's thread
        pump = self._pump
        if pump is None:
            self._wake.set()  # gRPC (or connecting): the transport's call sends
        else:
            pump()

    # ---- the LinkEnd a transport sees ----------------------------------------------------
    def take(self) -> list[Any]:
        """The next samples waiting in the link's policy storage (at most 64)."""
        values = []
        for _ in range(64):
            status, value = self.inp.read()
            if status is not FlowStatus.NEW_DATA:
                break
            values.append(value)
        return values

    def messages(self, values: list[Any], batch_bytes: int = 0) -> list[bytes]:
        """``values`` as ``WritePortStreamRequest`` messages, serialized (see :meth:`requests`)."""
        return [request.SerializeToString() for request in self.requests(values, batch_bytes)]

    def requests(self, values: list[Any], batch_bytes: int = 0) -> list[Any]:
        """``values`` as ``WritePortStreamRequest`` messages: one each, or with
        ``batch_bytes`` as few as fit in that many bytes (a larger value goes alone)."""
        kind = self.out.type
        if not batch_bytes:
            return [pb.WritePortStreamRequest(value=codec.encode(value, kind)) for value in values]
        out: list[Any] = []
        batch: list[Any] = []
        size = 0
        for value in values:
            encoded = codec.encode(value, kind)
            n = encoded.ByteSize() + 8  # + the field's tag and length
            if batch and size + n > batch_bytes:
                out.append(pb.WritePortStreamRequest(values=batch))
                batch, size = [], 0
            batch.append(encoded)
            size += n
        if batch:
            out.append(pb.WritePortStreamRequest(values=batch))
        return out

    def reads_batches(self) -> bool:
        """Whether the sink's deployer reads several values per message (it says so in its
        health service, :data:`~dataflow.remote._registry.BATCHES_SERVICE`); False for an
        older one, or when it cannot tell within the control-plane deadline."""
        from grpc_health.v1 import health_pb2, health_pb2_grpc

        channel = self._channel
        if channel is None:
            return False
        try:
            reply = health_pb2_grpc.HealthStub(channel).Check(
                health_pb2.HealthCheckRequest(service=BATCHES_SERVICE), timeout=self.timeout)
        except grpc.RpcError:
            return False
        return reply.status == health_pb2.HealthCheckResponse.SERVING

    def wait_data(self, timeout: float) -> bool:
        """True once the port was written since the last call (or :meth:`wake`); False after ``timeout`` s."""
        if not self._wake.wait(timeout):
            return False
        self._wake.clear()
        return True

    def wake(self) -> None:
        """Make the next :meth:`wait_data` return at once."""
        self._wake.set()

    def opened(self, transport: str, cancel: Callable[[], None], *, pump: Callable[[], None] | None = None,
                  dropped: Callable[[], int] | None = None) -> bool:
        """The connection is up over ``transport`` (see :class:`~dataflow.remote.transport.LinkEnd`)."""
        self._cancel, self._dropping = cancel, dropped
        self.transport = transport
        self._pump = pump
        self.settled.set()
        if self.closed.is_set():  # close() may have looked before cancel was set
            cancel()
            return False
        return True

    def _ended(self) -> None:
        """The transport's connection is over: forget it, keep its count of losses."""
        self._pump = self._cancel = None
        dropping, self._dropping = self._dropping, None
        self._lost += dropping() if dropping else 0
        self.transport = ""
        self._wake.set()  # what the port's storage holds goes by the next connection

    def _run(self) -> None:
        backoff = 0.05
        failed = False
        while not self.closed.is_set():
            try:
                address = self.server.resolve(self.sink_task)
                with self.server.security.channel(address, _rpc.channel_options()) as channel:
                    self._channel = channel
                    stub = df_grpc.DeployerServiceStub(channel)
                    try:
                        carry(self.policy.transport, lambda t: t.link(self, address, stub), self._ended,
                              f"{self.sink_task}.{self.sink_port}", address)
                    finally:
                        self._channel = None
                backoff = 0.05
            except TransportError as exc:  # a plug-in that cannot be loaded: said once, then retried quietly
                if self.closed.is_set():
                    return
                if not failed:
                    log.error("link to %s.%s: %s", self.sink_task, self.sink_port, exc)
                failed = True
                backoff = 1.0
            except (grpc.RpcError, grpc.FutureCancelledError, errors.RemoteError, NotFoundError) as exc:
                if self.closed.is_set():
                    return
                log.info("link to %s.%s interrupted: %s", self.sink_task, self.sink_port, exc)
            except Exception:  # noqa: BLE001 - the link's thread must not die: log, back off, retry
                if self.closed.is_set():
                    return
                log.exception("link to %s.%s failed; retrying", self.sink_task, self.sink_port)
            self.settled.set()
            if self.closed.wait(backoff):
                return
            backoff = min(1.0, backoff * 2)

    def close(self) -> None:
        """Disconnect and end the link's thread (idempotent; joins ≤ 5 s)."""
        self.closed.set()
        self._wake.set()
        cancel = self._cancel
        if cancel is not None:
            cancel()  # the transport ends its connection at once, not at its next poll
        self.out.disconnect(self.inp)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)


class _EmbeddedNaming(NamingServicer):
    """The embedded name service: publishes tasks added to the deployer after it started
    serving before answering a lookup."""

    def __init__(self, owner: DeployerServer) -> None:
        super().__init__(owner.registry)
        self._owner = owner

    def Resolve(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802
        self._owner.refresh_names()
        return super().Resolve(request, context)

    def ListEntries(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802
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
            _rpc.parse_advertise(advertise)  # a malformed one raises before anything is bound
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
        servicers: list[_rpc.Servicer] = [(df_grpc.add_DeployerServiceServicer_to_server, self._servicer)]
        names = [DEPLOYER_SERVICE_NAME]
        roles = dict(DEPLOYER_ROLES)
        if self.registry is not None:
            servicers.append((ns_grpc.add_NamingServiceServicer_to_server, _EmbeddedNaming(self)))
            names.append(NAMING_SERVICE_NAME)
            roles.update(NAMING_ROLES)
        self._server, port, health, self._executor = _rpc.make_server(
            address, servicers, names, max_workers, security=security, roles=roles)
        health.set(boot_service(self.boot_id), health_pb2.HealthCheckResponse.SERVING)
        health.set(BATCHES_SERVICE, health_pb2.HealthCheckResponse.SERVING)
        self._health = health
        self.address = _rpc.bound_address(address, port)
        #: What the server listens on (``0.0.0.0:P`` when bound to every interface).
        self.listen_address = f"{address.rpartition(':')[0] or '127.0.0.1'}:{port}"
        #: Where other processes are told to reach it (name service, Zenoh): ``advertise``,
        #: or the bound address; this host's name for a wildcard listener.
        self.advertised = _rpc.advertised_address(self.listen_address, advertise)
        self.ns_address = ns or self.address
        self._links: dict[tuple[str, str, str, str], _RemoteLink] = {}
        self._lock = threading.Lock()
        self._reroute_lock = threading.Lock()  # one reroute at a time (check, connect, disconnect)
        self._stopped = False
        self._ns_client: NameClient | None = None
        self._registration: Registration | None = None
        self._published: list[str] = []
        self._refused: list[str] = []
        self._retry_at = 0.0
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

    # ---- connections -------------------------------------------------------------------
    def connect_ports(
        self,
        source_task: str,
        source_port: str,
        sink_task: str,
        sink_port: str,
        policy: ConnPolicy,
        defer: bool = False,
        name: str | None = None,
    ) -> tuple[bool, str]:
        """Connect a local output port to a local or remote input port, as the link ``name``
        (default ``"a.out->b.in"``); returns ``(local, sink address)``.

        Idempotent for the same pair. Raises ``NotFoundError`` (source not here, sink
        unknown — unless ``defer``: then the link waits for the sink to be registered, as
        when deployers start in any order), ``PortTypeError`` (types differ, local case;
        across deployers a type mismatch makes the sink refuse the samples, logged).
        """
        if source_task not in self.deployer.names():
            raise NotFoundError(
                f"source task {source_task!r} is not in the deployer at {self.address}; "
                f"it has: {', '.join(self.deployer.names()) or '(none)'} — send the request to the source's deployer"
            )
        out = self.deployer.task(source_task).port(source_port)
        if out.is_input:
            raise _rpc.Abort("INVALID_ARGUMENT", f"{source_task}.{source_port} is an input port; the source must be an output")
        source, sink = f"{source_task}.{source_port}", f"{sink_task}.{sink_port}"
        if sink_task in self.deployer.names():
            self.deployer.connect(source, sink, policy, name=name)
            return True, self.address
        if name is not None:
            self.deployer.check_link_name(source, sink, name)
        try:
            address = self.resolve(sink_task)
        except NotFoundError:
            if not defer:
                raise
            address = ""
        key = (source_task, source_port, sink_task, sink_port)
        with self._lock:
            link = self._links.get(key)
            if link is None:
                link = self._links[key] = _RemoteLink(self, out, sink_task, sink_port, policy)
        if name is not None:  # named once made
            self.deployer.name_link(source, sink, name)
        if address:  # the sink is known: return once its transport is chosen (``links`` then tells it)
            link.settled.wait(SETTLE_S)
        return False, address

    def disconnect_ports(self, source_task: str, source_port: str, sink_task: str, sink_port: str) -> bool:
        """Undo :meth:`connect_ports`; False when they were not connected."""
        key = (source_task, source_port, sink_task, sink_port)
        with self._lock:
            link = self._links.pop(key, None)
        if link is not None:
            link.close()
            self.deployer.forget_link(f"{source_task}.{source_port}", f"{sink_task}.{sink_port}")
            return True
        if source_task in self.deployer.names() and sink_task in self.deployer.names():
            return self.deployer.disconnect(f"{source_task}.{source_port}", f"{sink_task}.{sink_port}")
        return False

    def links(self) -> list[LinkDescription]:
        """The links whose source is one of these tasks: in-process ones, then those to
        other deployers (transport ``ipc`` or ``grpc``; ``auto?`` while not connected)."""
        with self._lock:
            remote = list(self._links.items())
        described = []
        for (st, sp, kt, kp), link in remote:
            source, sink = f"{st}.{sp}", f"{kt}.{kp}"
            described.append(LinkDescription(
                name=self.deployer.link_name(source, sink), source=source, sink=sink, policy=str(link.policy),
                transport=link.transport or f"{link.policy.transport}?", samples=link.out.last_sample()[0],
                dropped=link.dropped))
        return self.deployer.links(described)

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
        ``PortTypeError``, ``DeploymentError`` (the source feeds that sink already)."""
        with self._reroute_lock:
            link = self.find_link(name)
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

    # ---- lifecycle ---------------------------------------------------------------------
    def stop(self, grace: float = 0.2) -> None:
        """Stop serving: end streams and links, unregister, stop gRPC, wait (idempotent)."""
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
            links = list(self._links.values())
            self._links.clear()
        for link in links:
            link.close()
        if self._registration is not None:
            self._registration.stop()
        if self._ns_client is not None:
            self._ns_client.close()
        self._servicer.stop()
        _rpc.stop_server(self._server, self._executor, grace)

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the server terminates or ``timeout`` s pass; True if terminated."""
        return self._server.wait_for_termination(timeout)

    def __enter__(self) -> DeployerServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
