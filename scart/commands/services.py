"""``scart services``: the SCA services ``scart run`` serves, with their interfaces and
operations: every endpoint the name service knows (``--ns``, ``SCART_NS``, the default),
or the one ``--at HOST:PORT`` names (see :mod:`scart.commands._sca`)."""

from __future__ import annotations

import argparse

from scart.commands._sca import SERVICES_ENV, at, list_services, named_endpoints, with_services
from scart_wire.console import add_common, address_arg, dump, out

HELP = "list the SCA services scart run serves (found through the name service, or --at)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--at`` and the common options."""
    parser.add_argument("--at", default=None, metavar="HOST:PORT", type=address_arg,
                        help=f"list the services served there instead (scart run prints it), or ${SERVICES_ENV}")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """List; 1 when nothing answers."""
    return with_services(args, _services)


def _services(args: argparse.Namespace) -> int:
    address = at(args)
    services = []
    for where, namespace in [(address, "")] if address else named_endpoints(args):
        services += list_services(where, args, namespace)
    if args.json:
        out(dump(services))
        return 0
    for s in services:
        ops = ", ".join(o["name"] + (" (one-way)" if o["oneway"] else "") for o in s["operations"])
        also = f"  also: {', '.join(s['names'][1:])}" if len(s["names"]) > 1 else ""
        out(f"{s['names'][0]}  [{s['interface']}]  {ops}{also}" + ("" if address else f"  at {s['at']}"))
    return 0
