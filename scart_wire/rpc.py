"""gRPC plumbing shared by the server and the client (private; the only place that maps
gRPC statuses to scart errors). Servicers and stubs are the generated ones of
:mod:`scart_wire.proto`, so registered names always equal the proto's.
"""

from __future__ import annotations

import re
import socket
import threading
from collections.abc import Callable, Iterator, Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Generic, NoReturn, TypeAlias, TypeVar

import grpc

from scart_wire import errors
from scart_wire.security import CALLER, Role, Security, auth_interceptor, is_loopback, tls_mismatch

if TYPE_CHECKING:
    from concurrent.futures import ThreadPoolExecutor

    from grpc_health.v1.health import HealthServicer

R = TypeVar("R")
Req = TypeVar("Req")
Resp = TypeVar("Resp")

#: Name prefix of the servers' worker threads (``scart-rpc_0``, ...).
THREAD_PREFIX = "scart-rpc"

#: Largest message accepted or sent (4 MiB, gRPC's default receive limit, made explicit).
MAX_MESSAGE_BYTES = 4 * 1024 * 1024

#: Channel options: keepalive pings detect a frozen peer even on an idle connection.
def channel_options(keepalive_ms: int = 2000) -> list[tuple[str, int]]:
    """Options for client channels (message limits and HTTP/2 keepalive)."""
    return [
        ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
        ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
        ("grpc.keepalive_time_ms", keepalive_ms),
        ("grpc.keepalive_timeout_ms", keepalive_ms),
        ("grpc.keepalive_permit_without_calls", 1),
        ("grpc.http2.max_pings_without_data", 0),
        ("grpc.initial_reconnect_backoff_ms", 100),
        ("grpc.max_reconnect_backoff_ms", 1000),
        ("grpc.enable_retries", 0),
    ]


#: Calls beyond the stream budget are left this many workers (unary calls: health, lookups).
RESERVED_WORKERS = 8
#: A client stream whose first message does not come within this many seconds is cancelled.
FIRST_MESSAGE_S = 10.0
#: A connection without calls for this long is closed (clients reconnect on their next call).
MAX_CONNECTION_IDLE_MS = 5 * 60 * 1000
#: After this long a connection is asked to go (GOAWAY): new calls open a new one, calls in
#: flight finish (no grace limit, so long subscriptions are never cut).
MAX_CONNECTION_AGE_MS = 30 * 60 * 1000


def server_options() -> list[tuple[str, int]]:
    """Options for servers: message limits, connection idle and age bounds, and accept the
    clients' keepalive pings."""
    return [
        ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
        ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
        ("grpc.max_connection_idle_ms", MAX_CONNECTION_IDLE_MS),
        ("grpc.max_connection_age_ms", MAX_CONNECTION_AGE_MS),
        ("grpc.keepalive_permit_without_calls", 1),
        ("grpc.http2.min_ping_interval_without_data_ms", 500),
        ("grpc.http2.min_recv_ping_interval_without_data_ms", 500),
        ("grpc.http2.max_ping_strikes", 0),
        ("grpc.so_reuseport", 0),
    ]


_MAP: MappingProxyType[grpc.StatusCode, type[errors.RemoteError]] = MappingProxyType({
    grpc.StatusCode.NOT_FOUND: errors.RemoteNotFoundError,
    grpc.StatusCode.INVALID_ARGUMENT: errors.RemoteTypeError,
    grpc.StatusCode.OUT_OF_RANGE: errors.RemoteValueError,
    grpc.StatusCode.UNAVAILABLE: errors.UnavailableError,
    grpc.StatusCode.DEADLINE_EXCEEDED: errors.RemoteTimeoutError,
    grpc.StatusCode.ALREADY_EXISTS: errors.AlreadyRegisteredError,
    grpc.StatusCode.UNAUTHENTICATED: errors.AuthenticationError,
    grpc.StatusCode.PERMISSION_DENIED: errors.PermissionDeniedError,
})


