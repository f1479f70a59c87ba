"""Benchmark of scart's same-host hop against rospy's and a raw socket's, in one run.

Usage: ``python benchmarks/bench_hop.py [--quick | --smoke]``. Not a test: the test suite
runs its ``--smoke`` (that every path works), never for numbers.

Each hop is a publisher process and a subscriber process. The publisher writes
``time.monotonic_ns()`` at 1 kHz and at 100 Hz on absolute deadlines; the subscriber
records arrival − stamp; the first second is discarded. Alternating in each round:

- **rospy → rospy** (Debian's ``python3-rospy``: ``std_msgs/Int64``, ``queue_size=1``,
  ``tcp_nodelay``; a ``rosmaster --core`` on a free port) — skipped, and said, when rospy
  is missing;
- **scart, default transport** (``auto``: ipc on one host) and **scart, grpc**: a link from
  an ``int`` output port in one deployer process to an event input port in another; the
  arrival is taken where the sample is stored (the reader end's thread: "callback") and
  where the task's ``update_hook`` reads it (one hand-over later: "task");
- the **raw Python Unix-socket RTT/2** (``SOCK_SEQPACKET`` ping-pong at the same rate).

Prints one markdown table: p50 and p99 per hop and rate, the ratios to rospy → rospy in
the same run (issue 21's goal: p50 and p99 ≤ rospy's) and to the raw socket (p50 ≤ 3×).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import paced, pct, raw_socket_rtt2, wait_until  # noqa: E402

from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext  # noqa: E402


class HopSource(TaskContext):
    out = OutputPort(int, doc="time.monotonic_ns() when written")


class HopSink(TaskContext):
    """Records arrival − stamp where each sample is stored and where the task reads it."""

    inp = InputPort(int, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.stored: list[int] = []
        self.read: list[tuple[int, int]] = []
        self.inp.add_data_callback(self._stored)

    def _stored(self, _port: InputPort) -> None:  # the reader end's thread: when the sample was stored
        self.stored.append(time.monotonic_ns())

    def update_hook(self) -> None:  # the task's thread: one hand-over later
        for _ in range(10_000):
            flow, stamp = self.inp.read()
            if flow.name != "NEW_DATA":
                return
            self.read.append((time.monotonic_ns(), stamp))


def sink_child(count: int, warmup: float) -> None:
    """The subscriber process: serve a ``hop`` sink (embedded name service), say where,
    and once ``count`` samples came (or 2 s of nothing) print the latencies (ns); serve
    on until stdin closes."""
    deployer = Deployer()
    sink = deployer.add(HopSink("hop"))
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0")
    print("ready", server.address, flush=True)
    last, seen = -1, time.monotonic()
    deadline = time.monotonic() + 300
    while len(sink.read) < count and time.monotonic() < deadline:
        if len(sink.read) != last:
            last, seen = len(sink.read), time.monotonic()
        elif sink.read and time.monotonic() - seen > 2.0:
            break
        time.sleep(0.01)
    first = sink.read[0][1] if sink.read else 0
    task = [a - s for a, s in sink.read if s - first >= warmup * 1e9]
    stored = sink.stored[: len(sink.read)]  # in order, one per sample read
    callback = [a - s for a, (_, s) in zip(stored, sink.read) if s - first >= warmup * 1e9]
    print(json.dumps({"task": task, "callback": callback}), flush=True)
    sys.stdin.read()  # until the parent closes it: the source (registered here) has ended by then
    server.stop()
    deployer.stop_all()


def source_child(ns: str, transport: str, rate: float, count: int) -> None:
    """The publisher process: link ``src.out`` to ``hop.inp`` over ``transport``, then write."""
    from dataflow.remote import connect

    deployer = Deployer()
    src = deployer.add(HopSource("src"))
    server = deployer.serve("127.0.0.1:0", ns=ns)
    try:
        with connect(ns, timeout=5.0) as system:
            system.connect_ports("src.out", "hop.inp", ConnPolicy.buffer(100).with_(transport=transport), name="hop")
            if not wait_until(lambda: any(_carried(lk.transport, transport) for lk in system.links()), 10):
                raise SystemExit(f"the link did not come up over {transport}")
        paced(count, rate, lambda k: src.out.write(time.monotonic_ns()))
        time.sleep(0.5)
    finally:
        server.stop()


def _carried(shown: str, transport: str) -> bool:
    """A link shown with ``shown`` is up over ``transport`` (``auto``: over any; a link not
    up yet shows its policy's transport with a ``?``)."""
    return not shown.endswith("?") and shown != "local" and transport in ("auto", shown)


def scart_hop(transport: str, rate: float, seconds: float, warmup: float) -> dict[str, list[float]]:
    """One scart hop: latencies (µs) where stored ("callback") and where read ("task")."""
    count = int(rate * (seconds + warmup))
    sink = subprocess.Popen([sys.executable, __file__, "--sink", str(count), str(warmup)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert sink.stdout is not None
        line = sink.stdout.readline().split()
        if line[:1] != ["ready"]:
            raise RuntimeError("the scart sink did not start")
        subprocess.run([sys.executable, __file__, "--source", line[1], transport, str(rate), str(count)], check=True,
                       timeout=count / rate + 120)
        out, _ = sink.communicate(timeout=120)
    finally:
        if sink.poll() is None:
            sink.kill()
            sink.wait()
    found = json.loads(out.strip().splitlines()[-1])
    return {where: [ns / 1000 for ns in values] for where, values in found.items()}


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one round of 3 s hops")
    parser.add_argument("--smoke", action="store_true", help="one short round (proves every path works)")
    parser.add_argument("--sink", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--source", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.sink:
        sink_child(int(args.sink[0]), float(args.sink[1]))
        return 0
    if args.source:
        ns, transport, rate, count = args.source
        source_child(ns, transport, float(rate), int(count))
        return 0
    rounds, seconds, warmup = (1, 0.5, 0.2) if args.smoke else (1, 2.0, 1.0) if args.quick else (3, 5.0, 1.0)
    import bench_ros1

    rospy = shutil.which("rosmaster") is not None and bench_ros1._has_rospy()  # noqa: SLF001
    if not rospy:
        print("rospy is missing (Debian: apt-get install ros-core python3-rospy): its rows are not measured")
    samples: dict[tuple[float, str], list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        bench = None
        if rospy:
            script = Path(tmp) / "rospy_peer.py"
            script.write_text(bench_ros1.ROSPY_PEER)
            bench = bench_ros1.Bench(Path(tmp), script)
            bench.start_master()
        try:
            for _ in range(rounds):
                for rate in (1000.0,) if args.smoke else (1000.0, 100.0):
                    if bench is not None:
                        samples.setdefault((rate, "rospy → rospy"), []).extend(
                            bench.hop("rospy", "rospy", rate, seconds, warmup))
                    for transport in ("auto", "grpc"):
                        found = scart_hop(transport, rate, seconds, warmup)
                        label = "scart, default (ipc)" if transport == "auto" else "scart, grpc"
                        samples.setdefault((rate, f"{label}: stored"), []).extend(found["callback"])
                        samples.setdefault((rate, f"{label}: to the task"), []).extend(found["task"])
                    samples.setdefault((rate, "raw socket RTT/2"), []).extend(t * 1e6 for t in raw_socket_rtt2(rate, int(rate * seconds)))
        finally:
            if bench is not None:
                bench.stop_master()
    print_table(samples, rounds, seconds, warmup)
    return 0


def print_table(samples: dict[tuple[float, str], list[float]], rounds: int, seconds: float, warmup: float) -> None:
    print(f"\nSame-host hop, stamp → reader, {rounds} round(s) of {seconds:g} s per hop (first {warmup:g} s "
          f"discarded), alternating; {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}\n")
    print("| rate | hop | samples | p50 µs | p99 µs | p50 / rospy | p99 / rospy | p50 / raw RTT/2 |")
    print("|---|---|---|---|---|---|---|---|")
    for (rate, hop), values in sorted(samples.items(), key=lambda kv: (-kv[0][0], kv[0][1])):
        rospy = samples.get((rate, "rospy → rospy"))
        raw = samples.get((rate, "raw socket RTT/2"))
        ratio = (lambda base, q: f"{pct(values, q) / pct(base, q):.2f}×" if base else "—")
        print(f"| {rate:g} Hz | {hop} | {len(values)} | {pct(values, 0.5):.0f} | {pct(values, 0.99):.0f} | "
              f"{ratio(rospy, 0.5)} | {ratio(rospy, 0.99)} | {ratio(raw, 0.5)} |")


if __name__ == "__main__":
    raise SystemExit(main())
