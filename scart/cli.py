"""The ``scart`` command line: one dispatcher, one module per group of verbs.

Each module in :data:`COMMAND_MODULES` exposes ``register(subparsers)``, which adds
its verbs and sets ``func`` (returning the exit code) on each sub-parser. Keeping
the verbs in separate modules keeps this file small and lets each group import
only what it needs (``scart validate`` never imports gRPC).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

COMMAND_MODULES: tuple[str, ...] = (
    "scart.commands.run",  # run, validate, graph
    "scart.commands.inspect",  # ls, describe, echo, hz, write, call, prop, state, connect, disconnect
    "scart.commands.deploy",  # deploy, nameserver
)


def build_parser() -> argparse.ArgumentParser:
    """Build the full argument parser (all verbs)."""
    parser = argparse.ArgumentParser(
        prog="scart",
        description="SCA runtime with an Orocos-style data-flow bridge.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
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
