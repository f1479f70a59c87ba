"""The name service: component name → deployer address, with leases.

A deployer registers its components under a lease and renews it by heartbeats
(:class:`Registration` does this on its own thread); a deployer that stops heartbeating
loses its names when the lease runs out, so entries never go stale. The lease id is a
secret only its holder knows: nobody else can renew, change or drop its names. A name
already held by another *live* deployer is refused (``ALREADY_EXISTS``); a holder that
is gone (its process, known by its public boot id, no longer answers at its address) is
replaced, so a restarted deployer takes its names back at once. The table and its
bounds are :class:`~dataflow.remote._registry.NameRegistry` and ``Limits``.

The service is either embedded in a deployer's gRPC server (the default: one deployer
needs no extra process) or standalone (:func:`serve_nameserver`, ``scart nameserver``).
Registering needs the ``admin`` role where tokens are checked; lookups ``read``.
"""

from __future__ import annotations

import dataclasses

import logging
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Protocol
from collections.abc import Callable

import grpc

from dataflow.errors import DataflowError, NotFoundError
from dataflow.remote import errors
from scart_wire import rpc
from scart_wire.defaults import DEFAULT_LEASE, DEFAULT_NS_ADDRESS, DEFAULT_NS_PORT
from dataflow.remote._proto import NAMING_ROLES, NAMING_SERVICE_NAME, ns_grpc
from dataflow.remote._registry import Limits, NameEntry, NameRegistry, RegistryFullError, boot_service
from dataflow.remote._proto import ns as pb
from scart_wire.security import Security
from google.protobuf.message import Message
from dataflow.threads import OwnedThread

__all__ = [
    "DEFAULT_NS_PORT",
    "DEFAULT_NS_ADDRESS",
    "DEFAULT_LEASE",
    "Limits",
    "NameEntry",
    "NameRegistry",
    "NameServer",
    "NameClient",
    "Lookups",
    "Registration",
    "SCA_PREFIX",
    "serve_nameserver",
]

log = logging.getLogger(__name__)

#: Names of SCA services endpoints (``sca:HOST:PORT``, registered by ``scart run``): listed
#: apart from the data-flow components (:meth:`NameClient.entries`).
SCA_PREFIX = "sca:"


class Lookups(Protocol):
    """Where remote tasks are looked up: a :class:`NameClient`, or Zenoh liveliness
    (``dataflow.transports.zenoh.ZenohNames``)."""

    def resolve(self, component: str, timeout: float | None = None) -> NameEntry: ...
    def entries(self, timeout: float | None = None) -> list[NameEntry]: ...
    def close(self) -> None: ...



def _entry_msg(entry: NameEntry) -> pb.Entry:
    left = entry.expires_in if entry.expires_in != float("inf") else -1.0
    return pb.Entry(component=entry.component, address=entry.address, boot_id=entry.boot_id, expires_in=left)


