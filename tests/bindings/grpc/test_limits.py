"""binding.grpc at its limits: caps on open streams in total and per peer (unary calls
still answer), a deadline on a session's first message, calls that
time out while queued never run, bindings on services promoted out of nested composites,
a provider stop bounded by the drain deadline, results the client cannot convert."""

from __future__ import annotations

import queue
from pathlib import Path

import grpc
import pytest

from scart.bindings.grpc import _server as _grpc_server
from scart_wire.codec import Value
from scart.bindings.grpc._wire import PATHS, pb
from scart.errors import InvocationError
from support.grpc_binding import gpy, grpc_bindings, grpc_reference, grpc_service, provider_and_client

GEOMETRY = f'<component name="G">{gpy("GeometryImpl")}<service name="Geometry">{grpc_service()}</service></component>'
DESK = f'<component name="D">{gpy("DeskImpl")}<service name="Desk">{grpc_service()}</service></component>'


def asker(addr: str) -> str:
    return f'<component name="K">{gpy("Asker")}<reference name="desk">{grpc_reference(addr, "D/Desk")}</reference></component>'


def _open_session(channel: grpc.Channel, sid: str) -> tuple[queue.SimpleQueue, object]:
    stub = channel.stream_stream(PATHS["OpenCallbackSession"],
                                 request_serializer=pb.OpenCallbackSessionRequest.SerializeToString,
                                 response_deserializer=pb.OpenCallbackSessionResponse.FromString)
    outbox: queue.SimpleQueue = queue.SimpleQueue()
    outbox.put(pb.OpenCallbackSessionRequest(session_id=sid))

    def requests():
        while (item := outbox.get()) is not None:
            yield item
    return outbox, stub(requests(), timeout=20)


def test_open_streams_beyond_the_caps_are_refused_and_unary_calls_still_answer(tmp_path: Path) -> None:
    cap, per_peer = _grpc_server.MAX_STREAMS, _grpc_server.MAX_STREAMS_PER_PEER
    assert per_peer < cap < _grpc_server.MAX_WORKERS
    with provider_and_client(tmp_path, DESK + GEOMETRY, asker) as (provider, client):
        address = grpc_bindings(provider)[0].address
        # two connections: on loopback each is a peer of its own
        with grpc.insecure_channel(address) as one, \
                grpc.insecure_channel(address, options=[("grpc.use_local_subchannel_pool", 1)]) as two:
            calls = []

            def refused(channel: grpc.Channel, sid: str) -> str:
                outbox, extra = _open_session(channel, sid)
                calls.append((outbox, extra))
                with pytest.raises(grpc.RpcError) as info:
                    next(extra)
                assert info.value.code() == grpc.StatusCode.RESOURCE_EXHAUSTED
                return info.value.details()
            try:
                for i in range(cap):  # each session holds a server thread for its life
                    outbox, call = _open_session(one if i < per_peer else two, f"s{i}")
                    calls.append((outbox, call))
                    assert next(call).opened  # bounded by the call's deadline
                    if i == per_peer - 1:  # one peer has its share: the next from it is refused
                        assert refused(one, "greedy") == \
                            f"too many callback streams: at most {per_peer} streams from one peer"
                assert refused(two, "extra") == \
                    f"too many callback streams: this server carries at most {cap} streams at once"
                # a plain unary call still answers
                stub = one.unary_unary(PATHS["ListServices"],
                                       request_serializer=pb.ListServicesRequest.SerializeToString,
                                       response_deserializer=pb.ListServicesResponse.FromString)
                assert len(stub(pb.ListServicesRequest(), timeout=5).services) == 2
                # a client's callback call is refused with a clear error
                with pytest.raises(InvocationError, match="too many callback streams"):
                    client.service("K").ask("q")
            finally:
                for outbox, call in calls:
                    outbox.put(None)
                    call.cancel()
        # the slots come back: a callback call works again
        from support import wait_until

        def works() -> bool:
            try:
                return client.service("K").ask("q") == "q: True False"
            except InvocationError:
                return False
        wait_until(works, timeout=10, interval=0.05)


