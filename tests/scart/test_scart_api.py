"""The public API of ``scart``: exports, and what the decorators declare."""

from __future__ import annotations

from typing import Protocol

import pytest
from hypothesis import given
from hypothesis import strategies as st

import scart
from scart.api import component_type, interface_info
from scart.values import parse_value

EXPECTED = {
    "ComponentContext", "ExtensionError", "ExtensionRegistry", "InvocationError", "NoCallbackError", "Problem",
    "RemoteError", "Runtime",
    "RuntimeState", "RuntimeStateError", "ScartError", "ScdlError", "ServiceNotFoundError", "ServiceProxy",
    "ServiceUnavailableError", "Settings",
    "callback", "component", "context", "destroy", "init", "interface", "oneway", "prop", "reference",
}


def test_public_exports_are_curated() -> None:
    assert set(scart.__all__) == EXPECTED
    for name in scart.__all__:
        assert getattr(scart, name) is not None
    public = {n for n in vars(scart) if not n.startswith("_")}
    # submodules may appear as attributes once imported; nothing else leaks
    import pkgutil

    submodules = {m.name for m in pkgutil.iter_modules(scart.__path__)}
    assert public - EXPECTED <= submodules


def test_error_tree() -> None:
    for err in (scart.ScdlError, scart.RuntimeStateError, scart.ServiceNotFoundError,
                scart.NoCallbackError, scart.InvocationError):
        assert issubclass(err, scart.ScartError)
    e = scart.ScdlError([scart.Problem("ASM50001", "dup", "a.composite", 3)])
    assert (e.path, e.line, e.codes) == ("a.composite", 3, ["ASM50001"])
    assert str(e) == "a.composite:3: dup [ASM50001]"


@scart.interface
class Pinging(Protocol):
    def ping(self) -> str: ...

    @scart.oneway
    def poke(self, n: int) -> None: ...


@scart.interface(callback=Pinging, remotable=True)
class Ponging(Protocol):
    def pong(self) -> None: ...


class Plain:
    size: int = scart.prop(default=3)
    needed: str = scart.prop(required=True)
    one: Pinging = scart.reference()
    maybe: Pinging = scart.reference(required=False)
    many: list[Pinging] = scart.reference(multiple=True)
    any_: list[Pinging] = scart.reference(required=False, multiple=True)
    caller: Pinging = scart.callback()

    @scart.init
    def setup(self) -> None: ...

    @scart.destroy
    def teardown(self) -> None: ...

    def visible(self) -> int:
        return 1

    def _hidden(self) -> None: ...


def test_component_without_services_offers_its_public_methods() -> None:
    ct = component_type(Plain)
    assert list(ct.services) == ["Plain"]
    assert set(ct.services["Plain"].operations) == {"visible"}
    assert ct.scope == "composite" and ct.eager_init
    assert ct.init == ("setup",) and ct.destroy == ("teardown",)
    assert ct.callbacks == ("caller",)


def test_references_and_properties_by_attribute_name() -> None:
    ct = component_type(Plain)
    mult = {name: spec.multiplicity for name, (spec, _) in ct.references.items()}
    assert mult == {"one": "1..1", "maybe": "0..1", "many": "1..n", "any_": "0..n"}
    assert all(t is Pinging for _, t in ct.references.values())
    assert ct.properties["size"][1] is int and ct.properties["needed"][0].required


def test_declared_services_are_named_after_interfaces() -> None:
    @scart.component(services=[Pinging, Ponging], scope="stateless", eager_init=False)
    class Both:
        def ping(self) -> str:
            return "p"

        def poke(self, n: int) -> None: ...

        def pong(self) -> None: ...

    ct = component_type(Both)
    assert list(ct.services) == ["Pinging", "Ponging"]
    assert ct.scope == "stateless" and not ct.eager_init
    ping = interface_info(Pinging)
    assert ping.operations["poke"].oneway and not ping.operations["ping"].oneway
    assert ping.operations["ping"].returns_value
    pong = interface_info(Ponging)
    assert pong.remotable and pong.callback is not None and pong.callback.name == "Pinging"


def test_bad_scope() -> None:
    with pytest.raises(ValueError, match="scope"):
        scart.component(scope="request")


def test_callback_outside_a_call() -> None:
    with pytest.raises(scart.NoCallbackError, match="caller"):
        Plain().caller  # noqa: B018


def test_the_built_in_kinds_are_found_by_entry_point() -> None:
    registry = scart.ExtensionRegistry()
    assert {"implementation.python", "binding.sca", "binding.grpc", "binding.dataflow", "implementation.task",
            "connect"} <= set(registry.names())
    assert "reference" in registry.binding("binding.sca").sides
    assert registry.implementation("implementation.python") is not None
    assert registry.binding("implementation.python") is None  # a name's prefix says its kind


@given(st.integers(), st.floats(allow_nan=False, allow_infinity=False), st.lists(st.integers(), max_size=8))
def test_property_text_round_trips(n: int, x: float, xs: list[int]) -> None:
    assert parse_value([str(n)], int) == n
    assert parse_value([repr(x)], float) == x
    assert parse_value([str(v) for v in xs], list[int]) == xs
    assert parse_value([str(xs)], list[int]) == xs  # one JSON array value


@given(st.sampled_from(["true", "1", "TRUE", " false", "0"]))
def test_bool_property_forms(text: str) -> None:
    assert parse_value([text], bool) is (text.strip().lower() in ("true", "1"))


def test_bool_property_refuses_other_words() -> None:
    with pytest.raises(ValueError, match="not a boolean"):
        parse_value(["yes"], bool)
