"""The ROS options of the verbs that start a process holding ports (``scart deploy``,
``scart run``): shorthands setting this process's defaults for its one ROS 1 node (see
:mod:`dataflow.transports.ros1.transport`), which its ``ros1`` streams then use, and
ending the process when a peer shuts that node down (:func:`exit_on_shutdown`); and
``scart call ros1:/service`` or ``ros2:/service`` (:func:`call`)."""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from collections.abc import Iterable
from typing import Any

__all__ = ["add_arguments", "apply", "attach", "call", "detach", "exit_on_shutdown", "hold", "split_params",
           "split_remaps", "unhold"]

#: A launch-time parameter, as on a ROS command line: ``_TASK/PROPERTY:=VALUE`` (YAML).
PARAM = re.compile(r"_([A-Za-z][\w/]*):=(.*)\Z", re.S)
MAX_PARAMS = 256
SIM_TIME = "use_sim_time"  #: the node's own launch-time parameter (the others are task properties)


def split_params(items: Iterable[str]) -> tuple[list[str], dict[str, object]]:
    """``items`` apart from the launch-time parameters among them, and those parameters
    (``_TASK/PROP:=VALUE``, the value read as YAML, as ROS reads it). Raises ``ValueError``."""
    import yaml

    rest: list[str] = []
    params: dict[str, object] = {}
    for item in items:
        match = PARAM.match(item)
        if match is None:
            rest.append(item)
            continue
        try:
            params[match.group(1)] = yaml.safe_load(match.group(2))
        except yaml.YAMLError as exc:
            raise ValueError(f"ROS parameter {item[:80]!r}: the value is not YAML: {exc}") from None
    if len(params) > MAX_PARAMS:
        raise ValueError(f"{len(params)} ROS parameters: at most {MAX_PARAMS}")
    return rest, params


def add_arguments(parser: argparse.ArgumentParser, calls: bool = False) -> None:
    """``--ros-master URI``, ``--ros-name NAME``, ``--ros-namespace NS`` (with
    ``--insecure``, the security options' flag, the node listens on every interface
    instead of loopback); with ``calls`` (``scart call``), ``--msgs FILE``."""
    group = parser.add_argument_group("ROS (streams with transport ros1 or ros2)")
    if calls:
        group.add_argument("--msgs", action="append", default=[], metavar="FILE",
                           help="a .srv or .msg file of the service's type and of the types it uses "
                                "(.../PACKAGE/srv/TYPE.srv; repeatable or comma-separated; ROS_PACKAGE_PATH is "
                                "searched too)")
    else:
        group.add_argument("--ros-read-only", action="store_true",
                           help="serve ROS read-only: publish output ports only; no stream into an input port, no "
                                "ROS service, no parameter set, no shutdown from ROS (which authenticates no one)")
    group.add_argument("--ros-master", default=None, metavar="URI",
                       help="the ROS master of this process's ROS 1 node (default $ROS_MASTER_URI, else "
                            "http://localhost:11311/)")
    group.add_argument("--ros-name", default=None, metavar="NAME",
                       help="this process's ROS node name, ROS 1 and ROS 2 (default scart_PID)")
    group.add_argument("--ros-namespace", default=None, metavar="NS",
                       help="this process's ROS node namespace, ROS 1 and ROS 2 (default $ROS_NAMESPACE, else /)")


def add_params(parser: argparse.ArgumentParser, dest: str = "ros_params") -> None:
    """The launch-time ROS parameters: positional arguments ``_TASK/PROPERTY:=VALUE``
    (``scart run``), also after the options, as on a ROS command line (the parser's
    ``take_extras``)."""
    parser.add_argument(dest, nargs="*", default=[], metavar="_TASK/PROPERTY:=VALUE",
                        help="set a task's property at launch, as a ROS node's private parameter (its ROS 1 "
                             "parameter ~TASK/PROPERTY; the value is YAML); _PROPERTY:=VALUE when one task "
                             "has it; _use_sim_time:=true: the node follows /clock from its start")
    take_params(parser, dest)


def take_params(parser: argparse.ArgumentParser, dest: str) -> None:
    """Let ``parser`` take ``_TASK/PROPERTY:=VALUE`` words that follow its options too,
    into the list ``dest`` (argparse takes positionals only before them)."""
    def take(args: argparse.Namespace, extras: list[str]) -> list[str]:
        taken = [e for e in extras if PARAM.match(e)]
        setattr(args, dest, [*getattr(args, dest), *taken])
        return [e for e in extras if not PARAM.match(e)]

    parser.set_defaults(take_extras=take)


def split_remaps(rules: Iterable[str]) -> tuple[list[str], dict[str, str]]:
    """``--remap`` rules apart from the ROS names among them (``/FROM:=/TO``, or ``=``: a
    global or private ROS name, as on a ROS command line), and those as a mapping."""
    rest, names = [], {}
    for rule in rules:
        old, sep, new = rule.partition(":=") if ":=" in rule else rule.partition("=")
        if sep and old.strip().startswith(("/", "~")):
            names[old.strip()] = new.strip()
        else:
            rest.append(rule)
    return rest, names


def _sim_time(params: dict[str, object]) -> bool | None:
    """Take the node's own launch-time ``_use_sim_time:=BOOL`` out of ``params`` (None when
    not given); raises ``ValueError`` for a value that is no bool."""
    if SIM_TIME not in params:
        return None
    value = params.pop(SIM_TIME)
    if not isinstance(value, bool):
        raise ValueError(f"ROS parameter _{SIM_TIME}:={value!r}: true or false")
    return value