def test_a_session_that_never_says_its_id_is_cancelled(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from scart_wire import rpc
    monkeypatch.setattr(rpc, "FIRST_MESSAGE_S", 0.5)
    with provider_and_client(tmp_path, DESK + GEOMETRY, asker) as (provider, client):
        address = grpc_bindings(provider)[0].address
        with grpc.insecure_channel(address) as channel:
            stub = channel.stream_stream(PATHS["OpenCallbackSession"],
                                         request_serializer=pb.OpenCallbackSessionRequest.SerializeToString,
                                         response_deserializer=pb.OpenCallbackSessionResponse.FromString)
            silent: queue.SimpleQueue = queue.SimpleQueue()
            call = stub(iter(silent.get, None), timeout=20)  # opens the stream, never sends
            try:
                with pytest.raises(grpc.RpcError) as info:
                    next(call)
                assert info.value.code() == grpc.StatusCode.CANCELLED
            finally:
                silent.put(None)
                call.cancel()
        assert client.service("K").ask("q") == "q: True False"  # the server still serves


def test_a_call_that_timed_out_while_queued_never_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                       caplog: pytest.LogCaptureFixture) -> None:
    import logging

    from support import wait_until
    from support.grpc_binding import instance
    monkeypatch.setattr(_grpc_server, "INVOKE_WORKERS", 1)
    caplog.set_level(logging.WARNING, logger="scart.bindings.grpc")

    def client(addr: str) -> str:
        ref = grpc_reference(addr, "D/Desk", timeout=0.5)
        return f'<component name="K">{gpy("Asker")}<reference name="desk">{ref}</reference></component>'
    with provider_and_client(tmp_path, DESK, client) as (provider, rt):
        address = grpc_bindings(provider)[0].address
        with grpc.insecure_channel(address) as channel:
            stub = channel.unary_stream(PATHS["Invoke"], request_serializer=pb.InvokeRequest.SerializeToString,
                                        response_deserializer=pb.InvokeResponse.FromString)
            req = pb.InvokeRequest(call_id="blocker")
            req.invocation.service, req.invocation.operation = "D/Desk", "decide"
            from scart.bindings.grpc._wire import fill_invocation
            fill_invocation(req.invocation, ("hold",), {})
            blocker = stub(req, timeout=20)
            assert next(blocker).HasField("callback_call")  # the only Invoke worker is busy now
            with pytest.raises(InvocationError, match=r"no answer within 0.5 s \(the operation may have run\)"):
                rt.service("K").ask("late")
            blocker.cancel()  # frees the worker: the queued call must not run now
            wait_until(lambda: "cancelled before start" in caplog.text, timeout=10)
        assert instance(rt, "K").questions == []
        assert "late" not in str(instance(provider, "D").callers)


@pytest.mark.parametrize("where", ["inner", "outer"])
def test_binding_on_a_service_promoted_out_of_a_nested_composite_is_served(tmp_path: Path, where: str) -> None:
    from support.grpc_binding import composite, gwrite, instance
    inner_binding = grpc_service() if where == "inner" else ""
    inner = composite(f'''<service name="Front" promote="D/Desk">{inner_binding}</service>
        <component name="D">{gpy("DeskImpl")}</component>''', name="Inner")
    gwrite(tmp_path, {"inner.composite": inner})
    outer_service = f'<service name="Front">{grpc_service()}</service>' if where == "outer" else ""
    provider = f'<component name="Outer"><implementation.composite name="t:Inner"/>{outer_service}</component>'

    def client(addr: str) -> str:
        ref = grpc_reference(addr, "Outer/Front")
        return f'<component name="K">{gpy("Asker")}<reference name="desk">{ref}</reference></component>'
    with provider_and_client(tmp_path, provider, client) as (provider_rt, rt):
        names = grpc_bindings(provider_rt)[0].names
        assert "Outer/D/Desk" in names and "Outer/Front" in names
        assert rt.service("K").ask("n") == "n: True False"
        assert instance(rt, "K").questions == ["n?", "n??"]


