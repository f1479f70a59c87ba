"""``scart record | info | play``: the youBot driver recorded for 2 s to MCAP, the file
described, then replayed into a fresh driver-less deployer — nothing lost, in order, the
recorded pacing kept within the driver's period."""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

from mcap.reader import make_reader

from dataflow import Deployer, FlowStatus, InputPort, PeriodicActivity, TaskContext
from support import wait_until
from support.remote import subprocess_env
from youbot_model import YouBotStatus  # on sys.path through support.remote
from driver import YouBotDriver


class Receiver(TaskContext):
    """A driver-less stand-in: records each status written to it and when it arrived."""

    status = InputPort(YouBotStatus, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[tuple[float, int]] = []
        self._lock = threading.Lock()

    def update_hook(self) -> None:
        for _ in range(10_000):
            flow, value = self.status.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            with self._lock:
                self.got.append((time.monotonic(), value.sequence))

    def seen(self) -> list[tuple[float, int]]:
        with self._lock:
            return list(self.got)


def scart(ns: str, *args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    done = subprocess.run([sys.executable, "-m", "scart", *args, "--ns", ns], capture_output=True, text=True,
                          timeout=timeout, env=subprocess_env(ns))
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    return done


def test_record_describe_and_replay_into_a_driverless_deployer(tmp_path: Path) -> None:
    robot = Deployer()
    driver = robot.add(YouBotDriver("youBotDriver"))
    driver.set_activity(PeriodicActivity(0.01))
    robot.configure_all()
    robot.start_all()
    server = robot.serve("127.0.0.1:0")
    try:
        run = tmp_path / "run.mcap"
        out = json.loads(scart(server.address, "record", "youBotDriver.jointStatus", "-o", str(run), "--duration", "2",
                               "--json").stdout)
        assert 150 <= out["samples"] <= 230, out  # ~2 s at 100 Hz
    finally:
        server.stop()
        robot.stop_all()
        robot.cleanup_all()

    with open(run, "rb") as fh:  # a standard MCAP file: any reader gets schemas and JSON messages
        reader = make_reader(fh)
        recorded = [(m.log_time, json.loads(m.data)["sequence"]) for _s, _c, m in reader.iter_messages()]
    info = json.loads(subprocess.run([sys.executable, "-m", "scart", "info", str(run), "--json"], capture_output=True,
                                     text=True, timeout=60).stdout)
    assert info["channels"] == [{"topic": "youBotDriver.jointStatus", "type": "YouBotStatus", "count": len(recorded),
                                 "rate": info["channels"][0]["rate"], "declared": True}]
    assert 80 < info["channels"][0]["rate"] < 120 and info["messages"] == len(recorded)

    fresh = Deployer()
    receiver = fresh.add(Receiver("stand_in"))
    fresh.configure_all()
    fresh.start_all()
    server = fresh.serve("127.0.0.1:0")
    try:
        scart(server.address, "play", str(run), "--remap", "youBotDriver.jointStatus=stand_in.status")
        seen = wait_until(lambda: (s := receiver.seen()) and len(s) == len(recorded) and s, timeout=10,
                          message=f"replay lost samples: {len(receiver.seen())} of {len(recorded)}")
    finally:
        server.stop()
        fresh.stop_all()
        fresh.cleanup_all()
    assert [seq for _, seq in seen] == [seq for _, seq in recorded]  # nothing lost, in order
    # the recorded pace: each sample's offset from its recorded time, around their median
    # (a constant delay, such as the first sample's way in, is latency, not pace)
    t0, l0 = seen[0][0], recorded[0][0]
    offsets = [(t - t0) - (lt - l0) / 1e9 for (t, _), (lt, _) in zip(seen, recorded)]
    middle = statistics.median(offsets)
    drift = sorted(abs(offset - middle) for offset in offsets)
    # 95 % within 25 ms of the recorded pace (samples 10 ms apart: unpaced, they would be up
    # to 2 s off); a tighter bound measured this 2-core machine's load, not play
    assert abs(middle) < 0.05 and drift[int(0.95 * len(drift))] < 0.025, (middle, drift[-5:])


def run_scart(*args: str, ns: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=60,
                          env=subprocess_env(ns))


def test_record_refuses_an_existing_file_a_folder_and_a_missing_folder(tmp_path: Path) -> None:
    """Said in one line before anything is subscribed (no name service is even asked)."""
    existing = tmp_path / "old.mcap"
    existing.write_bytes(b"keep me")
    nowhere = "127.0.0.1:1"
    cases = {
        str(existing): "the file exists; give --overwrite to replace it",
        str(tmp_path) + "/": "a folder; scart record writes one .mcap file (not a folder as ros2 bag)",
        str(tmp_path): "a folder; scart record writes one .mcap file",
        str(tmp_path / "missing" / "parent" / "x.mcap"): f"the folder {tmp_path / 'missing' / 'parent'} does not exist",
    }
    for output, why in cases.items():
        done = run_scart("record", "a.b", "-o", output, "--ns", nowhere)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1 and why in lines[0] and "Traceback" not in done.stderr, done
    assert existing.read_bytes() == b"keep me"
    assert "a file, not a folder as ros2 bag's -o" in " ".join(run_scart("record", "--help").stdout.split())


def test_play_plays_the_topics_asked_for_into_remapped_ports(tmp_path: Path) -> None:
    """``--topics`` leaves the other channels out (no remap needed for them); ``--remap``
    takes ROS's ``:=`` and ``/comp/port`` names."""
    from mcap.writer import Writer

    path = tmp_path / "two.mcap"
    with open(path, "wb") as fh:
        writer = Writer(fh)
        writer.start()
        schema = writer.register_schema("YouBotStatus", "jsonschema", b"{}")
        wanted = writer.register_channel("youBotDriver.jointStatus", "json", schema)
        other = writer.register_channel("nobody.else", "json", schema)
        for i in range(5):  # 0.1 s apart: the sink's default writer keeps the last value (DATA)
            status = {"joints": [], "timestamp": float(i), "sequence": i}
            writer.add_message(wanted, i * 100_000_000, json.dumps(status).encode(), i * 100_000_000)
            writer.add_message(other, i * 100_000_000 + 1, b'{"value": 1}', i * 100_000_000 + 1)
        writer.finish()
    fresh = Deployer()
    receiver = fresh.add(Receiver("stand_in"))
    fresh.configure_all()
    fresh.start_all()
    server = fresh.serve("127.0.0.1:0")
    try:
        done = run_scart("play", str(path), "--topics", "/youBotDriver/jointStatus", "--remap",
                         "/youBotDriver/jointStatus:=stand_in/status", "--ns", server.address)
        assert done.returncode == 0, done.stderr
        assert done.stdout.strip() == f"played 5 sample(s) from {path} (5 left out by --topics)"
        wait_until(lambda: [seq for _, seq in receiver.seen()] == [0, 1, 2, 3, 4], timeout=10)
    finally:
        server.stop()
        fresh.stop_all()
        fresh.cleanup_all()
