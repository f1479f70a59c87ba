"""``scart call TARGET.op ARGS...``: call an operation and print its result as JSON.

``TARGET`` is a data-flow task (its ``@operation``), else an SCA service that a ``scart
run`` registered with the name service: ``Component/Service``, a promoted service, or a
single-service component's name (``scart call Locomotor.poses``). ``--at HOST:PORT`` (or
``SCART_SERVICES``) calls the SCA service served there, without the name service.
``ros1:/service`` and ``ros2:/service`` call a ROS service (one object of its request's
fields; ``--type`` its type, which ROS 1 can also tell itself); ``yarp:/port`` a YARP RPC
port (the arguments are the bottle: ``scart call yarp:/arm/rpc scale 2``). Arguments are
JSON or YAML (a bare word is a string): in order, or as one mapping of the arguments by
name, as ``ros2 service call`` takes its request (``scart call Filter.scale '{pose: {x:
1}, factor: 2}'``). A value the operation's declaration refuses, a missing or unknown
argument, an unknown target and an operation that raises all exit 1 with one line, as
``write`` does for a refused value; a result is printed as it is (``false`` too), exit 0."""

from __future__ import annotations

import argparse

from scart.commands._sca import SERVICES_ENV, at, call, find, list_services, split_target, with_services
from scart_wire.console import add_common, address_arg, dump, err, jsonable, out, parse_value, with_client

HELP = "call a task's operation or an SCA service's, with JSON or YAML arguments"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The target, its arguments, ``--at`` and the common options."""
    parser.add_argument("operation", metavar="COMP.OP|COMPONENT/SERVICE.op|ros1:/service|ros2:/service|yarp:/port")
    parser.add_argument("args", nargs="*", help="arguments: JSON or YAML each (a ROS service: one object of "
                                                "its request's fields)")
    parser.add_argument("--at", default=None, metavar="HOST:PORT", type=address_arg,
                        help="call the SCA service served there, without the name service (scart run prints it: "
                             f"'SCA services at ...'; or ${SERVICES_ENV})")
    parser.add_argument("--type", default=None, metavar="pkg/Srv",
                        help="a ROS service's type (ROS 1: default, asked of the service as rosservice does)")
    from dataflow.launch import ros as ros_args
    from dataflow.launch import yarp as yarp_args

    ros_args.add_arguments(parser, calls=True)
    yarp_args.add_arguments(parser)
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Call; 1 when the target is unknown, refuses or raises."""
    if args.operation.startswith(("ros1:", "ros2:")):  # a ROS service: found through ROS, no name service
        return with_services(args, lambda a: _print(a, _ros_call(a)))
    if args.operation.startswith("yarp:"):  # a YARP RPC port: found through YARP's name server
        return with_services(args, lambda a: _print(a, _yarp_call(a)))
    try:
        address = at(args)
    except ValueError as exc:
        err(f"call: {exc}")
        return 2
    if address is not None:
        return with_services(args, lambda a: _print(a, _sca_call(address, a, split_target(a.operation)[0])))
    from dataflow.remote import connect  # the data-flow system the name service knows

    return with_client(args, connect, _call)


def _arguments(args: argparse.Namespace) -> list[object]:
    return [parse_value(a) for a in args.args]


def by_name(values: list[object], params: list[str], target: str) -> dict[str, object] | None:
    """The arguments by name when ``values`` is one mapping whose keys name parameters of
    ``params`` (else None: a mapping naming none is one argument's value, a model's
    fields). Raises ``ValueError`` naming what is missing or unknown."""
    if len(values) != 1 or not isinstance(values[0], dict) or not values[0] or not params:
        return None
    named = values[0]
    if not set(named) & set(params):
        return None
    missing = [p for p in params if p not in named]
    unknown = [k for k in named if k not in params]
    if missing or unknown:
        raise ValueError(f"{target}({', '.join(params)}): " + "; ".join(
            [f"missing {', '.join(map(repr, missing))}"] * bool(missing)
            + [f"no argument {', '.join(map(repr, unknown))}"] * bool(unknown)))
    return named


def _sca_call(address: str, args: argparse.Namespace, there: str) -> object:
    """An SCA service's operation at ``address``, where the service is named ``there``;
    one mapping naming its parameters is sent as keyword arguments."""
    values = _arguments(args)
    if len(values) == 1 and isinstance(values[0], dict):
        named = _sca_named(address, there, values[0], args)
        if named is not None:
            return call(address, args.operation, [], args, kwargs=named, there=there)
    return call(address, args.operation, values, args, there=there)


def _sca_named(address: str, service: str, mapping: dict[str, object],
               args: argparse.Namespace) -> dict[str, object] | None:
    """``mapping`` when its keys name parameters of the target operation (as the server
    lists them), else None (then it is one argument)."""
    operation = split_target(args.operation)[1]
    for s in list_services(address, args):
        if service in s["names"]:
            for op in s["operations"]:
                if op["name"] == operation and set(mapping) & set(op.get("params", ())):
                    return mapping  # the server binds them: a missing or unknown one is refused there, named
    return None


def _print(args: argparse.Namespace, result: object) -> int:
    out(dump(result))
    return 0


def _call(args: argparse.Namespace) -> int:
    """A task's operation when a task has that name, else an SCA service found by name."""
    name, operation = split_target(args.operation)
    if name in args.system.component_names():
        proxy = args.system.component(name)
        values = _arguments(args)
        if len(values) == 1 and isinstance(values[0], dict):
            ops = {o.name: o for o in proxy.describe().operations}
            params = [p for p, _ in ops[operation].params] if operation in ops else []
            named = by_name(values, params, args.operation)
            if named is not None:
                values = [named[p] for p in params]
        return _print(args, jsonable(proxy.call_json(operation, values, timeout=args.timeout)))
    address, there = find(name, args)
    return _print(args, _sca_call(address, args, there))


def _yarp_call(args: argparse.Namespace) -> object:
    """``yarp:/port``: the reply bottle as plain data."""
    from dataflow.launch import yarp as yarp_args

    return jsonable(yarp_args.call(args, _arguments(args)))


def _ros_call(args: argparse.Namespace) -> object:
    """``ros1:/service`` or ``ros2:/service``: the response as plain data."""
    from dataflow.launch import ros as ros_args

    return jsonable(ros_args.call(args, _arguments(args)))
