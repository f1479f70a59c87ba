"""``scart connect A.out B.in [--policy P] [--name LINK] [--transport T]``: connect an
output port to an input port, in any deployers, as a named link."""

from __future__ import annotations

import argparse

from dataflow.cli.connected import with_system
from dataflow.policy import ConnPolicy
from scart_wire.console import add_common, dump, out

HELP = "connect an output port to an input port (any deployers)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The two ports, ``--policy``, ``--name``, ``--transport`` and the common options."""
    parser.add_argument("source", metavar="A.out")
    parser.add_argument("sink", metavar="B.in")
    parser.add_argument("--policy", default="data", help="data | buffer:N | circular:N (default data)")
    parser.add_argument("--name", default=None, help="the link's name (default A.out->B.in)")
    parser.add_argument("--transport", default="auto", type=_transport,
                        help="across processes: auto (default: on one host shm for bytes and array ports, ipc "
                             "for the others, else grpc), ipc (same-host socket), shm (same host, large samples in "
                             "shared memory), grpc, or an installed plug-in's name")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Connect (or say what changed for a pair connected already); 1 when refused: an
    unknown port, an output as the sink, two types (``[SCART-T003]``), a limit."""
    return with_system(args, cmd_connect)


def _transport(text: str) -> str:
    """``--transport``: a name a policy accepts, checked by the policy (plug-ins are looked
    up only for a name that is not scart's own)."""
    try:
        return ConnPolicy(transport=text).transport
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def cmd_connect(args: argparse.Namespace) -> int:
    """``scart connect A.out B.in [--policy P]``."""
    policy = ConnPolicy.parse(args.policy).with_(transport=args.transport)
    note = args.system.connect_ports(args.source, args.sink, policy, name=args.name)
    name = args.name or next((lk.name for lk in args.system.links()
                              if (lk.source, lk.sink) == (args.source, args.sink)), f"{args.source}->{args.sink}")
    doc = {"name": name, "source": args.source, "sink": args.sink, "policy": str(policy),
           "transport": policy.transport, "connected": True, "note": note}
    over = f", {policy.transport}" if policy.transport != "auto" else ""
    out(dump(doc) if args.json else f"connected {args.source} -> {args.sink} ({policy}{over}) as {name}"
        + (f": {note}" if note else ""))
    return 0
