"""Benchmark of camera-sized samples between two processes of one host, peers alongside,
in one run (issue 35).

Usage: ``python benchmarks/bench_big.py [--quick | --smoke]``. Not a test: the test suite
runs its ``--smoke`` (that every path works), never for numbers.

**The big hop.** Samples of 1 MiB, 6.2 MB (one 1080p RGB frame) and 24.9 MB (one 4K RGB
frame) at 30 Hz on absolute deadlines, each stamped with ``time.monotonic_ns()`` in its
first 8 bytes just before it is written; the subscriber records arrival − stamp where its
task reads it (an event port's ``update_hook``). Alternating in each round:

- **scart, default** (``auto``: ``shm`` for large samples on one host), an array port
  (``Array[np.uint8, (n,)]``), and a ``bytes`` port; **scart** with each explicit
  transport: ``shm``, ``ipc``, ``grpc`` (array ports): a link from an output port of one
  ``Deployer`` process to an event input port of another (``buffer:4``);
- **rospy Image → rospy** (Debian's ``python3-rospy`` for ``/usr/bin/python3``,
  ``sensor_msgs/Image``, ``queue_size=1``, ``tcp_nodelay``; a ``rosmaster --core`` on a
  free port) — skipped, and said, when rospy is missing;
- **bare Cyclone DDS**: an ``IdlStruct`` of a stamp and a ``sequence<octet>``,
  cyclonedds-python both ends (1 MiB and 6.2 MB only: its Python serialiser takes a
  second for 25 MB), skipped without ``scart[ros2]``;
- **scart, ros2 stream**: the array port published as a ROS 2 topic
  (``std_msgs/msg/UInt8MultiArray``, CDR made by rosbags and written as bytes) and an
  input port of the other process fed from it, skipped without ``scart[ros2]``;
- **one copy**: ``bytearray(sample)`` of a sample of random bytes, in this process, at
  30 Hz as the hops (the floor a hop cannot beat in Python: the issue's 0.55 ms at 6.2 MB).

**ROS 2's codec**: one 1080p RGB ``sensor_msgs/msg/Image`` to and from its CDR bytes,
scart's way (rosbags) against Cyclone DDS's Python serialiser, and one copy.

**The goals** (issue 35), from the same run:

- 1 MiB hop p50, default: ≤ 0.5× rospy's;
- 6.2 MB hop p50, default: ≤ 0.25× rospy's and ≤ 5× one copy;
- 6.2 MB at 60 Hz from one writer to 3 readers (three processes, ``buffer:8``): the
  writer ≥ 99 % on time (each write done before its next deadline), the readers lose
  nothing;
- 24.9 MB at 30 Hz, default: every write delivered or counted, none over a limit;
- the hop to an event task, 1 kHz, a small sample (``int``): p50 and p99 ≤ rospy's
  callback (``std_msgs/Int64``) in the same run, with the task on a
  ``SequentialActivity`` (run in the thread that stores the sample) and, for comparison,
  on the default ``EventActivity`` (woken);
- the model codec: scart's encode + decode of a pydantic model (a youBot status) ≤ 1.15×
  pydantic's own ``model_dump_json`` + ``model_validate_json``, both measured cold, as a
  1 kHz sender and receiver pay them (one of each per millisecond).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from _common import paced, pct, pub_sub_hop, wait_until  # noqa: E402

import numpy as np  # noqa: E402

from dataflow import (  # noqa: E402
    Array, ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, SequentialActivity, TaskContext,
)
from dataflow.activities import freeze_heap  # noqa: E402

SIZES = {"1 MiB": 1 << 20, "6.2 MB": 6_220_800, "24.9 MB": 24_883_200}
RATE = 30.0
#: (label, port kind, transport) of the scart big hops
SCART_HOPS = (("scart, default", "array", "auto"), ("scart, default, bytes port", "bytes", "auto"),
              ("scart, shm", "array", "shm"), ("scart, ipc", "array", "ipc"), ("scart, grpc", "array", "grpc"))
SYSTEM_PYTHON = "/usr/bin/python3"
ROS2_TOPIC = "/scart_bench_big"
#: the ROS 2 stream hop (an array port published as a std_msgs/msg/UInt8MultiArray), with scart[ros2]
ROS2_HOP = ("scart, ros2 stream (UInt8MultiArray)", "array", "ros2")
STAMP = 8  # bytes of the stamp at the head of each sample


# ---- scart's sides ---------------------------------------------------------------------
def _port_type(kind: str, size: int) -> Any:
    return Array[np.uint8, (size,)] if kind == "array" else (bytes if kind == "bytes" else int)


def _stamp_of(value: Any) -> int:
    if isinstance(value, int):
        return value
    return int.from_bytes(bytes(memoryview(value)[:STAMP]), "little")


def sink_child(name: str, kind: str, size: int, count: int, warmup: float, sequential: bool, topic: str = "") -> None:
    """A subscriber process: serve a sink task ``name`` (an event port of the kind; fed
    from the ROS 2 ``topic`` when one is given), say where, and once ``count`` samples came
    (or 3 s of nothing) print the latencies (ns) and how many it read; serve on until
    stdin closes."""

    class Sink(TaskContext):
        inp = InputPort(_port_type(kind, size), event=True)

        def __init__(self, task_name: str) -> None:
            super().__init__(task_name)
            self.read: list[tuple[int, int]] = []

        def update_hook(self) -> None:
            for _ in range(10_000):
                flow, value = self.inp.read()
                if flow is not FlowStatus.NEW_DATA:
                    return
                self.read.append((time.monotonic_ns(), _stamp_of(value)))

    deployer = Deployer()
    sink = deployer.add(Sink(name))
    if sequential:
        sink.set_activity(SequentialActivity())
    deployer.configure_all()
    deployer.start_all()
    if topic:
        deployer.stream(f"{name}.inp", ConnPolicy.buffer(4).with_(transport="ros2", topic=topic), ros2_options())
    server = deployer.serve("127.0.0.1:0", ns=os.environ.get("BENCH_NS") or None)
    freeze_heap()  # as scart deploy does once its tasks run
    print("ready", server.address, flush=True)
    last, seen = -1, time.monotonic()
    deadline = time.monotonic() + 600
    while len(sink.read) < count and time.monotonic() < deadline:
        if len(sink.read) != last:
            last, seen = len(sink.read), time.monotonic()
        elif time.monotonic() - seen > (3.0 if sink.read else 30.0):
            break
        time.sleep(0.01)
    reads = list(sink.read)
    first = reads[0][1] if reads else 0
    latencies = [a - s for a, s in reads if s - first >= warmup * 1e9]
    print(json.dumps({"latencies": latencies, "read": len(reads)}), flush=True)
    sys.stdin.read()  # until the parent closes it
    server.stop()
    for stream in list(deployer.streams()):
        deployer.unstream(stream)
    deployer.stop_all()


def ros2_options() -> dict[str, str]:
    """The ROS 2 streams' options of this run (its DDS domain)."""
    return {"domain": os.environ.get("BENCH_DOMAIN", "0")}


