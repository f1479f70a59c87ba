"""Every transport has one shape: it carries links, subscriptions and streams, or says at
registration which it does not, so that a policy naming it for one it lacks is refused
at once, naming the transport and what it lacks (``scart connect --transport ros1``);
and a deployer's sample-path calls go to the serving half of the transport that lists
them, the control plane holding none."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import grpc
import pytest
from support.cli import run

from dataflow import ConnPolicy, Deployer, InputPort, OutputPort, TaskContext
from dataflow.remote import connect
from dataflow.remote._proto import df as pb
from dataflow.remote.server import DeployerServer
from dataflow.transports import CannotCarry, Peer, Transport, load, names, refusal
from dataflow.transports.ends import WriterEnd
from dataflow.transports.grpc._serve import GrpcServing
from dataflow.transports.ipc._tickets import IpcServing


class Counter(TaskContext):
    out = OutputPort(int)


class Collector(TaskContext):
    inp = InputPort(int)


@contextlib.contextmanager
def two_deployers() -> Iterator[tuple[DeployerServer, DeployerServer]]:
    """``src.out`` served by one deployer, ``sink.inp`` by a second joining its name service."""
    d1, d2 = Deployer(), Deployer()
    d1.add(Counter("src"))
    d2.add(Collector("sink"))
    s1 = d1.serve("127.0.0.1:0")
    try:
        s2 = d2.serve("127.0.0.1:0", ns=s1.address)
        try:
            yield s1, s2
        finally:
            s2.stop()
    finally:
        s1.stop()


def test_every_transport_says_what_it_carries() -> None:
    carried = {name: load(name).carries for name in names()}
    assert carried == {"grpc": {"link", "subscription"}, "ipc": {"link", "subscription"},
                       "shm": {"link", "subscription"}, "ros1": {"stream"}, "ros2": {"stream"},
                       "yarp": {"stream"}, "zenoh": {"stream"}}
    assert all(load(name).serving() is None for name, kinds in carried.items() if kinds == {"stream"})
    assert load("ipc").serving() is load("shm").serving() is IpcServing  # one serving half, shared
    assert load("grpc").serving() is GrpcServing


def test_a_class_that_does_not_say_carries_what_it_implements_and_one_that_says_is_taken_at_its_word() -> None:
    class Links(Transport):
        name = "links"

        def link(self, end: WriterEnd, peer: Peer) -> bool:  # never called
            return False

    class Said(Links):
        name = "said"
        carries = frozenset({"stream"})
        topics = True

    assert Links.carries == {"link"} and Said.carries == {"stream"}
    assert Links().lacks("subscription") == ("transport 'links' carries links, not subscriptions; "
                                             "subscriptions need one of: grpc, ipc, shm")
    assert Said().lacks("link").startswith("transport 'said' carries topics, not links")
    assert Links().lacks("link") == ""


def test_refusals_name_the_transport_and_what_it_lacks() -> None:
    assert refusal("auto", "link") is None and refusal("ipc", "subscription") is None
    refused = refusal("ros1", "link")
    assert isinstance(refused, CannotCarry)
    assert str(refused) == "transport 'ros1' carries topics, not links; links need one of: grpc, ipc, shm"
    assert "transport 'grpc' carries links and subscriptions, not topics" in str(refusal("grpc", "stream"))


def test_scart_connect_over_a_transport_without_links_is_refused_naming_it() -> None:
    with two_deployers() as (s1, _):
        result = run("connect", "src.out", "sink.inp", "--transport", "ros1", "--ns", s1.address)
        assert result.returncode == 1
        assert ("link src.out -> sink.inp: transport 'ros1' carries topics, not links; links need one of: "
                "grpc, ipc, shm") in result.stderr
        assert s1.links() == []  # refused before anything was linked
        with connect(s1.address, timeout=5.0) as system:
            with pytest.raises(CannotCarry, match="transport 'zenoh' carries topics, not subscriptions"):
                system.component("src").subscribe("out", lambda _: None,  # type: ignore[attr-defined]
                                                  policy=ConnPolicy.data().with_(transport="zenoh"))


def test_the_control_plane_routes_sample_path_calls_to_the_transport_serving_them() -> None:
    with two_deployers() as (s1, _), connect(s1.address, timeout=5.0) as system:
        channels = s1._servicer.channels  # noqa: SLF001 - which serving halves the deployer made
        assert channels.serving_of(GrpcServing) is None and channels.serving_of(IpcServing) is None
        seen: list[object] = []
        sub = system.component("src").subscribe("out", seen.append, policy=ConnPolicy.data().with_(transport="grpc"))
        try:
            assert sub.transport == "grpc"
            assert channels.serving_of(GrpcServing) is not None  # made by the first Subscribe
            assert channels.serving_of(IpcServing) is None  # no ipc call came: none made
        finally:
            sub.close()
        assert channels.handler("NoSuchMethod") is None
        with grpc.insecure_channel(s1.address) as channel:  # a method no transport serves: UNIMPLEMENTED
            call = channel.unary_unary("/scart.dataflow.v1.DeployerService/NoSuchMethod",
                                       request_serializer=pb.ListTasksRequest.SerializeToString,
                                       response_deserializer=pb.ListTasksResponse.FromString)
            with pytest.raises(grpc.RpcError) as failed:
                call(pb.ListTasksRequest(), timeout=5)
            assert failed.value.code() == grpc.StatusCode.UNIMPLEMENTED


def test_a_plug_in_whose_serving_half_fails_is_passed_over(monkeypatch: pytest.MonkeyPatch,
                                                          caplog: pytest.LogCaptureFixture) -> None:
    from dataflow.remote import _channels

    class Broken(Transport):
        name = "broken-serving"

        def serving(self) -> None:
            raise RuntimeError("a bug in the plug-in")

    monkeypatch.setattr(_channels, "_every_transport", lambda: [Broken(), load("grpc")])
    with two_deployers() as (s1, _):
        channels = s1._servicer.channels  # noqa: SLF001 - the routing table
        assert channels.handler("Subscribe") is not None
        assert channels.serving_of(GrpcServing) is not None
    assert "transport 'broken-serving' cannot serve Subscribe (RuntimeError: a bug in the plug-in)" in caplog.text
