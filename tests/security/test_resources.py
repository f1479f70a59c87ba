"""Bounded resources: idle streams cannot starve health checks and lookups, streams are
budgeted per server and per peer, and a client stream that never speaks is cancelled.
Real servers on 127.0.0.1:0; every wait has a deadline."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import grpc
import pytest

from dataflow import Deployer
from dataflow.remote import _rpc
from dataflow.remote._proto import df as pb
from dataflow.remote._proto import df_grpc
from dataflow.remote.naming import NameClient
from support import wait_until
from support.remote import Pinger


def _silent(stop: threading.Event) -> Iterator[object]:
    """A request stream that never sends its first message (until ``stop``)."""
    stop.wait(30)
    return
    yield  # a generator


def test_idle_streams_cannot_starve_health_and_lookups(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(_rpc, "FIRST_MESSAGE_S", 1.0)
    deployer = Deployer()
    deployer.add(Pinger("p"))
    server = deployer.serve("127.0.0.1:0", max_workers=16)  # 8 streams at most, 8 workers kept
    stop = threading.Event()
    calls = []
    channel = grpc.insecure_channel(server.address)
    names = NameClient(server.address, timeout=2.0)
    try:
        stub = df_grpc.DeployerServiceStub(channel)
        calls = [stub.WritePortStream.future(_silent(stop)) for _ in range(40)]
        wait_until(lambda: sum(1 for c in calls if c.done() and c.code() == grpc.StatusCode.RESOURCE_EXHAUSTED) >= 32,
                   timeout=10, message="streams beyond the budget were not refused")
        for _ in range(20):  # health and lookups still answer, promptly, while 8 streams sit idle
            start = time.monotonic()
            assert _rpc.health_ok(server.address, timeout=1.0)
            assert names.resolve("p").address == server.address
            assert time.monotonic() - start < 0.5
        # a stream that never sends its first message is cancelled: the idle ones go
        wait_until(lambda: all(c.done() for c in calls), timeout=10, message="silent streams were never cancelled")
        with pytest.raises(grpc.RpcError):
            calls[0].result()
        assert stub.ListTasks(pb.ListTasksRequest(), timeout=2).tasks[0].name == "p"
    finally:
        stop.set()
        for call in calls:
            call.cancel()
        names.close()
        channel.close()
        server.stop()


def test_one_peer_cannot_take_every_stream() -> None:
    budget = _rpc.StreamBudget(total=8, per_peer=6)
    assert [budget._take("a") for _ in range(6)] == [None] * 6
    assert budget._take("a") == "at most 6 streams from one peer"
    assert budget._take("b") is None and budget._take("b") is None
    assert budget._take("c") == "this server carries at most 8 streams at once"
    budget._give("a")
    assert budget._take("c") is None and budget.open == 8
