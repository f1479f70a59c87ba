"""``scart state COMP [TRANSITION]``: show a task's lifecycle state, or change it (exit 1
when the task refuses the transition)."""

from __future__ import annotations

import argparse

from dataflow.cli.connected import with_system
from dataflow.remote.api import TRANSITIONS
from scart_wire.console import add_common, dump, err, out

HELP = "show or change a component's lifecycle state"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``COMP [TRANSITION]`` and the common options."""
    parser.add_argument("component")
    parser.add_argument("transition", nargs="?", choices=TRANSITIONS)
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Show or change the state; 1 when refused."""
    return with_system(args, _state)


def _state(args: argparse.Namespace) -> int:
    proxy = args.system.component(args.component)
    accepted = True
    if args.transition:
        accepted = proxy.change_state(args.transition)
    state = proxy.state
    if args.json:
        doc: dict[str, object] = {"component": args.component, "state": state}
        if args.transition:
            doc.update(transition=args.transition, accepted=accepted)
        out(dump(doc))
    else:
        out(state)
    if not accepted:
        err(f"state: {args.component} refused {args.transition} (state {state})")
        return 1
    return 0
