"""What the composite verbs (``run``, ``validate``, ``graph``) share: the options that
change a composite at launch (``--set``, ``--contribution``, and each extension's own,
through its :class:`~scart.spi.LaunchProvider`), the settings they make, the names
components run under, and assembling a composite with its problems printed."""

from __future__ import annotations

import argparse
import os
import sys

from pydantic import BaseModel

from scart.assembly import assemble
from scart.errors import Problem, ScartError, ScdlError
from scart.extensions import ExtensionRegistry
from scart.assembled import Assembly
from scart.graph import Bound, Target
from scart.settings import Settings
from scart.spi import Verb
from scart_wire.security import SecurityError, from_args

__all__ = ["add_launch_options", "assemble_or_say", "endpoint_text", "parse_overrides", "run_names", "settings_of"]


def add_launch_options(parser: argparse.ArgumentParser, verb: Verb,
                       registry: ExtensionRegistry | None = None) -> None:
    """``--set`` and ``--contribution`` (repeatable each), then every launch provider's
    options for ``verb``."""
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="COMPONENT.PROP=VALUE",
                        help="override a component property (repeatable)")
    parser.add_argument("--contribution", dest="contributions", action="append", default=[], metavar="DIR",
                        help="another contribution folder the composite is resolved in: its exported "
                             "namespaces and its Python modules (repeatable)")
    for provider in (registry or ExtensionRegistry()).launch_providers():
        provider.add_arguments(parser, verb)


def parse_overrides(items: list[str]) -> dict[str, str]:
    """``["Comp.prop=value", ...]`` to a dict; raises ``ValueError`` naming a malformed item."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or "." not in key:
            raise ValueError(f"--set {item!r}: expected COMPONENT.PROPERTY=VALUE")
        out[key.strip()] = value
    return out


def settings_of(args: argparse.Namespace, verb: Verb, registry: ExtensionRegistry | None = None,
                **fields: object) -> Settings | None:
    """The settings of ``verb``: its security options, each launch provider's own settings
    from its options (else the environment), and ``fields``; None (after printing why)
    when a value is invalid."""
    try:
        extensions: list[BaseModel] = []
        try:
            fields["security"] = from_args(args)
            for provider in (registry or ExtensionRegistry()).launch_providers():
                value = provider.settings(args, verb, os.environ)
                if value is not None:
                    extensions.append(value)
        except (SecurityError, ValueError) as exc:
            raise ScartError(str(exc)) from None
        return Settings.from_env(None, extensions=tuple(extensions), **fields)
    except ScartError as exc:
        print(f"scart: {exc}", file=sys.stderr)
        return None


def run_names(assembly: Assembly, settings: Settings) -> dict[str, str]:
    """The name each component runs under when an extension renames it (a remapped task),
    by path (see :meth:`scart.spi.LaunchProvider.names`)."""
    names: dict[str, str] = {}
    for provider in assembly.registry.launch_providers():
        names.update(provider.names(assembly, settings))
    return names


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
