"""``scart prop list|get|set COMP [NAME] [VALUE]``: a task's properties; a value to set is
JSON or YAML (what ``prop get --json`` prints, ``prop set`` accepts)."""

from __future__ import annotations

import argparse

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, jsonable, out, parse_value

HELP = "list, get or set properties"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``list|get|set COMP [NAME] [VALUE]`` and the common options."""
    parser.add_argument("action", choices=["list", "get", "set"])
    parser.add_argument("component")
    parser.add_argument("name", nargs="?")
    parser.add_argument("value", nargs="?", help="the value to set: JSON or YAML (a bare word is a string)")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """List, read or set; 1 for an unknown name or a refused value."""
    return with_system(args, _prop)


def _prop(args: argparse.Namespace) -> int:
    proxy = args.system.component(args.component)
    if args.action == "list":
        props = list(proxy.properties().values())
        if args.json:
            out(dump([p.model_dump(mode="json") for p in props]))
        else:
            for p in props:
                out(f"{p.name}: {p.type_name} = {dump(p.value)}" + (f"  # {p.doc}" if p.doc else ""))
        return 0
    if not args.name:
        raise ValueError(f"prop {args.action} needs a property NAME")
    if args.action == "get":
        out(dump(jsonable(proxy.get_property(args.name))))
        return 0
    if args.value is None:
        raise ValueError("prop set needs a VALUE (JSON or YAML)")
    out(dump(proxy.set_property_json(args.name, parse_value(args.value))))
    return 0
