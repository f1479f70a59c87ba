"""``scart links [--sample S] [--subscriptions]``: every link and stream (name, ends,
policy, transport, state, measured rate, drops), or every subscription the deployers serve."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING, TypeVar

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, out, with_rates

if TYPE_CHECKING:
    from dataflow.introspection import LinkDescription, SubscriptionDescription

R = TypeVar("R", "LinkDescription", "SubscriptionDescription")  # a row: a link or a subscription

HELP = "list links and streams: name, ends, policy, transport, state, measured rate, drops"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--sample``, ``--subscriptions`` and the common options."""
    parser.add_argument("--sample", type=float, default=0.25, help="time over which the rate is measured (s)")
    parser.add_argument("--subscriptions", "-s", action="store_true",
                        help="list the subscriptions the deployers serve instead: port, subscriber, policy, "
                             "transport, the port's measured write rate, drops")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """List the links or subscriptions."""
    return with_system(args, cmd_links)


def cmd_links(args: argparse.Namespace) -> int:
    """``scart links``: one line per link; rate measured over ``--sample`` s
    (``--subscriptions``: one line per subscription served: which port goes to whom, over
    which transport (what ``auto`` picked), at what rate, losing how many)."""
    if args.subscriptions:
        return _rated_table(args, args.system.subscriptions, (
            ("source", "SOURCE", "<28"), ("subscriber", "SUBSCRIBER", "<28"), ("policy", "POLICY", "<12"),
            ("transport", "TRANSPORT", "<9"), ("rate", "RATE(Hz)", ">9.1f"), ("dropped", "DROPPED", ">8"),
            ("name", "DEPLOYER", "")))
    return _rated_table(args, args.system.links, (
        ("name", "NAME", "<28"), ("source", "SOURCE", "<28"), ("sink", "SINK", "<28"), ("policy", "POLICY", "<12"),
        ("transport", "TRANSPORT", "<9"), ("state", "STATE", "<9"), ("rate", "RATE(Hz)", ">9.1f"),
        ("dropped", "DROPPED", ">8")))


def _rated_table(args: argparse.Namespace, listing: Callable[[], list[R]],
                 columns: tuple[tuple[str, str, str], ...]) -> int:
    """Each item of ``listing()`` (links, subscriptions) with the rate its ``samples`` grow
    at over ``--sample`` s: JSON rows, or a table of ``columns`` (``(key, header, format)``)."""
    rows = [{**item.model_dump(), "name": item.name, "rate": rate}
            for item, rate in with_rates(listing, lambda item: item.samples, args.sample)]
    if args.json:
        out(dump(rows))
        return 0
    out(" ".join(f"{header:{spec.split('.')[0]}}" for _, header, spec in columns))
    for r in rows:
        out(" ".join(f"{r[key]:{spec}}" for key, _, spec in columns))
    return 0
