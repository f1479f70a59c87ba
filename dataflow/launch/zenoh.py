"""The ``--zenoh`` options of ``scart deploy``, ``ls`` and ``echo`` (see
:mod:`dataflow.transports.zenoh`): the Zenoh session they say, how many peers it reached,
and why a peer may have refused it, in a user's words (:func:`plain_error`)."""

from __future__ import annotations

import argparse
import socket
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import zenoh

    from scart_wire.security import Security

__all__ = ["add_arguments", "peers", "plain_error", "refusal_hint", "session_of"]


def add_arguments(parser: argparse.ArgumentParser, what: str) -> None:
    """``--zenoh`` (``what`` it does), ``--zenoh-connect/--zenoh-listen EP`` (repeatable),
    ``--zenoh-ns NAME``, ``--zenoh-insecure``."""
    group = parser.add_argument_group("Zenoh (pip install 'scart[zenoh]')")
    group.add_argument("--zenoh", action="store_true", help=what)
    group.add_argument("--zenoh-connect", action="append", default=[], metavar="EP",
                       help="a Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 or unixsock-stream/PATH "
                            "(what scart deploy --zenoh prints)")
    group.add_argument("--zenoh-listen", action="append", default=[], metavar="EP",
                       help="a Zenoh endpoint to listen on (default: loopback, a free port)")
    group.add_argument("--zenoh-ns", default="default", metavar="NAME",
                       help="the namespace word of the keys scart/NAME/COMPONENT/PORT (default 'default')")
    group.add_argument("--zenoh-insecure", action="store_true",
                       help="allow routable endpoints and gossip scouting (scart does not encrypt Zenoh traffic)")


def session_of(args: argparse.Namespace, serve: bool = False,
               security: Security | None = None) -> tuple[zenoh.Session, list[str]]:
    """The Zenoh session the options say and the endpoints it listens on. ``serve``
    (``scart deploy``): a peer, listening (on a free loopback port when no endpoint is
    given, so it can be printed); else a client of the endpoints given (``ls``, ``echo``),
    or a peer when told to listen. ``security``: the command's tokens (see
    :func:`~dataflow.transports.zenoh.open_session`). Raises ``ValueError`` with
    what to install or fix."""
    try:
        import zenoh  # noqa: F401

        from dataflow.transports.zenoh import key_of, open_session
    except ImportError:
        raise ValueError("--zenoh needs the Zenoh package: pip install 'scart[zenoh]'") from None
    key_of(args.zenoh_ns, "x")  # a plain key chunk: said before anything opens
    if not serve and not args.zenoh_listen:
        if not args.zenoh_connect:
            raise ValueError("nowhere to look: give --zenoh-connect ENDPOINT (scart deploy --zenoh prints where "
                             "it listens)")
        return open_session(args.zenoh_connect, insecure=args.zenoh_insecure, mode="client", security=security), []
    listen = list(args.zenoh_listen) or [f"tcp/127.0.0.1:{_free_port()}"]
    return open_session(args.zenoh_connect, listen, insecure=args.zenoh_insecure, security=security), listen


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def peers(session: zenoh.Session) -> int:
    """How many Zenoh peers and routers the session reached."""
    info = session.info
    return len(list(info.peers_zid())) + len(list(info.routers_zid()))


def refusal_hint(security: Security) -> str:
    """Why a peer may have refused this command's session (Zenoh says only that it could
    not connect): scart tokens on one end of the link and not on the other."""
    if security.token:
        return ("; this command presents its token (SCART_TOKEN / --token-file), which only a peer that checks "
                "tokens (--auth-file) admits, and only an operate or admin one")
    return "; a peer that checks tokens (--auth-file) admits only a command given one (SCART_TOKEN / --token-file)"


def plain_error(text: str) -> str:
    """``text`` with Rust source paths (``/x/y.rs:12``, ``src/z.rs:3:4``) and the words
    around them removed (Zenoh's error text carries the Rust source location: ``at
    /home/.../src/x.rs:12.``, or a ``[path.rs:12]`` prefix; a user needs what went wrong)."""
    import re

    cleaned = re.sub(r"\s*\bat\s+\S+\.rs(:\d+)+\.?", "", text)
    cleaned = re.sub(r"\[?\S+\.rs(:\d+)+\]?:?\s*", "", cleaned)
    return " ".join(cleaned.split()).strip() or text
