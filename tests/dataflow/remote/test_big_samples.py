"""Camera-sized samples across processes: a 6.2 MB frame (1080p RGB) and a 24.9 MB one
(4K RGB) are delivered on every transport, written = delivered + dropped holds for them,
and a sample over the limit is refused at ``write()``, counted and said, never "connected,
0 dropped" with nothing delivered."""

from __future__ import annotations

import contextlib
import json
import logging
import signal
import threading

import pytest
from support import wait_until
from support.cli import run
from support.remote import address_of, start_scart, stop_process

import numpy as np

from dataflow import Array, ConnPolicy, Deployer, FlowStatus, InputPort, OutputPort, TaskContext
from dataflow.remote import RemoteError, connect
from dataflow.transports.limits import MAX_FRAME_BYTES

pytestmark = pytest.mark.integration

HD = 6_220_800  # one 1080p RGB frame
UHD = 24_883_200  # one 4K RGB frame


class Camera(TaskContext):
    video = OutputPort(bytes)


class Screen(TaskContext):
    video = InputPort(bytes)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list[bytes] = []
        self.lock = threading.Lock()
        self.video.add_data_callback(self._take)

    def _take(self, port: InputPort) -> None:
        for _ in range(1000):
            flow, value = port.read()
            if flow is not FlowStatus.NEW_DATA:
                return
            with self.lock:
                self.got.append(value[:1] + len(value).to_bytes(8, "little"))  # what it was, not the bytes

    def seen(self) -> list[tuple[int, int]]:
        with self.lock:
            return [(g[0], int.from_bytes(g[1:], "little")) for g in self.got]


@contextlib.contextmanager
def serving():
    d1, d2 = Deployer(), Deployer()
    camera = d1.add(Camera("camera"))
    screen = d2.add(Screen("screen"))
    s1 = d1.serve("127.0.0.1:0")
    s2 = d2.serve("127.0.0.1:0", ns=s1.address)
    try:
        with connect(s1.address, timeout=5.0) as system:
            yield system, camera, screen
    finally:
        s2.stop()
        s1.stop()


def _link(system, name: str = "l"):
    return next(lk for lk in system.links() if lk.name == name)


@pytest.mark.parametrize("transport", ["ipc", "grpc"])
def test_camera_frames_cross_every_transport_and_one_too_large_is_refused_at_write(transport, caplog) -> None:
    caplog.set_level(logging.WARNING, logger="dataflow.transports.ends")
    with serving() as (system, camera, screen):
        system.connect_ports("camera.video", "screen.video", ConnPolicy.buffer(4).with_(transport=transport), name="l")
        wait_until(lambda: _link(system).transport == transport, timeout=10)
        sent = []
        for k, size in enumerate([HD, HD, UHD, HD], start=1):
            assert camera.video.write(bytes([k]) + bytes(size - 1)).name == "WRITE_SUCCESS"
            sent.append((k, size))
            wait_until(lambda: len(screen.seen()) == k, timeout=20, message=f"{_link(system)}")  # at a camera's pace
        assert screen.seen() == sent

        status = camera.video.write(bytes(MAX_FRAME_BYTES))  # over 64 MiB and its frame
        assert status.name == "WRITE_FAILURE"
        assert camera.video.write(bytes([9]) + bytes(HD - 1)).name == "WRITE_SUCCESS"
        wait_until(lambda: len(screen.seen()) == 5 and _link(system).dropped == 1, timeout=20,
                   message=f"{screen.seen()[-1:]}, {_link(system)}")
        assert _link(system).samples == len(screen.seen()) + _link(system).dropped  # written = delivered + dropped
        said = [r.getMessage() for r in caplog.records if "limit" in r.getMessage()]
        assert len(said) == 1 and f"limit of {MAX_FRAME_BYTES} bytes" in said[0] and "link l" in said[0], said


