"""Benchmark of scart's frame tree against ROS's tf2 (tf2_ros' Python ``Buffer``, C++ inside), one run.

Usage: ``python benchmarks/bench_tf.py [--quick | --smoke]`` (tf2_ros for ``/usr/bin/python3``:
Debian's ``python3-tf2-ros``; without it the tf2 rows say so and the rest is measured).
Not a test; CI runs its ``--smoke`` only.

**Lookups.** A 6-frame chain ``f0 ← f1 ← … ← f6``, every joint moving, published at 100 Hz
for 10 s (the history tf2 keeps); lookups of ``f6`` in ``f0`` at times drawn between the
stamps (so every frame interpolates: a lerp and a slerp each, then the composition). The
same chain, stamps and times in both processes (one seed); short rounds alternate scart
and tf2_ros (so a busy machine slows both alike), and each row gives the median over the
rounds of the time per lookup:

* ``tf2_ros``: ``tf2_ros.Buffer.lookup_transform`` in the system Python (the baseline);
* ``scart``: ``FrameBuffer.lookup`` (plain floats);
* ``scart, own stamps``: the same chain, but each frame published on its own, 1 ms after
  the one below it (so a lookup cannot take the stamp the frame below found: a bisection
  per frame, as a chain of separate publishers costs);
* ``scart, time 0``: the newest common time, as most lookups are;
* ``numpy``: the same walk composed with numpy 4x4 matrices (interpolation done the same
  way): why the buffer uses plain floats.

A few lookups are also compared: the largest difference from tf2_ros is printed.

**What a server keeps.** 100 frames at 100 Hz for 10 s (simulated stamps, as fast as they
go in) into one tree: transforms kept, memory (tracemalloc for scart; the resident set's
growth for tf2_ros, C++), bytes per transform, and the time to insert one.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import statistics
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from dataflow.tf import FrameBuffer, Transform  # noqa: E402

SYSTEM_PYTHON = "/usr/bin/python3"
FIRST_NS = 1000 * 1_000_000_000
STEP_NS = 10_000_000  # 100 Hz
CHAIN = 6
SEED = 22

# What both sides build: joint k of the chain at stamp i (a translation and a turn about a tilted axis).
SHARED = r'''
import math, random
FIRST_NS, STEP_NS, CHAIN, SEED = {first}, {step}, {chain}, {seed}

def joint(k, i):
    a = 0.3 * math.sin(0.011 * i * (k + 1)) + 0.1 * k
    axis = (0.3 * k % 1.0, 0.5, 0.8)
    n = math.sqrt(sum(c * c for c in axis))
    s = math.sin(a / 2)
    return ((0.1 * k, 0.02 * math.cos(0.003 * i), 0.05), (axis[0] / n * s, axis[1] / n * s, axis[2] / n * s, math.cos(a / 2)))

def times(stamps, n):
    rng = random.Random(SEED)
    span = (stamps - 1) * STEP_NS
    return [FIRST_NS + 1 + int(rng.random() * (span - 2)) for _ in range(n)]
'''.format(first=FIRST_NS, step=STEP_NS, chain=CHAIN, seed=SEED)

# tf2_ros in the system Python: commands on stdin, one JSON answer per line.
TF2_PEER = SHARED + r'''
import json, os, sys, time
import rospy, tf2_ros
from geometry_msgs.msg import TransformStamped

def stamped(parent, child, t, q, ns):
    m = TransformStamped()
    m.header.stamp = rospy.Time(ns // 1000000000, ns % 1000000000)
    m.header.frame_id, m.child_frame_id = parent, child
    m.transform.translation.x, m.transform.translation.y, m.transform.translation.z = t
    m.transform.rotation.x, m.transform.rotation.y, m.transform.rotation.z, m.transform.rotation.w = q
    return m

def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")

buffer = None
for line in sys.stdin:
    cmd = json.loads(line)
    if cmd["do"] == "chain":
        buffer = tf2_ros.Buffer(cache_time=rospy.Duration(10.0), debug=False)
        for i in range(cmd["stamps"]):
            for k in range(1, CHAIN + 1):
                t, q = joint(k, i)
                buffer.set_transform(stamped("f%d" % (k - 1), "f%d" % k, t, q, FIRST_NS + i * STEP_NS), "bench")
        asked = [rospy.Time(ns // 1000000000, ns % 1000000000) for ns in times(cmd["stamps"], cmd["n"])]
        print(json.dumps({"ok": True}), flush=True)
    elif cmd["do"] == "round":
        look = buffer.lookup_transform
        t0 = time.perf_counter()
        for when in asked:
            look("f0", "f%d" % CHAIN, when)
        print(json.dumps({"us": (time.perf_counter() - t0) / len(asked) * 1e6}), flush=True)
    elif cmd["do"] == "check":
        out = []
        for when in asked[:cmd["n"]]:
            r = buffer.lookup_transform("f0", "f%d" % CHAIN, when)
            tr, q = r.transform.translation, r.transform.rotation
            out.append([tr.x, tr.y, tr.z, q.x, q.y, q.z, q.w])
        print(json.dumps({"values": out}), flush=True)
    elif cmd["do"] == "memory":
        big = tf2_ros.Buffer(cache_time=rospy.Duration(10.0), debug=False)
        before, count = rss(), 0
        t0 = time.perf_counter()
        for i in range(cmd["stamps"]):
            for k in range(cmd["frames"]):
                t, q = joint(k % CHAIN, i)
                big.set_transform(stamped("root" if k < 10 else "g%d" % (k - 10), "g%d" % k, t, q,
                                          FIRST_NS + i * STEP_NS), "bench")
                count += 1
        spent = time.perf_counter() - t0
        print(json.dumps({"bytes": rss() - before, "insert_us": spent / count * 1e6}), flush=True)
        del big
'''

_SHARED: dict = {}
exec(SHARED, _SHARED)  # the same definitions on both sides
joint, times = _SHARED["joint"], _SHARED["times"]


def build_chain(stamps: int, skew_ns: int = 0) -> FrameBuffer:
    """The chain, each stamp's transforms in one message (``skew_ns``: frame k published
    on its own, k times that later)."""
    buffer = FrameBuffer(10.0)
    for i in range(stamps):
        batch = [Transform(f"f{k - 1}", f"f{k}", *joint(k, i), FIRST_NS + i * STEP_NS + k * skew_ns)
                 for k in range(1, CHAIN + 1)]
        for message in ([batch] if not skew_ns else [[t] for t in batch]):
            buffer.publish(message)
    return buffer


def time_scart(buffer: FrameBuffer, asked: list[float]) -> float:
    look, source = buffer.lookup, f"f{CHAIN}"
    t0 = time.perf_counter()
    for when in asked:
        look("f0", source, when)
    return (time.perf_counter() - t0) / len(asked) * 1e6


def time_scart_latest(buffer: FrameBuffer, n: int) -> float:
    look, source = buffer.lookup, f"f{CHAIN}"
    t0 = time.perf_counter()
    for _ in range(n):
        look("f0", source, 0.0)
    return (time.perf_counter() - t0) / n * 1e6


def time_numpy(buffer: FrameBuffer, asked_ns: list[int]) -> float:
    """The same walk, each frame's interpolated transform as a numpy 4x4 matrix, multiplied."""
    import numpy as np

    frames = [buffer._frames[f"f{k}"] for k in range(CHAIN, 0, -1)]

    def matrix(values: tuple[float, ...]) -> np.ndarray:
        x, y, z, qx, qy, qz, qw = values
        m = np.eye(4)
        m[:3, :3] = ((1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)),
                     (2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)),
                     (2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)))
        m[:3, 3] = (x, y, z)
        return m

    t0 = time.perf_counter()
    for when in asked_ns:
        acc = np.eye(4)
        for frame in frames:
            values = frame.at(when, 0)
            assert values is not None
            acc = matrix(values) @ acc
    return (time.perf_counter() - t0) / len(asked_ns) * 1e6


