"""binding.grpc in one process: a provider runtime and a client runtime talking over real
gRPC on 127.0.0.1 — the behaviour matrix of tests/scart/test_spi.py plus what only a
remote binding has (values on the wire, remote errors, deadlines, reconnection)."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

import scart
from scart import RemoteError, ServiceUnavailableError
from scart.errors import InvocationError
from support.grpc_binding import (
    composite, gpy, grpc_bindings, grpc_reference, grpc_service, gwrite, instance, module, provider_and_client, py,
)
from support import free_port, wait_until

WORKER = f'<component name="W">{py("WorkerImpl")}<service name="Worker">{grpc_service()}</service></component>'
GEOMETRY = f'<component name="G">{gpy("GeometryImpl")}<service name="Geometry">{grpc_service()}</service></component>'
DESK = f'<component name="D">{gpy("DeskImpl")}<service name="Desk">{grpc_service()}</service></component>'


def boss(addr: str) -> str:
    return f'<component name="B">{py("Boss")}<reference name="worker">{grpc_reference(addr, "W/Worker")}</reference></component>'


def geo_client(addr: str, service: str = "G/Geometry", timeout: float = 5.0) -> str:
    ref = grpc_reference(addr, service, timeout)
    return f'<component name="C">{gpy("GeometryClient")}<reference name="geo">{ref}</reference></component>'


# --- the shared behaviour matrix (same scenarios as scart/test_spi.py) -----------------


def test_sync_call_and_callback_during_it(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, WORKER, boss) as (_, client):
        assert client.service("B").run_sync(3) == 6
        assert instance(client, "B").received == ["sync 3"]


def test_oneway_returns_before_callee_finishes_and_calls_back_after(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, WORKER, boss) as (_, client):
        gate = module("comps").GATE
        gate.clear()
        try:
            assert client.service("B").run_async(1) is None  # returned while the callee waits on GATE
            b = instance(client, "B")
            assert b.received == []
        finally:
            gate.set()
        assert b.wait_message(10)[0].startswith("async 1 on scart-oneway")


def test_calculator_style_chain(tmp_path: Path) -> None:
    provider = f'''<component name="A">{py("GreeterImpl")}<property name="greeting">Yo</property>
        <service name="Greeter">{grpc_service()}</service></component>'''

    def client(addr: str) -> str:
        return f'<component name="S">{py("Single")}<reference name="one">{grpc_reference(addr, "A/Greeter")}</reference></component>'
    with provider_and_client(tmp_path, provider, client) as (_, rt):
        assert rt.service("S").call("x") == "Yo, x"


# --- values ---------------------------------------------------------------------------------


def test_models_lists_dicts_and_none_cross_by_value(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, GEOMETRY, geo_client) as (_, client):
        g = module("gcomps")
        geo = instance(client, "C").geo
        c = geo.centroid([g.Point(x=0, y=0), g.Point(x=2, y=4)])
        assert isinstance(c, g.Point) and (c.x, c.y) == (1.0, 2.0)
        assert geo.scale([1.0, 2.5], 2) == [2.0, 5.0]
        assert geo.scale([], 3.0) == []
        assert geo.tags(["a", "b"], {"k": [1, 2]}) == {"names": ["a", "b"], "meta": {"k": [1, 2]}, "n": 2}
        assert geo.tags(names=["z"], meta={}) == {"names": ["z"], "meta": {}, "n": 1}
        assert geo.nothing() is None


def test_remote_error_carries_type_and_message(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, GEOMETRY, geo_client) as (_, client):
        with pytest.raises(RemoteError) as info:
            instance(client, "C").geo.fail("not today")
        err = info.value
        assert isinstance(err, InvocationError) and isinstance(err, scart.ScartError)
        assert err.remote_type == "gcomps.Rejected" and err.remote_message == "not today"
        assert "G/Geometry" in str(err) and "fail" in str(err)


def test_unknown_service_is_a_remote_error_listing_what_exists(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, GEOMETRY, lambda a: geo_client(a, "G/Nope")) as (_, client):
        with pytest.raises(RemoteError) as info:
            instance(client, "C").geo.nothing()
        assert "ServiceNotFoundError" in info.value.remote_type and "G/Geometry" in info.value.remote_message


def test_oneway_failures_are_counted_on_the_service_side(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, GEOMETRY, geo_client) as (provider, client):
        instance(client, "C").geo.explode()
        binding = grpc_bindings(provider)[0]
        wait_until(lambda: binding.oneway_failures == 1 and provider.oneway_failures == 1, timeout=10)


def test_oneway_returns_when_accepted_not_when_finished(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, GEOMETRY, geo_client) as (_, client):
        g = module("gcomps")
        g.STARTED.clear(), g.RELEASE.clear(), g.DONE.clear()
        try:
            assert instance(client, "C").geo.slow(7) is None
            assert g.STARTED.wait(10) and g.DONE == []
        finally:
            g.RELEASE.set()
        wait_until(lambda: g.DONE == ["slow 7"], timeout=10)


# --- callbacks ------------------------------------------------------------------------------


def test_synchronous_callbacks_keep_their_order_and_return_values(tmp_path: Path) -> None:
    def client(addr: str) -> str:
        return f'<component name="K">{gpy("Asker")}<reference name="desk">{grpc_reference(addr, "D/Desk")}</reference></component>'
    with provider_and_client(tmp_path, DESK, client) as (_, rt):
        assert rt.service("K").ask("go") == "go: True False"
        asker = instance(rt, "K")
        assert asker.questions == ["go?", "go??"]
        assert asker.got.wait(10) and asker.told_msgs == ["decided"]


def test_callbacks_during_and_after_a_oneway_call(tmp_path: Path) -> None:
    def client(addr: str) -> str:
        return f'<component name="K">{gpy("Asker")}<reference name="desk">{grpc_reference(addr, "D/Desk")}</reference></component>'
    with provider_and_client(tmp_path, DESK, client) as (provider, rt):
        assert rt.service("K").ask_later("q?") is None
        desk = instance(provider, "D")
        assert desk.done.wait(10)
        assert desk.results == ["q? -> True"]
        asker = instance(rt, "K")
        assert asker.got.wait(10) and asker.told_msgs == ["later q?"]
        desk.done.clear()
        rt.service("K").ask_later("again")  # the session is reused
        assert desk.done.wait(10) and desk.results[-1] == "again -> False"
        rt.service("K").ask("sync")  # a synchronous call names the same session
        assert len(desk.callers) == 1  # one remote caller is one callback target, as locally


# --- deadlines, reconnection, promotion ----------------------------------------------------


def test_unreachable_service_fails_naming_the_address_within_the_deadline(tmp_path: Path) -> None:
    addr = f"127.0.0.1:{free_port()}"
    path = gwrite(tmp_path, {"c.composite": composite(geo_client(addr, timeout=0.5))})
    with scart.Runtime.from_file(str(path)) as rt:
        began = time.monotonic()
        with pytest.raises(ServiceUnavailableError) as info:
            instance(rt, "C").geo.nothing()
        assert time.monotonic() - began < 3.0
        assert addr in str(info.value)
        with pytest.raises(ServiceUnavailableError):
            instance(rt, "C").geo.slow(1)


def test_provider_restarted_on_the_same_port_is_reached_again(tmp_path: Path) -> None:
    addr = f"127.0.0.1:{free_port()}"
    body = f'<component name="G">{gpy("GeometryImpl")}<service name="Geometry">{grpc_service(addr)}</service></component>'
    prov = gwrite(tmp_path, {"p.composite": composite(body)})
    cli = gwrite(tmp_path, {"c.composite": composite(geo_client(addr, timeout=1.0))})
    with scart.Runtime.from_file(str(cli)) as client:
        geo = instance(client, "C").geo
        with scart.Runtime.from_file(str(prov)):
            assert geo.scale([1.0], 2.0) == [2.0]
        with pytest.raises(ServiceUnavailableError):
            geo.scale([1.0], 2.0)
        with scart.Runtime.from_file(str(prov)):
            assert wait_until(lambda: _reachable(geo), timeout=10)
            assert geo.scale([1.0], 3.0) == [3.0]


def _reachable(geo: object) -> bool:
    try:
        return geo.scale([1.0], 1.0) == [1.0]  # type: ignore[attr-defined]
    except ServiceUnavailableError:
        return False


def test_promoted_composite_service_and_reference_take_the_binding(tmp_path: Path) -> None:
    provider = f'''<service name="Front" promote="A/Greeter">{grpc_service()}</service>
        <component name="A">{py("GreeterImpl")}</component>'''

    def client(addr: str) -> str:
        inner = composite(f'''<reference name="out" promote="S/one"/>
            <component name="S">{py("Single")}</component>''', name="Inner")
        gwrite(tmp_path, {"inner.composite": inner})
        return f'''<component name="Outer"><implementation.composite name="t:Inner"/>
            <reference name="out">{grpc_reference(addr, "Front")}</reference></component>'''
    with provider_and_client(tmp_path, provider, client) as (_, rt):
        assert rt.service("Outer/S").call("p") == "Hello, p"


# --- static checks --------------------------------------------------------------------------


def test_bad_binding_attributes_are_static_errors_with_lines(tmp_path: Path) -> None:
    text = composite(f'''
        <component name="A">{py("GreeterImpl")}<service name="Greeter"><scart:binding.grpc address="127.0.0.1:99999"/></service></component>
        <component name="S">{py("Single")}<reference name="one"><scart:binding.grpc service="A/Greeter"/></reference></component>
        <component name="T">{py("Single")}<reference name="one"><scart:binding.grpc address="h:1" timeout="0"/></reference></component>
        <component name="U">{py("Single")}<reference name="one"><scart:binding.grpc adress="h:1"/></reference></component>
    ''')
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(gwrite(tmp_path, {"b.composite": text})))
    errors = [(p.line, p.code) for p in info.value.errors]
    assert (3, "SCART-B101") in errors and (4, "SCART-B101") in errors
    assert any(line == 5 for line, _ in errors) and any(line == 6 for line, _ in errors)
    assert "port must be 1..65535" in str(info.value) and "needs address" in str(info.value)


def test_callback_session_is_reopened_after_the_provider_restarts(tmp_path: Path) -> None:
    addr = f"127.0.0.1:{free_port()}"
    body = f'<component name="D">{gpy("DeskImpl")}<service name="Desk">{grpc_service(addr)}</service></component>'
    prov = gwrite(tmp_path, {"p.composite": composite(body)})
    cli = gwrite(tmp_path, {"c.composite": composite(
        f'<component name="K">{gpy("Asker")}<reference name="desk">{grpc_reference(addr, "D/Desk", 2.0)}</reference></component>')})
    with scart.Runtime.from_file(str(cli)) as client:
        asker = instance(client, "K")
        for round_ in range(2):
            with scart.Runtime.from_file(str(prov)) as provider:
                asker.got.clear()
                wait_until(lambda: _sends(asker, f"q{round_}"), timeout=10)
                desk = instance(provider, "D")
                assert desk.done.wait(10) and desk.results == [f"q{round_} -> False"]
                assert asker.got.wait(10) and asker.told_msgs[-1] == f"later q{round_}"


def _sends(asker: object, q: str) -> bool:
    try:
        asker.ask_later(q)  # type: ignore[attr-defined]
        return True
    except ServiceUnavailableError:
        return False


def test_a_port_in_use_is_a_start_error_naming_the_address(tmp_path: Path) -> None:
    with provider_and_client(tmp_path, GEOMETRY, geo_client) as (provider, _):
        taken = grpc_bindings(provider)[0].address
        body = f'<component name="G2">{gpy("GeometryImpl")}<service name="Geometry">{grpc_service(taken)}</service></component>'
        other = scart.Runtime.from_file(str(gwrite(tmp_path, {"x.composite": composite(body)})))
        with pytest.raises(scart.ScartError, match=f"cannot listen on {taken}"):
            other.start()


def test_services_listed_by_the_server(tmp_path: Path) -> None:
    import grpc

    from scart.bindings.grpc._wire import PATHS, pb
    with provider_and_client(tmp_path, GEOMETRY + DESK, geo_client) as (provider, _):
        with grpc.insecure_channel(grpc_bindings(provider)[0].address) as channel:
            stub = channel.unary_unary(PATHS["ListServices"], request_serializer=pb.ListServicesRequest.SerializeToString,
                                       response_deserializer=pb.ListServicesResponse.FromString)
            services = {s.interface: s for s in stub(pb.ListServicesRequest(), timeout=5).services}
        assert list(services["Geometry"].names) == ["G/Geometry", "G"]
        assert services["Desk"].callback_interface == "Asking"
        assert {o.name: o.oneway for o in services["Desk"].callback_operations} == {"confirm": False, "told": True}


def test_concurrent_calls_with_callbacks_keep_each_callers_answers(tmp_path: Path) -> None:
    import threading

    def client(addr: str) -> str:
        return f'<component name="K">{gpy("Asker")}<reference name="desk">{grpc_reference(addr, "D/Desk")}</reference></component>'
    with provider_and_client(tmp_path, DESK, client) as (_, rt):
        errors: list[BaseException] = []
        results: list[str] = []

        def worker(i: int) -> None:
            try:
                for j in range(10):
                    results.append(rt.service("K").ask(f"w{i}-{j}"))
            except BaseException as exc:  # reported below
                errors.append(exc)
        threads = [threading.Thread(target=worker, args=(i,)) for i in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
        assert not errors and sorted(results) == sorted(f"w{i}-{j}: True False" for i in range(4) for j in range(10))


def test_every_binding_thread_ends_with_the_runtimes(tmp_path: Path) -> None:
    import threading

    def client(addr: str) -> str:
        return f'<component name="K">{gpy("Asker")}<reference name="desk">{grpc_reference(addr, "D/Desk")}</reference></component>'
    with provider_and_client(tmp_path, DESK, client) as (provider, rt):
        rt.service("K").ask_later("q")  # opens a callback session (a thread on each side)
        assert instance(provider, "D").done.wait(10)
        assert rt.service("K").ask("x")  # an Invoke stream (a pool thread on the provider)
        assert any(t.name.startswith("scart-grpc") for t in threading.enumerate())
    wait_until(lambda: not [t for t in threading.enumerate() if t.name.startswith("scart-grpc")], timeout=10,
               message="binding.grpc threads still running after stop")
