"""Benchmark of the data-flow core: port cost, cross-thread latency, periodic jitter, fan-out.

Usage: ``python benchmarks/bench_ports.py [--quick | --smoke]`` (``--quick``: 1 s per
periodic run instead of 5 s, fewer iterations; ``--smoke``: a few seconds, that it runs). Prints one table. Not a test: numbers depend on the
machine; report what you get.
"""

from __future__ import annotations

import argparse
import collections
import sys
import threading
import time
from collections.abc import Callable

from dataflow import ConnPolicy, FlowStatus, InputPort, OutputPort, PeriodicActivity, TaskContext

from _common import pct

Row = tuple[str, str, str]


def per_op_ns(fn: Callable[[int], None], n: int) -> float:
    """Best of 3 runs of ``fn(n)``, in ns per iteration."""
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter_ns()
        fn(n)
        best = min(best, (time.perf_counter_ns() - t0) / n)
    return best


def bench_costs(n: int) -> list[Row]:
    def port_loop(policy: ConnPolicy) -> Callable[[int], None]:
        out, inp = OutputPort(float, "o"), InputPort(float, "i")
        out.connect_to(inp, policy)
        write, read = out.write, inp.read

        def loop(k: int) -> None:
            for _ in range(k):
                write(1.0)
                read()

        return loop

    dq: collections.deque[float] = collections.deque()

    def deque_loop(k: int) -> None:
        append, popleft = dq.append, dq.popleft
        for _ in range(k):
            append(1.0)
            popleft()

    class Box:
        value = 0.0

    box = Box()

    def attr_loop(k: int) -> None:
        for _ in range(k):
            box.value = 1.0
            _ = box.value

    base = per_op_ns(deque_loop, n)
    rows = [
        ("write+read DATA", f"{per_op_ns(port_loop(ConnPolicy.data()), n):.0f} ns", ""),
        ("write+read BUFFER(16)", f"{per_op_ns(port_loop(ConnPolicy.buffer(16)), n):.0f} ns", ""),
        ("baseline deque append+popleft", f"{base:.0f} ns", ""),
        ("baseline attribute swap", f"{per_op_ns(attr_loop, n):.0f} ns", ""),
    ]
    data_ns = float(rows[0][1].split()[0])
    rows[0] = (rows[0][0], rows[0][1], f"{data_ns / base:.1f}x deque (goal <= 3x)")
    return rows


def bench_latency(samples: int) -> list[Row]:
    rows = []
    for mode in ("busy reader", "event-waiting reader"):
        out, inp = OutputPort(int, "o"), InputPort(int, "i")
        out.connect_to(inp, ConnPolicy.buffer(1024))
        lat: list[float] = []
        done = threading.Event()
        wake = threading.Event()
        if mode == "event-waiting reader":
            inp.add_data_callback(lambda _p: wake.set())

        def reader() -> None:
            while len(lat) < samples and not done.is_set():
                if mode == "event-waiting reader":
                    wake.wait(0.1)
                    wake.clear()
                flow, stamp = inp.read()
                while flow is FlowStatus.NEW_DATA:
                    lat.append((time.perf_counter_ns() - stamp) / 1e3)
                    flow, stamp = inp.read()

        th = threading.Thread(target=reader, daemon=True)
        th.start()
        for _ in range(samples):
            out.write(time.perf_counter_ns())
            time.sleep(0.0005)
        done.set()
        th.join(5.0)
        rows.append((f"cross-thread latency, {mode}", f"p50 {pct(lat, 0.5):.0f} µs",
                     f"p99 {pct(lat, 0.99):.0f} µs (n={len(lat)})"))
    return rows


class Stamp(TaskContext):
    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.stamps: list[float] = []

    def update_hook(self) -> None:
        self.stamps.append(time.perf_counter())


def bench_periodic(duration: float) -> list[Row]:
    rows = []
    for hz in (1000, 500, 100):
        for ntasks in (1, 20):
            period = 1.0 / hz
            tasks = [Stamp(f"t{i}") for i in range(ntasks)]
            for t in tasks:
                t.set_activity(PeriodicActivity(period))
            for t in tasks:
                t.start()
            time.sleep(duration)  # the measurement window itself
            for t in tasks:
                t.stop()
            jitter = [
                abs((b - a) - period) * 1e6
                for t in tasks
                for a, b in zip(t.stamps, t.stamps[1:])
            ]
            overruns = sum(t.activity.overruns for t in tasks)
            cycles = sum(t.activity.cycles for t in tasks)
            rows.append((
                f"PeriodicActivity {hz} Hz x {ntasks} task{'s' if ntasks > 1 else ''}",
                f"jitter p50 {pct(jitter, 0.5):.0f} / p99 {pct(jitter, 0.99):.0f} / "
                f"max {max(jitter, default=0):.0f} µs",
                f"overruns {overruns} of {cycles} cycles",
            ))
    return rows


def bench_fanout(n: int) -> list[Row]:
    rows = []
    for readers in (1, 10, 100):
        out = OutputPort(float, "o")
        inps = [InputPort(float, f"i{k}") for k in range(readers)]
        for inp in inps:
            out.connect_to(inp, ConnPolicy.data())
        write = out.write

        def loop(k: int) -> None:
            for _ in range(k):
                write(1.0)

        ns = per_op_ns(loop, max(200, n // readers))
        rows.append((f"fan-out DATA write to {readers} reader(s)", f"{ns / 1e3:.2f} µs/write",
                     f"{ns / readers:.0f} ns per reader"))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short runs (about 10 s in all)")
    parser.add_argument("--smoke", action="store_true", help="a few seconds: that every path runs")
    args = parser.parse_args(argv)
    n, duration, samples = (5_000, 0.2, 50) if args.smoke else (50_000, 1.0, 300) if args.quick else (300_000, 5.0, 2000)
    rows = bench_costs(n) + bench_latency(samples)
    rows += bench_periodic(duration) + bench_fanout(n // 5)
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    print(f"Python {sys.version.split()[0]}, switch interval {sys.getswitchinterval() * 1e3:.0f} ms"
          f"{' (smoke)' if args.smoke else ' (quick)' if args.quick else ''}")
    print(f"| {'measure'.ljust(w0)} | {'result'.ljust(w1)} | note")
    print(f"|{'-' * (w0 + 2)}|{'-' * (w1 + 2)}|------")
    for a, b, c in rows:
        print(f"| {a.ljust(w0)} | {b.ljust(w1)} | {c}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
