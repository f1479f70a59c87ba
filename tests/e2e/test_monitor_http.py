"""The monitor's HTTP side with plain urllib: pages, Plotly from the package, commands, SSE,
and its defences (Host and Origin checks, framing headers, stream and connection caps, token)."""

from __future__ import annotations

import http.client
import importlib.resources
import json
import logging
import socket
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest
from support import wait_until

from scart_monitor import MonitorBackend, MonitorServer
from scart_monitor.demo import DEMO_FLAG_NAMES
from scart_monitor.hub import StatusHub, flag_names


class FakeBackend:
    """Records calls; answers like a driver that accepts 2 ms … 1 s."""

    def __init__(self) -> None:
        self.periods: list[float] = []
        self.poses_sent: list[Any] = []

    def set_period(self, seconds: float) -> tuple[bool, str]:
        self.periods.append(seconds)
        if seconds < 0.002:
            return False, "too fast: the driver's minimum period is 2 ms"
        return True, f"accepted {seconds * 1000:g} ms"

    def send_pose(self, pose: str | list[float]) -> tuple[bool, str]:
        self.poses_sent.append(pose)
        if pose == "broken":
            raise RuntimeError("locomotor unreachable")
        return True, f"moving to {pose}"

    def poses(self) -> list[str]:
        return ["home", "candle"]


def sample(seq: int, stamp: float, flags: int = 0) -> dict[str, Any]:
    joint = {"position": 0.1 * seq, "velocity": 0.0, "current": 0.3, "temperature": 30.0, "error_flags": flags}
    return {"sequence": seq, "timestamp": stamp, "joints": [dict(joint) for _ in range(5)]}


@pytest.fixture
def backend() -> FakeBackend:
    return FakeBackend()


@pytest.fixture
def server(backend: FakeBackend) -> Iterator[MonitorServer]:
    srv = MonitorServer(backend)
    srv.start()
    yield srv
    srv.stop()


def get(url: str) -> tuple[int, str, bytes]:
    with urllib.request.urlopen(url, timeout=10) as resp:
        return resp.status, resp.headers.get("Content-Type", ""), resp.read()


def origin_of(url: str) -> str:
    """``scheme://host:port`` of ``url``: the ``Origin`` the monitor's own page sends."""
    parts = urllib.parse.urlsplit(url)
    return f"{parts.scheme}://{parts.netloc}"


def post(
    url: str, body: bytes, ctype: str = "application/json", headers: dict[str, str] | None = None
) -> tuple[int, dict[str, Any]]:
    """POST as the page does (same-origin ``Origin``) unless ``headers`` say otherwise."""
    sent = {"Content-Type": ctype, "Origin": origin_of(url), **(headers or {})}
    req = urllib.request.Request(url, data=body, method="POST", headers={k: v for k, v in sent.items() if v})
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, json.loads(resp.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read())


def monitor_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("scart-monitor")]


def test_index_and_our_static_files_are_served(server: MonitorServer) -> None:
    assert server.url.startswith("http://127.0.0.1:") and server.url.endswith("/")
    status, ctype, body = get(server.url)
    assert status == 200 and ctype.startswith("text/html")
    page = body.decode()
    for marker in ('id="joint-table"', 'id="tab-joint-5"', "/static/plotly.min.js", "/static/app.js"):
        assert marker in page
    assert get(server.url + "static/app.js")[1].startswith("text/javascript")
    assert get(server.url + "static/style.css")[1].startswith("text/css")


def test_plotly_is_served_from_the_installed_package(server: MonitorServer) -> None:
    status, ctype, body = get(server.url + "static/plotly.min.js")
    shipped = (importlib.resources.files("plotly") / "package_data" / "plotly.min.js").read_bytes()
    assert status == 200 and ctype.startswith("text/javascript")
    assert body == shipped and b"extendTraces" in body


def test_unknown_path_is_404_with_a_message(server: MonitorServer) -> None:
    with pytest.raises(urllib.error.HTTPError) as err:
        get(server.url + "nope")
    assert err.value.code == 404
    assert "no such page: /nope" in json.loads(err.value.read())["message"]