def translate(exc: grpc.RpcError, address: str) -> errors.RemoteError:
    """The scart error for a failed call to ``address`` (keeps the server's message)."""
    code = exc.code() if hasattr(exc, "code") else grpc.StatusCode.UNKNOWN
    details = exc.details() if hasattr(exc, "details") else str(exc)
    cls = _MAP.get(code, errors.RemoteError)
    name = code.name if code is not None else "UNKNOWN"
    mismatch = tls_mismatch(address, details or "") if cls is errors.UnavailableError else None
    if mismatch is not None:
        cls, message = errors.TlsMismatchError, mismatch
    elif cls is errors.UnavailableError:
        message = f"nothing answers at {address} ({details})"
    elif cls is errors.RemoteTimeoutError:
        message = f"{address} did not answer in time ({details})"
    else:
        message = details or name
    return cls(message, code=name, address=address)


def call(fn: Callable[..., R], request: object, timeout: float, address: str) -> R:
    """Invoke a unary stub method with a deadline; raises the translated scart error."""
    try:
        return fn(request, timeout=timeout)
    except grpc.RpcError as exc:
        raise translate(exc, address) from None


class Abort(Exception):
    """Raised inside servicers: ``context.abort`` with this code name and message."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


#: ``bounded(text)``: a status's details carry at most this much of an error's text (a name
#: of megabytes sent by a client is not echoed whole: gRPC would drop the reply for its
#: metadata size).
bounded = errors.bounded


def abort(context: grpc.ServicerContext, exc: BaseException) -> NoReturn:
    """Abort the RPC with the status matching ``exc`` (never returns); its text bounded
    (:data:`scart_wire.errors.MAX_ECHO`)."""
    from scart_wire.errors import DeploymentError, NotFoundError, PortTypeError, PortValueError, PropertyValueError

    text = bounded(str(exc))
    if isinstance(exc, Abort):
        context.abort(grpc.StatusCode[exc.code], text)
    if isinstance(exc, NotFoundError):
        context.abort(grpc.StatusCode.NOT_FOUND, text)
    if isinstance(exc, (PropertyValueError, PortValueError)):
        context.abort(grpc.StatusCode.OUT_OF_RANGE, text)
    if isinstance(exc, (PortTypeError, TypeError, ValueError)):
        context.abort(grpc.StatusCode.INVALID_ARGUMENT, text)
    if isinstance(exc, DeploymentError):  # a refused deployment step (a link name taken, an input as source...)
        context.abort(grpc.StatusCode.FAILED_PRECONDITION, text)
    context.abort(grpc.StatusCode.INTERNAL, bounded(f"{type(exc).__name__}: {exc}"))


#: A servicer and the generated function that adds it to a server
#: (``dataflow_pb2_grpc.add_DeployerServiceServicer_to_server``, ...). Each function takes
#: its own servicer class, so a list of them can name the first parameter only as Any.
Servicer = tuple[Callable[[Any, grpc.Server], None], object]

#: The handler of one method of any service: each method has its own request and reply
#: messages, so a table of them (by method name) names both only as Any.
MethodHandler: TypeAlias = "grpc.RpcMethodHandler[Any, Any]"


def make_server(
    address: str,
    servicers: list[Servicer],
    service_names: list[str],
    max_workers: int = 32,
    security: Security | None = None,
    roles: Mapping[str, Role] | None = None,
) -> tuple[grpc.Server, int, HealthServicer, ThreadPoolExecutor]:
    """Create, bind and start a server with ``servicers``, health checking and reflection.

    ``security`` gives TLS and the auth file (tokens checked against ``roles``, the role
    each method needs); without it, plaintext and no tokens. A non-loopback ``address``
    without TLS and tokens is refused unless ``security.insecure`` (see
    :mod:`scart_wire.security`); :class:`SecurityError` then, or for unusable files.

    Returns ``(server, bound_port, health_servicer, executor)``; the caller owns the
    executor and ends it with :func:`stop_server` (grpc does not shut it down).
    ``max_workers`` bounds concurrent RPCs: beyond it a call fails fast with
    RESOURCE_EXHAUSTED instead of queueing; long-lived (streaming) calls get at most
    ``max_workers - RESERVED_WORKERS`` of them (see :class:`StreamBudget`), so health
    checks and lookups always find a worker.
    Raises :class:`errors.UnavailableError` when the address cannot be bound.
    """
    from concurrent import futures

    from grpc_health.v1 import health, health_pb2, health_pb2_grpc
    from grpc_reflection.v1alpha import reflection

    security = security or Security()
    security.check_bind(address, "server")
    credentials = security.server_credentials()
    table = security.auth_table()
    streams = max(1, max_workers - RESERVED_WORKERS)
    interceptors = [StreamBudget(streams, streams - streams // 4).interceptor()]  # no one peer takes all
    if table is not None:
        interceptors.insert(0, auth_interceptor(table, roles or {}))
    executor = futures.ThreadPoolExecutor(max_workers=max_workers, thread_name_prefix=THREAD_PREFIX)
    server = grpc.server(executor, options=server_options(), maximum_concurrent_rpcs=max_workers,
                         interceptors=interceptors)
    for add, servicer in servicers:
        add(servicer, server)
    health_servicer = health.HealthServicer()
    health_pb2_grpc.add_HealthServicer_to_server(health_servicer, server)
    for name in service_names:
        health_servicer.set(name, health_pb2.HealthCheckResponse.SERVING)
    health_servicer.set("", health_pb2.HealthCheckResponse.SERVING)
    reflection.enable_server_reflection(
        [*service_names, health.SERVICE_NAME, reflection.SERVICE_NAME], server
    )
    problem = bind_problem(address)
    if problem is not None:
        stop_server(server, executor, 0.0)
        raise errors.UnavailableError(problem, "UNAVAILABLE", address)
    try:
        port = server.add_secure_port(address, credentials) if credentials else server.add_insecure_port(address)
    except RuntimeError as exc:
        stop_server(server, executor, 0.0)
        raise errors.UnavailableError(f"cannot listen on {address}: {exc}", "UNAVAILABLE", address) from None
    if port == 0:
        stop_server(server, executor, 0.0)
        raise errors.UnavailableError(f"cannot listen on {address}", "UNAVAILABLE", address)
    server.start()
    return server, port, health_servicer, executor


def bind_problem(address: str) -> str | None:
    """Why a server cannot listen on ``address`` (``HOST:PORT``), asked of the kernel with a
    socket of our own before gRPC tries (gRPC would print its own raw ``add_port.cc`` line on
    stderr): the port in use, or an address this host does not have; None when it can (or
    for port 0, or an address that is not ``HOST:PORT``: gRPC then says)."""
    import errno

    host, _, port_text = address.rpartition(":")
    host = host.strip("[]")
    if not port_text.isdigit() or int(port_text) == 0 or not host:
        return None
    try:
        infos = socket.getaddrinfo(host, int(port_text), type=socket.SOCK_STREAM)[:4]
    except OSError:
        return f"cannot listen on {address}: no such host here"
    problems = []
    for family, kind, proto, _, where in infos:  # gRPC fails only when it can bind none of them
        with socket.socket(family, kind, proto) as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as gRPC's listener: TIME_WAIT is no conflict
            try:
                probe.bind(where)
                return None
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE:
                    problems.append(f"the port is in use (another scart, or another program: `ss -ltnp 'sport = "
                                    f":{port_text}'` says which); choose another port, or 0 for a free one")
                elif exc.errno == errno.EADDRNOTAVAIL:
                    problems.append(f"this host has no address {host}")
                else:
                    problems.append(exc.strerror or str(exc))
    return f"cannot listen on {address}: {sorted(problems, key=lambda p: 'in use' not in p)[0]}" if problems else None


def stop_server(server: grpc.Server, executor: ThreadPoolExecutor, grace: float = 0.2, timeout: float = 5.0) -> None:
    """Stop ``server`` (``grace`` s for calls in flight), then end its worker threads.

    Blocks at most ``grace + 2 * timeout`` s. Idempotent.
    """
    import time

    server.stop(grace).wait(grace + timeout)
    executor.shutdown(wait=False, cancel_futures=True)
    deadline = time.monotonic() + timeout
    for thread in list(getattr(executor, "_threads", ())):  # bounded join of each worker
        thread.join(max(0.0, deadline - time.monotonic()))


def bound_address(requested: str, port: int) -> str:
    """``host:port`` actually bound for a requested ``host:port`` (port 0 → real port)."""
    host = requested.rpartition(":")[0] or "127.0.0.1"
    if host in ("0.0.0.0", "[::]", ""):
        host = "127.0.0.1"
    return f"{host}:{port}"


def advertised_address(listen: str, advertise: str | None = None) -> str:
    """The address other processes are told to reach a server listening on ``listen``
    (``host:port`` as bound) at: ``advertise`` when given (``HOST``, ``HOST:PORT``,
    ``[V6]`` or ``[V6]:PORT``; the bound port when it has none), else ``listen`` itself, or
    for a wildcard listener (every interface) this host's name: a loopback address would
    send another host to itself. Raises ``ValueError`` for a malformed ``advertise``."""
    port = listen.rpartition(":")[2]
    if advertise:
        host, given = parse_advertise(advertise)
        return f"{host}:{given or port}"
    if listen.rpartition(":")[0].strip("[]") in ("0.0.0.0", "::", ""):
        return f"{socket.gethostname()}:{port}"  # its name, never a loopback one (getfqdn may say localhost)
    return listen


def parse_advertise(text: str) -> tuple[str, str]:
    """``(host, port)`` of ``HOST[:PORT]`` or ``[V6][:PORT]`` (port ``""`` when absent)."""
    bad = ValueError(f"advertise {text!r}: expected HOST, HOST:PORT, [V6] or [V6]:PORT")
    if text.startswith("["):
        inner, _, rest = text[1:].partition("]")
        host, port = f"[{inner}]", rest[1:]
        if not inner or (rest and not rest.startswith(":")) or not _V6.fullmatch(inner):
            raise bad
    else:
        host, _, port = text.partition(":")
        if not _HOST.fullmatch(host) or ":" in port:
            raise bad
    if port and not (port.isdigit() and 0 < int(port) < 65536):
        raise ValueError(f"advertise {text!r}: the port must be a number from 1 to 65535")
    if text.endswith(":") or len(host) > 253:
        raise bad
    return host, port


_HOST = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?")
_V6 = re.compile(r"[0-9A-Fa-f:.]+")


def health_ok(address: str, timeout: float = 0.5, security: Security | None = None, service: str = "") -> bool:
    """True if a gRPC health service answers SERVING for ``service`` ("": the server as a
    whole) at ``address`` within ``timeout``."""
    return health_state(address, timeout, security, service) is True


def health_state(address: str, timeout: float = 0.5, security: Security | None = None,
                 service: str = "") -> bool | None:
    """Is ``service`` served at ``address``? True (SERVING), False (surely not: nothing
    listens there, or a server that does not know it or says NOT_SERVING), None (cannot
    tell: no answer within ``timeout``, overloaded, or any other failure)."""
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    with (security or Security()).channel(address, channel_options()) as channel:
        try:
            reply = health_pb2_grpc.HealthStub(channel).Check(  # type: ignore[attr-defined]  # its stub lists no method
                health_pb2.HealthCheckRequest(service=service), timeout=timeout
            )
        except grpc.RpcError as exc:
            code = exc.code() if callable(getattr(exc, "code", None)) else None
            return False if code in (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.NOT_FOUND) else None
    return reply.status == health_pb2.HealthCheckResponse.SERVING


class StreamBudget:
    """Bounds the long-lived (streaming) calls of one server: at most ``total`` at once,
    at most ``per_peer`` from one peer (a remote host; on loopback, one connection), and a
    client stream whose first message does not come within ``first_message_s`` is cancelled.
    Beyond a bound the call ends at once with RESOURCE_EXHAUSTED, its message starting
    with ``label`` when one is given. Thread-safe."""

    def __init__(self, total: int, per_peer: int, first_message_s: float | None = None,
                 label: str = "") -> None:
        self.total = total
        self.per_peer = per_peer
        self.label = label
        self.first_message_s = FIRST_MESSAGE_S if first_message_s is None else first_message_s
        self._lock = threading.Lock()
        self._open = 0
        self._by_peer: dict[str, int] = {}

    def _take(self, peer: str) -> str | None:
        """Take a slot; None when taken, else why not."""
        with self._lock:
            if self._open >= self.total:
                return f"this server carries at most {self.total} streams at once"
            if self._by_peer.get(peer, 0) >= self.per_peer:
                return f"at most {self.per_peer} streams from one peer"
            self._open += 1
            self._by_peer[peer] = self._by_peer.get(peer, 0) + 1
            return None

    def _give(self, peer: str) -> None:
        with self._lock:
            self._open -= 1
            left = self._by_peer.get(peer, 1) - 1
            if left > 0:
                self._by_peer[peer] = left
            else:
                self._by_peer.pop(peer, None)

    @property
    def open(self) -> int:
        """Streams open now."""
        return self._open

    def interceptor(self) -> grpc.ServerInterceptor:
        """The server interceptor applying this budget to every streaming method."""
        budget = self

        class Interceptor(grpc.ServerInterceptor):
            def intercept_service(
                    self, continuation: Callable[[grpc.HandlerCallDetails], grpc.RpcMethodHandler[Req, Resp] | None],
                    details: grpc.HandlerCallDetails) -> grpc.RpcMethodHandler[Req, Resp] | None:
                handler = continuation(details)
                if handler is None or not (handler.request_streaming or handler.response_streaming):
                    return handler
                return budget._wrap(handler)

        return Interceptor()

    def _wrap(self, handler: Any) -> Any:  # Any: one wrapper over three kinds of gRPC behaviour
        if handler.unary_stream is not None:
            behavior, make, client_stream = handler.unary_stream, grpc.unary_stream_rpc_method_handler, False
        elif handler.stream_unary is not None:
            behavior, make, client_stream = handler.stream_unary, grpc.stream_unary_rpc_method_handler, True
        else:
            behavior, make, client_stream = handler.stream_stream, grpc.stream_stream_rpc_method_handler, True
        budget = self

        def admitted(request: object, context: grpc.ServicerContext) -> str:
            peer = peer_key(context)
            refused = budget._take(peer)
            if refused is not None:
                context.abort(grpc.StatusCode.RESOURCE_EXHAUSTED,
                              f"{budget.label}: {refused}" if budget.label else refused)
            return peer

        wrapped: Callable[[Any, grpc.ServicerContext], Any]
        if handler.response_streaming:
            def streaming(request: Any, context: grpc.ServicerContext) -> Any:
                peer = admitted(request, context)
                try:
                    if client_stream:
                        request = _FirstMessageDeadline(request, context, budget.first_message_s)
                    yield from behavior(request, context)
                finally:
                    budget._give(peer)
            wrapped = streaming
        else:
            def unary_reply(requests: Any, context: grpc.ServicerContext) -> Any:
                peer = admitted(requests, context)
                try:
                    return behavior(_FirstMessageDeadline(requests, context, budget.first_message_s), context)
                finally:
                    budget._give(peer)
            wrapped = unary_reply
        return make(wrapped, request_deserializer=handler.request_deserializer,
                    response_serializer=handler.response_serializer)


class _FirstMessageDeadline(Generic[Req]):
    """A request iterator whose first message must come within ``seconds`` (else the call
    is cancelled: a client holding a stream open without speaking does not pin a worker)."""

    def __init__(self, requests: Iterator[Req], context: grpc.ServicerContext, seconds: float) -> None:
        self._requests = requests
        self._context = context
        self._seconds = seconds
        self._first = True

    def __iter__(self) -> _FirstMessageDeadline[Req]:
        return self

    def __next__(self) -> Req:
        if not self._first:
            return next(self._requests)
        self._first = False
        timer = threading.Timer(self._seconds, self._context.cancel)
        timer.daemon = True
        timer.start()
        try:
            return next(self._requests)
        finally:
            timer.cancel()


def peer_key(context: grpc.ServicerContext) -> str:
    """Who a call comes from, for per-peer bounds: its token (when the server checks
    tokens: see :data:`security.CALLER`), else the remote host, or on loopback (where every
    local process shares one address) the connection (host and port)."""
    caller = CALLER.get()
    if caller:
        return caller
    peer = context.peer() or ""
    kind, _, rest = peer.partition(":")
    host, _, _port = rest.rpartition(":")
    host = host.strip("[]")
    if kind in ("ipv4", "ipv6") and host and not is_loopback(host):
        return f"{kind}:{host}"
    return peer