def source_child(ns: str, sinks: list[str], kind: str, transport: str, size: int, rate: float, count: int,
                 policy: str) -> None:
    """A publisher process: link its port to each sink's over ``transport``, write
    ``count`` stamped samples at ``rate`` Hz, and print how many writes were on time and
    what each link counted."""
    from dataflow.remote import connect

    class Source(TaskContext):
        out = OutputPort(_port_type(kind, size))

    deployer = Deployer()
    src = deployer.add(Source("src"))
    server = deployer.serve("127.0.0.1:0", ns=ns)
    frames = [np.random.default_rng(k).integers(0, 255, size, dtype=np.uint8) for k in range(3)] if kind != "int" else []
    try:
        with connect(ns, timeout=5.0) as system:
            if transport == "ros2":  # a ROS 2 topic between the two: the stream's reader matched, or nothing is read
                deployer.stream("src.out", ConnPolicy.parse(policy).with_(transport="ros2", topic=ROS2_TOPIC),
                                ros2_options())
                if not wait_until(lambda: any(p.matched() for p in _ros2_publishers()), 20):
                    raise SystemExit("the ROS 2 stream's reader never matched")
            for k, sink in enumerate(sinks if transport != "ros2" else ()):
                system.connect_ports("src.out", f"{sink}.inp", ConnPolicy.parse(policy).with_(transport=transport),
                                     name=f"hop{k}")
            if transport != "ros2" and not wait_until(
                    lambda: sum(not lk.transport.endswith("?") for lk in system.links()) == len(sinks), 20):
                raise SystemExit(f"the links did not come up over {transport}: {system.links()}")
            freeze_heap()  # as scart deploy does once its tasks run
            on_time, period = [0], 1.0 / rate
            start = time.perf_counter()

            def write(k: int) -> None:
                stamp = time.monotonic_ns()
                if kind == "int":
                    src.out.write(stamp)
                else:
                    frame = frames[k % len(frames)]
                    frame[:STAMP] = np.frombuffer(stamp.to_bytes(STAMP, "little"), dtype=np.uint8)
                    src.out.write(frame if kind == "array" else frame.tobytes())
                on_time[0] += time.perf_counter() <= start + (k + 1) * period

            paced(count, rate, write)
            wait_until(lambda: all(lk.pending == 0 for lk in system.links()), 10)
            links = [{"samples": lk.samples, "dropped": lk.dropped, "transport": lk.transport} for lk in system.links()]
        print(json.dumps({"on_time": on_time[0], "written": count, "links": links}), flush=True)
    finally:
        server.stop()
        for stream in list(deployer.streams()):
            deployer.unstream(stream)