def test_post_period_calls_the_backend_and_returns_its_answer(server: MonitorServer, backend: FakeBackend) -> None:
    assert post(server.url + "api/period", b'{"seconds": 0.02}') == (200, {"ok": True, "message": "accepted 20 ms"})
    code, answer = post(server.url + "api/period", b'{"seconds": 0.0005}')
    assert code == 200 and answer == {"ok": False, "message": "too fast: the driver's minimum period is 2 ms"}
    assert backend.periods == [0.02, 0.0005]


def test_post_pose_by_name_and_by_positions(server: MonitorServer, backend: FakeBackend) -> None:
    assert post(server.url + "api/pose", b'{"pose": "home"}')[1] == {"ok": True, "message": "moving to home"}
    assert post(server.url + "api/pose", b'{"pose": [0, 1, 2, 3, 4]}')[1]["ok"] is True
    assert backend.poses_sent == ["home", [0.0, 1.0, 2.0, 3.0, 4.0]]
    code, answer = post(server.url + "api/pose", b'{"pose": "broken"}')
    assert code == 200 and answer == {"ok": False, "message": "backend error: RuntimeError: locomotor unreachable"}
    assert json.loads(get(server.url + "api/poses")[2]) == {"poses": ["home", "candle"]}


@pytest.mark.parametrize(
    ("path", "body", "ctype", "code", "says"),
    [
        ("api/period", b"{not json", "application/json", 400, "body is not valid JSON"),
        ("api/period", b'{"period": 1}', "application/json", 400, 'expected a JSON object like {"seconds": 0.01}'),
        ("api/period", b'{"seconds": "fast"}', "application/json", 400,
         "set_period(seconds): 'fast' refused: Input should be a valid number"),  # as at every other door
        ("api/period", b'{"seconds": NaN}', "application/json", 400,
         "set_period(seconds): nan refused: Value error, nan is not a finite number"),
        ("api/period", b'{"seconds": 0.01}', "text/plain", 415, "expected Content-Type application/json"),
        ("api/pose", b'{"pose": []}', "application/json", 400, "move(pose): [] refused: Input should be a pose name"),
        ("api/nothing", b"{}", "application/json", 404, "no such command: /api/nothing"),
    ],
)
def test_bad_requests_are_refused_with_a_clear_message(
    server: MonitorServer, backend: FakeBackend, path: str, body: bytes, ctype: str, code: int, says: str
) -> None:
    got, answer = post(server.url + path, body, ctype)
    assert got == code and answer["ok"] is False
    assert says in answer["message"]
    assert backend.periods == [] and backend.poses_sent == []


def read_update(stream: Any, predicate: Any, limit: int = 500, events: list[str] | None = None) -> dict[str, Any]:
    """Read SSE ``update`` messages (bounded count) until ``predicate(message)``; the names
    of the events seen on the way (each is sent once per stream) go to ``events``."""
    for _ in range(limit):
        line = stream.readline()
        assert line, "SSE stream closed early"
        if line.startswith(b"data: "):
            message = json.loads(line[6:])
            if events is not None:
                events.extend(e["name"] for e in message["events"])
            if predicate(message):
                return message
    raise AssertionError(f"no matching SSE message within {limit} lines")


def test_sse_stream_delivers_published_status_events_and_driver_info(server: MonitorServer) -> None:
    server.error_flag_names = {3: "OVER_TEMPERATURE"}
    server.set_driver_info("RUNNING", 0.01, True)
    with urllib.request.urlopen(server.url + "events", timeout=10) as stream:
        assert stream.headers["Content-Type"] == "text/event-stream"
        now = time.time()
        for seq in range(1, 11):
            server.publish_status(sample(seq, now + seq * 0.01, flags=0b1000 if seq == 10 else 0))
            server.publish_event("refresh")
        server.publish_event("busy", "moving to home")
        names: list[str] = []
        msg = read_update(stream, lambda m: "busy" in names and m["status"]["sequence"] == 10, events=names)
    assert msg["driver"] == {"state": "RUNNING", "period": 0.01, "connected": True}
    assert msg["flags"][0] == ["OVER_TEMPERATURE"]
    assert msg["samples"] == 10 and msg["age"] < 5.0
    assert msg["rate"] == pytest.approx(100.0, rel=0.01)  # from the sample timestamps, 10 ms apart
    assert msg["coalesced"]["refresh"]["count"] == 10
    assert [n for n in names if n != "error"] == ["connected", "busy"]  # refresh is counted, never listed
    assert names.count("error") == 5  # OVER_TEMPERATURE raised on each of the 5 joints at sequence 10


