"""Benchmarks are code too: every ``benchmarks/bench_*.py`` takes ``--quick`` and
``--smoke``, and runs its ``--smoke`` here (a few seconds: every path once), so a broken
benchmark fails the tests. The numbers are never judged. A benchmark that needs what this
machine lacks (rosmaster, Cyclone DDS, Zenoh, the ``bench`` extra's psutil) is skipped,
saying which."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from support import ROOT

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]

BENCHES = sorted((ROOT / "benchmarks").glob("bench_*.py"))
#: What a benchmark needs beyond the test extra: (is it there?, what to install).
NEEDS = {
    "bench_ros1.py": (lambda: shutil.which("rosmaster") is not None, "rosmaster (Debian: apt-get install ros-core)"),
    "bench_ros2.py": (lambda: _installed("cyclonedds"), "cyclonedds (pip install 'scart[ros2]')"),
    "bench_zenoh.py": (lambda: _installed("zenoh"), "eclipse-zenoh (pip install 'scart[zenoh]')"),
    "bench_youbot.py": (lambda: _installed("psutil"), "psutil (pip install 'scart[bench]')"),
    "bench_yarp.py": (lambda: shutil.which("yarpserver") is not None and shutil.which("yarp") is not None,
                      "YARP's yarpserver and yarp on PATH (the steering repository's shared/yarp/build.sh)"),
}


def _installed(module: str) -> bool:
    return importlib.util.find_spec(module) is not None


def test_there_are_benchmarks_and_every_one_takes_quick_and_smoke() -> None:
    assert len(BENCHES) >= 15
    for bench in BENCHES:
        text = bench.read_text(encoding="utf-8")
        flags = set(re.findall(r'add_argument\("(--quick|--smoke)"', text))
        assert flags == {"--quick", "--smoke"}, bench.name
        assert "--smoke" in (text.split('"""')[1] if text.startswith('"""') else ""), f"{bench.name}: its usage line"


@pytest.mark.parametrize("bench", BENCHES, ids=[b.stem for b in BENCHES])
def test_a_benchmarks_smoke_run_ends_well(bench: Path) -> None:
    there, what = NEEDS.get(bench.name, (lambda: True, ""))
    if not there():
        pytest.skip(f"{bench.name} needs {what}")
    done = subprocess.run([sys.executable, str(bench), "--smoke"], capture_output=True, text=True, timeout=150,
                          cwd=ROOT)
    assert done.returncode == 0, f"{bench.name} --smoke:\n{done.stdout[-2000:]}\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert len(done.stdout.strip().splitlines()) >= 3, done.stdout  # it printed its table
