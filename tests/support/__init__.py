"""What the test suites share (never collected by pytest): waiting on conditions, free
ports, the repository's folders; and, in submodules, SCA components (:mod:`support.sca`),
data-flow tasks and processes (:mod:`support.remote`), the command line
(:mod:`support.cli`), binding.grpc fixtures (:mod:`support.grpc_binding`), the youBot demo
(:mod:`support.youbot`), the browser (:mod:`support.browser`) and the imports of a source
file (:mod:`support.imports`)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

TESTS = Path(__file__).resolve().parent.parent  #: the tests/ folder
ROOT = TESTS.parent  #: the repository
DATA = TESTS / "data"  #: composites and modules the tests run


def wait_until(
    predicate: Callable[[], T], timeout: float = 10.0, interval: float = 0.01, message: str = ""
) -> T:
    """Poll ``predicate`` until it returns a truthy value or ``timeout`` s pass.

    Returns that value; raises ``AssertionError`` (with ``message``) on timeout. The
    loop is bounded in time and sleeps ``interval`` between polls, so it never spins.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            raise AssertionError(message or f"condition not met within {timeout} s")
        time.sleep(interval)


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (for subprocesses that need one)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def stop_group(proc: subprocess.Popen[bytes]) -> None:
    """End a server started in a session of its own (``start_new_session=True``): SIGTERM
    to its group, then SIGKILL after 10 s; waits for it either way."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
