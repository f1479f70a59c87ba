"""The name service: component name → deployer address, with leases.

A deployer registers its components under a lease and renews it by heartbeats
(:class:`Registration` does this on its own thread); a deployer that stops heartbeating
loses its names when the lease runs out, so entries never go stale. A name already held
by another *live* deployer is refused (``ALREADY_EXISTS``); a holder that is gone (same
address now served by the newcomer, or its health service does not answer) is replaced,
so a restarted deployer takes its names back at once.

The service is either embedded in a deployer's gRPC server (the default: one deployer
needs no extra process) or standalone (:func:`serve_nameserver`, ``scart nameserver``).
Expiry is evaluated lazily on every access, so the registry owns no thread.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from typing import Any
from collections.abc import Callable
from dataclasses import dataclass, field

import grpc

from dataflow.errors import DataflowError, NotFoundError
from dataflow.remote import _rpc, errors
from dataflow.remote.defaults import DEFAULT_LEASE, DEFAULT_NS_ADDRESS, DEFAULT_NS_PORT
from dataflow.remote._proto import NAMING_ROLES, NAMING_SERVICE_NAME, ns_grpc
from dataflow.remote._proto import ns as pb
from dataflow.remote.security import Security

__all__ = [
    "DEFAULT_NS_PORT",
    "DEFAULT_NS_ADDRESS",
    "DEFAULT_LEASE",
    "NameEntry",
    "NameRegistry",
    "NameServer",
    "NameClient",
    "Registration",
    "serve_nameserver",
]

log = logging.getLogger(__name__)



@dataclass(frozen=True)
class NameEntry:
    """One registered component: where it is served, by which deployer, lease left (s)."""

    component: str
    address: str
    deployer_id: str
    expires_in: float


@dataclass
class _Lease:
    deployer_id: str
    address: str
    components: set[str]
    seconds: float
    expires: float
    permanent: bool = False
    lease_id: str = field(default_factory=lambda: uuid.uuid4().hex)
    refused: list[str] = field(default_factory=list)


class NameRegistry:
    """The name table (thread-safe; every method is short and non-blocking, except that
    a conflicting :meth:`register` may probe the current holder with ``probe``).

    ``clock`` is injectable for tests; ``probe(address) -> bool`` says whether a
    deployer still answers (default: its gRPC health service, 0.5 s deadline).
    """

    def __init__(
        self,
        default_lease: float = DEFAULT_LEASE,
        max_lease: float = 600.0,
        clock: Callable[[], float] = time.monotonic,
        probe: Callable[[str], bool] | None = None,
    ) -> None:
        self._default = default_lease
        self._max = max_lease
        self._clock = clock
        self._probe = probe if probe is not None else _rpc.health_ok
        self._leases: dict[str, _Lease] = {}
        self._lock = threading.Lock()

    def _purge(self) -> None:
        now = self._clock()
        for lease_id in [k for k, v in self._leases.items() if not v.permanent and v.expires <= now]:
            lease = self._leases.pop(lease_id)
            log.info("lease of %s (%s) expired", lease.address, sorted(lease.components))

    def _holder(self, component: str) -> _Lease | None:
        for lease in self._leases.values():
            if component in lease.components:
                return lease
        return None

    def register(
        self,
        deployer_id: str,
        address: str,
        components: list[str],
        lease_seconds: float = 0.0,
        permanent: bool = False,
    ) -> tuple[str, float]:
        """Register ``components`` served at ``address``; returns ``(lease_id, lease_seconds)``.

        Idempotent per ``deployer_id`` (a re-registration replaces the previous lease).
        Raises :class:`errors.AlreadyRegisteredError` naming the component and its live holder.
        """
        seconds = min(lease_seconds or self._default, self._max)
        with self._lock:
            self._purge()
            conflicts = {
                h.lease_id: h
                for c in components
                if (h := self._holder(c)) is not None and h.deployer_id != deployer_id
            }
        dead = {lid for lid, h in conflicts.items() if h.address == address or not self._probe(h.address)}
        with self._lock:
            for lid, holder in conflicts.items():
                if lid not in dead and lid in self._leases:
                    taken = sorted(holder.components & set(components))
                    raise errors.AlreadyRegisteredError(
                        f"component name(s) {', '.join(taken)} already registered by the deployer at "
                        f"{holder.address}; choose another name or stop that deployer",
                        "ALREADY_EXISTS",
                        address,
                    )
            for lid in dead:
                self._leases.pop(lid, None)
            for lid in [k for k, v in self._leases.items() if v.deployer_id == deployer_id]:
                del self._leases[lid]
            lease = _Lease(deployer_id, address, set(components), seconds, self._clock() + seconds, permanent)
            self._leases[lease.lease_id] = lease
        log.info("registered %s at %s", sorted(components), address)
        return lease.lease_id, seconds

    def heartbeat(self, lease_id: str, components: list[str] | None = None) -> float:
        """Renew a lease (and update its names); returns its length. Raises ``NotFoundError`` if expired."""
        with self._lock:
            self._purge()
            lease = self._leases.get(lease_id)
            if lease is None:
                raise NotFoundError(f"lease {lease_id} is unknown or expired; register again")
            if components is not None:
                free = {c for c in components if (h := self._holder(c)) is None or h is lease}
                refused = sorted(set(components) - free)
                if refused and refused != lease.refused:
                    holders = {c: h.address for c in refused if (h := self._holder(c)) is not None}
                    log.warning(
                        "deployer at %s: name(s) %s refused, held by %s",
                        lease.address, ", ".join(refused),
                        ", ".join(f"{c} @ {a}" for c, a in sorted(holders.items())),
                    )
                lease.refused = refused
                lease.components = free
            lease.expires = self._clock() + lease.seconds
            return lease.seconds

    def unregister(self, lease_id: str) -> None:
        """Drop a lease and its names (idempotent)."""
        with self._lock:
            self._leases.pop(lease_id, None)

    def resolve(self, component: str) -> NameEntry:
        """Where ``component`` is served; raises ``NotFoundError`` listing the known names."""
        with self._lock:
            self._purge()
            lease = self._holder(component)
            if lease is None:
                known = sorted(c for v in self._leases.values() for c in v.components)
                raise NotFoundError(
                    f"no component named {component!r} is registered; known: {', '.join(known) or '(none)'}"
                )
            return self._entry(component, lease)

    def entries(self) -> list[NameEntry]:
        """Every live registration, sorted by component name."""
        with self._lock:
            self._purge()
            return sorted(
                (self._entry(c, v) for v in self._leases.values() for c in v.components),
                key=lambda e: e.component,
            )

    def _entry(self, component: str, lease: _Lease) -> NameEntry:
        left = float("inf") if lease.permanent else max(0.0, lease.expires - self._clock())
        return NameEntry(component, lease.address, lease.deployer_id, left)


def _entry_msg(entry: NameEntry) -> Any:
    left = entry.expires_in if entry.expires_in != float("inf") else -1.0
    return pb.Entry(component=entry.component, address=entry.address, deployer_id=entry.deployer_id, expires_in=left)


class NamingServicer(ns_grpc.NamingServiceServicer):
    """gRPC face of a :class:`NameRegistry` (methods named as in naming.proto)."""

    def __init__(self, registry: NameRegistry) -> None:
        self.registry = registry

    def Register(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802 - gRPC method names
        try:
            lease_id, seconds = self.registry.register(
                request.deployer_id, request.address, list(request.components), request.lease_seconds
            )
        except errors.AlreadyRegisteredError as exc:
            context.abort(grpc.StatusCode.ALREADY_EXISTS, str(exc))
        return pb.RegisterResponse(lease_id=lease_id, lease_seconds=seconds)

    def Heartbeat(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802
        try:
            seconds = self.registry.heartbeat(request.lease_id, list(request.components) or None)
        except NotFoundError as exc:
            context.abort(grpc.StatusCode.NOT_FOUND, str(exc))
        return pb.HeartbeatResponse(lease_seconds=seconds)

    def Unregister(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802
        self.registry.unregister(request.lease_id)
        return pb.UnregisterResponse()

    def Resolve(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802
        try:
            entry = self.registry.resolve(request.component)
        except NotFoundError as exc:
            context.abort(grpc.StatusCode.NOT_FOUND, str(exc))
        return pb.ResolveResponse(entry=_entry_msg(entry))

    def ListEntries(self, request: Any, context: grpc.ServicerContext) -> Any:  # noqa: N802
        return pb.ListEntriesResponse(entries=[_entry_msg(e) for e in self.registry.entries()])


class NameServer:
    """A running standalone name service. ``address`` is where it listens."""

    def __init__(self, server: grpc.Server, address: str, registry: NameRegistry, executor: Any = None,
                 listen_address: str | None = None) -> None:
        self._server = server
        self._executor = executor
        self.address = address
        #: What the server listens on (``0.0.0.0:P`` when bound to every interface).
        self.listen_address = listen_address or address
        self.registry = registry

    def stop(self, grace: float = 0.2) -> None:
        """Stop serving, end the worker threads (blocks ≤ ``grace`` + 10 s). Idempotent."""
        if self._executor is None:
            self._server.stop(grace).wait(grace + 5.0)
        else:
            _rpc.stop_server(self._server, self._executor, grace)

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the server terminates or ``timeout`` s pass; True if terminated."""
        return self._server.wait_for_termination(timeout)

    def __enter__(self) -> NameServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def serve_nameserver(
    address: str = "127.0.0.1:0", default_lease: float = DEFAULT_LEASE, max_workers: int = 16,
    security: Security | None = None,
) -> NameServer:
    """Start a standalone name service (health + reflection included); returns at once.

    ``security``: TLS and the auth file (see :mod:`dataflow.remote.security`; lookups need
    ``read``, registrations ``admin``). Raises :class:`errors.UnavailableError` when
    ``address`` cannot be bound, :class:`~dataflow.remote.security.SecurityError` for an
    unsafe bind or unusable security files.
    """
    security = security or Security()
    registry = NameRegistry(default_lease=default_lease, probe=lambda a: _rpc.health_ok(a, security=security))
    servicer = (ns_grpc.add_NamingServiceServicer_to_server, NamingServicer(registry))
    server, port, _health, executor = _rpc.make_server(address, [servicer], [NAMING_SERVICE_NAME], max_workers,
                                                       security=security, roles=NAMING_ROLES)
    return NameServer(server, _rpc.bound_address(address, port), registry, executor,
                      f"{address.rpartition(':')[0] or '127.0.0.1'}:{port}")


