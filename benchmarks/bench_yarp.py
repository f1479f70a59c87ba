"""Benchmark of scart on YARP against YARP itself and rospy, hop by hop, one run.

Usage: ``python benchmarks/bench_yarp.py [--quick | --smoke] [--rounds N] [--hops scart>scart,...]`` (needs YARP's ``yarpserver``
and ``yarp`` on PATH; the rospy row needs Debian's ``ros-core`` and ``python3-rospy``).

Each hop sends ``CLOCK_MONOTONIC`` stamps (an int, one per sample) at 1 kHz and 100 Hz on
absolute deadlines, from a writer process to a reader process on this host, and the reader
notes when each arrived (the first second of each hop is left out). The hops:

* ``yarp → yarp``: YARP's own tools, C++ (the anchor): the bench writes each stamp to
  ``yarp write``'s stdin and reads it from ``yarp read``'s stdout;
* ``scart → yarp``: a scart output port streamed on YARP (``tcp``), read by ``yarp read``
  (its stdout read by the bench);
* ``yarp → scart``: ``yarp write`` (fed by the bench) into a scart input port, timed in the
  port's data callback (as rospy's callback runs in its receiving thread);
* ``scart → scart``: two scart processes, both sides native;
* ``ours → yarp`` and ``yarp → ours``: the bare YARP library (``scart_yarp.Network``, no
  task, port or stream) in place of scart's side: the rows minus these are what scart's
  data-flow layer adds to YARP's protocol;
* ``rospy → rospy``: Debian's rospy, ``tcp_nodelay`` (the goal's yardstick);
* ``pipe → cat → pipe``: the bench through ``cat``: what the two pipe legs of the
  ``yarp → yarp`` row cost by themselves (the ``scart → yarp`` and ``yarp → scart`` rows
  have one leg each).

Goal (issue 32): scart's hops at most the rospy hop of the same run; the ratio to YARP's
own hop is printed too.

**YARP's own latency test, with no pipe.** The rows with a YARP tool time that tool too
(``yarp write`` reads the bench's pipe, ``yarp read`` prints to it). A second table runs
YARP's ``yarp latency-test --client`` (C++: it writes ``[frame, time]``, waits for
the answer, logs the round trip, pauses 1 ms) against its own ``--server`` (C++) and against a
``scart_yarp`` port answering the same way (``/latencyTest/server``), alternating: both
with ``--no-reply`` (data ports: the answer goes back on a connection of its own, as a
port's stream) and with YARP's default, the answer on the same connection (an RPC: the
``responder`` of a scart_yarp port).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import paced, pct, wait_until  # noqa: E402
from bench_ros1 import ROSPY_PEER, Bench, _has_rospy, _wait_for  # noqa: E402

HOPS = (("rospy", "rospy"), ("yarp", "yarp"), ("scart", "yarp"), ("yarp", "scart"), ("scart", "scart"),
        ("ours", "yarp"), ("yarp", "ours"), ("pipe", "pipe"))
IN, OUT = "/bench/scart/in", "/bench/scart/out"


def scart_side(role: str, rate: float, count: int, warmup: float, server: str, peer: str) -> None:
    """The ``--child`` side: a scart port streamed on YARP, writing stamps (``pub``,
    connected to ``peer``) or noting them in its data callback (``sub``)."""
    from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext

    class Stamper(TaskContext):
        stamp = OutputPort(int)

    class Receiver(TaskContext):
        stamp = InputPort(int)

        def __init__(self, name: str) -> None:
            super().__init__(name)
            self.got: list[tuple[int, int]] = []
            self.stamp.add_data_callback(lambda port: self.got.append((time.monotonic_ns(),
                                                                       port.read_newest()[1])))

    options = {"server": server, **({"connect": peer} if role == "pub" else {})}
    with Deployer() as dep:
        task = dep.add(Stamper("stamper") if role == "pub" else Receiver("receiver"))
        dep.configure_all()
        dep.start_all()
        made = dep.stream(f"{task.name}.stamp", ConnPolicy.data().with_(transport="yarp", topic=OUT if role == "pub"
                                                                        else IN), options)
        if role == "pub":
            port = dep.streams()[made.name]._stream._port  # the benchmark peeks: wait for its reader
            wait_until(lambda: peer in port.outputs, 30)
            paced(count, rate, lambda k: task.stamp.write(time.monotonic_ns()))
            time.sleep(0.5)
        else:
            print("ready", flush=True)
            _wait_for(task.got, count, rate)
        dep.unstream(made.name)
        dep.stop_all()
    if role != "pub":
        got = list(task.got)
        first = got[0][1] if got else 0
        print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)


#: the scart_yarp side of ``yarp latency-test`` (its server's protocol)
LATENCY_SERVER = "/latencyTest/server"


def latency_server(server: str, mode: str) -> None:
    """The ``--child-latency-server`` side: answer YARP's latency-test client as its C++
    server does (``start N`` sets an N-byte payload; each ``[frame, time]`` comes back with
    the payload, a copy time and a count appended; ``stop`` ends), with a reader that writes
    back (``noreply``) or a responder (``reply``)."""
    from scart_yarp import Incoming, Network, parse_address

    net = Network(parse_address(server))
    done = threading.Event()
    state: dict[str, Any] = {"payload": "", "n": 0}

    def answer(values: list[Any]) -> list[Any] | None:
        if values and values[0] == "start":
            state["payload"] = "p" * max(0, int(values[1]) - 1)
            return None
        if values and values[0] in ("stop", "quit"):
            done.set()
            return None
        state["n"] += 1
        return [*values, state["payload"], 0.0, state["n"] - 1]

    def on_data(msg: Incoming) -> None:
        reply = answer(msg.values())
        if reply is not None:
            port.write(reply)

    try:
        if mode == "reply":
            port = net.open_port(LATENCY_SERVER, responder=lambda values: answer(list(values)) or [])
        else:
            port = net.open_port(LATENCY_SERVER, reader=on_data)
        print("ready", flush=True)
        done.wait(600)
    finally:
        net.close()


def latency_test(yarp: Yarp, server: str, mode: str, frames: int, folder: Path) -> list[float]:
    """One ``yarp latency-test --client`` run against ``server`` (``yarp`` or ``ours``);
    the round trips in µs (the first quarter left out)."""
    if server == "yarp":
        proc = subprocess.Popen(["yarp", "latency-test", "--server"], env=yarp.env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
    else:
        proc = subprocess.Popen([sys.executable, __file__, "--child-latency-server", yarp.address, mode],
                                env=yarp.env, stdout=subprocess.DEVNULL)
    try:
        if not wait_until(lambda: yarp.registered(LATENCY_SERVER), 30, interval=0.05):
            raise RuntimeError(f"the {server} latency-test server did not register")
        log = folder / f"latency_{server}_{mode}_"
        try:
            subprocess.run(["yarp", "latency-test", "--client", "--nframes", str(frames), "--payload_size", "8",
                            "--client_wait", "0.001", "--logfile", str(log),
                            *(["--no-reply"] if mode == "noreply" else [])],
                           env=yarp.env, capture_output=True, timeout=frames / 200 + 30, check=True)
        except subprocess.TimeoutExpired:  # the client waits for ever for an answer that never comes
            print(f"yarp latency-test against the {server} server ({mode}): no end in time, not counted")
            return []
        rows = Path(f"{log}8.txt").read_text().splitlines()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
        # YARP's server leaves its name registered when killed: the next server must not meet it
        subprocess.run(["yarp", "name", "unregister", LATENCY_SERVER], env=yarp.env, capture_output=True, timeout=30)
    return [float(row.split()[0]) * 1000 for row in rows[len(rows) // 4:]]


def ours_side(role: str, rate: float, count: int, warmup: float, server: str, peer: str) -> None:
    """The ``--child-ours`` side: the same with the bare library, a ``scart_yarp`` port
    writing a one-number bottle per stamp, or noting each in its reader callback."""
    from scart_yarp import Network, parse_address

    got: list[tuple[int, int]] = []
    net = Network(parse_address(server))
    try:
        if role == "pub":
            port = net.open_port(OUT, connect={peer: "tcp"})
            wait_until(lambda: peer in port.outputs, 30)
            paced(count, rate, lambda k: port.write([time.monotonic_ns()]))
            time.sleep(0.5)
            return
        net.open_port(IN, reader=lambda msg: got.append((time.monotonic_ns(), msg.values()[0])))
        print("ready", flush=True)
        _wait_for(got, count, rate)
    finally:
        net.close()
    first = got[0][1] if got else 0
    print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)


class Yarp:
    """A ``yarpserver`` of the bench's own (own configuration folder, a free port)."""

    def __init__(self, folder: Path) -> None:
        self.port = _server_port()
        self.address = f"127.0.0.1:{self.port}"
        self.env = dict(os.environ, YARP_CONFIG_HOME=str(folder / "yarp"))
        subprocess.run(["yarp", "conf", "127.0.0.1", str(self.port)], env=self.env, capture_output=True, check=True)
        self.server = subprocess.Popen(["yarpserver", "--read", "--ip", "127.0.0.1", "--socket", str(self.port)],
                                       env=self.env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                       start_new_session=True)
        if not wait_until(lambda: self.registered("/root"), timeout=30, interval=0.05):
            self.stop()
            raise SystemExit("yarpserver did not start")

    def registered(self, name: str) -> bool:
        done = subprocess.run(["yarp", "name", "query", name], env=self.env, capture_output=True, text=True)
        return f"registration name {name} " in done.stdout

    def tool(self, *args: str) -> subprocess.Popen[str]:
        return subprocess.Popen(["yarp", *args], env=self.env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True, bufsize=1)

    def stop(self) -> None:
        self.server.terminate()
        try:
            self.server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.server.kill()
            self.server.wait(timeout=10)