class NamingServicer(ns_grpc.NamingServiceServicer):
    """gRPC face of a :class:`NameRegistry` (methods named as in naming.proto)."""

    def __init__(self, registry: NameRegistry) -> None:
        self.registry = registry

    def Register(self, request: pb.RegisterRequest, context: grpc.ServicerContext) -> pb.RegisterResponse:  # noqa: N802 - gRPC method names
        try:
            lease_id, seconds = self.registry.register(
                request.address, list(request.components), request.lease_seconds, boot_id=request.boot_id,
                lease_id=request.lease_id, peer=rpc.peer_key(context))
        except errors.AlreadyRegisteredError as exc:
            context.abort(grpc.StatusCode.ALREADY_EXISTS, rpc.bounded(str(exc)))
        except RegistryFullError as exc:
            context.abort(grpc.StatusCode.RESOURCE_EXHAUSTED, rpc.bounded(str(exc)))
        except NotFoundError as exc:
            context.abort(grpc.StatusCode.NOT_FOUND, rpc.bounded(str(exc)))
        except ValueError as exc:
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, rpc.bounded(str(exc)))
        return pb.RegisterResponse(lease_id=lease_id, lease_seconds=seconds)

    def Heartbeat(self, request: pb.HeartbeatRequest, context: grpc.ServicerContext) -> pb.HeartbeatResponse:  # noqa: N802
        try:
            seconds = self.registry.heartbeat(request.lease_id, list(request.components) or None)
        except NotFoundError as exc:
            context.abort(grpc.StatusCode.NOT_FOUND, rpc.bounded(str(exc)))
        except RegistryFullError as exc:
            context.abort(grpc.StatusCode.RESOURCE_EXHAUSTED, rpc.bounded(str(exc)))
        except ValueError as exc:
            context.abort(grpc.StatusCode.INVALID_ARGUMENT, rpc.bounded(str(exc)))
        return pb.HeartbeatResponse(lease_seconds=seconds)

    def Unregister(self, request: pb.UnregisterRequest, context: grpc.ServicerContext) -> pb.UnregisterResponse:  # noqa: N802
        self.registry.unregister(request.lease_id)
        return pb.UnregisterResponse()

    def Resolve(self, request: pb.ResolveRequest, context: grpc.ServicerContext) -> pb.ResolveResponse:  # noqa: N802
        try:
            entry = self.registry.resolve(request.component)
        except NotFoundError as exc:
            context.abort(grpc.StatusCode.NOT_FOUND, rpc.bounded(str(exc)))
        return pb.ResolveResponse(entry=_entry_msg(entry))

    def ListEntries(self, request: pb.ListEntriesRequest, context: grpc.ServicerContext) -> pb.ListEntriesResponse:  # noqa: N802
        page = self.registry.entries(after=request.page_token, limit=request.page_size or None)
        size = min(request.page_size or self.registry.limits.page, self.registry.limits.page)
        more = len(page) == size and bool(self.registry.entries(after=page[-1].component, limit=1))
        return pb.ListEntriesResponse(entries=[_entry_msg(e) for e in page],
                                      next_page_token=page[-1].component if more else "")


