"""A start that hangs is bounded and named, and the first SIGTERM or Ctrl-C always begins
a bounded stop.

The probe of the issue: with a ``start_hook`` or an ``@init`` that never returns,
``scart run`` printed nothing, named no component, and ignored the first SIGTERM for more
than 20 s."""

from __future__ import annotations

import signal
import subprocess
import time

import pytest

from support import ROOT
from support.cli import finish, scart_cmd
from support.youbot import ns_address

DATA = ROOT / "tests" / "data" / "security"


def run(composite: str, *extra: str) -> subprocess.Popen[bytes]:
    return subprocess.Popen(scart_cmd("run", str(DATA / composite), "--ns", ns_address(), "--stop-timeout", "2",
                                      *extra),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)


def wait_for_stderr(proc: subprocess.Popen[bytes], needle: bytes, timeout: float = 30.0) -> bytes:
    """Read stderr until ``needle`` (the hook said it began), within ``timeout`` s."""
    import os
    import selectors

    assert proc.stderr is not None
    seen = b""
    deadline = time.monotonic() + timeout
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stderr.fileno(), selectors.EVENT_READ)
        while needle not in seen and time.monotonic() < deadline:
            if sel.select(max(0.0, deadline - time.monotonic())):
                chunk = os.read(proc.stderr.fileno(), 65536)
                if not chunk:
                    break
                seen += chunk
    assert needle in seen, seen.decode(errors="replace")
    return seen


def test_a_start_hook_that_hangs_fails_the_start_naming_the_component_and_hook() -> None:
    proc = run("hang-task.composite", "--start-timeout", "2")
    try:
        proc.wait(timeout=20)  # a start bounded at 2 s ends well within it
    finally:
        out, err = finish(proc)
    assert proc.returncode == 1, err
    assert "component slow (start_hook) did not return within 2 s (--start-timeout)" in err, err
    assert "Traceback" not in err and "scart: started" not in out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_the_first_signal_during_a_hung_init_begins_a_bounded_stop(sig: signal.Signals) -> None:
    proc = run("hang-init.composite")  # the default --start-timeout: the signal comes first
    try:
        seen = wait_for_stderr(proc, b"hangs: @init began")
        proc.send_signal(sig)
        proc.wait(timeout=10)  # the stop that signal begins is bounded
    finally:
        out, err = finish(proc)
    err = seen.decode() + err
    assert proc.returncode == 1, err
    assert "stopping while starting: component Slow (@init open) had not returned" in err, err
    assert "scart: started" not in out


def test_a_signal_during_a_hung_start_exits_at_once() -> None:
    """The README says "stops at once"; it exited after 10.4 s (the default --stop-timeout,
    waiting for the very component that hung). What started before it is stopped; the one
    that never returned is not waited for."""
    proc = subprocess.Popen(scart_cmd("run", str(DATA / "hang-init.composite"), "--ns", ns_address()),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)  # default --stop-timeout: 10 s
    try:
        seen = wait_for_stderr(proc, b"hangs: @init began")
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=5)  # at once: not the 10 s a stop may take
    finally:
        out, err = finish(proc)
    err = seen.decode() + err
    assert proc.returncode == 1, err
    assert "component Slow had not returned from its start; not waited for" in err, err
