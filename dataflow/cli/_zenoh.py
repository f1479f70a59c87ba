"""The ``--zenoh`` options of ``scart deploy``, ``ls`` and ``echo`` (see
:mod:`dataflow.remote.zenoh_transport`)."""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["add_arguments", "session_of"]


def add_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--zenoh`` (``what`` it does), ``--zenoh-connect/--zenoh-listen EP`` (repeatable),
    ``--zenoh-ns NAME``."""
    group = parser.add_argument_group("Zenoh (pip install 'scart[zenoh]')")
    group.add_argument("--zenoh", action="store_true", help=what)
    group.add_argument("--zenoh-connect", action="append", default=[], metavar="EP",
                       help="a Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 or unixsock-stream/PATH")
    group.add_argument("--zenoh-listen", action="append", default=[], metavar="EP",
                       help="a Zenoh endpoint to listen on (default tcp/127.0.0.1:0; a routable one needs --insecure)")
    group.add_argument("--zenoh-ns", default="default", metavar="NAME",
                       help="the namespace word of the keys scart/NAME/COMPONENT/PORT (default 'default')")


def session_of(args: argparse.Namespace) -> Any:
    """The Zenoh session the options say (raises ``ValueError`` with what to install or fix)."""
    try:
        from dataflow.remote.zenoh_transport import open_session
        import zenoh  # noqa: F401
    except ImportError:
        raise ValueError("--zenoh needs the Zenoh package: pip install 'scart[zenoh]'") from None
    return open_session(args.zenoh_connect, args.zenoh_listen, insecure=getattr(args, "insecure", False))
