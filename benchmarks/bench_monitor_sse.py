"""Benchmark of the youBot Monitor under many SSE clients: does ``GET /api/state`` stay fast?

Usage: ``python benchmarks/bench_monitor_sse.py [--quick | --smoke] [--clients 200] [--requests 200]``
(``--quick``: 100 clients, 100 requests; ``--smoke``: 10 and 20, that it runs).
Not a test: numbers depend on the machine. Prints one markdown table.

A `MonitorServer` is fed by the demo's `SyntheticArm` (a status every 10 ms, so every
stream carries the full 25 updates/s). Phases, in one run:

1. baseline: no stream open; ``--requests`` sequential ``GET /api/state`` (a new
   connection each, as the server speaks HTTP/1.0), latency p50 / p99;
2. ``--clients`` streams open (raw sockets, drained by one reader thread), the same again;
3. the server's cap (`MAX_SSE_CLIENTS`) filled and 20 more attempted: how many got 503,
   and the latency at the cap.

Ratios are against the baseline of the same run. Every thread started is joined.
"""

from __future__ import annotations

import argparse
import http.client
import selectors
import socket
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from _common import pct, wait_until

from scart_monitor import MonitorServer
from scart_monitor.demo import SyntheticArm
from scart_monitor.server import MAX_SSE_CLIENTS


class Streams:
    """Raw ``GET /events`` sockets, drained by one reader thread (created in `__init__`,
    joined in `close`); counts frames and the streams whose answer was not 200."""

    def __init__(self) -> None:
        self._sel = selectors.DefaultSelector()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.socks: list[socket.socket] = []
        self.status: dict[int, bytes] = {}  # fileno → status line
        self.frames = 0
        self._thread = threading.Thread(target=self._drain, name="bench-sse-reader", daemon=True)
        self._thread.start()

    def open(self, port: int) -> None:
        sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        sock.sendall(f"GET /events HTTP/1.0\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        sock.setblocking(False)
        with self._lock:
            self.socks.append(sock)
            self._sel.register(sock, selectors.EVENT_READ)

    def answered(self) -> int:
        with self._lock:
            return len(self.status)

    def refused(self) -> int:
        with self._lock:
            return sum(1 for line in self.status.values() if b" 200 " not in line)

    def _drain(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                ready = self._sel.select(timeout=0) if self._sel.get_map() else []
            if not ready:
                self._stop.wait(0.005)  # poll period of the reader, not synchronisation
                continue
            for key, _ in ready:
                self._read(key.fileobj)

    def _read(self, sock: socket.socket) -> None:
        try:
            data = sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        with self._lock:
            if sock.fileno() not in self.status and data:
                self.status[sock.fileno()] = data.split(b"\r\n", 1)[0]
            self.frames += data.count(b"event: update")
            if not data:
                self._sel.unregister(sock)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        for sock in self.socks:
            sock.close()
        self._sel.close()


def latencies(port: int, n: int) -> list[float]:
    """``n`` sequential ``GET /api/state`` round trips (connect → full body), in seconds."""
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        conn.request("GET", "/api/state")
        resp = conn.getresponse()
        resp.read()
        conn.close()
        assert resp.status == 200, resp.status
        out.append(time.perf_counter() - t0)
    return out


def measure(port: int, n: int, streams: Streams | None) -> tuple[float, float, float]:
    """(p50 s, p99 s, frames/s delivered to the streams meanwhile)."""
    frames0, t0 = (streams.frames if streams else 0), time.monotonic()
    values = latencies(port, n)
    rate = ((streams.frames - frames0) / (time.monotonic() - t0)) if streams else 0.0
    return pct(values, 0.5), pct(values, 0.99), rate


def open_streams(streams: Streams, port: int, count: int) -> None:
    target = len(streams.socks) + count
    for _ in range(count):
        streams.open(port)
    if not wait_until(lambda: streams.answered() >= target, 30):
        raise SystemExit(f"only {streams.answered()} of {target} streams answered")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=None, help="streams open in phase 2 (default 200)")
    parser.add_argument("--requests", type=int, default=None, help="requests per phase (default 200)")
    parser.add_argument("--quick", action="store_true", help="100 clients, 100 requests")
    parser.add_argument("--smoke", action="store_true", help="10 clients, 20 requests: that it runs")
    args = parser.parse_args(argv)
    clients, requests = (10, 20) if args.smoke else (100, 100) if args.quick else (200, 200)
    args.clients, args.requests = args.clients or clients, args.requests or requests
    arm = SyntheticArm(period=0.01)
    server = MonitorServer(arm)
    streams: Streams | None = None
    rows = []
    try:
        server.start()
        arm.start(server)
        port = int(server.url.rsplit(":", 1)[1].strip("/"))
        latencies(port, 20)  # warm-up
        rows.append(("baseline", 0, 0, *measure(port, args.requests, None)))
        streams = Streams()
        open_streams(streams, port, args.clients)
        rows.append((f"{args.clients} streams", args.clients, streams.refused(),
                     *measure(port, args.requests, streams)))
        extra = MAX_SSE_CLIENTS - args.clients + 20
        open_streams(streams, port, extra)
        opened = args.clients + extra
        rows.append((f"cap ({MAX_SSE_CLIENTS}) + 20", opened - streams.refused(), streams.refused(),
                     *measure(port, args.requests, streams)))
    finally:
        if streams is not None:
            streams.close()
        arm.stop()
        server.stop()
    base50, base99 = rows[0][3], rows[0][4]
    print(f"GET /api/state latency, {args.requests} requests per phase (SyntheticArm at 100 Hz)\n")
    print("| phase | streams served | refused (503) | p50 ms | p99 ms | p50 × base | p99 × base | SSE frames/s |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, served, refused, p50, p99, rate in rows:
        print(f"| {name} | {served} | {refused} | {p50 * 1e3:.2f} | {p99 * 1e3:.2f} | "
              f"{p50 / base50:.2f} | {p99 / base99:.2f} | {rate:.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
