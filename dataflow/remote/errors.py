"""Errors of remote data-flow access; all are :class:`dataflow.errors.DataflowError`.

Remote failures map to the core's errors where the meaning is the same (an unknown
name is :class:`NotFoundError`, a wrong type :class:`PortTypeError`), so code written
against the in-process proxies handles the gRPC ones unchanged. The gRPC status code
is kept on :attr:`RemoteError.code` as a plain string (no gRPC type leaks out).

Every class but :class:`ClosedError` is defined in :mod:`scart_wire.errors` (the RPC
helpers both worlds share raise them) and is the same object here.
"""

from __future__ import annotations

from scart_wire.errors import (
    AlreadyRegisteredError,
    AuthenticationError,
    DataflowError,
    PermissionDeniedError,
    RemoteError,
    RemoteNotFoundError,
    RemoteTimeoutError,
    RemoteTypeError,
    RemoteValueError,
    TlsMismatchError,
    UnavailableError,
)

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


class ClosedError(DataflowError):
    """The proxy / system / subscription was closed by its owner."""