def _server_port() -> int:
    """A port for yarpserver below the kernel's ephemeral range (32768 on Linux), free with
    the 50 after it: yarpserver hands its tools the ports after its own without asking."""
    import random
    import socket

    def free(port: int) -> bool:
        with socket.socket() as sock:
            try:
                sock.bind(("127.0.0.1", port))
                return True
            except OSError:
                return False

    for _ in range(200):  # bounded: random tries
        port = random.randrange(20_000, 32_000)
        if all(free(p) for p in range(port, port + 51)):
            return port
    raise SystemExit("no run of 51 free ports for yarpserver")


def _lines(proc: subprocess.Popen[str], got: list[tuple[int, int]], ready: threading.Event) -> None:
    """Note when each stamp a tool prints arrives (a thread of the bench's)."""
    assert proc.stdout is not None
    for line in proc.stdout:
        now = time.monotonic_ns()
        word = line.strip().split(" ")[0]
        if word.lstrip("-").isdigit():
            got.append((now, int(word)))
        elif "Receiving input" in line or word == "ready":
            ready.set()


def _feed(proc: subprocess.Popen[str], count: int, rate: float) -> None:
    assert proc.stdin is not None
    stdin = proc.stdin

    def one(_: int) -> None:
        stdin.write(f"{time.monotonic_ns()}\n")
        stdin.flush()

    paced(count, rate, one)


