"""The youBot Monitor's door: when the runtime checks tokens its control API needs the
control token by default, and slow clients cannot keep it from answering (each request
has a total deadline; one peer's connections still sending their request are bounded,
and give way to new ones).

The probes of the issue: with the default ``control_token=false``, another user's
``curl -X POST .../api/period`` was accepted while the robot ran with an auth file; 520
slow connections (one byte every 4 s) left ``GET /`` unanswered for 30 s."""

from __future__ import annotations

import secrets
import socket
import threading
import time
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest

from scart_monitor import MonitorServer
from scart_monitor.server import REQUEST_DEADLINE_S
from support import wait_until
from support.users import run_as, second_user
from support.youbot import start_serving

SLOW_CLIENTS = 520

POST_PERIOD = """
import sys, urllib.error, urllib.request
url = sys.argv[1]
request = urllib.request.Request(url + "api/period", data=b'{"seconds": 0.05}', method="POST",
                                 headers={"Content-Type": "application/json", "Origin": url.rstrip("/")})
try:
    with urllib.request.urlopen(request, timeout=10) as answer:
        print(answer.status, answer.read().decode())
except urllib.error.HTTPError as refused:
    print(refused.code, refused.read().decode())
"""


class Backend:
    def __init__(self) -> None:
        self.periods: list[float] = []

    def set_period(self, seconds: float) -> tuple[bool, str]:
        self.periods.append(seconds)
        return True, "ok"

    def send_pose(self, pose: str | list[float]) -> tuple[bool, str]:
        return True, "ok"

    def poses(self) -> list[str]:
        return ["home"]


@pytest.fixture
def monitor() -> Iterator[MonitorServer]:
    server = MonitorServer(Backend())
    server.start()
    try:
        yield server
    finally:
        server.stop()


def page_latency(url: str, timeout: float = 5.0) -> float:
    """Seconds ``GET /`` takes to be answered (raises if it is not, within ``timeout``)."""
    started = time.monotonic()
    with urllib.request.urlopen(url, timeout=timeout) as answer:
        assert answer.status == 200 and b"joint-table" in answer.read()
    return time.monotonic() - started


def test_a_slowloris_of_520_connections_leaves_the_page_answering(monitor: MonitorServer) -> None:
    address = ("127.0.0.1", urllib.parse.urlsplit(monitor.url).port)
    slow: list[socket.socket] = []
    stop = threading.Event()

    def dribble() -> None:  # one byte every 4 s on each, as the probe did (a pace, not a synchronisation)
        for _ in range(10):
            if stop.wait(4.0):
                return
            for sock in slow:
                try:
                    sock.send(b"E")
                except OSError:
                    pass

    dribbler = threading.Thread(target=dribble, name="test-slowloris", daemon=True)
    try:
        for _ in range(SLOW_CLIENTS):
            sock = socket.create_connection(address, timeout=5)
            sock.send(b"G")
            slow.append(sock)
        dribbler.start()
        # a page held up by the slow clients would wait for their cut (REQUEST_DEADLINE_S):
        # each GET must be answered well before it (urlopen raises otherwise)
        answered = REQUEST_DEADLINE_S / 2
        latencies = [page_latency(monitor.url, answered)]
        deadline = time.monotonic() + REQUEST_DEADLINE_S + 2.0
        while time.monotonic() < deadline:  # across the slow ones' deadline, while they dribble
            latencies.append(page_latency(monitor.url, answered))
            stop.wait(0.5)
        print(f"GET / under a slowloris of {SLOW_CLIENTS}: worst {max(latencies) * 1000:.1f} ms of {len(latencies)}")
        httpd = monitor._httpd
        assert httpd is not None
        wait_until(lambda: httpd.open_connections() < 8, timeout=10.0, interval=0.1,
                   message="slow connections outlived their request deadline")
    finally:
        stop.set()
        for sock in slow:
            sock.close()
        if dribbler.is_alive():
            dribbler.join(5)


def test_a_request_has_a_total_deadline_whatever_its_pace(monitor: MonitorServer) -> None:
    address = ("127.0.0.1", urllib.parse.urlsplit(monitor.url).port)
    with socket.create_connection(address, timeout=5) as sock:
        sock.settimeout(0.25)  # a byte every 0.25 s: well under each read's 10 s timeout
        opened, closed_at = time.monotonic(), None
        for byte in (b"GET / HTTP/1.0\r\nX-Slow: " + b"a" * 200)[:80]:
            try:
                sock.send(bytes([byte]))
                if sock.recv(1) == b"":
                    closed_at = time.monotonic()
                    break
            except TimeoutError:
                continue  # still open: the next byte
            except OSError:
                closed_at = time.monotonic()
                break
    assert closed_at is not None, "a request dribbling a byte every 0.25 s was never cut"
    assert closed_at - opened < REQUEST_DEADLINE_S + 1.5


def test_the_control_api_needs_the_token_when_the_runtime_checks_tokens(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    user = second_user()
    tokens = {role: secrets.token_hex(16) for role in ("operate", "admin")}
    auth = tmp_path / "tokens.auth"
    auth.write_text("".join(f"{role} {token}\n" for role, token in tokens.items()))
    auth.chmod(0o600)
    own = tmp_path / "admin.token"
    own.write_text(tokens["admin"] + "\n")
    own.chmod(0o600)
    monkeypatch.setenv("SCART_TOKEN_FILE", str(own))
    demo = start_serving("youbot.composite", "--auth-file", str(auth))
    try:
        url = demo.monitor_url()
        printed = demo.wait_line(r"youBot Monitor: (\S+)")[1]
        assert "?token=" in printed  # on by default: the runtime checks tokens
        answer = run_as(user, POST_PERIOD, url).stdout
        assert answer.startswith("401") and "no valid token" in answer, answer
        token = urllib.parse.parse_qs(urllib.parse.urlsplit(printed).query)["token"][0]
        request = urllib.request.Request(url + "api/period", data=b'{"seconds": 0.05}', method="POST", headers={
            "Content-Type": "application/json", "Origin": url.rstrip("/"), "X-Monitor-Token": token})
        with urllib.request.urlopen(request, timeout=10) as accepted:  # the page's own holder: still works
            assert accepted.status == 200
    finally:
        assert demo.stop() == 0
