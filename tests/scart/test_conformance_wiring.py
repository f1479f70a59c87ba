"""SCA Assembly 1.1 conformance, interfaces and wiring: each statement, loaded both ways —
a composite that follows it runs (or validates), one that breaks it is refused with the
statement's code, at the faulty line. Composites written from the spec's text."""

from __future__ import annotations

from pathlib import Path

import pytest

import scart
from support.sca import SCA, composite, line_of, py, write

CONF = '''
from __future__ import annotations

from typing import Protocol

import scart


class Pong(Protocol):
    @scart.oneway
    def pong(self, n: int) -> None: ...


class Pang(Protocol):
    @scart.oneway
    def pang(self, n: int) -> None: ...


@scart.interface(callback=Pong)
class Ping(Protocol):
    def ping(self, n: int) -> int: ...


class PlainPing(Protocol):
    def ping(self, n: int) -> int: ...


class WidePing(Protocol):
    def ping(self, n: int) -> int: ...
    def reset(self) -> None: ...


@scart.component(services=[Ping])
class PingImpl:
    caller: Pong = scart.callback()

    def ping(self, n: int) -> int:
        self.caller.pong(n)
        return n + 1


@scart.component(services=[PlainPing])
class PlainPingImpl:
    def ping(self, n: int) -> int:
        return n + 1


class Caller:
    target: Ping = scart.reference()

    def pong(self, n: int) -> None: ...

    def call(self, n: int) -> int:
        return self.target.ping(n)


class PlainCaller:
    target: PlainPing = scart.reference()

    def call(self, n: int) -> int:
        return self.target.ping(n)


@scart.component(services=[WidePing])
class WidePingImpl:
    def ping(self, n: int) -> int:
        return n + 1

    def reset(self) -> None: ...


class WideCaller:
    target: WidePing = scart.reference()

    def call(self, n: int) -> int:
        return self.target.ping(n)


class ManyCaller:
    targets: list[PlainPing] = scart.reference(multiple=True, required=False)

    def call(self, n: int) -> list:
        return [t.ping(n) for t in self.targets]
'''

WSDL = """<?xml version="1.0"?>
<definitions xmlns="http://schemas.xmlsoap.org/wsdl/" xmlns:sca="http://docs.oasis-open.org/ns/opencsa/sca/200912"
             xmlns:tns="urn:ping" targetNamespace="urn:ping" name="Ping">
  <portType name="Ping" sca:callback="tns:Pong">
    <operation name="ping"><input message="tns:n"/><output message="tns:n"/></operation>
  </portType>
  <portType name="PlainPing">
    <operation name="ping"><input message="tns:n"/><output message="tns:n"/></operation>
  </portType>
  <portType name="Pong"><operation name="pong"><input message="tns:n"/></operation></portType>
  <portType name="Pang"><operation name="pang"><input message="tns:n"/></operation></portType>
</definitions>
"""


def c(cls: str) -> str:
    return f'<scart:implementation.python class="conf:{cls}"/>'


def contribution(tmp_path: Path, body: str, **others: str) -> tuple[Path, str]:
    text = composite(body)
    path = write(tmp_path, {"main.composite": text, "conf.py": CONF, "ping.wsdl": WSDL, **others})
    return path, text


def refused(path: Path) -> scart.ScdlError:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return info.value


def only(tmp_path: Path, body: str, code: str, marker: str = "<!--HERE-->", **others: str) -> str:
    """The composite is refused with exactly ``code``, at the line of ``marker``; the message."""
    path, text = contribution(tmp_path, body, **others)
    err = refused(path)
    assert err.codes == [code], str(err)
    assert err.errors[0].line == line_of(text, marker), str(err)
    return err.errors[0].message


def runs(tmp_path: Path, body: str, **others: str) -> scart.Runtime:
    path, _ = contribution(tmp_path, body, **others)
    return scart.Runtime.from_file(str(path))


# ---- interface.wsdl -----------------------------------------------------------------

WSDL_CALLER = """
    <component name="P">{impl}</component>
    <component name="C">{caller}
      <reference name="target" target="P"><!--HERE-->
        <interface.wsdl interface="{iface}"{extra}/>
      </reference>
    </component>
"""


@pytest.mark.parametrize("form", ["wsdl.porttype", "wsdl.interface"])
def test_a_wsdl_port_type_is_named_in_the_1_1_form_and_the_1_0_one(tmp_path: Path, form: str) -> None:
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface=f"urn:ping#{form}(Ping)", extra="")
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(1) == 2


