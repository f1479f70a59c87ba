"""``scart foxglove [--host H] [--port P]``: every output port live in the Foxglove app
(the server is :class:`dataflow.cli.foxglove.FoxgloveLive`; see there)."""

from __future__ import annotations

import argparse

from dataflow.cli.output import add_common, with_system

HELP = "serve every output port live to the Foxglove app (WebSocket protocol)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Where to listen, how often to look for tasks, and the common options."""
    parser.add_argument("--host", default="127.0.0.1", help="where to listen (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8765, help="port (default 8765; 0: a free one)")
    parser.add_argument("--refresh", type=float, default=2.0, help="look for new tasks every this many seconds")
    parser.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    parser.add_argument("--insecure-host", "--insecure", dest="insecure_host", action="store_true",
                        help="allow a routable --host (no authentication: warned, and read-only)")
    parser.add_argument("--control", "--foxglove-control", dest="control", nargs="?", const="", default=None,
                        metavar="TOKEN_FILE", help="writable: parameters can be set and operations called, acting with "
                                                   "the 'operate' token in TOKEN_FILE (default: read-only)")
    parser.add_argument("--auth-file", default=None, metavar="PATH",
                        help="the tokens the deployers check ($SCART_AUTH_FILE): the control token's role is checked "
                             "against it, and a viewer must present one of them (?token= in the URL)")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C or ``--duration``."""
    from dataflow.cli.foxglove import cmd_foxglove

    return with_system(args, cmd_foxglove)
