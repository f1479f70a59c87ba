"""Suite-wide guards and markers.

Guards: each test must end every non-daemon thread it started; at the end of the session
no thread started during the session (daemon or not: activities, servers, connections)
may still be alive.

Markers (the fast loop is ``pytest -m "not integration"``): ``integration`` — real gRPC
servers, processes or browsers; every test under ``dataflow/remote/``, ``bindings/``, ``e2e/``
and ``security/``, and every ``subprocess`` or ``browser`` test. ``subprocess`` — runs the
``scart`` command (the files in :data:`SUBPROCESS_FILES`, or marked one by one).
``browser`` — drives Debian's chromium (the ``*_browser.py`` files).
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
INTEGRATION_DIRS = ("dataflow/remote", "bindings", "e2e", "security")
SUBPROCESS_FILES = {"scart/test_run_cli.py", "scart/test_stop.py", "scart/test_cli_entry.py",
                    "dataflow/test_dataflow_cli.py"}

sys.path.insert(0, str(TESTS))  # the support package
# The youBot case study is an SCA contribution: its modules are imported by plain names
# (driver, youbot_model, ...), exactly as `scart run` imports them from the composite's folder.
YOUBOT = Path(__file__).resolve().parent.parent / "composites" / "youbot"
sys.path.insert(0, str(YOUBOT))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark items by where they live (see the module docstring)."""
    for item in items:
        rel = Path(item.path).resolve().relative_to(TESTS).as_posix()
        if rel in SUBPROCESS_FILES:
            item.add_marker(pytest.mark.subprocess)
        if rel.endswith("_browser.py"):
            item.add_marker(pytest.mark.browser)
        slow = any(m in ("subprocess", "browser") for m in (mark.name for mark in item.iter_markers()))
        if slow or rel.startswith(INTEGRATION_DIRS):
            item.add_marker(pytest.mark.integration)


@pytest.fixture(autouse=True)
def _no_leaked_threads():
    """Fail a test that leaves a new non-daemon thread running (bounded wait for it to end)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 5.0
    while True:
        leaked = [
            t for t in threading.enumerate() if t not in before and t.is_alive() and not t.daemon
        ]
        if not leaked or time.monotonic() >= deadline:
            break
        time.sleep(0.01)
    assert not leaked, f"test left threads running: {[t.name for t in leaked]}"


@pytest.fixture(scope="session", autouse=True)
def _no_threads_left_at_the_end():
    """After the whole session, every thread our code started has ended (bounded wait)."""
    before = set(threading.enumerate())
    yield
    deadline = time.monotonic() + 10.0
    while True:
        left = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not left or time.monotonic() >= deadline:
            break
        time.sleep(0.05)
    assert not left, f"the test session left threads running: {sorted(t.name for t in left)}"