#: the child flag of each Python side
_CHILD = {"scart": "--child", "ours": "--child-ours"}


def yarp_hop(yarp: Yarp, pub: str, sub: str, rate: float, seconds: float, warmup: float) -> list[float]:
    """A hop with a YARP tool or ``cat`` on one side or both; the latencies in µs."""
    count = int(rate * (seconds + warmup))
    got: list[tuple[int, int]] = []
    ready = threading.Event()
    procs: list[subprocess.Popen[str]] = []
    try:
        if pub == "pipe":
            cat = subprocess.Popen(["cat"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
            procs.append(cat)
            threading.Thread(target=_lines, args=(cat, got, ready), daemon=True).start()
            _feed(cat, count, rate)
        elif sub == "yarp":
            reader = yarp.tool("read", "/bench/r")
            procs.append(reader)
            threading.Thread(target=_lines, args=(reader, got, ready), daemon=True).start()
            wait_until(lambda: yarp.registered("/bench/r"), 30)
            if pub == "yarp":
                writer = yarp.tool("write", "/bench/w", "/bench/r")
                procs.append(writer)
                ready.wait(30)
                _feed(writer, count, rate)
            else:
                subprocess.run([sys.executable, __file__, _CHILD[pub], "pub", str(rate), str(count), str(warmup),
                                yarp.address, "/bench/r"], check=True, timeout=count / rate + 120)
        else:  # yarp → scart or ours
            receiver = subprocess.Popen([sys.executable, __file__, _CHILD[sub], "sub", str(rate), str(count),
                                         str(warmup), yarp.address, ""], stdout=subprocess.PIPE, text=True)
            assert receiver.stdout is not None
            if receiver.stdout.readline().strip() != "ready":
                raise RuntimeError("the scart receiver failed")
            writer = yarp.tool("write", "/bench/w", IN)
            procs.append(writer)
            time.sleep(0.5)  # the writer's connection is made when it starts (no event to wait on)
            _feed(writer, count, rate)
            out, _ = receiver.communicate(timeout=count / rate + 120)
            return [ns / 1000 for ns in json.loads(out.strip().splitlines()[-1])]
        wait_until(lambda: len(got) >= count, timeout=5)
    finally:
        for proc in procs:
            proc.terminate()
            proc.wait(timeout=10)
    first = got[0][1] if got else 0
    return [(a - s) / 1000 for a, s in got if s - first >= warmup * 1e9]


def scart_pair(yarp: Yarp, rate: float, seconds: float, warmup: float) -> list[float]:
    """scart → scart: both processes native."""
    count = int(rate * (seconds + warmup))
    receiver = subprocess.Popen([sys.executable, __file__, "--child", "sub", str(rate), str(count), str(warmup),
                                 yarp.address, ""], stdout=subprocess.PIPE, text=True)
    assert receiver.stdout is not None
    try:
        if receiver.stdout.readline().strip() != "ready":
            raise RuntimeError("the scart receiver failed")
        subprocess.run([sys.executable, __file__, "--child", "pub", str(rate), str(count), str(warmup),
                        yarp.address, IN], check=True, timeout=count / rate + 120)
        out, _ = receiver.communicate(timeout=count / rate + 120)
    finally:
        if receiver.poll() is None:
            receiver.kill()
            receiver.wait()
    return [ns / 1000 for ns in json.loads(out.strip().splitlines()[-1])]


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one round of 2 s hops")
    parser.add_argument("--smoke", action="store_true", help="one short round (proves every path works)")
    parser.add_argument("--rounds", type=int, help="rounds of every hop, alternating (default: 3; 1 with --quick)")
    parser.add_argument("--hops", default=",".join(f"{p}>{s}" for p, s in HOPS),
                        help="the hops to measure, writer>reader (default: all; the rospy hop is the goal's yardstick)")
    parser.add_argument("--child", nargs=6, help=argparse.SUPPRESS)
    parser.add_argument("--child-ours", nargs=6, help=argparse.SUPPRESS)
    parser.add_argument("--child-latency-server", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child_latency_server:
        latency_server(*args.child_latency_server)
        return 0
    for child, side in ((args.child, scart_side), (args.child_ours, ours_side)):
        if child:
            role, rate, count, warmup, server, peer = child
            side(role, float(rate), int(count), float(warmup), server, peer)
            return 0
    if shutil.which("yarpserver") is None or shutil.which("yarp") is None:
        print("YARP's yarpserver and yarp are not on PATH (the steering repository's shared/yarp/build.sh builds "
              "them): nothing to measure\n\n| rate | hop | p50 µs |\n|---|---|---|")
        return 0
    rounds, seconds, warmup = (1, 0.5, 0.2) if args.smoke else (1, 2.0, 1.0) if args.quick else (3, 5.0, 1.0)
    rounds = args.rounds or rounds
    asked = [h for h in args.hops.replace(" ", "").split(",") if h]
    unknown = sorted(set(asked) - {f"{p}>{s}" for p, s in HOPS})
    if unknown:
        parser.error(f"unknown hop(s) {', '.join(unknown)}; the hops: {', '.join(f'{p}>{s}' for p, s in HOPS)}")
    hops = [hop for hop in HOPS if f"{hop[0]}>{hop[1]}" in asked]
    rospy = ("rospy", "rospy") in hops and shutil.which("rosmaster") is not None and _has_rospy()
    if not rospy and ("rospy", "rospy") in hops:
        print("rosmaster or rospy is missing (Debian: apt-get install ros-core python3-rospy): no rospy row")
        hops.remove(("rospy", "rospy"))
    samples: dict[tuple[float, str, str], list[float]] = {}
    trips: dict[tuple[str, str], list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        script = Path(tmp) / "rospy_peer.py"
        script.write_text(ROSPY_PEER)
        ros = Bench(Path(tmp), script)
        yarp: Yarp | None = None
        try:  # whatever fails, the servers started are stopped
            yarp = Yarp(Path(tmp))
            if rospy:
                ros.start_master()
            for _ in range(rounds):
                for rate in (1000.0,) if args.smoke else (1000.0, 100.0):
                    for pub, sub in hops:
                        if pub == "rospy":
                            got = ros.hop("rospy", "rospy", rate, seconds, warmup)
                        elif pub == sub == "scart":
                            got = scart_pair(yarp, rate, seconds, warmup)
                        else:
                            got = yarp_hop(yarp, pub, sub, rate, seconds, warmup)
                        samples.setdefault((rate, pub, sub), []).extend(got)
                for mode in ("noreply", "reply"):
                    for server in ("yarp", "ours"):
                        frames = 300 if args.smoke else int(1000 * seconds)
                        trips.setdefault((mode, server), []).extend(latency_test(yarp, server, mode, frames, Path(tmp)))
        finally:
            ros.stop_master()
            if yarp is not None:
                yarp.stop()
    print_table(samples, rounds, seconds, warmup)
    print_trips(trips)
    return 0


def print_table(samples: dict[tuple[float, str, str], list[float]], rounds: int, seconds: float, warmup: float) -> None:
    print(f"\nYARP same-host hop, a stamp per sample, {rounds} round(s) of {seconds:g} s per hop (the first "
          f"{warmup:g} s discarded), alternating; load average {os.getloadavg()[0]:.1f}\n")
    print("| rate | hop | samples | p50 µs | p99 µs | p50 / rospy | p99 / rospy | p50 / yarp→yarp |")
    print("|---|---|---|---|---|---|---|---|")
    for (rate, pub, sub), values in samples.items():
        rospy, yarp = samples.get((rate, "rospy", "rospy")), samples.get((rate, "yarp", "yarp"))

        def ratio(base: list[float] | None, q: float) -> str:
            return f"{pct(values, q) / pct(base, q):.2f}×" if base else "—"

        print(f"| {rate:g} Hz | {pub} → {sub} | {len(values)} | {pct(values, 0.5):.0f} | {pct(values, 0.99):.0f} | "
              f"{ratio(rospy, 0.5)} | {ratio(rospy, 0.99)} | {ratio(yarp, 0.5)} |")


def print_trips(trips: dict[tuple[str, str], list[float]]) -> None:
    print("\nYARP's own latency test (`yarp latency-test --client`, C++: a frame 1 ms after each answer, 8-byte payload): its round trip "
          "through its own C++ server and through a scart_yarp port, no pipe\n")
    print("| answer | server | frames | p50 µs | p99 µs | p50 / YARP's server |")
    print("|---|---|---|---|---|---|")
    for (mode, server), values in trips.items():
        base = trips.get((mode, "yarp"))
        label = "its own connection (data ports)" if mode == "noreply" else "same connection (RPC)"
        who = "YARP (C++)" if server == "yarp" else "scart_yarp"
        if not values:
            print(f"| {label} | {who} | 0 | — | — | — |")
            continue
        ratio = f"{pct(values, 0.5) / pct(base, 0.5):.2f}×" if base else "—"
        print(f"| {label} | {who} | {len(values)} | {pct(values, 0.5):.0f} | {pct(values, 0.99):.0f} | {ratio} |")


if __name__ == "__main__":
    sys.exit(main())
