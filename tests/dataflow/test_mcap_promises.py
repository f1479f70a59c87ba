"""MCAP files someone handed you (issue: "every promise kept", section 2): ``scart info``
lists every message it counts, and reading a file is bounded per file — messages,
decompressed bytes, time — so a few kilobytes cannot take seconds and hundreds of
megabytes; each ends in one line."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.writer import CompressionType, Writer

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
