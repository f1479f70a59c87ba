"""gRPC plumbing shared by the server and the client (private; the only place that maps
gRPC statuses to scart errors). Servicers and stubs are the generated ones of
:mod:`dataflow.proto`, so registered names always equal the proto's.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType
from typing import Any

import grpc

from dataflow.remote import errors
from dataflow.remote.security import Role, Security, auth_interceptor

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


def server_options() -> list[tuple[str, int]]:
    """Options for servers: message limits, and accept the clients' keepalive pings."""
    return [
        ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
        ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
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
    if cls is errors.UnavailableError:
        message = f"nothing answers at {address} ({details})"
    elif cls is errors.RemoteTimeoutError:
        message = f"{address} did not answer in time ({details})"
    else:
        message = details or name
    return cls(message, code=name, address=address)


def call(fn: Callable[..., Any], request: Any, timeout: float, address: str) -> Any:
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


def abort(context: grpc.ServicerContext, exc: BaseException) -> None:
    """Abort the RPC with the status matching ``exc`` (never returns)."""
    from dataflow.errors import NotFoundError, PortTypeError, PropertyValueError

    if isinstance(exc, Abort):
        context.abort(grpc.StatusCode[exc.code], str(exc))
    if isinstance(exc, NotFoundError):
        context.abort(grpc.StatusCode.NOT_FOUND, str(exc))
    if isinstance(exc, PropertyValueError):
        context.abort(grpc.StatusCode.OUT_OF_RANGE, str(exc))
    if isinstance(exc, (PortTypeError, TypeError, ValueError)):
        context.abort(grpc.StatusCode.INVALID_ARGUMENT, str(exc))
    context.abort(grpc.StatusCode.INTERNAL, f"{type(exc).__name__}: {exc}")


#: A servicer and the generated function that adds it to a server
#: (``dataflow_pb2_grpc.add_DeployerServiceServicer_to_server``, ...).
Servicer = tuple[Callable[[Any, grpc.Server], None], object]


def make_server(
    address: str,
    servicers: list[Servicer],
    service_names: list[str],
    max_workers: int = 32,
    security: Security | None = None,
    roles: Mapping[str, Role] | None = None,
) -> tuple[grpc.Server, int, Any, Any]:
    """Create, bind and start a server with ``servicers``, health checking and reflection.

    ``security`` gives TLS and the auth file (tokens checked against ``roles``, the role
    each method needs); without it, plaintext and no tokens. A non-loopback ``address``
    without TLS and tokens is refused unless ``security.insecure`` (see
    :mod:`dataflow.remote.security`); :class:`SecurityError` then, or for unusable files.

    Returns ``(server, bound_port, health_servicer, executor)``; the caller owns the
    executor and ends it with :func:`stop_server` (grpc does not shut it down).
    ``max_workers`` bounds concurrent
    RPCs: beyond it a call fails fast with RESOURCE_EXHAUSTED instead of queueing.
    Raises :class:`errors.UnavailableError` when the address cannot be bound.
    """
    from concurrent import futures

    from grpc_health.v1 import health, health_pb2, health_pb2_grpc
    from grpc_reflection.v1alpha import reflection

    security = security or Security()
    security.check_bind(address, "server")
    credentials = security.server_credentials()
    table = security.auth_table()
    interceptors = [auth_interceptor(table, roles or {})] if table is not None else []
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


def stop_server(server: grpc.Server, executor: Any, grace: float = 0.2, timeout: float = 5.0) -> None:
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


def health_ok(address: str, timeout: float = 0.5, security: Security | None = None, service: str = "") -> bool:
    """True if a gRPC health service answers SERVING for ``service`` ("": the server as a
    whole) at ``address`` within ``timeout``."""
    from grpc_health.v1 import health_pb2, health_pb2_grpc

    with (security or Security()).channel(address, channel_options()) as channel:
        try:
            reply = health_pb2_grpc.HealthStub(channel).Check(
                health_pb2.HealthCheckRequest(service=service), timeout=timeout
            )
        except grpc.RpcError:
            return False
    return reply.status == health_pb2.HealthCheckResponse.SERVING