class NameClient:
    """Client of a name service at ``address``; every call has a ``timeout`` deadline.

    Thread-safe. Raises :class:`errors.UnavailableError` (nothing answers),
    :class:`errors.RemoteTimeoutError`, :class:`errors.RemoteNotFoundError`,
    :class:`errors.AlreadyRegisteredError`. :meth:`close` is idempotent.
    """

    def __init__(self, address: str, timeout: float = 2.0, security: Security | None = None) -> None:
        self.address = address
        self.timeout = timeout
        self._channel = (security or Security()).channel(address, _rpc.channel_options())
        self._stub = ns_grpc.NamingServiceStub(self._channel)

    def _call(self, name: str, request: Any, timeout: float | None) -> Any:
        return _rpc.call(getattr(self._stub, name), request, timeout or self.timeout, self.address)

    def resolve(self, component: str, timeout: float | None = None) -> NameEntry:
        """Where ``component`` is served."""
        reply = self._call("Resolve", pb.ResolveRequest(component=component), timeout)
        return _entry_from_msg(reply.entry)

    def entries(self, timeout: float | None = None) -> list[NameEntry]:
        """Every live registration."""
        reply = self._call("ListEntries", pb.ListEntriesRequest(), timeout)
        return [_entry_from_msg(e) for e in reply.entries]

    def register(
        self, deployer_id: str, address: str, components: list[str], lease_seconds: float = 0.0
    ) -> tuple[str, float]:
        """Register; returns ``(lease_id, lease_seconds)``."""
        req = pb.RegisterRequest(
            deployer_id=deployer_id, address=address, components=components, lease_seconds=lease_seconds
        )
        reply = self._call("Register", req, None)
        return reply.lease_id, reply.lease_seconds

    def heartbeat(self, lease_id: str, components: list[str] | None = None) -> float:
        """Renew a lease; raises :class:`errors.RemoteNotFoundError` when it expired."""
        reply = self._call("Heartbeat", pb.HeartbeatRequest(lease_id=lease_id, components=components or []), None)
        return reply.lease_seconds

    def unregister(self, lease_id: str, timeout: float | None = None) -> None:
        """Drop a lease (idempotent)."""
        self._call("Unregister", pb.UnregisterRequest(lease_id=lease_id), timeout)

    def close(self) -> None:
        """Close the channel (idempotent)."""
        self._channel.close()


