"""``scart ls``: one line per component (name, state, period, measured rate, deployer);
``--zenoh``: the components and output ports Zenoh's liveliness tokens announce, with no
name service.

The rate is ``hz``'s estimator applied to the task's cycles: the cycles that began
between two listings ``--sample`` s apart, over the time between the first and the last
of them (the task's own clock), so a steady 10 Hz task reads 10.0, not 8 or 12 as
counting cycles in a window would say."""

from __future__ import annotations

import argparse
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_session, with_system
from dataflow.launch import zenoh as zenoh_args
from scart_wire.console import add_common, dump, out, rate_of

if TYPE_CHECKING:
    from dataflow.remote import ComponentInfo

HELP = "list components: name, state, period, measured rate, deployer"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--sample``, ``--zenoh ...`` and the common options."""
    parser.add_argument("--sample", type=float, default=0.25, help="time over which the rate is measured (s)")
    zenoh_args.add_arguments(parser, "list what Zenoh announces (liveliness tokens), no name service needed")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """List the components."""
    if args.zenoh:
        return with_session(args, _ls_zenoh)
    return with_system(args, _ls)


def cycle_rates(listing: Callable[[], list[ComponentInfo]], sample: float) -> list[tuple[ComponentInfo, float]]:
    """Each component of ``listing()`` with its cycle rate over ``sample`` s (see the
    module docstring; 0.0 for one that did not cycle twice in between)."""
    first = {c.name: c for c in listing()}
    if sample > 0:
        threading.Event().wait(sample)
    rows = []
    for c in listing():
        before = first.get(c.name)
        rate = 0.0
        if before is not None and c.last_cycle and before.last_cycle:
            rate = round(rate_of(c.cycles - before.cycles, c.last_cycle - before.last_cycle), 2)
        rows.append((c, rate))
    return rows


def _ls(args: argparse.Namespace) -> int:
    rows = [{"name": c.name, "state": c.state, "activity": c.activity, "period": c.period, "rate": rate,
             "cycles": c.cycles, "overruns": c.overruns, "deployer": c.address}
            for c, rate in cycle_rates(args.system.components, args.sample)]
    if args.json:
        out(dump(rows))
        return 0
    out(f"{'NAME':<24} {'STATE':<16} {'PERIOD':>9} {'RATE(Hz)':>9}  DEPLOYER")
    for r in rows:
        period = f"{r['period']:g}" if r["period"] else "-"
        out(f"{r['name']:<24} {r['state']:<16} {period:>9} {r['rate']:>9.1f}  {r['deployer']}")
    return 0


def _ls_zenoh(args: argparse.Namespace) -> int:
    from dataflow.transports.zenoh import discover

    found = discover(args.zenoh_session, args.zenoh_ns, timeout=max(args.timeout / 3, 0.2))
    if args.json:
        out(dump([{"name": name, "ports": ports} for name, ports in found.items()]))
        return 0
    out(f"{'NAME':<24} PORTS (on Zenoh: scart/{args.zenoh_ns}/NAME/PORT)")
    for name, ports in found.items():
        out(f"{name:<24} {' '.join(ports) or '-'}")
    return 0