def fill(frames: int, stamps: int) -> tuple[FrameBuffer, int, float]:
    """A tree of ``frames`` frames (chains of ten under ``root``) given ``stamps`` stamps at
    100 Hz: the tree, the transforms stored, the seconds it took."""
    buffer = FrameBuffer(10.0)
    count = 0
    t0 = time.perf_counter()
    for i in range(stamps):
        batch = []
        for k in range(frames):
            parent = "root" if k < 10 else f"g{k - 10}"
            batch.append(Transform(parent, f"g{k}", *joint(k % CHAIN, i), FIRST_NS + i * STEP_NS))
        count += buffer.publish(batch)
    return buffer, count, time.perf_counter() - t0


def memory_scart(frames: int, stamps: int) -> tuple[int, int, float]:
    """(transforms kept, bytes, µs per insert): timed without tracemalloc, then measured with it."""
    _, count, spent = fill(frames, stamps)
    tracemalloc.start()
    before = tracemalloc.get_traced_memory()[0]
    buffer, _, _ = fill(frames, stamps)
    size = tracemalloc.get_traced_memory()[0] - before
    tracemalloc.stop()
    kept = sum(f.kept for f in buffer.frames())
    return kept, size, spent / count * 1e6


class Tf2:
    """tf2_ros in a system-Python subprocess (None when it cannot be had)."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[str] | None = None
        self.why = ""
        if not os.path.exists(SYSTEM_PYTHON):
            self.why = f"no {SYSTEM_PYTHON}"
            return
        probe = subprocess.run([SYSTEM_PYTHON, "-c", "import tf2_ros, rospy"], capture_output=True, timeout=60)
        if probe.returncode != 0:
            self.why = "tf2_ros is not installed for the system Python (apt-get install python3-tf2-ros)"
            return
        self.proc = subprocess.Popen([SYSTEM_PYTHON, "-c", TF2_PEER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, bufsize=1)

    def ask(self, **cmd: object) -> dict:
        assert self.proc is not None and self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps(cmd) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("tf2_ros' process ended")
        return json.loads(line)

    def close(self) -> None:
        if self.proc is not None:
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            self.proc.wait(timeout=30)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer lookups and rounds")
    parser.add_argument("--smoke", action="store_true", help="a few seconds: every path once")
    args = parser.parse_args()
    stamps, n, rounds, mem_frames, mem_stamps = 1001, 20_000, 21, 100, 1001
    if args.quick:
        stamps, n, rounds = 1001, 5_000, 7
    if args.smoke:
        stamps, n, rounds, mem_frames, mem_stamps = 60, 1000, 1, 20, 60

    tf2 = Tf2()
    try:
        buffer, skewed = build_chain(stamps), build_chain(stamps, 1_000_000)
        asked_ns = times(stamps, n)
        asked = [t / 1e9 for t in asked_ns]
        span, first = (stamps - 1) * STEP_NS, FIRST_NS + CHAIN * 1_000_000
        later = [(first + (t - FIRST_NS) * (span - (CHAIN - 1) * 1_000_000) // span) / 1e9
                 for t in asked_ns]  # within every skewed frame's span
        rows: dict[str, list[float]] = {"tf2_ros": [], "scart": [], "scart, own stamps": [], "scart, time 0": [],
                                        "numpy": []}
        if tf2.proc is not None:
            tf2.ask(do="chain", stamps=stamps, n=n)
        for _ in range(rounds):
            if tf2.proc is not None:
                rows["tf2_ros"].append(tf2.ask(do="round")["us"])
            rows["scart"].append(time_scart(buffer, asked))
            rows["scart, own stamps"].append(time_scart(skewed, later))
            rows["scart, time 0"].append(time_scart_latest(buffer, n))
        rows["numpy"].append(time_numpy(buffer, asked_ns[: max(200, n // 20)]))
        agree = ""
        if tf2.proc is not None:
            theirs = tf2.ask(do="check", n=min(200, n))["values"]
            ours = [(*t.translation, *t.rotation) for t in (buffer.lookup("f0", f"f{CHAIN}", time_ns=w)
                                                            for w in asked_ns[: len(theirs)])]
            agree = f"{max(abs(a - b) for o, t in zip(ours, theirs) for a, b in zip(o, t)):.1e}"
        base = statistics.median(rows["tf2_ros"]) if rows["tf2_ros"] else float("nan")
        print(f"## Lookups: f6 in f0, a 6-frame chain of moving joints at 100 Hz, {stamps} stamps each, "
              f"{n} lookups between stamps, {rounds} round(s)\n")
        print("| lookup | µs per lookup: median (best) of rounds | × tf2_ros (median) |")
        print("|---|---:|---:|")
        for name, values in rows.items():
            if not values:
                print(f"| {name} | — ({tf2.why}) | — |")
                continue
            med = statistics.median(values)
            ratio = f"{med / base:.2f}" if math.isfinite(base) else "—"
            print(f"| {name} | {med:.2f} ({min(values):.2f}) | {ratio} |")
        if agree:
            print(f"\nLargest difference from tf2_ros over {min(200, n)} lookups: {agree}")

        kept, size, insert_us = memory_scart(mem_frames, mem_stamps)
        print(f"\n## What a tree keeps: {mem_frames} frames at 100 Hz for {(mem_stamps - 1) / 100:g} s, "
              "10 s of history\n")
        print("| tree | transforms kept | memory | bytes per transform | µs per insert |")
        print("|---|---:|---:|---:|---:|")
        print(f"| scart | {kept} | {size / 1e6:.1f} MB | {size / kept:.0f} | {insert_us:.2f} |")
        if tf2.proc is not None:
            theirs_mem = tf2.ask(do="memory", frames=mem_frames, stamps=mem_stamps)
            print(f"| tf2_ros (resident growth) | {kept} | {theirs_mem['bytes'] / 1e6:.1f} MB | "
                  f"{theirs_mem['bytes'] / kept:.0f} | {theirs_mem['insert_us']:.2f} |")
        else:
            print(f"| tf2_ros | — ({tf2.why}) | | | |")
    finally:
        tf2.close()


if __name__ == "__main__":
    main()
