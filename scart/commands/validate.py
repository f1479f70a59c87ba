"""``scart validate FILE...``: check composites without running them (offline unless
``--online``); ``FILE: ok (N component(s))`` for each valid one, every problem of the
others as ``path:line: message [CODE]`` on stderr. Exit 0 when all are valid, else 2."""

from __future__ import annotations

import argparse
import sys

from scart.commands._composite import add_launch_options, assemble_or_say, parse_overrides, settings_of

HELP = "check composites without running them (offline)"


def add_arguments(validate: argparse.ArgumentParser) -> None:
    """The files, the launch options (the extensions' among them), ``--online`` and its
    credentials."""
    from scart_wire.security import add_arguments as add_security

    validate.add_argument("files", nargs="+", help=".composite files (or contribution folders)")
    validate.add_argument("--online", action="store_true",
                          help="also let the extensions' checks ask the running services a composite names "
                               "(remote data-flow tasks in their name service)")
    add_launch_options(validate, "validate")
    add_security(validate, server=False)


def main(args: argparse.Namespace) -> int:
    """Validate; 0 or 2."""
    return cmd_validate(args)


def cmd_validate(args: argparse.Namespace) -> int:
    """Check each file; print "ok" lines or every problem; 0 if all valid, else 2."""
    settings = settings_of(args, "validate", online=args.online)
    if settings is None:
        return 2
    failed = 0
    several = len(args.files) > 1
    unused_in: list[set[str]] = []
    for file in args.files:
        unused: set[str] | None = set() if several else None
        assembly = assemble_or_say(file, args.overrides, settings, unused, args.contributions)
        if unused is not None:
            unused_in.append(unused)
        if assembly is None:
            failed += 1
        else:
            warned = f", {len(assembly.warnings)} warning(s)" if assembly.warnings else ""
            print(f"{file}: ok ({len(assembly.nodes)} component(s){warned})")
    if several and args.overrides:  # an override must fit at least one of the files
        try:
            keys = parse_overrides(args.overrides)
        except ValueError:
            keys = {}
        for key in sorted(k for k in keys if all(k in u for u in unused_in)):
            print(f"<command line>:0: --set {key}: no such component property in any of the files "
                  f"[SCART-C005]", file=sys.stderr)
            failed += 1
    return 2 if failed else 0


