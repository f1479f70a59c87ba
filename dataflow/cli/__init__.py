"""The data-flow verbs of the ``scart`` command line.

``ls``, ``describe``, ``echo``, ``hz``, ``write``, ``call``, ``prop``, ``state``,
``connect``, ``links``, ``reroute``, ``disconnect`` (:mod:`dataflow.cli.inspect`:
introspection of a running system, through its name service), ``record``, ``play``,
``info`` (:mod:`dataflow.cli.record`: MCAP files) and ``deploy``, ``nameserver``
(:mod:`dataflow.cli.deploy`: host tasks, serve names). They belong to the data-flow
side and never import ``scart``: the ``scart`` command finds them through the
``scart.commands`` entry point naming :func:`register`, as ros2cli finds its verbs.
"""

from __future__ import annotations

import argparse


def register(subparsers: argparse._SubParsersAction) -> None:  # noqa: SLF001
    """Add the data-flow verbs to ``subparsers`` (each sets ``func`` returning the exit code)."""
    from dataflow.cli import deploy, inspect

    inspect.register(subparsers)
    deploy.register(subparsers)
