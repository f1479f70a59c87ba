"""Do the bounds hold under load? gRPC health latency of a deployer while it carries 10 000
name registrations, 2000 remote writers, and 200 SSE clients of a youBot Monitor in the
same process; and how long 2000 writers take to come and go, and a server holding 3000
to stop.

Run: ``python benchmarks/bench_security.py [--quick | --smoke] [--checks 300]`` (prints a
table; no assertions; ``--quick``: a quarter of every load, ``--smoke``: a fiftieth, that
every path runs). Latencies are p50 / p99 of ``--checks`` health checks on one channel, as
ratios against the idle server of the same run (goal: under 50 ms at p99).
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import grpc

ROOT = Path(__file__).resolve().parent.parent
for extra in (ROOT, ROOT / "tests", ROOT / "composites" / "youbot"):
    if str(extra) not in sys.path:
        sys.path.insert(0, str(extra))

from _common import pct  # noqa: E402
from bench_monitor_sse import Streams, open_streams  # noqa: E402
from grpc_health.v1 import health_pb2, health_pb2_grpc  # noqa: E402

from scart_monitor import MonitorServer  # noqa: E402
from scart_monitor.demo import SyntheticArm  # noqa: E402
from dataflow import Deployer  # noqa: E402
from dataflow.remote._proto import df as pb  # noqa: E402
from dataflow.remote._proto import df_grpc  # noqa: E402
from dataflow.remote.naming import NameClient  # noqa: E402
from support.remote import Pinger  # noqa: E402


def health(address: str, checks: int) -> tuple[float, float]:
    """p50 and p99 (ms) of ``checks`` health checks over one channel."""
    times = []
    with grpc.insecure_channel(address) as channel:
        stub = health_pb2_grpc.HealthStub(channel)
        stub.Check(health_pb2.HealthCheckRequest(), timeout=5)
        for _ in range(checks):
            start = time.perf_counter()
            stub.Check(health_pb2.HealthCheckRequest(), timeout=5)
            times.append((time.perf_counter() - start) * 1000)
    return pct(times, 0.5), pct(times, 0.99)


def open_writers(stub: df_grpc.DeployerServiceStub, n: int, port: str = "input") -> tuple[list[str], float]:
    """``n`` writers opened on ``p.PORT`` with up to 16 calls in flight; (ids, seconds)."""
    start = time.perf_counter()
    request = pb.OpenWriterRequest(task="p", port=port)
    with ThreadPoolExecutor(16) as pool:
        ids = list(pool.map(lambda _: stub.OpenWriter(request, timeout=10).writer, range(n)))
    return ids, time.perf_counter() - start


def bare_calls(address: str, n: int) -> float:
    """Seconds for ``n`` health checks with up to 16 in flight: the unary-call baseline."""
    with grpc.insecure_channel(address) as channel:
        stub = health_pb2_grpc.HealthStub(channel)
        start = time.perf_counter()
        with ThreadPoolExecutor(16) as pool:
            list(pool.map(lambda _: stub.Check(health_pb2.HealthCheckRequest(), timeout=10), range(n)))
        return time.perf_counter() - start


def close_writers(stub: df_grpc.DeployerServiceStub, ids: list[str]) -> float:
    start = time.perf_counter()
    with ThreadPoolExecutor(16) as pool:
        list(pool.map(lambda w: stub.CloseWriter(pb.CloseWriterRequest(writer=w), timeout=10), ids))
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checks", type=int, default=None, help="health checks per row (default 300)")
    parser.add_argument("--quick", action="store_true", help="a quarter of every load")
    parser.add_argument("--smoke", action="store_true", help="a fiftieth of every load: that every path runs")
    args = parser.parse_args()
    scale = 0.02 if args.smoke else 0.25 if args.quick else 1.0

    def sized(n: int) -> int:
        return max(1, int(n * scale))

    args.checks = args.checks or sized(300) + (20 if args.smoke else 0)
    names_n, writers_n, held_n = sized(10_000), sized(2000), sized(1500)
    rows: list[tuple[str, float, float, str]] = []
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0")
    channel = grpc.insecure_channel(server.address)
    stub = df_grpc.DeployerServiceStub(channel)
    monitor = arm = streams = None
    try:
        base = health(server.address, args.checks)
        rows.append(("idle deployer (baseline)", *base, ""))

        names = NameClient(server.address, timeout=10)
        start = time.perf_counter()
        for i in range(0, names_n, 100):  # 10 000 names (full), 100 per registration
            names.register(f"127.0.0.1:{20000 + i}", [f"n{i + k}" for k in range(100)])
        took = time.perf_counter() - start
        rows.append((f"+ {names_n:,} names registered", *health(server.address, args.checks),
                     f"registered in {took:.2f} s; {len(names.entries())} listed"))
        names.close()

        bare = bare_calls(server.address, 2 * writers_n)
        ids, opened = open_writers(stub, writers_n)
        rows.append((f"+ {writers_n} remote writers open", *health(server.address, args.checks),
                     f"{writers_n} opened in {opened:.2f} s"))
        closed = close_writers(stub, ids)
        rows.append((f"  {writers_n} writers closed", *health(server.address, args.checks),
                     f"closed in {closed:.2f} s; open+close {(opened + closed) / bare:.2f}x {2 * writers_n} bare "
                     f"health calls ({bare:.2f} s, same concurrency)"))

        arm = SyntheticArm()
        monitor = MonitorServer(arm)
        monitor.start()
        arm.start(monitor)
        streams = Streams()
        port = int(monitor.url.rsplit(":", 1)[1].strip("/"))
        open_streams(streams, port, sized(200))
        rows.append((f"+ {sized(200)} SSE clients of a monitor", *health(server.address, args.checks),
                     f"{len(streams.socks)} streams"))
    finally:
        if streams is not None:
            streams.close()
        if arm is not None:
            arm.stop()
        if monitor is not None:
            monitor.stop()
        channel.close()
        server.stop()

    deployer2 = Deployer()
    deployer2.add(Pinger("p"))
    server2 = deployer2.serve("127.0.0.1:0")
    own = [("grpc.use_local_subchannel_pool", 1)]  # two clients: 2048 writers at most per port and per peer
    with grpc.insecure_channel(server2.address, options=own) as one, \
            grpc.insecure_channel(server2.address, options=own) as two:
        open_writers(df_grpc.DeployerServiceStub(one), held_n, "input")
        open_writers(df_grpc.DeployerServiceStub(two), held_n, "samples")
    start = time.perf_counter()
    server2.stop()
    stop_took = time.perf_counter() - start

    p50_0, p99_0 = rows[0][1], rows[0][2]
    print(f"{'load':<34} {'health p50':>11} {'p99':>9} {'p50 ratio':>10} {'p99 ratio':>10}  note")
    for name, p50, p99, note in rows:
        print(f"{name:<34} {p50:8.2f} ms {p99:6.2f} ms {p50 / p50_0:9.2f}x {p99 / p99_0:9.2f}x  {note}")
    print(f"a deployer holding {2 * held_n} writers stops in {stop_took:.2f} s")


if __name__ == "__main__":
    main()
