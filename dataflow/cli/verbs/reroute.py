"""``scart reroute LINK C.in``: point a link at another input port (the new connection is
made before the old one goes)."""

from __future__ import annotations

import argparse

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, out

HELP = "point a link at another input port (made before the old one goes)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``LINK C.in`` and the common options."""
    parser.add_argument("name", metavar="LINK")
    parser.add_argument("sink", metavar="C.in")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Reroute; 1 when refused."""
    return with_system(args, cmd_reroute)


def cmd_reroute(args: argparse.Namespace) -> int:
    """``scart reroute LINK C.in``."""
    link = args.system.reroute(args.name, args.sink)
    out(dump(link.model_dump()) if args.json else f"{link.name}: {link.source} -> {link.sink} ({link.policy})")
    return 0