@pytest.mark.parametrize("iface", ["urn:ping#Ping", "urn:ping#wsdl.porttype(Nope)", "urn:ping#wsdl.porttype()"])
def test_asm80001_interface_wsdl_names_a_port_type(tmp_path: Path, iface: str) -> None:
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface=iface, extra="")
    message = only(tmp_path, body, "ASM80001", marker="interface.wsdl")
    assert iface.partition("#")[2] in message or "Nope" in message


def test_asm80010_a_port_type_s_sca_callback_declares_the_callback(tmp_path: Path) -> None:
    # Ping's portType declares sca:callback="tns:Pong": the reference is bidirectional
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface="urn:ping#wsdl.porttype(Ping)", extra="")
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(41) == 42
    # a portType without one, given the callback by @callbackInterface: the same
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface="urn:ping#wsdl.porttype(PlainPing)",
                              extra=' callbackInterface="urn:ping#wsdl.porttype(Pong)"')
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(1) == 2


def test_asm80016_callback_interface_names_a_port_type(tmp_path: Path) -> None:
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface="urn:ping#wsdl.porttype(PlainPing)",
                              extra=' callbackInterface="urn:ping#wsdl.porttype(Nope)"')
    assert "callbackInterface" in only(tmp_path, body, "ASM80016", marker="interface.wsdl")


def test_asm80011_callback_interface_agrees_with_the_port_type_s_own(tmp_path: Path) -> None:
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface="urn:ping#wsdl.porttype(Ping)",
                              extra=' callbackInterface="urn:ping#wsdl.porttype(Pang)"')
    path, text = contribution(tmp_path, body)
    err = refused(path)
    assert "ASM80011" in err.codes and "disagrees with the callback interface Pong" in str(err)
    same = body.replace("(Pang)", "(Pong)")
    with runs(tmp_path, same) as rt:
        assert rt.service("C").call(1) == 2


def test_asm80017_a_wsdl_interface_is_remotable(tmp_path: Path) -> None:
    body = WSDL_CALLER.format(impl=c("PingImpl"), caller=c("Caller"), iface="urn:ping#wsdl.porttype(Ping)",
                              extra=' remotable="false"')
    assert "always remotable" in only(tmp_path, body, "ASM80017", marker="interface.wsdl")
    with runs(tmp_path, body.replace('"false"', '"true"')) as rt:
        assert rt.service("C").call(1) == 2


# ---- callbacks and compatibility ------------------------------------------------------

def test_asm50004_a_component_service_declares_the_callback_its_implementation_has(tmp_path: Path) -> None:
    lacks = f"""
        <component name="P">{c("PlainPingImpl")}
          <service name="PlainPing">
            <scart:interface.python interface="conf:PlainPing" callbackInterface="conf:Pong"/><!--HERE-->
          </service>
        </component>"""
    assert "PlainPing has no callback interface" in only(tmp_path, lacks, "ASM50004")
    hides = f"""
        <component name="P">{c("PingImpl")}
          <service name="Ping"><scart:interface.python interface="conf:PlainPing"/><!--HERE--></service>
        </component>"""
    assert "declares callback interface Pong" in only(tmp_path, hides, "ASM50004")
    same = hides.replace("conf:PlainPing", "conf:Ping")
    with runs(tmp_path, same) as rt:
        assert "P" in rt.assembly.nodes


def test_asm50011_a_component_reference_interface_may_add_never_take(tmp_path: Path) -> None:
    narrower = f"""
        <component name="P">{c("PingImpl")}</component>
        <component name="C">{c("Caller")}
          <reference name="target" target="P"><scart:interface.python interface="conf:PlainPing"/><!--HERE--></reference>
        </component>"""
    assert "PlainPing has no callback interface" in only(tmp_path, narrower, "ASM50011")
    wider = f"""
        <component name="P">{c("PlainPingImpl")}</component>
        <component name="C">{c("PlainCaller")}
          <reference name="target" target="P"><scart:interface.python interface="conf:WidePing"/></reference>
        </component>"""
    path, _ = contribution(tmp_path, wider)
    err = refused(path)  # wider than the implementation's: fine by ASM50011, but the target lacks reset
    assert err.codes == ["ASM60043"] and "lacks operation(s) reset" in str(err)


