"""``scart call TARGET.op ARGS...``: call an operation and print its result as JSON.

``TARGET`` is a data-flow task (its ``@operation``), else an SCA service that a ``scart
run`` registered with the name service: ``Component/Service``, a promoted service, or a
single-service component's name (``scart call Locomotor.poses``). ``--at HOST:PORT`` (or
``SCART_SERVICES``) calls the SCA service served there, without the name service.
``ros1:/service`` and ``ros2:/service`` call a ROS service (one object of its request's
fields; ``--type`` its type, which ROS 1 can also tell itself). Arguments are JSON or YAML
(a bare word is a string)."""

from __future__ import annotations

import argparse

from dataflow.cli.output import add_common, dump, jsonable, out, parse_value, with_system
from scart.commands._sca import SERVICES_ENV, at, call, find, split_target, with_services

HELP = "call a task's operation or an SCA service's, with JSON or YAML arguments"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The target, its arguments, ``--at`` and the common options."""
    parser.add_argument("operation", metavar="COMP.OP|COMPONENT/SERVICE.op|ros1:/service|ros2:/service")
    parser.add_argument("args", nargs="*", help="arguments: JSON or YAML each (a ROS service: one object of "
                                                "its request's fields)")
    parser.add_argument("--at", default=None, metavar="HOST:PORT",
                        help="call the SCA service served there, without the name service (scart run prints it: "
                             f"'SCA services at ...'; or ${SERVICES_ENV})")
    parser.add_argument("--type", default=None, metavar="pkg/Srv",
                        help="a ROS service's type (ROS 1: default, asked of the service as rosservice does)")
    from dataflow.cli import _ros as ros_args

    ros_args.add_arguments(parser, calls=True)
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Call; 1 when the target is unknown, refuses or raises."""
    if args.operation.startswith(("ros1:", "ros2:")):  # a ROS service: found through ROS, no name service
        return with_services(args, lambda a: _print(a, _ros_call(a)))
    address = at(args)
    if address is not None:
        return with_services(args, lambda a: _print(a, call(address, a.operation, _arguments(a), a)))
    return with_system(args, _call)


def _arguments(args: argparse.Namespace) -> list[object]:
    return [parse_value(a) for a in args.args]


def _print(args: argparse.Namespace, result: object) -> int:
    out(dump(result))
    return 0


def _call(args: argparse.Namespace) -> int:
    """A task's operation when a task has that name, else an SCA service found by name."""
    name, operation = split_target(args.operation)
    if name in args.system.component_names():
        result = args.system.component(name).call_json(operation, _arguments(args), timeout=args.timeout)
        return _print(args, jsonable(result))
    return _print(args, call(find(name, args), args.operation, _arguments(args), args))


def _ros_call(args: argparse.Namespace) -> object:
    """``ros1:/service`` or ``ros2:/service``: the response as plain data."""
    from dataflow.cli import _ros as ros_args

    return jsonable(ros_args.call(args, _arguments(args)))