def test_stop_closes_sse_streams_and_leaves_no_threads(backend: FakeBackend) -> None:
    before = monitor_threads()
    server = MonitorServer(backend)
    assert monitor_threads() == before  # nothing started in __init__
    server.start()
    stream = urllib.request.urlopen(server.url + "events", timeout=10)
    server.publish_status(sample(1, time.time()))
    read_update(stream, lambda m: m["status"] is not None)
    started = time.monotonic()
    server.stop()
    server.stop()  # idempotent
    assert time.monotonic() - started < 3.0
    for _ in range(1000):  # the stream ends: EOF within a bounded number of reads
        if not stream.readline():
            break
    else:
        raise AssertionError("SSE stream still open after stop()")
    stream.close()
    assert monitor_threads() == before
    server.publish_status(sample(2, time.time()))  # publishing after stop is harmless


def test_publish_never_blocks_on_a_stalled_reader(server: MonitorServer) -> None:
    stream = urllib.request.urlopen(server.url + "events", timeout=10)  # opened, never read
    try:
        started = time.monotonic()
        base = time.time()
        for seq in range(20_000):
            server.publish_status(sample(seq, base + seq * 0.001))
        assert time.monotonic() - started < 5.0
        state = json.loads(get(server.url + "api/state")[2])
        assert state["status"]["sequence"] == 19_999 and state["samples"] == 20_000
    finally:
        stream.close()


def test_public_api(backend: FakeBackend) -> None:
    import scart_monitor as monitor

    assert monitor.__all__ == ["MonitorBackend", "MonitorServer"]
    assert isinstance(backend, MonitorBackend)  # the Protocol is runtime-checkable
    assert "Plotly.js" in (monitor.__doc__ or "")  # the technology choice is explained


def test_stop_from_inside_a_request_does_not_deadlock() -> None:
    class Stopper(FakeBackend):
        server: MonitorServer

        def set_period(self, seconds: float) -> tuple[bool, str]:
            self.server.stop(timeout=2.0)
            return True, "stopping"

    backend = Stopper()
    server = backend.server = MonitorServer(backend)
    server.start()
    assert post(server.url + "api/period", b'{"seconds": 1}') == (200, {"ok": True, "message": "stopping"})
    wait_until(lambda: not monitor_threads(), timeout=5.0, message="monitor threads left")


def test_start_twice_is_refused_and_url_needs_start(backend: FakeBackend) -> None:
    server = MonitorServer(backend)
    with pytest.raises(RuntimeError, match="not started"):
        _ = server.url
    server.start()
    try:
        with pytest.raises(RuntimeError, match="already started"):
            server.start()
    finally:
        server.stop()
    wait_until(lambda: not monitor_threads(), timeout=5.0, message="monitor threads left")


def test_hub_rate_age_and_flag_names() -> None:
    hub = StatusHub()
    message, _ = hub.snapshot()
    assert message["rate"] == 0.0 and message["age"] is None and message["status"] == "null"
    for seq in range(300):  # 3 s of samples at 100 Hz: only the last second counts
        hub.publish_status(sample(seq, 1000.0 + seq * 0.01))
    assert hub.snapshot()[0]["rate"] == pytest.approx(100.0, rel=0.01)
    hub.publish_status(sample(0, 5.0))  # the source restarted with an earlier clock
    assert hub.snapshot()[0]["rate"] == 0.0
    assert flag_names(0b1000001000, {3: "OVER_TEMPERATURE", 9: "JOINT_LIMIT"}) == ["OVER_TEMPERATURE", "JOINT_LIMIT"]
    assert flag_names(0b100, {}) == ["bit2"] and flag_names(0, {}) == []
    hub.close()
    started = time.monotonic()
    hub.wait(hub.snapshot()[0]["version"], timeout=10.0)
    assert time.monotonic() - started < 5.0  # closed: returns at once, not after the timeout