def test_asm60043_a_wire_matches_callbacks_both_ways(tmp_path: Path) -> None:
    to_bidirectional = f"""
        <component name="P">{c("PingImpl")}</component>
        <component name="C">{c("PlainCaller")}<reference name="target" target="P"/><!--HERE--></component>"""
    assert "Ping declares callback interface Pong, and PlainPing has no callback" in \
        only(tmp_path, to_bidirectional, "ASM60043")
    from_bidirectional = f"""
        <component name="P">{c("PlainPingImpl")}</component>
        <component name="C">{c("Caller")}<reference name="target" target="P"/><!--HERE--></component>"""
    assert "no callback interface" in only(tmp_path, from_bidirectional, "ASM60043")
    matching = f"""
        <component name="P">{c("PingImpl")}</component>
        <component name="C">{c("Caller")}<reference name="target" target="P"/></component>"""
    with runs(tmp_path, matching) as rt:
        assert rt.service("C").call(1) == 2


INNER = """<?xml version="1.0"?>
<composite xmlns="{sca}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="Inner">
  <component name="P">{impl}</component>
  <service name="S" promote="P">{iface}</service>
</composite>
"""


def test_asm60005_a_composite_service_interface_is_a_compatible_subset(tmp_path: Path) -> None:
    outer = '<component name="O"><implementation.composite name="t:Inner"/></component>'
    for iface, ok in (('<scart:interface.python interface="conf:Ping"/>', True),
                      ("", True),
                      ('<scart:interface.python interface="conf:PlainPing"/>', False),  # hides the callback
                      ('<scart:interface.python interface="conf:WidePing"/>', False)):  # an operation P lacks
        inner = INNER.format(sca=SCA, impl=c("PingImpl"), iface=iface)
        path, _ = contribution(tmp_path, outer, **{"inner.composite": inner})
        if ok:
            with scart.Runtime.from_file(str(path)) as rt:
                assert "O/S" in rt.assembly.aliases or rt.assembly.nodes
        else:
            err = refused(path)
            assert set(err.codes) == {"ASM60005"} and err.errors[0].path.endswith("inner.composite"), str(err)


INNER_REFERENCE = """<?xml version="1.0"?>
<composite xmlns="{sca}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="Inner">
  <component name="C">{caller}{wired}</component>
  {second}
  <reference name="R" promote="{promote}"{mult}>{iface}</reference>
</composite>
"""


def inner_reference(caller: str = "Caller", wired: str = "", second: str = "", promote: str = "C/target",
                    mult: str = "", iface: str = "") -> str:
    return INNER_REFERENCE.format(sca=SCA, caller=c(caller), wired=wired, second=second, promote=promote,
                                  mult=f' multiplicity="{mult}"' if mult else "", iface=iface)


OUTER = f"""
    <component name="P">{c("PingImpl")}</component>
    <component name="Q">{c("PlainPingImpl")}</component>
    <component name="O"><implementation.composite name="t:Inner"/><reference name="R" target="{{target}}"/></component>
"""


def test_asm60012_a_composite_reference_interface_is_a_compatible_superset(tmp_path: Path) -> None:
    ok = inner_reference(iface='<scart:interface.python interface="conf:Ping"/>')
    with runs(tmp_path, OUTER.format(target="P"), **{"inner.composite": ok}) as rt:
        assert rt.service("O/C").call(1) == 2
    bad = inner_reference(iface='<scart:interface.python interface="conf:PlainPing"/>')
    path, _ = contribution(tmp_path, OUTER.format(target="P"), **{"inner.composite": bad})
    err = refused(path)
    assert "ASM60012" in err.codes and "has no callback interface" in str(err)


def test_asm60008_references_promoted_together_share_an_interface(tmp_path: Path) -> None:
    second = f'<component name="D">{c("PlainCaller")}</component>'
    bad = inner_reference(second=second, promote="C/target D/target")
    path, _ = contribution(tmp_path, OUTER.format(target="P"), **{"inner.composite": bad})
    err = refused(path)
    assert "ASM60008" in err.codes and "promotes C/target (Ping) and D/target (PlainPing) together" in str(err)


# ---- references, services, bindings ---------------------------------------------------

