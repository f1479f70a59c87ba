"""Benchmark of scart on ROS 1 against rospy, hop by hop, one run.

Usage: ``python benchmarks/bench_ros1.py [--quick | --smoke] [--hops a>b,...]`` (needs
Debian's ``ros-core`` and, for the rospy rows, ``python3-rospy`` for ``/usr/bin/python3``;
says so and measures what it can when they are missing). Not a test; CI does not run it.

A ``rosmaster --core`` on a free port; then, alternating in each round, same-host hops,
each a publisher process and a subscriber process, three kinds of side:

* ``rospy``: Debian's rospy;
* ``ours``: the bare node library (``scart_ros1.Node``), its callback;
* ``scart``: the whole scart path, as a user has it — an output port of a task streamed
  with ``Deployer.stream(..., ConnPolicy(transport="ros1", topic=...))`` (the value
  written with ``port.write``), or an event input port fed by such a stream, the sample
  timed in the task's ``update_hook`` (reader end, the port's check, the buffer, and the
  task's wake-up: one hand-over to the task's thread);
* ``scart-port``: an input port fed by such a stream, not an event port, the sample timed
  when it is in the port (a data callback, in the node's io thread, right after the reader
  end stored it, as rospy's callback runs in its receiving thread): the stream's own cost,
  with no task to wake;
* ``scart-event-port``: the same with the event port of ``scart``: the data callback runs
  after the port has woken its task (the kernel call that hands the sample over), so the
  row minus ``scart-port`` is the wake-up's cost to the node's thread;
* ``scart-seq``: the task of ``scart`` with a ``SequentialActivity``: its ``update_hook``
  runs in the thread that stored the sample (the node's io thread), as rospy runs a
  callback in its receiving thread — the task path with rospy's threading.

The publisher sends ``std_msgs/Int64(time.monotonic_ns())`` on absolute deadlines at 1 kHz
and at 100 Hz (rospy with ``queue_size=1`` and ``tcp_nodelay=True``, the subscriber with
``tcp_nodelay=True``); the subscriber records arrival − stamp. The first second is
discarded. Prints one markdown table: p50 and p99 per hop and rate, samples pooled over
the rounds, and each hop's p50 against rospy → rospy's in the same run.

The goal (issues 22 and 36): scart → rospy and rospy → scart-port ≤ 1.2×, both with no
more threads than rospy's (a stream's port, as rospy's publisher and callback). The
``scart`` row (an ``EventActivity`` task) carries no goal: it hands each sample to a
thread of its own, one cross-CPU wake-up more than rospy (20–40 µs on a shared 2-vCPU
machine); ``scart-seq`` is the same task without that hand-over.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import xmlrpc.client
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import paced, pct, pub_sub_hop, wait_until  # noqa: E402

SYSTEM_PYTHON = "/usr/bin/python3"
TOPIC = "/bench_hop"
#: publisher > subscriber, in the order measured (alternating within each round)
HOPS = (("rospy", "rospy"), ("scart", "rospy"), ("rospy", "scart-port"), ("rospy", "scart-event-port"),
        ("rospy", "scart"), ("rospy", "scart-seq"), ("ours", "rospy"), ("rospy", "ours"), ("scart", "scart"))
#: the subscriber roles of a scart side, by its name in a hop
SCART_ROLES = {"scart": "sub", "scart-port": "sub-port", "scart-event-port": "sub-event-port", "scart-seq": "sub-seq"}

# The rospy side: run by the system Python (Debian's rospy), as publisher or subscriber.
ROSPY_PEER = r'''
import json, sys, time
import rospy
from std_msgs.msg import Int64
role, rate, count, warmup = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
rospy.init_node("rospy_" + role, anonymous=True, disable_signals=True)
if role == "pub":
    pub = rospy.Publisher(sys.argv[5], Int64, queue_size=1, tcp_nodelay=True)
    deadline = time.monotonic() + 30
    while pub.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    period, t = 1.0 / rate, time.perf_counter()
    for _ in range(count):
        t += period
        pub.publish(Int64(data=time.monotonic_ns()))
        pause = t - time.perf_counter()
        if pause > 0:
            time.sleep(pause)
    time.sleep(0.5)
else:
    got = []
    rospy.Subscriber(sys.argv[5], Int64, lambda m: got.append((time.monotonic_ns(), m.data)), tcp_nodelay=True)
    print("ready", flush=True)
    deadline, last = time.monotonic() + count / rate + 60, None
    while len(got) < count and time.monotonic() < deadline:
        if got and last == len(got) and time.monotonic() - seen > 2.0:
            break
        if last != len(got):
            last, seen = len(got), time.monotonic()
        time.sleep(0.01)
    first = got[0][1] if got else 0
    print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)
rospy.signal_shutdown("done")
'''


def ours(role: str, rate: float, count: int, warmup: float, topic: str) -> None:
    """The ``--child`` side: our node as publisher or subscriber (same protocol as ROSPY_PEER)."""
    from scart_ros1 import Node

    with Node(f"ours_{role}_{os.getpid()}") as node:
        if role == "pub":
            pub = node.advertise(topic, "std_msgs/Int64", queue_size=1)
            pub.wait_for_connections(1, timeout=30)
            make = pub.type.cls
            paced(count, rate, lambda k: pub.publish(make(data=time.monotonic_ns())))
            time.sleep(0.5)
            return
        got: list[tuple[int, int]] = []
        node.subscribe(topic, "std_msgs/Int64", lambda m: got.append((time.monotonic_ns(), m.data)), tcp_nodelay=True)
        node.wait_registered(30)
        print("ready", flush=True)
        _wait_for(got, count, rate)
    first = got[0][1] if got else 0
    print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)


def scart_side(role: str, rate: float, count: int, warmup: float, topic: str) -> None:
    """The ``--child-scart`` side: a task's port streamed on ROS 1 (same protocol as ROSPY_PEER)."""
    from dataflow import ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, SequentialActivity, TaskContext

    class Stamper(TaskContext):
        stamp = OutputPort(int)

    in_port = role in ("sub-port", "sub-event-port")  # timed in the port: an update_hook only drains

    class Receiver(TaskContext):
        stamp = InputPort(int, event=role != "sub-port")

        def __init__(self, name: str) -> None:
            super().__init__(name)
            self.got: list[tuple[int, int]] = []
            if in_port:
                self.stamp.add_data_callback(lambda port: self.got.append((time.monotonic_ns(), port_value(port))))

        def drain(self) -> None:
            for _ in range(1000):
                if self.stamp.read()[0] is not FlowStatus.NEW_DATA:
                    return

        def update_hook(self) -> None:
            if in_port:
                return self.drain()
            for _ in range(1000):
                flow, value = self.stamp.read()
                if flow is not FlowStatus.NEW_DATA:
                    return
                self.got.append((time.monotonic_ns(), value))

    def port_value(port: InputPort) -> int:
        return port.read_newest()[1]  # the sample just stored (the callback runs in the writer's thread)

    policy = ConnPolicy.data().with_(transport="ros1", topic=topic)
    options = {"node": f"scart_{role.replace('-', '_')}_{os.getpid()}"}
    with Deployer() as dep:
        task = dep.add(Stamper("stamper") if role == "pub" else Receiver("receiver"))
        if role == "sub-seq":
            task.set_activity(SequentialActivity())
        dep.configure_all()
        dep.start_all()
        made = dep.stream(f"{task.name}.stamp", policy, options)
        if role == "pub":
            stream = dep.streams()[made.name]._stream  # the benchmark peeks: wait for the rospy subscriber
            stream._pub.wait_for_connections(1, timeout=30)
            paced(count, rate, lambda k: task.stamp.write(time.monotonic_ns()))
            time.sleep(0.5)
        else:
            wait_until(lambda: next(lk for lk in dep.links() if lk.name == made.name).state == "connected", 30)
            print("ready", flush=True)
            _wait_for(task.got, count, rate)
        dep.unstream(made.name)
        dep.stop_all()
    if role != "pub":
        got = list(task.got)
        first = got[0][1] if got else 0
        print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)


