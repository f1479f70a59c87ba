"""Benchmark of ``binding.dataflow`` against the remote data-flow layer's own figures.

Usage: ``python benchmarks/bench_dataflow_binding.py [--quick | --smoke]`` (prints a markdown
table; ``--smoke``: a few samples, that every path runs); ``run(mode) -> list[(measure,
value, vs-baseline)]`` (mode ``full``, ``quick`` or ``smoke``) is what ``bench_bindings.py`` prints.

Everything runs in one process on 127.0.0.1: a Deployer with a probe task served over gRPC
(embedded name service), an SCA runtime whose component reaches the task through
``binding.dataflow`` (``ns`` = that name service, so the binding goes over gRPC exactly as
it would across processes). Samples are sent one at a time (the next after the previous
arrived), so the figures are latencies, not throughput; binding and baseline are measured in
the same loop, taking turns (writes) or receiving the very same samples (push), so both
see the same conditions. Rows:

- binding.dataflow reference call → sample read by the task (event port), p50/p99;
  baseline: a raw ``dataflow.remote`` writer (``proxy.connect_input(...).write``);
- task write → SCA service operation invoked (push subscription), p50/p99;
  baseline: a raw ``proxy.subscribe`` observer.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext  # noqa: E402
from dataflow.remote import connect  # noqa: E402

from _common import pct, wait_until  # noqa: E402

Row = tuple[str, str, str]

COMPONENTS = '''
from __future__ import annotations

import threading
import time
from typing import Protocol

import scart

STATE = {"got": {}, "event": threading.Event()}


class ProbePorts(Protocol):
    def x(self, value: float) -> None: ...


class Samples(Protocol):
    def y(self, value: float) -> None: ...


class Sender(Protocol):
    def send(self, value: float) -> None: ...


@scart.component(services=[Sender, Samples])
class BenchClient:
    probe: ProbePorts = scart.reference()

    def send(self, value: float) -> None:
        self.probe.x(value)

    def y(self, value: float) -> None:
        STATE["got"][value] = time.perf_counter()
        STATE["event"].set()
'''

COMPOSITE = """<?xml version="1.0" encoding="UTF-8"?>
<composite xmlns="http://docs.oasis-open.org/ns/opencsa/sca/200912" xmlns:scart="urn:scart:1.0"
           targetNamespace="urn:bench" name="BenchDataflowBinding">
  <component name="client">
    <scart:implementation.python class="benchcomps:BenchClient"/>
    <service name="Sender"/>
    <service name="Samples"><scart:binding.dataflow component="probe" ns="{ns}" policy="buffer:64"/></service>
    <reference name="probe"><scart:binding.dataflow component="probe" ns="{ns}"/></reference>
  </component>