def test_binding_sca_uri_on_a_reference_is_its_target(tmp_path: Path) -> None:
    body = f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}<reference name="one"><binding.sca uri="A/Greeter"/></reference></component>"""
    with runs(tmp_path, body) as rt:
        assert rt.service("S").call("x") == "Hello, x"
    message = only(tmp_path, body.replace("A/Greeter", "B/Greeter").replace("<binding.sca", "<binding.sca<!--HERE-->"
                                                                             ).replace("<binding.sca<!--HERE-->",
                                                                                       "<!--HERE--><binding.sca"),
                   "ASM60047")
    assert "reference 'one'" in message and "no component 'B'" in message


def test_asm90005_binding_sca_on_a_service_has_no_uri(tmp_path: Path) -> None:
    body = f"""
        <component name="A">{py("GreeterImpl")}
          <service name="Greeter"><binding.sca uri="A/Greeter"/><!--HERE--></service>
        </component>"""
    assert "must not have @uri" in only(tmp_path, body, "ASM90005", marker="binding.sca")
    with runs(tmp_path, body.replace(' uri="A/Greeter"', "")) as rt:
        assert rt.service("A").greet("x") == "Hello, x"


@pytest.mark.parametrize("where", ["binding", "service"])
def test_asm13001_the_sca_1_0_operation_element_is_refused(tmp_path: Path, where: str) -> None:
    inside = '<binding.sca><operation name="greet"/><!--HERE--></binding.sca>' if where == "binding" \
        else '<operation name="greet"/><!--HERE-->'
    body = f'<component name="A">{py("GreeterImpl")}<service name="Greeter">{inside}</service></component>'
    assert "SCA 1.0" in only(tmp_path, body, "ASM13001")


def test_asm50026_a_target_and_a_binding_naming_its_own_endpoint(tmp_path: Path) -> None:
    body = f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="B">{py("GreeterImpl")}<property name="greeting">Hi</property></component>
        <component name="S">{py("Single")}
          <reference name="one" target="A"><binding.sca uri="B/Greeter"/><!--HERE--></reference>
        </component>"""
    path, text = contribution(tmp_path, body)
    err = refused(path)
    assert "ASM50026" in err.codes and err.errors[0].line == line_of(text, "<!--HERE-->"), str(err)
    grpc = body.replace('<binding.sca uri="B/Greeter"/>', '<scart:binding.grpc address="127.0.0.1:1" service="B/Greeter"/>')
    path, text = contribution(tmp_path, grpc)
    err = refused(path)
    assert err.codes == ["ASM50026"] and err.errors[0].line == line_of(text, "<!--HERE-->")
    with runs(tmp_path, body.replace(' uri="B/Greeter"', "")) as rt:  # binding.sca alone: the default binding
        assert rt.service("S").call("x") == "Hello, x"


def test_asm90002_binding_names_are_unique_on_a_service(tmp_path: Path) -> None:
    body = f"""
        <component name="A">{py("GreeterImpl")}
          <service name="Greeter">
            <scart:binding.grpc name="fred"/>
            <scart:binding.grpc name="fred" address="127.0.0.1:0"/><!--HERE-->
          </service>
        </component>"""
    assert "two bindings named 'fred'" in only(tmp_path, body, "ASM90002")


NON_OVERRIDABLE = """<?xml version="1.0"?>
<composite xmlns="{sca}" targetNamespace="urn:test" name="Inner" xmlns:scart="urn:scart:1.0">
  <component name="A"><scart:implementation.python class="comps:GreeterImpl"/></component>
  <component name="S"><scart:implementation.python class="comps:{cls}"/>
    <reference name="{ref}" target="A"{flag}/>
  </component>
  <reference name="R" promote="S/{ref}"/>
</composite>
"""


def outer_greeting(tmp_path: Path, cls: str, ref: str, flag: str) -> Path:
    inner = NON_OVERRIDABLE.format(sca=SCA, cls=cls, ref=ref, flag=flag)
    body = f"""
        <component name="B">{py("GreeterImpl")}<property name="greeting">Outer</property></component>
        <component name="O"><implementation.composite name="t:Inner"/><reference name="R" target="B"/></component>"""
    return contribution(tmp_path, body, **{"inner.composite": inner})[0]


def test_asm50042_a_non_overridable_single_reference_is_not_promoted(tmp_path: Path) -> None:
    err = refused(outer_greeting(tmp_path, "Single", "one", ' nonOverridable="true"'))
    assert err.codes == ["ASM50042"] and err.errors[0].path.endswith("inner.composite")
    # overridable (the default): the composite reference's target replaces the inner one
    with scart.Runtime.from_file(str(outer_greeting(tmp_path, "Single", "one", ""))) as rt:
        assert rt.service("O/S").call("x") == "Outer, x"
    # a 1..n nonOverridable reference may be promoted: the outer targets add to its own
    with scart.Runtime.from_file(str(outer_greeting(tmp_path, "AtLeastOne", "many", ' nonOverridable="true"'))) as rt:
        assert sorted(rt.service("O/S").call("x")) == ["Hello, x", "Outer, x"]


