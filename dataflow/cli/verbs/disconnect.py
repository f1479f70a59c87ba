"""``scart disconnect LINK`` or ``scart disconnect A.out B.in``: undo a link (exit 1 when
there was none)."""

from __future__ import annotations

import argparse

from dataflow.cli.output import add_common, dump, out, with_system

HELP = "disconnect a link (by its name, or by its two ports)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``LINK`` or ``A.out B.in`` and the common options."""
    parser.add_argument("source", metavar="LINK|A.out")
    parser.add_argument("sink", metavar="B.in", nargs="?")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Disconnect; 1 when nothing was connected."""
    return with_system(args, cmd_disconnect)


def cmd_disconnect(args: argparse.Namespace) -> int:
    """``scart disconnect A.out B.in`` or ``scart disconnect LINK``."""
    if args.sink is None:
        done = args.system.disconnect_link(args.source)
        doc = {"name": args.source, "disconnected": done}
    else:
        done = args.system.disconnect_ports(args.source, args.sink)
        doc = {"source": args.source, "sink": args.sink, "disconnected": done}
    out(dump(doc) if args.json else ("disconnected" if done else "were not connected"))
    return 0 if done else 1
