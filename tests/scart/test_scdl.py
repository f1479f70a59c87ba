"""The SCDL loader: safe parsing, namespaces, the shipped XSD, WSDL interfaces, locations."""

from __future__ import annotations

from pathlib import Path

import pytest
from lxml import etree

import scart
from scart import scdl
from scart.contribution import Contribution
from support.sca import composite, line_of, py, write

SECRET = "TOP-SECRET-CONTENT-42"


def refused(path: Path) -> scart.ScdlError:
    with pytest.raises(scart.ScdlError) as info:
        scart.Runtime.from_file(str(path))
    return info.value


def test_external_entity_is_refused_without_reading_the_file(tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET, encoding="utf-8")
    text = (f'<?xml version="1.0"?>\n<!DOCTYPE composite [<!ENTITY xxe SYSTEM "file://{secret}">]>\n'
            f'<composite xmlns="{scdl.SCA11_NS}" name="X"><property name="p">&xxe;</property></composite>\n')
    err = refused(write(tmp_path, {"xxe.composite": text}, with_components=False))
    assert err.codes == ["SCART-X002"] and err.line == 2
    assert SECRET not in str(err)


def test_billion_laughs_is_refused(tmp_path: Path) -> None:
    entities = '<!ENTITY lol "lol">' + "".join(
        f'<!ENTITY lol{i} "{("&lol%s;" % (i - 1 if i > 1 else "")) * 10}">' for i in range(1, 10))
    text = (f'<?xml version="1.0"?>\n<!DOCTYPE lolz [{entities}]>\n'
            f'<composite xmlns="{scdl.SCA11_NS}" name="X"><property name="p">&lol9;</property></composite>\n')
    err = refused(write(tmp_path, {"lol.composite": text}, with_components=False))
    assert err.codes == ["SCART-X002"]


def test_utf16_doctype_is_refused_after_parsing(tmp_path: Path) -> None:
    text = (f'<?xml version="1.0" encoding="UTF-16"?>\n<!DOCTYPE composite [<!ENTITY e "x">]>\n'
            f'<composite xmlns="{scdl.SCA11_NS}" name="X"/>\n')
    path = tmp_path / "u16.composite"
    path.write_bytes(text.encode("utf-16"))
    err = refused(path)
    assert err.codes == ["SCART-X002"]


def test_parser_never_expands_entities_even_if_asked_to_parse_a_dtd(tmp_path: Path) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET, encoding="utf-8")
    doc = (f'<!DOCTYPE r [<!ENTITY xxe SYSTEM "file://{secret}"><!ENTITY a "aaaa">]><r>&xxe;&a;</r>').encode()
    root = etree.fromstring(doc, scdl._parser())
    assert SECRET not in etree.tostring(root, encoding="unicode")
    assert "aaaa" not in (root.text or "")


def test_size_bound_is_checked_before_reading(tmp_path: Path) -> None:
    path = tmp_path / "big.composite"
    path.write_text("<composite>" + " " * 500 + "</composite>", encoding="utf-8")
    problems: list[scart.Problem] = []
    assert scdl.parse_xml(str(path), problems, max_bytes=100) is None
    assert problems[0].code == "SCART-X002" and "bound" in problems[0].message


def test_malformed_xml_reports_its_line(tmp_path: Path) -> None:
    text = composite(f"<component name='A'>{py('GreeterImpl')}\n<oops></component>")
    err = refused(write(tmp_path, {"bad.composite": text}))
    assert err.codes == ["SCART-X001"] and "malformed XML" in str(err)
    assert err.line >= line_of(text, "<oops>")


def test_wrong_root_element(tmp_path: Path) -> None:
    err = refused(write(tmp_path, {"x.composite": "<notacomposite/>"}, with_components=False))
    assert err.codes == ["SCART-X004"]


def test_unknown_element_is_reported(tmp_path: Path) -> None:
    text = composite(f"<component name='A'>{py('GreeterImpl')}</component>\n<frobnicate/>")
    err = refused(write(tmp_path, {"u.composite": text}))
    assert err.codes == ["ASM13001"] and err.line == line_of(text, "frobnicate")


def test_xsd_ships_in_the_package() -> None:
    schema = Path(scdl.__file__).with_name("schema") / "scart-1.0.xsd"
    assert schema.is_file()
    assert scdl._xsd() is not None


def test_model_remembers_locations(tmp_path: Path) -> None:
    text = composite(f"""
        <component name="A">{py("GreeterImpl")}
          <property name="greeting">Hi</property>
        </component>
    """)
    path = write(tmp_path, {"m.composite": text})
    comp = Contribution(str(path)).load_root()
    assert comp is not None and comp.qname == "{urn:test}Test"
    a = comp.component("A")
    assert a is not None and a.loc.line == line_of(text, 'name="A"')
    assert a.properties[0].loc.line == line_of(text, "greeting") and a.properties[0].values == ["Hi"]
    assert a.implementation is not None and a.implementation.attributes["class"] == "comps:GreeterImpl"


WSDL = """<?xml version="1.0"?>
<definitions xmlns="http://schemas.xmlsoap.org/wsdl/" targetNamespace="urn:greet" name="G">
  <portType name="GreeterPortType">
    <operation name="greet"><input message="x"/><output message="y"/></operation>
  </portType>
  <portType name="HelloPortType">
    <operation name="greet"><input message="x"/><output message="y"/></operation>
    <operation name="wave"><input message="x"/></operation>
  </portType>
</definitions>
"""


def test_interface_wsdl_port_types(tmp_path: Path) -> None:
    ok = composite(f"""
        <component name="A">{py("GreeterImpl")}</component>
        <component name="S">{py("Single")}
          <reference name="one" target="A">
            <interface.wsdl interface="urn:greet#wsdl.interface(GreeterPortType)"/>
          </reference>
        </component>
    """)
    bad = ok.replace("GreeterPortType", "HelloPortType")
    write(tmp_path, {"greet.wsdl": WSDL})
    with scart.Runtime.from_file(str(write(tmp_path, {"ok.composite": ok}))) as rt:
        assert rt.service("S").call("x") == "Hello, x"
    err = refused(write(tmp_path, {"bad.composite": bad}))
    assert err.codes == ["ASM60043"] and "wave" in str(err)
    missing = ok.replace("GreeterPortType", "Nope")
    assert refused(write(tmp_path, {"missing.composite": missing})).codes == ["ASM80001"]
    with_callback = ok.replace('GreeterPortType)"', 'GreeterPortType)" callbackInterface="urn:greet#wsdl.interface(Nope)"')
    assert refused(write(tmp_path, {"cb.composite": with_callback})).codes == ["ASM80016"]


def test_wsdl_one_way_operations() -> None:
    from scart.wsdl import read_port_types

    types, _ = read_port_types(etree.fromstring(WSDL.encode(), scdl._parser()))
    hello = types["{urn:greet}HelloPortType"]
    assert hello.operations["wave"].oneway and not hello.operations["greet"].oneway
