"""``scart foxglove`` against the real youBot driver, with a real WebSocket client speaking
the published Foxglove protocol: the channel is advertised with a JSON Schema, a
subscription gets messages, a parameter (a task property) is read and set."""

from __future__ import annotations

import asyncio
import json
import re
import struct
import subprocess
import sys

import websockets

from support.cli import read_until
from support.youbot import env, start_serving

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


async def conversation(url: str) -> dict:
    """Connect, read the advertisement, subscribe, get and set parameters; what was seen."""
    seen: dict = {}
    async with websockets.connect(url, subprotocols=SUBPROTOCOLS, open_timeout=10) as ws:
        for _ in range(20):  # serverInfo, then the advertisement
            message = json.loads(await asyncio.wait_for(ws.recv(), 10))
            if message["op"] == "serverInfo":
                seen["capabilities"] = message.get("capabilities", [])
            if message["op"] == "advertise":
                seen["channels"] = {c["topic"]: c for c in message["channels"]}
                break
        channel = seen["channels"]["youBotDriver.jointStatus"]
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 7, "channelId": channel["id"]}]}))
        await ws.send(json.dumps({"op": "setParameters", "id": "s", "parameters": [
            {"name": "youBotDriver.noise", "value": 0.0}]}))
        await ws.send(json.dumps({"op": "getParameters", "id": "g", "parameterNames": ["youBotDriver.noise"]}))
        for _ in range(500):
            message = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(message, bytes) and message[0] == 1:  # opcode 1: message data
                subscription, _stamp = struct.unpack_from("<IQ", message, 1)
                seen.setdefault("messages", []).append((subscription, json.loads(message[13:])))
            elif isinstance(message, str) and json.loads(message)["op"] == "parameterValues":
                reply = json.loads(message)
                seen[reply.get("id")] = {p["name"]: p.get("value") for p in reply["parameters"]}
            if seen.get("messages") and "g" in seen:
                break
    return seen


def test_the_driver_live_in_the_foxglove_protocol() -> None:
    demo = start_serving("robot.composite")
    proc = subprocess.Popen([sys.executable, "-m", "scart", "foxglove", "--port", "0", "--ns", demo.ns,
                             "--duration", "60"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env(), bufsize=0)
    try:
        url = re.search(r"ws://\S+", read_until(proc, "Foxglove at"))[0]  # type: ignore[index]
        seen = asyncio.run(conversation(url))
    finally:
        proc.terminate()
        proc.communicate(timeout=30)
        assert demo.stop() == 0
    assert "parameters" in seen["capabilities"]
    channel = seen["channels"]["youBotDriver.jointStatus"]
    assert channel["encoding"] == "json" and channel["schemaName"] == "YouBotStatus"
    assert "joints" in json.loads(channel["schema"])["properties"]  # plots per joint in the app
    subscription, sample = seen["messages"][0]
    assert subscription == 7 and len(sample["joints"]) == 5 and "position" in sample["joints"][0]
    assert seen["g"] == {"youBotDriver.noise": 0.0}