def test_camera_frames_on_a_zenoh_stream_are_delivered_or_counted(tmp_path) -> None:
    zenoh = pytest.importorskip("dataflow.transports.zenoh")
    pytest.importorskip("zenoh")
    a = zenoh.open_session(listen=[f"unixsock-stream/{tmp_path}/a.sock"])
    b = zenoh.open_session(connect=[f"unixsock-stream/{tmp_path}/a.sock"])
    writer, reader = Deployer(), Deployer()
    camera = writer.add(Camera("camera"))
    screen = reader.add(Screen("screen"))
    try:
        zenoh.use_session(a)
        out = writer.stream("camera.video", ConnPolicy.data().with_(transport="zenoh", topic="lab/frames"))
        zenoh.use_session(b)
        reader.stream("screen.video", ConnPolicy.buffer(4).with_(transport="zenoh", topic="lab/frames"), name="in")
        zenoh.use_session(None)
        wait_until(lambda: camera.video.write(b"\x00") and screen.seen(), timeout=15, message="Zenoh never matched")
        for k in (1, 2, 3):
            camera.video.write(bytes([k]) + bytes(UHD - 1))
            wait_until(lambda: screen.seen()[-1] == (k, UHD), timeout=20, message=f"{screen.seen()[-1:]}")
        assert [s for s in screen.seen() if s[1] == UHD] == [(1, UHD), (2, UHD), (3, UHD)]
        assert camera.video.write(bytes(MAX_FRAME_BYTES)).name == "WRITE_FAILURE"
        assert next(lk for lk in writer.links() if lk.name == out.name).dropped == 1  # refused there, and counted
    finally:
        zenoh.use_session(None)
        for d, name in ((reader, "in"), (writer, "camera.video~zenoh:lab/frames")):
            with contextlib.suppress(Exception):
                d.unstream(name)
        b.close()
        a.close()


@pytest.mark.subprocess
def test_a_1080p_camera_in_one_process_feeds_a_screen_in_another_through_scart_connect() -> None:
    """The case that said "connected, 0 dropped" and delivered nothing: two ``scart deploy``
    processes, a camera at 30 Hz, ``scart connect`` with the default transport."""
    camera, line = start_scart(["deploy", "support.remote:Camera", "--name", "camera", "--period", "0.033"])
    address = address_of(line)
    screen = None
    try:
        screen, _ = start_scart(["deploy", "support.remote:Screen", "--name", "screen", "--ns", address])
        result = run("connect", "camera.video", "screen.video", "--ns", address)
        assert result.returncode == 0 and "connected" in result.stdout, result.stdout + result.stderr
        with connect(address, timeout=5.0) as system:
            far = system.component("screen")
            wait_until(lambda: far.call("seen") >= 10, timeout=20, message=f"{system.links()}")
            assert far.call("last_size") == HD
        links = run("links", "--json", "--ns", address)
        (link,) = json.loads(links.stdout)
        assert link["transport"] in ("ipc", "shm") and link["state"] == "connected"
        assert link["rate"] > 5, link  # frames at the camera's pace
    finally:
        if screen is not None:
            stop_process(screen, signal.SIGKILL)
        stop_process(camera, signal.SIGKILL)


IMAGE = Array[np.uint8, (1080, 1920, 3)]
HUGE = Array[np.uint8, (8192, 8192, 3)]  # 201 MB a sample: over every transport's limit


class Eye(TaskContext):
    image = OutputPort(IMAGE)
    huge = OutputPort(HUGE)


class Viewer(TaskContext):
    image = InputPort(IMAGE)
    huge = InputPort(HUGE)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.got: list = []
        self.image.add_data_callback(lambda port: self.got.append(port.read()[1]))


@pytest.mark.parametrize("transport", ["ipc", "grpc"])
def test_an_image_port_crosses_processes_as_a_read_only_array_and_a_type_too_large_is_refused_at_connect(
        transport) -> None:
    d1, d2 = Deployer(), Deployer()
    eye = d1.add(Eye("eye"))
    viewer = d2.add(Viewer("viewer"))
    s1 = d1.serve("127.0.0.1:0")
    s2 = d2.serve("127.0.0.1:0", ns=s1.address)
    try:
        with connect(s1.address, timeout=5.0) as system:
            system.connect_ports("eye.image", "viewer.image", ConnPolicy.buffer(2).with_(transport=transport))
            frame = np.random.default_rng(7).integers(0, 255, (1080, 1920, 3), dtype=np.uint8)
            wait_until(lambda: eye.image.write(frame).name == "WRITE_SUCCESS" and viewer.got, timeout=10)
            got = viewer.got[-1]
            assert got.shape == (1080, 1920, 3) and got.dtype == np.uint8 and np.array_equal(got, frame)
            assert not got.flags.writeable  # a view of what was received: read-only
            with pytest.raises(RemoteError, match=r"eye.huge \(ndarray<uint8>\[8192,8192,3\]\) cannot cross "
                                                      r"processes .*201326617 bytes, over the transports' limit"):
                system.connect_ports("eye.huge", "viewer.huge", ConnPolicy.data().with_(transport=transport))
            assert [lk.sink for lk in system.links()] == ["viewer.image"]  # nothing linked
            with pytest.raises(Exception, match=r"eye.huge .*cannot cross processes \(a subscription\)"):
                system.component("eye").subscribe("huge", lambda e: None, ConnPolicy.data().with_(transport=transport))
    finally:
        s2.stop()
        s1.stop()
