"""An image port through the user's tools: ``scart echo`` prints what it is (shape, element
type, mean), not its bytes; ``scart record`` keeps it as a ``foxglove.RawImage`` that
``scart play`` writes back into an image port; ``scart foxglove`` shows it as one, for the
app's image panel."""

from __future__ import annotations

import asyncio
import base64
import json
import re
import signal
import subprocess
import sys

import pytest
import websockets
from support import wait_until
from support.cli import finish, read_until, run
from support.remote import address_of, start_scart, stop_process, subprocess_env

from dataflow.remote import connect

pytestmark = [pytest.mark.integration, pytest.mark.subprocess]


@pytest.fixture
def eye():
    proc, line = start_scart(["deploy", "support.remote:EyeCam", "--name", "eye", "--period", "0.1",
                              "--listen", "127.0.0.1:0"])
    try:
        yield address_of(line)
    finally:
        stop_process(proc, signal.SIGKILL)


def test_echo_of_an_image_port_prints_its_shape_type_and_mean(eye) -> None:
    result = run("echo", "eye.image", "--once", "--json", "--ns", eye)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert summary["shape"] == [480, 640, 3] and summary["dtype"] == "uint8"
    assert summary["min"] == summary["max"] == summary["mean"]  # a frame is one value throughout
    assert len(result.stdout) < 500  # a summary, not 921 600 numbers


def test_record_keeps_an_image_as_a_raw_image_and_play_writes_it_back(eye, tmp_path) -> None:
    from mcap.reader import make_reader

    out = tmp_path / "images.mcap"
    result = run("record", "eye.image", "-o", str(out), "-n", "3", "--ns", eye)
    assert result.returncode == 0, result.stderr
    with open(out, "rb") as f:
        records = list(make_reader(f).iter_messages())
    assert len(records) == 3
    schema, _, message = records[0]
    assert schema.name == "foxglove.RawImage"  # what the app's image panel shows
    image = json.loads(message.data)
    assert (image["width"], image["height"], image["encoding"], image["step"]) == (640, 480, "rgb8", 1920)
    assert len(base64.b64decode(image["data"])) == 640 * 480 * 3
    firsts = [base64.b64decode(json.loads(m.data)["data"])[0] for _, _, m in records]

    album, _ = start_scart(["deploy", "support.remote:Album", "--name", "album", "--ns", eye])
    try:
        result = run("play", str(out), "--rate", "5", "--remap", "eye.image:=album.image", "--ns", eye)
        assert result.returncode == 0, result.stderr
        with connect(eye, timeout=5.0) as system:
            kept = wait_until(lambda: system.component("album").call("firsts"), timeout=10)
        assert kept == firsts  # the same images, whole, in order
    finally:
        stop_process(album, signal.SIGKILL)


def test_a_recorded_1080p_frame_is_played_back_whole_over_the_data_plane(tmp_path) -> None:
    """A 6.2 MB frame is 8.3 MB of JSON in the file, over the control plane's 4 MiB: play
    writes such a port's samples through a link of its own (shm on one host)."""
    cam, line = start_scart(["deploy", "support.remote:HdCam", "--name", "hdcam", "--period", "0.2",
                             "--listen", "127.0.0.1:0"])
    album = None
    try:
        ns = address_of(line)
        out = tmp_path / "hd.mcap"
        result = run("record", "hdcam.image", "-o", str(out), "-n", "2", "--ns", ns)
        assert result.returncode == 0, result.stderr
        album, _ = start_scart(["deploy", "support.remote:HdAlbum", "--name", "album", "--ns", ns])
        result = run("play", str(out), "--rate", "5", "--remap", "hdcam.image:=album.image", "--ns", ns)
        assert result.returncode == 0, result.stderr
        assert "played 2 sample(s)" in result.stdout, result.stdout
        with connect(ns, timeout=5.0) as system:
            kept = wait_until(lambda: system.component("album").call("firsts"), timeout=10)
            assert len(kept) == 2 and kept[1] == (kept[0] + 1) % 256  # two whole frames, in order
            assert not [lk for lk in system.links() if lk.sink == "album.image"]  # play's link went with it
    finally:
        for proc in (album, cam):
            if proc is not None:
                stop_process(proc, signal.SIGKILL)


def test_foxglove_shows_an_image_port_as_a_raw_image(eye) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "scart", "foxglove", "--port", "0", "--ns", eye, "--duration", "60"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=subprocess_env(), bufsize=0)
    try:
        url = re.search(r"ws://\S+", read_until(proc, "Foxglove at"))[0]  # type: ignore[index]
        channel, image = asyncio.run(_first_image(url, "eye.image"))
    finally:
        proc.terminate()
        finish(proc)
    assert channel["schemaName"] == "foxglove.RawImage" and channel["encoding"] == "json"
    assert (image["width"], image["height"], image["encoding"]) == (640, 480, "rgb8")
    assert len(base64.b64decode(image["data"])) == 640 * 480 * 3


async def _first_image(url: str, topic: str) -> tuple[dict, dict]:
    async with websockets.connect(url, subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"], open_timeout=10,
                                  max_size=16 << 20) as ws:
        channel = None
        for _ in range(20):
            message = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if message["op"] == "advertise":
                channel = next((c for c in message["channels"] if c["topic"] == topic), None)
                if channel is not None:
                    break
        assert channel is not None, f"{topic} was not advertised"
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel["id"]}]}))
        for _ in range(100):
            message = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(message, bytes) and message[0] == 1:  # opcode 1: message data
                return channel, json.loads(message[13:])
    raise AssertionError("no image came")
