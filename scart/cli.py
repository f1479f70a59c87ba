"""The ``scart`` command line: one dispatcher; the verbs come in groups found through the
``scart.commands`` entry points, as ros2cli finds its verbs.

Each entry point names a ``register(subparsers)`` function that adds its verbs and sets
``func`` (returning the exit code) on each sub-parser: ``sca`` (``run``, ``validate``,
``graph``: :mod:`scart.commands.run`) first, then the others by name (``dataflow``: the
inspection and deployment verbs of :mod:`dataflow.cli`). A group imports only what its
verbs need, when they run: ``scart --help`` and ``scart validate`` import no gRPC.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from importlib.metadata import EntryPoint, entry_points

COMMANDS_GROUP = "scart.commands"
CORE_GROUP = "sca"


def build_parser() -> argparse.ArgumentParser:
    """Build the full argument parser (every group's verbs). A group that fails to load is
    reported on stderr and left out: the other verbs still work."""
    parser = argparse.ArgumentParser(
        prog="scart",
        description="SCA runtime with an Orocos-style data-flow bridge.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    groups = sorted(entry_points(group=COMMANDS_GROUP), key=lambda ep: (ep.name != CORE_GROUP, ep.name))
    if not any(ep.name == CORE_GROUP for ep in groups):  # not installed: the core verbs still work
        print("scart: the scart.commands entry points are not installed: only run, validate and graph "
              "are available; install scart (pip install -e .)", file=sys.stderr)
        groups.insert(0, EntryPoint(CORE_GROUP, "scart.commands.run:register", COMMANDS_GROUP))
    seen: set[str] = set()
    for ep in groups:
        if ep.name in seen:  # the same distribution seen twice on sys.path
            continue
        seen.add(ep.name)
        try:
            ep.load()(subparsers)
        except Exception as exc:  # noqa: BLE001 - a broken plug-in must not break the others
            print(f"scart: command group {ep.name!r} ({ep.value}) not loaded: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``scart`` console script; returns the process exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)  # --help prints too
        func = getattr(args, "func", None)
        if func is None:
            parser.print_help(sys.stderr)
            return 2
        code = int(func(args) or 0)
        sys.stdout.flush()
    except BrokenPipeError:  # stdout closed early (``scart describe X | head``): quiet exit
        _silence_stdout()
        return 141
    return code


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not fail again."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