def _ros2_publishers() -> list[Any]:
    from dataflow.transports import load

    return [e for p in load("ros2").participants().values() for e in p._endpoints if hasattr(e, "publish")]


def scart_hop(kind: str, transport: str, size: int, rate: float, count: int, warmup: float, readers: int = 1,
              policy: str = "buffer:4", sequential: bool = False) -> dict[str, Any]:
    """One scart hop (``readers`` sink processes): each reader's latencies (µs) and read
    count, the writer's on-time writes, and the links' counts."""
    import random

    sinks: list[subprocess.Popen[str]] = []
    domain = str(random.randint(1, 200))  # (ros2 only) a DDS domain of this hop's own
    try:
        ns = ""
        for k in range(readers):
            env = dict(os.environ, BENCH_NS=ns, BENCH_DOMAIN=domain)
            proc = subprocess.Popen([sys.executable, __file__, "--sink", f"hop{k}", kind, str(size), str(count),
                                     str(warmup), str(int(sequential)), ROS2_TOPIC if transport == "ros2" else ""],
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
            sinks.append(proc)
            assert proc.stdout is not None
            line = proc.stdout.readline().split()
            if line[:1] != ["ready"]:
                raise RuntimeError("a scart sink did not start")
            ns = ns or line[1]
        done = subprocess.run([sys.executable, __file__, "--source", ns, ",".join(f"hop{k}" for k in range(readers)),
                               kind, transport, str(size), str(rate), str(count), policy],
                              capture_output=True, text=True, timeout=count / rate + 180,
                              env=dict(os.environ, BENCH_DOMAIN=domain))
        if done.returncode != 0:
            raise RuntimeError(f"the scart source failed: {done.stderr[-2000:]}")
        source = json.loads(done.stdout.strip().splitlines()[-1])
        reads = []
        for proc in sinks:
            out, _ = proc.communicate(timeout=120)
            reads.append(json.loads(out.strip().splitlines()[-1]))
    finally:
        for proc in sinks:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return {"latencies": [ns_ / 1000 for r in reads for ns_ in r["latencies"]], "read": [r["read"] for r in reads],
            **source}


# ---- peers -------------------------------------------------------------------------------
ROSPY_IMAGE = r'''
import json, sys, time
import rospy
from sensor_msgs.msg import Image
from std_msgs.msg import Int64
role, rate, count, warmup, size, kind = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]), sys.argv[6]
rospy.init_node("rospy_" + role, anonymous=True, disable_signals=True)
def stamp_of(m):
    return m.data if kind == "int" else int.from_bytes(m.data[:8], "little")
if role == "pub":
    pub = rospy.Publisher("/bench_big", Int64 if kind == "int" else Image, queue_size=1, tcp_nodelay=True)
    deadline = time.monotonic() + 30
    while pub.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    frames = [bytearray(bytes([k]) * size) for k in range(3)]
    period, t = 1.0 / rate, time.perf_counter()
    for k in range(count):
        t += period
        if kind == "int":
            pub.publish(Int64(data=time.monotonic_ns()))
        else:
            frame = frames[k % 3]
            frame[:8] = time.monotonic_ns().to_bytes(8, "little")
            pub.publish(Image(height=1, width=size, encoding="mono8", step=size, data=bytes(frame)))
        pause = t - time.perf_counter()
        if pause > 0:
            time.sleep(pause)
    time.sleep(0.5)
else:
    got = []
    rospy.Subscriber("/bench_big", Int64 if kind == "int" else Image,
                     lambda m: got.append((time.monotonic_ns(), stamp_of(m))), tcp_nodelay=True, queue_size=1,
                     buff_size=1 << 26)
    print("ready", flush=True)
    deadline, last, seen = time.monotonic() + count / rate + 60, -1, time.monotonic()
    while len(got) < count and time.monotonic() < deadline:
        if last != len(got):
            last, seen = len(got), time.monotonic()
        elif got and time.monotonic() - seen > 3.0:
            break
        time.sleep(0.01)
    first = got[0][1] if got else 0
    print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)
rospy.signal_shutdown("done")
'''


class Rospy:
    """A rosmaster on a free port and the rospy peer's command lines (bench_ros1's)."""

    def __init__(self, folder: Path) -> None:
        import bench_ros1

        script = folder / "rospy_image.py"
        script.write_text(ROSPY_IMAGE)
        self.script = script
        self.bench = bench_ros1.Bench(folder, script)

    def __enter__(self) -> Rospy:
        self.bench.start_master()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bench.stop_master()

    def hop(self, kind: str, size: int, rate: float, count: int, warmup: float) -> list[float]:
        args = [str(rate), str(count), str(warmup), str(size), kind]
        script = [SYSTEM_PYTHON, str(self.script)]
        return pub_sub_hop([*script, "sub", *args], [*script, "pub", *args], self.bench.env,
                           count / rate + 120, "the rospy")


def has_rospy() -> bool:
    if shutil.which("rosmaster") is None or not os.path.exists(SYSTEM_PYTHON):
        return False
    check = [SYSTEM_PYTHON, "-c", "import rospy, sensor_msgs.msg"]
    return subprocess.run(check, capture_output=True).returncode == 0


def cyclone_child(role: str, size: int, rate: float, count: int, warmup: float, domain: int) -> None:
    """Bare cyclonedds-python, a stamp and a ``sequence<octet>``, one end of the hop."""
    from cyclonedds.core import Qos, Policy
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.util import duration
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as t
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    Blob = make_idl_struct("Blob", "scart_bench::Blob", {"stamp": t.int64, "data": t.sequence[t.uint8]})

    participant = DomainParticipant(domain)
    topic = Topic(participant, "scart_bench_big", Blob)
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(1))
    if role == "pub":
        writer = DataWriter(participant, topic, qos=qos)
        wait_until(lambda: writer.get_matched_subscriptions(), 30)
        frame = bytes(size)
        paced(count, rate, lambda k: writer.write(Blob(stamp=time.monotonic_ns(), data=frame)))
        time.sleep(1.0)
        return
    reader = DataReader(participant, topic, qos=qos)
    print("ready", flush=True)
    got: list[tuple[int, int]] = []
    deadline, last, seen = time.monotonic() + count / rate + 120, -1, time.monotonic()
    while len(got) < count and time.monotonic() < deadline:
        for sample in reader.take(N=16):
            if hasattr(sample, "stamp"):  # not the writer going away (an InvalidSample)
                got.append((time.monotonic_ns(), sample.stamp))
        if last != len(got):
            last, seen = len(got), time.monotonic()
        elif got and time.monotonic() - seen > 3.0:
            break
        time.sleep(0.0005)
    first = got[0][1] if got else 0
    print(json.dumps([a - s for a, s in got if s - first >= warmup * 1e9]), flush=True)


