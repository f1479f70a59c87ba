"""Fixtures of the ROS 2 tests (``tests/scart_ros2`` and the ``ros2`` transport's, whose
``conftest.py`` take them from here): a random DDS domain per run, unique topic names, the
independent peer (``support/ros2_peer.py``) in a subprocess on the loopback-only network,
and the ``cyclonedds`` command."""

from __future__ import annotations

import itertools
import json
import os
import random
import selectors
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from support import TESTS

PEER = TESTS / "support" / "ros2_peer.py"
STREAM_PEER = TESTS / "support" / "ros2_stream_peer.py"
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
    from scart_ros2 import Network

    return {**os.environ, "CYCLONEDDS_URI": Network.loopback().config_xml(), **(extra or {})}


class Peer:
    """A running ``ros2_peer.py``: its JSON events, read with deadlines."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self.proc = proc
        self.events: list[dict] = []
        self._buffer = b""

    def next_event(self, kind: str, timeout: float = 15.0) -> dict:
        """The next event of ``kind`` printed within ``timeout`` s (else AssertionError)."""
        event = self.poll(kind, timeout)
        if event is None:
            raise AssertionError(f"the peer printed no {kind!r} within {timeout} s; saw {self.events}; "
                                 f"stderr: {self._stderr()}")
        return event

    def poll(self, kind: str, timeout: float) -> dict | None:
        """The next event of ``kind`` printed within ``timeout`` s, or None (for ``wait_until``)."""
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
        return None

    def _stderr(self) -> str:
        if self.proc.poll() is None:
            return "(running)"
        return self.proc.stderr.read().decode(errors="replace") if self.proc.stderr else ""


def _peers(command: Callable[..., list[str]]) -> Iterator[Callable[..., Peer]]:
    """The body of a peer fixture: ``start(...)`` runs ``command(...)``'s process on the
    loopback network and returns its :class:`Peer` once it says ``ready``; every process
    started is killed when the test ends."""
    started: list[subprocess.Popen[bytes]] = []

    def start(*args: Any, **kwargs: Any) -> Peer:
        proc = subprocess.Popen(command(*args, **kwargs), stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0,
                                env=loopback_env())
        started.append(proc)
        found = Peer(proc)
        found.next_event("ready", timeout=30.0)
        return found

    yield start
    for proc in started:
        proc.kill()
        proc.communicate(timeout=30)


@pytest.fixture
def peer(domain: int) -> Iterator[Callable[..., Peer]]:
    """Start the independent peer: ``peer(mode)`` returns a :class:`Peer` once ready."""

    def command(mode: str, seconds: float = 60.0) -> list[str]:
        return [sys.executable, str(PEER), mode, str(domain), str(seconds)]

    yield from _peers(command)


@pytest.fixture
def stream_peer(domain: int) -> Iterator[Callable[..., Peer]]:
    """Start the independent peer of streams (``support/ros2_stream_peer.py``):
    ``stream_peer(mode, topic, type, values=None, latched=False, depth=10, on=DOMAIN)`` returns a
    :class:`Peer` once ready (``read``: it prints each sample; ``write``: it writes
    ``values`` once a reader matched)."""

    def command(mode: str, topic: str, type_name: str, values: list | None = None, *, latched: bool = False,
                depth: int = 10, seconds: float = 60.0, on: int | None = None) -> list[str]:
        return [sys.executable, str(STREAM_PEER), mode, str(on or domain), topic, type_name, json.dumps(values or []),
                "--depth", str(depth), "--seconds", str(seconds)] + (["--latched"] if latched else [])

    yield from _peers(command)


def cli(*args: str, timeout: float = 60) -> subprocess.CompletedProcess[str]:
    """The ``cyclonedds`` command (``ls``, ...) on the loopback network, plain output."""
    return subprocess.run([cyclonedds_cli(), *args, "--suppress-progress-bar", "--color", "none"],
                          capture_output=True, text=True, timeout=timeout, env=loopback_env({"COLUMNS": "200"}))


def cli_subscribe(domain: int, dds_topic: str, publish: Callable[[], object]) -> tuple[str, str]:
    """``cyclonedds subscribe`` of ``dds_topic`` while ``publish()`` runs (until it returns
    something true: matched), then 2 s more; the tool's output."""
    proc = subprocess.Popen([cyclonedds_cli(), "subscribe", "--id", str(domain), "--runtime", "2",
                             "--suppress-progress-bar", "--color", "none", dds_topic],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=loopback_env({"COLUMNS": "400"}))
    try:
        for _ in range(600):  # bounded (~30 s): the tool prints what arrives once it subscribed
            if publish() or proc.poll() is not None:
                break
            try:
                proc.wait(timeout=0.05)
            except subprocess.TimeoutExpired:
                pass
        for _ in range(40):  # then 2 s more of samples
            publish()
            time.sleep(0.05)
    finally:
        proc.terminate()
        out, err = proc.communicate(timeout=30)
    return out, err


def cli_read(domain: int, dds_topic: str, until: str, timeout: float = 30.0) -> str:
    """``cyclonedds subscribe`` of ``dds_topic`` (a type it learns from DDS) until its output
    holds ``until`` (else AssertionError after ``timeout`` s); that output."""
    proc = subprocess.Popen([cyclonedds_cli(), "subscribe", "--id", str(domain), "--runtime", "1",
                             "--suppress-progress-bar", "--color", "none", dds_topic],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=loopback_env({"COLUMNS": "400"}))
    out, deadline = b"", time.monotonic() + timeout
    try:
        assert proc.stdout is not None
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout.fileno(), selectors.EVENT_READ)
            while until.encode() not in out and (left := deadline - time.monotonic()) > 0:
                if not sel.select(timeout=left):
                    break
                chunk = os.read(proc.stdout.fileno(), 65536)
                if not chunk:
                    break
                out += chunk
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert until.encode() in out, (out.decode(errors="replace"), err.decode(errors="replace"))
    return out.decode(errors="replace")


def cyclonedds_cli() -> str:
    """The ``cyclonedds`` command beside this Python (the venv's)."""
    candidate = Path(sys.executable).parent / "cyclonedds"
    return str(candidate) if candidate.exists() else "cyclonedds"
