"""``scart topics`` (alias ``scart ports``): every port of every task the name service
lists, as ``ros2 topic list`` lists topics: its name (``COMP.PORT``; ``/COMP/PORT`` is
accepted wherever that is), type, direction, measured write rate (output ports) and
number of connections. ``-t`` prints ``ros2 topic list -t``'s form, ``NAME [TYPE]`` a
line; ``--json`` one document.

The rate is ``hz``'s estimator over the port's writes between two descriptions
``--sample`` s apart, timed by the task's own cycles when it cycled in between (a port
written once a cycle reads its task's exact rate), else by the two descriptions."""

from __future__ import annotations

import argparse
import threading
import time
from typing import TYPE_CHECKING, TypedDict

from dataflow.cli.connected import with_system
from scart_wire.console import add_common, dump, out, rate_of

if TYPE_CHECKING:
    from dataflow.introspection import PortDescription, TaskDescription
    from dataflow.remote import System

HELP = "list every port: name, type, direction, measured rate, connections"
ALIASES = ("ports",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``-t``, ``--sample`` and the common options."""
    parser.add_argument("-t", "--show-types", action="store_true", help="NAME [TYPE] a line (ros2 topic list -t)")
    parser.add_argument("--sample", type=float, default=0.5, help="time over which the rates are measured (s)")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """List the ports."""
    return with_system(args, _topics)


def _describe_all(system: System) -> tuple[float, dict[str, TaskDescription]]:
    """``(when, {task: description})`` of every task that answers (one gone meanwhile is left out)."""
    from dataflow import DataflowError

    found = {}
    for name in system.component_names():
        try:
            found[name] = system.component(name).describe()
        except DataflowError:
            continue
    return time.monotonic(), found


class PortRow(TypedDict):
    """One row of :func:`port_rows` (``scart topics --json``)."""

    name: str
    component: str
    port: str
    type: str
    direction: str
    rate: float | None
    connections: int


def port_rows(system: System, sample: float) -> list[PortRow]:
    """One row per port: ``name``, ``component``, ``port``, ``type``, ``direction``,
    ``rate`` (None for an input port), ``connections``."""
    t0, before = _describe_all(system)
    if sample > 0:
        threading.Event().wait(sample)
    t1, after = _describe_all(system)
    rows: list[PortRow] = []
    for task, desc in after.items():
        old = before.get(task)
        for p in desc.ports:
            rate = None
            if p.direction == "out":
                rate = _rate(old, desc, p, t1 - t0)
            rows.append({"name": f"{task}.{p.name}", "component": task, "port": p.name, "type": p.type_name,
                         "direction": p.direction, "rate": rate, "connections": p.connections})
    return rows


def _rate(old: TaskDescription | None, new: TaskDescription, port: PortDescription, elapsed: float) -> float:
    """Writes per second of ``port`` between the descriptions ``old`` and ``new`` (see the module docstring)."""
    if old is None:
        return 0.0
    was = next((p for p in old.ports if p.name == port.name), None)
    if was is None:
        return 0.0
    writes = port.writes - was.writes
    span = new.last_cycle - old.last_cycle if new.last_cycle and old.last_cycle else 0.0
    if span <= 0 or new.cycles == old.cycles:
        span = elapsed  # a port written outside the task's cycles: the descriptions' own times
    return round(rate_of(writes, span), 2)


def _topics(args: argparse.Namespace) -> int:
    rows = port_rows(args.system, 0.0 if args.show_types and not args.json else args.sample)
    if args.json:
        out(dump(rows))
        return 0
    if args.show_types:
        for r in rows:
            out(f"{r['name']} [{r['type']}]")
        return 0
    width = max([len(r["name"]) for r in rows] + [4])
    out(f"{'NAME':<{width}}  {'TYPE':<20} {'DIR':<3} {'RATE(Hz)':>9} {'CONNECTIONS':>11}")
    for r in rows:
        rate = "-" if r["rate"] is None else f"{r['rate']:.1f}"
        out(f"{r['name']:<{width}}  {r['type']:<20} {r['direction']:<3} {rate:>9} {r['connections']:>11}")
    return 0