</composite>
"""


class Probe(TaskContext):
    """Stamps each sample of ``x`` when its update cycle reads it; ``y`` is written by the bench."""

    x = InputPort(float, event=True)
    y = OutputPort(float)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.seen: dict[float, float] = {}
        self.arrived = threading.Event()

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, v = self.x.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.seen[v] = time.perf_counter()
            self.arrived.set()


def _latency(send: object, value: float, seen: dict[float, float], event: threading.Event) -> float | None:
    """Send ``value`` and wait (≤ 5 s) until it is in ``seen``; its latency, or None if lost."""
    event.clear()
    t0 = time.perf_counter()
    send(value)  # type: ignore[operator]
    deadline = t0 + 5.0
    while value not in seen and time.perf_counter() < deadline:
        event.wait(0.5)
        event.clear()
    return seen.pop(value) - t0 if value in seen else None


def _interleaved_writes(n: int, sends: list[object], seen: dict[float, float], event: threading.Event) -> list[list[float]]:
    """Latencies per sender, the senders taking turns sample by sample (same conditions)."""
    out: list[list[float]] = [[] for _ in sends]
    for i in range(n):
        for k, send in enumerate(sends):
            lat = _latency(send, float(i * len(sends) + k) + 0.5, seen, event)
            if lat is not None:
                out[k].append(lat)
    return out


def _shared_pushes(n: int, write: object, sinks: list[tuple[dict[float, float], threading.Event]]) -> list[list[float]]:
    """One task write per sample, received by every sink: the latency of each, per sink."""
    out: list[list[float]] = [[] for _ in sinks]
    for i in range(n):
        value = float(i) + 0.5
        for seen, event in sinks:
            seen.pop(value, None)
            event.clear()
        t0 = time.perf_counter()
        write(value)  # type: ignore[operator]
        deadline = t0 + 5.0
        for k, (seen, event) in enumerate(sinks):
            while value not in seen and time.perf_counter() < deadline:
                event.wait(0.5)
                event.clear()
            if value in seen:
                out[k].append(seen.pop(value) - t0)
    return out


def _rows(label: str, got: list[float], base: list[float]) -> list[Row]:
    rows = []
    for p in (50, 99):
        v, b = pct(got, p / 100), pct(base, p / 100)
        rows.append((f"{label} p{p}", f"{v * 1e6:.0f} µs", f"{v / b:.2f}x (raw {b * 1e6:.0f} µs)"))
    return rows


def run(mode: str = "full") -> list[Row]:
    """Measure (see the module docstring); returns (measure, value, vs-baseline) rows."""
    import scart

    n = {"smoke": 20, "quick": 200}.get(mode, 2000)
    deployer = Deployer()
    probe = deployer.add(Probe("probe"))
    probe.configure()
    probe.start()
    server = deployer.serve("127.0.0.1:0")
    rows: list[Row] = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            (Path(tmp) / "benchcomps.py").write_text(textwrap.dedent(COMPONENTS), encoding="utf-8")
            path = Path(tmp) / "bench.composite"
            path.write_text(COMPOSITE.format(ns=server.ns_address), encoding="utf-8")
            with connect(server.ns_address) as system, scart.Runtime.from_file(path) as rt:
                proxy = system.component("probe")
                writer = proxy.connect_input("x", ConnPolicy.data())
                sender = rt.service("client/Sender")
                _interleaved_writes(20, [writer.write, sender.send], probe.seen, probe.arrived)  # warm-up
                base_w, got_w = _interleaved_writes(n, [writer.write, sender.send], probe.seen, probe.arrived)
                rows += _rows("reference call → task read", got_w, base_w)

                raw_seen: dict[float, float] = {}
                raw_event = threading.Event()

                def observe(event: object) -> None:
                    raw_seen[event.value] = time.perf_counter()  # type: ignore[attr-defined]
                    raw_event.set()

                state = sys.modules["benchcomps"].STATE
                _wait_subscribed(rt)
                with proxy.subscribe("y", observe, policy=ConnPolicy.buffer(64)):
                    sinks = [(raw_seen, raw_event), (state["got"], state["event"])]
                    _shared_pushes(20, probe.y.write, sinks)
                    base_s, got_s = _shared_pushes(n, probe.y.write, sinks)
                rows += _rows("task write → service invoked", got_s, base_s)
    finally:
        server.stop()
        deployer.stop_all()
        deployer.cleanup_all()
    return rows


def _wait_subscribed(rt: object) -> None:
    from scart.bindings.dataflow import DataflowServiceBinding, bindings_of

    if not wait_until(lambda: all(b.connected for b in bindings_of(rt) if isinstance(b, DataflowServiceBinding)),
                      timeout=10.0, interval=0.01):
        raise RuntimeError("binding.dataflow service never subscribed")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer samples")
    parser.add_argument("--smoke", action="store_true", help="a few samples: that every path runs")
    args = parser.parse_args()
    rows = run("smoke" if args.smoke else "quick" if args.quick else "full")
    print("| measure | value | vs baseline |")
    print("|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]} | {r[2]} |")


if __name__ == "__main__":
    main()
