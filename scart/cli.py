"""The ``scart`` command line: one dispatcher; each verb is a module of its own, found
through the ``scart.verbs`` entry points and imported only when it runs, as ros2cli
finds ``ros2topic.verb`` modules.

A verb module has ``HELP`` (one line), ``add_arguments(parser)`` (its options) and
``main(args) -> int`` (the exit code); ``ALIASES`` (a tuple of other names) and
``DESCRIPTION`` (its ``--help`` text, default ``HELP``) are optional.
``scart VERB ...`` imports that verb's module alone; ``scart --help``, an alias or an
unknown word imports every verb module, which import nothing heavy until ``main`` runs:
``scart --help`` and ``scart validate`` import no gRPC. The SCA verbs (``run``,
``validate``, ``graph``, ``services``, ``call``) live in :mod:`scart.commands`, the
data-flow ones in :mod:`dataflow.cli.verbs`; a plug-in adds a verb with one entry point.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import typing
from collections.abc import Sequence
from importlib.metadata import entry_points
from types import MappingProxyType, ModuleType

VERBS_GROUP = "scart.verbs"
#: The verbs that work without the entry points (scart imported from a bare checkout).
CORE_VERBS = MappingProxyType({"run": "scart.commands.run", "validate": "scart.commands.validate",
                               "graph": "scart.commands.graph"})
_FIRST = tuple(CORE_VERBS)  # listed first in --help, the others alphabetically
class _Parser(argparse.ArgumentParser):
    """argparse's parser, its usage errors bounded: an argument of megabytes is not echoed
    whole ("invalid choice: '...'")."""

    def error(self, message: str) -> typing.NoReturn:
        from scart_wire.errors import bounded

        super().error(bounded(message))


def verb_modules() -> dict[str, str]:
    """``{verb: module name}`` from the ``scart.verbs`` entry points (the core verbs when
    none are installed, after saying so on stderr). Imports no verb."""
    found: dict[str, str] = {}
    for ep in entry_points(group=VERBS_GROUP):
        found.setdefault(ep.name, ep.value.partition(":")[0])  # the same distribution seen twice on sys.path
    if not found:
        print("scart: the scart.verbs entry points are not installed: only run, validate and graph are "
              "available; install scart (pip install -e .)", file=sys.stderr)
        found = dict(CORE_VERBS)
    return dict(sorted(found.items(), key=lambda kv: (kv[0] not in _FIRST, _FIRST.index(kv[0])
                                                      if kv[0] in _FIRST else 0, kv[0])))


def _load(name: str, module: str) -> ModuleType | None:
    """A verb's module, or None (said on stderr) when it cannot be imported: the others still work."""
    try:
        loaded = importlib.import_module(module)
        for attr in ("HELP", "add_arguments", "main"):
            if not hasattr(loaded, attr):
                raise AttributeError(f"has no {attr}")
        return loaded
    except Exception as exc:  # noqa: BLE001 - a broken plug-in must not break the other verbs
        print(f"scart: verb {name!r} ({module}) not loaded: {type(exc).__name__}: {exc}", file=sys.stderr)
        return None


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser: every verb (importing each verb module), or with ``only`` that
    verb alone (its module alone imported)."""
    parser = _Parser(prog="scart", description="SCA runtime with an Orocos-style data-flow bridge.")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = verb_modules()
    if only is not None and only in modules:
        modules = {only: modules[only]}
    for name, module_name in modules.items():
        module = _load(name, module_name)
        if module is None:
            continue
        sub = subparsers.add_parser(name, help=module.HELP, description=getattr(module, "DESCRIPTION", module.HELP),
                                    aliases=list(getattr(module, "ALIASES", ())))
        module.add_arguments(sub)
        sub.set_defaults(func=module.main, command=name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``scart`` console script; returns the process exit code."""
    args_list = list(sys.argv[1:] if argv is None else argv)
    word = args_list[0] if args_list and not args_list[0].startswith("-") else None
    parser = build_parser(only=word)
    try:
        args, extras = parser.parse_known_args(args_list)  # --help prints too
        take = getattr(args, "take_extras", None)  # a verb may take trailing words (ROS's _param:=value)
        if extras and (take is None or take(args, extras)):
            parser.parse_args(args_list)  # says what is unrecognised, exits 2
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