def cyclone_hop(size: int, rate: float, count: int, warmup: float) -> list[float]:
    import random

    args = [str(size), str(rate), str(count), str(warmup), str(random.randint(1, 200))]
    sub = subprocess.Popen([sys.executable, __file__, "--cyclone", "sub", *args], stdout=subprocess.PIPE, text=True)
    try:
        assert sub.stdout is not None
        if sub.stdout.readline().strip() != "ready":
            raise RuntimeError("the Cyclone DDS subscriber failed")
        subprocess.run([sys.executable, __file__, "--cyclone", "pub", *args], check=True, timeout=count / rate + 180)
        out, _ = sub.communicate(timeout=180)
    finally:
        if sub.poll() is None:
            sub.kill()
            sub.wait()
    return [ns / 1000 for ns in json.loads(out.strip().splitlines()[-1])]


def has_cyclone() -> bool:
    import importlib.util

    return importlib.util.find_spec("cyclonedds") is not None


def one_copy(size: int, count: int, rate: float = RATE) -> list[float]:
    """``bytearray(sample)`` of random bytes, µs each, at ``rate`` Hz as the hops copy (the
    caches go cold between two samples, as they do between two frames of a camera)."""
    samples = [np.random.default_rng(k).integers(0, 255, size, dtype=np.uint8).tobytes() for k in range(3)]
    out: list[float] = []

    def copy(k: int) -> None:
        t0 = time.perf_counter()
        bytearray(samples[k % 3])
        out.append((time.perf_counter() - t0) * 1e6)

    paced(count, rate, copy)
    return out


