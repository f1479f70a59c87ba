"""The ROS options of the verbs that start a process holding ports (``scart deploy``,
``scart run``): shorthands setting this process's defaults for its one ROS 1 node (see
:mod:`dataflow.transports.ros1.transport`), which its ``ros1`` streams then use, and
ending the process when a peer shuts that node down (:func:`exit_on_shutdown`); and
``scart call ros1:/service`` or ``ros2:/service`` (:func:`call`)."""

from __future__ import annotations

import argparse
import os
import signal
import sys
from typing import Any

__all__ = ["add_arguments", "apply", "call", "exit_on_shutdown"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--ros-master URI``, ``--ros-name NAME``, ``--ros-namespace NS`` (with
    ``--insecure``, the security options' flag, the node listens on every interface
    instead of loopback)."""
    group = parser.add_argument_group("ROS (streams with transport ros1 or ros2)")
    group.add_argument("--ros-master", default=None, metavar="URI",
                       help="the ROS master of this process's ROS 1 node (default $ROS_MASTER_URI, else "
                            "http://localhost:11311/)")
    group.add_argument("--ros-name", default=None, metavar="NAME",
                       help="this process's ROS node name, ROS 1 and ROS 2 (default scart_PID)")
    group.add_argument("--ros-namespace", default=None, metavar="NS",
                       help="this process's ROS node namespace, ROS 1 and ROS 2 (default $ROS_NAMESPACE, else /)")


def apply(args: argparse.Namespace) -> None:
    """Set the process's ROS defaults from ``args`` (nothing is loaded unless one is given).
    Raises ``ValueError`` for a bad URI or name."""
    master, name = getattr(args, "ros_master", None), getattr(args, "ros_name", None)
    namespace = getattr(args, "ros_namespace", None)
    insecure = bool(getattr(args, "insecure", False))
    if master is None and name is None and namespace is None and not insecure:
        return
    from dataflow.transports import load

    transport = load("ros1")
    configure = getattr(transport, "configure", None)
    if configure is not None:
        configure(master=master, name=name, namespace=namespace, insecure=insecure or None)


def exit_on_shutdown(prog: str) -> None:
    """When a peer shuts this process's ROS 1 node down (``rosnode kill``, the Slave API's
    ``shutdown``), say who asked and stop the process as SIGTERM does (a clean stop):
    rospy ends its process then. For a verb that owns its process (``run``, ``deploy``)."""
    from dataflow.transports import TransportError, load

    try:
        on_shutdown = getattr(load("ros1"), "on_shutdown", None)
    except TransportError:
        return
    if on_shutdown is None:
        return

    def stop(node: str, caller_id: str, reason: str) -> None:
        print(f"{prog}: the ROS node {node} was shut down by {caller_id} ({reason or 'no reason given'}): stopping",
              file=sys.stderr, flush=True)
        os.kill(os.getpid(), signal.SIGTERM)

    on_shutdown(stop)


def call(args: argparse.Namespace, json_args: list[Any]) -> Any:
    """``scart call ros1:/service|ros2:/service ['{"field": value}'] [--type pkg/Srv]``: the
    response as plain data. Raises ``ValueError`` saying what went wrong (no such service,
    its error, a request that is not one object of its fields, a ROS 2 call without
    ``--type``)."""
    kind, _, service = args.operation.partition(":")
    if len(json_args) > 1 or (json_args and not isinstance(json_args[0], dict)):
        raise ValueError("a ROS service takes one object of its request's fields, e.g. '{data: true}'")
    request = json_args[0] if json_args else {}
    if kind == "ros2":
        from dataflow.transports.ros2 import call_service as call_ros2

        if not args.type:
            raise ValueError("a ROS 2 service needs --type pkg/srv/Type (ROS 2 cannot be asked it)")
        return call_ros2(service, request, type_name=args.type, timeout=args.timeout)
    from dataflow.transports.ros1.calls import call_service
    from dataflow.transports.ros1.services import ServiceError

    apply(args)
    try:
        return call_service(service, request, type_name=args.type, timeout=args.timeout)
    except (ServiceError, TypeError, LookupError) as exc:
        raise ValueError(str(exc)) from None