HOLD = '''
import threading
from typing import Protocol

import scart

STARTED = threading.Event()
RELEASE = threading.Event()


class Hold(Protocol):
    def hold(self) -> str: ...


@scart.component(services=[Hold])
class HoldImpl:
    def hold(self) -> str:
        STARTED.set()
        RELEASE.wait(20)
        return "released"
'''


def test_provider_stop_is_bounded_by_the_drain_deadline(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    import logging
    import sys
    import time

    import scart
    from support.grpc_binding import composite, gwrite
    caplog.set_level(logging.WARNING, logger="scart.bindings.grpc")
    (tmp_path / "rv5hold.py").write_text(HOLD)
    body = ('<component name="H"><scart:implementation.python class="rv5hold:HoldImpl"/>'
            f'<service name="Hold">{grpc_service()}</service></component>')
    path = gwrite(tmp_path, {"hold.composite": composite(body, name="HoldP")})
    provider = scart.Runtime.from_file(str(path), drain_timeout=0.5)
    provider.start()
    mod = sys.modules.get("rv5hold")
    try:
        address = grpc_bindings(provider)[0].address
        mod = sys.modules["rv5hold"]
        with grpc.insecure_channel(address) as channel:
            stub = channel.unary_unary(PATHS["Call"], request_serializer=pb.CallRequest.SerializeToString,
                                       response_deserializer=pb.CallResponse.FromString)
            req = pb.CallRequest()
            req.invocation.service, req.invocation.operation = "H/Hold", "hold"
            future = stub.future(req, timeout=20)
            assert mod.STARTED.wait(10)
            began = time.monotonic()
            provider.stop()
            took = time.monotonic() - began
            assert took < 3.0, f"stop took {took:.1f} s with a drain deadline of 0.5 s"
            assert "1 call(s) still running after 0.5 s abandoned: H/Hold.hold" in caplog.text
            with pytest.raises(grpc.RpcError):
                future.result(timeout=10)
    finally:
        if mod is not None:
            mod.RELEASE.set()
        provider.stop()


def test_a_result_the_client_cannot_convert_names_service_and_operation(tmp_path: Path) -> None:
    from concurrent.futures import ThreadPoolExecutor

    import scart
    from scart.bindings.grpc._wire import decode
    from support.grpc_binding import composite, gwrite, instance

    with pytest.raises(InvocationError, match="malformed value: cannot decode float64"):
        decode(Value(type_name="float64[]", data=b"\0" * 12))

    def call(request, context):  # a provider answering with a malformed float64[] payload
        return pb.CallResponse(outcome=pb.Outcome(value=Value(type_name="float64[]", data=b"\0" * 12)))
    handler = grpc.method_handlers_generic_handler("scart.sca.v1.ScaService", {
        "Call": grpc.unary_unary_rpc_method_handler(call, pb.CallRequest.FromString, pb.CallResponse.SerializeToString)})
    pool = ThreadPoolExecutor(2)
    server = grpc.server(pool)
    server.add_generic_rpc_handlers((handler,))
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        body = (f'<component name="C">{gpy("GeometryClient")}<reference name="geo">'
                f'{grpc_reference(f"127.0.0.1:{port}", "G/Geometry")}</reference></component>')
        with scart.Runtime.from_file(str(gwrite(tmp_path, {"c.composite": composite(body)}))) as rt:
            with pytest.raises(InvocationError, match=r"G/Geometry at 127\.0\.0\.1:\d+: scale: cannot convert") as info:
                instance(rt, "C").geo.scale([1.0], 2.0)
            assert "cannot decode float64[]" in str(info.value)
    finally:
        server.stop(None).wait(5)
        pool.shutdown(wait=True)
