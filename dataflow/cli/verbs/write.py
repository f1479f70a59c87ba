"""``scart write COMP.PORT VALUE [-r RATE] [-t TIMES]``: write a value to an input port,
once, or ``-r`` times a second (``ros2 topic pub -r``) until ``-t`` writes, ``--duration``
or Ctrl-C.

``VALUE`` is JSON (what ``echo --json`` prints), or YAML as ``ros2 topic pub`` takes it
(``"{joints: [0, 1]}"``, ``"data: 2"``); a bare word is a string. What is printed is the
verdict, never more than it knows: a task that checks what its port is given
(``InputPort(check=...)``, its bounds) answers at once, so a refused value exits 1 with
the task's reason on stderr; an accepted one says which check passed, or, for a port
that declares none, that the port only took the sample (whether the task uses it is its
own business). Exit 0 when every write was accepted."""

from __future__ import annotations

import argparse
import threading
import time
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from dataflow.remote.api import split_port
from scart_wire.console import add_common, dump, err, out, parse_value, stopped_by_signals

if TYPE_CHECKING:
    from dataflow.introspection import PortDescription
    from dataflow.remote import ComponentProxy

HELP = "write a value (JSON or YAML) to an input port, once or at a rate"
MAX_RATE = 1000.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The port, the value, ``-r``, ``-t``, ``--duration`` and the common options."""
    parser.add_argument("port", metavar="COMP.PORT", help="the port: COMP.PORT, /COMP/PORT or COMP/PORT")
    parser.add_argument("value", help='JSON or YAML, e.g. 0.05, "[0.1, 0.2]", "{x: 1}" (a bare word is a string)')
    parser.add_argument("-r", "--rate", type=float, default=None, metavar="RATE",
                        help=f"write again RATE times a second until Ctrl-C (at most {MAX_RATE:g})")
    parser.add_argument("-t", "--times", type=int, default=None, metavar="N", help="with -r: stop after N writes")
    parser.add_argument("--duration", type=float, default=None, help="with -r: stop after this many seconds")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Write; 1 when the port or the task refuses."""
    if args.rate is not None and not 0 < args.rate <= MAX_RATE:
        err(f"write: -r {args.rate:g}: expected 0 < RATE <= {MAX_RATE:g}")
        return 2
    if (args.times is not None or args.duration is not None) and args.rate is None:
        err("write: -t and --duration repeat a write: give -r RATE too")
        return 2
    return with_system(args, _write)


def _write(args: argparse.Namespace) -> int:
    component, port = split_port(args.port)
    value = parse_value(args.value)
    proxy = args.system.component(component)
    info = proxy.ports().get(port)
    if info is None or info.direction != "in":
        inputs = ", ".join(n for n, p in proxy.ports().items() if p.direction == "in") or "none"
        raise ValueError(f"{component} has no input port {port!r}; inputs: {inputs}")
    if not _write_once(args, proxy, port, value):
        return 1
    out(_verdict(args, component, port, info))
    if args.rate is None:
        return 0
    return _repeat(args, proxy, port, value)


def _write_once(args: argparse.Namespace, proxy: ComponentProxy, port: str, value: object) -> bool:
    """One write; a refusal by the task or its port raises (one line, exit 1); a status other
    than success is said here. True when written."""
    status = proxy.write_json(port, value)
    if status.name != "WRITE_SUCCESS":
        err(f"write: {args.port}: {status.name}" + (" (the port is full: its reader is behind)"
                                                     if status.name == "WRITE_FAILURE" else ""))
        return False
    return True


def _verdict(args: argparse.Namespace, component: str, port: str, info: PortDescription) -> str:
    """What an accepted write means, said plainly (see the module docstring)."""
    check = getattr(info, "check", "")
    if check:
        by, text = "task", f"{component} checked it and accepted it ({check})"
    elif info.bounds:
        by, text = "port", (f"the port took it within its bounds ({info.bounds}); {component} declares no check "
                            "of its own, so whether it uses the value is not known")
    else:
        by, text = "port", (f"the port took it; {component} declares no check of its own, so whether it uses "
                            "the value is not known")
    if args.json:
        return dump({"status": "WRITE_SUCCESS", "port": f"{component}.{port}", "accepted_by": by})
    return f"WRITE_SUCCESS: {text}"


def _repeat(args: argparse.Namespace, proxy: ComponentProxy, port: str, value: object) -> int:
    """Write again at ``--rate`` (absolute deadlines: no drift) until ``-t`` writes,
    ``--duration``, Ctrl-C or a refusal; then say how many."""
    done = threading.Event()
    written = 1
    period = 1.0 / args.rate
    start = time.monotonic()
    end = None if args.duration is None else start + args.duration
    with stopped_by_signals(done):
        while (args.times is None or written < args.times) and not done.is_set():
            due = start + written * period
            if end is not None and due > end:
                break
            if done.wait(max(0.0, due - time.monotonic())):
                break
            if not _write_once(args, proxy, port, value):
                return 1
            written += 1
    out(dump({"written": written}) if args.json else f"wrote {written} sample(s) to {args.port}")
    return 0
