"""``scart stream COMP.PORT TRANSPORT:TOPIC [--policy P] [--type T] [--option K=V]``: join
a port to a named topic of a transport (a stream; its deployer makes it). Undone with
``scart disconnect NAME``; listed by ``scart links``."""

from __future__ import annotations

import argparse

from dataflow.cli.connected import with_system
from dataflow.policy import ConnPolicy
from scart_wire.console import add_common, dump, out

HELP = "join a port to a topic of a transport (zenoh, ros1, ros2...): a stream"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The port, ``TRANSPORT:TOPIC``, the policy, the transport's options, the common options."""
    parser.add_argument("port", metavar="COMP.PORT")
    parser.add_argument("topic", metavar="TRANSPORT:TOPIC")
    parser.add_argument("--policy", default="data", help="data | buffer:N | circular:N (default data)")
    parser.add_argument("--type", default=None, help="the topic's message type, for a transport with its own (ROS)")
    parser.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                        help="what the transport needs besides (e.g. connect=tcp/127.0.0.1:7447 for zenoh)")
    parser.add_argument("--name", default=None, help="the stream's name (default COMP.PORT~TRANSPORT:TOPIC)")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Make the stream; 1 when refused (no such port, a transport without topics, a bad topic)."""
    return with_system(args, cmd_stream)


def cmd_stream(args: argparse.Namespace) -> int:
    """``scart stream COMP.PORT TRANSPORT:TOPIC``."""
    transport, colon, topic = args.topic.partition(":")
    if not colon or not topic:
        raise ValueError(f"{args.topic!r}: expected TRANSPORT:TOPIC, e.g. zenoh:robot/status or ros1:/joint_states")
    options = dict(_option(o) for o in args.option)
    if args.type:
        options["type"] = args.type
    policy = ConnPolicy.parse(args.policy).with_(transport=transport, topic=topic)
    link = args.system.stream(args.port, policy, options, name=args.name)
    out(dump(link.model_dump()) if args.json else f"streaming {link.source} -> {link.sink} ({link.policy}) "
        f"as {link.name}")
    return 0


def _option(text: str) -> tuple[str, str]:
    key, eq, value = text.partition("=")
    if not eq or not key:
        raise ValueError(f"--option {text!r}: expected KEY=VALUE")
    return key, value
