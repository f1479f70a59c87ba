"""``scart disconnect LINK`` or ``scart disconnect A.out B.in``: undo a link (exit 1 when
there was none), saying how many samples written were never delivered to the sink's
task (it may read what its buffer holds first, 1 s at most)."""

from __future__ import annotations

import argparse

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, out

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
        lost = args.system.disconnect_link_counted(args.source)
        doc: dict[str, object] = {"name": args.source}
    else:
        lost = args.system.disconnect_counted(args.source, args.sink)
        doc = {"source": args.source, "sink": args.sink}
    doc.update(disconnected=lost is not None, undelivered=lost or 0)
    if args.json:
        out(dump(doc))
    elif lost is None:
        out("were not connected")
    else:
        out(f"disconnected: {lost} sample(s) written were never delivered" if lost else
            "disconnected: every sample written was delivered")
    return 0 if lost is not None else 1
