"""Operation arguments are checked in one place. One bounded operation
(``set_gain(x: Annotated[float, Field(ge=0, le=1)])``, on a task and on an SCA Python
component) is called with values out of its bounds or of the wrong type through every
entry — the data-flow path, the services endpoint (``scart call --at``), Foxglove, and a
``binding.grpc`` reference — and each entry gives the same refusal, and nothing reaches
the operation.

The probe of the issue: the services endpoint handed 5, NaN, inf, ``"0.5"`` and ``true``
to a task's bounded operation that the data-flow path refused."""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import struct
import sys
from pathlib import Path

import pytest
import websockets

import scart
from scart.commands._sca import call as services_call
from dataflow.remote import connect
from support import ROOT
from support.sca import composite
from support.youbot import start_serving

DATA = ROOT / "tests" / "data" / "security"
sys.path.insert(0, str(DATA))

BAD = [(5, "Input should be less than or equal to 1"), (math.nan, "Input should be less than or equal to 1"),
       (math.inf, "Input should be less than or equal to 1"), ("0.5", "Input should be a valid number"),
       (True, "Input should be a valid number")]


def refusal(value: object, reason: str) -> str:
    """What every entry says, whoever asks (each adds where it was called)."""
    return f"set_gain(x): {value!r} refused: {reason}"


def through_foxglove(url: str, values: list[object]) -> dict[int, str]:
    """Call the task's operation as a Foxglove service, once per value; the answers by call id."""
    async def talk() -> dict[int, str]:
        answers: dict[int, str] = {}
        async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
            services: dict[str, int] = {}
            while "probe.set_gain" not in services:
                message = json.loads(await asyncio.wait_for(ws.recv(), 10))
                if message["op"] == "advertiseServices":
                    services.update({s["name"]: s["id"] for s in message["services"]})
            for call, value in enumerate(values):
                body = json.dumps({"x": value}).encode()
                await ws.send(struct.pack("<BIII", 2, services["probe.set_gain"], call, 4) + b"json" + body)
            while len(answers) < len(values):
                message = await asyncio.wait_for(ws.recv(), 10)
                if isinstance(message, str) and json.loads(message)["op"] == "serviceCallFailure":
                    answers[json.loads(message)["callId"]] = json.loads(message)["message"]
                elif isinstance(message, bytes) and message[0] == 3:
                    _service, call, size = struct.unpack_from("<III", message, 1)
                    answers[call] = "answered " + message[13 + size:].decode()
        return answers
    return asyncio.run(talk())


@pytest.mark.timeout(240)
def test_one_bounded_operation_gets_the_same_refusal_from_every_entry(tmp_path: Path) -> None:
    demo = start_serving(str(DATA / "bounded.composite"), "--foxglove", "0", "--foxglove-control")
    try:
        services = demo.wait_line(r"SCA services at (\S+)")[1]
        url = demo.wait_line(r"scart: Foxglove at (ws://\S+)")[1]
        seen: dict[str, list[str]] = {}
        with connect(demo.ns) as system:  # the data-flow path (scart call COMP.op, Python clients)
            task = system.component("probe")
            for value, _ in BAD:
                with pytest.raises(Exception) as refused:
                    task.call("set_gain", value)
                seen.setdefault("data-flow", []).append(str(refused.value))
            args = argparse.Namespace(timeout=10.0)
            for target in ("probe/BoundedTask.set_gain", "Gain/Gaining.set_gain"):  # the services endpoint
                for value, _ in BAD:
                    with pytest.raises(Exception) as refused:
                        services_call(services, target, [value], args)
                    seen.setdefault(target, []).append(str(refused.value))
            answers = through_foxglove(url, [v for v, _ in BAD])
            seen["foxglove"] = [answers[i] for i in range(len(BAD))]
            seen["binding.grpc reference"] = grpc_reference_calls(tmp_path, services, [v for v, _ in BAD])
            assert task.call("set_gain", 0.25) == 0.25  # in bounds: through
            assert task.get_property("received") == "0.25"  # nothing refused ever reached the task
        assert json.loads(json.dumps(services_call(services, "Gain/Gaining.received", [], args))) == []
    finally:
        assert demo.stop() == 0
    assert len(seen) == 5  # data-flow, the services endpoint (task, component), Foxglove, a reference
    for entry, messages in seen.items():
        for (value, reason), message in zip(BAD, messages, strict=True):
            assert refusal(value, reason) in message, (entry, message)


def grpc_reference_calls(folder: Path, address: str, values: list[object]) -> list[str]:
    """``set_gain`` of the task's service called through a ``binding.grpc`` reference of an
    SCA Python client (in this process), once per value: the refusals."""
    client = folder / "client.composite"
    client.write_text(composite(f"""
        <component name="Caller">
            <scart:implementation.python class="bounded:Caller"/>
            <reference name="gain">
                <scart:binding.grpc address="{address}" service="probe/BoundedTask" timeout="10"/>
            </reference>
        </component>
    """, name="Client"))
    out = []
    with scart.Runtime.from_file(str(client), contributions=[str(DATA)]) as runtime:
        caller = runtime.service("Caller")
        for value in values:
            with pytest.raises(scart.RemoteError) as refused:
                caller.forward(value)
            out.append(str(refused.value))
    return out
