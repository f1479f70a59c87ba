"""Benchmark of the youBot demo at driver periods 10 ms, 2 ms and 1 ms.

Usage: ``python benchmarks/bench_youbot.py [--quick | --smoke]`` (``--quick``: 2 s windows
instead of 5 s; ``--smoke``: 0.5 s, that every path runs). Needs the ``bench`` extra (psutil).
Not a test: numbers depend on the machine. Prints markdown tables.

Two-process way (the paper's experiment): ``scart run robot.composite`` is a subprocess
(the data-flow driver, served with its own name service); the workstation composite
(SCA proxy, Locomotor, monitor) runs in this process, so its counters can be read. The
period is set the way a user does, through ``SettingPeriod.set_period``. Per period, over
one window after a warm-up:

- produced: driver cycles/s (from the driver's deployer, ``scart ls`` data);
- proxy: samples/s delivered to the proxy's ``jointStatus`` subscription (push, DATA);
- monitor: samples/s published to the monitor (refresh callbacks are coalesced: at most
  one pending per client, so the monitor may skip samples but never lags behind);
- latency: driver write (the sample's own timestamp) → monitor receipt, p50 / p99;
- CPU: % of one core of the robot process and of the workstation process (this one);
- overruns: the driver's overrun count during the window (must be 0 at 10 ms).

The push run is made once per transport (``SCAYouBotDriver.transport``): ``ipc`` (the
same-host fast path) and ``grpc``; ``auto``, the default, is ``ipc`` on one host, so it
is not run again. The ``transport`` column is what the proxy's subscription reports it
used (``GrpcSubscription.transport``), read after the run, not the value asked for.

The same again with the proxy polling ``jointStatus`` at half the driver period (polling
reads the port with gRPC ``ReadPort`` calls whatever the transport: its row says so).

One-process way (``scart run youbot.composite`` and ``youbot-binding.composite``, both
subprocesses): produced vs monitor samples/s (the monitor's own ``/api/state`` counter),
CPU of the one process, overruns. In ``youbot.composite`` the hand-written proxy reaches
the driver through the name service even in one process, so it is run per transport too
(``--set SCAYouBotDriver.transport=T``); its column is what the proxy's
``get_driver_info`` answers after the run (``scart call --at``, the SCA services the run
serves). In ``youbot-binding.composite`` the binding has no ``ns`` and its task is in the
composite: ``binding.dataflow`` uses the task in place (``local``), where a ``transport``
attribute changes nothing, so it runs once.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

import psutil

ROOT = Path(__file__).resolve().parent.parent
YOUBOT = ROOT / "composites" / "youbot"
sys.path.insert(0, str(YOUBOT))  # a contribution: its modules are imported by plain names

import scart  # noqa: E402
from dataflow.remote import connect  # noqa: E402

from _common import pct, wait_until  # noqa: E402

PERIODS = (0.01, 0.002, 0.001)


def free_address() -> str:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"127.0.0.1:{sock.getsockname()[1]}"


class Proc:
    """A ``scart run`` subprocess; output lines collected by a daemon reader."""

    def __init__(self, composite: str, ns: str, *extra: str) -> None:
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), str(YOUBOT), env.get("PYTHONPATH", "")) if p)
        env.pop("SCART_NS", None)
        self.proc = subprocess.Popen([sys.executable, "-m", "scart", "run", str(YOUBOT / composite), "--ns", ns, *extra],
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=ROOT)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.ps = psutil.Process(self.proc.pid)

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip())

    def wait_for(self, pattern: str, timeout: float = 30.0) -> re.Match[str]:
        rx = re.compile(pattern)

        def found() -> re.Match[str] | bool:  # the match, or True once the process has exited
            for line in list(self.lines):
                if m := rx.search(line):
                    return m
            return self.proc.poll() is not None

        m = wait_until(found, timeout, interval=0.05)
        if isinstance(m, re.Match):
            return m
        raise RuntimeError(f"no /{pattern}/ in output:\n" + "\n".join(self.lines))

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        try:
            return self.proc.wait(20)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait(5)


def driver_counters(system: Any) -> tuple[int, int]:
    info = next(c for c in system.components() if c.name == "youBotDriver")
    return info.cycles, info.overruns


def wait(predicate: Any, timeout: float, what: str) -> None:
    if not wait_until(predicate, timeout, interval=0.05):
        raise RuntimeError(f"timed out waiting for {what}")


def used_transport(proxy: Any) -> str:
    """What the proxy's subscription says it used (measured, not the property's value)."""
    sub = proxy._subscription
    if sub is None:
        return "?"
    kind = " (polling)" if sub.period is not None else ""  # polling: unary ReadPort calls
    return (sub.transport or "?") + kind


def two_process(window: float, transport: str = "auto", poll: bool = False,
                periods: tuple[float, ...] = PERIODS) -> list[list[str]]:
    """The robot subprocess + the workstation in this process, per period, the proxy's
    subscription on ``transport``; ``poll``: the proxy polls (JOrocos-style) at half the
    driver period instead of the push subscription."""
    ns = free_address()
    robot = Proc("robot.composite", ns)
    rows: list[list[str]] = []
    try:
        robot.wait_for(r"scart: name service at")
        overrides = {"SCAYouBotDriver.name_service": ns, "SCAYouBotDriver.transport": transport}
        if poll:
            overrides["SCAYouBotDriver.poll_period"] = "1.0"  # clamped to half the driver period
        rt = scart.Runtime.from_file(YOUBOT / "workstation.composite", overrides=overrides)
        with rt, connect(ns) as system:
            proxy: Any = rt._managers["SCAYouBotDriver"].instance()
            monitor: Any = rt._managers["YouBotMonitor"].instance()
            setter = rt.service("SCAYouBotDriver/SettingPeriod")
            wait(lambda: proxy.received > 10, 20, "samples at the proxy")
            me = psutil.Process()
            for period in periods:
                answer = setter.set_period(period)
                assert answer["accepted"], answer
                time.sleep(min(1.0, window))  # warm-up at the new period
                cycles0, over0 = driver_counters(system)
                recv0, pub0 = proxy.received, monitor.published
                lat0 = len(monitor._latencies)
                robot.ps.cpu_percent(None)
                me.cpu_percent(None)
                t0 = time.monotonic()
                time.sleep(window)
                elapsed = time.monotonic() - t0
                cpu_robot, cpu_ws = robot.ps.cpu_percent(None), me.cpu_percent(None)
                cycles1, over1 = driver_counters(system)
                recv1, pub1 = proxy.received, monitor.published
                lat = list(monitor._latencies)[lat0:] if len(monitor._latencies) < monitor._latencies.maxlen \
                    else list(monitor._latencies)[-(pub1 - pub0):]
                rows.append([
                    used_transport(proxy), f"{period * 1000:g} ms", f"{(cycles1 - cycles0) / elapsed:.0f}",
                    f"{(recv1 - recv0) / elapsed:.0f}", f"{(pub1 - pub0) / elapsed:.0f}",
                    f"{pct(lat, 0.5) * 1000:.2f}", f"{pct(lat, 0.99) * 1000:.2f}",
                    f"{cpu_robot:.0f}", f"{cpu_ws:.0f}", str(over1 - over0),
                ])
    finally:
        robot.stop()
    return rows


def proxy_transport(services: str) -> str:
    """The transport the ``SCAYouBotDriver`` of a ``scart run`` serving its SCA services at
    ``services`` says it uses (its ``get_driver_info``, through ``scart call --at``)."""
    out = subprocess.run([sys.executable, "-m", "scart", "call", "--at", services, "--json",
                          "SCAYouBotDriver/RetrievingStatus.get_driver_info"],
                         capture_output=True, text=True, timeout=30, cwd=ROOT, check=False)
    if out.returncode != 0:
        return f"? (scart call: {' '.join(out.stderr.split())[:80]})"
    info = json.loads(out.stdout)
    return f"{info.get('transport') or '?'} (asked {info.get('transport_policy', '?')})"


def one_process(composite: str, window: float, transport: str | None = None,
                periods: tuple[float, ...] = PERIODS) -> list[list[str]]:
    """``scart run COMPOSITE`` alone; the period set through the monitor's HTTP API;
    ``transport``: ``--set SCAYouBotDriver.transport=`` (the hand-written proxy), else the
    proxy is ``binding.dataflow`` on the task in place (``local``)."""
    ns = free_address()
    extra = ("--set", f"SCAYouBotDriver.transport={transport}") if transport else ()
    demo = Proc(composite, ns, *extra)
    rows: list[list[str]] = []
    try:
        url = demo.wait_for(r"youBot Monitor: (http://\S+)").group(1)
        services = demo.wait_for(r"scart: SCA services at (\S+)").group(1)
        demo.wait_for(r"scart: name service at")

        def state() -> dict[str, Any]:
            with urllib.request.urlopen(url + "api/state", timeout=5) as reply:
                return json.load(reply)

        wait(lambda: state().get("samples", 0) > 10, 20, "samples at the monitor")
        with connect(ns) as system:
            for period in periods:
                body = json.dumps({"seconds": period}).encode()
                req = urllib.request.Request(url + "api/period", body, {  # same-origin, as the page
                    "Content-Type": "application/json", "Origin": url.rstrip("/")})
                with urllib.request.urlopen(req, timeout=10) as reply:
                    assert json.load(reply)["ok"]
                time.sleep(min(1.0, window))
                cycles0, over0 = driver_counters(system)
                s0 = state()["samples"]
                demo.ps.cpu_percent(None)
                t0 = time.monotonic()
                time.sleep(window)
                elapsed = time.monotonic() - t0
                cpu = demo.ps.cpu_percent(None)
                cycles1, over1 = driver_counters(system)
                s1 = state()["samples"]
                rows.append(["", f"{period * 1000:g} ms", f"{(cycles1 - cycles0) / elapsed:.0f}",
                             f"{(s1 - s0) / elapsed:.0f}", f"{cpu:.0f}", str(over1 - over0)])
        used = proxy_transport(services) if transport else "local (binding.dataflow in place)"
        for row in rows:  # asked once, after the windows (a call registers no listener: no callback)
            row[0] = used
    finally:
        demo.stop()
    return rows


def table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 s windows")
    parser.add_argument("--smoke", action="store_true", help="0.5 s windows: that every path runs")
    args = parser.parse_args(argv)
    window = 0.5 if args.smoke else 2.0 if args.quick else 5.0
    periods = PERIODS[:1] if args.smoke else PERIODS  # smoke: every path once, one period
    print(f"youBot demo, {window:g} s windows, {os.cpu_count()} CPU(s), Python {sys.version.split()[0]}\n")
    header = ["transport", "period", "produced/s", "proxy/s", "monitor/s", "latency p50 ms", "latency p99 ms",
              "CPU robot %", "CPU workstation %", "overruns"]
    print("Two processes (robot.composite subprocess; workstation in the benchmark process), push, once per "
          "transport (auto = ipc on one host, not run again):\n")
    rows = [row for transport in ("ipc", "grpc") for row in two_process(window, transport, periods=periods)]
    print(table(header, rows))
    print("\nTwo processes, the proxy polling at half the driver period (JOrocos-style):\n")
    print(table(header, two_process(window, poll=True, periods=periods)))
    one_header = ["transport", "period", "produced/s", "monitor/s", "CPU %", "overruns"]
    print("\nOne process (scart run youbot.composite --set SCAYouBotDriver.transport=T), once per transport:\n")
    print(table(one_header, [row for t in ("ipc", "grpc")
                             for row in one_process("youbot.composite", window, t, periods)]))
    print("\nOne process (scart run youbot-binding.composite):\n")
    print(table(one_header, one_process("youbot-binding.composite", window, periods=periods)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
