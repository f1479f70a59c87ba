"""Errors of remote data-flow access; all are :class:`dataflow.errors.DataflowError`.

Remote failures map to the core's errors where the meaning is the same (an unknown
name is :class:`NotFoundError`, a wrong type :class:`PortTypeError`), so code written
against the in-process proxies handles the gRPC ones unchanged. The gRPC status code
is kept on :attr:`RemoteError.code` as a plain string (no gRPC type leaks out).
"""

from __future__ import annotations

from dataflow.errors import DataflowError, NotFoundError, PortTypeError, PropertyValueError

__all__ = [
    "RemoteError",
    "UnavailableError",
    "RemoteTimeoutError",
    "AlreadyRegisteredError",
    "RemoteNotFoundError",
    "RemoteTypeError",
    "RemoteValueError",
    "ClosedError",
    "AuthenticationError",
    "PermissionDeniedError",
    "TlsMismatchError",
]


class RemoteError(DataflowError):
    """A remote call failed. ``code`` is the status name (e.g. ``"UNAVAILABLE"``), ``address`` the peer."""

    def __init__(self, message: str, code: str = "UNKNOWN", address: str = "") -> None:
        super().__init__(message)
        self.code = code
        self.address = address


class UnavailableError(RemoteError):
    """Nothing answers at the address (not started, dead, or unreachable)."""


class RemoteTimeoutError(RemoteError, TimeoutError):
    """The peer did not answer before the call's deadline (frozen, overloaded)."""


class AlreadyRegisteredError(RemoteError):
    """A component name is already held by another live deployer in the name service."""


class RemoteNotFoundError(RemoteError, NotFoundError):
    """A component, port, property or operation does not exist; the message lists what does."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class RemoteTypeError(RemoteError, PortTypeError):
    """A value does not match the remote port's / property's / parameter's type."""


class RemoteValueError(RemoteError, PropertyValueError):
    """A value has the right type but the remote side refused it."""


class AuthenticationError(RemoteError):
    """The server wants a valid token (``--token`` / ``SCART_TOKEN``) or certificate."""


class TlsMismatchError(AuthenticationError):
    """The two ends disagree about TLS (one speaks it, the other does not, or the server's
    certificate is not trusted); the message names the flag that fixes it."""


class PermissionDeniedError(RemoteError):
    """The token's role does not allow the call; the message names the role it needs."""


class ClosedError(DataflowError):
    """The proxy / system / subscription was closed by its owner."""
