"""SCA services from the command line: ``scart services --at ADDRESS`` and ``scart call
--at ADDRESS COMPONENT/SERVICE.operation ARGS...``.

``ADDRESS`` is a ``binding.grpc`` server: the one ``scart run`` serves every component
service on (it prints it: ``scart: SCA services at ...``; ``--services`` chooses it), or
any ``binding.grpc`` service of a composite. ``--at`` may also come from
``SCART_SERVICES``. Arguments are JSON (a bare word is a string), converted by the server
to the operation's parameter types; the result prints as JSON. The server's TLS and tokens
apply (``--token``, ``--tls-*``): listing needs the ``read`` role, calling ``operate``.
The wire is ``scart.sca.v1`` (``dataflow/proto/scart/sca/v1/sca.proto``), so this side
needs nothing of ``scart``.
"""

from __future__ import annotations

import argparse
import os
from typing import Any

__all__ = ["SERVICES_ENV", "call", "list_services"]

SERVICES_ENV = "SCART_SERVICES"


def at(args: argparse.Namespace) -> str | None:
    """The services address of a verb that takes ``--at``: ``--at``, else ``$SCART_SERVICES``,
    else None (always None for the other verbs: they use the name service)."""
    if not hasattr(args, "at"):
        return None
    return args.at or os.environ.get(SERVICES_ENV) or None


def _stub(address: str, args: argparse.Namespace) -> tuple[Any, Any]:
    from dataflow.proto.scart.sca.v1 import sca_pb2_grpc
    from dataflow.remote import _rpc
    from dataflow.remote.security import from_args

    channel = from_args(args).channel(address, _rpc.channel_options())
    return channel, sca_pb2_grpc.ScaServiceStub(channel)


def list_services(address: str, args: argparse.Namespace) -> list[dict[str, Any]]:
    """Every service the server at ``address`` exports: names, interface, operations."""
    from dataflow.proto.scart.sca.v1 import sca_pb2 as pb
    from dataflow.remote import _rpc

    channel, stub = _stub(address, args)
    try:
        reply = _rpc.call(stub.ListServices, pb.ListServicesRequest(), args.timeout, address)
    finally:
        channel.close()
    return [{"names": list(s.names), "interface": s.interface,
             "operations": [{"name": o.name, "oneway": o.oneway, "returns_value": o.returns_value}
                            for o in s.operations]} for s in reply.services]


def call(address: str, target: str, json_args: list[Any], args: argparse.Namespace) -> Any:
    """Call ``COMPONENT/SERVICE.operation`` (or ``SERVICE.operation`` for a promoted or
    single service) at ``address`` with JSON arguments; the result as JSON-able data.
    Raises ``ValueError`` for a malformed target, ``DataflowError`` for a remote fault."""
    from dataflow import codec, registry
    from dataflow.errors import DataflowError
    from dataflow.proto.scart.sca.v1 import sca_pb2 as pb
    from dataflow.remote import _rpc

    service, dot, operation = target.rpartition(".")
    if not dot or not service or not operation:
        raise ValueError(f"expected COMPONENT/SERVICE.operation, got {target!r}")
    request = pb.CallRequest(invocation=pb.Invocation(service=service, operation=operation,
                                                      args=[codec.encode(a) for a in json_args]))
    channel, stub = _stub(address, args)
    try:
        reply = _rpc.call(stub.Call, request, args.timeout, address)
    finally:
        channel.close()
    if reply.outcome.WhichOneof("kind") == "fault":
        fault = reply.outcome.fault
        raise DataflowError(f"{target} raised {fault.type}: {fault.message}")
    return registry.to_jsonable(codec.decode(reply.outcome.value))


def cmd_services(args: argparse.Namespace) -> int:
    """``scart services --at ADDRESS``."""
    from dataflow.cli.inspect import _dump, _out

    address = at(args)
    if address is None:
        raise ValueError(f"give --at HOST:PORT (scart run prints it: 'SCA services at ...'), or set ${SERVICES_ENV}")
    services = list_services(address, args)
    if args.json:
        _out(_dump(services))
        return 0
    for s in services:
        ops = ", ".join(o["name"] + (" (one-way)" if o["oneway"] else "") for o in s["operations"])
        _out(f"{s['names'][0]}  [{s['interface']}]  {ops}" + (f"  also: {', '.join(s['names'][1:])}"
                                                               if len(s["names"]) > 1 else ""))
    return 0

