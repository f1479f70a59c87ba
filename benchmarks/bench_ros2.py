"""Benchmark of ROS 2 in scart against bare cyclonedds pub/sub of the same message,
measured in the same run, alternating.

Usage: ``python benchmarks/bench_ros2.py [--quick | --smoke]`` (needs ``scart[ros2]``).
The same-host hop: a publisher process sends ``std_msgs/msg/Int64`` holding
``time.monotonic_ns()`` at 1 kHz on absolute deadlines; this process's subscriber records
arrival − stamp (CLOCK_MONOTONIC is one clock for every process of the host). Variants:

* **bare**: cyclonedds-python alone, both ends: an ``IdlStruct`` named
  ``std_msgs::msg::dds_::Int64_``, a ``DataWriter``, and a ``DataReader`` drained by a
  waitset thread (``take``);
* **ros2**: the library :mod:`scart_ros2`, both ends:
  ``Participant.publisher`` of a rosbags message, ``Participant.subscribe`` delivering a
  rosbags message to a callback;
* **stream out**: a scart port → a ``ros2`` stream → the bare reader: a task's
  ``OutputPort(int)`` written in the publisher process, joined to the topic by
  ``Deployer.stream`` (``ConnPolicy.data(init=False)``);
* **stream in**: the bare writer → a ``ros2`` stream → a scart port: a task's
  ``InputPort(int)`` in this process fed by ``Deployer.stream``, timed when the sample
  is in the port (its data callback, on the transport's thread, reads it), so after the
  conversion and the port's check.

All reliable keep-last 1 volatile (``QoS.data()``), loopback only, each variant on its own
random domain; the first second of each round is dropped. Rounds run the variants in
turn, the order rotating each round. Prints one markdown table, with each p50 over bare's
of the same round. Not a test (``.ci/run`` does not run it).
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import paced, pct, wait_until  # noqa: E402

from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext  # noqa: E402
from scart_ros2 import Network, Participant, QoS  # noqa: E402

TOPIC = "/scart_bench/hop"
RATE = 1000.0
VARIANTS = ("bare", "ros2", "stream out", "stream in")
PUBLISHER = {"bare": "bare", "ros2": "ros2", "stream out": "stream", "stream in": "bare"}


class Stamps(TaskContext):
    """The benchmark's task: ``out`` in the publisher process, ``inp`` in this one."""

    out = OutputPort(int)
    inp = InputPort(int)


def _stream(deployer: Deployer, port: str, domain: int) -> object:
    """``port`` joined to the benchmark's topic on ``domain``; the transport's stream."""
    made = deployer.stream(f"bench.{port}", ConnPolicy.data(init=False).with_(transport="ros2", topic=TOPIC),
                           {"domain": str(domain)})
    return deployer.streams()[made.name]._stream


def bare_types() -> tuple[Any, Any]:
    """The bare variant's IDL type and QoS (written as a cyclonedds user would)."""
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl.types import int64
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.util import duration

    # (made, not declared: this module's postponed annotations would hide int64 from cyclonedds)
    int64_type = make_idl_struct("Int64_", "std_msgs::msg::dds_::Int64_", {"data": int64})
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1),
              Policy.Durability.Volatile)
    return int64_type, qos


def publish(variant: str, domain: int, seconds: float) -> None:
    """The publisher process: wait for the subscriber, send for ``seconds`` at 1 kHz."""
    count = int(seconds * RATE)
    if variant == "bare":
        from cyclonedds.domain import Domain, DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        int64_type, qos = bare_types()
        _domain = Domain(domain, Network.loopback().config_xml())  # noqa: F841  (kept open)
        dp = DomainParticipant(domain)
        writer = DataWriter(dp, Topic(dp, "rt" + TOPIC, int64_type), qos=qos)
        if not wait_until(lambda: writer.get_matched_subscriptions(), timeout=20):
            raise SystemExit("bare: no subscriber matched")
        paced(count, RATE, lambda k: writer.write(int64_type(data=time.monotonic_ns())))
        return
    if variant == "stream":
        deployer = Deployer()
        task = deployer.add(Stamps("bench"))
        stream = _stream(deployer, "out", domain)
        try:
            if not wait_until(lambda: stream.matched, timeout=20):
                raise SystemExit("stream: no subscriber matched")
            paced(count, RATE, lambda k: task.out.write(time.monotonic_ns()))
        finally:
            for name in list(deployer.streams()):
                deployer.unstream(name)
        return
    with Participant(domain) as ros:
        pub = ros.publisher(TOPIC, "std_msgs/msg/Int64", QoS.data())
        int64 = ros.types.message_class("std_msgs/msg/Int64")
        if not wait_until(pub.matched, timeout=20):
            raise SystemExit("ros2: no subscriber matched")
        paced(count, RATE, lambda k: pub.publish(int64(data=time.monotonic_ns())))