def apply(args: argparse.Namespace, params: dict[str, object] | None = None,
          remaps: dict[str, str] | None = None) -> None:
    """Set the process's ROS defaults from ``args``, the launch-time ``params`` (the node's
    own ``use_sim_time`` among them, for ROS 1 and ROS 2; the rest task properties) and
    the ROS name ``remaps`` (nothing is loaded unless one is given). Raises ``ValueError``
    for a bad URI, name, remap or ``use_sim_time``."""
    master, name = getattr(args, "ros_master", None), getattr(args, "ros_name", None)
    namespace = getattr(args, "ros_namespace", None)
    insecure = bool(getattr(args, "insecure", False))
    read_only = True if getattr(args, "ros_read_only", False) else None
    params = dict(params or {})
    sim_time = _sim_time(params)
    if master is None and name is None and namespace is None and not insecure and not params and not remaps \
            and not read_only and sim_time is None:
        return
    from dataflow.transports import load

    transport = load("ros1")
    configure = getattr(transport, "configure", None)
    if configure is not None:
        configure(master=master, name=name, namespace=namespace, insecure=insecure or None, params=params or None,
                  remaps=remaps or None, read_only=read_only, use_sim_time=sim_time)
    if name is not None or namespace is not None or remaps or read_only or sim_time is not None:  # ROS 2's too
        configure = getattr(_transport("ros2"), "configure", None)  # (no Cyclone DDS loaded)
        if configure is not None:
            configure(name=name, namespace=namespace, remaps=remaps or None, read_only=read_only,
                      use_sim_time=sim_time)


def _add_types(kind: str, files: list[str]) -> None:
    """Add the types defined in ``files`` to the process's ``kind`` (``ros1``/``ros2``)
    transport; raises ``ValueError`` naming a bad file."""
    if not files:
        return
    if kind == "ros2":
        from dataflow.transports.ros2._transport import add_type_file

        types = _transport("ros2").types
        for path in files:
            add_type_file(types, path, ("msg", "srv"))
        return
    from scart_ros1 import TypeDefinitionError

    for path in files:
        try:
            _transport("ros1").types.add_file(path)
        except TypeDefinitionError as exc:
            raise ValueError(f"--msgs {exc}") from None


def _transport(name: str) -> Any:  # Any: the ROS transports' own attributes (types, configure, attach)
    from dataflow.transports import TransportError, load

    try:
        return load(name)
    except TransportError:
        return None


def attach(deployer: object) -> None:
    """Make this process's ROS nodes (now, or when a stream, a service or :func:`hold`
    makes one) speak for ``deployer``'s tasks: their properties its parameters, its log on
    /rosout. Raises ``ValueError`` (a launch-time parameter refused)."""
    for name in ("ros1", "ros2"):
        transport = _transport(name)
        if hasattr(transport, "attach"):
            transport.attach(deployer)


def hold() -> None:
    """Make this process's ROS 1 node now, when the process was told it is a ROS node
    (``--ros-*`` options, launch-time parameters), and keep it until :func:`unhold`. Call
    once everything of the process's own has started. Raises the transport's error."""
    hold = getattr(_transport("ros1"), "hold", None)
    if hold is not None:
        hold()


def unhold() -> None:
    """Undo :func:`hold` (idempotent)."""
    unhold = getattr(_transport("ros1"), "unhold", None)
    if unhold is not None:
        unhold()


def detach(deployer: object) -> None:
    """Undo :func:`attach` (idempotent)."""
    for name in ("ros2", "ros1"):
        transport = _transport(name)
        if hasattr(transport, "detach"):
            transport.detach(deployer)


def exit_on_shutdown(prog: str) -> None:
    """When a peer shuts this process's ROS 1 node down (``rosnode kill``, the Slave API's
    ``shutdown``), say who asked and stop the process as SIGTERM does (a clean stop):
    rospy ends its process then. For a verb that owns its process (``run``, ``deploy``)."""
    on_shutdown = getattr(_transport("ros1"), "on_shutdown", None)
    if on_shutdown is None:
        return

    def stop(node: str, caller_id: str, reason: str) -> None:
        print(f"{prog}: the ROS node {node} was shut down by {caller_id} ({reason or 'no reason given'}): stopping",
              file=sys.stderr, flush=True)
        os.kill(os.getpid(), signal.SIGTERM)

    on_shutdown(stop)


def call(args: argparse.Namespace, json_args: list[object]) -> object:
    """``scart call ros1:/service|ros2:/service ['{"field": value}'] [--type pkg/Srv]``: the
    response as plain data. Raises ``ValueError`` saying what went wrong (no such service,
    its error, a request that is not one object of its fields, a ROS 2 call without
    ``--type``)."""
    kind, _, service = args.operation.partition(":")
    if len(json_args) > 1 or (json_args and not isinstance(json_args[0], dict)):
        raise ValueError("a ROS service takes one object of its request's fields, e.g. '{data: true}'")
    request = json_args[0] if json_args else {}
    _add_types(kind, [f.strip() for item in getattr(args, "msgs", None) or [] for f in item.split(",") if f.strip()])
    if kind == "ros2":
        from dataflow.transports.ros2 import call_service as call_ros2

        if not args.type:
            raise ValueError("a ROS 2 service needs --type pkg/srv/Type (ROS 2 cannot be asked it)")
        return call_ros2(service, request, type_name=args.type, timeout=args.timeout)
    from dataflow.transports.ros1.calls import call_service
    from scart_ros1.services import ServiceError

    apply(args)
    try:
        return call_service(service, request, type_name=args.type, timeout=args.timeout)
    except (ServiceError, TypeError, LookupError) as exc:
        raise ValueError(str(exc)) from None
