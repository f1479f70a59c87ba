"""Benchmark of remote data-flow access against bare grpcio baselines measured in the same run.

Usage: ``python benchmarks/bench_remote.py [--quick | --smoke]`` (``--smoke``: a few
seconds, that every path runs). Everything runs in one process on
127.0.0.1 (server, task and client share the interpreter, as do the baselines), with the
youBot 5-joint status sample as payload (its registry encoding; the baselines send the
same bytes). Prints one markdown table. Not a test: numbers depend on the machine.

Rows:
- remote write → value read by the task (event port): p50/p99; baseline: bare unary call
  whose handler signals the waiting client;
- task write → observer called, push, at 100 Hz and 1 kHz, over each transport (``grpc``,
  ``ipc``): p50/p99; baseline: bare server streaming fed by a producer thread at the same rate,
  and the same stream carrying scart's codec (each sample encoded as sent, decoded as received),
  for the youBot status and, at 1 kHz, for a float64 sample (the codec floor);
- maximum sustained rate of one subscription (BUFFER(1000)); baseline: bare streaming;
- polling at 2× the task rate: latency and the share of wasted polls;
- 10 subscribers on one port at 100 Hz, the task in its own ``scart deploy`` process:
  per-subscriber rate, the jitter of the task's write times and its overruns (read
  remotely), with and without a stuck subscriber (goal: overrun delta 0).

Note: scart batches the samples pending when its sender wakes into one message; the bare
"flat out" stream sends one message per sample, so the throughput rows compare a
delivered rate at a given offered rate with the bare per-message ceiling.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import queue
import signal
import socket
import statistics
import struct
import subprocess
import sys
import threading
import time
from concurrent import futures
from pathlib import Path
from typing import Any

import grpc

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "composites" / "youbot"))  # a contribution, imported by plain names

from youbot_model import JointStatus, YouBotStatus
from scart_wire import codec
from dataflow import (
    ConnPolicy, Deployer, EventActivity, InputPort, OutputPort, PeriodicActivity, TaskContext, registry,
)
from dataflow.remote import connect

from _common import pct, wait_until

SAMPLE = YouBotStatus(
    joints=[JointStatus(position=0.1 * i, velocity=0.01, current=0.2, temperature=30.5, error_flags=3) for i in range(5)],
    timestamp=1.7e9, sequence=12345,
)
PAYLOAD = registry.encode(SAMPLE).data
Row = tuple[str, str, str, str]


def us(v: float) -> str:
    return f"{v * 1e6:.0f} µs"


# ---- tasks -----------------------------------------------------------------------------
class Sink(TaskContext):
    """Signals when it read a command (event port)."""

    commands = InputPort(YouBotStatus, event=True)

    def __init__(self) -> None:
        super().__init__("sink")
        self.got = threading.Event()

    def update_hook(self) -> None:
        status, _ = self.commands.read()
        if status.name == "NEW_DATA":
            self.got.set()


class Source(TaskContext):
    """Writes the status sample every cycle; records its cycle start times."""

    status = OutputPort(YouBotStatus)

    def __init__(self, name: str = "source") -> None:
        super().__init__(name)
        self.starts: list[float] = []

    def update_hook(self) -> None:
        self.starts.append(time.perf_counter())
        self.status.write(SAMPLE)


# ---- bare grpcio baselines -------------------------------------------------------------
class Bare:
    """A bare grpcio server: unary ``/b.B/U`` (signals an Event) and streaming ``/b.B/S``."""

    def __init__(self) -> None:
        self.got = threading.Event()
        self.feed: queue.Queue[bytes | None] = queue.Queue()
        self.flood = False
        ident = lambda b: b  # noqa: E731
        handlers = {
            "U": grpc.unary_unary_rpc_method_handler(self._unary, ident, ident),
            "S": grpc.unary_stream_rpc_method_handler(self._stream, ident, ident),
        }
        self.server = grpc.server(futures.ThreadPoolExecutor(8))
        self.server.add_generic_rpc_handlers([grpc.method_handlers_generic_handler("b.B", handlers)])
        self.port = self.server.add_insecure_port("127.0.0.1:0")
        self.server.start()

    def _unary(self, req: bytes, ctx: grpc.ServicerContext) -> bytes:
        self.got.set()
        return b""

    def _stream(self, req: bytes, ctx: grpc.ServicerContext):
        if self.flood:
            msg = struct.pack("<d", 0.0) + PAYLOAD
            while ctx.is_active() and self.flood:
                yield msg
            return
        while ctx.is_active():
            item = self.feed.get()
            if item is None:
                return
            yield item

    def stop(self) -> None:
        self.feed.put(None)
        self.server.stop(0.2).wait(5)


def bare_unary(n: int) -> list[float]:
    bare = Bare()
    lat = []
    with grpc.insecure_channel(f"127.0.0.1:{bare.port}") as ch:
        fn = ch.unary_unary("/b.B/U")
        for _ in range(n):
            bare.got.clear()
            t0 = time.perf_counter()
            fn(PAYLOAD, timeout=5)
            bare.got.wait(5)
            lat.append(time.perf_counter() - t0)
    bare.stop()
    return lat


def bare_stream(rate: float, seconds: float, with_codec: bool = False, sample: Any = SAMPLE) -> list[float]:
    """A bare server stream's latency carrying ``sample``; ``with_codec``: each sample
    encoded by scart's codec as it is sent and decoded (so checked) as it arrives, the
    floor of a checked transport (without: the registry's bytes of it, made once)."""
    payload, py_type = registry.encode(sample).data, type(sample)
    bare = Bare()
    lat: list[float] = []
    with grpc.insecure_channel(f"127.0.0.1:{bare.port}") as ch:
        call = ch.unary_stream("/b.B/S")(b"", timeout=seconds + 10)

        def produce() -> None:
            period, nxt = 1.0 / rate, time.perf_counter()
            end = nxt + seconds
            while nxt < end:
                now = struct.pack("<d", time.time())
                bare.feed.put(now + (codec.encode(sample, py_type).SerializeToString() if with_codec else payload))
                nxt += period
                time.sleep(max(0.0, nxt - time.perf_counter()))
            bare.feed.put(None)

        t = threading.Thread(target=produce)
        t.start()
        for msg in call:
            if with_codec:
                codec.decode(codec.Value.FromString(msg[8:]))
            lat.append(time.time() - struct.unpack("<d", msg[:8])[0])
        t.join()
    bare.stop()
    return lat


def bare_max_rate(seconds: float) -> float:
    bare = Bare()
    bare.flood = True
    n = 0
    with grpc.insecure_channel(f"127.0.0.1:{bare.port}") as ch:
        call = ch.unary_stream("/b.B/S")(b"", timeout=seconds + 10)
        t0 = time.perf_counter()
        for _ in call:
            n += 1
            if time.perf_counter() - t0 >= seconds:
                break
        elapsed = time.perf_counter() - t0
        call.cancel()
    bare.flood = False
    bare.stop()
    return n / elapsed


# ---- scart measurements ----------------------------------------------------------------
def scart_write(n: int) -> list[float]:
    d = Deployer()
    sink = d.add(Sink())
    sink.set_activity(EventActivity())
    d.configure_all()
    d.start_all()
    server = d.serve()
    lat = []
    with connect(server.address) as system:
        proxy = system.component("sink")
        for _ in range(n):
            sink.got.clear()
            t0 = time.perf_counter()
            proxy.write("commands", SAMPLE)
            sink.got.wait(5)
            lat.append(time.perf_counter() - t0)
    server.stop()
    d.stop_all()
    d.cleanup_all()
    return lat


def scart_push(rate: float, seconds: float, period: float | None = None,
               transport: str = "grpc") -> tuple[list[float], object]:
    d = Deployer()
    src = d.add(Source())
    src.set_activity(PeriodicActivity(1.0 / rate))
    d.configure_all()
    server = d.serve()
    lat: list[float] = []
    with connect(server.address) as system:
        sub = system.component("source").subscribe(
            "status", lambda e: lat.append(time.time() - e.source_time),
            policy=ConnPolicy.buffer(100).with_(transport=transport), period=period,
        )
        d.start_all()
        threading.Event().wait(seconds)
        d.stop_all()
        sub.close()
        stats = sub
    server.stop()
    d.cleanup_all()
    return lat[1:], stats


def scart_max_rate(seconds: float, offered: float, transport: str = "grpc") -> tuple[float, int, int]:
    """The task's port written at ``offered`` samples/s (bursts every 1 ms); returns
    (delivered/s, delivered, dropped) for one BUFFER(1000) subscription."""
    d = Deployer()
    src = d.add(Source())
    server = d.serve()
    n = [0]
    stop = threading.Event()
    with connect(server.address) as system:
        sub = system.component("source").subscribe("status", lambda e: n.__setitem__(0, n[0] + 1),
                                                   policy=ConnPolicy.buffer(1000).with_(transport=transport))

        def produce() -> None:
            burst = max(1, int(offered / 1000))
            nxt = time.perf_counter()
            while not stop.is_set():
                for _ in range(burst):
                    src.status.write(SAMPLE)
                nxt += burst / offered
                time.sleep(max(0.0, nxt - time.perf_counter()))

        t = threading.Thread(target=produce)
        t0 = time.perf_counter()
        t.start()
        threading.Event().wait(seconds)
        stop.set()
        t.join()
        wait_until(lambda: sub.delivered + sub.dropped >= n[0], timeout=2.0, interval=0.01)  # the in-flight flush
        elapsed = time.perf_counter() - t0
        got, dropped = n[0], sub.dropped
        sub.close()
    server.stop()
    return got / elapsed, got, dropped


def _deployer_process(period: float) -> tuple[subprocess.Popen, str]:
    """``scart deploy bench_remote:Source@source`` in its own process; returns (process, address)."""
    here = Path(__file__).resolve().parent
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(here), str(here.parent / "composites" / "youbot"), env.get("PYTHONPATH", "")])
    env.pop("SCART_NS", None)
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{sock.getsockname()[1]}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "scart", "deploy", "bench_remote:Source@source", "--period", str(period),
         "--listen", address], env=env, stderr=subprocess.PIPE, text=True,
    )
    for _ in range(50):
        line = proc.stderr.readline()
        if "serving" in line or not line:
            break
    if proc.poll() is not None:
        raise RuntimeError("scart deploy failed to start")
    return proc, address


