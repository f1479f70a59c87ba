"""The error tree both worlds share: what the type registry, the codec, the bounds and
the RPC helpers raise, and what ``dataflow`` and ``scart`` catch.

The root keeps the name it had when this layer was part of :mod:`dataflow`,
:class:`DataflowError` (every value that crosses a process is a
``scart.dataflow.v1.Value``): :mod:`dataflow.errors` and :mod:`dataflow.remote.errors`
re-export these classes, so ``except dataflow.PortTypeError`` around a codec or registry
call, and ``except DataflowError`` around a remote call, keep working. Python's
``except`` matches real subclasses only, so the classes a wire module raises must be
defined here, below both worlds.

Remote failures map to the local errors where the meaning is the same (an unknown name
is :class:`NotFoundError`, a wrong type :class:`PortTypeError`), so code written against
in-process proxies handles the gRPC ones unchanged. The gRPC status code is kept on
:attr:`RemoteError.code` as a plain string (no gRPC type leaks out).
"""

from __future__ import annotations

__all__ = [
    "MAX_ECHO",
    "bounded",
    "DataflowError",
    "PortTypeError",
    "NotFoundError",
    "DeploymentError",
    "PropertyValueError",
    "PortValueError",
    "RemoteError",
    "UnavailableError",
    "RemoteTimeoutError",
    "AlreadyRegisteredError",
    "RemoteNotFoundError",
    "RemoteTypeError",
    "RemoteValueError",
    "AuthenticationError",
    "PermissionDeniedError",
    "TlsMismatchError",
]

#: Characters of one error text, at most, where it echoes what someone sent (a name or an
#: argument of megabytes is cut in the middle, and said): the CLI's lines, a status's details.
MAX_ECHO = 2000


def bounded(text: str, limit: int = MAX_ECHO) -> str:
    """``text``, or its head and tail around ``... (N characters left out) ...`` when it is
    longer than ``limit``."""
    if len(text) <= limit:
        return text
    keep = limit // 2
    return f"{text[:keep]} ... ({len(text) - 2 * keep} characters left out) ... {text[-keep:]}"


class DataflowError(Exception):
    """Base of every error raised by :mod:`dataflow` and by this wire layer."""


class PortTypeError(DataflowError, TypeError):
    """A value or a connection does not match a port's (or property's) type."""


class NotFoundError(DataflowError, KeyError):
    """A task, port, property or operation name does not exist; the message lists what does."""

    def __str__(self) -> str:  # KeyError quotes its argument; keep the message readable
        return str(self.args[0]) if self.args else ""


class DeploymentError(DataflowError):
    """A deployment step failed (duplicate task name, a task refused to configure, ...)."""


class PropertyValueError(DataflowError, ValueError):
    """A property value has the right type but is outside what the property accepts."""


class PortValueError(DataflowError, ValueError):
    """A value written to an input port from outside has the right type but is outside the
    port's bounds (not finite, below or above its range)."""


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
