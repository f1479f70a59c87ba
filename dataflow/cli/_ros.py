"""The ROS options of the verbs that start a process holding ports (``scart deploy``,
``scart run``): shorthands setting this process's defaults for its one ROS 1 node (see
:mod:`dataflow.transports.ros1.transport`), which its ``ros1`` streams then use."""

from __future__ import annotations

import argparse

__all__ = ["add_arguments", "apply"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--ros-master URI`` and ``--ros-name NAME`` (with ``--insecure``, the security
    options' flag, the node listens on every interface instead of loopback)."""
    group = parser.add_argument_group("ROS 1 (streams with transport ros1)")
    group.add_argument("--ros-master", default=None, metavar="URI",
                       help="the ROS master of this process's node (default $ROS_MASTER_URI, else "
                            "http://localhost:11311/)")
    group.add_argument("--ros-name", default=None, metavar="NAME",
                       help="this process's ROS node name (default scart_PID)")


def apply(args: argparse.Namespace) -> None:
    """Set the process's ROS defaults from ``args`` (nothing is loaded unless one is given).
    Raises ``ValueError`` for a bad URI or name."""
    master, name = getattr(args, "ros_master", None), getattr(args, "ros_name", None)
    insecure = bool(getattr(args, "insecure", False))
    if master is None and name is None and not insecure:
        return
    from dataflow.transports import load

    transport = load("ros1")
    configure = getattr(transport, "configure", None)
    if configure is not None:
        configure(master=master, name=name, insecure=insecure or None)
