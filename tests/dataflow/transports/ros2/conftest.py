"""Fixtures of the ROS 2 tests: a random DDS domain per run, unique topic names, and the
independent peer (``support/ros2_peer.py``) in a subprocess on the loopback-only network."""

from __future__ import annotations

import itertools
import json
import os
import random
import selectors
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from support import TESTS

PEER = TESTS / "support" / "ros2_peer.py"
_DOMAIN = random.SystemRandom().randint(1, 232)  # concurrent runs on one host stay apart
_NAMES = itertools.count()


@pytest.fixture(scope="session")
def domain() -> int:
    """This run's DDS domain id."""
    return _DOMAIN


@pytest.fixture
def topic(request: pytest.FixtureRequest) -> str:
    """A ROS 2 topic name no other test of this run uses."""
    return f"/scart_test/{request.node.name.split('[')[0]}_{next(_NAMES)}"


def loopback_env(extra: dict[str, str] | None = None) -> dict[str, str]:
    """The environment for a Cyclone DDS tool or peer: the library's loopback config."""
    from dataflow.transports.ros2 import Network

    return {**os.environ, "CYCLONEDDS_URI": Network.loopback().config_xml(), **(extra or {})}


class Peer:
    """A running ``ros2_peer.py``: its JSON events, read with deadlines."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self.proc = proc
        self.events: list[dict] = []
        self._buffer = b""

    def next_event(self, kind: str, timeout: float = 15.0) -> dict:
        """The next event of ``kind`` printed within ``timeout`` s (else AssertionError)."""
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout
        fd = self.proc.stdout.fileno()
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while True:
                line, newline, rest = self._buffer.partition(b"\n")
                if newline:
                    self._buffer = rest
                    event = json.loads(line)
                    self.events.append(event)
                    if event.get("event") == kind:
                        return event
                    continue
                left = deadline - time.monotonic()
                if left <= 0 or not sel.select(timeout=left):
                    break
                chunk = os.read(fd, 65536)
                if not chunk:
                    break
                self._buffer += chunk
        raise AssertionError(f"the peer printed no {kind!r} within {timeout} s; saw {self.events}; "
                             f"stderr: {self._stderr()}")

    def _stderr(self) -> str:
        if self.proc.poll() is None:
            return "(running)"
        return self.proc.stderr.read().decode(errors="replace") if self.proc.stderr else ""


@pytest.fixture
def peer(domain: int) -> Iterator:
    """Start the independent peer: ``peer(mode)`` returns a :class:`Peer` once ready."""
    started: list[subprocess.Popen[bytes]] = []

    def start(mode: str, seconds: float = 60.0) -> Peer:
        proc = subprocess.Popen([sys.executable, str(PEER), mode, str(domain), str(seconds)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0, env=loopback_env())
        started.append(proc)
        found = Peer(proc)
        found.next_event("ready", timeout=30.0)
        return found

    yield start
    for proc in started:
        proc.kill()
        proc.communicate(timeout=30)


def cyclonedds_cli() -> str:
    """The ``cyclonedds`` command beside this Python (the venv's)."""
    candidate = Path(sys.executable).parent / "cyclonedds"
    return str(candidate) if candidate.exists() else "cyclonedds"