def test_a_real_youbot_status_sample_is_shown_with_the_driver_bit_names(server: MonitorServer) -> None:
    """What the host will do: publish ``YouBotStatus.model_dump()`` with the driver's bit names."""
    model = pytest.importorskip("youbot_model")
    server.error_flag_names = model.ERROR_BITS
    assert DEMO_FLAG_NAMES == model.ERROR_BITS  # the demo's stand-alone copy has not drifted
    joints = [model.JointStatus(position=0.1 * i, error_flags=0) for i in range(5)]
    joints[2] = model.JointStatus(position=1.0, error_flags=(1 << 3) | (1 << 7))
    server.publish_status(model.YouBotStatus(joints=joints, timestamp=time.time(), sequence=7).model_dump())
    state = json.loads(get(server.url + "api/state")[2])
    assert state["status"]["sequence"] == 7 and state["status"]["joints"][2]["position"] == 1.0
    assert state["flags"][2] == ["OVER_TEMPERATURE", "POSITION_LIMIT"] and state["flags"][0] == []


def test_a_reconnecting_stream_resumes_the_event_log_without_repeats(server: MonitorServer) -> None:
    server.publish_event("busy", "first")
    with urllib.request.urlopen(server.url + "events", timeout=10) as stream:
        names: list[str] = []
        read_update(stream, lambda m: "busy" in names, events=names)
        last_id = ""
        for _ in range(100):  # the id line of the frame just read comes before its data line
            line = stream.readline()
            if line.startswith(b"id: "):
                last_id = line[4:].strip().decode()
                break
    server.publish_event("idle", "second")
    req = urllib.request.Request(server.url + "events", headers={"Last-Event-ID": last_id})
    with urllib.request.urlopen(req, timeout=10) as stream:
        again: list[str] = []
        read_update(stream, lambda m: "idle" in again, events=again)
    assert again == ["idle"]  # "busy" was not sent twice
    req = urllib.request.Request(server.url + "events", headers={"Last-Event-ID": "otherserver:99"})
    with urllib.request.urlopen(req, timeout=10) as stream:
        fresh: list[str] = []
        read_update(stream, lambda m: "idle" in fresh, events=fresh)
    assert fresh == ["busy", "idle"]  # an id from another server instance: the whole log


# -- defences (issue 11) -------------------------------------------------------------------


def raw_request(
    url: str, method: str, path: str, headers: dict[str, str], body: bytes | None = None
) -> tuple[int, dict[str, str], bytes]:
    """One request with exactly ``headers`` (``Host`` included: none is added if absent)."""
    parts = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(parts.hostname, parts.port, timeout=10)
    try:
        conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
        for name, value in headers.items():
            conn.putheader(name, value)
        if body is not None:
            conn.putheader("Content-Length", str(len(body)))
        conn.endheaders(body)
        resp = conn.getresponse()
        return resp.status, {k.lower(): v for k, v in resp.getheaders()}, resp.read()
    finally:
        conn.close()


def test_a_foreign_or_missing_host_is_refused_and_changes_nothing(server: MonitorServer, backend: FakeBackend) -> None:
    port = urllib.parse.urlsplit(server.url).port
    evil = {"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}",  # DNS rebinding
            "Content-Type": "application/json"}
    status, headers, body = raw_request(server.url, "POST", "/api/period", evil, b'{"seconds": 0.02}')
    assert status == 421 and "misdirected" in json.loads(body)["message"]
    assert headers["x-frame-options"] == "DENY"
    assert raw_request(server.url, "GET", "/api/state", {"Host": f"evil.example:{port}"})[0] == 421
    assert raw_request(server.url, "GET", "/", {"Host": "127.0.0.1:1"})[0] == 421  # another port
    assert raw_request(server.url, "GET", "/api/state", {})[0] == 421  # no Host at all
    assert backend.periods == []
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"LOCALHOST:{port}"):  # our own names
        assert raw_request(server.url, "GET", "/api/state", {"Host": host})[0] == 200
    ours = {"Host": f"localhost:{port}", "Origin": f"http://localhost:{port}", "Content-Type": "application/json"}
    assert raw_request(server.url, "POST", "/api/period", ours, b'{"seconds": 0.02}')[0] == 200
    assert backend.periods == [0.02]


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "https://127.0.0.1:{port}", "http://127.0.0.1:1", ""])
def test_a_command_without_a_same_origin_origin_is_refused(
    server: MonitorServer, backend: FakeBackend, origin: str
) -> None:
    port = urllib.parse.urlsplit(server.url).port
    code, answer = post(server.url + "api/pose", b'{"pose": "home"}', headers={"Origin": origin.format(port=port)})
    assert code == 403 and answer["ok"] is False
    assert ("Origin" in answer["message"]) and backend.poses_sent == []


