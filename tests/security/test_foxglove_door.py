"""The Foxglove door (``scart foxglove``, ``scart run --foxglove``): the WebSocket protocol
carries no credentials, so the server checks the handshake (Host, Origin, a token in the
URL), is read-only unless told otherwise, acts with an ``operate`` token of its own when
writable (never an ``admin`` one, auth file or not), answers refusals with the protocol's
failures, and bounds what one message may ask. Only its gate can be reached (the SDK's
server behind it drops anyone else), and tokenless connections cannot keep a token
holder out.

The probe of the issue: another local user, tokenless, set ``youBotDriver.max_velocity``
to 7.5 and ``noise`` to 42 and called ``set_period(0.5)`` through a server that acted
with the runtime's admin token."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import secrets
import socket
import struct
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from dataflow import Deployer, PeriodicActivity
from dataflow.foxglove.server import MAX_PARAMETER_NAMES, FoxgloveLive, control_token
from dataflow.remote import connect
from scart_wire.security import Security
from support import ROOT
from support.cli import finish, read_until
from support.users import run_as, second_user
from support.youbot import env as youbot_env

sys.path.insert(0, str(ROOT / "composites" / "youbot"))
from driver import YouBotDriver  # noqa: E402

PROBE = (ROOT / "tests" / "support" / "ws_probe.py").read_text()


@dataclass
class Robot:
    task: YouBotDriver
    address: str
    security: Security  # the runtime's own: the admin token
    tokens: dict[str, str]
    folder: Path

    def token_file(self, role: str) -> str:
        path = self.folder / f"{role}.token"
        path.write_text(self.tokens[role] + "\n")
        path.chmod(0o600)
        return str(path)


@pytest.fixture
def robot(tmp_path: Path) -> Iterator[Robot]:
    tokens = {role: secrets.token_hex(16) for role in ("read", "operate", "admin")}
    auth = tmp_path / "tokens.auth"
    auth.write_text("".join(f"{role} {token}\n" for role, token in tokens.items()))
    auth.chmod(0o600)
    deployer = Deployer()
    task = YouBotDriver()
    task.set_activity(PeriodicActivity(0.02))  # samples flow: each port's channel is made from its first
    deployer.add(task)
    deployer.configure_all()
    deployer.start_all()
    server = deployer.serve("127.0.0.1:0", security=Security(auth_file=str(auth)))
    try:
        yield Robot(task, server.address, Security(auth_file=str(auth), token=tokens["admin"]), tokens, tmp_path)
    finally:
        server.stop()
        deployer.stop_all()


class Served:
    """A ``scart foxglove`` subprocess against the robot, reading with the runtime's admin
    token (``SCART_TOKEN``), as ``scart run --foxglove`` does; told the auth file
    (``SCART_AUTH_FILE``) unless ``auth_file`` is False."""

    def __init__(self, robot: Robot, *extra: str, auth_file: bool = True) -> None:
        env = {**youbot_env(), "SCART_TOKEN": robot.tokens["admin"],
               "SCART_AUTH_FILE": (robot.security.auth_file or "") if auth_file else ""}
        self.proc = subprocess.Popen([sys.executable, "-m", "scart", "foxglove", "--port", "0", "--ns", robot.address,
                                      "--duration", "120", *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=env, bufsize=0, cwd=ROOT)
        self.stderr = ""
        try:
            self.line = read_until(self.proc, "Foxglove at")
        except AssertionError:
            self.stop()
            raise AssertionError(f"scart foxglove did not start: {self.stderr}") from None
        found = re.search(r"ws://127\.0\.0\.1:(\d+)/\?token=(\S+)", self.line)
        assert found is not None, self.line
        self.port, self.seat = int(found[1]), found[2]  # the seat: this launch's token, printed to its owner

    def stop(self) -> None:
        self.proc.terminate()
        self.stderr = finish(self.proc)[1]


@contextlib.contextmanager
def served(robot: Robot, *extra: str, auth_file: bool = True) -> Iterator[Served]:
    server = Served(robot, *extra, auth_file=auth_file)
    try:
        yield server
    finally:
        server.stop()


def probe(server: Served, actions: list[dict], seconds: float = 3.0, origin: str = "",
          user: str | None = None, token: str | None = None) -> dict:
    """What the standard-library client saw (run as ``user``, else as this process's user),
    presenting ``token`` (default: the printed URL's; "" none)."""
    token = server.seat if token is None else token
    args = ("127.0.0.1", str(server.port), origin, str(seconds), f"/?token={token}" if token else "/")
    if user is not None:
        done = run_as(user, PROBE, *args, stdin=json.dumps(actions))
    else:
        done = subprocess.run([sys.executable, "-c", PROBE, *args], input=json.dumps(actions), capture_output=True,
                              text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def statuses(seen: dict) -> list[str]:
    return [m["message"] for m in seen["messages"] if m.get("op") == "status"]


def handshake(port: int, host: str, origin: str | None, path: str = "/") -> int:
    """The HTTP status answering a WebSocket upgrade with these Host and Origin headers."""
    with socket.create_connection(("127.0.0.1", port), timeout=5) as sock:
        sock.sendall((f"GET {path} HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                      "Sec-WebSocket-Protocol: foxglove.sdk.v1, foxglove.websocket.v1\r\n"
                      + (f"Origin: {origin}\r\n" if origin is not None else "") + "\r\n").encode())
        return int(sock.recv(4096).split()[1])


WRITES = [
    {"op": "setParameters", "id": "s", "parameters": [{"name": "youBotDriver.max_velocity", "value": 7.5},
                                                      {"name": "youBotDriver.noise", "value": 42.0}]},
    {"call": "youBotDriver.set_period", "id": 1, "body": {"seconds": 0.5}},
]


def test_another_user_changes_nothing_through_a_read_only_server(robot: Robot) -> None:
    user = second_user()
    with served(robot) as live:
        tokenless = probe(live, WRITES, user=user, token="")  # the deployer checks tokens: so does this door
        seen = probe(live, WRITES, user=user, token=robot.tokens["read"])
    assert tokenless["status"] == 401 and "a token is needed" in tokenless["body"]
    assert seen["status"] == 101
    assert robot.task.max_velocity == 1.0 and robot.task.noise == 1.0  # untouched
    assert "read-only" in live.line
    assert seen["services"] == {} and seen["calls"] == {"1": "no such service advertised"}
    assert any("read-only" in s and "--foxglove-control" in s for s in statuses(seen)), seen["messages"]
    values = next(m for m in seen["messages"] if m.get("op") == "parameterValues" and m.get("id") == "s")
    assert {p["name"]: p["value"] for p in values["parameters"]}["youBotDriver.max_velocity"] == 1.0


def test_the_handshake_admits_only_loopback_hosts_and_the_foxglove_app(robot: Robot) -> None:
    with served(robot) as live:
        port, seat = live.port, f"/?token={live.seat}"
        here = f"127.0.0.1:{port}"
        assert handshake(port, here, None, seat) == 101  # a program (browsers always send an Origin)
        assert handshake(port, f"localhost:{port}", "https://app.foxglove.dev", seat) == 101
        assert handshake(port, f"localhost:{port}", "file://", seat) == 101  # the desktop app, as the message says
        assert handshake(port, here, "https://evil.example") == 403  # any other web page
        assert handshake(port, here, "null") == 403  # a sandboxed frame or a file page
        assert handshake(port, f"evil.example:{port}", None) == 421  # DNS rebinding
        refused = probe(live, [], seconds=0.5, origin="http://localhost:8000")
    assert refused["status"] == 403 and "https://app.foxglove.dev" in refused["body"]


def test_a_writable_server_acts_with_its_operate_token_and_says_why_it_refuses(robot: Robot) -> None:
    with served(robot, "--control", robot.token_file("operate")) as server:
        assert "writable" in server.line
        seen = probe(server, [
            {"op": "setParameters", "id": "ok", "parameters": [{"name": "youBotDriver.noise", "value": 0.5}]},
            {"op": "setParameters", "id": "no", "parameters": [{"name": "youBotDriver.max_velocity", "value": 20.0}]},
            {"call": "youBotDriver.error_names", "id": 1, "body": {"joint": 2}},
            {"call": "youBotDriver.error_names", "id": 2, "body": {"joint": 9}},
            {"call": "youBotDriver.set_period", "id": 3, "body": {"seconds": "0.5"}},
        ])
    assert robot.task.noise == 0.5 and robot.task.max_velocity == 1.0
    refusal = next(s for s in statuses(seen) if "max_velocity" in s)
    assert "youBotDriver.max_velocity" in refusal and "10" in refusal  # the task's own reason: its bound
    values = next(m for m in seen["messages"] if m.get("op") == "parameterValues" and m.get("id") == "no")
    assert values["parameters"][0]["value"] == 1.0  # the value the task kept
    assert seen["calls"]["1"] == {"result": []}
    assert "0..4" in seen["calls"]["2"]["failure"]
    assert "set_period(seconds): '0.5' refused" in seen["calls"]["3"]["failure"]


def test_the_control_token_is_an_operate_token_of_its_own(robot: Robot) -> None:
    flag = "--foxglove-control"
    assert control_token(robot.token_file("operate"), robot.security, flag) == robot.tokens["operate"]
    with pytest.raises(ValueError, match="'admin' role") as admin:
        control_token(robot.token_file("admin"), replace(robot.security, token=None), flag)
    with pytest.raises(ValueError, match="this process's own token"):
        control_token(robot.token_file("admin"), replace(robot.security, auth_file=None), flag)
    with pytest.raises(ValueError, match="'read' role"):
        control_token(robot.token_file("read"), robot.security, flag)
    with pytest.raises(ValueError, match="needs TOKEN_FILE"):
        control_token(None, robot.security, flag)
    stranger = robot.folder / "stranger.token"
    stranger.write_text("not-a-token-of-this-file\n")
    stranger.chmod(0o600)
    with pytest.raises(ValueError, match="not in the auth file"):
        control_token(str(stranger), robot.security, flag)
    for refused in (admin,):
        assert robot.tokens["admin"] not in str(refused.value)  # never printed


def test_one_message_may_name_a_bounded_number_of_parameters(robot: Robot) -> None:
    many = [{"name": f"youBotDriver.p{i}", "value": 1.0} for i in range(5000)]
    with served(robot, "--control", robot.token_file("operate")) as server:
        seen = probe(server, [{"op": "setParameters", "id": "many", "parameters": many},
                              {"op": "getParameters", "id": "all", "parameterNames": [p["name"] for p in many]}],
                     seconds=2.0)
    refusals = [s for s in statuses(seen) if "5000 names refused" in s]
    assert len(refusals) == 2 and f"at most {MAX_PARAMETER_NAMES}" in refusals[0]  # set and get, at once
    assert server.stderr.count("refused") <= 2  # not 5000 log lines


def test_a_routable_host_needs_insecure_warns_and_is_never_writable(robot: Robot,
                                                                    caplog: pytest.LogCaptureFixture) -> None:
    with connect(robot.address, security=robot.security) as system:
        with pytest.raises(ValueError, match="--insecure"):
            FoxgloveLive(system, "0.0.0.0", 0)
        with caplog.at_level(logging.WARNING, logger="scart.foxglove"):
            FoxgloveLive(system, "0.0.0.0", 0, insecure_host=True)  # not started: nothing binds
        assert any("no authentication" in r.getMessage() for r in caplog.records)
        with pytest.raises(ValueError, match="loopback only"):
            FoxgloveLive(system, "0.0.0.0", 0, insecure_host=True, control=system)


def test_subscribing_logs_no_listener_error(robot: Robot) -> None:
    with served(robot) as live:
        seen = probe(live, [{"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 1}]},
                            {"op": "unsubscribe", "subscriptionIds": [1]}])
    assert seen["sent"], seen  # the subscribe and unsubscribe reached the server
    assert seen["status"] == 101 and any(m.get("op") == "advertise" for m in seen["messages"]), (seen, live.stderr)
    assert "on_subscribe" not in live.stderr and "on_unsubscribe" not in live.stderr, live.stderr


def test_scart_foxglove_refuses_an_admin_token_for_control(robot: Robot) -> None:
    env = {**os.environ, "SCART_AUTH_FILE": robot.security.auth_file or ""}
    done = subprocess.run([sys.executable, "-m", "scart", "foxglove", "--port", "0", "--ns", robot.address,
                           "--duration", "5", "--control", robot.token_file("admin")],
                          capture_output=True, text=True, env={**env, "SCART_TOKEN": robot.tokens["read"]},
                          timeout=60, cwd=ROOT)
    assert done.returncode == 1 and "'admin' role" in done.stderr and "Foxglove at" not in done.stdout
    assert robot.tokens["admin"] not in done.stderr + done.stdout


def listening(pid: int) -> list[tuple[str, int]]:
    """The IPv4 TCP addresses process ``pid`` listens on, found as any local user finds
    them: ``/proc/net/tcp`` (here matched to the process's sockets to pick its own)."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    with open("/proc/net/tcp", encoding="ascii") as fh:
        for row in (line.split() for line in fh.readlines()[1:]):
            if row[3] == "0A" and row[9] in inodes:
                ip, port = row[1].split(":")
                found.append((socket.inet_ntoa(struct.pack("=I", int(ip, 16))), int(port, 16)))
    return found


def test_the_server_behind_the_gate_cannot_be_reached_around_it(robot: Robot) -> None:
    """The SDK's server listened on a random 127.x.y.z any user reads from /proc/net/tcp;
    connecting there with a hostile Origin got channels, parameters and services. Now its
    socket drops every connection but the gate's (tried here as this very user: the
    filter lets no one else in, whoever they are)."""
    with served(robot, auth_file=False) as live:
        behind = [a for a in listening(live.proc.pid) if a[1] != live.port]
        assert behind, "the SDK's server listens somewhere"
        for host, port in behind:
            with socket.socket() as sock:
                sock.settimeout(1.0)
                with pytest.raises(OSError):  # its SYN is dropped: a timeout, never a connection
                    sock.connect((host, port))
                    sock.sendall(b"GET / HTTP/1.1\r\nHost: evil.example\r\nOrigin: https://evil.example\r\n\r\n")
                    assert not sock.recv(100), "the server behind answered"
        through = probe(live, [], seconds=1.0)
    assert through["status"] == 101 and through["messages"][0]["op"] == "serverInfo"


def upgrade(source: str, port: int, path: str = "/") -> tuple[socket.socket, int]:
    """A WebSocket upgrade from ``source`` (an address of 127.0.0.0/8), left open: the
    socket and the HTTP status answered."""
    sock = socket.socket()
    sock.settimeout(5)
    sock.bind((source, 0))
    sock.connect(("127.0.0.1", port))
    sock.sendall((f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                  "Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n").encode())
    return sock, int(sock.recv(4096).split()[1])


def test_tokenless_connections_cannot_keep_a_token_holder_out(robot: Robot) -> None:
    """16 idle connections from each of 127.0.0.2 to 127.0.0.5 filled the 64-connection cap
    and locked everyone out. Now tokenless ones are bounded apart, one that sends no
    request is closed within 2 s (or gives way to a newer one), and the printed URL's
    token always gets in."""
    opened: list[socket.socket] = []
    try:
        with served(robot, auth_file=False) as live:
            for i in range(64):  # idle: connected, nothing sent (never authenticated)
                sock = socket.create_connection(("127.0.0.1", live.port), timeout=5,
                                                source_address=(f"127.0.0.{2 + i // 16}", 0))
                opened.append(sock)
            statuses = []
            for i in range(64):  # tokenless WebSockets, kept open
                sock, status = upgrade(f"127.0.0.{2 + i // 16}", live.port)
                opened.append(sock)
                statuses.append(status)
            holder = probe(live, [], seconds=1.0)
            idle = opened[0]
            idle.settimeout(5)
            closed = idle.recv(1) == b""  # given way, or timed out: closed by the gate, unanswered
    finally:
        for sock in opened:
            sock.close()
    assert statuses.count(101) == 16 and statuses.count(503) == 48, statuses
    assert holder["status"] == 101 and holder["messages"][0]["op"] == "serverInfo", holder
    assert closed


def test_an_admin_token_is_refused_without_condition(robot: Robot) -> None:
    """Without an auth file, Foxglove took an admin token for control; and scart foxglove
    had no --auth-file. The name service now says the token's role; --auth-file checks it
    here."""
    env = {**youbot_env(), "SCART_TOKEN": robot.tokens["read"], "SCART_AUTH_FILE": ""}
    base = [sys.executable, "-m", "scart", "foxglove", "--port", "0", "--ns", robot.address, "--duration", "5"]
    for extra in ([], ["--auth-file", robot.security.auth_file or ""]):
        done = subprocess.run([*base, *extra, "--control", robot.token_file("admin")], capture_output=True, text=True,
                              env=env, timeout=60, cwd=ROOT)
        assert done.returncode == 1 and "'admin' role" in done.stderr, (extra, done.stderr)
        assert "Foxglove at" not in done.stdout and robot.tokens["admin"] not in done.stderr + done.stdout
    with served(robot, "--control", robot.token_file("operate"), auth_file=False) as live:
        assert "writable" in live.line


def test_a_busy_port_is_one_line(robot: Robot) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        done = subprocess.run([sys.executable, "-m", "scart", "foxglove", "--port", str(port), "--ns", robot.address,
                               "--duration", "5"], capture_output=True, text=True, timeout=60, cwd=ROOT,
                              env={**youbot_env(), "SCART_TOKEN": robot.tokens["read"]})
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.strip().endswith(f"cannot listen on 127.0.0.1:{port}: the port is in use; choose another "
                                        "--port (0: a free one)"), done.stderr
