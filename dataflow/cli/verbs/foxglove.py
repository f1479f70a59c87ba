"""``scart foxglove [--host H] [--port P]``: every output port live in the Foxglove app
(the server is :class:`dataflow.foxglove.server.FoxgloveLive`; see there)."""

from __future__ import annotations

import argparse
import threading
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, err, ns_address, wait_until_stopped

if TYPE_CHECKING:
    from dataflow.foxglove.server import FoxgloveLive

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
    return with_system(args, _serve)


def _serve(args: argparse.Namespace) -> int:
    """``scart foxglove [--host H] [--port P] [--control [TOKEN_FILE]] [--auth-file AUTH]``
    with ``args.system`` connected: serve, print the URL, wait."""
    import dataclasses

    from dataflow.foxglove.server import FoxgloveLive, control_token
    from dataflow.remote import connect
    from scart_wire.security import from_args

    control = None
    security = from_args(args)
    if args.control is not None:
        token = control_token(args.control or None, security, "--control", ns=ns_address(args))
        control = connect(ns_address(args), timeout=args.timeout, security=dataclasses.replace(security, token=token))
    try:
        live = FoxgloveLive(args.system, args.host, args.port, args.refresh, args.insecure_host, control=control,
                            auth_file=security.auth_file)
    except BaseException:
        if control is not None:
            control.close()
        raise
    if not _started(live, args):
        return 1
    try:
        print(f"scart: Foxglove at {live.url} ({live.channels} channel(s), "
              f"{'writable' if live.writable else 'read-only'})", flush=True)
        err(f"foxglove: open {live.url} in the Foxglove app; Ctrl-C to stop")
        wait_until_stopped(threading.Event(), args.duration)
    finally:
        live.stop()
    return 0


def _started(live: FoxgloveLive, args: argparse.Namespace) -> bool:
    """Start ``live``; False (said on stderr) when the port is taken or the server behind
    the gate could not be kept private."""
    import errno

    from dataflow.foxglove.inner_guard import GuardError

    try:
        live.start()
    except OSError as exc:
        why = "the port is in use" if exc.errno == errno.EADDRINUSE else (exc.strerror or str(exc))
        err(f"foxglove: {exc}" if isinstance(exc, GuardError) else
            f"foxglove: cannot listen on {args.host}:{args.port}: {why}; choose another --port (0: a free one)")
        return False
    return True
