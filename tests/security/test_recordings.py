"""MCAP files someone hands you, and recordings that crash (issue 23, sections 6 and 8).

``scart play`` and ``scart info`` read a file with bounds: a chunk declaring a huge size is
refused before anything is decompressed (the process stays small), a chunk holding more
than it declares too; a pause of 31 years is shortened to ``--max-gap``; deep JSON is
skipped; a truncated, foreign or non-regular file gets one line and exit 1, never a
traceback. ``scart record`` killed with -9 loses at most the last second (chunks reach
the disk on a time bound), ``info`` reads what it left, ``record --recover`` finishes it;
a full disk (a small tmpfs, or a file-size limit) stops the recording with one line and
leaves a finished file."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.data_stream import RecordBuilder
from mcap.reader import make_reader
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from dataflow import Deployer, FlowStatus, InputPort, PeriodicActivity, TaskContext
from dataflow.remote.naming import serve_nameserver
from support import wait_until
from support.remote import subprocess_env
from driver import YouBotDriver

MAGIC = b"\x89MCAP0\r\n"


def scart(*args: str, ns: str | None = None, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=timeout,
                          env=subprocess_env(ns))


def one_line(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def write_mcap(path: Path, messages: list[tuple[str, int, bytes]], chunk_size: int = 1 << 20) -> None:
    """A well-formed MCAP file of JSON messages ``(topic, log_time ns, data)``."""
    with open(path, "wb") as fh:
        writer = Writer(fh, chunk_size=chunk_size)
        writer.start()
        channels: dict[str, int] = {}
        for topic, log_time, data in messages:
            if topic not in channels:
                schema = writer.register_schema("float64", "jsonschema", b"{}")
                channels[topic] = writer.register_channel(topic, "json", schema)
            writer.add_message(channels[topic], log_time, data, log_time)
        writer.finish()


def bomb(path: Path, actual: int, declared: int) -> None:
    """A small zstd MCAP file whose one chunk holds a message of ``actual`` zero bytes and
    declares ``declared`` bytes uncompressed (the size is the file's word, not the truth)."""
    import zstandard

    inner = RecordBuilder()
    Channel(id=1, topic="sink.value", message_encoding="json", schema_id=1, metadata={}).write(inner)
    head = inner.end() + bytes([0x05]) + (actual + 22).to_bytes(8, "little") + (1).to_bytes(2, "little") \
        + bytes(4 + 8 + 8)
    compressor = zstandard.ZstdCompressor(level=1).compressobj()
    parts = [compressor.compress(head)]
    zeros = bytes(1 << 20)
    for _ in range(actual >> 20):
        parts.append(compressor.compress(zeros))
    parts.append(compressor.flush())
    outer = RecordBuilder()
    Header(profile="", library="probe").write(outer)
    Schema(id=1, name="float64", encoding="jsonschema", data=b"{}").write(outer)
    Chunk(message_start_time=0, message_end_time=0, uncompressed_size=declared, uncompressed_crc=0,
          compression="zstd", data=b"".join(parts)).write(outer)
    DataEnd(data_section_crc=0).write(outer)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(outer)
    path.write_bytes(MAGIC + outer.end() + MAGIC)


@pytest.fixture(scope="module")
def name_service() -> Iterator[str]:
    server = serve_nameserver("127.0.0.1:0")
    try:
        yield server.address
    finally:
        server.stop()


#: Runs ``argv[1:]`` and prints its peak resident memory (kB). A child started straight from
#: pytest would not do: Linux carries the high-water mark of the mm a process execs from into
#: its ``ru_maxrss``, so it would report pytest's own size; this small process stands between.
_MEASURE = ("import resource, subprocess, sys\n"
            "code = subprocess.call(sys.argv[1:])\n"
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n"
            "sys.exit(code)\n")


def peak_rss_mb(args: list[str], ns: str, timeout: float = 60) -> tuple[int, str, float]:
    """Run ``scart ARGS``: its exit code, stderr and peak resident memory (MB)."""
    proc = subprocess.run([sys.executable, "-c", _MEASURE, sys.executable, "-m", "scart", *args],
                          capture_output=True, text=True, timeout=timeout, env=subprocess_env(ns))
    return proc.returncode, proc.stderr, int(proc.stdout.split()[-1]) / 1024


@pytest.mark.parametrize("actual, declared", [(600 << 20, 600 << 20), (200 << 20, 1 << 20)],
                         ids=["declares 600 MB", "holds more than it declares"])
def test_a_chunk_is_bounded_before_it_is_decompressed(tmp_path: Path, name_service: str, actual: int,
                                                      declared: int) -> None:
    path = tmp_path / "bomb.mcap"
    bomb(path, actual, declared)
    assert path.stat().st_size < 1 << 20  # a small file
    code, err, rss = peak_rss_mb(["play", str(path), "--ns", name_service], name_service)
    assert code == 1 and str(path) in one_line(err) and "chunk at byte" in err, err
    assert rss < 300, f"play reached {rss:.0f} MB"
    info = scart("info", str(path))
    assert info.returncode == 1 and "chunk at byte" in one_line(info.stderr) and str(path) in info.stderr


class Sink(TaskContext):
    value = InputPort(float, event=True)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[float] = []

    def update_hook(self) -> None:
        for _ in range(1000):
            flow, value = self.value.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            self.got.append(value)


@pytest.fixture
def sink() -> Iterator[tuple[str, Sink]]:
    deployer = Deployer()
    task = deployer.add(Sink("sink"))
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0")
    try:
        yield server.address, task
    finally:
        server.stop()
        deployer.stop_all()
        deployer.cleanup_all()


def test_a_31_year_pause_is_shortened_to_the_max_gap_and_said(tmp_path: Path, sink: tuple[str, Sink]) -> None:
    ns, task = sink
    path = tmp_path / "gap.mcap"
    write_mcap(path, [("sink.value", 0, b'{"value": 1.0}'), ("sink.value", 10**18, b'{"value": 2.0}')])
    began = time.monotonic()
    done = scart("play", str(path), "--ns", ns, timeout=30)
    assert done.returncode == 0, done.stderr
    assert time.monotonic() - began < 20
    assert "shortened to 3 s (--max-gap)" in one_line(done.stderr)
    wait_until(lambda: task.got == [1.0, 2.0], timeout=10)
    fast = scart("play", str(path), "--ns", ns, "--max-gap", "0", timeout=30)
    assert fast.returncode == 0 and "shortened to 0 s" in fast.stderr


def test_deep_json_is_skipped_in_one_line(tmp_path: Path, sink: tuple[str, Sink]) -> None:
    ns, task = sink
    path = tmp_path / "deep.mcap"
    deep = b'{"value": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    nested = b'{"value": ' + b"[" * 100 + b"]" * 100 + b"}"  # parses, but deeper than scart reads
    write_mcap(path, [("sink.value", 0, deep), ("sink.value", 1, nested), ("sink.value", 2, b'{"value": 3.0}')])
    done = scart("play", str(path), "--ns", ns)
    assert done.returncode == 1 and "2 message(s) unreadable" in one_line(done.stderr) and str(path) in done.stderr
    assert done.stdout.strip() == f"played 1 sample(s) from {path} (2 unreadable, skipped)"
    wait_until(lambda: task.got == [3.0], timeout=10)


def test_truncated_foreign_and_special_files_get_one_line(tmp_path: Path, name_service: str) -> None:
    path = tmp_path / "cut.mcap"
    write_mcap(path, [("sink.value", i * 10**7, b'{"value": %d.0}' % i) for i in range(400)], chunk_size=512)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 6 // 10])
    info = scart("info", str(path), "--json")
    assert info.returncode == 0 and "truncated at byte" in one_line(info.stderr)
    doc = json.loads(info.stdout)
    assert doc["truncated"] and 50 < doc["messages"] < 400 and doc["channels"][0]["count"] == doc["messages"]
    play = scart("play", str(path), "--ns", name_service, "--topics", "nobody.here")
    assert play.returncode == 1 and "truncated at byte" in play.stderr and "Traceback" not in play.stderr
    foreign = tmp_path / "foreign.mcap"
    foreign.write_bytes(os.urandom(4096))
    for verb in (["info", str(foreign)], ["play", str(foreign), "--ns", name_service]):
        out = scart(*verb)
        assert out.returncode == 1 and f"{foreign}: not an MCAP file" in one_line(out.stderr)
    fifo = tmp_path / "fifo.mcap"
    os.mkfifo(fifo)
    out = scart("info", str(fifo), timeout=20)
    assert out.returncode == 1 and f"{fifo}: not a regular file" in one_line(out.stderr)


# ---- recordings that crash ----------------------------------------------------------------

@pytest.fixture
def robot() -> Iterator[str]:
    """A youBot driver at 200 Hz, served with an embedded name service."""
    deployer = Deployer()
    driver = deployer.add(YouBotDriver("youBotDriver"))
    driver.set_activity(PeriodicActivity(0.005))
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0")
    try:
        yield server.address
    finally:
        server.stop()
        deployer.stop_all()
        deployer.cleanup_all()


def readable_messages(path: Path) -> list[int]:
    """The log times mcap's own stream reader gets from ``path`` before it ends or breaks."""
    times: list[int] = []
    with open(path, "rb") as fh, contextlib.suppress(Exception):
        for record in StreamReader(fh).records:
            if isinstance(record, Message):
                times.append(record.log_time)
    return times


def test_kill_9_loses_at_most_the_last_second_and_the_file_is_recovered(tmp_path: Path, robot: str) -> None:
    path = tmp_path / "run.mcap"
    proc = subprocess.Popen([sys.executable, "-m", "scart", "record", "youBotDriver.jointStatus", "-o", str(path),
                             "--duration", "60", "--ns", robot], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=subprocess_env(robot))
    try:
        wait_until(lambda: path.exists() and len(readable_messages(path)) > 300, timeout=30, interval=0.1,
                   message="nothing reached the disk")  # samples of a second and a half or more, on disk
        killed_at = time.time_ns()
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    times = readable_messages(path)
    assert times and killed_at - max(times) < 1.0e9, (len(times), (killed_at - max(times)) / 1e9)
    info = scart("info", str(path), "--json")
    assert info.returncode == 0 and "truncated" in one_line(info.stderr)
    count = json.loads(info.stdout)["messages"]
    assert count == len(times)
    fixed = tmp_path / "fixed.mcap"
    done = scart("record", "--recover", str(path), "-o", str(fixed))
    assert done.returncode == 0 and f"recovered {count} message(s)" in done.stdout, done.stderr
    with open(fixed, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics.message_count == count  # complete: summary and index
    again = scart("record", "--recover", str(path), "-o", str(fixed))
    assert again.returncode == 1 and "the file exists; give --overwrite" in one_line(again.stderr)


@contextlib.contextmanager
def small_tmpfs(tmp_path: Path, size: str) -> Iterator[Path]:
    """A tmpfs of ``size`` mounted for the test (root only; skipped where mounting is not allowed)."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    where = tmp_path / "small"
    where.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                             capture_output=True, text=True, timeout=30)
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {mounted.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", str(where)], capture_output=True, timeout=30)


#: Runs the rest of its arguments under a kernel limit on the size of the files written (a
#: fresh interpreter sets it, then execs: a preexec_fn would fork this process, whose gRPC
#: threads can abort the child before it execs).
FSIZE_LIMITED = ("import os, resource, sys; lim = int(sys.argv[1]); "
                 "resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim)); "
                 "os.execv(sys.executable, [sys.executable, *sys.argv[2:]])")


def record_until_full(path: Path, ns: str, file_limit: int | None = None) -> tuple[int, str, float]:
    began = time.monotonic()
    limited = ["-c", FSIZE_LIMITED, str(file_limit)] if file_limit is not None else []
    done = subprocess.run([sys.executable, *limited, "-m", "scart", "record", "youBotDriver.jointStatus",
                           "-o", str(path), "--duration", "60", "--ns", ns], capture_output=True, text=True,
                          timeout=45, env=subprocess_env(ns))
    return done.returncode, done.stderr, time.monotonic() - began


def assert_finished_as_far_as_it_got(path: Path, stderr: str, what: str) -> None:
    line = one_line("\n".join(line for line in stderr.splitlines() if "Ctrl-C to stop" not in line))
    assert what in line and "recording stopped; kept" in line, line
    kept = int(line.split("kept ", 1)[1].split(" ", 1)[0])
    assert kept > 0
    info = scart("info", str(path), "--json")
    assert info.returncode == 0 and info.stderr == "", info.stderr  # finished: not even truncated
    assert json.loads(info.stdout)["messages"] == kept
    with open(path, "rb") as fh:
        assert sum(1 for _ in make_reader(fh).iter_messages()) == kept


def test_a_full_disk_stops_the_recording_and_finishes_the_file(tmp_path: Path, robot: str) -> None:
    with small_tmpfs(tmp_path, "1m") as disk:
        filler = disk / "filler"
        with open(filler, "wb") as fh:
            with contextlib.suppress(OSError):
                fh.write(bytes((1 << 20) - (96 << 10)))
        code, err, took = record_until_full(disk / "run.mcap", robot)
        assert code == 1 and took < 40, (code, took, err)
        assert_finished_as_far_as_it_got(disk / "run.mcap", err, "the disk is full")


def test_a_file_size_limit_stops_the_recording_and_finishes_the_file(tmp_path: Path, robot: str) -> None:
    code, err, took = record_until_full(tmp_path / "run.mcap", robot, file_limit=64 << 10)  # a real kernel limit
    assert code == 1 and took < 40, (code, took, err)
    assert_finished_as_far_as_it_got(tmp_path / "run.mcap", err, "the file-size limit is reached")