def name_service_answers(address: str, timeout: float = 0.5, security: Security | None = None) -> bool:
    """True when a name service answers at ``address`` within ``timeout`` s.

    Used by ``scart run``/``scart deploy`` to decide between joining a running name service
    and embedding one at that address. Blocks at most ``timeout``; never raises for an
    unreachable address.
    """
    probe = NameClient(address, timeout=timeout, security=security)
    try:
        probe.entries()
        return True
    except (errors.AuthenticationError, errors.PermissionDeniedError):
        return True  # one answers, and wants credentials
    except DataflowError:
        return False
    finally:
        probe.close()


def _entry_from_msg(msg: Any) -> NameEntry:
    left = float("inf") if msg.expires_in < 0 else msg.expires_in
    return NameEntry(msg.component, msg.address, msg.deployer_id, left)


def held_elsewhere(resolve: Callable[[str], NameEntry], names: list[str], deployer_id: str) -> dict[str, str]:
    """``{name: address}`` of ``names`` registered by a deployer other than ``deployer_id``
    (``resolve`` is a registry's or a name client's; unknown names are skipped)."""
    held: dict[str, str] = {}
    for name in names:
        try:
            entry = resolve(name)
        except NotFoundError:  # errors.RemoteNotFoundError too
            continue
        if entry.deployer_id != deployer_id:
            held[name] = entry.address
    return held


