"""Helpers of the youBot demo tests (no tests here): ``scart run`` subprocesses.

:class:`Demo` starts ``python -m scart run FILE --ns 127.0.0.1:PORT`` (never the default
port), collects its merged stdout/stderr on a reader thread, waits for lines, reads the
monitor's JSON API and stops the process with a signal.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import urllib.parse
import urllib.request
from typing import Any

from support import ROOT, free_port, wait_until

YOUBOT = ROOT / "composites" / "youbot"
URL_LINE = re.compile(r"youBot Monitor: (http://127\.0\.0\.1:\d+/)")


def env() -> dict[str, str]:
    """The environment of scart subprocesses: the youBot folder importable, no SCART_NS."""
    out = dict(os.environ)
    paths = [str(ROOT), str(YOUBOT), out.get("PYTHONPATH", "")]
    out["PYTHONPATH"] = os.pathsep.join(p for p in paths if p)
    out.pop("SCART_NS", None)
    return out


def ns_address() -> str:
    """A fresh name-service address on 127.0.0.1 (never the default port)."""
    return f"127.0.0.1:{free_port()}"


class Demo:
    """One ``scart run`` subprocess and its output lines."""

    def __init__(self, composite: str, ns: str, *extra: str) -> None:
        self.ns = ns
        self.lines: list[str] = []
        self._lock = threading.Lock()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "scart", "run", str(YOUBOT / composite), "--ns", ns, *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env(), text=True, bufsize=1, cwd=ROOT,
        )
        self._reader = threading.Thread(target=self._read, name="youbot-demo-reader", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:  # ends at EOF, when the process exits
            with self._lock:
                self.lines.append(line.rstrip("\n"))

    def output(self) -> str:
        """Everything printed so far."""
        with self._lock:
            return "\n".join(self.lines)

    def wait_line(self, pattern: str, timeout: float = 30.0) -> re.Match[str]:
        """The first output line matching ``pattern`` (regex), waiting ≤ ``timeout`` s."""
        rx = re.compile(pattern)

        def found() -> re.Match[str] | None:
            if self.proc.poll() is not None and not self._reader.is_alive():
                raise AssertionError(f"scart exited with {self.proc.returncode}:\n{self.output()}")
            with self._lock:
                return next((m for line in self.lines if (m := rx.search(line))), None)

        return wait_until(found, timeout, 0.02, message=f"no line /{pattern}/ in:\n{self.output()}")

    def monitor_url(self, timeout: float = 30.0) -> str:
        """The URL the monitor printed at start."""
        return self.wait_line(URL_LINE.pattern, timeout).group(1)

    def stop(self, sig: int = signal.SIGINT, timeout: float = 20.0) -> int:
        """Send ``sig``, wait for the exit code (kill after ``timeout`` s), join the reader."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        self._reader.join(5)
        if self.proc.stdout is not None:
            self.proc.stdout.close()
        return self.proc.returncode


def start_serving(composite: str, *extra: str, tries: int = 3) -> Demo:
    """Start a composite with tasks on a fresh name-service port and wait until it serves
    them (its ``scart: name service at ... (embedded)`` line). A port taken by another
    process between :func:`free_port` and the bind (parallel test runs) makes scart exit at
    start: then it is retried on another port, ``tries`` times at most."""
    for attempt in range(tries):
        demo = Demo(composite, ns_address(), *extra)
        try:
            demo.wait_line(rf"scart: name service at {re.escape(demo.ns)} \(embedded\)")
            return demo
        except AssertionError:
            code = demo.stop()
            if attempt == tries - 1 or code == 0 or "start failed" not in demo.output():
                raise
    raise AssertionError("unreachable")


def get_json(url: str) -> Any:
    """GET ``url`` and decode its JSON answer."""
    with urllib.request.urlopen(url, timeout=5) as reply:
        return json.load(reply)


def post_json(url: str, body: Any) -> Any:
    """POST ``body`` as JSON to ``url`` as the monitor's page does (same-origin ``Origin``,
    which the monitor requires on commands) and decode the JSON answer."""
    parts = urllib.parse.urlsplit(url)
    headers = {"Content-Type": "application/json", "Origin": f"{parts.scheme}://{parts.netloc}"}
    request = urllib.request.Request(url, json.dumps(body).encode(), headers)
    with urllib.request.urlopen(request, timeout=10) as reply:
        return json.load(reply)


def monitor_state(url: str) -> dict[str, Any]:
    """The monitor's ``/api/state`` snapshot."""
    return get_json(url + "api/state")
