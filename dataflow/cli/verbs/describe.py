"""``scart describe COMP``: a component's properties (with values and bounds), operations
(with signatures) and ports (direction, type, bounds, connections, last value; under each,
its streams: topic, type, state, whether unauthenticated, samples refused and why)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, jsonable, out

if TYPE_CHECKING:
    from dataflow.introspection import PortStreamDescription

HELP = "properties, operations and ports of a component"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``COMP`` and the common options."""
    parser.add_argument("component")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Describe the component; 1 when it is unknown."""
    return with_system(args, _describe)


def _describe(args: argparse.Namespace) -> int:
    proxy = args.system.component(args.component)
    desc, last = proxy.describe_with_values()
    if args.json:
        doc = desc.model_dump(mode="json")
        for port in doc["ports"]:
            if port["name"] in last:
                port["last_value"] = jsonable(last[port["name"]])
        out(dump(doc))
        return 0
    period = f", period {desc.period:g} s" if desc.period else ""
    out(f"{desc.name}: {desc.state} ({desc.activity}{period}, {desc.cycles} cycles, {desc.overruns} overruns)")
    out("properties:")
    for p in desc.properties:
        bounds = f" [{p.bounds}]" if p.bounds else ""
        out(f"  {p.name}: {p.type_name}{bounds} = {dump(p.value)}" + (f"  # {p.doc}" if p.doc else ""))
    out("operations:")
    for o in desc.operations:
        out(f"  {o.signature or o.name}" + (f"  # {o.doc}" if o.doc else ""))
    out("ports:")
    for p in desc.ports:
        bounds = f" [{p.bounds}]" if p.bounds else ""
        line = f"  {p.direction:<3} {p.name}: {p.type_name}{bounds}, {p.connections} connection(s)"
        if p.name in last:
            text = dump(jsonable(last[p.name]))
            line += f", last = {text if len(text) <= 120 else text[:117] + '...'}"
        out(line + (f"  # {p.doc}" if p.doc else ""))
        for st in p.streams:
            out("      " + _stream_line(st))
    return 0


def _stream_line(s: PortStreamDescription) -> str:
    """A stream under its port: ``stream NAME: transport:topic (type), state[, UNAUTHENTICATED]``
    and, when samples were refused, how many and why the last one was."""
    kind = f" ({s.type_name})" if s.type_name else ""
    line = f"stream {s.name}: {s.topic}{kind}, {s.state}"
    if s.unauthenticated:
        line += ", UNAUTHENTICATED (anyone who reaches it may publish)"
    if s.refused or s.refusal:
        line += f"; {s.refused} refused" + (f", last: {s.refusal}" if s.refusal else "")
    return line
