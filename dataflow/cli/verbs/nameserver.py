"""``scart nameserver [--listen HOST:PORT]``: a standalone name service until Ctrl-C or
SIGTERM. Readiness: one stderr line ``scart nameserver: serving on HOST:PORT``."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import TYPE_CHECKING

from scart_wire.defaults import DEFAULT_LEASE, DEFAULT_NS_ADDRESS
from scart_wire.security import add_arguments as add_security

if TYPE_CHECKING:
    from types import FrameType

HELP = "run a standalone name service until Ctrl-C"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--listen``, ``--lease`` and the server's security options."""
    parser.add_argument("--listen", default=DEFAULT_NS_ADDRESS, help=f"HOST:PORT (default {DEFAULT_NS_ADDRESS})")
    parser.add_argument("--lease", type=float, default=DEFAULT_LEASE, help="default lease (s)")
    add_security(parser, server=True, client=False)


def main(args: argparse.Namespace) -> int:
    """Serve until SIGINT/SIGTERM; 1 when it cannot listen."""
    from dataflow import DataflowError
    from dataflow.remote.naming import serve_nameserver
    from scart_wire.security import from_args

    stop = threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    try:
        server = serve_nameserver(args.listen, default_lease=args.lease, security=from_args(args))
    except DataflowError as exc:
        print(f"scart nameserver: {exc}", file=sys.stderr, flush=True)
        return 1
    print(f"scart nameserver: serving on {server.listen_address}", file=sys.stderr, flush=True)
    try:
        while not stop.wait(1.0):
            pass
    finally:
        server.stop()
    return 0
