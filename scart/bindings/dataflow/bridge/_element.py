"""The ``scart:bridge`` element: its load-time check (each bridge read by :mod:`._spec`,
its types checked by :mod:`._resolve`, its sources of other deployers looked up), and
what runs it (:mod:`._runtime`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from scart.bindings.dataflow._checks import remap_problems, remote_end
from scart.bindings.dataflow._host import TASK_KIND
from scart.bindings.dataflow.settings import DataflowSettings
from scart.errors import Severity
from scart.spi import AssemblyView, CheckContext, Element, ElementProvider, Host, Location, Problem

from ._resolve import Resolver
from ._spec import BRIDGE, ELEMENT, BridgeSpec, parse_bridge

if TYPE_CHECKING:
    from ._runtime import BridgeParticipant

__all__ = ["BridgeElement"]


class BridgeElement(ElementProvider):
    """The ``scart:bridge`` composite element (see the module docstring)."""

    name = ELEMENT

    def check(self, elements: list[tuple[str, Element]], assembly: AssemblyView,
              context: CheckContext) -> list[Problem]:
        """Static problems of every bridge element, at its line."""
        out: list[Problem] = []
        specs: dict[str, tuple[BridgeSpec, Element]] = {}
        for prefix, el in elements:
            spec, problems = parse_bridge(prefix, el)
            out += [Problem(code, msg, at.loc.path, at.loc.line) for code, msg, at in problems]
            if spec is None:
                continue
            if spec.name in specs or spec.name in assembly.nodes:
                out.append(Problem(BRIDGE, f"bridge {spec.name!r}: a component or bridge of that name exists",
                                   el.loc.path, el.loc.line))
                continue
            specs[spec.name] = (spec, el)
        resolver = Resolver(assembly, context.settings, context.import_object, {n: s for n, (s, _) in specs.items()})
        for spec, el in specs.values():
            out += _remote_inputs(spec, assembly, context, specs)
            before = len(resolver.problems)
            resolver.resolve(spec)
            out += [Problem(code, msg, (at or el.loc).path, (at or el.loc).line, severity)
                    for code, msg, at, severity in resolver.problems[before:]]
        if not any(n.kind == TASK_KIND for n in assembly.nodes.values()):  # else the tasks' check says it
            out += remap_problems([], assembly, DataflowSettings.of(context.settings).remap)
        return out

    def activate(self, host: Host) -> BridgeParticipant:
        """Runs the bridges: tasks added at start, inputs connected (remote ones by a connector)."""
        from ._runtime import BridgeParticipant  # the checks never load the run-time half

        return BridgeParticipant(host)


def _remote_inputs(spec: BridgeSpec, assembly: AssemblyView, context: CheckContext,
                   specs: dict[str, tuple[BridgeSpec, Element]]) -> list[Problem]:
    """The inputs whose source is no task or bridge of the composite: a warning offline,
    an error online when no name service knows it (see :func:`remote_end`)."""
    out: list[Problem] = []
    for inp in spec.inputs:
        comp = inp.source[0]
        if inp.topic is not None or comp in assembly.nodes or comp in specs or inp.loc is None:
            continue
        loc = inp.loc

        def add(message: str, severity: Severity, _loc: Location = loc) -> None:
            out.append(Problem(BRIDGE, message, _loc.path, _loc.line, severity))

        remote_end(comp, f"bridge {spec.name!r} input {inp.name!r}", inp.ns, assembly, context, add)
    return out
