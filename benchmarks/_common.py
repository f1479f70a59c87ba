"""Helpers shared by the benchmark scripts (imported by plain name: ``from _common import ...``;
the scripts run as ``python benchmarks/bench_*.py``, so this directory is on ``sys.path``)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

__all__ = ["paced", "pct", "raw_socket_rtt2", "wait_until"]


def pct(values: list[float], q: float) -> float:
    """The ``q`` quantile (a fraction, 0-1: ``0.99`` for p99) of ``values`` by nearest rank
    (the sorted value at index ``int(q * n)``, clamped); NaN if ``values`` is empty."""
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def paced(n: int, rate: float, step: Callable[[int], object]) -> None:
    """Call ``step(k)`` for k in 0..n-1 at ``rate`` Hz on absolute deadlines (a late step
    does not push the later ones back: ``sleep(period)`` would drift)."""
    period = 1.0 / rate
    deadline = time.perf_counter()
    for k in range(n):
        deadline += period
        step(k)
        pause = deadline - time.perf_counter()
        if pause > 0:
            time.sleep(pause)


def wait_until(predicate: Callable[[], T], timeout: float, interval: float = 0.01) -> T | None:
    """Poll ``predicate`` every ``interval`` s until it returns something truthy (returned) or
    ``timeout`` s have passed (``None``; the caller decides whether that is an error)."""
    deadline = time.monotonic() + timeout
    for _ in range(1_000_000_000):  # bounded; ends at the deadline
        result = predicate()
        if result:
            return result
        if time.monotonic() >= deadline:
            break
        time.sleep(interval)
    return None


def raw_socket_rtt2(rate: float, n: int) -> list[float]:
    """The baseline of a same-host hop: one-way times (RTT/2, s) of ``n`` ``SOCK_SEQPACKET``
    ping-pongs with a child Python process, sent at ``rate`` Hz on absolute deadlines (as
    the ports are: idle CPUs between samples cost their wake-up; a tight loop would hide
    it). 20 warm-up round trips are left out."""
    parent, kid = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    code = ("import socket\n"
            f"s = socket.socket(fileno={kid.fileno()})\n"
            "while True:\n"
            "    m = s.recv(256)\n"
            "    if not m: break\n"
            "    s.send(m)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], pass_fds=(kid.fileno(),))
    kid.close()
    out: list[float] = []
    payload = b"x" * 24

    def ping(_: int) -> None:
        t0 = time.perf_counter()
        parent.send(payload)
        parent.recv(256)
        out.append((time.perf_counter() - t0) / 2)

    try:
        paced(n + 20, rate, ping)
    finally:
        parent.close()
        proc.wait(timeout=10)
    return out[20:]


def pub_sub_hop(sub_cmd: list[str], pub_cmd: list[str], env: dict[str, str], timeout: float,
                what: str = "") -> list[float]:
    """One hop between two processes: start the subscriber, wait for its ``ready`` line,
    run the publisher to its end (≤ ``timeout`` s), then read the subscriber's last line
    (a JSON list of latencies in ns); the latencies in µs. Raises ``RuntimeError`` naming
    ``what`` (e.g. "rospy") and the side that failed; the subscriber never outlives it."""
    sub = subprocess.Popen(sub_cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert sub.stdout is not None
        if sub.stdout.readline().strip() != "ready":
            raise RuntimeError(f"{what} subscriber failed: {sub.stderr.read() if sub.stderr else ''}")
        pub = subprocess.run(pub_cmd, env=env, capture_output=True, text=True, timeout=timeout)
        if pub.returncode != 0:
            raise RuntimeError(f"{what} publisher failed: {pub.stderr[-2000:]}")
        out, _ = sub.communicate(timeout=120)
    finally:
        if sub.poll() is None:
            sub.kill()
            sub.wait()
    return [ns / 1000 for ns in json.loads(out.strip().splitlines()[-1])]
