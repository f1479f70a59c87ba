"""What the data-flow verbs share beside the output module (:mod:`scart_wire.console`):
running a verb's body connected, to a system through the name service (:func:`with_system`)
or on a Zenoh session (:func:`with_session`, ``--zenoh``: no name service involved), every
error it can meet one stderr line and exit 1. The Zenoh session itself is the library's
(:mod:`dataflow.launch.zenoh`); this module imports no verb, and nothing heavy until a
verb runs."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from scart_wire.console import err, with_client

__all__ = ["with_session", "with_system"]


def with_system(args: argparse.Namespace, body: Callable[[argparse.Namespace], int]) -> int:
    """Run a verb's ``body`` with ``args.system``, a proxy of the system the name service
    knows (:func:`dataflow.remote.connect`; see :func:`scart_wire.console.with_client`)."""
    from dataflow.remote import connect

    return with_client(args, connect, body)


def with_session(args: argparse.Namespace, body: Callable[[argparse.Namespace], int]) -> int:
    """Run a verb's ``body`` with ``args.zenoh_session`` open (no name service involved);
    every error it can meet, Zenoh's own included, becomes one stderr line and exit 1."""
    from dataflow import DataflowError
    from dataflow.launch.zenoh import peers, plain_error, refusal_hint, session_of
    from scart_wire.security import from_args

    try:
        security = from_args(args)
    except DataflowError as exc:  # unusable security files
        err(f"{args.command}: {exc}")
        return 1
    try:
        args.zenoh_session, _ = session_of(args, security=security)
    except (ValueError, DataflowError) as exc:  # ours: a bad endpoint, namespace or auth file, a missing package
        err(f"{args.command}: --zenoh: {exc}")
        return 1
    except Exception as exc:  # noqa: BLE001 - Zenoh's own errors: nothing reached, perhaps refused
        err(f"{args.command}: --zenoh: {plain_error(str(exc))}{refusal_hint(security)}")
        return 1
    try:
        if not peers(args.zenoh_session):
            err(f"{args.command}: --zenoh: no Zenoh peer reached; give --zenoh-connect ENDPOINT "
                f"(scart deploy --zenoh prints where it listens){refusal_hint(security)}")
            if args.command == "ls":
                return 1
        return body(args)
    except Exception as exc:  # noqa: BLE001 - Zenoh's own errors too: one line, exit 1
        err(f"{args.command}: {plain_error(str(exc))}")
        return 1
    finally:
        args.zenoh_session.close()