@pytest.mark.parametrize("path", ["", "api/state", "static/app.js", "nope"])
def test_every_answer_forbids_framing_and_sniffing(server: MonitorServer, path: str) -> None:
    try:
        resp = urllib.request.urlopen(server.url + path, timeout=10)
    except urllib.error.HTTPError as err:
        resp = err
    with resp:
        headers = resp.headers
        assert headers["X-Frame-Options"] == "DENY"
        assert "frame-ancestors 'none'" in headers["Content-Security-Policy"]
        assert "default-src 'self'" in headers["Content-Security-Policy"]
        assert headers["X-Content-Type-Options"] == "nosniff"
        assert headers["Referrer-Policy"] == "no-referrer"
        assert headers["Cache-Control"] == "no-cache"


def open_stream(url: str) -> Any:
    """An open ``/events`` stream whose first bytes were read (the server is streaming)."""
    stream = urllib.request.urlopen(url + "events", timeout=10)
    assert stream.readline() == b"retry: 1000\n"
    return stream


def test_sse_clients_are_capped_and_a_freed_slot_is_reused(backend: FakeBackend) -> None:
    server = MonitorServer(backend, max_sse_clients=3)
    server.start()
    streams = []
    try:
        streams = [open_stream(server.url) for _ in range(3)]
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(server.url + "events", timeout=10)
        assert err.value.code == 503 and err.value.headers["Retry-After"] == "5"
        assert "too many event streams" in json.loads(err.value.read())["message"]
        err.value.close()
        assert get(server.url + "api/state")[0] == 200  # the rest of the server still answers
        streams.pop().close()

        def reopened() -> Any:  # the server notices the closed stream at its next writes
            try:
                return open_stream(server.url)
            except urllib.error.HTTPError as refused:
                refused.close()
                return None

        streams.append(wait_until(reopened, timeout=10.0, interval=0.05, message="the freed slot was never reused"))
    finally:
        for stream in streams:
            stream.close()
        server.stop()


def test_connections_beyond_the_cap_are_closed_at_once(backend: FakeBackend) -> None:
    """When every connection is being answered (streams), one more is closed unanswered;
    a connection still sending its request would have been dropped for it instead
    (tests/security/test_monitor.py)."""
    server = MonitorServer(backend, max_connections=2)
    server.start()
    address = ("127.0.0.1", urllib.parse.urlsplit(server.url).port)
    streams = [open_stream(server.url) for _ in range(2)]  # each pins a handler thread, answering
    try:
        with socket.create_connection(address, timeout=5) as extra:
            started = time.monotonic()
            try:
                assert extra.recv(1) == b""  # closed, unanswered
            except ConnectionResetError:
                pass
            assert time.monotonic() - started < 3.0  # well before the handlers' 10 s read timeout
        streams.pop().close()

        def served() -> bool:
            try:
                return get(server.url + "api/state")[0] == 200
            except (urllib.error.URLError, ConnectionError):
                return False

        wait_until(served, timeout=10.0, interval=0.05, message="no connection accepted after one closed")
    finally:
        for stream in streams:
            stream.close()
        server.stop()