def _wait_for(got: list, count: int, rate: float) -> None:
    """Until ``count`` samples, or 2 s without a new one, or a deadline."""
    deadline, last, seen = time.monotonic() + count / rate + 60, -1, time.monotonic()
    while len(got) < count and time.monotonic() < deadline:
        if len(got) != last:
            last, seen = len(got), time.monotonic()
        elif got and time.monotonic() - seen > 2.0:
            break
        time.sleep(0.01)


class Bench:
    """The master and the peers' command lines."""

    def __init__(self, folder: Path, rospy_script: Path) -> None:
        self.port = _free_port()
        self.env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{self.port}/", ROS_HOSTNAME="127.0.0.1",
                        ROS_LOG_DIR=str(folder), ROS_HOME=str(folder))
        self.rospy_script = rospy_script
        self.master: subprocess.Popen[bytes] | None = None

    def start_master(self) -> None:
        self.master = subprocess.Popen(["rosmaster", "--core", "-p", str(self.port)], env=self.env,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        proxy = xmlrpc.client.ServerProxy(self.env["ROS_MASTER_URI"])
        if not wait_until(lambda: _answers(proxy), timeout=30):
            raise SystemExit("rosmaster did not start")

    def stop_master(self) -> None:
        if self.master is not None:
            os.killpg(self.master.pid, signal.SIGTERM)
            self.master.wait(timeout=10)

    def command(self, side: str, role: str, rate: float, count: int, warmup: float) -> list[str]:
        args = [role, str(rate), str(count), str(warmup), TOPIC]
        if side == "rospy":
            return [SYSTEM_PYTHON, str(self.rospy_script), *args]
        if side.startswith("scart"):
            role = SCART_ROLES[side] if role == "sub" else role
            return [sys.executable, __file__, "--child-scart", role, *args[1:]]
        return [sys.executable, __file__, "--child", *args]

    def hop(self, pub: str, sub: str, rate: float, seconds: float, warmup: float) -> list[float]:
        """One hop: start the subscriber, then the publisher; the latencies in µs."""
        count = int(rate * (seconds + warmup))
        return pub_sub_hop(self.command(sub, "sub", rate, count, warmup), self.command(pub, "pub", rate, count, warmup),
                           self.env, count / rate + 120, f"{pub} → {sub}:")


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _answers(proxy: xmlrpc.client.ServerProxy) -> bool:
    try:
        return proxy.getPid("/bench")[0] == 1
    except OSError:
        return False


def _has_rospy() -> bool:
    if not os.path.exists(SYSTEM_PYTHON):
        return False
    return subprocess.run([SYSTEM_PYTHON, "-c", "import rospy, std_msgs.msg"], capture_output=True).returncode == 0


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one round of 3 s hops")
    parser.add_argument("--smoke", action="store_true", help="one short round (proves every path works)")
    parser.add_argument("--hops", default=",".join(f"{p}>{s}" for p, s in HOPS),
                        help="the hops to measure, publisher>subscriber (default: all)")
    parser.add_argument("--child", nargs=5, metavar=("ROLE", "RATE", "COUNT", "WARMUP", "TOPIC"), help=argparse.SUPPRESS)
    parser.add_argument("--child-scart", nargs=5, help=argparse.SUPPRESS)
    args = parser.parse_args()
    for child, side in ((args.child, ours), (args.child_scart, scart_side)):
        if child:
            role, rate, count, warmup, topic = child
            side(role, float(rate), int(count), float(warmup), topic)
            return 0
    if shutil.which("rosmaster") is None:
        print("rosmaster is missing (Debian: apt-get install ros-core python3-rospy): nothing to measure")
        return 0
    rounds, seconds, warmup = (1, 0.5, 0.2) if args.smoke else (1, 2.0, 1.0) if args.quick else (3, 5.0, 1.0)
    hops = [tuple(h.split(">", 1)) for h in args.hops.split(",") if ">" in h]
    if not _has_rospy():
        print(f"rospy is missing for {SYSTEM_PYTHON} (Debian: apt-get install python3-rospy): the rospy hops are "
              "not measured")
        hops = [h for h in hops if "rospy" not in h]
    samples: dict[tuple[float, str, str], list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "rospy_peer.py"
        script.write_text(ROSPY_PEER)
        bench = Bench(Path(tmp), script)
        try:  # a master that does not answer in time is stopped too
            bench.start_master()
            for _ in range(rounds):
                for rate in (1000.0,) if args.smoke else (1000.0, 100.0):
                    for pub, sub in hops:
                        samples.setdefault((rate, pub, sub), []).extend(bench.hop(pub, sub, rate, seconds, warmup))
        finally:
            bench.stop_master()
    print_table(samples, rounds, seconds, warmup)
    return 0


def print_table(samples: dict[tuple[float, str, str], list[float]], rounds: int, seconds: float, warmup: float) -> None:
    print(f"\nROS 1 same-host hop, std_msgs/Int64 stamp → callback, {rounds} round(s) of {seconds:g} s per hop "
          f"(the first {warmup:g} s discarded), alternating; load average {os.getloadavg()[0]:.1f}\n")
    print("| rate | hop | samples | p50 µs | p99 µs | p50 / rospy→rospy |")
    print("|---|---|---|---|---|---|")
    for (rate, pub, sub), values in samples.items():
        base = samples.get((rate, "rospy", "rospy"))
        ratio = f"{pct(values, 0.5) / pct(base, 0.5):.2f}×" if base else "—"
        print(f"| {rate:g} Hz | {pub} → {sub} | {len(values)} | {pct(values, 0.5):.0f} | {pct(values, 0.99):.0f} | {ratio} |")


if __name__ == "__main__":
    sys.exit(main())