# ---- the model codec ---------------------------------------------------------------------
def codec_rows(count: int) -> dict[str, float]:
    """Median µs of scart's encode + decode of a model, and of pydantic's own dump + check,
    each call a millisecond after the last of its kind (cold, as a 1 kHz sender and receiver pay them)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "composites" / "youbot"))
    from youbot_model import YouBotStatus  # the driver's model, as it crosses

    from scart_wire import codec

    status = YouBotStatus.model_validate({"joints": [{"position": 0.1 * k, "velocity": 0.0, "current": 0.2,
                                                      "temperature": 30.0 + k, "error_flags": 0} for k in range(5)]}) \
        if "joints" in YouBotStatus.model_fields else YouBotStatus()
    times: dict[str, list[float]] = {"scart": [], "pydantic": []}
    sides = (("scart", lambda: codec.decode(codec.encode(status, YouBotStatus))),
             ("pydantic", lambda: YouBotStatus.model_validate_json(status.model_dump_json())))

    def step(k: int) -> None:
        # each call follows its own kind a millisecond before, as at a 1 kHz sender or receiver
        # (tick by tick, the other kind would warm pydantic's code for it); blocks of 50
        # alternate 4 × count / 50 times, so a loaded machine's drift hits both alike
        label, round_trip = sides[k // 50 % 2]
        t0 = time.perf_counter()
        round_trip()
        times[label].append((time.perf_counter() - t0) * 1e6)

    paced(4 * count, 1000.0, step)  # 2 × count calls of each
    return {k: pct(v, 0.5) for k, v in times.items()}


def ros2_codec_rows(count: int) -> dict[str, float]:
    """Median ms to make and to read one 1080p RGB ``sensor_msgs/msg/Image`` sample's CDR
    bytes: scart's ROS 2 array conversion (rosbags' CDR, written and taken as bytes) and
    Cyclone DDS's own Python serialiser (an IDL ``sequence<uint8>``), at 30 Hz."""
    from scart_ros2 import MessageTypes
    from dataflow.transports.ros2._convert import plan

    types, spec = MessageTypes(), Array[np.uint8, (1080, 1920, 3)]
    out, back = plan(types, spec, None, outgoing=True)[0], plan(types, spec, None, outgoing=False)[0]
    assert out is not None and out.to_cdr is not None and back is not None and back.from_cdr is not None
    frame = np.random.default_rng(0).integers(0, 255, (1080, 1920, 3), dtype=np.uint8)
    data = bytes(out.to_cdr(frame, 0))
    idl = types.idl_type("sensor_msgs/msg/Image")
    sample = idl.deserialize(data)
    times: dict[str, list[float]] = {}

    def timed(label: str, fn: Any) -> Any:
        def step(_: int) -> None:
            t0 = time.perf_counter()
            fn()
            times.setdefault(label, []).append((time.perf_counter() - t0) * 1e3)
        return step

    paced(count, RATE, timed("scart: write (rosbags CDR)", lambda: out.to_cdr(frame, 0)))
    paced(count, RATE, timed("scart: read (rosbags CDR)", lambda: back.from_cdr(data)))
    paced(max(3, count // 10), RATE, timed("Cyclone DDS Python: serialise", lambda: sample.serialize(use_version_2=False)))
    paced(max(3, count // 10), RATE, timed("Cyclone DDS Python: deserialise", lambda: idl.deserialize(data)))
    paced(count, RATE, timed("one bytearray copy", lambda: bytearray(data)))
    return {k: pct(v, 0.5) for k, v in times.items()}


# ---- the run -------------------------------------------------------------------------------
def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one round of 3 s hops")
    parser.add_argument("--smoke", action="store_true", help="one short round (proves every path works)")
    parser.add_argument("--sink", nargs=7, help=argparse.SUPPRESS)
    parser.add_argument("--source", nargs=8, help=argparse.SUPPRESS)
    parser.add_argument("--cyclone", nargs=6, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.sink:
        name, kind, size, count, warmup, sequential, topic = args.sink
        sink_child(name, kind, int(size), int(count), float(warmup), sequential == "1", topic)
        return 0
    if args.source:
        ns, sinks, kind, transport, size, rate, count, policy = args.source
        source_child(ns, sinks.split(","), kind, transport, int(size), float(rate), int(count), policy)
        return 0
    if args.cyclone:
        role, size, rate, count, warmup, domain = args.cyclone
        cyclone_child(role, int(size), float(rate), int(count), float(warmup), int(domain))
        return 0
    rounds, seconds, warmup = (1, 0.7, 0.2) if args.smoke else (1, 3.0, 1.0) if args.quick else (3, 5.0, 1.0)
    run(rounds, seconds, warmup, args.smoke)
    return 0


def run(rounds: int, seconds: float, warmup: float, smoke: bool) -> None:
    rospy = has_rospy()
    cyclone = has_cyclone()
    if not rospy:
        print("rospy is missing (Debian: apt-get install ros-core python3-rospy python3-sensor-msgs): its rows are "
              "not measured")
    if not cyclone:
        print("cyclonedds is missing (pip install 'scart[ros2]'): the bare Cyclone DDS rows are not measured")
    sizes = {"6.2 MB": SIZES["6.2 MB"]} if smoke else SIZES
    hops = SCART_HOPS[:1] if smoke else SCART_HOPS
    count = int(RATE * (seconds + warmup))
    rows: dict[tuple[str, str], list[float]] = {}
    extra: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        peer = Rospy(Path(tmp)) if rospy else None
        try:
            if peer is not None:
                peer.__enter__()
            for _ in range(rounds):
                for size_label, size in sizes.items():
                    if peer is not None:
                        rows.setdefault((size_label, "rospy Image → rospy"), []).extend(
                            peer.hop("image", size, RATE, count, warmup))
                    for label, kind, transport in hops:
                        found = scart_hop(kind, transport, size, RATE, count, warmup)
                        rows.setdefault((size_label, label), []).extend(found["latencies"])
                        if (label, size_label) == ("scart, default", "24.9 MB"):
                            extra["uhd"] = found
                    if cyclone and size <= SIZES["6.2 MB"] and not smoke:
                        rows.setdefault((size_label, "bare Cyclone DDS, sequence<octet>"), []).extend(
                            cyclone_hop(size, RATE, count, warmup))
                    if cyclone and (size == SIZES["6.2 MB"] or not smoke):
                        label, kind, transport = ROS2_HOP
                        rows.setdefault((size_label, label), []).extend(
                            scart_hop(kind, transport, size, RATE, count, warmup)["latencies"])
                    rows.setdefault((size_label, "one bytearray copy"), []).extend(one_copy(size, count))
            fan_count = int(60.0 * (seconds + warmup))
            extra["fan"] = scart_hop("array", "auto", SIZES["6.2 MB"], 60.0, fan_count, warmup, readers=3,
                                     policy="buffer:8")
            small = int(1000.0 * (seconds + warmup))
            for label, sequential in (("scart task, SequentialActivity", True), ("scart task, EventActivity", False)):
                found = scart_hop("int", "auto", 0, 1000.0, small, warmup, sequential=sequential)
                rows.setdefault(("1 kHz int", label), []).extend(found["latencies"])
            if peer is not None:
                rows.setdefault(("1 kHz int", "rospy callback"), []).extend(peer.hop("int", 0, 1000.0, small, warmup))
        finally:
            if peer is not None:
                peer.__exit__()
    extra["codec"] = codec_rows(200 if smoke else 1000)
    if cyclone:
        extra["ros2_codec"] = ros2_codec_rows(3 if smoke else 30)
    print_tables(rows, extra, rounds, seconds, warmup)


def print_tables(rows: dict[tuple[str, str], list[float]], extra: dict[str, Any], rounds: int, seconds: float,
                 warmup: float) -> None:
    print(f"\nLarge samples, stamp → the reader's task, {rounds} round(s) of {seconds:g} s per hop at {RATE:g} Hz "
          f"(first {warmup:g} s discarded); {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}\n")
    print("| sample | hop | samples | p50 ms | p99 ms | p50 / rospy | p50 / one copy |")
    print("|---|---|---|---|---|---|---|")
    for (size, hop), values in rows.items():
        rospy = rows.get((size, "rospy Image → rospy")) or rows.get((size, "rospy callback"))
        copy = rows.get((size, "one bytearray copy"))
        ratio = (lambda base: f"{pct(values, 0.5) / pct(base, 0.5):.2f}×" if base else "—")
        print(f"| {size} | {hop} | {len(values)} | {pct(values, 0.5) / 1e3:.3f} | {pct(values, 0.99) / 1e3:.3f} | "
              f"{ratio(rospy)} | {ratio(copy)} |")
    ros2_codec = extra.get("ros2_codec")
    if ros2_codec:
        print("\nROS 2: one 1080p RGB sensor_msgs/msg/Image (6.2 MB) to and from its CDR bytes, median at 30 Hz\n")
        print("| step | ms | / one copy |")
        print("|---|---|---|")
        for label, ms in ros2_codec.items():
            print(f"| {label} | {ms:.3f} | {ms / ros2_codec['one bytearray copy']:.1f}× |")
    print("\n| goal (issue 35) | measured | met |")
    print("|---|---|---|")

    def p50(size: str, hop: str) -> float:
        return pct(rows.get((size, hop), []), 0.5)

    def goal(text: str, measured: str, met: bool | None) -> None:
        print(f"| {text} | {measured} | {'—' if met is None else ('yes' if met else 'no')} |")

    for size, limit in (("1 MiB", 0.5), ("6.2 MB", 0.25)):
        base = p50(size, "rospy Image → rospy")
        ours = p50(size, "scart, default")
        ratio = ours / base if base == base and base else float("nan")
        goal(f"{size} hop p50, default, one host ≤ {limit}× rospy", f"{ratio:.2f}×",
             None if ratio != ratio else ratio <= limit)
    copy = p50("6.2 MB", "one bytearray copy")
    ours = p50("6.2 MB", "scart, default")
    goal("6.2 MB hop p50, default ≤ 5× one copy", f"{ours / copy:.1f}×", ours / copy <= 5)
    fan = extra.get("fan")
    if fan:
        lost = [fan["written"] - r for r in fan["read"]]
        goal("6.2 MB at 60 Hz to 3 readers: writer ≥ 99 % on time, readers lose nothing under buffer",
             f"{100 * fan['on_time'] / fan['written']:.1f} % on time; lost {lost}",
             fan["on_time"] >= 0.99 * fan["written"] and not any(lost))
    uhd = extra.get("uhd")
    if uhd:
        links = uhd["links"]
        counted = all(lk["samples"] == uhd["written"] for lk in links)
        delivered = sum(uhd["read"])
        dropped = sum(lk["dropped"] for lk in links)
        goal("24.9 MB at 30 Hz: delivered, counted; no limit hit",
             f"{delivered} delivered + {dropped} dropped of {uhd['written']}",
             counted and delivered + dropped == uhd["written"] and delivered > 0)
    base = rows.get(("1 kHz int", "rospy callback"))
    ours_rows = rows.get(("1 kHz int", "scart task, SequentialActivity"))
    if ours_rows:
        measured = (f"p50 {pct(ours_rows, 0.5) / pct(base, 0.5):.2f}×, p99 {pct(ours_rows, 0.99) / pct(base, 0.99):.2f}×"
                    if base else "no rospy")
        goal("hop to an event task, 1 kHz, small sample: p50 and p99 ≤ rospy", measured,
             None if not base else pct(ours_rows, 0.5) <= pct(base, 0.5) and pct(ours_rows, 0.99) <= pct(base, 0.99))
    codec_times = extra["codec"]
    ratio = codec_times["scart"] / codec_times["pydantic"]
    goal("model codec ≤ 1.15× pydantic's own check and dump",
         f"{ratio:.2f}× ({codec_times['scart']:.1f} µs vs {codec_times['pydantic']:.1f} µs)", ratio <= 1.15)


if __name__ == "__main__":
    raise SystemExit(main())