def test_token_mode_commands_need_the_token_and_it_is_never_logged(
    backend: FakeBackend, caplog: pytest.LogCaptureFixture
) -> None:
    server = MonitorServer(backend, token="launch-Secret_1")
    server.start()
    try:
        assert server.page_url == server.url + "?token=launch-Secret_1"
        assert "launch-Secret_1" not in server.url and "launch-Secret_1" not in repr(server)
        with caplog.at_level(logging.DEBUG, logger="scart_monitor"):
            assert get(server.page_url)[0] == 200  # GETs stay open
            assert get(server.url + "api/state")[0] == 200
            body = b'{"seconds": 0.02}'
            for headers in ({}, {"X-Monitor-Token": "launch-Secret_2"}, {"X-Monitor-Token": ""}):
                code, answer = post(server.url + "api/period", body, headers=headers)
                assert code == 401 and answer["message"].startswith("set_period: no valid token")
            assert backend.periods == []
            code, answer = post(server.url + "api/period", body, headers={"X-Monitor-Token": "launch-Secret_1"})
            assert (code, answer["ok"]) == (200, True) and backend.periods == [0.02]
            code, _ = post(server.url + "api/period", body, headers={"X-Monitor-Token": "launch-Secret_1", "Origin": ""})
            assert code == 403  # the token does not replace the Origin check
        assert "token=***" in caplog.text and "launch-Secret_1" not in caplog.text
    finally:
        server.stop()


def test_bad_settings_are_refused(backend: FakeBackend) -> None:
    for kwargs in ({"token": ""}, {"max_sse_clients": 0}, {"max_connections": 0}):
        with pytest.raises(ValueError):
            MonitorServer(backend, **kwargs)


def test_a_routable_host_needs_a_control_token(backend: FakeBackend, caplog: pytest.LogCaptureFixture) -> None:
    with pytest.raises(ValueError, match="refusing to serve on 0.0.0.0 without a control token"):
        MonitorServer(backend, host="0.0.0.0")
    MonitorServer(backend, host="0.0.0.0", token="per-launch-secret")  # with one: fine (not started)
    with caplog.at_level(logging.WARNING):
        MonitorServer(backend, host="0.0.0.0", insecure=True)
    assert "anyone who reaches it can move the arm" in caplog.text


def test_the_event_log_tells_period_state_error_flag_and_connection_changes() -> None:
    hub = StatusHub()
    hub.error_flag_names = {0: "OVER_CURRENT", 3: "TIMEOUT"}
    hub.set_driver_info("RUNNING", 0.01, True)   # connected
    hub.set_driver_info("RUNNING", 0.02, True)   # a period change
    hub.set_driver_info("STOPPED", 0.02, True)   # a state change
    hub.set_driver_info("OFFLINE", 0.0, False)   # lost
    hub.set_driver_info("RUNNING", 0.02, True)   # restored
    joints = [{"position": 0.0, "error_flags": 0} for _ in range(5)]
    hub.publish_status({"joints": joints, "sequence": 1})
    raised = [dict(j) for j in joints]
    raised[1]["error_flags"] = 0b1001
    hub.publish_status({"joints": raised, "sequence": 2})
    hub.publish_status({"joints": joints, "sequence": 3})
    events = [(e["name"], e["detail"]) for e in hub.snapshot()[0]["events"]]
    assert events == [
        ("connected", "RUNNING"), ("period", "10 ms → 20 ms"), ("state", "RUNNING → STOPPED"),
        ("disconnected", "OFFLINE"), ("connected", "RUNNING"),
        ("error", "joint 2: OVER_CURRENT, TIMEOUT set"), ("error", "joint 2: OVER_CURRENT, TIMEOUT cleared"),
    ]


def test_the_last_minute_is_kept_for_a_page_opened_now(server: MonitorServer,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    clock = [1000.0]
    monkeypatch.setattr(server._hub, "_clock", lambda: clock[0])  # noqa: SLF001 - this hub's clock only
    for seq in range(1, 3001):  # 30 s at 100 Hz
        clock[0] += 0.01
        server.publish_status(sample(seq, clock[0]))
    status, _, body = get(server.url + "api/history")
    statuses = json.loads(body)["statuses"]
    assert status == 200
    sequences = [s["sequence"] for s in statuses]
    assert sequences == sorted(sequences) and sequences[-1] >= 2996  # oldest first, up to now
    assert 700 <= len(statuses) <= 760  # one per 40 ms, not every sample
    for seq in range(3001, 9001):  # 60 s more: only the last minute stays
        clock[0] += 0.01
        server.publish_status(sample(seq, clock[0]))
    kept = json.loads(get(server.url + "api/history")[2])["statuses"]
    assert kept[0]["sequence"] > 3000 and len(kept) <= 1510
