"""MCAP files someone handed you (issue: "every promise kept", section 2): ``scart info``
lists every message it counts, and reading a file is bounded per file — messages,
decompressed bytes, time — so a few kilobytes cannot take seconds and hundreds of
megabytes; each ends in one line."""

from __future__ import annotations

import io
import json
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zstandard
from mcap.writer import CompressionType, Writer

from dataflow import Deployer
from dataflow.recording.mcap import MAGIC, MIN_MESSAGES, Budget, McapError, McapScan
from support import ROOT

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


def scart(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "scart", *args], capture_output=True, text=True, timeout=120, cwd=ROOT)


def test_info_lists_the_messages_of_a_channel_the_file_never_declares(tmp_path: Path) -> None:
    out = io.BytesIO()
    writer = Writer(out)
    writer.start()
    schema = writer.register_schema("T", "jsonschema", b"{}")
    channel = writer.register_channel("a.out", "json", schema)
    writer.add_message(channel, 1, b'{"value": 1}', 1)
    for i in range(2):
        writer.add_message(77, 2 + i, b'{"value": 2}', 2 + i)  # channel 77: never declared
    writer.finish()
    path = tmp_path / "undeclared.mcap"
    path.write_bytes(out.getvalue())
    done = scart("info", str(path), "--json")
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["messages"] == sum(c["count"] for c in doc["channels"]) == 3  # the rows add up to the total
    assert {"topic": "(channel 77, undeclared)", "count": 2, "declared": False}.items() <= doc["channels"][1].items()
    assert "2 message(s) of channels the file never declares" in done.stderr


def _record(opcode: int, body: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(body)) + body


def _string(text: str) -> bytes:
    return struct.pack("<I", len(text)) + text.encode()


def amplified(path: Path, messages: int, chunks: int = 1, distinct: bool = False) -> Path:
    """An MCAP file of ``chunks`` zstd chunks, each of ``messages`` empty messages on one
    declared channel: identical ones compress ~10 000:1 (the issue's 5.9 KB of 2.1 M
    messages); ``distinct`` ones (their sequence and times differ) far less."""
    header = _record(0x01, _string("") + _string("bomb"))
    schema = _record(0x03, struct.pack("<H", 1) + _string("T") + _string("jsonschema") + struct.pack("<I", 2) + b"{}")
    channel = _record(0x04, struct.pack("<HH", 1, 1) + _string("a.out") + _string("json") + struct.pack("<I", 0))
    body = []
    for k in range(chunks):
        if distinct:
            data = b"".join(_record(0x05, struct.pack("<HIQQ", 1, i, 10 * i, 10 * i)) for i in range(messages))
        else:
            data = _record(0x05, struct.pack("<HIQQ", 1, 0, 7, 7)) * messages
        packed = zstandard.ZstdCompressor(level=3).compress(data)
        body.append(_record(0x06, struct.pack("<QQQI", 0, 10 * messages, len(data), 0) + _string("zstd")
                            + struct.pack("<Q", len(packed)) + packed))
    footer = _record(0x02, struct.pack("<QQI", 0, 0, 0))
    path.write_bytes(MAGIC + header + schema + channel + b"".join(body) + footer + MAGIC)
    return path


#: ``scart ARGS`` in this interpreter, then its own peak memory on a last stderr line (the
#: kernel's ``VmHWM`` of the program's memory: ``ru_maxrss`` would count the forking
#: pytest process's too).
PEAK = """
import sys
from scart.cli import main
try:
    code = main(sys.argv[1:])
finally:
    peak = next(line for line in open("/proc/self/status") if line.startswith("VmHWM:"))
    print(peak.strip(), file=sys.stderr)
sys.exit(code)
"""


def run_measured(*args: str, timeout: float = 60.0) -> tuple[int, str, float, float]:
    """``scart ARGS``: its exit code, stderr (without the peak line), seconds taken and
    peak memory (MiB), killed past ``timeout``."""
    began = time.monotonic()
    done = subprocess.run([sys.executable, "-c", PEAK, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)
    took = time.monotonic() - began
    err, _, peak = done.stderr.rstrip("\n").rpartition("\n")
    assert peak.startswith("VmHWM:"), done.stderr
    return done.returncode, err + "\n", took, int(peak.split()[1]) / 1024


def test_a_few_kilobytes_of_millions_of_messages_stop_at_once_with_one_line(tmp_path: Path) -> None:
    bomb = amplified(tmp_path / "bomb.mcap", 2_100_000)
    assert bomb.stat().st_size < 10_000
    code, err, took, peak_mib = run_measured("info", str(bomb))
    assert code == 1 and err.count("\n") == 1 and "more than 1000000 messages" in err, err
    assert took < 10 and peak_mib < 200, (took, peak_mib)  # it took 16 s and 407 MB
    server = Deployer().serve("127.0.0.1:0")  # play reads after it reached a name service
    try:
        code, err, took, _ = run_measured("play", str(bomb), "--ns", server.address)
    finally:
        server.stop()
    assert code == 1 and "more than 1000000 messages" in err and took < 10, err


def test_the_work_of_one_file_is_bounded_in_messages_bytes_and_time(tmp_path: Path) -> None:
    spread = amplified(tmp_path / "spread.mcap", 3000, chunks=3, distinct=True)
    whole = McapScan(str(spread))
    assert sum(1 for r in whole.records() if type(r).__name__ == "Message") == 9000
    assert whole.count == 9000 and whole.expanded > 0 and whole.spent > 0
    for budget, said in ((Budget(messages=5000), "more than 5000 messages"),
                         (Budget(expansion=2 * 3000 * 31), "declare 279000 bytes in all"),
                         (Budget(seconds=0.0), "still reading after 0 s")):
        with pytest.raises(McapError, match=said):
            for _ in McapScan(str(spread), budget=budget).records():
                pass
    small = Budget.of(1000)
    assert small.messages == MIN_MESSAGES and small.expansion >= 64 << 20
    assert Budget.of(10 << 30).messages == 10 << 30 and Budget.of(10 << 30).expansion == 1000 * (10 << 30)


def test_a_chunk_as_large_as_one_sample_is_read_however_well_it_compresses(tmp_path: Path) -> None:
    """A black camera frame compresses thousands to one: a recording of one is read."""
    path = tmp_path / "black.mcap"
    with open(path, "wb") as fh:
        writer = Writer(fh, compression=CompressionType.ZSTD)
        writer.start()
        schema = writer.register_schema("Frame", "jsonschema", b"{}")
        channel = writer.register_channel("cam.frame", "json", schema)
        writer.add_message(channel, log_time=1, data=b'{"data": "' + b"A" * 2_000_000 + b'"}', publish_time=1)
        writer.finish()
    assert path.stat().st_size < 2000  # 1000:1 and more
    assert sum(1 for r in McapScan(str(path)).records() if type(r).__name__ == "Message") == 1
