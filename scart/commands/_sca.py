"""SCA services from the command line, the client side of ``scart services`` and
``scart call``: list and call the services a ``binding.grpc`` server exports.

A server is found by name (the ``sca:HOST:PORT`` entries ``scart run`` registers with
its name service: ``--ns``, else ``SCART_NS``, else the default) or given with ``--at
HOST:PORT`` (else ``SCART_SERVICES``), which overrides the name service: the endpoint
``scart run`` serves every component service on (``--services`` chooses it), or any
``binding.grpc`` service of a composite. Arguments are JSON or YAML (a bare word is a
string), converted by the server to the operation's parameter types; the result prints as
JSON. The server's TLS and tokens apply (``--token``, ``--tls-*``): listing needs the
``read`` role, calling ``operate``. The wire is ``scart.sca.v1``
(``dataflow/proto/scart/sca/v1/sca.proto``).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from typing import TYPE_CHECKING, TypedDict

if TYPE_CHECKING:
    import grpc

    from scart_wire.proto.scart.sca.v1.sca_pb2_grpc import ScaServiceStub

__all__ = ["SERVICES_ENV", "at", "call", "endpoints", "find", "list_services", "named_endpoints", "with_services"]

SERVICES_ENV = "SCART_SERVICES"
MAX_ENDPOINTS = 64  # services endpoints one command lists or searches


def at(args: argparse.Namespace) -> str | None:
    """``--at``, else ``$SCART_SERVICES``, else None (then the name service is asked).
    Raises ``ValueError`` naming ``$SCART_SERVICES`` when it is not ``HOST:PORT``."""
    from scart_wire.console import checked_address

    given = getattr(args, "at", None)
    if given:
        return str(given)
    env = os.environ.get(SERVICES_ENV)
    return checked_address(env, f"${SERVICES_ENV}") if env else None


def with_services(args: argparse.Namespace, body: Callable[[argparse.Namespace], int]) -> int:
    """Run ``body``; a remote fault, a refusal or a malformed target becomes one stderr line
    and exit 1."""
    from scart_wire.errors import DataflowError
    from scart_wire.console import err

    try:
        return body(args)
    except (DataflowError, ValueError) as exc:
        err(f"{args.command}: {exc}")
        return 1


class OperationRow(TypedDict):
    """An operation as ``scart services --json`` lists it."""

    name: str
    oneway: bool
    returns_value: bool
    params: list[str]


class ServiceRow(TypedDict):
    """A service as ``scart services --json`` lists it: its names, interface, endpoint, operations."""

    names: list[str]
    interface: str
    at: str
    operations: list[OperationRow]


def _stub(address: str, args: argparse.Namespace) -> tuple[grpc.Channel, ScaServiceStub]:
    from scart_wire.proto.scart.sca.v1 import sca_pb2_grpc
    from scart_wire import rpc
    from scart_wire.security import from_args

    channel = from_args(args).channel(address, rpc.channel_options())
    return channel, sca_pb2_grpc.ScaServiceStub(channel)


def endpoints(args: argparse.Namespace) -> list[str]:
    """The services endpoints registered with the name service (``--ns``, ``SCART_NS``, the
    default); raises ``DataflowError`` naming it when it does not answer."""
    return sorted({address for address, _ in named_endpoints(args)})


def named_endpoints(args: argparse.Namespace) -> list[tuple[str, str]]:
    """``(address, namespace)`` of each services endpoint the name service knows (the
    namespace of a ``scart run --remap __ns=NS``, else ``""``); raises ``DataflowError``
    naming the name service when it does not answer."""
    from scart_wire.console import ns_address
    from scart_wire.errors import RemoteTimeoutError, UnavailableError
    from dataflow.remote.naming import NameClient
    from scart_wire.security import from_args

    ns = ns_address(args)
    names = NameClient(ns, timeout=args.timeout, security=from_args(args))
    try:
        entries = names.entries(sca=True)
    except (UnavailableError, RemoteTimeoutError) as exc:
        raise type(exc)(f"no name service answers at {ns} ({exc}): give --ns, or --at HOST:PORT "
                        "(scart run prints it: 'SCA services at ...')") from None
    finally:
        names.close()
    from dataflow.remote.naming import SCA_PREFIX

    found = {(e.address, e.component[len(SCA_PREFIX):].removesuffix(e.address).rstrip("/")) for e in entries}
    return sorted(found)[:MAX_ENDPOINTS]


def list_services(address: str, args: argparse.Namespace, namespace: str = "") -> list[ServiceRow]:
    """Every service the server at ``address`` exports: names (each under ``namespace/``
    when one is given), interface, operations."""
    from scart_wire.proto.scart.sca.v1 import sca_pb2 as pb
    from scart_wire import rpc

    channel, stub = _stub(address, args)
    try:
        reply = rpc.call(stub.ListServices, pb.ListServicesRequest(), args.timeout, address)
    finally:
        channel.close()
    under = f"{namespace}/" if namespace else ""
    return [{"names": [under + n for n in s.names], "interface": s.interface, "at": address,
             "operations": [{"name": o.name, "oneway": o.oneway, "returns_value": o.returns_value,
                             "params": list(o.params)} for o in s.operations]} for s in reply.services]


def find(service: str, args: argparse.Namespace) -> tuple[str, str]:
    """``(endpoint, name there)`` of ``service`` (``COMPONENT/SERVICE``, a promoted service or
    a single-service component's name; ``NS/...`` for a run under ``--remap __ns=NS``)
    among those the name service knows; raises ``NotFoundError`` listing what there is,
    ``DataflowError`` when it is ambiguous."""
    from scart_wire.errors import DataflowError, NotFoundError

    found, known = [], []
    for address, namespace in named_endpoints(args):
        try:
            listed = list_services(address, args, namespace)
        except DataflowError:  # an endpoint going away: the others still count
            continue
        known += [s["names"][0] for s in listed]
        if any(service in s["names"] for s in listed):
            found.append((address, service.removeprefix(f"{namespace}/") if namespace else service))
    if not found:
        raise NotFoundError(f"no component or SCA service named {service!r}; SCA services: "
                            f"{', '.join(sorted(known)[:20]) or 'none registered'}")
    if len(found) > 1:
        raise DataflowError(f"SCA service {service!r} is served at {', '.join(a for a, _ in found)}: choose one "
                            "with --at")
    return found[0]


def call(address: str, target: str, json_args: list[object], args: argparse.Namespace,
         kwargs: dict[str, object] | None = None, there: str | None = None) -> object:
    """Call ``COMPONENT/SERVICE.operation`` (or ``SERVICE.operation`` for a promoted or
    single service) at ``address`` with JSON arguments (in order, and ``kwargs`` by name);
    ``there``: the service's name at ``address`` when ``target`` names it under a
    namespace (see :func:`find`). The result as JSON-able data. Raises ``ValueError`` for a malformed target,
    ``DataflowError`` for a remote fault: a refused argument (a missing one, a value its
    declaration refuses) in the server's words, an operation that raised with its type."""
    from scart_wire import codec
    from scart_wire.types import registry
    from scart_wire.errors import DataflowError
    from scart_wire.proto.scart.sca.v1 import sca_pb2 as pb
    from scart_wire import rpc

    shown, operation = split_target(target)
    service = there or shown  # the name at the endpoint (without the namespace it is found under)
    request = pb.CallRequest(invocation=pb.Invocation(service=service, operation=operation,
                                                      args=[codec.encode(a) for a in json_args],
                                                      kwargs={k: codec.encode(v) for k, v in (kwargs or {}).items()}))
    channel, stub = _stub(address, args)
    try:
        reply = rpc.call(stub.Call, request, args.timeout, address)
    finally:
        channel.close()
    if reply.outcome.WhichOneof("kind") == "fault":
        fault = reply.outcome.fault
        if fault.code == "INVALID_ARGUMENT":  # the caller's mistake: the server's own words say it
            message = fault.message
            if message.startswith(f"{operation}("):
                message = f"{shown}.{message}"
            raise DataflowError(f"{message} (refused: give the arguments in order, or as one mapping by name)")
        ref = f" (reference {fault.reference} in the server's log)" if fault.reference else ""
        raise DataflowError(f"{target} raised {fault.type}: {fault.message}{ref}")
    return registry.to_jsonable(codec.decode(reply.outcome.value))


def split_target(target: str) -> tuple[str, str]:
    """``"Component/Service.op"`` → ``("Component/Service", "op")`` (``ValueError`` otherwise)."""
    service, dot, operation = target.rpartition(".")
    if not dot or not service or not operation:
        raise ValueError(f"expected COMPONENT/SERVICE.operation, got {target!r}")
    return service, operation