def scart_fanout(seconds: float, subscribers: int, stuck: bool) -> tuple[float, float, int, float]:
    """The task in its own deployer process at 100 Hz; ``subscribers`` subscriptions from this
    process, each through a system proxy of its own (+ one whose observer never returns). Returns (min per-subscriber rate,
    jitter of the task's write times, overruns during the run, max period)."""
    proc, address = _deployer_process(0.01)
    counts = [0] * max(1, subscribers)
    stamps: list[float] = []
    hold = threading.Event()
    try:
        with contextlib.ExitStack() as stack:
            system = stack.enter_context(connect(address))
            proxy = system.component("source")
            probe = proxy.subscribe("status", lambda e: stamps.append(e.source_time), policy=ConnPolicy.buffer(1000))
            # one system proxy each, as separate processes: subscriptions alike of one proxy share a stream
            subs = [stack.enter_context(connect(address)).component("source").subscribe(
                "status", lambda e, i=i: counts.__setitem__(i, counts[i] + 1)) for i in range(subscribers)]
            if stuck:
                subs.append(proxy.subscribe("status", lambda e: hold.wait(), policy=ConnPolicy.buffer(4)))
            before = proxy.describe().overruns
            stamps.clear()
            counts[:] = [0] * len(counts)
            threading.Event().wait(seconds)
            overruns = proxy.describe().overruns - before
            hold.set()
            for sub in [probe, *subs]:
                sub.close()
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(10)
        proc.stderr.close()
    periods = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
    jitter = statistics.pstdev(periods) if len(periods) > 1 else 0.0
    rate = min(counts) / seconds if subscribers else len(stamps) / seconds
    return rate, jitter, overruns, max(periods) if periods else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--smoke", action="store_true", help="a few seconds: that every path runs")
    args = ap.parse_args()
    secs, n = (0.2, 30) if args.smoke else (1.5, 300) if args.quick else (4.0, 1500)
    offers = (2000,) if args.smoke else (2000, 5000, 10000, 20000)
    rows: list[Row] = []

    b, s = bare_unary(n), scart_write(n)
    rows.append(("remote write → read by task, p50", us(pct(s, 0.5)), us(pct(b, 0.5)) + " (bare unary)", f"{pct(s, 0.5) / pct(b, 0.5):.2f}×"))
    rows.append(("remote write → read by task, p99", us(pct(s, 0.99)), us(pct(b, 0.99)), f"{pct(s, 0.99) / pct(b, 0.99):.2f}×"))
    for rate in (100, 1000):
        b = bare_stream(rate, secs)
        bc = bare_stream(rate, secs, with_codec=True)
        rows.append((f"push {rate} Hz bare stream + scart codec (encode, decode), p50", us(pct(bc, 0.5)),
                     us(pct(b, 0.5)) + " (bare stream)", f"{pct(bc, 0.5) / pct(b, 0.5):.2f}× (the codec floor; goal ≤ 1.15×)"))
        if rate == 1000:
            fb, fbc = bare_stream(rate, secs, sample=1.5), bare_stream(rate, secs, with_codec=True, sample=1.5)
            rows.append((f"push {rate} Hz bare stream + scart codec, a float64 sample, p50", us(pct(fbc, 0.5)),
                         us(pct(fb, 0.5)) + " (bare stream, 8 bytes)",
                         f"{pct(fbc, 0.5) / pct(fb, 0.5):.2f}× (the codec floor; goal ≤ 1.15×)"))
        for transport in ("grpc", "ipc"):
            s, _ = scart_push(rate, secs, transport=transport)
            rows.append((f"push {rate} Hz task write → observer ({transport}), p50", us(pct(s, 0.5)),
                         us(pct(b, 0.5)) + " (bare stream)",
                         f"{pct(s, 0.5) / pct(b, 0.5):.2f}×; {pct(s, 0.5) / pct(bc, 0.5):.2f}× bare + codec (goal ≤ 1.3×)"))
            rows.append((f"push {rate} Hz ({transport}), p99", us(pct(s, 0.99)), us(pct(b, 0.99)),
                         f"{pct(s, 0.99) / pct(b, 0.99):.2f}×"))
    bm = bare_max_rate(secs)
    for transport in ("grpc", "ipc"):
        for offered in offers:
            rate, got, dropped = scart_max_rate(secs, offered, transport)
            rows.append((f"one subscription ({transport}), task writing {offered:,}/s",
                         f"{rate:,.0f} /s delivered ({dropped} dropped)",
                         f"{bm:,.0f} /s (bare stream, flat out)", "goal: sustain ≥ 5,000 /s"))
    s, sub = scart_push(100, secs, period=0.005)
    wasted = sub.wasted_polls / max(1, sub.polls)
    rows.append(("polling at 2× (100 Hz task, 5 ms), latency p50/p99", f"{us(pct(s, 0.5))} / {us(pct(s, 0.99))}", "-",
                 f"wasted polls {wasted:.0%} ({sub.wasted_polls}/{sub.polls})"))
    r0, j0, o0, m0 = scart_fanout(secs, 0, False)
    r1, j1, o1, m1 = scart_fanout(secs, 10, False)
    r2, j2, o2, m2 = scart_fanout(secs, 10, True)
    rows.append(("deployer process, task 100 Hz, 1 probe subscriber: jitter / overruns", f"{us(j0)} / {o0}", "-",
                 f"max period {m0 * 1e3:.1f} ms"))
    rows.append(("+10 subscribers: min per-subscriber rate", f"{r1:.1f} Hz", "100 Hz",
                 f"jitter {us(j1)}, overruns {o1}, max period {m1 * 1e3:.1f} ms"))
    rows.append(("+10 subscribers +1 stuck: min rate / overruns", f"{r2:.1f} Hz / {o2}", "-",
                 f"overrun delta vs +10: {o2 - o1} (goal 0), jitter {us(j2)}"))

    print(f"payload: YouBotStatus, {len(PAYLOAD)} bytes as encoded by the registry (JSON); latency rows in one process; fan-out rows with the task in its own deployer process; 127.0.0.1\n")
    print("| measurement | scart | bare grpcio baseline | ratio / note |")
    print("|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
