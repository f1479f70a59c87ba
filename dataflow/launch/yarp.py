"""The YARP options of the verbs that start a process holding ports (``scart deploy``,
``scart run``): ``--yarp-server HOST:PORT``, this process's name server for its ``yarp``
streams and RPC ports (default: YARP's own configuration, as ``yarp conf`` writes it); and
``scart call yarp:/port WORD ARGS...`` (:func:`call`), an RPC as ``yarp rpc`` makes it."""

from __future__ import annotations

import argparse

__all__ = ["add_arguments", "apply", "call"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--yarp-server HOST:PORT`` (with ``--insecure``, the security options' flag, YARP
    ports listen on every interface instead of loopback)."""
    group = parser.add_argument_group("YARP (streams with transport yarp, RPC ports)")
    group.add_argument("--yarp-server", default=None, metavar="HOST:PORT",
                       help="the YARP name server (default: YARP's configuration, `yarp conf`)")


def apply(args: argparse.Namespace) -> None:
    """Set the process's YARP defaults from ``args`` (nothing is loaded unless one is
    given). Raises ``ValueError`` for a bad address."""
    server, insecure = getattr(args, "yarp_server", None), bool(getattr(args, "insecure", False))
    if server is None and not insecure:
        return
    from dataflow.transports import load

    configure = getattr(load("yarp"), "configure", None)
    if configure is not None:
        configure(server=server, insecure=insecure or None)


def call(args: argparse.Namespace, values: list[object]) -> list[object]:
    """``scart call yarp:/port WORD ARGS...``: the reply bottle as plain data (a vocab as its
    text). Raises ``ValueError`` saying what went wrong (no such port, no answer)."""
    from dataflow.transports.yarp.rpc import call_rpc

    return call_rpc(args.operation.partition(":")[2], values, getattr(args, "yarp_server", None), args.timeout)
