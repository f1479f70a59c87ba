"""Assembly: the static checks, and the flat, resolved component graph the runtime runs.

:func:`assemble` loads a composite and its contribution, introspects every
implementation, checks every SCA assembly rule (and each extension's own checks), and
returns an :class:`~scart.assembled.Assembly` — or raises one
:class:`~scart.errors.ScdlError` listing every problem. Nothing is started, and
nothing touches the network unless the settings say ``online``.

Two phases. *Build* walks composites top-down (nesting through
``implementation.composite``), introspects implementations and resolves property values
(composite properties flow in through ``source="$name"``). *Wire* resolves every
reference to endpoints (``@target``, ``<wire>`` with ``replace``, autowire, then
promotion from the enclosing component), and checks multiplicity and interface
compatibility. Leaf components are named by their path ("Outer/Inner").
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from scart import errors as E
from scart.archive import ArchiveError, is_archive, unpack
from scart.assembled import Assembly
from scart.assembly._components import Components
from scart.contribution import METADATA, Contribution, deployable_of
from scart.errors import Problem, ScdlError
from scart.extensions import ExtensionError, ExtensionRegistry
from scart.graph import Target
from scart.model import Binding, Composite
from scart.settings import Settings
from scart.spi import CheckContext


def assemble(path: str, overrides: dict[str, str] | None = None, *, strict_overrides: bool = True,
             extensions: ExtensionRegistry | None = None, settings: Settings | None = None,
             contributions: Sequence[str | os.PathLike[str]] = ()) -> Assembly:
    """Load, check and resolve the composite at ``path`` (a ``.composite`` file, or a
    contribution folder with one deployable composite); ``overrides`` maps
    "Component.prop" (or "Outer/Inner.prop") to a raw value. Raises ``ScdlError``.

    ``contributions`` are more contribution folders the composite is resolved in (see
    :mod:`scart.contribution`).

    ``extensions`` is the registry of kinds to check against (default: the entry points);
    ``settings`` are given to the extensions' checks (offline unless ``settings.online``).
    With ``strict_overrides=False`` an override naming no component property is no
    problem; the keys not used are then in ``unused_overrides`` of the result (or of the
    ``ScdlError``), for callers checking several files (``scart validate --set``)."""
    registry = extensions if extensions is not None else ExtensionRegistry()
    path, root_archive = _root_file(path, overrides)
    contribution = Contribution(path, is_element=lambda name: _is_element(registry, name),
                                contributions=[str(c) for c in contributions], root_archive=root_archive)
    root = contribution.load_root()
    context = CheckContext(contribution.folder, contribution.root_file, settings or Settings(), contribution.import_object)
    assembler = _Assembler(contribution, registry, context, dict(overrides or {}), strict_overrides)
    if root is None:
        _refuse([contribution.display_problem(p) for p in contribution.problems], set(overrides or {}))
    result = assembler.run(root)
    # a composite used by several components is checked once per use: report each problem once
    # causes first, their knock-ons after: the contributions' metadata, then what was read
    # wrong, then the rest; within each, the root file first, by line
    reading = set(contribution.problems)
    problems = list(dict.fromkeys(contribution.problems + assembler.problems))
    root_path = str(path)
    problems.sort(key=lambda p: (not p.path.endswith(METADATA.name), p not in reading, p.path != root_path,
                                 p.path, p.line))
    problems = [contribution.display_problem(p) for p in problems]
    errors = [p for p in problems if p.severity == "error"]
    warnings = [p for p in problems if p.severity != "error"]
    unused = set(assembler.overrides) - assembler.used_overrides
    if errors:
        _refuse(errors, unused, warnings)
    result.unused_overrides = unused
    result.warnings = warnings
    return result


def _refuse(errors: list[Problem], unused: set[str], warnings: list[Problem] | None = None) -> NoReturn:
    """Raise the ``ScdlError`` of ``errors`` (with the overrides not used, and the warnings)."""
    err = ScdlError(errors)
    err.unused_overrides = unused
    err.warnings = list(warnings or [])
    raise err


def _root_file(path: str, overrides: dict[str, str] | None
               ) -> tuple[str, tuple[Path, tempfile.TemporaryDirectory[str]] | None]:
    """The composite file to load for ``path`` — a ``.composite`` file, or the one
    deployable of a contribution folder or ZIP archive (unpacked: see
    :mod:`scart.archive`) — and the unpacked archive; raises ``ScdlError`` when there is
    none."""
    given = Path(path)
    unpacked = None
    if is_archive(given):
        try:
            unpacked = unpack(given)
        except ArchiveError as exc:
            _refuse([Problem(E.SCART_ARCHIVE, str(exc), path, 0)], set(overrides or {}))
        folder = Path(unpacked.name).resolve()
    elif given.is_dir():
        folder = given
    else:
        return path, None
    found, why = deployable_of(folder)
    if found is None:
        shown = [p if unpacked is None else dataclasses.replace(
            p, path=p.path.replace(str(folder), f"{path}!"), message=p.message.replace(str(folder), f"{path}!"))
                 for p in why]
        _refuse(shown, set(overrides or {}))
    return found, (given, unpacked) if unpacked is not None else None


def _is_element(registry: ExtensionRegistry, name: str) -> bool:
    try:
        return registry.element(name) is not None
    except ExtensionError:
        return True  # known but broken: read it, and let the check report why it cannot be used


class _Assembler(Components):
    """Assembles one root composite: its components (:mod:`._components`), their
    properties (:mod:`._properties`), references and wires (:mod:`._references`), the
    services they target and promote (:mod:`._targets`) and the interfaces of all
    (:mod:`._interfaces`), over a shared state (:mod:`._state`); then the whole's checks."""

    def run(self, root: Composite) -> Assembly:
        props = {p.name: self.declaration_values(p) for p in root.properties}
        scope = self.build(root, "", props, {p.name: self.reader.declared(p) for p in root.properties})
        self.wire(scope, {})
        for key in sorted(set(self.overrides) - self.used_overrides) if self.strict_overrides else ():
            self.problems.append(Problem(E.SCART_OVERRIDE, f"--set {key}: {self.no_such_property(key)}",
                                         "<command line>", 0))
        services: dict[str, Target] = {}
        bindings: dict[str, list[Binding]] = {}
        for cs in root.services:
            target = self.resolve_service(scope, cs.promote, cs.loc, E.ASM_PROMOTED_SERVICE,
                                          what=f"composite service {cs.name!r}: @promote ")
            if target is not None:
                self.promoted_service(cs, target)
                services[cs.name] = target
                bindings[cs.name] = cs.bindings
        aliases: dict[str, Target] = {}
        for name, child in scope.children.items():
            offered = list(child.ctype.services) if child.ctype is not None else []
            for sname in offered:
                t = self.resolve_service(scope, f"{name}/{sname}", root.loc)
                if t is not None:
                    aliases[f"{name}/{sname}"] = t
                    if len(offered) == 1:
                        aliases[name] = t
        result = Assembly(root, self.contribution, self.registry, self.nodes, self.init_order(), services, bindings,
                          aliases, self.extensions)
        self.check_bindings(result)
        self.check_implementations(result)
        self.check_extensions(result)
        return result

    def init_order(self) -> list[str]:
        """Leaf paths, targets before sources; definition order otherwise; cycles broken."""
        order: list[str] = []
        state: dict[str, int] = {}
        for start in self.nodes:
            stack: list[tuple[str, int]] = [(start, 0)]
            while stack:
                path, i = stack.pop()
                if i == 0:
                    if state.get(path):
                        continue
                    state[path] = 1
                deps = [t.node for ts in self.nodes[path].references.values() for t in ts if isinstance(t, Target)]
                if i < len(deps):
                    stack.append((path, i + 1))
                    if not state.get(deps[i]):
                        stack.append((deps[i], 0))
                else:
                    state[path] = 2
                    order.append(path)
        return order


__all__ = ["assemble"]
