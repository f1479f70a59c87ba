"""``scart hz COMP.PORT [-w WINDOW] [-n N]``: the rate of an output port from its
samples' source times, as ``ros2 topic hz``: average rate, min/max period, standard
deviation and the periods measured (the last ``-w`` of them), every second until Ctrl-C
or ``--duration``; ``-n N`` measures N periods, prints one report and stops."""

from __future__ import annotations

import argparse
import math
import statistics
import threading
from typing import TYPE_CHECKING

from dataflow.cli.connected import with_system
from dataflow.remote.api import split_port
from scart_wire.console import add_common, dump, err, out, rate_of, stopped_by_signals, wait_until_stopped

if TYPE_CHECKING:
    from dataflow.remote import SampleEvent

HELP = "measure the rate of an output port"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The port, ``-w``, ``-n``, ``--duration`` and the common options."""
    parser.add_argument("port", metavar="COMP.PORT", help="the port: COMP.PORT, /COMP/PORT or COMP/PORT")
    parser.add_argument("-n", type=int, default=None, help="stop after N periods (prints one report)")
    parser.add_argument("-w", "--window", type=int, default=10000,
                        help="periods kept for the statistics (default 10000; ros2 topic hz -w)")
    parser.add_argument("--duration", type=float, default=None, help="stop after this many seconds")
    add_common(parser)


def main(args: argparse.Namespace) -> int:
    """Measure until ``-n``, ``--duration`` or Ctrl-C."""
    if args.window < 1 or (args.n is not None and args.n < 1):
        err("hz: -w/--window and -n: at least 1 period")
        return 2
    return with_system(args, _hz)


def hz_stats(stamps: list[float]) -> dict[str, float]:
    """``ros2 topic hz`` statistics from sample times (s): rate, min, max, std_dev, and window
    (the number of periods measured)."""
    periods = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    if not periods:
        return {"rate": 0.0, "min": 0.0, "max": 0.0, "std_dev": 0.0, "window": 0}
    span = stamps[-1] - stamps[0]
    return {
        "rate": rate_of(len(periods), span) if span > 0 else math.inf,
        "min": min(periods),
        "max": max(periods),
        "std_dev": statistics.pstdev(periods),
        "window": len(periods),  # intervals measured: `hz -n 100` reports 100
    }


def _hz(args: argparse.Namespace) -> int:
    from dataflow import ConnPolicy

    component, port = split_port(args.port)
    proxy = args.system.component(component)
    done = threading.Event()
    stamps: list[float] = []
    lock = threading.Lock()
    target = None if args.n is None else args.n + 1  # n periods need n+1 samples

    def observer(event: SampleEvent) -> None:
        with lock:
            stamps.append(event.source_time)
            del stamps[: max(0, len(stamps) - args.window - 1)]  # window periods need window + 1 samples
            if target is not None and len(stamps) >= target:
                done.set()

    def report() -> None:
        with lock:
            stats = hz_stats(list(stamps))
        if args.json:
            out(dump(stats))
        else:
            out(f"average rate: {stats['rate']:.3f}\n\tmin: {stats['min']:.6f}s max: {stats['max']:.6f}s "
                f"std dev: {stats['std_dev']:.6f}s window: {stats['window']}")

    with stopped_by_signals(done):  # a Ctrl-C while subscribing stops it too
        sub = proxy.subscribe(port, observer, policy=ConnPolicy.buffer(1000))
        try:
            wait_until_stopped(done, args.duration, on_tick=report if args.n is None else None)
        finally:
            sub.close()
    report()
    return 0