def test_asm60011_a_composite_reference_narrows_never_widens(tmp_path: Path) -> None:
    body = OUTER.format(target="P")
    widen = inner_reference(mult="0..n")  # C/target is 1..1 and unwired inside
    path, text = contribution(tmp_path, body, **{"inner.composite": widen})
    err = refused(path)
    assert "ASM60011" in err.codes and "multiplicity '0..n' would widen it" in str(err)
    same = inner_reference(mult="1..1")
    with runs(tmp_path, body, **{"inner.composite": same}) as rt:
        assert rt.service("O/C").call(1) == 2
    # wired inside already: "at least one" may be relaxed to 0..1
    relaxed = inner_reference(wired='<reference name="target" target="Local"/>', mult="0..1",
                              second=f'<component name="Local">{c("PingImpl")}</component>')
    with runs(tmp_path, body, **{"inner.composite": relaxed}) as rt:
        assert rt.service("O/C").call(1) == 2


@pytest.mark.parametrize("promote, code", [("Not a URI", "ASM60004"), ("A/<Greeter>", "ASM60004")])
def test_asm60004_a_composite_service_promotes_one_uri(tmp_path: Path, promote: str, code: str) -> None:
    body = f'<component name="A">{py("GreeterImpl")}</component>\n<service name="S" promote="{promote}"/><!--HERE-->'
    path, text = contribution(tmp_path, body.replace("<", "&lt;").replace("&lt;component", "<component")
                              if False else body.replace("<Greeter>", "&lt;Greeter&gt;"))
    err = refused(path)
    assert code in err.codes and all("promote" in p.message for p in err.errors), str(err)


def test_asm60007_a_composite_reference_promotes_uris(tmp_path: Path) -> None:
    body = f'<component name="S">{py("Single")}</component>\n<reference name="R" promote="S/one S/{{x}}"/><!--HERE-->'
    err = refused(contribution(tmp_path, body)[0])
    assert "ASM60007" in err.codes and "@promote 'S/{x}' is not a valid URI" in str(err)


def test_asm60041_a_local_composite_is_included_only_into_a_local_one(tmp_path: Path) -> None:
    inner = f"""<?xml version="1.0"?>
<composite xmlns="{SCA}" xmlns:scart="urn:scart:1.0" targetNamespace="urn:test" name="Parts" local="true">
  <component name="A">{py("GreeterImpl")}</component>
</composite>
"""
    body = '<include name="t:Parts"/><!--HERE-->'
    assert "local" in only(tmp_path, body, "ASM60041", **{"parts.composite": inner})
    text = composite(body).replace('name="Test"', 'name="Test" local="true"')
    path = write(tmp_path, {"main.composite": text, "parts.composite": inner})
    with scart.Runtime.from_file(str(path)) as rt:
        assert rt.service("A").greet("x") == "Hello, x"


