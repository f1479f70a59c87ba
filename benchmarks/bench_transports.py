"""Benchmark of the data-flow transports between two processes on one host, against a raw
Unix-socket baseline measured in the same run.

Usage: ``python benchmarks/bench_transports.py [--quick | --smoke]`` (``--smoke``: a few
seconds, that every path runs). This process hosts the name
service and the tasks ``src`` (an output port) and ``sink`` (an input port); a child
process (this script with ``--child NS``) hosts ``mirror``, whose input port's data
callback writes each value straight to its output port. The links ``src.out →
mirror.inp`` and ``mirror.out → sink.inp`` cross the two processes with the transport of
the row, so a sample's one-way port → port time is half its round trip. Prints one
markdown table. Not a test: numbers depend on the machine.

Rows:
- round trip / 2 at 100 Hz and 1 kHz (periodic writes on absolute deadlines): p50 / p99;
  baseline: a raw ``SOCK_SEQPACKET`` round trip / 2 between two Python processes
  (blocking ``recv`` on both sides), at the same rate, the same number of times;
- the 1 kHz loop split over the two processes (sensor → controller → back): the share of
  cycles whose answer came back within the period;
- throughput of one connection (``src.out → mirror.inp`` only, BUFFER(10000), written as
  fast as one thread can): samples/s the mirror received (its output's write number,
  read over gRPC), and drops. A writer flat out holds its process's GIL, so its own
  io thread, which sends what waited for room, gets the GIL only every switch interval
  (5 ms): this row is the link under overload, with drops;
- sustained throughput of one connection: the same, written at a set rate (a burst each
  millisecond, on absolute deadlines) for 2 s: what a connection carries without loss
  (issue 21's goal: 100,000 samples/s).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import paced, pct, raw_socket_rtt2, wait_until  # noqa: E402

from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext  # noqa: E402
from dataflow.remote import connect  # noqa: E402

BURST_S = 0.001  #: a paced throughput row writes its samples in a burst this often


class Source(TaskContext):
    out = OutputPort(int, doc="a sequence number")


class Sink(TaskContext):
    inp = InputPort(int, doc="the sequence number back")


class Mirror(TaskContext):
    """Writes what it reads, in the thread that delivered it (no activity hop)."""

    inp = InputPort(int)
    out = OutputPort(int)

    def echo(self, port: InputPort) -> None:
        for _ in range(10_000):
            status, value = port.read()
            if status is not FlowStatus.NEW_DATA:
                return
            self.out.write(value)


def child(ns: str) -> int:
    """The mirror's process: serve it with the name service ``ns`` until stdin closes."""
    deployer = Deployer()
    mirror = deployer.add(Mirror("mirror"))
    mirror.inp.add_data_callback(mirror.echo)
    server = deployer.serve("127.0.0.1:0", ns=ns)
    print("ready", flush=True)
    sys.stdin.read()
    server.stop()
    return 0


def round_trips(src: Source, sink: Sink, rate: float, n: int) -> tuple[list[float], float]:
    """One-way times (s) of ``n`` writes at ``rate`` Hz, and the share of cycles answered
    within the period."""
    sent: dict[int, float] = {}
    back: dict[int, float] = {}
    done = threading.Event()

    def on_back(port: InputPort) -> None:
        for _ in range(10_000):
            status, value = port.read()
            if status is not FlowStatus.NEW_DATA:
                return
            back[value] = time.perf_counter()
            if len(back) >= n:
                done.set()

    sink.inp.add_data_callback(on_back)
    base = 1_000_000 * int(rate)  # distinct values per row

    def write(k: int) -> None:
        sent[base + k] = time.perf_counter()
        src.out.write(base + k)

    try:
        paced(n, rate, write)
        done.wait(10)
    finally:
        sink.inp.remove_data_callback(on_back)
    one_way = [(back[v] - t) / 2 for v, t in sent.items() if v in back]
    in_time = sum(1 for v, t in sent.items() if v in back and back[v] - t <= 1.0 / rate) / n
    return one_way, in_time


