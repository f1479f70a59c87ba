"""Binding benchmark: binding.grpc against bare grpcio, one-way rate, callback round trip;
then the binding.dataflow rows of ``benchmarks/bench_dataflow_binding.py`` when present.

Run: ``python benchmarks/bench_bindings.py [--quick | --smoke]`` (prints one table; no
assertions; ``--smoke``: a few seconds, that every path runs).
Everything runs in this process over real gRPC on 127.0.0.1: a provider runtime and a
client runtime, and a bare grpcio server/channel pair carrying the same payload as a
protobuf message (no scart at all). Goal: a binding.grpc call within 1.3x of the bare
unary call. Blocks of both are interleaved so machine noise hits both alike.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import tempfile
import textwrap
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import grpc  # noqa: E402

import scart  # noqa: E402
from dataflow import registry  # noqa: E402
from scart_wire.codec import Value  # noqa: E402

from _common import pct  # noqa: E402

Row = tuple[str, str, str]

MODULE = '''
import threading
from typing import Protocol
import scart

FIRED = [0]
LOCK = threading.Lock()
ALL_FIRED = threading.Event()
TARGET = [0]


@scart.interface
class Echo(Protocol):
    def echo(self, values: list[float]) -> list[float]: ...

    @scart.oneway
    def fire(self, values: list[float]) -> None: ...


@scart.interface
class Pong(Protocol):
    def pong(self, n: int) -> int: ...


@scart.interface(callback=Pong)
class Ping(Protocol):
    def ping(self, n: int) -> int: ...
    def quiet(self, n: int) -> int: ...


@scart.component(services=[Echo])
class EchoImpl:
    def echo(self, values: list[float]) -> list[float]:
        return values

    def fire(self, values: list[float]) -> None:
        with LOCK:
            FIRED[0] += 1
            if FIRED[0] >= TARGET[0]:
                ALL_FIRED.set()


@scart.component(services=[Ping])
class PingImpl:
    caller: Pong = scart.callback()

    def ping(self, n: int) -> int:
        return self.caller.pong(n) + 1

    def quiet(self, n: int) -> int:
        return n


class Client:
    echo: Echo = scart.reference()
    pinger: Ping = scart.reference()

    def pong(self, n: int) -> int:
        return n + 1

    def ping(self, n: int) -> int:
        return self.pinger.ping(n)

    def quiet(self, n: int) -> int:
        return self.pinger.quiet(n)
'''

COMPOSITE = '''<?xml version="1.0" encoding="UTF-8"?>
<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0"
           targetNamespace="urn:bench" name="{name}">
{body}
</composite>
'''

PROVIDER = '''
  <component name="E"><scart:implementation.python class="benchmod:EchoImpl"/>
    <service name="Echo"><scart:binding.grpc/></service></component>
  <component name="P"><scart:implementation.python class="benchmod:PingImpl"/>
    <service name="Ping"><scart:binding.grpc/></service></component>
'''

CLIENT = '''
  <component name="C"><scart:implementation.python class="benchmod:Client"/>
    <reference name="echo"><scart:binding.grpc address="{addr}" service="E/Echo"/></reference>
    <reference name="pinger"><scart:binding.grpc address="{addr}" service="P/Ping"/></reference>
  </component>
'''


def _per_call_us(fn: Callable[[], Any], n: int) -> list[float]:
    out: list[float] = []
    clock = time.perf_counter_ns
    for _ in range(n):
        t0 = clock()
        fn()
        out.append((clock() - t0) / 1000.0)
    return out


class BareEcho:
    """A hand-written grpcio unary echo of a ``Value`` message (the baseline)."""

    def __init__(self) -> None:
        self.server = grpc.server(ThreadPoolExecutor(8))
        handler = grpc.unary_unary_rpc_method_handler(
            lambda req, ctx: Value(type_name=req.type_name, data=req.data),
            Value.FromString, Value.SerializeToString)
        self.server.add_generic_rpc_handlers((grpc.method_handlers_generic_handler("bench.Bare", {"Echo": handler}),))
        port = self.server.add_insecure_port("127.0.0.1:0")
        self.server.start()
        self.channel = grpc.insecure_channel(f"127.0.0.1:{port}")
        self.stub = self.channel.unary_unary("/bench.Bare/Echo", request_serializer=Value.SerializeToString,
                                             response_deserializer=Value.FromString)

    def call(self, values: list[float]) -> list[float]:
        enc = registry.encode(values, list[float])
        resp = self.stub(Value(type_name=enc.type_name, data=enc.data), timeout=5.0, wait_for_ready=True)
        return registry.decode(resp.type_name, resp.data)

    def close(self) -> None:
        self.channel.close()
        self.server.stop(None).wait(5)


def bench_grpc(mode: str) -> list[Row]:
    n, blocks = {"smoke": (40, 2), "quick": (300, 4)}.get(mode, (2000, 8))
    rows: list[Row] = []
    with tempfile.TemporaryDirectory(prefix="scart-bench-") as tmp:
        folder = Path(tmp)
        (folder / "benchmod.py").write_text(textwrap.dedent(MODULE), encoding="utf-8")
        (folder / "p.composite").write_text(COMPOSITE.format(name="P", body=PROVIDER), encoding="utf-8")
        with scart.Runtime.from_file(str(folder / "p.composite"), max_workers=8) as provider:
            addr = next(a for a in provider.addresses().values() if a)
            (folder / "c.composite").write_text(COMPOSITE.format(name="C", body=CLIENT.format(addr=addr)), encoding="utf-8")
            with scart.Runtime.from_file(str(folder / "c.composite")) as client:
                client_obj = client._managers["C"].instance()
                bare = BareEcho()
                try:
                    for size in (5, 128):
                        payload = [float(i) for i in range(size)]
                        assert client_obj.echo.echo(payload) == payload and bare.call(payload) == payload
                        ours: list[float] = []
                        base: list[float] = []
                        _per_call_us(lambda: client_obj.echo.echo(payload), n // 4)  # warm up
                        _per_call_us(lambda: bare.call(payload), n // 4)
                        for _ in range(blocks):
                            base += _per_call_us(lambda: bare.call(payload), n // blocks)
                            ours += _per_call_us(lambda: client_obj.echo.echo(payload), n // blocks)
                        ratio = statistics.median(ours) / statistics.median(base)
                        rows.append((f"bare grpcio unary, {size} floats", f"p50 {statistics.median(base):.0f} us",
                                     f"p99 {pct(base, 0.99):.0f} us"))
                        rows.append((f"binding.grpc call, {size} floats", f"p50 {statistics.median(ours):.0f} us",
                                     f"p99 {pct(ours, 0.99):.0f} us; {ratio:.2f}x bare (goal <= 1.3x)"))
                    rows += _oneway(client_obj, sys.modules["benchmod"], n)
                    ping = client._managers["C"].instance().ping
                    assert ping(1) == 3
                    _per_call_us(lambda: ping(1), n // 4)
                    cb = _per_call_us(lambda: ping(1), n)
                    rows.append(("binding.grpc call + 1 sync callback", f"p50 {statistics.median(cb):.0f} us",
                                 f"p99 {pct(cb, 0.99):.0f} us (Invoke stream: call, callback, reply, result)"))
                    quiet = client._managers["C"].instance().quiet
                    _per_call_us(lambda: quiet(1), n // 4)
                    qs = _per_call_us(lambda: quiet(1), n)
                    rows.append(("binding.grpc call, callback interface, none made", f"p50 {statistics.median(qs):.0f} us",
                                 f"p99 {pct(qs, 0.99):.0f} us (the Invoke stream's own cost)"))
                finally:
                    bare.close()
    return rows


def _oneway(client_obj: Any, mod: Any, n: int) -> list[Row]:
    payload = [1.0, 2.0, 3.0, 4.0, 5.0]
    total = n * 2
    mod.FIRED[0] = 0
    mod.TARGET[0] = total
    mod.ALL_FIRED.clear()
    fire = client_obj.echo.fire
    t0 = time.perf_counter()
    for _ in range(total):
        fire(payload)
    accepted = time.perf_counter() - t0
    done = mod.ALL_FIRED.wait(60)
    finished = time.perf_counter() - t0
    return [("binding.grpc one-way, accepted", f"{total / accepted:,.0f} calls/s",
             f"{accepted / total * 1e6:.0f} us per call until the provider's ack"),
            ("binding.grpc one-way, executed", f"{total / finished:,.0f} calls/s" if done else "incomplete",
             f"{total} calls queued and run on the provider's pool")]


def bench_dataflow(mode: str) -> list[Row]:
    """Rows of ``bench_dataflow_binding.run(mode)`` (TASK-BRIDGE), if that module exists."""
    path = Path(__file__).with_name("bench_dataflow_binding.py")
    if not path.exists():
        return [("binding.dataflow", "n/a", "benchmarks/bench_dataflow_binding.py not present")]
    spec = importlib.util.spec_from_file_location("bench_dataflow_binding", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    try:
        spec.loader.exec_module(mod)
        return [(str(a), str(b), str(c)) for a, b, c in mod.run(mode)]
    except Exception as exc:  # a failing sibling benchmark must not hide ours
        return [("binding.dataflow", "error", f"{type(exc).__name__}: {exc}")]


def table(rows: list[Row]) -> str:
    """A Markdown table of (measure, value, notes) rows."""
    head: Row = ("measure", "value", "notes")
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(3)]
    line = lambda r: "| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |"  # noqa: E731
    return "\n".join([line(head), "|" + "|".join("-" * (w + 2) for w in widths) + "|", *map(line, rows)])


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    ap.add_argument("--smoke", action="store_true", help="a few seconds: that every path runs")
    args = ap.parse_args()
    mode = "smoke" if args.smoke else "quick" if args.quick else "full"
    rows = bench_grpc(mode) + bench_dataflow(mode)
    print(table(rows))
    leftover = [t.name for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon]
    if leftover:
        print(f"(threads still running: {leftover})", file=sys.stderr)


if __name__ == "__main__":
    main()
