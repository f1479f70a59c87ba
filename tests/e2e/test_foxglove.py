"""``scart foxglove`` against the real youBot driver, with a real WebSocket client speaking
the published Foxglove protocol: the channel is advertised with a JSON Schema, a
subscription gets messages, a parameter (a task property) is read and set, and an
operation is called as a service (its answer, and a refused call's reason)."""

from __future__ import annotations

import asyncio
import json
import re
import struct
import subprocess
import sys

import websockets

from support import ROOT
from support.cli import finish, read_until
from support.youbot import env, start_serving

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


async def conversation(url: str) -> dict:
    """Connect, read the advertisement, subscribe, get and set parameters; what was seen."""
    seen: dict = {}
    async with websockets.connect(url, subprotocols=SUBPROTOCOLS, open_timeout=10) as ws:
        for _ in range(20):  # serverInfo, then the advertisements of channels and services
            message = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if message["op"] == "serverInfo":
                seen["capabilities"] = message.get("capabilities", [])
            if message["op"] == "advertise":
                seen["channels"] = {c["topic"]: c for c in message["channels"]}
            if message["op"] == "advertiseServices":
                seen["services"] = {s["name"]: s for s in message["services"]}
            if "channels" in seen and "services" in seen:
                break
        channel = seen["channels"]["youBotDriver.jointStatus"]
        service = seen["services"]["youBotDriver.error_names"]["id"]
        for call, body in ((1, b'{"joint": 2}'), (2, b'{"joint": 9}'), (3, b'{"jont": 2}')):
            await ws.send(struct.pack("<BIII", 2, service, call, 4) + b"json" + body)  # opcode 2: call request
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel["id"]}]}))
        await ws.send(json.dumps({"op": "setParameters", "id": "s", "parameters": [
            {"name": "youBotDriver.noise", "value": 0.0}]}))
        await ws.send(json.dumps({"op": "getParameters", "id": "g", "parameterNames": ["youBotDriver.noise"]}))
        for _ in range(500):
            message = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(message, bytes) and message[0] == 1:  # opcode 1: message data
                subscription, _stamp = struct.unpack_from("<IQ", message, 1)
                seen.setdefault("messages", []).append((subscription, json.loads(message[13:])))
            elif isinstance(message, bytes) and message[0] == 3:  # opcode 3: call response
                _service, call, size = struct.unpack_from("<III", message, 1)
                seen.setdefault("calls", {})[call] = json.loads(message[13 + size:])
            elif isinstance(message, str) and json.loads(message)["op"] == "parameterValues":
                reply = json.loads(message)
                seen[reply.get("id")] = {p["name"]: p.get("value") for p in reply["parameters"]}
            elif isinstance(message, str) and json.loads(message)["op"] == "serviceCallFailure":
                reply = json.loads(message)
                seen.setdefault("calls", {})[reply["callId"]] = reply["message"]
            if seen.get("messages") and "g" in seen and len(seen.get("calls", {})) == 3:
                break
    return seen


def test_the_driver_live_in_the_foxglove_protocol() -> None:
    demo = start_serving("robot.composite")
    proc = subprocess.Popen([sys.executable, "-m", "scart", "foxglove", "--port", "0", "--ns", demo.ns,
                             "--duration", "60", "--control"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env(), bufsize=0)
    try:
        url = re.search(r"ws://\S+", read_until(proc, "Foxglove at"))[0]  # type: ignore[index]
        seen = asyncio.run(conversation(url))
    finally:
        proc.terminate()
        finish(proc)  # killed if it hangs
        assert demo.stop() == 0
    assert "parameters" in seen["capabilities"]
    channel = seen["channels"]["youBotDriver.jointStatus"]
    assert channel["encoding"] == "json" and channel["schemaName"] == "YouBotStatus"
    assert "joints" in json.loads(channel["schema"])["properties"]  # plots per joint in the app
    subscription, sample = seen["messages"][0]
    assert subscription == 7 and len(sample["joints"]) == 5 and "position" in sample["joints"][0]
    assert seen["g"] == {"youBotDriver.noise": 0.0}
    assert "services" in seen["capabilities"]
    request = json.loads(seen["services"]["youBotDriver.error_names"]["request"]["schema"])
    assert request["properties"]["joint"]["type"] == "integer"
    assert seen["calls"][1] == {"result": []}  # the operation ran on the driver: no error on joint 2
    assert "0..4" in seen["calls"][2]  # the driver's own refusal, as the call's failure
    assert "missing ['joint']" in seen["calls"][3] and "jont" in seen["calls"][3]


def test_scart_run_serves_foxglove_beside_the_composite() -> None:
    """``scart run --foxglove 0``: the same live view, from the running composite itself
    (no second command), stopped with it."""
    demo = start_serving("robot.composite", "--foxglove", "0", "--foxglove-control")
    try:
        url = demo.wait_line(r"scart: Foxglove at (ws://\S+)")[1]
        seen = asyncio.run(conversation(url))
    finally:
        assert demo.stop() == 0
    assert seen["messages"][0][1]["joints"] and seen["g"] == {"youBotDriver.noise": 0.0}
    assert seen["calls"][1] == {"result": []}


def test_scart_run_foxglove_refuses_a_routable_host_without_insecure() -> None:
    proc = subprocess.run([sys.executable, "-m", "scart", "run", "composites/youbot/robot.composite",
                           "--ns", "127.0.0.1:0", "--foxglove", "0.0.0.0:0"],
                          capture_output=True, text=True, env=env(), timeout=60, cwd=ROOT)
    assert proc.returncode == 1
    assert "--foxglove 0.0.0.0:0" in proc.stderr and "no authentication" in proc.stderr
    assert "scart: started" not in proc.stdout  # nothing announced as running
