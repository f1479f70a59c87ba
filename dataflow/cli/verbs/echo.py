"""``scart echo COMP.PORT [-n N | --once] [--field PATH]``: each sample of an output port
(or the part ``--field`` names): readable, over several lines for a structure (``---
[sequence]`` first), or one JSON line with ``--json`` (what ``write`` accepts). A
sample without the ``--field`` asked for ends it: one line naming the fields there are,
exit 1 (a typo never prints ``null``). ``--zenoh`` takes the samples from Zenoh, with no name service."""

from __future__ import annotations

import argparse
import json
import threading
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_session, with_system
from dataflow.launch import zenoh as zenoh_args
from dataflow.policy import ConnPolicy
from dataflow.remote.api import split_port
from scart_wire.console import add_common, dump, err, jsonable, out, stopped_by_signals, wait_until_stopped

if TYPE_CHECKING:
    from dataflow.remote import SampleEvent, Subscription
    from dataflow.transports.zenoh import ZenohSubscription

HELP = "print samples of an output port"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The port, how many samples, how to subscribe, and the common options."""
    parser.add_argument("port", metavar="COMP.PORT", help="the port: COMP.PORT, /COMP/PORT or COMP/PORT")
    parser.add_argument("-n", type=int, default=None, help="stop after N samples")
    parser.add_argument("--once", action="store_true", help="print one sample, then stop (as -n 1; ros2 topic echo --once)")
    parser.add_argument("--policy", default="data", help="data | buffer:N | circular:N (default data)")
    parser.add_argument("--period", type=float, default=None, help="poll at this period instead of push")
    zenoh_args.add_arguments(parser, "take the samples from Zenoh (scart/NS/COMP/PORT), no name service needed")
    parser.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    parser.add_argument("--field", default=None, metavar="PATH",
                        help="print only this part of each sample: joints[2].position, joints[*].position")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Print samples until ``-n``, ``--once``, ``--duration`` or Ctrl-C."""
    if args.once:
        if args.n not in (None, 1):
            err("echo: --once prints one sample; drop -n")
            return 2
        args.n = 1
    if args.zenoh:
        if args.policy != "data" or args.period is not None:
            err("echo: --policy and --period are for the name service's subscriptions, not --zenoh")
            return 1
        return with_session(args, _echo)
    return with_system(args, _echo)


def _echo(args: argparse.Namespace) -> int:
    from dataflow.fields import parse_path

    component, port = split_port(args.port)
    path = parse_path(args.field) if args.field is not None else None
    if args.field is not None and path is None:
        raise ValueError(f"--field {args.field!r}: expected a path such as joints[2].position or joints[*].position")
    proxy = None if args.zenoh else args.system.component(component)
    done = threading.Event()
    printer = _Printer(args, path, done)
    with stopped_by_signals(done):  # before the first sample can be printed
        if args.zenoh:
            from dataflow.transports.zenoh import ZenohSubscription

            sub: ZenohSubscription | Subscription = ZenohSubscription(args.zenoh_session, component, port, printer, args.zenoh_ns)
        else:
            assert proxy is not None
            sub = proxy.subscribe(port, printer, policy=ConnPolicy.parse(args.policy), period=args.period)
        try:
            wait_until_stopped(done, args.duration)
        finally:
            sub.close()
    if printer.failed:
        err(f"echo: {printer.failed}")
        return 1
    if sub.dropped and args.zenoh:
        err(f"echo: {sub.dropped} sample(s) lost on Zenoh or not decodable")
    elif sub.dropped:
        err(f"echo: {sub.dropped} sample(s) dropped by the policy {args.policy}")
    return 0


class _Printer:
    """The observer: prints each sample (thread-safe), sets ``done`` after ``-n``."""

    def __init__(self, args: argparse.Namespace, path: tuple[str | int, ...] | None, done: threading.Event) -> None:
        self.args, self.path, self.done = args, path, done
        self.count = 0
        self.failed = ""  #: why echoing stopped: a sample without the ``--field`` asked for
        self._lock = threading.Lock()

    def __call__(self, event: SampleEvent) -> None:
        from dataflow.fields import apply_path

        args = self.args
        with self._lock:
            if self.done.is_set():
                return
            data = jsonable(event.value)
            if self.path is not None:
                try:
                    data = apply_path(data, self.path)
                except (KeyError, IndexError, TypeError, AttributeError):
                    self.failed = f"sample {event.sequence} of {args.port} has no {args.field}{_fields_of(data)}"
                    self.done.set()  # an unknown field is an error (exit 1), never a null printed
                    return
            if args.json:
                out(dump(data))
            elif isinstance(data, (dict, list)) and data:
                out(f"--- [{event.sequence}]\n{json.dumps(data, ensure_ascii=False, indent=2)}")
            else:
                out(f"[{event.sequence}] {dump(data)}")
            self.count += 1
            if args.n is not None and self.count >= args.n:
                self.done.set()


def _fields_of(data: object) -> str:
    """``"; its fields: a, b, c"`` for a structure (what ``--field`` could name first)."""
    if isinstance(data, dict) and data:
        return f"; its fields: {', '.join(sorted(map(str, data))[:20])}"
    return f"; the sample is of type {type(data).__name__}" if data is not None else ""