def throughput(system: object, src: Source, transport: str, n: int, rate: float = 0.0) -> tuple[float, int, int]:
    """(samples/s received by the mirror, drops, received) for ``n`` writes: flat out
    (``rate`` 0), or paced at ``rate`` samples/s in bursts of :data:`BURST_S` (on absolute
    deadlines). The mirror's output port's write number counts what it received."""
    system.connect_ports("src.out", "mirror.inp", ConnPolicy.buffer(10_000).with_(transport=transport),  # type: ignore[attr-defined]
                         name="flat")
    proxy = system.component("mirror")  # type: ignore[attr-defined]
    wait_until(lambda: any(lk.name == "flat" and lk.transport == transport for lk in system.links()), 10)  # type: ignore[attr-defined]
    start = proxy.read_sample_of("out")[2]
    write = src.out.write
    t0 = time.perf_counter()
    if rate:
        burst = max(1, round(rate * BURST_S))

        def write_burst(b: int) -> None:
            for k in range(b * burst, min(n, (b + 1) * burst)):
                write(k)

        paced(-(-n // burst), rate / burst, write_burst)
    else:
        for k in range(n):
            write(k)
    last = [start, time.perf_counter()]

    def arrived() -> bool:
        seq = proxy.read_sample_of("out")[2]
        if seq != last[0]:
            last[:] = [seq, time.perf_counter()]
        return seq - start >= n or time.perf_counter() - last[1] > 2.0  # all, or nothing more for 2 s

    wait_until(arrived, 60, 0.002)
    got = last[0] - start
    elapsed = last[1] - t0
    dropped = next(lk.dropped for lk in system.links() if lk.name == "flat")  # type: ignore[attr-defined]
    system.disconnect_link("flat")  # type: ignore[attr-defined]
    return got / elapsed, dropped, got


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer samples")
    parser.add_argument("--smoke", action="store_true", help="a few samples: that every path runs")
    parser.add_argument("--child", metavar="NS", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        return child(args.child)
    n100, n1k, nflat = (20, 100, 500) if args.smoke else (200, 1000, 5000) if args.quick else (500, 3000, 20000)
    sustain_s, rates = (0.05, (10_000,)) if args.smoke else (1.0, (100_000,)) if args.quick else \
        (2.0, (50_000, 100_000, 150_000))

    deployer = Deployer()
    src = deployer.add(Source("src"))
    sink = deployer.add(Sink("sink"))
    server = deployer.serve("127.0.0.1:0")
    proc = subprocess.Popen([sys.executable, __file__, "--child", server.address], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    rows = []
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
        raw50 = {}
        for rate, n in ((100.0, n100), (1000.0, n1k)):
            raw = raw_socket_rtt2(rate, n)
            raw50[rate] = pct(raw, 0.5)
            rows.append(("raw SEQPACKET RTT/2 (baseline)", f"{rate:g} Hz", raw50[rate], pct(raw, 0.99), "", "", "1.00"))
        with connect(server.address, timeout=5.0) as system:
            for transport in ("ipc", "grpc"):
                policy = ConnPolicy.buffer(1000).with_(transport=transport)
                system.connect_ports("src.out", "mirror.inp", policy, name="there")
                system.connect_ports("mirror.out", "sink.inp", policy, name="back")
                ok = wait_until(lambda: {lk.transport for lk in system.links() if lk.name in ("there", "back")}
                                == {transport}, 10)
                if not ok:
                    raise SystemExit(f"the links did not come up over {transport}: {system.links()}")
                round_trips(src, sink, 200.0, min(100, n100))  # warm-up
                for rate, n in ((100.0, n100), (1000.0, n1k)):
                    one_way, in_time = round_trips(src, sink, rate, n)
                    p50, p99 = pct(one_way, 0.5), pct(one_way, 0.99)
                    rows.append((f"{transport}: port → port (RTT/2)", f"{rate:g} Hz", p50, p99,
                                 f"{len(one_way)}/{n}", f"{in_time:.1%}", f"{p50 / raw50[rate]:.2f}"))
                system.disconnect_link("there")
                system.disconnect_link("back")
                flat, dropped, got = throughput(system, src, transport, nflat)
                rows.append((f"{transport}: throughput, one connection", "flat out", None, None,
                             f"{got}/{nflat} (drops {dropped})", f"{flat:,.0f}/s", ""))
                for rate in rates:
                    n = int(rate * sustain_s)
                    paced_rate, dropped, got = throughput(system, src, transport, n, rate)
                    rows.append((f"{transport}: sustained, one connection", f"{rate:,}/s", None, None,
                                 f"{got}/{n} (drops {dropped})", f"{paced_rate:,.0f}/s", ""))
    finally:
        if proc.stdin is not None:
            proc.stdin.close()
        proc.wait(timeout=30)
        server.stop()
    print(f"\nTransports between two processes on one host ({os.cpu_count()} CPUs); ratios to the raw "
          "socket's p50 at the same rate, same run\n")
    print("| measure | rate | p50 | p99 | received | in period / rate | p50 ratio |")
    print("|---|---|---|---|---|---|---|")
    for name, rate, p50, p99, got, extra, ratio in rows:
        us = (lambda v: f"{v * 1e6:.1f} µs" if v is not None else "—")
        print(f"| {name} | {rate} | {us(p50)} | {us(p99)} | {got} | {extra} | {ratio} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
