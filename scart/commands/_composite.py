"""What the composite verbs (``run``, ``validate``, ``graph``) share: the options that
change a composite at launch (``--set``, ``--remap``, ``--contribution``), the settings
they make, and assembling a composite with its problems printed."""

from __future__ import annotations

import argparse
import sys

from dataflow import DataflowError
from scart_wire.security import from_args
from scart.assembly import assemble
from scart.errors import Problem, ScartError, ScdlError
from scart.graph import Assembly, Bound, Target
from scart.settings import Remap, Settings

__all__ = ["add_launch_options", "assemble_or_say", "endpoint_text", "parse_overrides", "settings_of"]

TASK_KIND = "implementation.task"  # the data-flow extension's kind (the core does not import it)


def add_launch_options(parser: argparse.ArgumentParser) -> None:
    """``--set``, ``--remap`` and ``--contribution`` (repeatable each)."""
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="COMPONENT.PROP=VALUE",
                        help="override a component property (repeatable)")
    parser.add_argument("--remap", action="append", default=[], metavar="FROM=TO",
                        help="rename a data-flow task or port at launch (FROM:=TO too; TASK.PORT=NAME for one "
                             "task's port; __ns=NAMESPACE puts every task under NAMESPACE/); repeatable")
    parser.add_argument("--contribution", dest="contributions", action="append", default=[], metavar="DIR",
                        help="another contribution folder the composite is resolved in: its exported "
                             "namespaces and its Python modules (repeatable)")


def parse_overrides(items: list[str]) -> dict[str, str]:
    """``["Comp.prop=value", ...]`` to a dict; raises ``ValueError`` naming a malformed item."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or "." not in key:
            raise ValueError(f"--set {item!r}: expected COMPONENT.PROPERTY=VALUE")
        out[key.strip()] = value
    return out


def settings_of(args: argparse.Namespace, **fields: object) -> Settings | None:
    """The settings of a verb: ``--ns`` (else ``SCART_NS``) and ``fields``; None (after
    printing why) when a value is invalid."""
    ns = getattr(args, "ns", None)
    try:
        try:
            fields["security"] = from_args(args)
            fields["remap"] = Remap.parse(getattr(args, "remap", None) or [])
        except (DataflowError, ValueError) as exc:
            raise ScartError(str(exc)) from None
        if ns:
            try:
                return Settings.from_env(ns=ns, **fields)
            except ScartError as exc:
                raise ScartError(f"--ns {ns!r}: {str(exc).partition(': ')[2]}") from None
        return Settings.from_env(**fields)
    except ScartError as exc:
        print(f"scart: {exc}", file=sys.stderr)
        return None


def assemble_or_say(file: str, raw_overrides: list[str], settings: Settings, unused: set[str] | None = None,
              contributions: list[str] | None = None) -> Assembly | None:
    """Assemble ``file`` or print its problems. With ``unused`` (a set), overrides naming no
    property of this file are no problem: their keys are added to ``unused`` instead."""
    try:
        result = assemble(file, parse_overrides(raw_overrides), strict_overrides=unused is None, settings=settings,
                          contributions=contributions or [])
        if unused is not None:
            unused |= result.unused_overrides
        _print_warnings(result.warnings)
        return result
    except ScdlError as exc:
        if unused is not None:
            unused |= exc.unused_overrides
        print(str(exc), file=sys.stderr)
        _print_warnings(exc.warnings)
        print(f"scart: {file}: {len(exc.errors)} problem(s); nothing started", file=sys.stderr)
    except ValueError as exc:
        if unused is not None:
            unused.add("")  # malformed --set: fails every file
        print(f"scart: {exc}", file=sys.stderr)
    return None


def _print_warnings(warnings: list[Problem]) -> None:
    """Each warning as ``path:line: warning: message [CODE]`` on stderr."""
    for warning in warnings:
        print(warning, file=sys.stderr)


def endpoint_text(ep: Target | Bound) -> str:
    """A reference's target as the summary and the graph show it."""
    if isinstance(ep, Target):
        return f"{ep.node}/{ep.service}"
    return f"<{ep.binding.kind} {' '.join(f'{k}={v}' for k, v in ep.binding.attributes.items())}>"
