"""Running the ``scart`` command in real subprocesses: run to completion, start and read
its output until a line appears (a deadline, never a sleep), finish (bounded)."""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
import time


def scart_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "scart", *args]


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(scart_cmd(*args), capture_output=True, text=True, timeout=60)


def start(*args: str) -> subprocess.Popen[bytes]:
    """``scart ARGS`` with unbuffered binary pipes (so ``read_until`` can select on them)."""
    return subprocess.Popen(scart_cmd(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0)


def read_until(proc: subprocess.Popen[bytes], needle: str, timeout: float = 30.0) -> str:
    """Read the process's stdout and stderr until together they contain ``needle``
    (deadline; never sleeps): what scart itself says goes to stderr, what its components
    print to stdout. Returns what was read, both streams in arrival order."""
    streams = [s for s in (proc.stdout, proc.stderr) if s is not None]  # stderr may be merged into stdout
    assert streams, "the process has no pipe to read"
    seen = b""
    deadline = time.monotonic() + timeout
    with selectors.DefaultSelector() as sel:
        for stream in streams:
            sel.register(stream.fileno(), selectors.EVENT_READ)
        while time.monotonic() < deadline and sel.get_map():
            for key, _ in sel.select(timeout=max(0.0, deadline - time.monotonic())):
                chunk = os.read(key.fd, 65536)
                if not chunk:
                    sel.unregister(key.fd)
                    continue
                seen += chunk
                if needle.encode() in seen:
                    return seen.decode()
    raise AssertionError(f"{needle!r} not printed within {timeout} s; got: {seen.decode(errors='replace')}")


def finish(proc: subprocess.Popen[bytes]) -> tuple[str, str]:
    """Wait (bounded) for the process; kill it if it hangs. Returns (stdout, stderr)."""
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate(timeout=30)
    return (out or b"").decode(), (err or b"").decode()