class Registration:
    """Keeps one deployer's components registered with a remote name service.

    :meth:`start` registers synchronously (so a duplicate name or a missing name service
    fails at once, raising), then heartbeats every ``lease/3`` s on its own thread,
    registering again whenever the lease was lost (name service restarted, deployer was
    frozen). :meth:`stop` ends the thread (joins it) and unregisters; idempotent.
    """

    def __init__(
        self,
        ns_address: str,
        address: str,
        components: Callable[[], list[str]],
        lease_seconds: float = DEFAULT_LEASE,
        deployer_id: str | None = None,
        timeout: float = 2.0,
        security: Security | None = None,
    ) -> None:
        self.ns_address = ns_address
        self.address = address
        self.deployer_id = deployer_id or uuid.uuid4().hex
        self._components = components
        self._lease_seconds = lease_seconds
        self._client = NameClient(ns_address, timeout=timeout, security=security)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.lease_id = ""
        self.registrations = 0
        #: This deployer's names the name service refused (held by another deployer).
        self.refused: list[str] = []
        self._checked: list[str] = []

    def start(self) -> None:
        """Register now (raises on failure) and start heartbeating."""
        self._register()
        self._thread = threading.Thread(target=self._run, name=f"scart-ns-heartbeat-{self.address}", daemon=True)
        self._thread.start()

    def _register(self) -> None:
        names = sorted(self._components())
        refused: list[str] = []
        try:
            self.lease_id, self._lease_seconds = self._client.register(
                self.deployer_id, self.address, names, self._lease_seconds
            )
        except errors.AlreadyRegisteredError:
            if not self.registrations:
                raise  # at start: a duplicate name fails the deployer loudly
            # registering again (lease lost): keep the free names, report the others
            held = held_elsewhere(self._client.resolve, names, self.deployer_id)
            refused = sorted(held)
            self._warn_refused(held)
            self.lease_id, self._lease_seconds = self._client.register(
                self.deployer_id, self.address, [n for n in names if n not in held], self._lease_seconds
            )
        self.registrations += 1
        self.refused, self._checked = refused, names

    def _warn_refused(self, held: dict[str, str]) -> None:
        if held and sorted(held) != self.refused:
            log.warning(
                "name service %s refused %s of the deployer at %s: held by %s; rename them",
                self.ns_address, ", ".join(sorted(held)), self.address,
                ", ".join(f"{n} @ {a}" for n, a in sorted(held.items())),
            )

    def _heartbeat(self) -> None:
        """Renew the lease; when the names changed, check which ones the service took and
        warn about (and record in :attr:`refused`) those held by another deployer."""
        names = sorted(self._components())
        self._client.heartbeat(self.lease_id, names)
        if names == self._checked:
            return
        held = held_elsewhere(self._client.resolve, names, self.deployer_id)
        self._warn_refused(held)
        self.refused, self._checked = sorted(held), names

    def _run(self) -> None:
        while not self._stop.wait(self._lease_seconds / 3.0):
            try:
                if self.lease_id:
                    self._heartbeat()
                else:
                    self._register()
            except errors.RemoteNotFoundError:
                self.lease_id = ""
                self._try_register()
            except errors.RemoteError as exc:
                log.warning("name service %s: %s", self.ns_address, exc)

    def _try_register(self) -> None:
        try:
            self._register()
        except errors.RemoteError as exc:
            log.warning("re-registering with %s failed: %s", self.ns_address, exc)

    def stop(self) -> None:
        """Stop heartbeating, join the thread, unregister (best effort, short deadline)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self.lease_id:
            try:
                self._client.unregister(self.lease_id, timeout=0.5)
            except errors.RemoteError:
                pass
            self.lease_id = ""
        self._client.close()