class NameServer:
    """A running standalone name service. ``address`` is where it listens."""

    def __init__(self, server: grpc.Server, address: str, registry: NameRegistry, executor: ThreadPoolExecutor | None = None,
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
            rpc.stop_server(self._server, self._executor, grace)

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

    ``security``: TLS and the auth file (see :mod:`scart_wire.security`; lookups need
    ``read``, registrations ``admin``). Raises :class:`errors.UnavailableError` when
    ``address`` cannot be bound, :class:`~scart_wire.security.SecurityError` for an
    unsafe bind or unusable security files.
    """
    security = security or Security()
    registry = NameRegistry(default_lease=default_lease, probe=security_probe(security))
    servicer = (ns_grpc.add_NamingServiceServicer_to_server, NamingServicer(registry))
    server, port, _health, executor = rpc.make_server(address, [servicer], [NAMING_SERVICE_NAME], max_workers,
                                                       security=security, roles=NAMING_ROLES)
    return NameServer(server, rpc.bound_address(address, port), registry, executor,
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
        self._channel = (security or Security()).channel(address, rpc.channel_options())
        self._stub = ns_grpc.NamingServiceStub(self._channel)

    def _call(self, name: str, request: Message, timeout: float | None) -> Any:  # Any: the reply of method ``name``
        return rpc.call(getattr(self._stub, name), request, timeout or self.timeout, self.address)

    def resolve(self, component: str, timeout: float | None = None) -> NameEntry:
        """Where ``component`` is served."""
        reply = self._call("Resolve", pb.ResolveRequest(component=component), timeout)
        return _entry_from_msg(reply.entry)

    def entries(self, timeout: float | None = None, max_pages: int = 1_000, sca: bool = False) -> list[NameEntry]:
        """Every live registration of a data-flow component (or with ``sca``, of an SCA
        services endpoint: the names starting with :data:`SCA_PREFIX`), page after page (at
        most ``max_pages``, each with the call's deadline)."""
        return [e for e in self._entries(timeout, max_pages) if e.component.startswith(SCA_PREFIX) == sca]

    def _entries(self, timeout: float | None, max_pages: int) -> list[NameEntry]:
        out: list[NameEntry] = []
        token = ""
        for _ in range(max_pages):
            reply = self._call("ListEntries", pb.ListEntriesRequest(page_token=token), timeout)
            out.extend(_entry_from_msg(e) for e in reply.entries)
            token = reply.next_page_token
            if not token:
                break
        return out

    def register(self, address: str, components: list[str], lease_seconds: float = 0.0, *,
                 boot_id: str = "", lease_id: str = "") -> tuple[str, float]:
        """Register (a new lease, or change the one named by ``lease_id``); returns
        ``(lease_id, lease_seconds)``."""
        req = pb.RegisterRequest(address=address, components=components, lease_seconds=lease_seconds,
                                 boot_id=boot_id, lease_id=lease_id)
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


def _entry_from_msg(msg: pb.Entry) -> NameEntry:
    left = float("inf") if msg.expires_in < 0 else msg.expires_in
    return NameEntry(msg.component, msg.address, msg.boot_id, left)


def security_probe(security: Security) -> Callable[[str, str], bool | None]:
    """A registry probe: is the deployer process ``boot_id`` alive at ``address``? (Its gRPC
    health answers SERVING for ``scart.boot.<boot_id>``.) Health needs no token, and the
    address is the registrant's choice: the probe never sends one (TLS settings only)."""
    tokenless = dataclasses.replace(security, token=None)

    def probe(address: str, boot_id: str) -> bool | None:
        return rpc.health_state(address, security=tokenless, service=boot_service(boot_id) if boot_id else "")
    return probe


def held_elsewhere(resolve: Callable[[str], NameEntry], names: list[str], boot_id: str) -> dict[str, str]:
    """``{name: address}`` of ``names`` registered by a deployer process other than
    ``boot_id`` (``resolve`` is a registry's or a name client's; unknown names are skipped)."""
    held: dict[str, str] = {}
    for name in names:
        try:
            entry = resolve(name)
        except NotFoundError:  # errors.RemoteNotFoundError too
            continue
        if entry.boot_id != boot_id:
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
        boot_id: str = "",
        timeout: float = 2.0,
        security: Security | None = None,
    ) -> None:
        self.ns_address = ns_address
        self.address = address
        self.boot_id = boot_id
        self._components = components
        self._lease_seconds = lease_seconds
        self._client = NameClient(ns_address, timeout=timeout, security=security)
        self._thread = OwnedThread(self._run, f"scart-ns-heartbeat-{self.address}")
        self.lease_id = ""
        self.registrations = 0
        #: This deployer's names the name service refused (held by another deployer).
        self.refused: list[str] = []
        self._checked: list[str] = []

    def start(self) -> None:
        """Register now (raises on failure) and start heartbeating."""
        self._register()
        self._thread.start()

    def _register(self) -> None:
        names = sorted(self._components())
        refused: list[str] = []
        try:
            self.lease_id, self._lease_seconds = self._client.register(
                self.address, names, self._lease_seconds, boot_id=self.boot_id)
        except errors.AlreadyRegisteredError:
            if not self.registrations:
                raise  # at start: a duplicate name fails the deployer loudly
            # registering again (lease lost): keep the free names, report the others
            held = held_elsewhere(self._client.resolve, names, self.boot_id)
            refused = sorted(held)
            self._warn_refused(held)
            self.lease_id, self._lease_seconds = self._client.register(
                self.address, [n for n in names if n not in held], self._lease_seconds, boot_id=self.boot_id)
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
        held = held_elsewhere(self._client.resolve, names, self.boot_id)
        self._warn_refused(held)
        self.refused, self._checked = sorted(held), names

    def _run(self, stopping: threading.Event) -> None:
        while not stopping.wait(self._lease_seconds / 3.0):
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
        self._thread.stop()
        if self.lease_id:
            try:
                self._client.unregister(self.lease_id, timeout=0.5)
            except errors.RemoteError:
                pass
            self.lease_id = ""
        self._client.close()