def test_a_problem_names_the_reference_and_the_service(tmp_path: Path) -> None:
    body = f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}<reference name="one" target="A/Greter"/><!--HERE--></component>"""
    message = only(tmp_path, body, "ASM60047")
    assert "reference 'one'" in message and "no service 'Greter' (did you mean 'Greeter'?)" in message


def test_a_binding_on_a_service_the_component_lacks_is_one_problem(tmp_path: Path) -> None:
    body = f"""
        <component name="A">{py("GreeterImpl")}
          <service name="Greter"><scart:binding.grpc address="127.0.0.1:0"/></service><!--HERE-->
        </component>"""
    assert "did you mean" not in only(tmp_path, body, "ASM50003", marker="Greter")


def test_interface_java_names_its_callback_in_dotted_form(tmp_path: Path) -> None:
    body = f"""
        <component name="P">{c("PingImpl")}</component>
        <component name="C">{c("Caller")}
          <reference name="target" target="P"><interface.java interface="conf.Ping" callbackInterface="conf.Pong"/>
          </reference>
        </component>"""
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(1) == 2
    assert "Pang" in only(tmp_path, body.replace("conf.Pong", "conf.Pang").replace("<interface.java",
                                                                                     "<!--HERE--><interface.java"),
                          "ASM80011")


@pytest.mark.parametrize("source, said", [("Nobody/target", "no component 'Nobody'"),
                                          ("C/targt", "no reference 'targt' (did you mean 'target'?)")])
def test_a_wire_source_names_a_component_reference(tmp_path: Path, source: str, said: str) -> None:
    body = f"""
        <component name="P">{c("PlainPingImpl")}</component>
        <component name="C">{c("PlainCaller")}<reference name="target" target="P"/></component>
        <wire source="{source}" target="P" replace="true"/><!--HERE-->"""
    assert said in only(tmp_path, body, "SCART-C008")
    with runs(tmp_path, body.replace(source, "C/target")) as rt:
        assert rt.service("C").call(1) == 2


def test_asm60050_a_target_names_a_binding_of_the_service(tmp_path: Path) -> None:
    body = f"""
        <component name="P">{c("PlainPingImpl")}<service name="PlainPing"><binding.sca name="fast"/></service></component>
        <component name="C">{c("PlainCaller")}<reference name="target" target="P/PlainPing/{{b}}"/><!--HERE--></component>"""
    with runs(tmp_path, body.format(b="fast")) as rt:
        assert rt.service("C").call(1) == 2
    assert "no binding named 'slow'; its bindings: fast" in only(tmp_path, body.format(b="slow"), "ASM60050")
    plain = body.replace('<service name="PlainPing"><binding.sca name="fast"/></service>', "")
    with runs(tmp_path, plain.format(b="PlainPing")) as rt:  # no binding: its binding.sca, named after the service
        assert rt.service("C").call(1) == 2


def test_autowire_picks_only_a_compatible_service(tmp_path: Path) -> None:
    """PlainPingImpl has the operation but not the callback Caller's Ping declares: autowire passes it by."""
    body = f"""
        <component name="Plain">{c("PlainPingImpl")}</component>
        <component name="P">{c("PingImpl")}</component>
        <component name="C" autowire="true">{c("Caller")}</component>"""
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(1) == 2
    path, _ = contribution(tmp_path, body.replace(f'<component name="P">{c("PingImpl")}</component>', ""))
    assert refused(path).codes == ["ASM50040"]  # nothing compatible: the 1..1 reference has no target


def test_a_wire_sees_the_interface_the_service_declares(tmp_path: Path) -> None:
    """A component service declared with a narrower interface offers only that to wires."""
    body = f"""
        <component name="W">{c("WidePingImpl")}
          <service name="WidePing"><scart:interface.python interface="conf:PlainPing"/></service>
        </component>
        <component name="C">{c("WideCaller")}<reference name="target" target="W"/><!--HERE--></component>"""
    assert "PlainPing lacks operation(s) reset" in only(tmp_path, body, "ASM60043")
    with runs(tmp_path, body.replace("conf:PlainPing", "conf:WidePing")) as rt:
        assert rt.service("C").call(1) == 2


def test_policy_attributes_on_scart_elements_are_read_and_ignored(tmp_path: Path) -> None:
    body = f"""
        <component name="P" xmlns:sca="{SCA}" requires="sca:confidentiality">
          <scart:implementation.python class="conf:PlainPingImpl" requires="sca:confidentiality" policySets="sca:x"/>
          <service name="PlainPing"><scart:interface.python interface="conf:PlainPing" requires="sca:integrity"/>
            <scart:binding.grpc address="127.0.0.1:0" requires="sca:authentication"/></service>
        </component>
        <component name="C">{c("PlainCaller")}<reference name="target" target="P"/></component>"""
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(1) == 2
    path, _ = contribution(tmp_path, body.replace('requires="sca:integrity"', 'requires="x y:"'))
    assert refused(path).codes == ["SCART-X003"]


def test_binding_sca_takes_children_of_other_namespaces(tmp_path: Path) -> None:
    body = f"""
        <component name="P">{c("PlainPingImpl")}
          <service name="PlainPing"><binding.sca><x:hint xmlns:x="urn:vendor"/><wireFormat.sca/></binding.sca></service>
        </component>
        <component name="C">{c("PlainCaller")}<reference name="target" target="P"/></component>"""
    with runs(tmp_path, body) as rt:
        assert rt.service("C").call(1) == 2
    assert "did you mean" not in only(tmp_path, body.replace("<wireFormat.sca/>", "<bogus/><!--HERE-->"), "ASM13001")
