"""Remote access to data-flow components over gRPC (the JOrocos mirror).

Story: ``server = deployer.serve("127.0.0.1:0")`` (gRPC, name service embedded) →
``system = connect(server.address)`` → ``proxy = system.component("driver")`` →
``proxy.ports()`` / ``proxy.write("commands", v)`` / ``proxy.subscribe("status", cb)`` /
``proxy.call("reset")`` → ``sub.close(); system.close(); server.stop()``.

The proxy API (:mod:`dataflow.remote.api`) is transport-neutral; :func:`local_system`
gives the same API in-process without gRPC. Standalone name service:
:func:`serve_nameserver` (``scart nameserver``), default port :data:`DEFAULT_NS_PORT`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataflow.remote.api import (
    ComponentInfo, ComponentProxy, GapEvent, PortWriter, SampleEvent, Subscription, System,
)
from dataflow.remote.errors import (
    AlreadyRegisteredError, AuthenticationError, ClosedError, PermissionDeniedError, RemoteError,
    RemoteNotFoundError, RemoteTimeoutError, RemoteTypeError, RemoteValueError, UnavailableError,
)
from scart_wire.defaults import DEFAULT_LEASE, DEFAULT_NS_ADDRESS, DEFAULT_NS_PORT
from scart_wire.security import Role, Security, SecurityError

if TYPE_CHECKING:
    from dataflow.deployer import Deployer
    from dataflow.remote.client import GrpcSystem
    from dataflow.remote.naming import NameServer

__all__ = [
    "connect", "local_system", "serve_nameserver",
    "System", "ComponentProxy", "Subscription", "PortWriter", "SampleEvent", "GapEvent", "ComponentInfo",
    "RemoteError", "UnavailableError", "RemoteTimeoutError", "RemoteNotFoundError", "RemoteTypeError",
    "RemoteValueError", "AlreadyRegisteredError", "ClosedError", "DEFAULT_NS_PORT", "DEFAULT_NS_ADDRESS",
    "AuthenticationError", "PermissionDeniedError", "Security", "SecurityError", "Role",
]


def connect(address: str, timeout: float = 2.0, heartbeat_ms: int = 500,
            security: Security | None = None) -> GrpcSystem:
    """Connect to a name service (standalone or embedded in a deployer); see :func:`dataflow.remote.client.connect`
    (``security`` defaults to ``Security.from_env()``)."""
    from dataflow.remote.client import connect as _connect

    return _connect(address, timeout=timeout, heartbeat_ms=heartbeat_ms, security=security)


def local_system(deployer: Deployer) -> System:
    """The same proxy API over an in-process ``Deployer`` (no gRPC)."""
    from dataflow.remote.local import LocalSystem

    return LocalSystem(deployer)


def serve_nameserver(address: str = "127.0.0.1:0", default_lease: float = DEFAULT_LEASE, max_workers: int = 16,
                     security: Security | None = None) -> NameServer:
    """Start a standalone name service; see :func:`dataflow.remote.naming.serve_nameserver`."""
    from dataflow.remote.naming import serve_nameserver as _serve

    return _serve(address, default_lease, max_workers, security)