class BareSubscriber:
    """cyclonedds-python alone: a reader drained by a waitset on its own thread."""

    def __init__(self, domain: int) -> None:
        from cyclonedds.core import GuardCondition, ReadCondition, SampleState, ViewState, InstanceState, WaitSet
        from cyclonedds.domain import Domain, DomainParticipant
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic

        int64_type, qos = bare_types()
        self._domain = Domain(domain, Network.loopback().config_xml())
        self._dp = DomainParticipant(domain)
        self._reader = DataReader(self._dp, Topic(self._dp, "rt" + TOPIC, int64_type), qos=qos)
        self._waitset, self._guard = WaitSet(self._dp), GuardCondition(self._dp)
        self._waitset.attach(ReadCondition(self._reader, SampleState.Any | ViewState.Any | InstanceState.Any))
        self._waitset.attach(self._guard)
        self.latencies: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bench-bare-sub", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        from cyclonedds.util import duration

        while not self._stop.is_set():
            self._waitset.wait(duration(seconds=1))
            for sample in self._reader.take(N=64):
                if sample.sample_info.valid_data:
                    self.latencies.append((time.monotonic_ns() - sample.data) / 1e3)

    def close(self) -> None:
        self._stop.set()
        self._guard.set(True)
        self._thread.join(5)


class OurSubscriber:
    """The library: a callback on the participant's dispatcher thread."""

    def __init__(self, domain: int) -> None:
        self.latencies: list[float] = []
        self._ros = Participant(domain)
        self._ros.subscribe(TOPIC, "std_msgs/msg/Int64",
                            lambda m: self.latencies.append((time.monotonic_ns() - m.data) / 1e3), QoS.data())

    def close(self) -> None:
        self._ros.close()


class StreamSubscriber:
    """A scart input port fed by a ``ros2`` stream, timed by the port's data callback."""

    def __init__(self, domain: int) -> None:
        self.latencies: list[float] = []
        self._deployer = Deployer()
        task = self._deployer.add(Stamps("bench"))
        port = task.inp

        def arrived(_port: Any) -> None:  # the transport's thread, once the sample is in the port
            _flow, stamp = port.read()
            self.latencies.append((time.monotonic_ns() - stamp) / 1e3)

        port.add_data_callback(arrived)
        _stream(self._deployer, "inp", domain)

    def close(self) -> None:
        for name in list(self._deployer.streams()):
            self._deployer.unstream(name)


def run_round(variant: str, domain: int, subscriber: Any, seconds: float, warmup: float) -> list[float]:
    """One publisher process of ``variant``; the latencies after ``warmup`` s (µs)."""
    subscriber.latencies.clear()
    proc = subprocess.run([sys.executable, __file__, "--role", "pub", "--variant", PUBLISHER[variant],
                           "--domain", str(domain),
                           "--seconds", str(seconds)], capture_output=True, text=True, timeout=seconds + 60)
    if proc.returncode != 0:
        raise SystemExit(f"{variant} publisher failed: {proc.stderr or proc.stdout}")
    time.sleep(0.05)  # the last samples in flight
    return subscriber.latencies[int(warmup * RATE):]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 rounds of 4 s")
    parser.add_argument("--smoke", action="store_true", help="1 round of 1 s: that it runs")
    parser.add_argument("--role", default="sub", help=argparse.SUPPRESS)
    parser.add_argument("--variant", help=argparse.SUPPRESS)
    parser.add_argument("--domain", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--seconds", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "pub":
        publish(args.variant, args.domain, args.seconds)
        return 0
    rounds, seconds, warmup = (1, 1.0, 0.2) if args.smoke else (2, 4.0, 1.0) if args.quick else (3, 10.0, 1.0)
    first = random.SystemRandom().randint(1, 58)
    domains = {v: first + 58 * i for i, v in enumerate(VARIANTS)}
    makers = {"bare": BareSubscriber, "ros2": OurSubscriber, "stream out": BareSubscriber,
              "stream in": StreamSubscriber}
    subscribers: dict[str, Any] = {}
    results: dict[str, list[list[float]]] = {v: [] for v in VARIANTS}
    try:
        for v in VARIANTS:
            subscribers[v] = makers[v](domains[v])
        for r in range(rounds):
            order = VARIANTS[r % len(VARIANTS):] + VARIANTS[:r % len(VARIANTS)]
            for variant in order:
                results[variant].append(run_round(variant, domains[variant], subscribers[variant], seconds, warmup))
    finally:
        for subscriber in subscribers.values():
            subscriber.close()
    print_table(results, seconds, warmup)
    return 0


def print_table(results: dict[str, list[list[float]]], seconds: float, warmup: float) -> None:
    print(f"\nROS 2 same-host hop, std_msgs/msg/Int64 at {RATE:.0f} Hz, {seconds:g} s rounds "
          f"(first {warmup:g} s dropped), two processes, loopback\n")
    print("| variant | round | samples | p50 µs | p99 µs | p50 / bare |")
    print("|---|---|---|---|---|---|")
    for r in range(len(results["bare"])):
        bare_p50 = pct(results["bare"][r], 0.5)
        for variant in VARIANTS:
            values = results[variant][r]
            p50 = pct(values, 0.5)
            print(f"| {variant} | {r + 1} | {len(values)} | {p50:.0f} | {pct(values, 0.99):.0f} | "
                  f"{p50 / bare_p50:.2f}× |")
    pooled = {v: [x for run in runs for x in run] for v, runs in results.items()}
    bare_p50 = pct(pooled["bare"], 0.5)
    for variant in VARIANTS:
        p50 = pct(pooled[variant], 0.5)
        print(f"| **{variant}** | all | {len(pooled[variant])} | **{p50:.0f}** | **{pct(pooled[variant], 0.99):.0f}** | "
              f"**{p50 / bare_p50:.2f}×** |")
    print("\ngoal (issue 22): a DDS stream's p50 (stream out, stream in) ≤ 1.3× bare cyclonedds")


if __name__ == "__main__":
    sys.exit(main())
