"""Suite-wide guards: tests leave no thread behind.

Each test must end every non-daemon thread it started; at the end of the session no
thread started during the session (daemon or not: activities, servers, connections)
may still be alive.
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
# The youBot case study is an SCA contribution: its modules are imported by plain names
# (driver, youbot_model, ...), exactly as `scart run` imports them from the composite's folder.
YOUBOT = Path(__file__).resolve().parent.parent / "composites" / "youbot"
sys.path.insert(0, str(YOUBOT))


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
